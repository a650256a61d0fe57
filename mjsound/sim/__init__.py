"""MuJoCo side: which geoms sound (`SoundScene`), contacts -> events (`ContactReader`), the
per-step driver (`AudioSimulator`), a room around the scene (`Room`) and offline rollout
sonification (`sonify`)."""

from .contacts import ContactReader
from .rooms import Room
from .scene import SoundScene
from .simulator import AudioSimulator, SampleClock

__all__ = ["AudioSimulator", "ContactReader", "Room", "SampleClock", "SoundScene", "sonify"]


def __getattr__(name):
    if name == "sonify":
        from .rollout import sonify

        return sonify
    raise AttributeError(f"module 'mjsound.sim' has no attribute {name!r}")
