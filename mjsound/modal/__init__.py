"""Modal analysis: surface mesh + material -> ModalModel. Knows nothing of MuJoCo."""

from .discretization import Discretization
from .model import ModalModel

__all__ = ["Discretization", "ModalModel"]
