r"""Accuracy end to end against the real-time factor (the accuracy report's last section).

End to end
----------
A steel ball dropped on an aluminium plate (MJCF inline), simulated with
:class:`mjsound.sim.AudioSimulator` at several physics timesteps and analysis qualities; the
1/3-octave band levels of the sound are compared with the finest run, against the real-time
factor (simulated seconds per wall-clock second, physics and sound together).
"""

from __future__ import annotations

import math
import time

import numpy as np

__all__ = ["run_e2e", "third_octave_levels", "E2E_XML", "E2E_MATERIALS", "E2E_MIC"]

E2E_XML = """<mujoco model="drop">
  <option timestep="{dt}"/>
  <worldbody>
    <geom name="floor" type="plane" size="1 1 0.1"/>
    <geom name="plate" type="box" size="0.1 0.075 0.004" pos="0 0 0.004"/>
    <body name="ball" pos="0.023 0.011 0.25">
      <freejoint/>
      <geom name="ball" type="sphere" size="0.01" density="7850"/>
    </body>
  </worldbody>
</mujoco>"""
E2E_MATERIALS = {"plate": "aluminium", "ball": "steel", "floor": None}
E2E_MIC = [[0.0, -0.4, 0.3]]


def third_octave_levels(y, fs, f_lo=50.0, f_hi=20000.0):
    """Band centres [Hz] and energies [dB] of 1/3-octave bands (FFT binning)."""
    Y = np.abs(np.fft.rfft(y)) ** 2
    f = np.fft.rfftfreq(len(y), 1 / fs)
    centres = 1000.0 * 2.0 ** (np.arange(-13, 14) / 3.0)
    centres = centres[(centres >= f_lo) & (centres <= min(f_hi, 0.45 * fs))]
    lev = []
    for c in centres:
        sel = (f >= c * 2 ** (-1 / 6)) & (f < c * 2 ** (1 / 6))
        lev.append(10 * math.log10(max(Y[sel].sum(), 1e-300)))
    return centres, np.array(lev)


def _e2e_run(dt, quality, models=None, duration=0.6, fs=48000, cache=True):
    import mujoco

    from ..sim.scene import SoundScene
    from ..sim.simulator import AudioSimulator

    model = mujoco.MjModel.from_xml_string(E2E_XML.format(dt=dt))
    t0 = time.perf_counter()
    scene = SoundScene.from_model(model, materials=E2E_MATERIALS, microphones=E2E_MIC, sample_rate=fs,
                                  quality=quality, progress=False, models=models, cache=cache)
    t_an = time.perf_counter() - t0
    sim = AudioSimulator(model, scene=scene, sample_rate=fs)
    t0 = time.perf_counter()
    y = sim.run(duration)[0].astype(np.float64)
    wall = time.perf_counter() - t0
    mm = {s.name: s.model for s in scene.sounding}
    n_modes = sum(m.n_modes for m in mm.values())
    return {"y": y, "wall_s": wall, "rtf": duration / wall, "analysis_s": t_an, "n_modes": n_modes,
            "impacts": sim.events["impact"], "models": mm, "samples": len(y)}


def run_e2e(quick, log):
    fs = 48000
    dur = 0.4 if quick else 0.6
    rows = []
    # analysis + warm-up (the contact kernels compile at the first contact)
    base = _e2e_run(0.002, "draft" if quick else "default", duration=dur)
    models = base["models"]
    steps = (0.001, 0.002) if quick else (0.0005, 0.001, 0.002, 0.005)
    runs = {dt: _e2e_run(dt, "default", models=models, duration=dur) for dt in steps}
    ref = runs[steps[0]]
    c, lref = third_octave_levels(ref["y"], fs)
    for dt in steps:
        r = runs[dt]
        _, lev = third_octave_levels(r["y"], fs)
        d = lev - lref
        rows.append({"sweep": "timestep", "label": f"dt = {dt * 1000:g} ms", "dt": dt, "rtf": r["rtf"],
                     "wall_s": r["wall_s"], "n_modes": r["n_modes"], "impacts": r["impacts"],
                     "band_rms_db": float(np.sqrt(np.mean(d**2))), "band_max_db": float(np.max(np.abs(d))),
                     "total_db": float(10 * math.log10(np.sum(r["y"] ** 2) / np.sum(ref["y"] ** 2))),
                     "levels": lev.tolist(), "analysis_s": float("nan")})
        log(f"  e2e {rows[-1]['label']:16s} RTF {r['rtf']:7.1f}  bands rms {rows[-1]['band_rms_db']:5.2f} dB")
    qs = ("draft",) if quick else ("draft", "default", "high")
    qruns = {}
    for q in qs:
        qruns[q] = _e2e_run(0.001, q, duration=dur, cache=False)
    qref = qruns[qs[-1]]
    _, lq = third_octave_levels(qref["y"], fs)
    for q in qs:
        r = qruns[q]
        _, lev = third_octave_levels(r["y"], fs)
        d = lev - lq
        rows.append({"sweep": "quality", "label": f"quality {q}", "dt": 0.001, "rtf": r["rtf"],
                     "wall_s": r["wall_s"], "n_modes": r["n_modes"], "impacts": r["impacts"],
                     "band_rms_db": float(np.sqrt(np.mean(d**2))), "band_max_db": float(np.max(np.abs(d))),
                     "total_db": float(10 * math.log10(np.sum(r["y"] ** 2) / np.sum(qref["y"] ** 2))),
                     "levels": lev.tolist(), "analysis_s": r["analysis_s"]})
        log(f"  e2e {rows[-1]['label']:16s} RTF {r['rtf']:7.1f}  analysis {r['analysis_s']:6.2f} s  "
            f"bands rms {rows[-1]['band_rms_db']:5.2f} dB")
    return {"rows": rows, "centres": c.tolist(), "duration_s": dur, "fs": fs}
