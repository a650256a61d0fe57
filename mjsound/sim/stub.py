"""A cheap stand-in :class:`ModalModel` (no analysis): for tests, previews and benchmarks.

The modes are *not* physical: frequencies are spread geometrically from ``f0_hz``, shapes are
seeded random vectors at the mesh vertices scaled to ``1/sqrt(mass)``, decay follows the
material's Rayleigh damping and radiation the compact-monopole order of magnitude
``rho0 omega^2 A phi / (4 pi)``. Use :func:`mjsound.modal.analyze.analyze` for real sound.
"""

from __future__ import annotations

import numpy as np

from ..materials import parse_material
from ..modal.model import ModalModel

__all__ = ["stub_model"]


def stub_model(mesh="box:0.1,0.1,0.1", material="steel", n_modes: int = 8, f0_hz: float = 800.0,
               ratio: float = 1.37, seed: int = 0) -> ModalModel:
    """A seeded fake modal model on a real surface.

    Parameters
    ----------
    mesh : str | (vertices, faces)
        Built-in spec or arrays [m] (the surface sample points are its vertices).
    material : str | Material
    n_modes : int
        Number of modes.
    f0_hz : float
        Lowest frequency [Hz]; mode i is at ``f0 * ratio**i``.
    ratio : float
        Frequency ratio between consecutive modes.
    seed : int
        Seed of the random shapes.

    Returns
    -------
    ModalModel
    """
    from ..geometry import load_mesh

    mat = parse_material(material)
    tm = load_mesh(mesh, check_size=False)
    pts = np.asarray(tm.vertices)
    nrm = np.asarray(tm.vertex_normals)
    vol = float(abs(tm.volume)) if tm.is_volume else float(tm.area) * 0.002
    mass = mat.rho * vol
    f = f0_hz * ratio ** np.arange(n_modes)
    w = 2 * np.pi * f
    d = 0.5 * (mat.alpha + mat.beta * w**2)
    rng = np.random.default_rng(seed)
    shapes = rng.standard_normal((len(pts), 3, n_modes)) / np.sqrt(3 * mass)
    rad = 1.2 * w**2 * float(tm.area) / np.sqrt(mass) / (4 * np.pi) * 0.1
    return ModalModel(
        frequencies_hz=f,
        decay_per_s=d,
        points=pts,
        normals=nrm,
        shapes=shapes,
        radiation=rad,
        material=mat,
        method="stub",
        mass_kg=mass,
        info={"stub": True},
    )
