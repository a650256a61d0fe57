r"""`analyze`: surface mesh + material -> :class:`ModalModel`, with a disk cache.

Steps: load and clean the mesh, pick surface sample points, choose the element size
from the shortest wavelength ``f_max`` needs, discretize (hex | tet | shell), solve
``K phi = lambda M phi`` for ``20 Hz <= f <= f_max``, drop rigid and overdamped modes,
sample the mass-normalised shapes at the surface points, estimate radiation, and
estimate the frequency error from a coarser solve.

Element size
------------
Two wavelengths matter at ``f_max``: the shear wave ``lambda_s = c_s / f_max`` with
``c_s = sqrt(G / rho)``, and the bending wave of the thinnest wall,

.. math:: \lambda_b = 2\pi \left(\frac{E t^2}{12 \rho (1-\nu^2)}\right)^{1/4}
          \Big/ \sqrt{2\pi f_{max}},

with the wall thickness estimated as ``t = 2 V / A`` (exact for a plate, half the side
of a square bar) or given for open surfaces. The quality preset sets elements per
wavelength and a minimum count along the longest side:

=========  ======================  ==================  =============  ============
quality    elements / wavelength   min. along longest  hex refine r   min. across
=========  ======================  ==================  =============  ============
draft      3                       4                   2              2
default    6                       8                   3              4
high       10                      16                  4              6
=========  ======================  ==================  =============  ============

"min. across" is the least number of hex cells along each axis, capped so that no
cell is thinner than half the wall; a plate's thickness axis keeps one cell.

Radiation
---------
Each mode's far-field pressure at 1 m per unit modal coordinate uses the compact
monopole ``Q_i = sum_p a_p (phi_i(x_p) . n_p)`` and dipole ``D_i = sum_p a_p (x_p - c)
(phi_i(x_p) . n_p)`` of the surface displacement:

.. math:: R_i = \frac{\rho_0 \omega_i^2}{4\pi}\sqrt{Q_i^2 + (k_i |D_i|)^2 / 3},
          \quad k_i = \omega_i / c_0

(the dipole term averaged over directions), with air at ``rho_0 = 1.2 kg/m^3``,
``c_0 = 343 m/s``, capped at full radiation efficiency
``rho_0 c_0 omega sqrt(A_eff / 4 pi)``, ``A_eff = sum_p a_p (phi_i . n_p)^2``, for modes
whose wavelength is shorter than the object (where the compact estimate overshoots).
"""

from __future__ import annotations

import hashlib
import os
import time
import warnings

import numpy as np
import trimesh

from ..geometry import load_mesh, mesh_digest
from ..materials import Material, parse_material
from .discretization import Discretization
from .eigen import solve_band
from .model import ModalModel

__all__ = ["analyze", "element_size", "QUALITY", "cache_dir", "F_MIN_HZ", "default_f_max"]

F_MIN_HZ = 20.0
AIR_DENSITY = 1.2
SPEED_OF_SOUND = 343.0
QUADRATIC_SIZE = 1.5  # a quadratic element spans this many linear ones (measured on plate and bowl)
MAX_REFINE = 16  # fine cells per coarse cell per axis, at most (r^3 children: memory)
MODEL_VERSION = 10  # bump when discretization or model contents change (invalidates cache)

QUALITY = {
    "draft": {"per_wavelength": 3.0, "min_per_side": 4, "refine": 2, "min_across": 2},
    "default": {"per_wavelength": 6.0, "min_per_side": 8, "refine": 3, "min_across": 4},
    "high": {"per_wavelength": 10.0, "min_per_side": 16, "refine": 4, "min_across": 6},
}
METHODS = ("hex", "tet", "shell")


def default_f_max(sample_rate: float | None = None) -> float:
    """min(20 kHz, 0.45 fs) [Hz]."""
    return 20000.0 if sample_rate is None else min(20000.0, 0.45 * float(sample_rate))


#: Modes whose quality factor omega / (2 d) falls below this ring for less than a cycle:
#: the analysis stops at the frequency where Rayleigh damping reaches it.
MIN_Q = 2.0


def ringing_below(material: Material, q_min: float = MIN_Q) -> float:
    """Frequency [Hz] above which Rayleigh damping leaves every mode a quality factor < q_min.

    ``d = (alpha + beta w^2) / 2 = w / (2 Q)`` at ``w = (1/Q + sqrt(1/Q^2 - 4 alpha beta)) / (2 beta)``;
    inf without stiffness damping, 0 when no frequency reaches ``q_min``.
    """
    a, b = material.alpha, material.beta
    if b <= 0:
        return float("inf")
    disc = 1.0 / q_min**2 - 4 * a * b
    if disc < 0:
        return 0.0
    return float((1.0 / q_min + np.sqrt(disc)) / (2 * b) / (2 * np.pi))


def cache_dir() -> str:
    """``$MJSOUND_CACHE_DIR`` or the platform user cache dir (``~/.cache/mjsound``)."""
    env = os.environ.get("MJSOUND_CACHE_DIR")
    if env:
        return env
    import platformdirs

    return platformdirs.user_cache_dir("mjsound")


def wall_thickness(mesh: trimesh.Trimesh) -> float:
    """Thin-wall estimate ``2 V / A`` [m] of a closed mesh (nan if open)."""
    if not mesh.is_watertight:
        return float("nan")
    return float(2.0 * abs(mesh.volume) / mesh.area)


def element_size(mesh: trimesh.Trimesh, material: Material, f_max: float, quality: str = "default",
                 resolution: int | None = None, thickness: float | None = None, order: int = 1) -> float:
    """Target element size [m] (see the module docstring); quadratic elements (``order=2``)
    may be ``QUADRATIC_SIZE`` times larger for the same waves."""
    size = float(np.max(mesh.extents))
    if resolution is not None:
        if int(resolution) < 1:
            raise ValueError(f"resolution must be >= 1 element along the longest side, got {resolution}")
        return size / int(resolution)
    q = _quality(quality)
    lam_s = np.sqrt(material.shear_modulus / material.rho) / f_max
    t = thickness if thickness is not None else wall_thickness(mesh)
    if not np.isfinite(t) or t <= 0:
        t = size
    plate = material.E * t**2 / (12.0 * material.rho * (1.0 - material.nu**2))
    lam_b = 2 * np.pi * plate**0.25 / np.sqrt(2 * np.pi * f_max)
    h = min(lam_s, lam_b) / q["per_wavelength"] * (QUADRATIC_SIZE if order == 2 else 1.0)
    return float(min(h, size / q["min_per_side"]))


def _quality(quality: str) -> dict:
    if quality not in QUALITY:
        raise ValueError(f"quality {quality!r} unknown; choose one of {', '.join(QUALITY)}")
    return QUALITY[quality]


def surface_samples(mesh: trimesh.Trimesh, n_points: int = 1024):
    """Deterministic surface points (vertices first, then even samples) and normals."""
    V = np.asarray(mesh.vertices)
    N = np.asarray(mesh.vertex_normals)
    if len(V) >= n_points:
        idx = np.random.default_rng(0).choice(len(V), n_points, replace=False)
        idx.sort()
        return V[idx], N[idx]
    extra = n_points - len(V)
    pts, fid = trimesh.sample.sample_surface(mesh, extra, seed=0)
    return np.vstack([V, pts]), np.vstack([N, mesh.face_normals[fid]])


def _discretize(method, mesh, material, h, points, quality, thickness, order, refine) -> Discretization:
    if method == "hex":
        from .hex import discretize_hex

        # A bar or rod needs a few cells across its section even when the wavelength rule
        # allows one: up to `min_across`, but cells no thinner than half the wall.
        t = wall_thickness(mesh) if thickness is None else thickness
        # A plate's thickness axis (extent ~ t) keeps one cell: incompatible-mode cells bend
        # exactly through one layer, and a second layer would add a third of the dofs.
        if np.isfinite(t) and t > 0:
            across = np.where(mesh.extents > 1.5 * t, np.ceil(mesh.extents / (0.5 * t)), 1)
        else:
            across = np.ones(3)
        min_across = _quality(quality)["min_across"]
        if order == 2:
            min_across = (min_across + 1) // 2
        min_cells = np.minimum(min_across, across).astype(int)
        if refine is None:
            # Fine voxels of at most a quarter of the wall: a wall smeared over partly
            # filled voxels is too thick in bending (a 20 cm bowl with 4 mm walls rang 12 %
            # sharp with 2.4 mm voxels and 4 % with 1 mm ones).
            refine = _quality(quality)["refine"]
            if np.isfinite(t) and t > 0 and mesh.is_watertight:  # open surfaces are slabs of t
                refine = int(np.clip(np.ceil(4 * h / t), refine, MAX_REFINE))
        return discretize_hex(mesh, material, h, points, refine=refine, thickness=thickness, min_cells=min_cells,
                              order=order)
    if method == "tet":
        from .tet import discretize_tet

        return discretize_tet(mesh, material, h, points, order=order)
    if method == "shell":
        from .shell import discretize_shell

        t = thickness if thickness is not None else wall_thickness(mesh)
        if not np.isfinite(t):
            raise ValueError("shell: an open mesh needs thickness=... (wall thickness in metres)")
        return discretize_shell(mesh, material, points, thickness=t)
    raise ValueError(f"method {method!r} unknown; choose one of {', '.join(METHODS)}")


def _solve(disc: Discretization, f_max: float, progress: bool, max_modes=None):
    lam_min = (2 * np.pi * F_MIN_HZ) ** 2
    lam_max = (2 * np.pi * f_max) ** 2
    bar = None
    cb = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=100, desc=f"modes to {f_max / 1000:.1f} kHz ({disc.dofs} dofs)", unit="%", leave=False)

        def cb(frac):
            bar.n = int(round(100 * frac))
            bar.refresh()

    try:
        return solve_band(disc.K, disc.M, lam_min, lam_max, progress=cb, max_modes=max_modes)
    finally:
        if bar is not None:
            bar.close()


def analyze(
    mesh,
    material,
    method: str = "hex",
    quality: str = "default",
    f_max: float | None = None,
    *,
    sample_rate: float | None = None,
    resolution: int | None = None,
    thickness: float | None = None,
    order: int = 2,
    refine: int | None = None,
    n_points: int = 1024,
    max_modes: int | None = None,
    error_estimate: bool = True,
    cache: bool = True,
    progress: bool = False,
) -> ModalModel:
    """Modal model of a mesh made of a material.

    Parameters
    ----------
    mesh : path | built-in spec | (vertices, faces) | trimesh.Trimesh
        Surface in metres (see :func:`mjsound.geometry.load_mesh`), e.g. ``"box:0.5,0.01,0.01"``.
    material : str | Material | dict
        Named (``"aluminium"``) or inline (``"E=70e9,nu=0.33,rho=2700"``).
    method : {'hex', 'tet', 'shell'}
        Voxel-embedded hexahedra (default, any mesh), tetrahedra (watertight meshes;
        ``order`` 1 or 2) or Raghuvanshi's spring-mass shell (cheap, approximate).
    quality : {'draft', 'default', 'high'}
        Elements per wavelength at ``f_max`` (module docstring).
    f_max : float, optional
        Highest frequency [Hz]; default ``min(20 kHz, 0.45 sample_rate)``.
    sample_rate : float, optional
        Output sample rate [Hz]; ``f_max`` must stay below its Nyquist frequency.
    resolution : int, optional
        Elements along the longest side, overriding ``quality``.
    thickness : float, optional
        Wall thickness [m] for open surfaces (hex) and the shell model.
    order : {1, 2}
        Element order for hex (20-node serendipity cells by default; 1 = 8-node cells with
        condensed bubbles) and tet (10-node by default; 1 = 4-node, which locks).
    refine : int, optional
        Hex fine cells per coarse cell per axis (default from ``quality``).
    n_points : int
        Surface sample points of the sound map.
    max_modes : int, optional
        Keep at most this many (lowest) modes.
    error_estimate : bool
        Also solve at 1.5x coarser elements and report the estimated error in cents.
    cache : bool
        Read/write the disk cache (:func:`cache_dir`); corrupt entries are recomputed.
    progress : bool
        Show a progress bar during the eigen solve.

    Returns
    -------
    ModalModel

    Examples
    --------
    >>> m = analyze("box:0.5,0.01,0.01", "aluminium", f_max=2000, cache=False)  # doctest: +SKIP
    >>> m.frequencies_hz[:2].round()  # doctest: +SKIP
    array([209., 209.])
    """
    material = parse_material(material)
    if method not in METHODS:
        raise ValueError(f"method {method!r} unknown; choose one of {', '.join(METHODS)}")
    _quality(quality)
    if sample_rate is not None:
        sample_rate = float(sample_rate)
        if not np.isfinite(sample_rate) or sample_rate < 1000 or sample_rate > 768000:
            raise ValueError(f"sample_rate={sample_rate} Hz is not a plausible audio rate (1 kHz .. 768 kHz)")
    if f_max is None:
        f_max = default_f_max(sample_rate)
    f_max = float(f_max)
    if not np.isfinite(f_max) or f_max <= F_MIN_HZ:
        raise ValueError(f"f_max={f_max} Hz must be finite and above {F_MIN_HZ} Hz")
    if sample_rate is not None and f_max >= 0.5 * sample_rate:
        raise ValueError(
            f"f_max={f_max:g} Hz is at or above the Nyquist frequency of sample_rate={sample_rate:g} Hz; "
            f"use f_max <= {0.45 * sample_rate:g} Hz or leave it unset"
        )
    if order not in (1, 2):
        raise ValueError(f"order must be 1 or 2, got {order}")
    if thickness is not None and not (np.isfinite(thickness) and thickness > 0):
        raise ValueError(f"thickness={thickness} must be a positive length in metres")

    tm = load_mesh(mesh)
    # Modes above the frequency where Rayleigh damping leaves them less than a cycle of
    # ringing (Q < MIN_Q; overdamped a little higher) make a thud, not a tone: neither the
    # mesh nor the solve is sized for them (rubber: 0.7 kHz instead of 20 kHz shear waves,
    # ~100 modes instead of millions of dofs).
    f_ring = ringing_below(material)
    if f_ring < f_max:
        f_max = max(f_ring, 2 * F_MIN_HZ)
    h = element_size(tm, material, f_max, quality, resolution, thickness, order if method != "shell" else 1)
    params = dict(method=method, h=h, f_max=f_max, thickness=thickness, order=order, refine=refine, n_points=n_points, max_modes=max_modes,
                  error_estimate=error_estimate, version=MODEL_VERSION)
    key = hashlib.sha256((mesh_digest(tm) + material.key() + repr(sorted(params.items()))).encode()).hexdigest()[:40]
    path = os.path.join(cache_dir(), f"{key}.npz")
    if cache and os.path.exists(path):
        try:
            return ModalModel.load(path)
        except ValueError as exc:
            warnings.warn(f"cache entry {path} is corrupt ({exc}); recomputing", stacklevel=2)

    t0 = time.perf_counter()
    points, normals = surface_samples(tm, n_points)
    disc = _discretize(method, tm, material, h, points, quality, thickness, order, refine)
    # The error estimate's coarser discretization does not depend on the solve: it is built
    # on the second core meanwhile (the Lanczos iteration runs on one).
    pool = coarse = None
    if error_estimate and method != "shell":
        from concurrent.futures import ThreadPoolExecutor

        pool = ThreadPoolExecutor(1)
        coarse = pool.submit(_discretize, method, tm, material, 1.5 * h, points, quality, thickness, order, refine)
    try:
        sol = _solve(disc, f_max, progress, max_modes)
    except BaseException:
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)
        raise
    lam = np.maximum(sol.eigenvalues, 0.0)
    omega = np.sqrt(lam)
    shapes = (disc.interp @ sol.vectors).reshape(len(points), 3, -1)
    radiation = _radiation(points, normals, shapes, omega, float(tm.area))
    # Rayleigh damping d = (alpha + beta omega^2) / 2 plus what radiation takes away;
    # overdamped modes (d >= omega) make no tone and are dropped
    decay = 0.5 * (material.alpha + material.beta * omega**2) + radiation_damping(radiation, omega)
    under = decay < omega
    shapes, radiation, decay = shapes[:, :, under], radiation[under], decay[under]
    ex = np.zeros(disc.dofs)
    ex[0::3] = 1.0  # rigid translation along x: e^T M e is the total mass
    mass = float(ex @ (disc.M @ ex))
    info = dict(disc.info)
    info.update(
        h_target=h, f_max=f_max, quality=quality if resolution is None else f"resolution={resolution}",
        solver=sol.backend, slices=sol.n_slices, n_rigid=int(sol.n_below), n_overdamped=int((~under).sum()),
        solve_seconds=sol.seconds, size_m=float(np.max(tm.extents)), area_m2=float(tm.area),
        ringing_limit_hz=f_ring,
        watertight=bool(tm.is_watertight),
    )
    err = float("nan")
    # the shell model has no resolution to vary (it lives on the given surface mesh)
    if error_estimate and under.sum() > 0 and method != "shell":
        err = _error_estimate(method, tm, material, h, points, quality, thickness, order, refine,
                              omega[under] / (2 * np.pi), coarse=coarse)
    if pool is not None:
        pool.shutdown(wait=True, cancel_futures=True)
    model = ModalModel(
        frequencies_hz=omega[under] / (2 * np.pi),
        decay_per_s=decay,
        points=points,
        normals=normals,
        shapes=shapes,
        radiation=radiation,
        material=material,
        method=method if method != "tet" else f"tet{4 if order == 1 else 10}",
        dofs=disc.dofs,
        seconds=time.perf_counter() - t0,
        error_estimate_cents=err,
        mass_kg=mass,
        info=info,
    )
    if cache:
        try:
            model.save(path)
        except OSError as exc:
            warnings.warn(f"could not write cache entry {path}: {exc}", stacklevel=2)
    return model


def _radiation(points, normals, shapes, omega, area):
    """Per-mode far-field pressure at 1 m per unit modal coordinate (module docstring).

    The compact (k a << 1) monopole + dipole estimate grows as ``omega^3 |D|`` without
    bound, so for modes whose wavelength is shorter than the object it would radiate more
    power than the surface can emit. A surface radiates at most with efficiency 1,
    ``W = rho0 c <v_n^2> A``, which at 1 m is ``R_max = rho0 c omega sqrt(A_eff / 4 pi)``
    with ``A_eff = sum_p a_p (phi . n)^2``: the weight is the smaller of the two.

    The radiated power is energy the mode loses: see :func:`radiation_damping`.
    """
    if shapes.shape[2] == 0:
        return np.zeros(0)
    a = area / len(points)
    un = np.einsum("pcn,pc->pn", shapes.astype(np.float64), normals)  # normal displacement
    Q = a * un.sum(axis=0)
    x = points - points.mean(axis=0)
    D = a * np.einsum("pc,pn->cn", x, un)
    k = omega / SPEED_OF_SOUND
    compact = AIR_DENSITY * omega**2 / (4 * np.pi) * np.sqrt(Q**2 + (k * np.linalg.norm(D, axis=0)) ** 2 / 3.0)
    r_max = AIR_DENSITY * SPEED_OF_SOUND * omega * np.sqrt(a * np.einsum("pn,pn->n", un, un) / (4 * np.pi))
    return np.minimum(compact, r_max)


def radiation_damping(radiation, omega):
    """Decay rate [1/s] a mode gets from the sound it radiates.

    A mode of amplitude q holds ``E = omega^2 q^2 / 2`` and radiates
    ``W = 4 pi (R q)^2 / (2 rho0 c)`` (pressure amplitude ``R q`` at 1 m over a sphere),
    so its energy decays at ``W / E = 2 d_rad`` with ``d_rad = 2 pi R^2 / (rho0 c omega^2)``.
    Adding it to the Rayleigh decay keeps every mode from radiating more energy than it
    loses (lightly damped thin plates above coincidence get tens of 1/s from this alone),
    and a material without structural damping still rings down.
    """
    return 2 * np.pi * np.asarray(radiation) ** 2 / (AIR_DENSITY * SPEED_OF_SOUND * np.asarray(omega) ** 2)


def _error_estimate(method, tm, material, h, points, quality, thickness, order, refine, f_fine, n=10,
                    coarse=None):
    """Richardson-style error [cents] of the first ``n`` modes from a solve at 1.5 h.

    With second-order convergence f(h) = f* + C h^2, the fine solve's error is
    ``(f(h) - f(1.5 h)) / (1.5^2 - 1)``; the RMS over the first modes is returned.
    ``coarse``: a future of the 1.5 h discretization, when already under way.
    """
    try:
        if coarse is not None:
            disc = coarse.result()
        else:
            disc = _discretize(method, tm, material, 1.5 * h, points, quality, thickness, order, refine)
        f_hi = float(f_fine[min(n, len(f_fine)) - 1]) * 1.3
        sol = _solve(disc, max(f_hi, 2 * F_MIN_HZ), False)
    except Exception:  # an estimate must never break the analysis itself
        return float("nan")
    f_coarse = np.sqrt(np.maximum(sol.eigenvalues, 0)) / (2 * np.pi)
    m = min(n, len(f_fine), len(f_coarse))
    if m == 0:
        return float("nan")
    cents = 1200 * np.log2(f_coarse[:m] / f_fine[:m])
    return float(np.sqrt(np.mean(cents**2)) / (1.5**2 - 1))
