#!/usr/bin/env python
"""Where an env's loudness comes from: each sound path switched off in turn, and its loudest
impacts and clicks taken apart.

For one env (a gymnasium id, ``"dmc DOMAIN-TASK"``, or ``so101`` / ``robosuite`` / ``myosuite``
as in ``scripts/check_env_families.py``), wrapped with the default options at 16 kHz and stepped
with seeded random actions (seed 0, as ``scripts/check_stock_envs.py``):

1. the largest and median step peak [Pa] at the listener with everything on, without clicks,
   without sliding / rolling noise, and with the impacts' modes alone;
2. the impacts (read beside the simulator by a second
   :class:`mjsound.sim.ContactReader`), loudest first: the object struck, approach speed ``v``,
   impulse, the collision's effective mass ``m*``, the contact time, the modes' energy with the
   prescribed half-sine force (``E_1``, what the modes asked for before the contact was coupled)
   and coupled (``E_c``, :mod:`mjsound.synth.contact_coupling`) against the energy the collision
   loses (``budget``), the summed modal pressure at 1 m, the mode that carries most of it;
3. the loudest clicks (:mod:`mjsound.synth.accel_noise`): velocity change, contact time, the
   body's equivalent radius, the peak at the listener.

Usage::

    nice python scripts/diagnose_levels.py "dmc walker-walk" [--steps 300] [--top 10]
"""

from __future__ import annotations

import argparse
import os
import sys
import warnings

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

FAMILIES = ("so101", "robosuite", "myosuite")
PATHS = {"everything": {}, "no clicks": dict(clicks=False), "no sliding": dict(sim_kwargs=dict(sustained=False)),
         "impacts' modes": dict(clicks=False, sim_kwargs=dict(sustained=False))}


def make(name, **options):
    """``(sim, route, step)``: the env wrapped with ``options`` at 16 kHz, its simulator, its
    stepping route and a function taking one seeded random step (resetting at an episode's
    end) that returns the step's ``info``."""
    if name.startswith("dmc "):
        from dm_control import suite

        from mjsound.compat import patch_dm_control
        from mjsound.dmc import AudioEnvironment

        patch_dm_control()
        domain, task = name[4:].split("-")
        env = AudioEnvironment(suite.load(domain, task, task_kwargs={"random": 0}), seed=0, sample_rate=16000,
                               progress=False, **options)
        env.reset()
        spec, rng = env.action_spec(), np.random.default_rng(0)

        def dm_step():
            if env.step(rng.uniform(spec.minimum, spec.maximum, spec.shape)).last():
                env.reset()
            return env.last_info

        return env.sim, env._route, dm_step
    import gymnasium as gym

    from mjsound.wrappers import AudioObservation

    if name in FAMILIES:
        import check_env_families

        raw = check_env_families.make(name)
    else:
        from mjsound.compat import patch_gymnasium_robotics

        patch_gymnasium_robotics()
        if name.startswith("Fetch"):
            import gymnasium_robotics

            gym.register_envs(gymnasium_robotics)
        raw = gym.make(name)
    env = AudioObservation(raw, sample_rate=16000, progress=False, **options)
    env.reset(seed=0)
    env.action_space.seed(0)

    def gym_step():
        _, _, term, trunc, info = env.step(env.action_space.sample())
        if term or trunc:
            env.reset()
        return info

    return env.core.sim, env._route, gym_step


def path_peaks(name, steps):
    for path, options in PATHS.items():
        _, _, step = make(name, **options)
        p = np.array([float(step()["audio_peak_pa"]) for _ in range(steps)])
        print(f"  {path:15s} peak {p.max():8.2f} Pa   median step peak {np.median(p):7.3f}   steps over 20 Pa "
              f"{int(np.sum(p > 20))}", flush=True)


def record(name, steps):
    """Run without sliding noise and every impact row read beside the simulator: the rows with
    the synthesizer's poses, and the click inputs (rows, body poses, microphones)."""
    from mjsound.sim.contacts import ContactReader

    sim, route, step = make(name, **PATHS["no sliding"])
    restitution = [m.restitution if m is not None else None for m in sim.scene.geom_material]
    beside = ContactReader(sim.model, restitution=restitution)
    driver, data = sim.driver, sim.data
    own = driver.substeps
    rows, clicks, at = [], [], [0]

    def substeps(nstep, render=True, keep=False, stepped=False, times=None):
        for _ in range(int(nstep)):
            own(1, False, False, stepped, times)
            imp, _ = beside.events_fast(data)
            if imp is not None:
                st = sim.synth.kernel_state()
                rows.extend((at[0], r.copy(), st.pos.copy(), st.R.copy()) for r in imp)
                clicks.append((at[0], imp.copy(), np.array(data.xpos), np.array(data.xmat),
                               np.asarray(sim.synth.microphones).copy()))

    driver.substeps = substeps
    route.install(sim)
    for k in range(steps):
        at[0] = k
        step()
    return sim, rows, clicks


def impact_table(sim, rows, top):
    from mjsound.jit import call_inner
    from mjsound.sim.drive import impact_sides
    from mjsound.synth.contact_coupling import coupled_response
    from mjsound.synth.pulse import half_sine_spectrum
    from mjsound.synth.streams import nearest_sorted

    st = sim.synth.kernel_state()
    ob = st.objects
    names = dict(enumerate(sim.synth.objects))
    drive = sim._drive_state(sim.reader.state())
    mic = np.asarray(sim.synth.microphones)[0]
    out = []
    for k, r, pos, R in rows:
        obj, P, J, tau, budget, mass, n = call_inner(impact_sides, drive, np.array([r], r.dtype), 1)
        for i in range(n):
            o = int(obj[i])
            m0, m1, p0, p1 = ob.mode_off[o], ob.mode_off[o + 1], ob.pts_off[o], ob.pts_off[o + 1]
            nm = m1 - m0
            if nm <= 0:
                continue
            pl, jl = (P[i] - pos[o]) @ R[o], J[i] @ R[o]
            b = call_inner(nearest_sorted, ob.pts[p0:p1], ob.pts_index[p0:p1], ob.pts_axis[o], pl[0], pl[1], pl[2])
            G = jl @ ob.shk[ob.shk_off[o] + 3 * b * nm:][:3 * nm].reshape(3, nm)
            wd, lam, w = ob.wd[m0:m1], ob.lam[m0:m1].copy(), ob.w[m0:m1]
            one_way = G * half_sine_spectrum(wd, tau[i]) / wd
            ring = np.zeros(nm, np.complex128)
            jn = np.linalg.norm(jl)
            steps = coupled_response(G / jn, lam, tau[i], mass[i], ring)[0] if mass[i] > 0 and jn > 0 else 0
            amp = jn * ring if steps else one_way  # (at the contact's end, as the synthesizer queues them)
            e1, ec = (0.5 * float(np.sum(np.abs(a * wd) ** 2)) for a in (one_way, amp))
            amp = amp * min(1.0, np.sqrt(budget[i] / ec)) if ec > 0 else amp
            p1m = np.abs(amp * w)
            out.append(dict(step=k, obj=names.get(o, str(o)), v=r["speed"], J=abs(r["impulse"]), m=mass[i],
                            tau=tau[i], e1=e1, ec=ec, budget=budget[i], p=p1m.sum(),
                            r=max(np.linalg.norm(pos[o] - mic), 0.01), f=wd[np.argmax(p1m)] / (2 * np.pi)))
    out.sort(key=lambda d: -d["p"])
    print(f"  {len(out)} impact sides heard; the loudest (modal pressure summed over modes at 1 m):")
    for d in out[:top]:
        print(f"    step {d['step']:3d} {d['obj'][:18]:18s} v {d['v']:5.2f} m/s  J {d['J']:7.3f} N s  "
              f"m* {d['m']:6.2f} kg  "
              f"tau {d['tau'] * 1e6:4.0f} us  E_1 {d['e1']:8.3g} J  E_c {d['ec']:8.3g} J  budget {d['budget']:8.3g} J  "
              f"{d['p']:6.1f} Pa at 1 m ({d['r']:.2f} m away), most at {d['f']:.0f} Hz")


def click_table(sim, clicks, top):
    from scipy import signal

    from mjsound.sim.click_kernels import impact_pulses
    from mjsound.synth.bandlimited import PULSE_DTYPE

    cm = sim.pulses.state.model
    out = []
    for k, imp, xpos, xmat, mics in clicks:
        rows, dv = np.zeros(4 * len(imp) * (len(mics) + 1), PULSE_DTYPE), np.zeros(4 * len(imp) * (len(mics) + 1))
        n = impact_pulses(cm, imp, len(imp), 0.0, xpos, xmat, mics, rows, dv, 0)
        for i in range(n):
            r = rows[i]
            if r["channel"] != 0:
                continue
            tau = r["tau_s"]
            t = np.linspace(0, 6 * tau + 20 * r["d1"], 4000)
            accel = np.where(t < tau, dv[i] * np.pi / (2 * tau) * np.sin(np.pi * t / tau), 0.0)
            _, y, _ = signal.lsim(signal.lti([r["b1"], r["b0"]], [r["d2"], r["d1"], 1.0]), accel, t)
            out.append((float(np.abs(y).max()), k, dv[i], tau, r["d1"] * 343.0))
    out.sort(key=lambda x: -x[0])
    print(f"  {len(out)} clicks; the loudest (one body's click alone at the listener):")
    for peak, k, dv, tau, a in out[:top]:
        print(f"    step {k:3d} peak {peak:6.1f} Pa  dv {dv:5.2f} m/s  tau {tau * 1e6:4.0f} us  radius {a:.3f} m")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("env")
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--top", type=int, default=10)
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    print(f"{args.env}: {args.steps} random steps, 16 kHz, default listener")
    path_peaks(args.env, args.steps)
    sim, rows, clicks = record(args.env, args.steps)
    impact_table(sim, rows, args.top)
    click_table(sim, clicks, args.top)
    return 0


if __name__ == "__main__":
    sys.exit(main())
