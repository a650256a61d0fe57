"""Stock envs at the default material: mass warnings at construction, peak level over random steps.

For each env (gymnasium's MuJoCo envs, gymnasium-robotics' Fetch, one task per dm_control suite
domain), wrapped with its default options (``default_material="aluminium"``, 16 kHz, the
default listener, MuJoCo's masses for the sound's objects), this constructs the wrapper, counts
the warnings that mention mass, runs ``--steps`` random actions (seed 0; an episode's end
resets) and records the peak pressure at the listener (``info["audio_peak_pa"]``; the default
full scale is 20 Pa, beyond which the observation clips) and the clipped samples.

Writes ``reports/stock_envs.md`` (replaced, not appended) and prints the table::

    nice python scripts/check_stock_envs.py                # everything (~10 min on 2 cores)
    nice python scripts/check_stock_envs.py --only Ant-v5 Hopper-v5 --steps 100
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import warnings

import numpy as np

GYM = ["Ant-v5", "Humanoid-v5", "Walker2d-v5", "HalfCheetah-v5", "Hopper-v5", "Pusher-v5", "Reacher-v5"]
FETCH = ["FetchReach-v4", "FetchPush-v4", "FetchSlide-v4", "FetchPickAndPlace-v4"]
DMC = [("acrobot", "swingup"), ("ball_in_cup", "catch"), ("cartpole", "swingup"), ("cheetah", "run"),
       ("finger", "spin"), ("fish", "swim"), ("hopper", "hop"), ("humanoid", "walk"), ("manipulator", "bring_ball"),
       ("pendulum", "swingup"), ("point_mass", "easy"), ("reacher", "easy"), ("swimmer", "swimmer6"),
       ("walker", "walk"), ("dog", "walk"), ("quadruped", "walk"), ("stacker", "stack_2")]
FULL_SCALE_PA = 20.0


def _mass_warnings(caught) -> list:
    return [str(w.message) for w in caught if "differ in mass" in str(w.message)]


def run_gym(name: str, steps: int) -> dict:
    import gymnasium as gym

    from mjsound.wrappers import AudioObservation

    if name.startswith("Fetch"):
        import gymnasium_robotics

        gym.register_envs(gymnasium_robotics)
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        env = AudioObservation(gym.make(name), sample_rate=16000, progress=False)
        env.reset(seed=0)
    build = time.perf_counter() - t0
    env.action_space.seed(0)
    peak, clipped, impacts = 0.0, 0, 0
    for _ in range(steps):
        _, _, term, trunc, info = env.step(env.action_space.sample())
        peak = max(peak, float(info["audio_peak_pa"]))
        clipped += int(info["audio_clipped"])
        impacts += int(info.get("audio_impacts", 0))
        if term or trunc:
            env.reset()
    env.close()
    return dict(env=name, peak_pa=peak, clipped=clipped, impacts=impacts, mass_warnings=_mass_warnings(caught),
                build_s=build)


def run_dmc(domain: str, task: str, steps: int) -> dict:
    from dm_control import suite

    from mjsound.dmc import AudioEnvironment

    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        env = AudioEnvironment(suite.load(domain, task, task_kwargs={"random": 0}), seed=0, sample_rate=16000,
                               progress=False)
        env.reset()
    build = time.perf_counter() - t0
    spec = env.action_spec()
    rng = np.random.default_rng(0)
    peak, clipped, impacts = 0.0, 0, 0
    for _ in range(steps):
        ts = env.step(rng.uniform(spec.minimum, spec.maximum, spec.shape))
        info = env.last_info
        peak = max(peak, float(info["audio_peak_pa"]))
        clipped += int(info["audio_clipped"])
        impacts += int(info.get("audio_impacts", 0))
        if ts.last():
            env.reset()
    return dict(env=f"dmc {domain}-{task}", peak_pa=peak, clipped=clipped, impacts=impacts,
                mass_warnings=_mass_warnings(caught), build_s=build)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--only", nargs="*", help="env names (gymnasium ids or dmc DOMAIN-TASK)")
    ap.add_argument("--out", default=os.path.join(os.path.dirname(__file__), "..", "reports", "stock_envs.md"))
    args = ap.parse_args(argv)
    from mjsound.compat import patch_dm_control, patch_gymnasium_robotics

    patch_gymnasium_robotics()
    patch_dm_control()
    jobs = [("gym", n) for n in GYM + FETCH] + [("dmc", d) for d in DMC]
    if args.only:
        jobs = [j for j in jobs if (j[1] if j[0] == "gym" else f"{j[1][0]}-{j[1][1]}") in args.only]
    rows = []
    for kind, what in jobs:
        try:
            row = run_gym(what, args.steps) if kind == "gym" else run_dmc(*what, args.steps)
        except Exception as exc:  # (an env that does not install or build here: said in the table)
            row = dict(env=what if kind == "gym" else f"dmc {what[0]}-{what[1]}", error=f"{type(exc).__name__}: {exc}")
        rows.append(row)
        print(_line(row), flush=True)
    lines = ["# Stock envs at the default material", "",
             f"Generated by `nice python scripts/check_stock_envs.py` ({args.steps} random steps each, seed 0, "
             f"16 kHz, default listener, `default_material=\"aluminium\"`, MuJoCo's masses). Peak: the largest "
             f"`info[\"audio_peak_pa\"]`; full scale {FULL_SCALE_PA:g} Pa.", "",
             "| env | peak [Pa] | clipped samples | impacts | mass warnings | construction [s] |",
             "|---|---|---|---|---|---|"]
    lines += [_line(r) for r in rows]
    with open(args.out, "w") as f:
        f.write("\n".join(lines) + "\n")
    bad = [r for r in rows if r.get("error") or r.get("mass_warnings") or r.get("peak_pa", 0) > FULL_SCALE_PA]
    return 1 if bad else 0


def _line(r: dict) -> str:
    if r.get("error"):
        return f"| {r['env']} | - | - | - | - | {r['error'][:120]} |"
    warn = "; ".join(w[:100] for w in r["mass_warnings"]) or "none"
    return f"| {r['env']} | {r['peak_pa']:.3g} | {r['clipped']} | {r['impacts']} | {warn} | {r['build_s']:.1f} |"


if __name__ == "__main__":
    sys.exit(main())
