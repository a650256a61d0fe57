#!/usr/bin/env python
"""Actuator noise across env families as a user turns it on (a check, not a test): every env
wrapped twice at 16 kHz, without and with one preset for every actuator (``sim_kwargs=
{"actuators": PRESET}``), stepped with the same seeded random actions and then held at the zero
action; the sound does not change the physics, so the difference of the two audio
observations is the drives' part. Writes ``reports/actuator_envs.md`` (replaced, not appended)
and prints the table.

Per env: the actuators, those a preset reached (motors on hinge and slide joints:
``mjsound.sim.actuators.actuator_config``) and those heard (a sounding body on either side of
the joint), the drives' RMS pressure [Pa] over the random steps and over the last ``--rest // 3``
zero-action steps, the fastest driven joint there [rad/s] (the speed gate silences a joint under
0.05 rad/s: a joint still moving at the zero action is heard, as it should be), and mjsound's
warnings at construction (shortened).

    nice python scripts/check_actuator_envs.py              # every env below (~6 min on 2 cores)
    nice python scripts/check_actuator_envs.py --only Ant-v5 dmc:walker-walk --preset servo
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
import types
import warnings

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import bench_actuators  # noqa: E402
import check_env_families  # noqa: E402

ENVS = ["Ant-v5", "HalfCheetah-v5", "Hopper-v5", "Walker2d-v5", "Humanoid-v5", "Reacher-v5", "Pusher-v5",
        "FetchPickAndPlace-v4", "HandManipulateBlock-v1", "AdroitHandDoor-v1",
        "dmc:cheetah-run", "dmc:walker-walk", "dmc:humanoid-walk", "dmc:manipulator-bring_ball", "dmc:finger-spin",
        "robosuite", "so101", "myosuite"]


class DmcAsGym:
    """dm_control's ``AudioEnvironment`` stepped like a gymnasium env (uniform random actions
    from its own generator, seeded)."""

    def __init__(self, env, seed=0):
        self.env, spec = env, env.action_spec()
        rng = np.random.default_rng(seed)
        self.action_space = types.SimpleNamespace(shape=spec.shape, dtype=spec.dtype,
                                                  sample=lambda: rng.uniform(spec.minimum, spec.maximum))
        self.sim = env.sim

    def reset(self, seed=None):
        return self.env.reset(), {}

    def step(self, a):
        ts = self.env.step(a)
        return ts.observation, ts.reward, ts.last(), False, {}

    def close(self):
        self.env.close()


def make(name: str, **kw):
    """The env ``name`` wrapped at 16 kHz with the wrapper options ``kw``."""
    from mjsound.wrappers import AudioObservation

    if name.startswith("dmc:"):
        from dm_control import suite

        from mjsound.dmc import AudioEnvironment

        domain, task = name[4:].split("-")
        return DmcAsGym(AudioEnvironment(suite.load(domain, task, task_kwargs={"random": 0}), seed=0,
                                         sample_rate=16000, progress=False, **kw))
    if name in ("robosuite", "so101", "myosuite"):
        inner = check_env_families.make(name, seed=0)  # (robosuite seeded: its cube's place)
    else:
        inner = bench_actuators.make(name)  # (gymnasium-robotics registered where needed)
    env = AudioObservation(inner, sample_rate=16000, progress=False, **kw)
    env.action_space.seed(0)
    return env


def run(env, steps: int, rest: int):
    """The audio observations (float64) of ``steps`` random and ``rest`` zero actions, the
    fastest driven joint's speed [rad/s] over the last third of the rest, and the joint
    positions after each step."""
    env.reset(seed=0)
    sim = env.sim
    a = sim.actuators
    dofs = sim.model.jnt_dofadr[sim.model.actuator_trnid[a.ids, 0]] if a is not None else np.zeros(0, int)
    audio, fastest, qpos = [], 0.0, []
    for i in range(steps + rest):
        x = env.action_space.sample() if i < steps else np.zeros(env.action_space.shape, env.action_space.dtype)
        obs, _, term, trunc, _ = env.step(x)
        audio.append(np.array(obs["audio"], np.float64))
        qpos.append(sim.data.qpos.copy())
        if i >= steps + rest - rest // 3 and len(dofs):
            fastest = max(fastest, float(np.abs(sim.data.qvel[dofs]).max()))
        if term or trunc:
            env.reset(seed=0)
    return audio, fastest, np.array(qpos)


def check(name: str, preset: str, steps: int, rest: int) -> dict:
    t0 = time.perf_counter()
    try:
        off = make(name)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            on = make(name, sim_kwargs={"actuators": preset})
    except Exception as e:  # (reported in the table: what a user meets)
        return dict(env=name, error=f"{type(e).__name__}: {e}")
    said = sorted({str(w.message)[len("mjsound:"):].strip()[:90] for w in caught if str(w.message).startswith("mjsound:")})
    a = on.sim.actuators
    nu, reached, heard = on.sim.model.nu, 0 if a is None else len(a.ids), 0
    if a is not None:
        heard = len({int(r) // 2 for r in a.body_rows})
    x, _, qx = run(off, steps, rest)
    y, fastest, qy = run(on, steps, rest)
    off.close()
    on.close()
    full = 20.0  # (the observation's unit [Pa]: AudioObservation's full_scale_pa)
    d = np.array([np.sqrt(np.mean((q - p) ** 2)) * full for p, q in zip(x, y)])
    tail = d[-(rest // 3):]
    return dict(env=name, nu=nu, reached=reached, heard=heard, moving_pa=float(np.sqrt(np.mean(d[:steps] ** 2))),
                rest_pa=float(np.sqrt(np.mean(tail ** 2))), fastest=fastest, warnings=said,
                same=bool(np.array_equal(qx, qy)),
                seconds=time.perf_counter() - t0)


def table(rows, preset, steps, rest) -> str:
    try:
        commit = subprocess.run(["git", "-C", ROOT, "rev-parse", "--short", "HEAD"], capture_output=True,
                                text=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", ROOT, "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True).stdout.strip()
        commit += "+" if dirty else ""
    except OSError:
        commit = "?"
    out = [f"# Actuator noise across env families (`{preset}` on every actuator)", "",
           f"`python scripts/check_actuator_envs.py --preset {preset} --steps {steps} --rest {rest}` at `{commit}`: "
           f"{steps} random steps (seed 0), then {rest} at the zero action; the drives' part is the difference of "
           "the audio observations with and without the preset (the same physics). *At rest*: the last "
           f"{rest // 3} steps; *fastest*: the fastest driven joint there. A drive is silent where its joint "
           "is slower than 0.05 rad/s (the speed gate) or its actuator gives no force (a motor at zero control "
           "free-wheels); a position servo still moving to its target, or holding against a load while it "
           "creeps, is heard. *Same physics*: the joint positions of both runs equal at every step (else the "
           "difference holds more than the drives). gym-aloha is left out here (it renders camera images at every step: "
           "`tests/test_env_routes.py` hears it).", "",
           "| env | actuators | reached | heard | moving [Pa RMS] | at rest [Pa RMS] | fastest at rest [rad/s] | same physics | mjsound said |",
           "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        if "error" in r:
            out.append(f"| {r['env']} | | | | | | | | **{r['error'][:160]}** |")
            continue
        out.append(f"| {r['env']} | {r['nu']} | {r['reached']} | {r['heard']} | {r['moving_pa']:.3g} | "
                   f"{r['rest_pa']:.2g} | {r['fastest']:.3g} | {'yes' if r['same'] else 'no'} | {'; '.join(r['warnings'])} |")
    return "\n".join(out) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--preset", default="qdd")
    ap.add_argument("--steps", type=int, default=150)
    ap.add_argument("--rest", type=int, default=150)
    ap.add_argument("--only", nargs="+", help="these envs only (the report is not written)")
    args = ap.parse_args(argv)
    rows = []
    for name in args.only or ENVS:
        rows.append(check(name, args.preset, args.steps, args.rest))
        r = rows[-1]
        print({k: (round(v, 4) if isinstance(v, float) else v) for k, v in r.items()}, flush=True)
    text = table(rows, args.preset, args.steps, args.rest)
    print(text)
    if not args.only:
        path = os.path.join(ROOT, "reports", "actuator_envs.md")
        with open(path + ".tmp", "w") as f:
            f.write(text)
        os.replace(path + ".tmp", path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
