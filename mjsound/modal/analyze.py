r"""`analyze`: surface mesh + material -> :class:`ModalModel`, with a disk cache.

Steps: load and clean the mesh, pick surface sample points, choose the element size
from the shortest wavelength ``f_max`` needs, discretize (hex | tet | shell), solve
``K phi = lambda M phi`` for ``20 Hz <= f <= f_max``, drop rigid and overdamped modes,
sample the mass-normalised shapes at the surface points, estimate radiation, and
estimate the frequency error from a coarser solve (:mod:`.error_estimate`).

Method, element size and budget
-------------------------------
:func:`.plan.plan_analysis` decides from the mesh alone, before anything is built:
the method (``method="auto"``: shell triangles on the mid-surface of thin walls, or
quadratic tets through them where a shell would not do, voxel hexahedra otherwise), the element size (from the shortest wavelength at ``f_max``,
with a floor per side that bounds the lowest modes' error), and the estimated modes,
dofs and peak memory, kept under ``max_memory_gb`` (default 8 GB, or
``$MJSOUND_MAX_MEMORY_GB``) by coarsening or a refusal that names the numbers.

Hollow objects: ``wall=`` (or a material's ``wall``, ``"aluminium,wall=0.12mm"``) turns a
closed outer surface into a wall of that thickness inside it and an open surface into
a wall of exactly that thickness (:func:`.surface.hollow`) before the analysis.

Radiation
---------
Each mode's far-field pressure at 1 m per unit modal coordinate, by direction, comes from an
exterior boundary-element solve on the object's outer surface (:mod:`.radiation`, :mod:`.bem`;
``radiation=`` sets its accuracy) and is stored as spherical-harmonic coefficients
(``ModalModel.radiation_sh``, read with ``ModalModel.radiation_pattern``); ``radiation`` is its
RMS over directions. Every mode's pattern is capped at radiation efficiency 1 where it is
made (:mod:`.radiation_bound`; ``info['radiation']['capped_db']`` says by how much, and a
capped mode's ``error_db`` is at least that), so the pattern, ``radiation`` and the radiation
damping in ``decay_per_s`` agree. Where the outer surface is not closed (or ``radiation=False``), the compact
monopole ``Q_i = sum_p a_p (phi_i(x_p) . n_p)`` and dipole ``D_i = sum_p a_p (x_p - c)
(phi_i(x_p) . n_p)`` of the surface displacement stand in:

.. math:: R_i = \frac{\rho_0 \omega_i^2}{4\pi}\sqrt{Q_i^2 + (k_i |D_i|)^2 / 3},
          \quad k_i = \omega_i / c_0

(the dipole term averaged over directions), with air at ``rho_0 = 1.2 kg/m^3``,
``c_0 = 343 m/s``, capped at full radiation efficiency
``rho_0 c_0 omega sqrt(A_eff / 4 pi)``, ``A_eff = sum_p a_p (phi_i . n_p)^2``: measured
-26 .. +48 dB off the boundary elements (docs/radiation.md).
"""

from __future__ import annotations

import hashlib
import os
import time
import warnings
from functools import partial

import numpy as np
import trimesh

from ..geometry import load_mesh, mesh_digest
from ..materials import Material, parse_material, parse_length
from .band import F_MIN_HZ, MIN_Q, default_f_max, ringing_below  # noqa: F401 (re-exported)
from .cache import cache_dir
from .discretization import Discretization
from .eigen import solve_modes
from .error_estimate import (FACET_DRAFT_ERROR_ORDER, FACET_ERROR_ORDER, HEX_STAIRCASE_ERROR_ORDER,  # noqa: F401
                             coarse_ratio, convergence_order, facet_error_order, hex_coarsening, hex_error_order,
                             richardson_error)
from .model import ModalModel
from .radiation import radiation_damping  # noqa: F401 (re-exported)
from .radiation_bound import cap_radiation, efficiency_limit
from .plan import (QUALITY, AnalysisBudgetError, Plan, element_size, hex_min_cells, hex_moments, hex_refine,
                   plan_analysis, quality_preset, thin_wall)
from ..user_frame import user_stacklevel

__all__ = ["analyze", "element_size", "QUALITY", "cache_dir", "F_MIN_HZ", "default_f_max", "AnalysisBudgetError"]

AIR_DENSITY = 1.2
SPEED_OF_SOUND = 343.0
MODEL_VERSION = 23  # bump when discretization or model contents change (invalidates cache)
METHODS = ("auto", "hex", "tet", "facet", "shell")


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


def _discretize(method, mesh, material, h, points, quality, thickness, order, refine,
                through_wall=True, mid=None, moments=None) -> Discretization:
    if method == "hex":
        from .hex import discretize_hex

        # the error estimate's coarser solve takes the fine one's moments (the same method)
        if moments is None:
            moments = hex_moments(mesh, h, thickness, quality, order)
        min_cells = hex_min_cells(mesh, thickness, quality, order)
        if refine is None:
            refine = hex_refine(mesh, h, thickness, quality, order, moments)
        return discretize_hex(mesh, material, h, points, refine=refine, thickness=thickness, min_cells=min_cells,
                              order=order, moments=moments)
    if method == "tet":
        from .tet import discretize_tet

        return discretize_tet(mesh, material, h, points, order=order, through_wall=through_wall)
    if method == "facet":
        from .facet_shell import discretize_facet
        from .midsurface import mid_surface

        if mid is None:  # the plan's, when auto chose the method
            mid = mid_surface(mesh)
        if len(mid.faces) == 0:
            raise ValueError("facet: no part of this surface is a thin wall (two sheets facing each other); "
                             "use method='auto', 'hex' or 'tet'")
        from .midsurface import crease_thickness

        disc = discretize_facet(mid.vertices, mid.faces, mid.thickness, material, points, h=h)
        disc.info["crease_edges"] = mid.creases
        disc.info["crease_thickness"] = crease_thickness(mid.thickness)
        return disc
    if method == "shell":
        from .shell import discretize_shell

        t = thin_wall(mesh, thickness)
        if not np.isfinite(t):
            raise ValueError("shell: an open mesh needs thickness=... (wall thickness in metres)")
        return discretize_shell(mesh, material, points, thickness=t)
    raise ValueError(f"method {method!r} unknown; choose one of {', '.join(METHODS)}")


def analyze(
    mesh,
    material,
    method: str = "auto",
    quality: str = "default",
    f_max: float | None = None,
    *,
    sample_rate: float | None = None,
    resolution: int | None = None,
    thickness: float | None = None,
    wall=None,
    order: int = 2,
    refine: int | None = None,
    n_points: int = 1024,
    max_modes: int | None = None,
    max_memory_gb: float | None = None,
    over_budget: str = "coarsen",
    error_estimate: bool = True,
    radiation=None,
    cache: bool = True,
    progress: bool = False,
) -> ModalModel:
    """Modal model of a mesh made of a material.

    Parameters
    ----------
    mesh : path | built-in spec | (vertices, faces) | trimesh.Trimesh
        Surface in metres (see :func:`mjsound.geometry.load_mesh`), e.g. ``"box:0.5,0.01,0.01"``.
    material : str | Material | dict
        Named (``"aluminium"``) or inline (``"E=70e9,nu=0.33,rho=2700"``,
        ``"aluminium,wall=0.12mm"``).
    method : {'auto', 'hex', 'tet', 'facet', 'shell'}
        ``auto`` (default) picks per object (:mod:`.plan`; the reason is in
        ``info["method_choice"]``): shell triangles on the mid-surface of thin walls
        (``facet``: bowls, cans, tubes, hollow objects), quadratic tets with one element
        through a thin wall a shell would not fit (sharp creases; needs TetGen), voxel-embedded
        hexahedra otherwise (any mesh: open, non-manifold, self-intersecting). ``hex``,
        ``tet`` (watertight meshes, volume refined; ``order`` 1 or 2) and ``shell``
        (Raghuvanshi's spring-mass surface: cheap, approximate) force one.
    quality : {'draft', 'default', 'high'}
        Elements per wavelength at ``f_max`` and per side of the object (:mod:`.plan`).
    f_max : float, optional
        Highest frequency [Hz]; default ``min(20 kHz, 0.45 sample_rate)``.
    sample_rate : float, optional
        Output sample rate [Hz]; ``f_max`` must stay below its Nyquist frequency.
    resolution : int, optional
        Elements along the longest side, overriding ``quality``.
    thickness : float, optional
        Wall thickness [m] that an open surface stands for (hex slab, shell model).
    wall : float | str, optional
        Make the object hollow: a closed surface becomes a wall of this thickness inside
        it, an open surface a wall of exactly this thickness (mass and frequencies
        follow). Metres, or a length with a unit (``"0.12mm"``). Default: the
        material's ``wall`` (None: solid).
    order : {1, 2}
        Element order for hex (20-node serendipity cells by default; 1 = 8-node cells with
        condensed bubbles) and tet (10-node by default; 1 = 4-node, which locks).
    refine : int, optional
        Hex fine cells per coarse cell per axis (default from ``quality``).
    n_points : int
        Surface sample points of the sound map.
    max_modes : int, optional
        Keep at most this many (lowest) modes. Applied *before* the solve: the band (and
        with it the mesh) is narrowed to where about ``2 max_modes + 10`` modes are
        expected, so a scene can budget large objects (floors, tables) cheaply. Fewer
        than ``max_modes`` may come back when the object has fewer modes there than
        the estimate (``info["estimate"]``, ``info["f_max"]``).
    max_memory_gb : float, optional
        Cap on the estimated peak memory [GB] of this analysis (estimated from the mesh
        before anything is built). Default ``$MJSOUND_MAX_MEMORY_GB`` or 8 GB.
    over_budget : {'coarsen', 'refuse'}
        Over the cap: ``coarsen`` (default) lowers the resolution, at most to
        ``quality='draft'``'s, with a RuntimeWarning and a note in
        ``info["budget_notes"]``; ``refuse`` raises at once. Either raises
        :class:`AnalysisBudgetError` (a ValueError) with the estimate and the options
        when even draft does not fit.
    radiation : {None, 'draft', 'default', 'high'} | dict | False
        Accuracy of each mode's acoustic transfer (:mod:`.radiation`): None follows
        ``quality``; a dict overrides :data:`.radiation.RADIATION_QUALITY`'s settings
        (``epw``, ``n_max``, ``dka``, ``max_solves``, ``degree``); False keeps the compact
        monopole + dipole estimate (no boundary elements: fast, -26 .. +48 dB off).
    error_estimate : bool
        Also solve a coarser discretization and report the estimated error in cents.
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
    f_max, wall = _checked_options(material, method, quality, f_max, sample_rate, order, thickness, max_modes, wall)
    if radiation is not None and radiation is not False:
        from .radiation import radiation_settings

        radiation_settings(radiation)  # an unknown name or setting is refused here, before any work
    tm = load_mesh(mesh)
    outer = tm  # what the air sees: a hollow object radiates from its outside only
    if wall is not None:
        from .surface import hollow

        tm = hollow(tm, float(wall))
    elif method == "auto" and thickness is not None and not tm.is_watertight:
        tm = outer = _open_surface_as_shell(tm, float(thickness))
    from .frame import into_frame, model_out_of_frame, principal_frame

    frame = principal_frame(tm)  # a mesh at an angle to the axes: analysed along its own
    if frame is not None:
        tm = into_frame(tm, frame)
        outer = into_frame(outer, frame)
    # Modes above the frequency where Rayleigh damping leaves them less than a cycle of
    # ringing (Q < MIN_Q; overdamped a little higher) make a thud, not a tone: neither the
    # mesh nor the solve is sized for them (rubber: 0.7 kHz instead of 20 kHz shear waves,
    # ~100 modes instead of millions of dofs).
    f_ring = ringing_below(material)
    if f_ring < f_max:
        f_max = max(f_ring, 2 * F_MIN_HZ)
    plan_for = partial(plan_analysis, tm, material, quality=quality, resolution=resolution, thickness=thickness,
                       order=order, refine=refine, max_modes=max_modes, max_memory=max_memory_gb,
                       over_budget=over_budget)
    plan = plan_for(f_max, method=method)
    f_max, h = plan.f_max, plan.h
    params = dict(method=plan.method, through_wall=plan.through_wall, h=h, f_max=f_max, thickness=thickness,
                  wall=wall, order=order, refine=refine, n_points=n_points, max_modes=max_modes,
                  quality=plan.quality, error_estimate=error_estimate, version=MODEL_VERSION,
                  radiation=repr(sorted(radiation.items())) if isinstance(radiation, dict) else radiation)
    key = hashlib.sha256((mesh_digest(tm) + material.key() + repr(sorted(params.items()))).encode()).hexdigest()[:40]
    path = os.path.join(cache_dir(), f"{key}.npz")
    if cache and os.path.exists(path):
        try:
            return ModalModel.load(path)
        except ValueError as exc:
            warnings.warn(f"cache entry {path} is corrupt ({exc}); recomputing", stacklevel=user_stacklevel())

    t0 = time.perf_counter()
    try:
        model = _run(tm, material, plan, n_points, thickness, refine, error_estimate, progress, f_ring,
                     resolution, wall, t0, outer, radiation)
    except ValueError as exc:
        if method != "auto" or plan.method == "hex":
            raise
        # the robust path: any mesh TetGen or the mid-surface refuses (self-intersecting, badly shaped) is voxelized
        tried = "quadratic tets through the thin wall" if plan.method == "tet-wall" else f"the {plan.method} method"
        reason = f"hex: {tried} failed ({exc}); voxel hexahedra instead"
        plan = plan_for(plan.f_max, method="hex")
        plan.reason = reason
        model = _run(tm, material, plan, n_points, thickness, refine, error_estimate, progress, f_ring,
                     resolution, wall, t0, outer, radiation)
    if frame is not None:
        model = model_out_of_frame(model, frame)
    if cache:
        try:
            model.save(path)
        except OSError as exc:
            warnings.warn(f"could not write cache entry {path}: {exc}", stacklevel=user_stacklevel())
    return model


def _checked_options(material, method, quality, f_max, sample_rate, order, thickness, max_modes, wall):
    """:func:`analyze`'s options checked before anything is built: ``(f_max [Hz], wall [m] or
    None)``, ``f_max`` defaulted from ``sample_rate`` and ``wall`` from the material. Raises
    ValueError naming the option and what it must be."""
    if method not in METHODS:
        raise ValueError(f"method {method!r} unknown; choose one of {', '.join(METHODS)}")
    quality_preset(quality)
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
    if max_modes is not None and (isinstance(max_modes, bool) or int(max_modes) != max_modes or max_modes < 1):
        raise ValueError(f"max_modes={max_modes!r} must be a positive whole number of modes")
    if wall is None:
        wall = material.wall
    elif not isinstance(wall, (int, float, np.floating)) or isinstance(wall, bool):
        try:
            wall = parse_length(wall)
        except ValueError as exc:
            raise ValueError(f"wall: {exc}") from None
    if wall is not None and not (np.isfinite(wall) and wall > 0):
        raise ValueError(f"wall={wall!r} must be a positive length in metres")
    return f_max, wall


def _open_surface_as_shell(tm, thickness: float):
    """An open surface standing for a wall of ``thickness`` [m]: the closed slab of that
    wall around it (:func:`.surface.hollow`) when the shell applies to the slab (a curved
    wall: a bowl given by one sheet), so auto analyses its mid-surface; otherwise the
    surface unchanged (hex makes it a slab of voxels: exact for a flat plate)."""
    from .plan import choose_method
    from .surface import hollow

    try:
        slab = hollow(tm, thickness)
    except ValueError:  # non-manifold, or too thick for its features: hex copes
        return tm
    return slab if choose_method(slab)[0] == "facet" else tm


def _run(tm, material, plan: Plan, n_points, thickness, refine, error_estimate, progress, f_ring, resolution,
         wall, t0, outer, rad_quality=None) -> ModalModel:
    """The analysis itself, as planned: discretize, solve, sample, radiate, estimate."""
    method, order, h, f_max, quality = plan.method, plan.order, plan.h, plan.f_max, plan.quality
    points, normals = surface_samples(tm, n_points)
    rplan = too_fine = None
    # an open outer surface (a sheet given with thickness=) has no exterior problem here: compact estimate
    from .radiation_mesh import sealed

    if rad_quality is not False and sealed(outer):
        from .radiation import RadiationMeshTooFine, plan_radiation

        if rad_quality is None:
            rad_quality = quality if quality in ("draft", "high") else "default"
        try:
            rplan = plan_radiation(outer, f_max, rad_quality)
        except RadiationMeshTooFine as e:
            warnings.warn(f"mjsound.analyze: compact radiation estimate (tens of dB off, docs/radiation.md): {e}; "
                          "pass a simpler mesh for boundary-element radiation", stacklevel=3)
            too_fine = str(e)
    sampled = points if rplan is None else np.vstack([points, rplan.points()[0]])
    moments = hex_moments(tm, h, thickness, quality, order) if method == "hex" else None
    build = partial(_discretize, method, tm, material, points=sampled, quality=quality, thickness=thickness,
                    order=order, refine=refine, through_wall=plan.through_wall, mid=plan.mid_surface, moments=moments)
    disc = build(h=h)
    # The error estimate's coarser discretization does not depend on the solve: it is built
    # on the second core meanwhile (the Lanczos iteration runs on one).
    pool = coarse = None
    ratio = coarse_ratio(plan)
    if error_estimate and method != "shell":
        from concurrent.futures import ThreadPoolExecutor

        pool = ThreadPoolExecutor(1)
        coarse = pool.submit(build, h=ratio * h)
    try:
        sol = solve_modes(disc, f_max, progress, plan.max_modes)
    except BaseException:
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)
        raise
    lam = np.maximum(sol.eigenvalues, 0.0)
    omega = np.sqrt(lam)
    shapes = (disc.interp @ sol.vectors).reshape(len(sampled), 3, -1)
    if rplan is None:
        radiation, radiation_sh, centre = _radiation(points, normals, shapes, omega, float(tm.area))
        why = ("radiation=False" if rad_quality is False else too_fine if too_fine
               else "the outer surface does not bound a volume")
        rad_info = dict(method=f"compact monopole + dipole ({why})")
    else:
        from .radiation import solve_radiation

        u_n = np.einsum("pcn,pc->pn", shapes[len(points):], rplan.points()[1])
        radiation, radiation_sh, rad_info = solve_radiation(rplan, u_n, omega)
        centre = rplan.centre
    shapes = shapes[: len(points)]
    # at most radiation efficiency 1 (.radiation_bound): an unresolved mode's solve can exceed
    # it by tens of dB. Capped here, so the pattern, its RMS and the damping below agree
    limit = efficiency_limit(points, normals, shapes, float(tm.area), omega)
    radiation, radiation_sh, over_db = cap_radiation(radiation, radiation_sh, limit)
    # Rayleigh damping d = (alpha + beta omega^2) / 2 plus what radiation takes away;
    # overdamped modes (d >= omega) make no tone and are dropped
    decay = 0.5 * (material.alpha + material.beta * omega**2) + radiation_damping(radiation, omega)
    under = decay < omega
    shapes, radiation, decay, radiation_sh = shapes[:, :, under], radiation[under], decay[under], radiation_sh[under]
    rad_info = _mark_capped(rad_info, over_db, under)
    ex = np.zeros(disc.dofs)
    ex[0::disc.dofs_per_node] = 1.0  # rigid translation along x: e^T M e is the total mass
    mass = float(ex @ (disc.M @ ex))
    info = dict(disc.info)
    info.update(
        h_target=h, f_max=f_max, quality=plan.quality if resolution is None else f"resolution={resolution}",
        solver=sol.backend, slices=sol.n_slices, n_rigid=int(sol.n_below), n_overdamped=int((~under).sum()),
        solve_seconds=sol.seconds, size_m=float(np.max(tm.extents)), area_m2=float(tm.area),
        ringing_limit_hz=f_ring, watertight=bool(tm.is_watertight), wall=wall, radiation=rad_info,
    )
    info.update(plan.info())
    err = float("nan")
    # the shell model has no resolution to vary (it lives on the given surface mesh)
    if error_estimate and under.sum() > 0 and method != "shell":
        p = convergence_order(plan, tm, thickness)
        grids = None
        if method == "hex":  # the coarser grid may keep some axes (a rod's section)
            grids = partial(hex_coarsening, tm, disc.info["grid"], ratio, p, plan.order == 2 and p != HEX_STAIRCASE_ERROR_ORDER)
        err = richardson_error(omega[under] / (2 * np.pi), coarse, ratio, f_max, order=p, coarsening=grids)
    if method == "facet" and disc.info.get("crease_edges", 0) > 0:
        from .midsurface import CREASE_RESIDUAL, crease_cents

        crease = CREASE_RESIDUAL * crease_cents(disc.info["crease_thickness"], float(np.min(tm.extents)))
        info["crease_cents"] = -crease
        err = float(np.hypot(err, crease)) if np.isfinite(err) else err
    if pool is not None:
        pool.shutdown(wait=True, cancel_futures=True)
    name = method
    if method == "tet":
        name = f"tet{4 if order == 1 else 10}" + ("" if plan.through_wall else "-wall")
    return ModalModel(
        frequencies_hz=omega[under] / (2 * np.pi),
        decay_per_s=decay,
        points=points,
        normals=normals,
        shapes=shapes,
        radiation=radiation,
        radiation_sh=radiation_sh,
        radiation_centre=centre,
        material=material,
        method=name,
        dofs=disc.dofs,
        seconds=time.perf_counter() - t0,
        error_estimate_cents=err,
        mass_kg=mass,
        info=info,
    )


def _radiation(points, normals, shapes, omega, area):
    """Per-mode far-field pressure at 1 m per unit modal coordinate (module docstring).

    The compact (k a << 1) monopole + dipole estimate grows as ``omega^3 |D|`` without
    bound, so for modes whose wavelength is shorter than the object it would radiate more
    power than the surface can emit. A surface radiates at most with efficiency 1,
    ``W = rho0 c <v_n^2> A``, which at 1 m is ``R_max = rho0 c omega sqrt(A_eff / 4 pi)``
    with ``A_eff = sum_p a_p (phi . n)^2``: the analysis keeps the smaller of the two.

    The pattern is the compact one, ``F(d) = -(rho0 omega^2 / 4 pi) (Q - i k d . D)``
    (degree 1 in spherical harmonics); :func:`_run` caps it at efficiency 1 as it does the
    boundary elements' (:func:`.radiation_bound.cap_radiation`).

    The radiated power is energy the mode loses: see :func:`radiation_damping`.

    Returns
    -------
    radiation : (n,) RMS over directions [Pa m]; radiation_sh : (n, 4) complex coefficients
    (:mod:`.sph`); centre : (3,) the point the phase refers to [m].
    """
    from .sph import fit_coefficients, sphere_quadrature

    centre = points.mean(axis=0)
    if shapes.shape[2] == 0:
        return np.zeros(0), np.zeros((0, 4), complex), centre
    a = area / len(points)
    un = np.einsum("pcn,pc->pn", shapes.astype(np.float64), normals)  # normal displacement
    Q = a * un.sum(axis=0)
    x = points - centre
    D = a * np.einsum("pc,pn->cn", x, un)
    k = omega / SPEED_OF_SOUND
    compact = AIR_DENSITY * omega**2 / (4 * np.pi) * np.sqrt(Q**2 + (k * np.linalg.norm(D, axis=0)) ** 2 / 3.0)
    dirs, _ = sphere_quadrature(1)
    F = -AIR_DENSITY * omega**2 / (4 * np.pi) * (Q[None, :] - 1j * k[None, :] * (dirs @ D))
    return compact, fit_coefficients(1, F), centre


def _mark_capped(rad_info: dict, over_db, kept) -> dict:
    """``rad_info`` with the modes ``kept`` only and the efficiency cap marked: ``capped_db``
    per mode (by how much the solve exceeded :func:`.radiation_bound.efficiency_limit`, 0 where
    it did not), ``capped`` (how many), and each capped mode's ``error_db`` at least its
    ``capped_db`` (the solve was at least that far off; the capped value is an upper bound)."""
    over = [round(float(x), 2) for x in np.asarray(over_db, float)[kept]]
    info = dict(rad_info, capped=int(sum(o > 0 for o in over)), capped_db=over)
    for key in ("error_db", "shift_db"):
        if key in info:
            info[key] = [e for e, k in zip(info[key], kept) if k]
    if "error_db" in info:
        info["error_db"] = [e if o <= 0 else max(o, e or 0.0) for e, o in zip(info["error_db"], over)]
    return info
