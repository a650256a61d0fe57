"""The live player's side of tests/test_live.py and scripts/live_timing.py, run in a process of
its own (the tap's variables must be set before sounddevice is imported:
:class:`mjsound.live_tap.PulseTap`):

- ``python tests/live_audio.py view SCENE OUT.npz DEVICE DURATION LEAD DEVICE_LATENCY STALL_AT STALL_S``
- ``python tests/live_audio.py envs OUT.npz GYM_DEVICE DMC_DEVICE STEPS``
"""

from __future__ import annotations

import time

import numpy as np


def _view_main(argv) -> None:
    """``view SCENE OUT.npz DEVICE DURATION LEAD DEVICE_LATENCY STALL_AT STALL_S``:
    :func:`mjsound.live_view.view` without the viewer, keeping every block it sent; the
    simulation stalls once for ``STALL_S`` seconds of wall time after ``STALL_AT`` seconds
    of audio (0: never), as a slow simulation would. Writes what was sent, the player's
    statistics and timing logs, and the log lines to ``OUT.npz``."""
    import json
    import logging

    from mjsound.live_view import view

    scene, out, device, duration, lead, latency, stall_at, stall_s = argv
    records = []
    logging.basicConfig(level=logging.WARNING, handlers=[_Keep(records)])
    sent, taken = [], [0]

    def keep(frames):
        sent.append(frames.copy())
        taken[0] += frames.shape[1]
        if float(stall_at) > 0 and taken[0] - frames.shape[1] < float(stall_at) * 48000 <= taken[0]:  # (view: 48 kHz)
            time.sleep(float(stall_s))

    timing = {}
    stats = view(scene, duration=float(duration), device=device, viewer=False, lead_s=float(lead),
                 device_latency_s=float(latency) if float(latency) > 0 else None, progress=False,
                 on_block=keep, on_timing=timing.update)
    np.savez(out, sent=np.concatenate(sent, axis=1).T, stats=json.dumps(stats), log=json.dumps(records),
             callbacks=timing["callbacks"], pushes=timing["pushes"])


def _envs_main(argv) -> None:
    """``envs OUT.npz GYM_DEVICE DMC_DEVICE SECONDS``: gymnasium's Ant-v5 through
    ``AudioObservation(play=GYM_DEVICE)`` and dm_control's ball_in_cup through
    ``AudioEnvironment(play=DMC_DEVICE)``, SECONDS of random env steps each; writes each
    env's audio observations, its step, the wall time each step returned (``time.monotonic``)
    and the player's underflows to ``OUT.npz``."""
    import gymnasium as gym
    from dm_control import suite

    from mjsound.compat import patch_dm_control
    from mjsound.dmc import AudioEnvironment
    from mjsound.wrappers import AudioObservation

    out, gym_device, dmc_device, seconds = argv
    patch_dm_control()
    env = AudioObservation(gym.make("Ant-v5"), play=gym_device, progress=False)
    env.reset(seed=0)
    env.action_space.seed(0)
    obs, wall, player = [], [], env.core.player
    for _ in range(round(float(seconds) / env.unwrapped.dt)):
        o = env.step(env.action_space.sample())[0]
        wall.append(time.monotonic())
        obs.append(o["audio"])
    gym_dt = env.unwrapped.dt
    env.close()
    gym_underflows = player.stats()["underflows"]
    denv = AudioEnvironment(suite.load("ball_in_cup", "catch", task_kwargs={"random": 0}), seed=3, play=dmc_device,
                            progress=False)
    denv.reset()
    spec, rng = denv.action_spec(), np.random.default_rng(0)
    dobs, dwall, player = [], [], denv.core.player
    for _ in range(round(float(seconds) / denv.control_timestep())):
        dobs.append(denv.step(rng.uniform(spec.minimum, spec.maximum, spec.shape)).observation["audio"])
        dwall.append(time.monotonic())
    dmc_dt = denv.control_timestep()
    denv.close()
    np.savez(out, gym=np.concatenate(obs, axis=1).T, gym_wall=wall, gym_dt=gym_dt, gym_underflows=gym_underflows,
             dmc=np.concatenate(dobs, axis=1).T, dmc_wall=dwall, dmc_dt=dmc_dt,
             dmc_underflows=player.stats()["underflows"])


class _Keep(__import__("logging").Handler):
    def __init__(self, records):
        super().__init__()
        self.records = records

    def emit(self, record):
        self.records.append([record.name, record.getMessage()])


if __name__ == "__main__":
    import sys

    {"view": _view_main, "envs": _envs_main}[sys.argv[1]](sys.argv[2:])
