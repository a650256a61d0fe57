r"""Stability on stiff and extreme cases: a PASS/FAIL table with the measured quantity.

``mjsound report stability [--quick] [-o FILE]`` runs every case and prints one row each.

Pass criteria
-------------
* finite output (no NaN / Inf anywhere, no exception other than a clear ``ValueError``
  where the input is refused);
* bounded by the closed form: an impulse J at point x gives mode i the amplitude
  ``|phi_i(x) . J| / omega_d,i`` (times ``|S_i| <= 1`` for the half-sine pulse), so the
  pressure at a microphone at distance r can never exceed
  ``B = sum_events sum_i |w_i| |phi_i(x) . J| / (omega_d,i r)`` (``w_i`` the synthesizer's
  radiation weight); every row that renders checks ``max|p| <= B``;
* no drift: where a closed-form reference is computed (``p[n] = sum Im(c_i w_i / r
  e^{lambda_i (n / fs - t_a)})`` in float64 numpy), the rendered samples match it to the
  stated tolerance, including after an hour of ringing, and sample counts are exact;
* a refused input raises ``ValueError`` with a message (not ``ZeroDivisionError``,
  ``IndexError`` ... and not a hang or an out-of-memory crash: analyses run in a child
  process under a time and memory limit).

A FAIL row is a bug to fix in the code, never a reason to drop the row.

The cases analyse without the boundary-element radiation (``radiation=False``, the compact
estimate's pattern): they test the eigen-solve and the synthesis on hostile input under a
time limit; the radiation's accuracy and cost have their own tests and report section.
"""

from __future__ import annotations

import math
import os
import time

import numpy as np

from .measure import cents

__all__ = ["run_report", "run_cases", "closed_form", "amplitude_bound"]

FS = 48000


class Row:
    def __init__(self, case, inp, ok, measured, seconds):
        self.case, self.inp, self.ok, self.measured, self.seconds = case, inp, bool(ok), measured, seconds

    def as_dict(self):
        return {"case": self.case, "input": self.inp, "pass": self.ok, "measured": self.measured,
                "seconds": self.seconds}


# ---------------------------------------------------------------------------- helpers
def _obj(syn, name):
    return syn.object_modes(name)


def amplitude_bound(syn, name, points, impulses) -> float:
    """Closed-form bound on |p| at any microphone for impulses J at points (module docstring)."""
    ob = _obj(syn, name)
    P = np.asarray(points, float).reshape(-1, 3)
    J = np.asarray(impulses, float).reshape(-1, 3)
    Pl = (P - ob.position) @ ob.rotation
    Jl = J @ ob.rotation
    idx = ob.model.nearest_points(Pl)
    G = np.abs(np.einsum("kcn,kc->kn", ob.shapes[idx], Jl)).sum(axis=0)  # (n,)
    r = float(np.min(ob.mic_distances))
    # the loudest direction any channel hears each mode in (1 where it is heard the same everywhere)
    gain = np.abs(ob.weights) * np.nanmax(np.abs(_direction_factors(syn, name)), axis=0, initial=1.0)
    return float(np.sum(gain * G / ob.damped_omega) / r)


def _direction_factors(syn, name):
    """(channels, n_modes) complex factors ``D`` each channel hears ``name``'s modes with, as
    the renderer last set them (NaN, for a mode nothing excited yet, becomes 1)."""
    D = syn.direction_factors(name)
    return np.where(np.isnan(D), 1.0, D)


def closed_form(syn, name, points, impulses, times, n0, n1, mic=0):
    """Float64 reference samples n0..n1-1 for ideal impulses (pulse_s=0) on ``name``."""
    ob = _obj(syn, name)
    fs = syn.sample_rate
    P = np.asarray(points, float).reshape(-1, 3)
    J = np.asarray(impulses, float).reshape(-1, 3)
    T = np.broadcast_to(np.asarray(times, float), (len(P),))
    Pl = (P - ob.position) @ ob.rotation
    Jl = J @ ob.rotation
    idx = ob.model.nearest_points(Pl)
    G = np.einsum("kcn,kc->kn", ob.shapes[idx], Jl)
    r = float(ob.mic_distances[mic])
    D = _direction_factors(syn, name)[mic]  # the pattern in the microphone's direction
    # events at the same time superpose exactly: sum their modal amplitudes first
    tu, inv = np.unique(T, return_inverse=True)
    Gu = np.zeros((len(tu), G.shape[1]))
    np.add.at(Gu, inv, G)
    ta = tu + r / syn.speed_of_sound
    na = np.ceil(ta * fs - 1e-6).astype(np.int64)
    n = np.arange(n0, n1)
    out = np.zeros(len(n))
    for k in range(len(tu)):
        c = Gu[k] / ob.damped_omega * ob.weights * D / r  # (modes,)
        live = n >= na[k]
        if not live.any():
            continue
        # sum over modes in chunks (exact exponent, no recursion)
        tt = n[live] / fs - ta[k]
        acc = np.zeros(live.sum())
        lam = -ob.decay + 1j * ob.damped_omega
        for a in range(0, len(c), 64):
            acc += np.imag(np.exp(np.outer(tt, lam[a:a + 64])) @ c[a:a + 64])
        out[live] += acc
    return out


def _err_db(y, ref):
    den = np.sqrt(np.mean(ref**2))
    num = np.sqrt(np.mean((np.asarray(y, float) - ref) ** 2))
    return 20 * math.log10(max(num, 1e-300) / den) if den > 0 else float("nan")


def _child_limited(fn, args, timeout, mem_gb):
    """Run in a forked child with a time limit and an address-space limit."""
    from .measure import measure

    def limited(*a):
        import resource

        lim = int(mem_gb * 2**30)
        try:
            resource.setrlimit(resource.RLIMIT_AS, (lim, lim))
        except (ValueError, OSError):
            pass
        return fn(*a)

    return measure(limited, args, timeout=timeout)


def _analyze_summary(mesh, material, kw):
    from ..modal.analyze import analyze

    t0 = time.perf_counter()
    m = analyze(mesh, material, error_estimate=False, cache=False, **{"radiation": False, **kw})
    return {"n_modes": int(m.n_modes), "dofs": int(m.dofs), "f": m.frequencies_hz[:12].tolist(),
            "finite": bool(np.all(np.isfinite(m.shapes)) and np.all(np.isfinite(m.frequencies_hz))),
            "seconds": time.perf_counter() - t0, "n_overdamped": int(m.info.get("n_overdamped", 0)),
            "n_rigid": int(m.info.get("n_rigid", -1))}


def _model(mesh, material, **kw):
    from ..modal.analyze import analyze

    return analyze(mesh, material, error_estimate=False, progress=False, **{"radiation": False, **kw})


def _strike(model, fs=FS, J=(0.0, 0.0, -1e-2), dur=0.5, dtype="float32", pulse_s=0.0, t=0.0, **kw):
    """Impact at the first surface point; returns (y, bound, syn, point, J)."""
    from ..synth.synthesizer import Synthesizer

    syn = Synthesizer(fs, microphones=[[0.0, -0.5, 0.3]], dtype=dtype, **kw)
    syn.add_object("o", model)
    p = np.asarray(model.points[0], float) if len(model.points) else np.zeros(3)
    syn.impact("o", p, J, t, pulse_s=pulse_s)
    y = syn.render(int(round(dur * fs)))[0].astype(np.float64)
    b = amplitude_bound(syn, "o", p, J) if len(_obj(syn, "o").keep) else 0.0
    return y, b, syn, p, np.asarray(J, float)


def _bounded(y, b):
    m = float(np.max(np.abs(y))) if len(y) else 0.0
    return np.all(np.isfinite(y)) and m <= b * (1 + 1e-3) + 1e-30, m


# ---------------------------------------------------------------------------- cases
def case_bead(quick):
    t0 = time.perf_counter()
    m = _model("sphere:0.001", "steel", sample_rate=FS, cache=False)
    y, b, syn, _, _ = _strike(m)
    ok = m.n_modes == 0 and np.all(y == 0) and np.all(np.isfinite(y))
    return [Row("2 mm steel bead", "sphere r=1 mm, steel, 48 kHz", ok,
                f"{m.n_modes} modes below {0.45 * FS / 1000:.1f} kHz (lowest ~{2.65 * math.sqrt(77.5e9 / 7850) / (2 * math.pi * 1e-3) / 1e6:.1f} MHz); "
                f"output max {np.max(np.abs(y)):.1g} Pa, no error", time.perf_counter() - t0)]


def case_stiff(quick):
    from ..materials import get_material

    rows = []
    t0 = time.perf_counter()
    kw = dict(quality="draft", f_max=3000.0, cache=False)
    al = _model("box:0.5,0.01,0.01", "aluminium", **kw)
    a = get_material("aluminium")
    for name in ("tungsten_carbide", "diamond"):
        t1 = time.perf_counter()
        mat = get_material(name)
        m = _model("box:0.5,0.01,0.01", name, **{**kw, "f_max": 3000.0 * math.sqrt((mat.E / mat.rho) / (a.E / a.rho))})
        expect = al.frequencies_hz[0] * math.sqrt((mat.E / mat.rho) / (a.E / a.rho))
        c = 1200 * math.log2(m.frequencies_hz[0] / expect)
        y, b, _, _, _ = _strike(m)
        okb, mx = _bounded(y, b)
        ok = okb and abs(c) < 5.0 and m.n_modes > 0
        rows.append(Row(f"very stiff: {name}", f"beam 0.5x0.01x0.01 m, E={mat.E / 1e9:.0f} GPa, hex draft", ok,
                        f"f1 = {m.frequencies_hz[0]:.1f} Hz, {c:+.2f} cents vs aluminium x sqrt(E/rho); "
                        f"max|p| = {mx / b:.3f} of bound", time.perf_counter() - t1))
    rows[0].seconds += 0 * t0
    return rows


def case_damping(quick):
    from ..materials import get_material

    rows = []
    t0 = time.perf_counter()
    al = _model("box:0.5,0.01,0.01", "aluminium,alpha=0,beta=0", quality="draft", f_max=3000.0, cache=False)
    y, b, syn, p, J = _strike(al, dur=2.0)
    okb, mx = _bounded(y, b)
    ref = closed_form(syn, "o", p, J, 0.0, 0, len(y))
    e = _err_db(y, ref)
    d = float(np.min(_obj(syn, "o").decay))
    rows.append(Row("nearly undamped", "aluminium alpha=beta=0 (beam, 2 s)", okb and e < -60 and d > 0,
                    f"decay floored at {d:g} 1/s; error vs closed form {e:.1f} dB; max|p| = {mx / b:.3f} of bound",
                    time.perf_counter() - t0))
    # overdamped: rubber (d_i = (alpha + beta w^2)/2 >= w above ~3.2 kHz) at the default settings
    from ..geometry import load_mesh
    from ..modal.analyze import element_size

    rub = get_material("rubber")
    t0 = time.perf_counter()
    tm = load_mesh("box:0.1,0.05,0.05")
    h = element_size(tm, rub, 0.45 * FS, "draft")
    est = 3 * np.prod(np.ceil(tm.extents / h) + 1)
    f_od = (1 + math.sqrt(max(0.0, 1 - rub.alpha * rub.beta))) / rub.beta / (2 * math.pi)
    kw = {"quality": "draft", "sample_rate": FS}
    res = _child_limited(_analyze_summary, ("box:0.1,0.05,0.05", "rubber", kw), 20 if quick else 60, 6)
    out = res["out"]
    inp = "rubber block 10x5x5 cm, hex draft, sample_rate 48 kHz (default f_max)"
    if out is None:
        rows.append(Row("overdamped (rubber)", inp, False,
                        f"{str(res['error'])[:110]} after {time.perf_counter() - t0:.0f} s: element size "
                        f"{h * 1000:.2f} mm from the shear wave at f_max = 21.6 kHz -> ~{est / 1e6:.1f} M dofs, "
                        f"although every mode above {f_od / 1000:.1f} kHz is overdamped", time.perf_counter() - t0))
        return rows
    m = _model("box:0.1,0.05,0.05", "rubber", cache=False, **kw)
    y, b, syn, _, _ = _strike(m, J=(0, 0, -1e-3))
    okb, mx = _bounded(y, b)
    under = bool(np.all(m.decay_per_s < m.omega))
    rows.append(Row("overdamped (rubber)", inp, okb and under and m.n_modes > 0 and out["finite"],
                    f"{m.n_modes} modes kept (analysis band capped at {m.info.get('f_max', float('nan')):.0f} Hz, "
                    f"overdamped above {f_od:.0f} Hz), {out['n_overdamped']} overdamped dropped, {out['dofs']} dofs, "
                    f"{out['seconds']:.1f} s; all kept d < omega: {under}; max|p| = {mx / max(b, 1e-300):.3f} of bound",
                    time.perf_counter() - t0))
    return rows


def case_pane(quick):
    from ..materials import get_material

    t0 = time.perf_counter()
    f_max = 150.0 if quick else 1000.0
    g = get_material("glass")
    m = _model("box:2,2,0.004", "glass", quality="default", f_max=f_max, cache=False)
    t_an = time.perf_counter() - t0
    D = g.E * 0.004**3 / (12 * (1 - g.nu**2))
    # Weyl's law for a plate, N(f) = A k^2 / (4 pi), k^2 = omega sqrt(rho h / D), in the band 20 Hz..f_max
    weyl = 4.0 * 2 * math.pi * (f_max - 20.0) * math.sqrt(g.rho * 0.004 / D) / (4 * math.pi)
    y, b, syn, _, _ = _strike(m, J=(0, 0, -0.01), dur=1.0)
    okb, mx = _bounded(y, b)
    ok = okb and 0.6 < m.n_modes / weyl < 1.6
    return [Row("large thin pane", f"glass 2 m x 2 m x 4 mm, f_max {f_max:.0f} Hz, hex default", ok,
                f"{m.n_modes} modes (plate Weyl estimate {weyl:.0f}), {m.dofs} dofs, analysis {t_an:.1f} s; "
                f"max|p| = {mx / b:.3f} of bound", time.perf_counter() - t0)]


def _bowl():
    return _model("bowl:0.1,0.004", "aluminium", quality="draft", f_max=12000.0, cache=True)


def case_sample_rates(quick):
    rows = []
    bowl = _bowl()
    for fs in (8000, 16000, 22050, 44100, 48000, 96000, 192000):
        t0 = time.perf_counter()
        y, b, syn, p, J = _strike(bowl, fs=fs, dur=0.25, t=0.003)
        okb, mx = _bounded(y, b)
        ref = closed_form(syn, "o", p, J, 0.003, 0, len(y))
        e = _err_db(y, ref)
        n_ok = len(y) == round(0.25 * fs)
        top = float(np.max(bowl.frequencies_hz[_obj(syn, "o").keep])) if len(_obj(syn, "o").keep) else 0.0
        ok = okb and n_ok and e < -60 and top < 0.45 * fs
        rows.append(Row("sample rate", f"{fs} Hz (bowl, hex draft, modes to 12 kHz)", ok,
                        f"{syn.n_modes('o')} modes (top {top:.0f} Hz < 0.45 fs); {len(y)} samples; "
                        f"error vs closed form {e:.1f} dB; max|p| = {mx / b:.3f} of bound", time.perf_counter() - t0))
    return rows


def case_timesteps(quick):
    import mujoco

    from ..sim.scene import SoundScene
    from ..sim.simulator import AudioSimulator
    from .accuracy_e2e import E2E_MATERIALS, E2E_MIC, E2E_XML

    rows = []
    dur = 0.15
    xml = E2E_XML.replace('pos="0.023 0.011 0.25"', 'pos="0.023 0.011 0.06"')
    base = mujoco.MjModel.from_xml_string(xml.format(dt=0.001))
    scene0 = SoundScene.from_model(base, materials=E2E_MATERIALS, microphones=E2E_MIC, quality="draft", progress=False)
    models = {s.name: s.model for s in scene0.sounding}
    for dt in (1e-5, 1e-4, 1e-3, 0.01, 0.02):
        t0 = time.perf_counter()
        model = mujoco.MjModel.from_xml_string(xml.format(dt=dt))
        scene = SoundScene.from_model(model, materials=E2E_MATERIALS, microphones=E2E_MIC, quality="draft",
                                      progress=False, models=models)
        sim = AudioSimulator(model, scene=scene, sample_rate=FS, clicks=False)  # (the bound is the modes')
        ts = time.perf_counter()
        y = sim.run(dur)[0].astype(np.float64)
        wall = time.perf_counter() - ts
        n_exp = math.ceil(round(round(dur / dt) * dt, 12) * FS)
        ob = _obj(sim.synth, "plate")
        r = float(np.min(ob.mic_distances))
        phimax = np.max(np.linalg.norm(ob.shapes, axis=1), axis=0)  # (n,)
        gp = scene.by_geom()
        plate_hits = [e for e in sim.event_log if e[1] == "impact" and (e[2] in gp or e[3] in gp)]
        Jsum = sum(abs(float(e[4])) for e in plate_hits)
        b = Jsum * float(np.sum(np.abs(ob.weights) * phimax / ob.damped_omega)) / r
        okb, mx = _bounded(y, b)
        ok = okb and len(y) == n_exp and np.all(np.isfinite(y))
        rows.append(Row("physics timestep", f"dt = {dt:g} s, drop scene, {dur} s", ok,
                        f"{len(y)} samples (expected {n_exp}); {len(plate_hits)} of {sim.events['impact']} impacts on the plate; "
                        f"max|p| = {mx:.3g} Pa = {mx / b if b > 0 else 0:.3f} of bound; RTF {dur / wall:.1f}",
                        time.perf_counter() - t0))
    return rows


def case_impulses(quick):
    rows = []
    bowl = _bowl()
    y1, b1, *_ = _strike(bowl, J=(0, 0, -1.0), dur=0.3)
    for mag in (1e-9, 1e-6, 1e-3, 1.0, 1e3, 1e5):
        t0 = time.perf_counter()
        y, b, *_ = _strike(bowl, J=(0, 0, -mag), dur=0.3)
        okb, mx = _bounded(y, b)
        lin = float(np.max(np.abs(y / mag - y1)) / np.max(np.abs(y1)))
        yh, bh, *_ = _strike(bowl, J=(0, 0, -mag), dur=0.3, pulse_s=None)  # Hertz pulse
        okh, mxh = _bounded(yh, bh)
        ok = okb and okh and lin < 1e-4
        rows.append(Row("impulse", f"|J| = {mag:g} N s (bowl)", ok,
                        f"max|p| = {mx:.3g} Pa ({mx / b:.3f} of bound); linearity error {lin:.1e}; "
                        f"Hertz pulse {mxh / bh:.3f} of bound", time.perf_counter() - t0))
    return rows


def case_contacts(quick):
    from ..synth.synthesizer import Synthesizer

    bowl = _bowl()
    rng = np.random.default_rng(0)
    k = 10000
    idx = rng.integers(0, len(bowl.points), k)
    P = np.asarray(bowl.points, float)[idx]
    J = -np.asarray(bowl.normals, float)[idx] * rng.uniform(1e-5, 1e-3, (k, 1))
    t0 = time.perf_counter()
    syn = Synthesizer(FS, microphones=[[0.0, -0.5, 0.3]])
    syn.add_object("o", bowl)
    syn.impacts("o", P, J, np.full(k, 0.001), pulse_s=0.0)
    y = syn.render(int(0.2 * FS))[0].astype(np.float64)
    wall = time.perf_counter() - t0
    b = amplitude_bound(syn, "o", P, J)
    okb, mx = _bounded(y, b)
    # superposition: every impulse's modal amplitude summed, as one closed-form sum
    ref = closed_form(syn, "o", P, J, np.full(k, 0.001), 0, len(y))
    e = _err_db(y, ref)
    return [Row("simultaneous contacts", f"{k} impacts at once (bowl)", okb and e < -60,
                f"add + render 0.2 s: {wall:.2f} s; error vs closed-form superposition {e:.1f} dB; "
                f"max|p| = {mx / b:.3f} of bound", wall)]


def case_hour(quick):
    from ..modal.model import ModalModel
    from ..synth.synthesizer import Synthesizer

    rows = []
    base = _model("box:0.5,0.01,0.01", "aluminium", quality="draft", f_max=3000.0, cache=True)
    m8 = base.truncated(n_modes=8)
    m8 = ModalModel(m8.frequencies_hz, np.full(m8.n_modes, 1e-3), m8.points, m8.normals, m8.shapes,
                    m8.radiation, m8.material, mass_kg=m8.mass_kg)
    for dtype in (("float32",) if quick else ("float32", "float64")):
        t0 = time.perf_counter()
        syn = Synthesizer(FS, microphones=[[0.0, -0.5, 0.3]], dtype=dtype)
        syn.add_object("o", m8)
        p = np.asarray(m8.points[0], float)
        J = np.array([0.0, 0.3, -1.0]) * 1e-2
        syn.impact("o", p, J, 0.0, pulse_s=0.0)
        total = 3600 * FS
        block = 10 * FS
        peak = 0.0
        finite = True
        for _ in range(total // block - 1):
            y = syn.render(block)
            peak = max(peak, float(np.max(np.abs(y))))
            finite &= bool(np.all(np.isfinite(y)))
        y = syn.render(block)[0].astype(np.float64)
        n0 = total - block
        tail = slice(block - 4800, block)
        ref = closed_form(syn, "o", p, J, 0.0, n0 + block - 4800, n0 + block)
        e = _err_db(y[tail], ref)
        b = amplitude_bound(syn, "o", p, J)
        env = 20 * math.log10(np.sqrt(np.mean(y[tail] ** 2)) / np.sqrt(np.mean(ref**2)))
        # float32: the exact-pole correction cancels the rounded pole, not the rounding of each
        # sample's complex multiply, whose drift depends on the machine code (fused multiply-adds,
        # vector order). Measured on one host: -56.1 dB from numba's cached kernels, -44.6 dB when
        # the same source is compiled in the process, -25.1 dB (level -0.49 dB) with
        # NUMBA_CPU_NAME=generic (no FMA). -40 dB (1 % after an hour) holds on FMA machines;
        # float64 is the exact path.
        ok = finite and peak <= b * (1 + 1e-3) and e < (-40 if dtype == "float32" else -80)
        rows.append(Row("an hour of ringing", f"8 modes, d = 1e-3 1/s, {dtype}, 3600 s at 48 kHz", ok,
                        f"last 0.1 s vs closed form: error {e:.1f} dB, level {env:+.4f} dB; "
                        f"peak {peak / b:.3f} of bound; {total} samples in {time.perf_counter() - t0:.1f} s",
                        time.perf_counter() - t0))
    return rows


# ---------------------------------------------------------------------------- degenerate meshes
def _box_unmerged():
    import trimesh

    b = trimesh.creation.box(extents=(0.2, 0.1, 0.01))
    V = b.vertices[b.faces].reshape(-1, 3)
    F = np.arange(len(V)).reshape(-1, 3)
    return V, F


def _nonmanifold():
    import trimesh

    a = trimesh.creation.box(extents=(0.05, 0.05, 0.05))
    b = trimesh.creation.box(extents=(0.05, 0.05, 0.05))
    b.apply_translation((0.05, 0.05, 0.0))  # shares one edge with a: 4 faces on that edge
    m = trimesh.util.concatenate([a, b])
    return np.asarray(m.vertices), np.asarray(m.faces)


def _flat_square():
    return np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float) * 0.1, np.array([[0, 1, 2], [0, 2, 3]])


def _collinear():
    return np.array([[0, 0, 0], [0.05, 0, 0], [0.1, 0, 0]], float), np.array([[0, 1, 2]])


def _sliver_cylinder():
    import trimesh

    return trimesh.creation.cylinder(radius=0.01, height=0.3, sections=1500)


def _big_sphere(subdiv):
    import trimesh

    return trimesh.creation.icosphere(subdivisions=subdiv, radius=0.1)


def _degenerate_case(label, inp, builder, kw, ref_builder=None, expect_error=False, tol_cents=15.0,
                     timeout=90, mem_gb=8):
    t0 = time.perf_counter()

    def job():
        mesh = builder()
        out = _analyze_summary(mesh, "aluminium", dict(kw))
        if ref_builder is not None:
            out["ref"] = _analyze_summary(ref_builder(), "aluminium", dict(kw))["f"]
        return out

    res = _child_limited(job, (), timeout, mem_gb)
    out, err = res["out"], res["error"]
    secs = time.perf_counter() - t0
    if out is None:
        clear = err is not None and err.startswith("ValueError") and len(err) > 30
        meas = f"refused: {err[:160]}" if clear else f"{err[:200]}"
        return Row("degenerate mesh", f"{label}: {inp}", clear, meas, secs)
    if expect_error and out["n_modes"] == 0:
        return Row("degenerate mesh", f"{label}: {inp}", False, f"no error and no modes ({out})", secs)
    meas = f"{out['n_modes']} modes, {out['dofs']} dofs, {out['seconds']:.1f} s analysis; finite: {out['finite']}"
    ok = out["finite"] and out["n_modes"] > 0
    if out.get("ref") is not None and out["n_modes"]:
        m = min(len(out["ref"]), len(out["f"]), 6)
        c = np.max(np.abs(cents(out["f"][:m], out["ref"][:m])))
        meas += f"; first {m} modes within {c:.2f} cents of the clean mesh"
        ok = ok and c < tol_cents
    return Row("degenerate mesh", f"{label}: {inp}", ok, meas, secs)


def case_degenerate(quick):
    import trimesh

    kw = {"quality": "draft", "f_max": 2500.0}
    cyl64 = lambda: trimesh.creation.cylinder(radius=0.01, height=0.3, sections=64)  # noqa: E731
    rows = [
        _degenerate_case("slivers", "rod r=1 cm L=30 cm, 1500 sections (0.24 deg cap triangles, side quads "
                         "0.04 x 300 mm), hex", _sliver_cylinder, kw, ref_builder=cyl64),
        _degenerate_case("slivers", "same, tet10", _sliver_cylinder, {**kw, "method": "tet"}, ref_builder=cyl64,
                         timeout=20 if quick else 120),
        _degenerate_case("duplicate vertices", "plate 20x10x1 cm, every triangle's vertices unmerged (STL soup)",
                         _box_unmerged, kw, ref_builder=lambda: trimesh.creation.box(extents=(0.2, 0.1, 0.01)),
                         tol_cents=0.01),
        _degenerate_case("zero volume", "flat 10 cm square (2 triangles), hex, no thickness", _flat_square, kw),
        _degenerate_case("zero volume", "flat 10 cm square, thickness=2 mm, hex", _flat_square,
                         {**kw, "thickness": 0.002}),
        _degenerate_case("zero volume", "flat square, tet", _flat_square, {**kw, "method": "tet"}),
        _degenerate_case("zero area", "3 collinear vertices", _collinear, kw),
        _degenerate_case("non-manifold", "two 5 cm cubes sharing an edge, hex", _nonmanifold,
                         {**kw, "f_max": 20000.0}),
        _degenerate_case("non-manifold", "two cubes sharing an edge, tet", _nonmanifold, {**kw, "method": "tet"}),
    ]
    subdiv = 7 if quick else 8
    big = _degenerate_case("1e6 triangles" if subdiv == 8 else "3e5 triangles (quick; 1.3e6 in the full run)", f"icosphere r=10 cm, {20 * 4 ** subdiv} triangles, hex draft",
                           lambda: _big_sphere(subdiv), {"quality": "draft", "f_max": 16000.0},
                           timeout=120 if quick else 300)
    rows.append(big)
    return rows


CASES = [case_bead, case_stiff, case_damping, case_pane, case_sample_rates, case_timesteps, case_impulses,
         case_contacts, case_hour, case_degenerate]


def run_cases(quick=True, log=None):
    rows = []
    for fn in CASES:
        t0 = time.perf_counter()
        try:
            got = fn(quick)
        except Exception as exc:  # a crash of the case itself is a FAIL row, not a crash of the table
            got = [Row(fn.__name__.replace("case_", ""), "-", False, f"{type(exc).__name__}: {exc}",
                       time.perf_counter() - t0)]
        if log:
            log(f"      ({fn.__name__}: {time.perf_counter() - t0:.1f} s)")
        for r in got:
            rows.append(r)
            if log:
                log(f"{'PASS' if r.ok else 'FAIL'}  {r.case:22s} {r.inp:58s} {r.measured}  [{r.seconds:.1f} s]")
    return rows


def to_markdown(rows, header=""):
    L = [header, "", "| result | case | input | measured | s |", "|---|---|---|---|---:|"]
    for r in rows:
        L.append(f"| {'PASS' if r.ok else '**FAIL**'} | {r.case} | {r.inp} | {r.measured} | {r.seconds:.1f} |")
    n_fail = sum(not r.ok for r in rows)
    L += ["", f"{len(rows) - n_fail} of {len(rows)} cases pass."]
    return "\n".join(L) + "\n"


def run_report(quick: bool = False, output=None, hostile: bool = True) -> int:
    """Run every case (and, with ``hostile``, the hostile-input and interruption cases of
    :mod:`mjsound.report.hostile`), print the tables and optionally write them as Markdown to
    ``output`` (a file, or a directory for ``DIR/stability.md``). Returns the exit status (1
    if any case fails)."""
    from . import hostile as hostile_report
    from .measure import machine_info

    info = machine_info()
    t0 = time.perf_counter()
    rows = run_cases(quick, log=lambda s: print(s, flush=True))
    secs = time.perf_counter() - t0
    n_fail = sum(not r.ok for r in rows)
    print(f"\n{len(rows) - n_fail} of {len(rows)} cases pass ({secs:.0f} s).")
    h_rows, h_secs = [], 0.0
    if hostile:
        t1 = time.perf_counter()
        h_rows = hostile_report.run_hostile_cases(quick, log=lambda s: print(s, flush=True))
        h_secs = time.perf_counter() - t1
        n_fail += sum(not r.ok for r in h_rows)
    if output:
        head = (f"# mjsound stability{' (quick)' if quick else ''}\n\n"
                f"Generated by `mjsound report stability{' --quick' if quick else ''} -o {output}` on "
                f"{info['date']} in {secs + h_secs:.0f} s. Machine: {info['platform']}, {info['processor']}, "
                f"{info['cpus']} CPUs, Python {info['python']}, numpy {info['numpy']}; load average at the start "
                f"{info['load_start']} (shared machine).\n\n" + __doc__.split("Pass criteria\n-------------\n")[1]
                .split("A FAIL row")[0].strip())
        text = to_markdown(rows, head)
        if h_rows:
            crit = hostile_report.__doc__.split("Pass criteria\n-------------\n")[1].strip()
            how = hostile_report.__doc__.split("\n\n")[1].strip()
            text += ("\n## Hostile inputs and interruptions\n\n" + how + "\n\n" + crit + "\n\n"
                     + hostile_report.to_markdown(h_rows))
        path = output
        if os.path.isdir(path) or path.endswith(os.sep):
            path = os.path.join(path, "stability.md")
        from ..io import atomic_open

        with atomic_open(path) as fh:
            fh.write(text)
        print(f"wrote {path}")
    return 1 if n_fail else 0
