"""MuJoCo side: which geoms sound (`SoundScene`), contacts -> events (`ContactReader`), the
per-step driver (`AudioSimulator`) and offline rollout sonification (`sonify`)."""

from .contacts import ContactReader
from .scene import SoundScene
from .simulator import AudioSimulator, SampleClock

__all__ = ["AudioSimulator", "ContactReader", "SampleClock", "SoundScene", "sonify"]


def __getattr__(name):
    if name == "sonify":
        from .rollout import sonify

        return sonify
    raise AttributeError(f"module 'mjsound.sim' has no attribute {name!r}")
