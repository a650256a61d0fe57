"""Modal analysis section of the accuracy report: references (closed forms, Lamb's sphere,
the converged bowl), mode matching by shape, and the measured points (methods, qualities,
the scikit-fem peer, f_max)."""

from __future__ import annotations

import functools
import math
import time

import numpy as np

from .measure import cents, measure

ALU = "aluminium"

#: Converged bowl frequencies (first 8 modes) [Hz]: tet10, TetGen h = 3 mm (mean edge
#: 2.61 mm, 712 107 dofs), measured on this project's 2-core machine (736 s wall,
#: ``analyze("bowl:0.1,0.004", "aluminium", method="tet", order=2, resolution=67,
#: f_max=3500)``), Richardson-extrapolated (h^4, quadratic elements) with the tet10 solve at
#: the default mesh (mean edge 8.39 mm, 41 103 dofs: 415.9, 415.9, 1114.5, 1115.1, 2059.6,
#: 2061.2, 3212.8, 3221.5 Hz). The extrapolation moves no mode by more than 0.6 cent.
_BOWL_FINE = np.array([412.97, 412.98, 1098.67, 1098.69, 2013.51, 2013.52, 3116.05, 3116.08])
_BOWL_COARSE = np.array([415.9, 415.9, 1114.5, 1115.1, 2059.6, 2061.2, 3212.8, 3221.5])
_RATIO = 8.39 / 2.61
BOWL_REFERENCE = _BOWL_FINE + (_BOWL_FINE - _BOWL_COARSE) / (_RATIO**4 - 1)

#: Converged 3D bending frequencies [Hz] of the rod (the 62-gon prism of its mesh, each
#: degenerate pair averaged): quadratic hex cells with the voxels' moments, 8 cells across
#: and 100 along (87 639 dofs), Richardson-extrapolated (h^4) with 60 along (moves none by
#: more than 0.011 cent); 6 instead of 8 across moves each by 0.04 cent. Measured on this
#: project's 2-core machine. Timoshenko's beam with the same section and Cowper's
#: coefficient (:func:`rod_bending_references`) is 0.13, 0.53, 1.11, 1.88 cents below them
#: (within 0.5 cent for the square beam, whose section is half as wide); quadratic tets
#: approach them from above (8.3 mm: +1.3 cents at the fourth pair).
ROD_BENDING_3D = (360.787, 986.985, 1913.928, 3119.701)
BEAM_BENDING_3D = [209.06, 574.7, 1122.3, 1845.7]
BEAM_BENDING_EB = [209.36, 577.10, 1131.35, 1870.17]
BEAM_LONGITUDINAL = 5091.6
ROD_TORSION = [3122.0, 6243.9, 9365.9]
SPHERE_RADIUS = 0.1



# ---------------------------------------------------------------------------- references
def lamb_sphere(nu: float, kind: str, n: int, count: int = 1, x_max: float = 12.0) -> list:
    r"""Roots ``x = omega a / c_s`` of a free elastic sphere's frequency equations (Lamb 1882).

    Toroidal (torsional) modes of degree n: ``(n - 1) j_n(x) - x j_{n+1}(x) = 0``
    (independent of Poisson's ratio; 0T2: x = 2.5011).

    Spheroidal modes of degree n >= 1: with the displacement
    ``u = A grad(j_n(h r) Y_n) + B curl curl(r j_n(k r) Y_n)``, ``k = omega / c_s``,
    ``h = omega / c_p``, the stress-free surface ``sigma_rr = sigma_rt = 0`` at r = a gives

    .. math::
        \det\begin{pmatrix}
          -\tfrac{\lambda}{\mu} h^2 j_n(ha) + 2h^2 j_n''(ha) & 2n(n+1)\,(k j_n'(ka)/a - j_n(ka)/a^2)\\
          2h j_n'(ha)/a - 2 j_n(ha)/a^2 & k^2 j_n''(ka) + (n(n+1) - 2) j_n(ka)/a^2
        \end{pmatrix} = 0

    (for n = 0 only the top-left entry: the breathing modes). Checks: 0S2 at nu = 0.25 gives
    x = 2.6399 and 0T2 2.5011, the values tabulated in the literature (e.g. Sato & Usami 1962).
    """
    from scipy.optimize import brentq
    from scipy.special import spherical_jn as jn

    def jpp(m, z):
        return -2.0 / z * jn(m, z, True) - (1.0 - m * (m + 1) / z**2) * jn(m, z)

    g = math.sqrt((1 - 2 * nu) / (2 * (1 - nu)))  # c_s / c_p
    lam = 2 * nu / (1 - 2 * nu)  # lambda / mu

    def f(x):
        if kind == "T":
            return (n - 1) * jn(n, x) - x * jn(n + 1, x)
        k, h = x, g * x
        a11 = -lam * h**2 * jn(n, h) + 2 * h**2 * jpp(n, h)
        if n == 0:
            return a11
        a12 = 2 * n * (n + 1) * (k * jn(n, k, True) - jn(n, k))
        a21 = 2 * h * jn(n, h, True) - 2 * jn(n, h)
        a22 = k**2 * jpp(n, k) + (n * (n + 1) - 2) * jn(n, k)
        return a11 * a22 - a12 * a21

    xs = np.linspace(0.2, x_max, 6000)
    v = np.array([f(x) for x in xs])
    roots = []
    for i in range(len(xs) - 1):
        if np.sign(v[i]) != np.sign(v[i + 1]):
            roots.append(brentq(f, xs[i], xs[i + 1], xtol=1e-12))
            if len(roots) >= count:
                break
    return roots


def sphere_references(material) -> dict:
    cs = math.sqrt(material.shear_modulus / material.rho)
    k = cs / (2 * math.pi * SPHERE_RADIUS)
    return {"0T2": lamb_sphere(material.nu, "T", 2)[0] * k, "0S2": lamb_sphere(material.nu, "S", 2)[0] * k}


def sphere_mesh(radius=SPHERE_RADIUS, subdivisions=3):
    """Icosphere scaled to the volume of the true sphere (so faceting does not shift every mode)."""
    import trimesh

    m = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    s = (4.0 / 3.0 * math.pi * radius**3 / m.volume) ** (1.0 / 3.0)
    m.apply_scale(s)
    return m


SHAPES = {
    "beam": {"mesh": "box:0.5,0.01,0.01", "f_max": 6000.0, "peer_k": 30},
    "rod": {"mesh": "cylinder:0.01,0.5", "f_max": 10000.0, "peer_k": 30},
    "sphere": {"mesh": "sphere", "f_max": 14500.0, "peer_k": 18},
    "bowl": {"mesh": "bowl:0.1,0.004", "f_max": 3500.0, "peer_k": 16},
}


def _mesh_for(shape):
    spec = SHAPES[shape]["mesh"]
    return sphere_mesh() if spec == "sphere" else spec


def references(shape):
    """``[(label, f_ref)]`` of the modes compared for ``shape``."""
    from ..materials import get_material

    if shape == "beam":
        out = []
        for i, f in enumerate(BEAM_BENDING_3D):
            out += [(f"bend{i + 1}a", f), (f"bend{i + 1}b", f)]
        return out + [("long1", BEAM_LONGITUDINAL)]
    if shape == "rod":
        out = []
        for i, f in enumerate(ROD_BENDING_3D):
            out += [(f"bend{i + 1}a", f), (f"bend{i + 1}b", f)]
        return out + [(f"tors{i + 1}", f) for i, f in enumerate(ROD_TORSION)]
    if shape == "sphere":
        r = sphere_references(get_material(ALU))
        return [("0T2", r["0T2"])] * 5 + [("0S2", r["0S2"])] * 5
    if shape == "bowl":
        return [(f"mode{i + 1}", float(f)) for i, f in enumerate(BOWL_REFERENCE)]
    raise KeyError(shape)


@functools.lru_cache(maxsize=1)
def rod_bending_references() -> tuple:
    """The rod's first four bending frequencies [Hz] (each a degenerate pair): Timoshenko's
    beam (:mod:`.timoshenko`) with the section of the mesh itself (its 62-gon end cap:
    area and second moment 0.17 % and 0.34 % under the circle's) and Cowper's circular shear
    coefficient. The same model is within 0.5 cent of the square beam's converged 3D values;
    quadratic tets on the rod converge to it from above (8.3 mm: +0.2 .. +3.2 cents)."""
    from ..geometry import load_mesh
    from ..materials import get_material
    from .timoshenko import kappa_circle, polygon_section, timoshenko_free_free

    mat = get_material(ALU)
    tm = load_mesh(SHAPES["rod"]["mesh"])
    V = np.asarray(tm.vertices)
    cap = V[np.isclose(V[:, 2], V[:, 2].max())][:, :2]
    cap = cap[np.hypot(cap[:, 0], cap[:, 1]) > 1e-9 * np.ptp(V[:, 2])]  # the rim, not the centre
    cap = cap[np.argsort(np.arctan2(cap[:, 1], cap[:, 0]))]
    area, inertia = polygon_section(cap)
    f = timoshenko_free_free(mat, area, inertia, kappa_circle(mat.nu), float(np.ptp(V[:, 2])), 4)
    return tuple(float(x) for x in f)


def _bending(P, U, axis):
    """Modes (indices) that translate each cross-section of a bar along ``axis`` sideways
    (bending), and the axial energy fraction of every mode. Degenerate pairs may come out
    in any rotated basis; torsion turns the sections (no mean sideways motion)."""
    e = np.einsum("pcn,pcn->cn", U, U)
    fa = e[axis] / (e.sum(axis=0) + 1e-300)
    nb = 25
    b = np.clip(((P[:, axis] - P[:, axis].min()) / (np.ptp(P[:, axis]) + 1e-300) * nb).astype(int), 0, nb - 1)
    T = U[:, [c for c in range(3) if c != axis], :]  # (p, 2, n)
    cnt = np.bincount(b, minlength=nb).astype(float)
    trans = np.zeros(U.shape[2])
    for j in range(nb):
        if cnt[j] > 0:
            mean = T[b == j].mean(axis=0)  # (2, n)
            trans += cnt[j] * (mean**2).sum(axis=0)
    frac = trans / (np.einsum("pcn,pcn->n", T, T) + 1e-300)
    return np.flatnonzero((fa < 0.5) & (frac > 0.6)), fa


def match_modes(shape, freqs, points, disp):
    """Frequencies matched to :func:`references` by mode shape (nan where missing).

    ``points`` (p, 3) positions, ``disp`` (p, 3, n) displacements of the n modes there.
    """
    freqs = np.asarray(freqs, float)
    refs = references(shape)
    out = np.full(len(refs), np.nan)
    if len(freqs) == 0:
        return out
    P = np.asarray(points, float) - np.asarray(points, float).mean(axis=0)
    U = np.asarray(disp, float)
    if shape == "beam":
        bend, fx = _bending(P, U, 0)
        lon = np.flatnonzero(fx > 0.7)
        fb = np.sort(freqs[bend])[:8]
        out[: len(fb)] = fb
        if len(lon):
            out[8] = freqs[lon[0]]
        return out
    if shape == "rod":
        r = np.hypot(P[:, 0], P[:, 1])
        ok = r > 0.5 * r.max()
        t = np.zeros_like(P)
        t[ok, 0], t[ok, 1] = -P[ok, 1] / r[ok], P[ok, 0] / r[ok]
        ut = np.einsum("pcn,pc->pn", U[ok], t[ok])
        frac = (ut**2).sum(axis=0) / (np.einsum("pcn,pcn->n", U[ok], U[ok]) + 1e-300)
        ft = np.sort(freqs[frac > 0.8])[:3]
        out[8: 8 + len(ft)] = ft
        fb = np.sort(freqs[_bending(P, U, 2)[0]])[:8]
        out[: len(fb)] = fb
        return out
    if shape == "sphere":
        rr = np.linalg.norm(P, axis=1)
        ok = rr > 0.5 * rr.max()
        nrm = P[ok] / rr[ok, None]
        ur = np.einsum("pcn,pc->pn", U[ok], nrm)
        frac = (ur**2).sum(axis=0) / (np.einsum("pcn,pcn->n", U[ok], U[ok]) + 1e-300)
        ft = np.sort(freqs[frac < 0.1])[:5]
        fs = np.sort(freqs[frac >= 0.1])[:5]
        out[: len(ft)] = ft
        out[5: 5 + len(fs)] = fs
        return out
    fb = np.sort(freqs)[: len(refs)]
    out[: len(fb)] = fb
    return out


# ---------------------------------------------------------------------------- modal points
def _modal_point(shape, method, kw):
    """Child: one analysis; returns frequencies matched to the references and timings."""
    from ..modal.analyze import analyze

    f_max = kw.pop("f_max", SHAPES[shape]["f_max"])
    if "serendipity" in kw:  # 20- or 27-node hex cells (a forked child: patching is local)
        import functools

        from ..modal import hex as hexmod

        hexmod.discretize_hex = functools.partial(hexmod.discretize_hex, serendipity=kw.pop("serendipity"))
    mesh = _mesh_for(shape)
    estimate = kw.pop("error_estimate", False)
    # "separately": the timed analysis without the estimate, then the same analysis with it
    separately = kw.pop("estimate_apart", False)
    t0 = time.perf_counter()
    m = analyze(mesh, ALU, method=method, f_max=f_max, error_estimate=estimate and not separately, cache=False, **kw)
    wall = time.perf_counter() - t0
    matched = match_modes(shape, m.frequencies_hz, m.points, m.shapes)
    err = float(m.error_estimate_cents)
    if separately:
        err = float(analyze(mesh, ALU, method=method, f_max=f_max, error_estimate=True, cache=False,
                            **kw).error_estimate_cents)
    return {"dofs": int(m.dofs), "wall_s": wall, "n_modes": int(m.n_modes), "matched": matched.tolist(),
            "model_method": m.method, "error_estimate_cents": err,
            "solve_s": float(m.info.get("solve_seconds", float("nan"))),
            "element": str(m.info.get("element", m.method)), "h": float(m.info.get("h_target", float("nan")))}


def _peer_point(shape, h):
    """Child: scikit-fem ElementTetP2 elasticity on the TetGen mesh used by mjsound's tet method."""
    import scipy.sparse.linalg as spla
    import skfem
    from skfem.helpers import dot
    from skfem.models.elasticity import lame_parameters, linear_elasticity

    from ..geometry import load_mesh
    from ..materials import get_material
    from ..modal.tet import tetrahedralize

    mat = get_material(ALU)
    tm = load_mesh(_mesh_for(shape))
    t0 = time.perf_counter()
    nodes, tets = tetrahedralize(tm, h)
    mesh = skfem.MeshTet(np.ascontiguousarray(nodes.T), np.ascontiguousarray(tets.T))
    basis = skfem.Basis(mesh, skfem.ElementVector(skfem.ElementTetP2()))
    K = linear_elasticity(*lame_parameters(mat.E, mat.nu)).assemble(basis)

    @skfem.BilinearForm
    def mass(u, v, w):
        return mat.rho * dot(u, v)

    M = mass.assemble(basis)
    k = 6 + SHAPES[shape]["peer_k"]
    # shift just below zero, as far down as the lowest audible eigenvalue (sigma = -1 leaves
    # K - sigma M nearly singular and the factorization loses the low modes' accuracy)
    lam, V = spla.eigsh(K, k=k, M=M, sigma=-0.5 * (2 * np.pi * 20.0) ** 2, which="LM")
    wall = time.perf_counter() - t0
    order = np.argsort(lam)
    lam, V = lam[order], V[:, order]
    lam, V = lam[6:], V[:, 6:]
    f = np.sqrt(np.maximum(lam, 0)) / (2 * np.pi)
    # vertex displacements: the vector basis interleaves components per global dof
    nv = mesh.p.shape[1]
    dofs = basis.nodal_dofs[:, :nv]  # (3, nv)
    U = np.stack([V[dofs[c]] for c in range(3)], axis=1)  # (nv, 3, n)
    matched = match_modes(shape, f, mesh.p.T, U)
    return {"dofs": int(K.shape[0]), "wall_s": wall, "n_modes": int(len(f)), "matched": matched.tolist(),
            "solve_s": float("nan"), "element": "skfem P2", "h": float(h)}


def _bowl_reference_point():
    """Child (not in the default plan): the converged bowl solve itself (~12 min, 3 GB)."""
    return _modal_point("bowl", "tet", {"order": 2, "resolution": 67})


def modal_plan(quick: bool):
    """``[(shape, label, method, kwargs)]``; method 'peer' is scikit-fem at ``kwargs['h']``."""
    if quick:
        return [
            ("beam", "hex draft", "hex", {"quality": "draft", "error_estimate": True, "estimate_apart": True}),
            ("beam", "hex default", "hex", {"quality": "default", "error_estimate": True, "estimate_apart": True}),
            ("beam", "tet10 h=20mm", "tet", {"order": 2, "resolution": 25}),
            ("beam", "skfem P2 h=20mm", "peer", {"h": 0.02}),
            ("beam", "shell", "shell", {}),
            ("rod", "hex draft", "hex", {"quality": "draft"}),
        ]
    plan = []
    for shape in ("beam", "rod", "sphere", "bowl"):
        for q in ("draft", "default", "high"):
            plan.append((shape, f"hex {q}", "hex", {"quality": q, "error_estimate": True, "estimate_apart": True}))
    plan += [
        ("beam", "hex res=80", "hex", {"resolution": 80, "quality": "high"}),
        ("beam", "hex res=120", "hex", {"resolution": 120, "quality": "high"}),
        ("rod", "hex res=80", "hex", {"resolution": 80, "quality": "high"}),
        ("bowl", "hex res=30", "hex", {"resolution": 30, "quality": "high"}),
        ("bowl", "hex res=45", "hex", {"resolution": 45, "quality": "high"}),
        ("beam", "hex27 default", "hex", {"quality": "default", "serendipity": False}),
        ("sphere", "hex27 default", "hex", {"quality": "default", "serendipity": False}),
        ("bowl", "hex27 default", "hex", {"quality": "default", "serendipity": False}),
        ("beam", "tet4 h=10mm", "tet", {"order": 1, "resolution": 50}),
        ("beam", "tet4 h=5mm", "tet", {"order": 1, "resolution": 100}),
        ("beam", "tet10 h=20mm", "tet", {"order": 2, "resolution": 25}),
        ("beam", "tet10 h=10mm", "tet", {"order": 2, "resolution": 50}),
        ("beam", "tet10 h=7mm", "tet", {"order": 2, "resolution": 70}),
        ("rod", "tet10 h=33mm", "tet", {"order": 2, "quality": "draft"}),
        ("rod", "tet10 h=16mm", "tet", {"order": 2, "quality": "default"}),
        ("sphere", "tet4 h=20mm", "tet", {"order": 1, "resolution": 10}),
        ("sphere", "tet10 h=40mm", "tet", {"order": 2, "resolution": 5}),
        ("bowl", "tet4 h=16mm", "tet", {"order": 1, "quality": "default"}),
        ("bowl", "tet10 h=16mm", "tet", {"order": 2, "quality": "default"}),
        ("beam", "skfem P2 h=20mm", "peer", {"h": 0.02}),
        ("beam", "skfem P2 h=10mm", "peer", {"h": 0.01}),
        ("rod", "skfem P2 h=33mm", "peer", {"h": 0.0326}),
        ("sphere", "skfem P2 h=40mm", "peer", {"h": 0.04}),
        ("bowl", "skfem P2 h=16mm", "peer", {"h": 0.0163}),
    ]
    plan += [("bowl", f"auto {q}", "auto", {"quality": q, "error_estimate": True, "estimate_apart": True})
             for q in ("draft", "default", "high")]
    plan += [(s, "shell", "shell", {}) for s in ("beam", "rod", "sphere", "bowl")]
    return plan


def run_modal(quick, log):
    rows = []
    for shape, label, method, kw in modal_plan(quick):
        refs = references(shape)
        if method == "peer":
            res = measure(_peer_point, (shape, kw["h"]), timeout=150)
        else:
            res = measure(_modal_point, (shape, method, dict(kw)), timeout=150)
        row = {"shape": shape, "label": label, "method": method, "peak_mb": res["peak_mb"], "error": res["error"]}
        if res["out"] is not None:
            out = res["out"]
            row.update(out)
            c = cents(np.array(out["matched"]), np.array([f for _, f in refs]))
            row["cents"] = c.tolist()
            fin = np.isfinite(c)
            row["missing"] = int((~fin).sum())
            row["rms_cents"] = float(np.sqrt(np.mean(c[fin] ** 2))) if fin.any() else float("nan")
            row["max_cents"] = float(np.max(np.abs(c[fin]))) if fin.any() else float("nan")
            if kw.get("error_estimate"):
                row["estimate_ratio"] = estimate_ratio(out["error_estimate_cents"], row["rms_cents"])
            else:
                row["error_estimate_cents"] = float("nan")
        log(f"  modal {shape:6s} {label:18s} " + (
            f"dofs {row.get('dofs', 0):7d}  {row.get('wall_s', float('nan')):7.2f} s  {row['peak_mb']:7.1f} MB  "
            f"rms {row.get('rms_cents', float('nan')):8.1f} c  missing {row.get('missing', '-')}"
            if res["out"] is not None else f"ERROR {res['error']}"))
        rows.append(row)
    return rows


def _fmax_point(f_max, method="hex", shape="bowl"):
    return _modal_point(shape, method, {"quality": "default", "f_max": f_max, "error_estimate": True})


#: f_max of the sweep per shape: every one from 2 to 20 kHz that has a reference below it
FMAX_SWEEP = {"beam": (2000.0, 5000.0, 10000.0, 20000.0), "rod": (2000.0, 5000.0, 10000.0, 20000.0),
              "sphere": (14500.0, 20000.0), "bowl": (2000.0, 3500.0, 5000.0, 10000.0, 20000.0)}


def run_fmax(quick, log):
    """Every shape at default quality over f_max (auto, and hex for the bowl): modes, dofs,
    time, memory, the error of the reference modes below f_max and the model's estimate."""
    rows = []
    sweep = [("bowl", "auto", 5000.0), ("beam", "auto", 2000.0)] if quick else [
        (shape, method, f) for shape, fs in FMAX_SWEEP.items()
        for method in (("auto", "hex") if shape == "bowl" else ("auto",)) for f in fs]
    for shape, method, f_max in sweep:
        res = measure(_fmax_point, (f_max, method, shape), timeout=600)
        out = res["out"] or {}
        ref = np.array([f for _, f in references(shape)])
        got = np.asarray([np.nan if x is None else x for x in out.get("matched", [])], float)
        below = ref < f_max * 0.999
        ok = np.isfinite(got) & below if len(got) else np.zeros(0, bool)
        c = cents(got[ok], ref[ok]) if len(got) else np.zeros(0)
        rms = float(np.sqrt(np.mean(c**2))) if len(c) else float("nan")
        est = out.get("error_estimate_cents", float("nan"))
        rows.append({"shape": shape, "method": out.get("model_method", method), "f_max": f_max,
                     "wall_s": out.get("wall_s", float("nan")), "n_modes": out.get("n_modes", 0),
                     "dofs": out.get("dofs", 0), "peak_mb": res["peak_mb"], "compared": int(below.sum()),
                     "missing": int(below.sum() - ok.sum()), "rms_cents": rms,
                     "max_cents": float(np.max(np.abs(c))) if len(c) else float("nan"),
                     "estimate_cents": est, "estimate_ratio": estimate_ratio(est, rms),
                     "error": res["error"]})
        log(f"  {shape} {method} f_max {f_max:7.0f} Hz: {rows[-1]['n_modes']} modes, {rows[-1]['wall_s']:.2f} s, "
            f"{rows[-1]['rms_cents']:.1f} c RMS, estimate {est:.1f} c")
    return rows


def estimate_ratio(estimate, rms):
    """The model's error estimate over the measured RMS error (nan where either is unknown)."""
    if not (np.isfinite(estimate) and np.isfinite(rms) and rms > 0):
        return float("nan")
    return float(estimate / rms)


def fmax_markdown(fmax, fmt) -> list:
    """Markdown lines of the f_max sweep's table (:func:`run_fmax` rows); ``fmt(x, spec)``
    formats a number ('-' for nan)."""
    L = []
    w = L.append
    _f = fmt
    w("### What f_max costs in the analysis, and what the reference modes get (default quality)")
    w("")
    w("Every shape above at default quality over f_max (2 to 20 kHz, those with a reference mode below "
      "it): the error of the reference modes below f_max (the bowl: its first eight), against the "
      "closed forms or the converged reference; estimate: the model's own `error_estimate_cents` (wall "
      "time here includes its coarser solve). auto = the per-object choice (`facet` shell for the bowl, "
      "hex for the others); the bowl also with hex.")
    w("")
    w("| shape | method | f_max [Hz] | modes | dofs | wall [s] | peak mem [MB] | compared | missing | "
      "RMS [c] | max [c] | estimate [c] | estimate / RMS |")
    w("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in fmax:
        w(f"| {r.get('shape', 'bowl')} | {r.get('method', 'hex')} | {r['f_max']:.0f} | {r['n_modes']} | {r['dofs']} | "
          f"{_f(r['wall_s'], '{:.2f}')} | {_f(r['peak_mb'], '{:.0f}')} | {r.get('compared', '-')} | "
          f"{r.get('missing', '-')} | {_f(r.get('rms_cents', float('nan')), '{:.2f}')} | "
          f"{_f(r.get('max_cents', float('nan')), '{:.2f}')} | {_f(r.get('estimate_cents', float('nan')), '{:.2f}')} | "
          f"{_f(r.get('estimate_ratio', float('nan')), '{:.2f}')} |")
    w("")
    return L
