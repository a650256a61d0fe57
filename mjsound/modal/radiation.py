r"""Acoustic transfer per mode: far-field pressure at 1 m per unit modal coordinate by direction.

A mode ``phi_i`` vibrating with modal coordinate ``q`` moves the outer surface by
``u_n = (phi_i . n) q``; the air's normal pressure gradient there is ``dp/dn = rho0 omega^2 u_n``
(time factor ``e^{-i omega t}``). The exterior Helmholtz problem with that data is solved by
boundary elements (:mod:`.bem`: Burton-Miller, no interior resonances) and its far field
``F_i(d)`` [Pa m] is stored as spherical-harmonic coefficients (:mod:`.sph`) about the centre
of the object's bounding box.

Cost and accuracy
-----------------
* Meshes: the outer surface (a hollow object radiates from its outside only) as constant
  elements of edge ``h_j = h_0 / sqrt(2)^j`` (:mod:`.radiation_mesh`), ``h_0`` a sixth of the
  object's size, up to ``n_max`` elements. A mode uses the coarsest level with at least
  ``epw`` elements per acoustic wavelength.
* Frequency clusters: modes within ``dka`` of each other in ``k a`` (``a`` the radius of the
  sphere around the object) share one factorisation, solved at the cluster's middle; each mode
  then takes its own wavenumber in the far-field integral, which carries the strong ``(k a)^n``
  dependence of compact sources exactly (sphere ``n = 0..3``: 0.5 dB at ``k a = 6`` for 5 %
  off the solve's wavenumber, under 0.1 dB below ``k a = 1`` for 10 %; a cluster 0.6 wide,
  the default below ``k a = 4``, puts a mode at most 0.3 off: the sphere's ``n = 0..3`` within
  0.9 dB in every direction for ``k a`` from 0.5 to 6).
* Modes whose wavelength the finest affordable level does not resolve ``epw`` times (large
  objects at high frequency) are solved on that level regardless, at most ``max_solves``
  factorisations in all (wider clusters above): ``info['radiation']`` reports how many modes
  that concerns and an error estimate from the same modes solved one level coarser.
* Widened clusters (wider than ``dka``, or 15 % of ``k a``, to stay within ``max_solves``) put
  modes farther from the solve's wavenumber than the bounds above: the cluster is solved again
  on the level below at its lowest and its highest mode's wavenumber, and each mode's change
  of power from the middle towards its own end, scaled to its distance (linear in ``log k``),
  is its shift error (``info['radiation']['shift_db']``), combined with the level step in
  ``error_db`` (``hypot``). These checks are outside the budget (the model does not use them).
* Directions: each cluster's far field is sampled on the quadrature of its own degree,
  ``ceil(k a) + 3`` for its highest mode (at most ``degree``), and fitted there; the
  model's coefficients are those of the highest cluster, zero above a lower one's degree.
* Budget: the solves are counted (:func:`solve_cost`) against ``budget``; a cluster is solved
  on the finest level its solve and the coarser check fit in what is left, is refined only
  within its share of what is left (so a mode that converges slowly cannot starve the later
  ones), and once the budget is spent each further cluster takes the two coarsest levels.

Radiated power ``W = (1 / 2 rho0 c) int |F|^2 dOmega`` makes the mode's radiation damping
(:func:`radiation_damping`); the RMS of ``|F|`` over directions is ``ModalModel.radiation``.
"""

from __future__ import annotations

import contextlib
import time
from dataclasses import dataclass, field

import numpy as np

from .bem import BemMesh, assemble_mesh, far_field_parts, far_fields_per_mode
from .radiation_mesh import level_mesh
from .sph import fit_coefficients, sphere_quadrature

__all__ = ["RADIATION_QUALITY", "RadiationPlan", "plan_radiation", "solve_radiation", "radiation_damping",
           "AIR_DENSITY", "SPEED_OF_SOUND"]

AIR_DENSITY = 1.2
SPEED_OF_SOUND = 343.0

#: per analysis quality: elements per wavelength, fewest and most elements of a level, the
#: widest cluster in k a, the most clusters, the highest harmonic degree stored, and the
#: change of a mode's power [dB] from one level to the next under which it counts as converged,
#: the coarsening grid's cell in units of the element edge (:data:`.radiation_mesh.COARSEN_CELLS`),
#: and the budget of the solves in element pairs (:func:`solve_cost`; 1.2e7 took 3 s of CPU
#: on the plate at 20 kHz, docs/radiation.md "Cost"): a cluster it cannot afford is solved on
#: a coarser level, its error estimate reported
RADIATION_QUALITY = {
    "draft": dict(epw=4.0, n_min=100, n_max=500, dka=0.4, max_solves=6, degree=10, tol_db=1.0, budget=3e6,
                  coarsen=1.0),
    "default": dict(epw=5.0, n_min=200, n_max=1500, dka=0.6, max_solves=10, degree=16, tol_db=0.5, budget=12e6,
                    coarsen=1.0),
    "high": dict(epw=7.0, n_min=400, n_max=2500, dka=0.2, max_solves=40, degree=24, tol_db=0.25, budget=2e8,
                 coarsen=0.5),
}


@dataclass
class RadiationPlan:
    """The boundary-element levels of one object (coarse to fine) and where they sample it.

    Attributes
    ----------
    levels : list of BemMesh
    h : list of float, the levels' element edges [m]
    centre : (3,) centre of the surface's bounding box [m], the pattern's phase reference
    radius : float, largest distance of the surface from ``centre`` [m]
    settings : dict, the :data:`RADIATION_QUALITY` entry used
    """

    levels: list
    h: list
    centre: np.ndarray
    radius: float
    settings: dict
    info: dict = field(default_factory=dict)

    def points(self):
        """``(points (m, 3), normals (m, 3))``: every level's element centroids, coarse to
        fine, where the mode shapes are to be sampled."""
        return (np.concatenate([m.centroids for m in self.levels]),
                np.concatenate([m.normals for m in self.levels]))

    def split(self, values):
        """Per-level pieces of an array over :meth:`points` (first axis)."""
        cuts = np.cumsum([len(m) for m in self.levels])[:-1]
        return np.split(values, cuts)


#: most boundary elements of an object's coarsest level: a dense solve of more is minutes
RADIATION_MAX_ELEMENTS = 3000


class RadiationMeshTooFine(ValueError):
    """The outer surface cannot be coarsened to an affordable boundary-element mesh."""


def radiation_settings(quality) -> dict:
    """The :data:`RADIATION_QUALITY` entry named ``quality``, or the default one updated
    with a dict's entries; an error naming the choices otherwise."""
    if isinstance(quality, dict):
        unknown = set(quality) - set(RADIATION_QUALITY["default"])
        if unknown:
            raise ValueError(f"radiation: unknown settings {sorted(unknown)}; "
                             f"known: {', '.join(RADIATION_QUALITY['default'])}")
        return {**RADIATION_QUALITY["default"], **quality}
    if quality not in RADIATION_QUALITY:
        raise ValueError(f"radiation={quality!r} unknown; choose one of {', '.join(RADIATION_QUALITY)}, "
                         "a dict of settings, or False")
    return dict(RADIATION_QUALITY[quality])


def plan_radiation(outer, f_max: float, quality="default") -> RadiationPlan:
    """Boundary-element levels for the closed outer surface ``outer`` (trimesh) up to
    ``f_max`` [Hz]: from ``h_0`` = size / 6 down by ``sqrt 2`` until ``epw`` elements per
    wavelength at ``f_max`` and at least ``n_max / 2`` elements (finer levels check the
    coarser ones), or ``n_max`` elements. ``quality``: see :func:`radiation_settings`."""
    settings = radiation_settings(quality)
    v = np.asarray(outer.vertices, float)
    lo, hi = v.min(axis=0), v.max(axis=0)
    centre = 0.5 * (lo + hi)
    radius = float(np.linalg.norm(v - centre, axis=1).max())
    size = float(np.max(hi - lo))
    h_need = SPEED_OF_SOUND / (f_max * settings["epw"])
    levels, hs = [], []
    h = size / 6.0
    cells = tuple(dict.fromkeys((float(settings["coarsen"]), 0.5)))
    meshes = {}  # h -> level_mesh(outer, h), each made once
    for _ in range(6):  # a first level over n_max (a fine mesh the clustering could not coarsen): coarser
        meshes[h] = level_mesh(outer, h, cells)
        if len(meshes[h][1]) <= settings["n_max"]:
            break
        h *= np.sqrt(2.0)
    else:
        # no size gets under n_max: the fewest elements any reached (coarsening may give up at a
        # large h and return the surface as given, finer than a smaller h's level)
        h = min(meshes, key=lambda size: len(meshes[size][1]))
    if len(meshes[h][1]) > RADIATION_MAX_ELEMENTS:
        raise RadiationMeshTooFine(
            f"the outer surface coarsens to no fewer than {len(meshes[h][1])} boundary elements "
            f"(most {RADIATION_MAX_ELEMENTS})")
    while True:
        vv, ff = meshes[h] if h in meshes else level_mesh(outer, h, cells)
        if levels and len(ff) > settings["n_max"]:
            break
        levels.append(BemMesh(vv, ff))
        hs.append(h)
        if h <= h_need and len(ff) >= settings["n_max"] / 2:
            break
        h /= np.sqrt(2.0)
    if len(levels) == 1 or len(levels[0]) >= settings["n_min"]:
        # a coarser level below, so that every mode gets an error estimate, and one a solve on
        # the first level used (n_min) checks against at a fraction of its cost
        vv, ff = level_mesh(outer, hs[0] * np.sqrt(2.0), cells)
        if len(ff) < len(levels[0]):
            levels.insert(0, BemMesh(vv, ff))
            hs.insert(0, hs[0] * np.sqrt(2.0))
    return RadiationPlan(levels=levels, h=hs, centre=centre, radius=radius, settings=settings)


def _clusters(ka, level, dka, max_solves):
    """Groups of mode indices (sorted by ``ka``) on one level each, no wider than ``dka``
    in ``k a`` (or 15 % of it), widened evenly when there would be more than ``max_solves``
    (or than the number of levels, if that is more)."""
    # by level, then by k a: a mode's level follows its surface wavelength too, so levels
    # interleave in k a, and one group per level is the fewest there can be
    order = np.lexsort((ka, level))
    max_solves = max(max_solves, len(np.unique(level)))
    while True:
        groups, cur = [], [order[0]] if len(order) else []
        for i in order[1:]:
            lo = ka[cur[0]]
            if level[i] == level[cur[0]] and ka[i] - lo <= max(dka, 0.15 * lo):
                cur.append(i)
            else:
                groups.append(cur)
                cur = [i]
        if cur:
            groups.append(cur)
        if len(groups) <= max_solves:
            return groups
        dka *= 1.3


def solve_radiation(plan: RadiationPlan, u_n, omega, progress=None):
    """Far-field patterns of modes with normal displacements ``u_n`` on the plan's levels.

    Parameters
    ----------
    plan : RadiationPlan
    u_n : (m, n_modes) array
        ``phi_i . n`` at :meth:`RadiationPlan.points` [1/sqrt(kg)].
    omega : (n_modes,) array
        Angular frequencies [rad/s].

    Returns
    -------
    rms : (n_modes,) RMS over directions of ``|F|`` [Pa m]
    coefficients : (n_modes, (L + 1)^2) complex spherical-harmonic coefficients of ``F``
    info : dict (JSON-able): levels, solves, seconds, modes under-resolved and the error
        estimate for them.

    BLAS runs on one thread here: OpenBLAS's second thread on dense LUs of at most a few
    thousand unknowns gained no wall time on this 2-core machine and doubled the CPU time (its
    threads wait spinning beside the assembly's numba threads; the plate at 20 kHz, captured
    inputs: 5.8 -> 3.1 s CPU, 3.1 s wall either way). The numba kernels run on one thread
    too, ``numba_threads``: their OpenMP workers spin through the serial LU that follows each
    assembly (the plate: 2.0 s CPU for 1.0 s wall with two threads, 1.3 s either with one).
    """
    from .block_lanczos import single_threaded_blas

    with single_threaded_blas(), numba_threads(1):
        return _solve_radiation(plan, u_n, omega, progress)


@contextlib.contextmanager
def numba_threads(n: int):
    """A context in which numba's parallel loops (of the calling thread) use ``n`` threads
    (at most numba's own number); the previous number is restored after."""
    import numba

    before = numba.get_num_threads()
    numba.set_num_threads(max(1, min(int(n), numba.config.NUMBA_NUM_THREADS)))
    try:
        yield
    finally:
        numba.set_num_threads(before)


def _solve_radiation(plan: RadiationPlan, u_n, omega, progress=None):
    """:func:`solve_radiation`'s work."""
    t0, c0 = time.perf_counter(), time.process_time()
    s = plan.settings
    omega = np.asarray(omega, float)
    n = len(omega)
    k = omega / SPEED_OF_SOUND
    ka = k * plan.radius
    L = _degree(ka.max(initial=0.0), s["degree"])
    un_levels = plan.split(np.asarray(u_n, float))
    n_levels = len(plan.levels)
    # the coarsest level with epw elements per wavelength, acoustic and on the surface
    # (a plate's bending waves below coincidence are shorter than the sound's), else the finest
    lam = np.minimum(2 * np.pi / np.maximum(k, 1e-12), surface_wavelength(plan.levels[-1], un_levels[-1]))
    level = np.full(n, n_levels - 1)
    for j in range(n_levels - 1, -1, -1):
        level[plan.h[j] * s["epw"] <= lam] = j
    level = np.maximum(level, min(int(np.searchsorted([len(m) for m in plan.levels], s["n_min"])), n_levels - 1))
    under = np.zeros(n, bool)
    coef = np.zeros((n, (L + 1) ** 2), complex)
    rms = np.zeros(n)
    error_db = np.full(n, np.nan)
    shift_db = np.zeros(n)
    groups = _clusters(ka, level, s["dka"], s["max_solves"]) if n else []
    solves = []

    spent = [0.0, 0.0]  # solves counted against the budget, and the shift checks
    n_el = [len(m) for m in plan.levels]
    j_min = min(int(np.searchsorted(n_el, s["n_min"])), n_levels - 1)

    def affordable(j, check=False):  # check: and the solve one level coarser for the error estimate
        extra = solve_cost(n_el[j - 1]) if check and j > 0 else 0.0
        return spent[0] + solve_cost(n_el[j]) + extra <= s["budget"]

    def solve(j, g, kc, check=False):  # check: a shift check, outside the budget (the model does not use it)
        out = _solve_group(plan.levels[j], kc, k[g], omega[g], un_levels[j][:, g], dirs_g, plan.centre)
        spent[1 if check else 0] += solve_cost(n_el[j])
        solves.append(dict(level=j, elements=len(plan.levels[j]), ka=round(kc * plan.radius, 3), modes=len(g),
                           **({"shift_check": True} if check else {})))
        return out

    def step_db(Fa, Fb):  # change of each mode's radiated power from one level to the next
        pa = w_g @ (np.abs(Fa) ** 2)
        pb = w_g @ (np.abs(Fb) ** 2)
        return np.abs(10 * np.log10(np.maximum(pb, 1e-300) / np.maximum(pa, 1e-300)))

    limited = 0
    for gi, g in enumerate(groups):
        g = np.asarray(g)
        j = int(level[g[0]])
        while j > j_min and not affordable(j, check=True):  # over the budget: coarser, with its error estimate
            j -= 1
        limited += int(j < level[g[0]])
        kc = float(np.sqrt(k[g].min() * k[g].max()))
        # the far field on the quadrature of the cluster's own degree (a low cluster's pattern
        # needs a few directions, not the highest mode's hundreds)
        L_g = _degree(ka[g].max(), s["degree"])
        dirs_g, w_g = sphere_quadrature(L_g)
        Fg = solve(j, g, kc)
        est = below = None  # (below: the cluster at kc one level under its own, once solved)
        # refine while the next level changes the power by more than tol_db and the steps shrink.
        # A refinement step also stays within the cluster's share of the budget left (a mode
        # converging slowly, such as a thin plate's torsion, whose radiation is the remainder
        # of cancelling edge flows, keeps its error estimate rather than the later modes' solves)
        share = spent[0] + (s["budget"] - spent[0]) / (len(groups) - gi)
        prev = np.inf
        while (j + 1 < n_levels and (est is None or s["tol_db"] < est.max() < prev)
               and affordable(j + 1) and spent[0] + solve_cost(n_el[j + 1]) <= share):
            prev = np.inf if est is None else est.max()
            Fn = solve(j + 1, g, kc)
            est, below, Fg, j = step_db(Fg, Fn), Fg, Fn, j + 1
        if est is None and j > 0:  # not refined (finest level, or the budget): the step from below
            below = solve(j - 1, g, kc)
            est = step_db(below, Fg)
        elif est is None and j + 1 < n_levels:  # on the coarsest level: one step up, kept
            Fn = solve(j + 1, g, kc)
            est, below, Fg, j = step_db(Fg, Fn), Fg, Fn, j + 1
        if len(g) > 1 and ka[g].max() - ka[g].min() > max(s["dka"], 0.15 * ka[g].min()):
            # widened beyond dka (max_solves): the modes' shift from kc is measured on the level
            # below, solved again at the lowest and at the highest mode's wavenumber; the change
            # of each mode's power from kc towards its own side, scaled to its own distance
            # from kc (linear in log k), is its shift error (the end modes' exactly, there)
            jc, ref = (j - 1, below) if below is not None else (j, Fg)
            dist = np.log(k[g] / kc)
            for end, side in ((int(np.argmin(dist)), dist < 0), (int(np.argmax(dist)), dist > 0)):
                moved = step_db(ref, solve(jc, g, float(k[g][end]), check=True))
                shift_db[g[side]] = moved[side] * dist[side] / dist[end]
            est = shift_db[g] if est is None else np.hypot(est, shift_db[g])
        coef[np.ix_(g, np.arange((L_g + 1) ** 2))] = fit_coefficients(L_g, Fg)
        rms[g] = np.sqrt((w_g[:, None] * np.abs(Fg) ** 2).sum(axis=0) / (4 * np.pi))
        if est is not None:
            error_db[g] = est
        under[g] = under[g] | (plan.h[j] * s["epw"] > lam[g])
        if progress is not None:
            progress((gi + 1) / len(groups))
    # a pattern finer than degree L (high k a beyond the setting's degree) loses the power above
    # L in the fit: the coefficients are scaled to the solved power, so that the stored pattern's
    # RMS is ``radiation`` (sqrt(sum |c|^2 / 4 pi)) and the damping the power it radiates
    fitted = np.sqrt(np.sum(np.abs(coef) ** 2, axis=1) / (4 * np.pi))
    coef *= np.divide(rms, fitted, out=np.ones_like(rms), where=fitted > 0)[:, None]
    info = dict(method="bem-burton-miller", degree=L, levels=[len(m) for m in plan.levels],
                h_m=[round(h, 5) for h in plan.h], epw=s["epw"], solves=len(solves), clusters=solves,
                under_resolved=int(under.sum()), budget_limited_clusters=limited, cost=spent[0],
                shift_check_cost=spent[1],
                error_db=[None if not np.isfinite(e) else round(float(e), 3) for e in error_db],
                shift_db=[round(float(e), 3) for e in shift_db],
                radius_m=plan.radius, seconds=time.perf_counter() - t0, cpu_seconds=time.process_time() - c0)
    return rms, coef, info


def _degree(ka, most: int) -> int:
    """Spherical-harmonic degree of a far field up to ``k a``: ``ceil(k a) + 3`` (at least 2),
    at most ``most``."""
    return int(min(most, max(2, np.ceil(ka) + 3)))


def surface_wavelength(mesh: BemMesh, u_n, neighbours: int = 6):
    r"""Wavelength [m] of each mode's normal displacement along the surface (n_modes,).

    For ``u = cos(k_s . x)`` on a surface, the mean of ``(u_i - u_j)^2 / |x_i - x_j|^2`` over
    nearby element pairs (facing the same way: the two faces of a thin wall move oppositely)
    is ``k_s^2 / 4`` and the mean of ``u^2`` is 1/2, so ``k_s = sqrt(2 ratio)``."""
    from scipy.spatial import cKDTree

    x = mesh.centroids
    nb = min(neighbours, len(x) - 1)
    if nb < 1:
        return np.full(u_n.shape[1], np.inf)
    _, idx = cKDTree(x).query(x, nb + 1)
    i = np.repeat(np.arange(len(x)), nb)
    j = idx[:, 1:].reshape(-1)
    same = (np.einsum("pc,pc->p", mesh.normals[i], mesh.normals[j]) > 0.5) & np.any(x[i] != x[j], axis=1)
    i, j = i[same], j[same]
    d2 = np.sum((x[i] - x[j]) ** 2, axis=1)
    grad = np.mean((u_n[i] - u_n[j]) ** 2 / d2[:, None], axis=0)
    mean_sq = np.average(u_n**2, axis=0, weights=mesh.areas)
    ks = np.sqrt(2 * grad / np.maximum(mean_sq, 1e-300))
    return 2 * np.pi / np.maximum(ks, 1e-12)


def solve_cost(n_elements: int) -> float:
    """Cost of one solve in units of element pairs: assembly ``N^2`` plus the factorisation,
    ``N^3 / 1500`` (as long as the assembly at 1500 elements, measured). A deterministic
    measure, so that a model's content never depends on the machine's load."""
    return float(n_elements) ** 2 * (1.0 + n_elements / 1500.0)


def _solve_group(mesh: BemMesh, kc, k, omega, u_n, dirs, centre):
    """Far fields (n_dirs, g) of modes at wavenumbers ``k`` from one factorisation at ``kc``."""
    import scipy.linalg as sla

    q = AIR_DENSITY * omega[None, :] ** 2 * u_n  # dp/dn per element and mode
    A, Bq = assemble_mesh(mesh, kc)
    p = refined_solve(A, Bq @ q)
    # the element integrals at kc, each mode's own wavenumber through the centroids' phase
    lr, li, proj, dn = far_field_parts(mesh, kc, dirs, centre)
    return far_fields_per_mode(lr, li, proj, dn, np.ascontiguousarray(p.T), np.ascontiguousarray(q.T.astype(complex)),
                               np.asarray(k, float))


def refined_solve(A, b, steps: int = 2):
    r"""``A^{-1} b`` from a single-precision LU factorisation and ``steps`` of iterative
    refinement in double precision: ``x_{m+1} = x_m + LU^{-1}(b - A x_m)``.

    Each step shrinks the error by about ``cond(A) eps_32`` (Burton-Miller's matrices have
    ``cond`` in the tens to hundreds, so ``1e-5`` a step and double precision after two), at
    the cost of one product ``A x`` (``N^2`` per right-hand side), while the factorisation,
    ``N^3``, runs at single precision's speed (twice double's).

    Parameters
    ----------
    A : (N, N) complex128
    b : (N, m) complex128

    Returns
    -------
    (N, m) complex128
    """
    import scipy.linalg as sla

    lu = sla.lu_factor(A.astype(np.complex64), overwrite_a=True, check_finite=False)
    x = sla.lu_solve(lu, b.astype(np.complex64), check_finite=False).astype(np.complex128)
    for _ in range(steps):
        r = b - A @ x
        x += sla.lu_solve(lu, r.astype(np.complex64), check_finite=False)
    return x


def radiation_damping(radiation, omega):
    """Decay rate [1/s] a mode gets from the sound it radiates.

    A mode of amplitude q holds ``E = omega^2 q^2 / 2`` and radiates
    ``W = (q^2 / 2 rho0 c) int |F|^2 dOmega = 4 pi (R q)^2 / (2 rho0 c)`` with ``R`` the RMS of
    ``|F|`` over directions (``ModalModel.radiation``), so its energy decays at ``W / E = 2 d_rad``
    with ``d_rad = 2 pi R^2 / (rho0 c omega^2)``. Adding it to the Rayleigh decay keeps every
    mode from radiating more energy than it loses, and a material without structural damping
    still rings down.
    """
    return 2 * np.pi * np.asarray(radiation) ** 2 / (AIR_DENSITY * SPEED_OF_SOUND * np.asarray(omega) ** 2)
