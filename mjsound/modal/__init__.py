"""Modal analysis: surface mesh + material -> ModalModel. Knows nothing of MuJoCo."""

from .model import ModalModel

__all__ = ["Discretization", "ModalModel"]


def __getattr__(name):
    # (lazy: Discretization imports scipy.sparse, which a process loading cached models never needs)
    if name == "Discretization":
        from .discretization import Discretization

        return Discretization
    raise AttributeError(f"module 'mjsound.modal' has no attribute {name!r}")
