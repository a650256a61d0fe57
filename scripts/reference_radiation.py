"""Converged far-field references of the four level objects -> tests/data/radiation_<name>.npz.

For each object (plate, bar, bowl, can: :data:`mjsound.modal.radiation_check.LEVEL_OBJECTS`) the modal analysis is run once per
radiation setting on the same modes:

* ``reference``: boundary elements on the finest level of at most 3000 elements, one
  factorisation per mode or degenerate pair;
* ``check``: the same on at most 1500 elements, so the file says how converged the reference
  is (the dB step between the two);
* ``default`` and ``compact`` (the old monopole + dipole estimate, ``radiation=False``):
  stored for the report's before/after table, with their run times.

Stored per object: frequencies [Hz], the reference far field ``F`` [Pa m] on the degree-10
quadrature's directions (:func:`mjsound.modal.sph.sphere_quadrature`), complex64, the
``check`` field likewise, the default and compact RMS, the analysis and radiation seconds.
Regenerate (a few minutes per object, nice'd)::

    PYTHONPATH=$PWD nice python scripts/reference_radiation.py [plate bar bowl can]

With ``--bempp NAME`` it instead compares this solver with bempp-cl (Galerkin, P1 pressure,
Burton-Miller) on one mesh level of that object and prints the dB differences (bempp-cl's
first assembly compiles for minutes).
"""

from __future__ import annotations

import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from mjsound import analyze  # noqa: E402
from mjsound.modal.radiation_check import LEVEL_OBJECTS, REFERENCE_DEGREE  # noqa: E402
from mjsound.modal.sph import sphere_quadrature  # noqa: E402

OBJECTS = LEVEL_OBJECTS
#: every mode on the finest level of at most n_max elements (epw too large to be met sooner)
REFERENCE = dict(epw=1e3, n_max=3000, dka=0.02, max_solves=100, degree=16, tol_db=1e3, budget=1e12)
CHECK = dict(epw=1e3, n_max=1500, dka=0.02, max_solves=100, degree=16, tol_db=1e3, budget=1e12)
DEGREE = REFERENCE_DEGREE
DATA = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "tests", "data")


def model_of(name, radiation):
    mesh, material, kw = OBJECTS[name]
    t = time.perf_counter()
    m = analyze(mesh, material, cache=False, error_estimate=False, radiation=radiation, **kw)
    return m, time.perf_counter() - t


def build(name):
    dirs, _ = sphere_quadrature(DEGREE)
    ref, _ = model_of(name, REFERENCE)
    chk, _ = model_of(name, CHECK)
    dflt, t_default = model_of(name, None)
    old, t_compact = model_of(name, False)
    assert np.allclose(ref.frequencies_hz, dflt.frequencies_hz, rtol=1e-6), "the modes differ between runs"
    F, Fc = ref.radiation_pattern(dirs), chk.radiation_pattern(dirs)
    step = 10 * np.log10(np.sum(np.abs(Fc) ** 2, 0) / np.sum(np.abs(F) ** 2, 0))
    out = os.path.join(DATA, f"radiation_{name}.npz")
    os.makedirs(DATA, exist_ok=True)
    np.savez_compressed(
        out, frequencies_hz=ref.frequencies_hz, far_field=F.astype(np.complex64),
        check_far_field=Fc.astype(np.complex64), default_rms=dflt.radiation, compact_rms=old.radiation,
        seconds=np.array([t_default, dflt.info["radiation"]["seconds"], t_compact]),
        reference=np.array(repr(dict(mesh=OBJECTS[name][0], material=OBJECTS[name][1], **OBJECTS[name][2],
                                     reference=REFERENCE, check=CHECK, info=ref.info["radiation"]["levels"]))))
    print(f"{name}: {ref.n_modes} modes {np.round(ref.frequencies_hz)} Hz; reference vs check "
          f"{np.round(step, 2)} dB; default analysis {t_default:.1f} s (radiation "
          f"{dflt.info['radiation']['seconds']:.1f} s); wrote {out} ({os.path.getsize(out)} B)")


def bempp_check(name, level=-1):
    """This solver against bempp-cl on one of the object's default levels (printed)."""
    import bempp_cl.api as bempp
    from bempp_cl.api.operators.boundary import helmholtz, sparse
    from bempp_cl.api.operators.far_field import helmholtz as ff

    from mjsound.modal.bem import BemMesh, solve_far_field

    m, _ = model_of(name, None)
    from mjsound.geometry import load_mesh
    from mjsound.modal.radiation import plan_radiation

    plan = plan_radiation(load_mesh(OBJECTS[name][0]), OBJECTS[name][2]["f_max"], "default")
    mesh = plan.levels[level]
    import trimesh

    tm = trimesh.Trimesh(mesh.tri.reshape(-1, 3), np.arange(3 * len(mesh)).reshape(-1, 3))
    tm.merge_vertices()
    bm = BemMesh(tm.vertices, tm.faces)
    dirs, _ = sphere_quadrature(6)
    grid = bempp.Grid(tm.vertices.T.astype(float), tm.faces.T.astype(np.uint32))
    p1, p0 = bempp.function_space(grid, "P", 1), bempp.function_space(grid, "DP", 0)
    # a smooth test datum: dp/dn = the normal's z (a dipole-like velocity), at a mid wavenumber
    q = bm.normals[:, 2] + 0.3 * bm.normals[:, 0] * bm.centroids[:, 1] / plan.radius
    for f in (500.0, 2000.0):
        k = 2 * np.pi * f / 343.0
        t = time.perf_counter()
        ours, _ = solve_far_field(bm, k, q, dirs, plan.centre)
        t_ours = time.perf_counter() - t
        t = time.perf_counter()
        I1, I01 = sparse.identity(p1, p1, p1), sparse.identity(p0, p1, p1)
        K, W = helmholtz.double_layer(p1, p1, p1, k), helmholtz.hypersingular(p1, p1, p1, k)
        S, Kp = helmholtz.single_layer(p0, p1, p1, k), helmholtz.adjoint_double_layer(p0, p1, p1, k)
        alpha = 1j / k  # bempp's hypersingular is minus d/dn_x of the double layer
        L = np.asarray(bempp.as_matrix((0.5 * I1 - K - alpha * W).weak_form()))
        R = np.asarray(bempp.as_matrix((-S + alpha * (0.5 * I01 + Kp)).weak_form()))
        pc = np.linalg.solve(L, R @ q)
        pts = dirs.T * 1.0
        theirs = (ff.double_layer(p1, pts, k).evaluate(bempp.GridFunction(p1, coefficients=pc))
                  - ff.single_layer(p0, pts, k).evaluate(bempp.GridFunction(p0, coefficients=q))).ravel()
        theirs = theirs * np.exp(1j * k * dirs @ plan.centre)  # bempp refers the phase to the origin
        t_bempp = time.perf_counter() - t
        big = np.abs(theirs) > 0.1 * np.abs(theirs).max()
        db = 20 * np.log10(np.abs(ours[big]) / np.abs(theirs[big]))
        print(f"{name} level {len(bm)} elements, {f:.0f} Hz: ours - bempp-cl {np.sqrt(np.mean(db ** 2)):.2f} dB RMS, "
              f"{np.abs(db).max():.2f} dB max over {big.sum()} directions; {t_ours:.1f} s vs {t_bempp:.1f} s")


if __name__ == "__main__":
    args = sys.argv[1:]
    if args[:1] == ["--bempp"]:
        for name in args[1:] or ["bar"]:
            bempp_check(name)
    else:
        for name in args or list(OBJECTS):
            build(name)
