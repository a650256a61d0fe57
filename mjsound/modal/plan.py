r"""Planning an analysis before anything is built: method, element size, cost and budget.

:func:`plan_analysis` looks only at the surface mesh and the material. It picks the
method (for ``method="auto"``), the element size, and estimates the modes in the band,
the dofs and the peak memory; when the estimate exceeds the memory cap it coarsens
(at most to ``quality="draft"``'s rule, saying so in a warning and in the model's info)
or refuses with the numbers and the options that would fit.

Method choice (``method="auto"``)
---------------------------------
* **thin curved walls** (a watertight mesh whose wall ``t = 2 V / A`` is under a quarter
  of its smallest bounding-box side: bowls, cups, cans, tubes, hollow objects) get
  shell triangles on the wall's mid-surface (:mod:`.facet_shell`, ``"facet"``) when at
  least :data:`FACET_MIN_COVERAGE` of the surface pairs across the wall
  (:func:`.midsurface.mid_surface`); otherwise quadratic tetrahedra with one element
  through the wall (:func:`.tet.discretize_tet` with ``through_wall=False``, needs the
  optional TetGen wrapper). The voxel embedding makes such a wall a staircase (a 20 cm
  bowl rang +60 .. +200 cents sharp); the shell has a sixth of the tets' dofs for the
  same accuracy.
* everything else (solids, bars, plates, open or non-manifold or self-intersecting
  meshes, and thin walls TetGen refuses) gets the voxel-embedded hexahedra, Picard's
  robust path: bars and plates are exact in bending there (one incompatible-mode cell
  through a plate), solids converge fast.

The choice and its reason are in ``model.info["method_choice"]``.

Estimates
---------
Modes below ``f`` (Weyl's law for a solid, and the bending-mode counts of a thin wall
and of a bar; the largest of the three):

.. math:: N_{3D} = \frac{4\pi}{3} V f^3 \left(\frac{1}{c_l^3} + \frac{2}{c_s^3}\right),\quad
          N_{wall} = \frac{A}{2}\,\frac{f}{2}\sqrt{\frac{\rho t}{D}},\quad
          N_{bar} = \frac{2 L}{\pi} \left(\frac{(2\pi f)^2 \rho S}{E I}\right)^{1/4}

with ``D = E t^3 / 12 (1 - nu^2)``, ``L`` the longest side, ``S = V / L`` and
``I = S^2 / 12``. Memory: ``MEMORY_PER_DOF`` bytes per dof times ``(dofs / 1e5)^(1/3)``
(the sparse factor's fill grows as ``n^(4/3)`` in 3D) plus the Lanczos basis
(``48 x modes x dofs`` bytes) plus, for hexahedra, the fine voxel grid. Calibrated on
the accuracy report's runs (measured peaks 0.5 .. 1.5 x the estimate).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np
import trimesh

from ..limits import DEFAULT_MAX_MEMORY_GB, MAX_MEMORY_ENV, max_memory_gb
from ..materials import Material
from .surface import face_components
from ..user_frame import user_stacklevel

__all__ = ["Plan", "plan_analysis", "estimate_modes", "max_memory_gb", "DEFAULT_MAX_MEMORY_GB",
           "MAX_MEMORY_ENV", "AnalysisBudgetError", "thin_wall", "QUALITY", "QUALITY_ORDER", "quality_preset", "hex_refine", "hex_moments",
           "mode_count_inputs", "frequency_of_mode", "solid_modes", "axis_aligned_fraction", "fills_bounding_box"]

MEMORY_PER_DOF = 20e3  # bytes per dof at 1e5 dofs (factor, matrices, assembly)
QUADRATIC_SIZE = 1.5  # a quadratic element spans this many linear ones (measured on plate and bowl)
MAX_REFINE = 16  # fine cells per coarse cell per axis, at most (r^3 children: memory)
#: ``curved_refine`` is lowered so that the fine voxel grid stays under this many cells
MAX_FINE_VOXELS = 2e7
#: a wall thinner than this fraction of the smallest bounding-box side is a thin curved wall
THIN_WALL_RATIO = 0.25
#: the facet shell applies when at least this fraction of the surface is wall (both sheets
#: paired; the rest, a rim or end faces, is left out of the model)
FACET_MIN_COVERAGE = 0.9
#: ... and when its creases cost at most this many cents (:func:`.midsurface.crease_cents`:
#: a 1 mm can of radius 40 mm, 43 c; thicker walls folded at sharp edges go to the tets)
FACET_MAX_CREASE_CENTS = 50.0

#: Quality presets. hex: elements per wavelength at the band top, least elements along the
#: longest side, fine cells per coarse cell, least cells across a bar; elements per
#: wavelength at the :data:`LOW_MODES`-th mode (``low_per_wavelength``: the lowest modes'
#: error does not grow as f_max falls; the beam's first four bending pairs are within 3
#: cents at default quality from f_max 2 to 20 kHz), and fine cells per coarse cell where
#: the surface is curved (``curved_refine``: the voxel staircase of a curved surface is
#: what limits a solid sphere, 6.5 cents at refine 3, 1.5 at 6, 0.6 at 10, same dofs).
#: wall (thin walls, quadratic tets): elements per bending wavelength at the band top and
#: least elements along the longest side, which bounds the error of the lowest modes
#: whatever f_max is.
QUALITY = {
    "draft": {"per_wavelength": 3.0, "min_per_side": 4, "refine": 2, "min_across": 2,
              "low_per_wavelength": 6.0, "curved_refine": 4,
              "wall_per_wavelength": 3.0, "wall_min_per_side": 12,
              "facet_per_wavelength": 4.0, "facet_min_per_side": 16},
    "default": {"per_wavelength": 6.0, "min_per_side": 8, "refine": 3, "min_across": 4,
                "low_per_wavelength": 13.0, "curved_refine": 8,
                "wall_per_wavelength": 5.0, "wall_min_per_side": 24,
                "facet_per_wavelength": 6.0, "facet_min_per_side": 33},
    "high": {"per_wavelength": 10.0, "min_per_side": 16, "refine": 4, "min_across": 6,
             "low_per_wavelength": 20.0, "curved_refine": 10,
             "wall_per_wavelength": 8.0, "wall_min_per_side": 48,
             "facet_per_wavelength": 10.0, "facet_min_per_side": 50},
}
QUALITY_ORDER = ("high", "default", "draft")
#: the mode (counted from the lowest, :func:`estimate_modes`) whose wavelength the
#: ``low_per_wavelength`` rule resolves
LOW_MODES = 10
#: a curved solid with at most this many hex cells along its smallest side gets the voxel
#: moments (:func:`hex_moments`)
MOMENT_MAX_CELLS = 6
#: a surface with less than this fraction of its area facing along an axis is curved
#: (the voxels approximate it by a staircase: ``curved_refine``)
ALIGNED_CURVED = 0.9


class AnalysisBudgetError(ValueError):
    """The analysis would exceed its memory cap even at draft resolution."""


def thin_wall(mesh: trimesh.Trimesh, thickness: float | None = None) -> float:
    """Wall thickness [m]: ``thickness`` if given, else ``2 V / A`` of a closed mesh
    (exact for a plate, half the side of a square bar), else nan."""
    if thickness is not None:
        return float(thickness)
    if not mesh.is_watertight:
        return float("nan")
    return float(2.0 * abs(mesh.volume) / mesh.area)


def mode_count_inputs(mesh: trimesh.Trimesh, thickness: float | None = None) -> tuple:
    """``(volume [m^3], area [m^2], wall [m], longest side [m])`` of a mesh for
    :func:`estimate_modes` (an open surface of ``thickness`` has volume ``A t``)."""
    V = abs(float(mesh.volume)) if mesh.is_watertight else 0.0
    A = float(mesh.area)
    if not mesh.is_watertight and thickness is not None:
        V = A * thickness
    return V, A, thin_wall(mesh, thickness), float(np.max(mesh.extents))


def frequency_of_mode(material: Material, volume: float, area: float, wall: float, length: float,
                      n: float, f_hi: float = 1e6) -> float:
    """Frequency [Hz] below which :func:`estimate_modes` expects ``n`` modes (bisection in
    log f between 1 Hz and ``f_hi``; ``f_hi`` when fewer are expected there)."""
    if estimate_modes(material, volume, area, wall, length, f_hi) < n:
        return float(f_hi)
    lo, hi = 1.0, float(f_hi)
    for _ in range(60):
        mid = math.sqrt(lo * hi)
        lo, hi = (mid, hi) if estimate_modes(material, volume, area, wall, length, mid) < n else (lo, mid)
    return hi


def axis_aligned_fraction(mesh: trimesh.Trimesh, along=None) -> float:
    """Fraction of the surface area whose normal points along a coordinate axis (boxes:
    1; a sphere: 0): where the voxel embedding follows the surface exactly. ``along`` (3,)
    bools: also the area whose normal is square to every axis marked (a round rod's side
    for its own axis), where refining the grid along those axes alone changes nothing."""
    n = np.abs(np.asarray(mesh.face_normals))
    area = np.asarray(mesh.area_faces)
    if len(area) == 0:
        return 1.0
    exact = n.max(axis=1) > 0.999
    if along is not None:
        exact |= np.all(n[:, np.asarray(along, bool)] < 1e-3, axis=1)
    return float(area[exact].sum() / max(area.sum(), 1e-300))


def solid_modes(material: Material, volume: float, f: float) -> float:
    """Weyl's count of a solid's modes below ``f`` [Hz] (module docstring, ``N_3D``)."""
    lam, mu = material.lame
    c_l, c_s = math.sqrt((lam + 2 * mu) / material.rho), math.sqrt(mu / material.rho)
    return 4 * math.pi / 3 * volume * f**3 * (1 / c_l**3 + 2 / c_s**3)


def estimate_modes(material: Material, volume: float, area: float, wall: float, length: float,
                   f: float) -> float:
    """Modes below ``f`` [Hz] (module docstring): the largest of the solid, thin-wall and
    bar estimates. ``volume`` [m^3], ``area`` [m^2] of the surface, ``wall`` [m] (nan:
    no wall estimate), ``length`` [m] the longest side."""
    E, nu, rho = material.E, material.nu, material.rho
    n3 = solid_modes(material, volume, f)
    n_wall = n_bar = 0.0
    if np.isfinite(wall) and wall > 0:
        D = E * wall**3 / (12 * (1 - nu**2))
        n_wall = 0.5 * area / 2 * f * math.sqrt(rho * wall / D)
    if volume > 0 and length > 0:
        S = volume / length
        n_bar = 2 * length / math.pi * ((2 * math.pi * f) ** 2 * rho * S / (E * S**2 / 12)) ** 0.25
    return float(max(n3, n_wall, n_bar))


@dataclass
class Plan:
    """What :func:`plan_analysis` decided (lengths in m, memory in GB)."""

    method: str
    order: int
    h: float
    f_max: float
    quality: str
    reason: str
    modes: float
    dofs: int
    memory_gb: float
    cap_gb: float
    through_wall: bool = True
    refine: int | None = None
    max_modes: int | None = None
    notes: list = field(default_factory=list)
    #: the mid-surface ``auto`` found when choosing the method (:func:`choose_method`), or None
    mid_surface: object = field(default=None, repr=False, compare=False)

    def info(self) -> dict:
        return {"method_choice": self.reason, "quality_used": self.quality,
                "estimate": {"modes": round(self.modes, 1), "dofs": int(self.dofs),
                             "memory_gb": round(self.memory_gb, 3), "cap_gb": self.cap_gb},
                "budget_notes": list(self.notes)}


def quality_preset(quality: str) -> dict:
    """The :data:`QUALITY` preset named ``quality``; an error naming the choices if unknown."""
    if quality not in QUALITY:
        raise ValueError(f"quality {quality!r} unknown; choose one of {', '.join(QUALITY)}")
    return QUALITY[quality]


def _bending_wavelength(material: Material, t: float, f: float) -> float:
    plate = material.E * t**2 / (12.0 * material.rho * (1.0 - material.nu**2))
    return 2 * np.pi * plate**0.25 / np.sqrt(2 * np.pi * f)


def element_size(mesh: trimesh.Trimesh, material: Material, f_max: float, quality: str = "default",
                 resolution: int | None = None, thickness: float | None = None, order: int = 1) -> float:
    r"""Hexahedral (or refined tet) element size [m]: ``min(lambda_s, lambda_b) /
    per_wavelength`` (times :data:`QUADRATIC_SIZE` for quadratic elements), at most the
    longest side over ``min_per_side``; ``lambda_s = c_s / f_max`` and ``lambda_b`` the
    bending wavelength of the wall ``t`` (:func:`thin_wall`) at ``f_max``:

    .. math:: \lambda_b = 2\pi \left(\frac{E t^2}{12 \rho (1-\nu^2)}\right)^{1/4}
              \Big/ \sqrt{2\pi f_{max}}

    and at most the bending wavelength at ``f_low`` over ``low_per_wavelength``, with
    ``f_low`` the :data:`LOW_MODES`-th mode's frequency (:func:`frequency_of_mode`) or
    ``f_max`` if lower, where the lowest modes are bending modes (Weyl's solid count,
    :func:`solid_modes`, is under half of them there: bars, plates): the lowest bending
    modes, which quadratic cells resolve worst, are resolved alike whatever ``f_max`` is (a bar's fourth bending pair, 47 cents sharp with
    the band-top rule alone at f_max = 2 kHz, is within 3 cents). Shear and longitudinal
    modes are within about a cent at the band-top rule (beam, sphere).
    """
    size = float(np.max(mesh.extents))
    if resolution is not None:
        if int(resolution) < 1:
            raise ValueError(f"resolution must be >= 1 element along the longest side, got {resolution}")
        return size / int(resolution)
    q = quality_preset(quality)
    t = thin_wall(mesh, thickness)
    if not np.isfinite(t) or t <= 0:
        t = size
    quad = QUADRATIC_SIZE if order == 2 else 1.0
    lam_s = np.sqrt(material.shear_modulus / material.rho) / f_max
    h = min(lam_s, _bending_wavelength(material, t, f_max)) / q["per_wavelength"] * quad
    V, A, _, L = mode_count_inputs(mesh, thickness)
    f_low = frequency_of_mode(material, V, A, t, L, LOW_MODES)
    if solid_modes(material, V, f_low) < 0.5 * LOW_MODES:  # the lowest modes bend (a bar, a plate)
        h = min(h, _bending_wavelength(material, t, min(f_low, f_max)) / q["low_per_wavelength"] * quad)
    return float(min(h, size / q["min_per_side"]))


def wall_element_size(mesh: trimesh.Trimesh, material: Material, f_max: float, quality: str = "default",
                      resolution: int | None = None, kind: str = "wall") -> float:
    """In-wall element size [m] of a thin wall: the bending wavelength of the wall at
    ``f_max`` over ``{kind}_per_wavelength``, at most the longest side over
    ``{kind}_min_per_side`` (the lowest modes' floor, independent of f_max). ``kind``:
    ``"wall"`` (one quadratic tet through the wall) or ``"facet"`` (the shell's longest
    mid-surface edge; the 20 cm bowl's first eight modes are within 1.8 cents at 33 per
    side, 5 .. 13 cents at 16 and 20)."""
    size = float(np.max(mesh.extents))
    if resolution is not None:
        return size / int(resolution)
    q = quality_preset(quality)
    lam_b = _bending_wavelength(material, thin_wall(mesh), f_max)
    return float(min(lam_b / q[f"{kind}_per_wavelength"], size / q[f"{kind}_min_per_side"]))


def _tet_available() -> bool:
    try:
        import tetgen  # noqa: F401
    except ImportError:
        return False
    return True


def overlapping_parts(mesh: trimesh.Trimesh) -> int:
    """How many of the mesh's closed parts may cut into another: parts whose bounding boxes
    overlap without one holding the other (a cavity inside its shell is nested, separate
    pieces are apart). A body made of several collision geoms is such a union; TetGen needs
    one surface that does not cut itself (on a union it may crash the process) and the
    mid-surface rays would pair walls of different parts, so ``auto`` gives it to the voxels,
    whose winding rule fills unions exactly."""
    if len(mesh.faces) == 0:
        return 0
    n, labels = face_components(mesh)
    if n < 2:
        return 0
    tri = mesh.triangles  # (F, 3, 3)
    lo = np.full((n, 3), np.inf)
    hi = np.full((n, 3), -np.inf)
    np.minimum.at(lo, labels, tri.min(axis=1))
    np.maximum.at(hi, labels, tri.max(axis=1))
    eps = 1e-9 * float(np.max(mesh.extents))
    meet = np.all(lo[:, None, :] < hi[None, :, :] - eps, axis=2) & np.all(lo[None, :, :] < hi[:, None, :] - eps, axis=2)
    holds = np.all(lo[:, None, :] <= lo[None, :, :], axis=2) & np.all(hi[:, None, :] >= hi[None, :, :], axis=2)
    cut = meet & ~holds & ~holds.T
    np.fill_diagonal(cut, False)
    return int(np.count_nonzero(cut.any(axis=1)))


def choose_method(mesh: trimesh.Trimesh, thickness: float | None = None) -> tuple[str, str]:
    """``("facet" | "tet-wall" | "hex", reason)`` for ``method="auto"`` (module docstring)."""
    return _choose_method(mesh, thickness)[:2]


def _choose_method(mesh: trimesh.Trimesh, thickness: float | None):
    """:func:`choose_method`'s ``(kind, reason)`` and the :class:`.midsurface.MidSurface`
    it found on the way (None where it did not look for one), passed on to the
    discretization so that it is computed once per analysis."""
    mid = None
    if not mesh.is_watertight:
        return "hex", "hex: the mesh is open or non-manifold (voxel embedding handles any surface)", mid
    k = overlapping_parts(mesh)
    if k:
        return "hex", (f"hex: a union of closed parts, {k} of which overlap another (several geoms of one "
                       "body); the voxel embedding fills unions exactly"), mid
    t = thin_wall(mesh, thickness)
    smallest = float(np.min(mesh.extents))
    if not (t < THIN_WALL_RATIO * smallest):
        return "hex", (f"hex: a solid, bar or plate (wall 2V/A = {t * 1e3:.3g} mm against its smallest side "
                       f"{smallest * 1e3:.3g} mm), where voxel hexahedra are exact in bending and fast"), mid
    from .midsurface import crease_cents, crease_thickness, mid_surface

    mid = mid_surface(mesh)
    coverage = mid.coverage
    crease = crease_cents(crease_thickness(mid.thickness), smallest) if mid.creases else 0.0
    if coverage >= FACET_MIN_COVERAGE and crease <= FACET_MAX_CREASE_CENTS:
        return "facet", (f"facet: thin curved wall ({t * 1e3:.3g} mm against a smallest side of "
                         f"{smallest * 1e3:.3g} mm), {100 * coverage:.0f} % of its surface pairs across the wall: "
                         "shell triangles on its mid-surface"), mid
    if coverage < FACET_MIN_COVERAGE:
        why = f"only {100 * coverage:.0f} % of it pairs across the wall (a shell needs {100 * FACET_MIN_COVERAGE:.0f} %)"
    else:
        why = (f"its sharp creases would leave a shell about {crease:.0f} cents flat (over "
               f"{FACET_MAX_CREASE_CENTS:.0f})")
    if not _tet_available():
        return "hex", (f"hex: thin wall ({t * 1e3:.3g} mm), but {why} and TetGen is not installed "
                       "(pip install 'mjsound[tet]'); expect the staircase error in error_estimate_cents"), mid
    return "tet-wall", (f"tet10 through the wall: thin wall ({t * 1e3:.3g} mm against a smallest side "
                        f"of {smallest * 1e3:.3g} mm), but {why}; voxels would make a staircase"), mid


def _estimate_dofs(kind: str, mesh: trimesh.Trimesh, h: float, order: int, refine: int | None,
                   thickness: float | None, quality: str) -> tuple[float, float]:
    """(dofs, extra bytes) of a discretization, from the mesh alone."""
    V = abs(float(mesh.volume)) if mesh.is_watertight else 0.0
    A = float(mesh.area)
    if kind == "tet-wall":
        # the surface refined to h: ~ A / (0.43 h^2) equilateral triangles, plus the mesh's
        # own; 18 dofs per such triangle (measured: the 20 cm bowl at h = 8.3 mm, 98 793 dofs;
        # a 2 mm walled can at 12.5 mm, 69 054)
        tris = max(len(mesh.faces), A / (0.433 * h**2) * 1.3)
        return 18.0 * tris, 0.0
    if kind == "facet":
        # the mid-surface (half the area) refined to h: ~ 1.55 A / 2 / (0.433 h^2) nodes, 6 dofs
        # each (measured: the 20 cm bowl at h = 6.06 mm, 35 718 dofs)
        nodes = max(len(mesh.vertices) / 2, 1.55 * A / 2 / (0.433 * h**2))
        return 6.0 * nodes, 0.0
    if kind == "tet":
        tets = max(V / (h**3 / 8.49), 1.5 * len(mesh.faces))
        return (6.0 if order == 2 else 1.2) * tets, 0.0
    if kind == "shell":
        return 3.0 * len(mesh.vertices), 0.0
    # hex: the lattice nodes of the grid (corners, and edge midpoints for 20-node cells),
    # times the fraction of the grid's volume the object and its surface cells fill
    from .hex import grid_for

    r = int(refine or 3)
    # a flat surface's zero extent gets the wall (or one fine voxel), as discretize_hex does
    ext = np.maximum(np.asarray(mesh.extents, float), thickness or h / r)
    bounds = np.array([np.zeros(3), ext])
    _, n, hc = grid_for(bounds, h, hex_min_cells(mesh, thickness, quality, order))
    nodes = float(np.prod(n + 1))
    if order == 2:
        nodes += sum(float(n[d] * np.prod(np.delete(n + 1, d))) for d in range(3))
    cells = float(np.prod(n))
    fill = min(1.0, (V + A * float(np.mean(hc))) / (cells * float(np.prod(hc))))
    extra = cells * r**3 * 4.0 + cells * fill * r**3 * 8.0 * 2.0  # fine grid, children
    if hex_moments(mesh, h, thickness, quality, order):  # the moments, their 7 children tables
        extra += cells * r**3 * 36.0 + 7.0 * r**3 * 1830 * 8.0
    return 3.0 * nodes * fill, extra


def hex_min_cells(mesh: trimesh.Trimesh, thickness: float | None, quality: str, order: int) -> np.ndarray:
    """Least hex cells per axis (3,): a bar or rod needs a few across its section even when
    the wavelength rule allows one (up to ``min_across``, but no cell thinner than half the
    wall); a plate's thickness axis (extent ~ t) keeps one cell: incompatible-mode cells
    bend exactly through one layer, and a second layer would add a third of the dofs.

    Quadratic cells need half of ``min_across`` (rounded up) where the surface follows the
    axes (a square bar bends exactly in two), one more where it is curved
    (:data:`ALIGNED_CURVED`): a round rod (r = 10 mm, L = 0.5 m) with two cells across its
    section rang up to +5.8 cents sharp at its fourth bending pair, with three +3.7 (its
    partly filled cells' material placed by :func:`.hex._cell_operators`' moments)."""
    t = thin_wall(mesh, thickness)
    if np.isfinite(t) and t > 0:
        across = np.where(mesh.extents > 1.5 * t, np.ceil(mesh.extents / (0.5 * t)), 1)
    else:
        across = np.ones(3)
    min_across = quality_preset(quality)["min_across"]
    if order == 2:
        min_across = (min_across + (2 if axis_aligned_fraction(mesh) < ALIGNED_CURVED else 1)) // 2
    return np.minimum(min_across, across).astype(int)


def hex_moments(mesh: trimesh.Trimesh, h: float, thickness: float | None, quality: str, order: int = 2) -> bool:
    """Whether quadratic hex cells place their surface voxels' material by its moments
    (:func:`.hex._cell_operators`): on a curved closed solid (not a thin wall) whose grid has
    at most :data:`MOMENT_MAX_CELLS` cells along its smallest side (rods, pins, handles,
    discs), where the surface voxels are a large part of the section. Counted at their
    centres they made the round rod (r = 10 mm, 3 cells across) up to 10 cents sharp in
    bending; with the moments within 4. Larger solids (the 0.1 m sphere, 8 cells across:
    0.7 cents) skip the moments' seven children tables."""
    if order != 2 or not mesh.is_watertight or axis_aligned_fraction(mesh) >= ALIGNED_CURVED:
        return False
    ext = np.asarray(mesh.extents, float)
    t = thin_wall(mesh, thickness)
    if not (np.isfinite(t) and t >= THIN_WALL_RATIO * float(ext.min())):
        return False
    d = int(np.argmin(ext))
    cells = max(int(hex_min_cells(mesh, thickness, quality, order)[d]), int(np.ceil(ext[d] / h - 1e-9)))
    return cells <= MOMENT_MAX_CELLS


def hex_refine(mesh: trimesh.Trimesh, h: float, thickness: float | None, quality: str, order: int = 2,
               moments: bool | None = None) -> int:
    """Fine voxels per coarse hex cell per axis: the quality's ``refine``, raised so that a
    fine voxel is at most a quarter of a closed mesh's wall (:func:`thin_wall`), at most
    :data:`MAX_REFINE`. A wall smeared over partly filled voxels is too thick in bending (a
    20 cm bowl with 4 mm walls rang 12 % sharp with 2.4 mm voxels and 4 % with 1 mm ones);
    an open surface is a slab of ``thickness`` and keeps the quality's value. A solid
    whose voxels' material is placed by their moments (``moments``; None:
    :func:`hex_moments`) keeps at most :data:`.hex.MOMENT_MAX_REFINE` instead.

    A curved closed surface (less than :data:`ALIGNED_CURVED` of its area facing along an
    axis) gets at least ``curved_refine``: its staircase, not the element size, limits the
    accuracy there (the 0.1 m sphere: 6.5 cents at refine 3, 1.5 at 6, 0.6 at 10, same
    dofs), as long as the fine grid stays under :data:`MAX_FINE_VOXELS`.

    A box (:func:`fills_bounding_box`) no thinner than half a fine voxel of the quality's
    ``refine`` keeps that ``refine``: the cells tile its bounding box, so every fine voxel is
    full at any refinement and no wall is smeared (the beam's model is the same bit for bit
    at 3 as at the 12 the raise gave, and its analysis 10 % faster)."""
    q = quality_preset(quality)
    r = q["refine"]
    t = thin_wall(mesh, thickness)
    if np.isfinite(t) and t > 0 and mesh.is_watertight:
        if float(np.min(mesh.extents)) >= 0.5 * h / r and fills_bounding_box(mesh):
            return r
        r = int(np.clip(np.ceil(4 * h / t), r, MAX_REFINE))
        if axis_aligned_fraction(mesh) < ALIGNED_CURVED:
            if hex_moments(mesh, h, thickness, quality, order) if moments is None else moments:
                from .hex import MOMENT_MAX_REFINE

                r = max(q["refine"], min(r, MOMENT_MAX_REFINE))
            cells = float(np.prod(np.maximum(1.0, np.ceil(np.asarray(mesh.extents, float) / h))))
            r = max(r, min(q["curved_refine"], int((MAX_FINE_VOXELS / cells) ** (1.0 / 3.0))))
    return r


def fills_bounding_box(mesh: trimesh.Trimesh) -> bool:
    """Whether a mesh is its own axis-aligned bounding box: one watertight piece, every face
    along an axis, and the box's volume (to 1e-9)."""
    if not mesh.is_watertight or axis_aligned_fraction(mesh) < 1.0:
        return False
    box = float(np.prod(mesh.extents))
    if box <= 0.0 or abs(abs(float(mesh.volume)) - box) > 1e-9 * box:
        return False
    return face_components(mesh)[0] == 1


def memory_gb(dofs: float, modes: float, extra_bytes: float = 0.0) -> float:
    """Estimated peak memory [GB] (module docstring)."""
    fill = max(1.0, dofs / 1e5) ** (1.0 / 3.0)
    return float((MEMORY_PER_DOF * dofs * fill + 48.0 * modes * dofs + extra_bytes) / 1e9)


def plan_analysis(mesh: trimesh.Trimesh, material: Material, f_max: float, *, method: str = "auto",
                  quality: str = "default", resolution: int | None = None, thickness: float | None = None,
                  order: int = 2, refine: int | None = None, max_modes: int | None = None,
                  max_memory: float | None = None, over_budget: str = "coarsen") -> Plan:
    """Method, element size and cost of an analysis, within the memory cap.

    Parameters
    ----------
    mesh, material, f_max, method, quality, resolution, thickness, order, refine
        As for :func:`mjsound.analyze` (``f_max`` already limited by damping).
    max_modes : int, optional
        The band is first narrowed to where about ``2 max_modes + 10`` modes are expected
        (:func:`estimate_modes`), so neither the mesh nor the solve is sized for modes
        that would be dropped.
    max_memory : float, optional
        Cap on the estimated peak memory [GB] (:func:`max_memory_gb` resolves None).
    over_budget : {'coarsen', 'refuse'}
        Over the cap: coarsen to the next quality's element size (down to draft) with a
        warning, or refuse at once.

    Raises
    ------
    AnalysisBudgetError
        Over the cap even at draft resolution (or at once with ``'refuse'``); the message
        gives the estimate and the options (a larger ``max_memory_gb``, a lower ``f_max``,
        ``max_modes``, ``quality='draft'``).
    """
    if over_budget not in ("coarsen", "refuse"):
        raise ValueError(f"over_budget={over_budget!r}: choose 'coarsen' or 'refuse'")
    cap = max_memory_gb(max_memory)
    notes = []
    V, A, t, L = mode_count_inputs(mesh, thickness)
    if max_modes is not None:
        want = 2 * int(max_modes) + 10
        if estimate_modes(material, V, A, t, L, f_max) > want:
            hi = frequency_of_mode(material, V, A, t, L, want, f_max)
            notes.append(f"band narrowed from {f_max:.0f} Hz to {hi:.0f} Hz, where about {want} modes are "
                         f"expected (max_modes={max_modes})")
            f_max = max(hi, 40.0)
    if method == "auto":
        kind, reason, mid = _choose_method(mesh, thickness)
    else:
        kind, reason, mid = method, f"{method}: asked for", None
    modes = estimate_modes(material, V, A, t, L, f_max)
    if max_modes is not None:
        modes = min(modes, 2 * max_modes + 10)
    qualities = QUALITY_ORDER[QUALITY_ORDER.index(quality):] if resolution is None else (quality,)
    tried = []
    for q in qualities:
        if kind == "tet-wall":
            h = wall_element_size(mesh, material, f_max, q, resolution)
        elif kind == "facet":
            h = wall_element_size(mesh, material, f_max, q, resolution, kind="facet")
        else:
            h = element_size(mesh, material, f_max, q, resolution, thickness, order if kind != "shell" else 1)
        r = hex_refine(mesh, h, thickness, q, order) if kind == "hex" and refine is None else refine
        dofs, extra = _estimate_dofs(kind, mesh, h, order, r, thickness, q)
        mem = memory_gb(dofs, modes, extra)
        tried.append((q, dofs, mem))
        if mem <= cap:
            if q != quality:
                msg = (f"analysis: quality={quality!r} would need about {tried[0][1]:.3g} dofs and "
                       f"{tried[0][2]:.3g} GB, over the cap of {cap:g} GB (max_memory_gb / ${MAX_MEMORY_ENV}); "
                       f"using quality={q!r}'s resolution ({dofs:.3g} dofs, {mem:.3g} GB): expect a larger error")
                warnings.warn(msg, RuntimeWarning, stacklevel=user_stacklevel())
                notes.append(msg)
            return Plan(method="tet" if kind == "tet-wall" else kind, order=order if kind not in ("shell", "facet") else 1, h=h,
                        f_max=f_max, quality=q, reason=reason, modes=modes, dofs=int(dofs), memory_gb=mem,
                        cap_gb=cap, through_wall=kind != "tet-wall", refine=r, max_modes=max_modes,
                        notes=notes, mid_surface=mid)
        if over_budget == "refuse":
            break
    q, dofs, mem = tried[-1]
    if kind in ("tet-wall", "facet"):  # the thin-wall method does not fit: the voxels may
        plan = plan_analysis(mesh, material, f_max, method="hex", quality=quality, resolution=resolution,
                             thickness=thickness, order=order, refine=refine, max_modes=max_modes,
                             max_memory=max_memory, over_budget=over_budget)
        what = "quadratic tets through it" if kind == "tet-wall" else "shell triangles on its mid-surface"
        plan.reason = (f"hex: thin wall, but {what} would need about {dofs:.3g} dofs and "
                       f"{mem:.3g} GB, over the cap of {cap:g} GB")
        plan.notes = notes + plan.notes
        return plan
    raise AnalysisBudgetError(
        f"analysis of this mesh ({L:.3g} m, {kind}) to f_max={f_max:.0f} Hz would need about {dofs:.3g} dofs, "
        f"{modes:.3g} modes and {mem:.3g} GB at quality={q!r}, over the cap of {cap:g} GB. Options: raise "
        f"max_memory_gb (or ${MAX_MEMORY_ENV}), lower f_max, give max_modes=N (the band is then sized for N "
        f"modes), or quality='draft'"
    )
