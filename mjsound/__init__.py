"""mjsound: MuJoCo simulations made audible from real physics.

Pipeline (one way): mesh + material -> :func:`analyze` -> :class:`ModalModel`
-> synthesis driven by contacts -> audio.
"""

from . import jit as _jit  # (first: numba's CPU target and cache, before any kernel is declared)
from .materials import MATERIALS, Material, get_material, parse_material
from .modal.model import ModalModel

__version__ = "0.1.0"

__all__ = ["MATERIALS", "Material", "ModalModel", "get_material", "parse_material", "analyze"]


def __getattr__(name):
    # Lazy imports keep `import mjsound` light (numba/scipy work only when used).
    if name == "analyze":
        from .modal.analyze import analyze

        return analyze
    if name == "Synthesizer":
        from .synth.synthesizer import Synthesizer

        return Synthesizer
    if name == "RerunLogger":
        from .rerun_log import RerunLogger

        return RerunLogger
    if name == "AudioObservation":
        from .wrappers import AudioObservation

        return AudioObservation
    if name in ("AudioSimulator", "SoundScene"):
        from . import sim

        return getattr(sim, name)
    raise AttributeError(f"module 'mjsound' has no attribute {name!r}")


_jit.seed_shipped_kernels()  # (last: numba's indexes name types of the modules above)
