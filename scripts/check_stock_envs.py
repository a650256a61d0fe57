"""Stock envs at the default material: mass warnings at construction, peak level over random steps.

For each env (gymnasium's MuJoCo envs, gymnasium-robotics' Fetch, one task per dm_control suite
domain), wrapped with its default options (``default_material="aluminium"``, 16 kHz, the
default listener, MuJoCo's masses for the sound's objects), this constructs the wrapper, counts
the warnings that mention mass, runs ``--steps`` random actions (seed 0; an episode's end
resets) and records the peak pressure at the listener (``info["audio_peak_pa"]``), the steps
louder than the 20 Pa full scale (the observation's unit: by default it keeps such levels) and
the clipped samples (none unless a sample passes one atmosphere, i.e. the simulation broke).

Writes ``reports/stock_envs.md`` (replaced, not appended) and prints the table; each row says
the commit it was measured at (``+`` when the work tree had changes). ``--only`` measures the
named envs and keeps the other rows of the existing report as they were (their commit says
when)::

    nice python scripts/check_stock_envs.py                # everything (~10 min on 2 cores)
    nice python scripts/check_stock_envs.py --only Ant-v5 "dmc walker-walk"
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
    peak, clipped, impacts, loud = 0.0, 0, 0, 0
    for _ in range(steps):
        _, _, term, trunc, info = env.step(env.action_space.sample())
        peak = max(peak, float(info["audio_peak_pa"]))
        loud += info["audio_peak_pa"] > FULL_SCALE_PA
        clipped += int(info["audio_clipped"])
        impacts += int(info.get("audio_impacts", 0))
        if term or trunc:
            env.reset()
    env.close()
    return dict(env=name, peak_pa=peak, loud_steps=loud, clipped=clipped, impacts=impacts,
                mass_warnings=_mass_warnings(caught), build_s=build)


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
    peak, clipped, impacts, loud = 0.0, 0, 0, 0
    for _ in range(steps):
        ts = env.step(rng.uniform(spec.minimum, spec.maximum, spec.shape))
        info = env.last_info
        peak = max(peak, float(info["audio_peak_pa"]))
        loud += info["audio_peak_pa"] > FULL_SCALE_PA
        clipped += int(info["audio_clipped"])
        impacts += int(info.get("audio_impacts", 0))
        if ts.last():
            env.reset()
    return dict(env=f"dmc {domain}-{task}", peak_pa=peak, loud_steps=loud, clipped=clipped, impacts=impacts,
                mass_warnings=_mass_warnings(caught), build_s=build)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--only", nargs="*", help="env names (gymnasium ids or dmc DOMAIN-TASK)")
    ap.add_argument("--out", default=os.path.join(os.path.dirname(__file__), "..", "reports", "stock_envs.md"))
    args = ap.parse_args(argv)
    rows = []
    from mjsound.compat import patch_dm_control, patch_gymnasium_robotics

    patch_gymnasium_robotics()
    patch_dm_control()
    jobs = [("gym", n) for n in GYM + FETCH] + [("dmc", d) for d in DMC]
    name = lambda job: job[1] if job[0] == "gym" else f"dmc {job[1][0]}-{job[1][1]}"  # noqa: E731
    wanted = {w[4:] if w.startswith("dmc ") else w for w in args.only or ()}
    unknown = wanted - {name(j).removeprefix("dmc ") for j in jobs}
    if unknown:
        ap.error(f"--only: no such env {sorted(unknown)}; the envs: {[name(j) for j in jobs]}")
    kept = _table_rows(args.out) if args.only else {}
    commit = _commit()
    lines_by_env = {}
    for job in jobs:
        kind, what = job
        if args.only and name(job).removeprefix("dmc ") not in wanted:
            if name(job) in kept:
                lines_by_env[name(job)] = kept[name(job)]
            continue
        try:
            row = run_gym(what, args.steps) if kind == "gym" else run_dmc(*what, args.steps)
        except Exception as exc:  # (an env that does not install or build here: said in the table)
            row = dict(env=name(job), error=f"{type(exc).__name__}: {exc}")
        row["commit"] = commit
        row["bad"] = bool(row.get("error") or row.get("mass_warnings") or row.get("clipped", 0) > 0)
        lines_by_env[name(job)] = _line(row)
        print(lines_by_env[name(job)], flush=True)
        rows.append(row)
    lines = ["# Stock envs at the default material", "",
             f"Generated by `nice python scripts/check_stock_envs.py` ({args.steps} random steps each, seed 0, "
             f"16 kHz, default listener, `default_material=\"aluminium\"`, MuJoCo's masses). Peak: the largest "
             f"`info[\"audio_peak_pa\"]`; steps over full scale: env steps louder than the {FULL_SCALE_PA:g} Pa full "
             "scale (the observation's unit; by default it keeps such levels, unclipped); clipped samples: those "
             "the observation clipped (at one atmosphere, by default). Each row's commit is the one it was "
             "measured at (`--only` reruns the rows named and keeps the others); construction time with the "
             "modal-model disk cache as it was (seconds where the models were cached).", "",
             "| env | peak [Pa] | steps over full scale | clipped samples | impacts | mass warnings | construction [s] "
             "| commit |",
             "|---|---|---|---|---|---|---|---|"]
    lines += [lines_by_env[name(j)] for j in jobs if name(j) in lines_by_env]
    with open(args.out, "w") as f:
        f.write("\n".join(lines) + "\n")
    return 1 if any(r["bad"] for r in rows) else 0


def _line(r: dict) -> str:
    if r.get("error"):
        return f"| {r['env']} | - | - | - | - | - | {r['error'][:120]} | {r['commit']} |"
    warn = "; ".join(w[:100] for w in r["mass_warnings"]) or "none"
    return (f"| {r['env']} | {r['peak_pa']:.3g} | {r['loud_steps']} | {r['clipped']} | {r['impacts']} | {warn} "
            f"| {r['build_s']:.1f} "
            f"| {r['commit']} |")


def _table_rows(path: str) -> dict:
    """``{env: table line}`` of an existing report (a row from before rows had a commit gets
    ``unknown``); empty when there is none."""
    if not os.path.exists(path):
        return {}
    out = {}
    with open(path) as f:
        for line in f:
            cells = [c.strip() for c in line.strip().strip("|").split("|")]
            if not line.startswith("| ") or cells[0] in ("env", "---") or set(cells[0]) <= {"-"}:
                continue
            if len(cells) != 8:  # (a row of an older layout: measured again by a full run)
                continue
            out[cells[0]] = "| " + " | ".join(cells) + " |"
    return out


def _commit() -> str:
    """The repository's commit (short), ``+`` when its tracked files (but ``reports/``) have changes."""
    import subprocess

    here = os.path.dirname(os.path.abspath(__file__))
    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=here, capture_output=True, text=True,
                              check=True).stdout.strip()
        dirty = subprocess.run(["git", "diff", "--quiet", "HEAD", "--", ".", ":!reports"],
                               cwd=os.path.dirname(here)).returncode  # (the report itself does not count)
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return head + ("+" if dirty else "")


if __name__ == "__main__":
    sys.exit(main())
