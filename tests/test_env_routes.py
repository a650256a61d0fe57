"""Env families whose physics is not gymnasium's own, heard through AudioObservation (issue 36
items 2-3, issue 40 item 7): gym-aloha (a dm_control physics inside a gymnasium env) and
robosuite 1.5 (its own substep loop on an MjSim rebuilt at every hard reset), with no user patch
beyond mjsound.compat. No modal analysis (default_material=None): the impacts click."""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest

from mjsound.compat import patch_robosuite
from mjsound.env_stepping import DmPhysicsStepping, MjSimStepping
from mjsound.wrappers import AudioObservation

patch_robosuite()


def test_gym_aloha_is_heard_through_its_dm_control_physics():
    import gym_aloha  # noqa: F401  (registers the envs)

    env = AudioObservation(gym.make("gym_aloha/AlohaInsertion-v0"), sample_rate=16000, default_material=None,
                           progress=False)
    inner = env.unwrapped._env  # the dm_control environment AlohaEnv steps
    assert isinstance(env._route, DmPhysicsStepping)
    assert env.sim.model is inner.physics.model.ptr and env.sim.data is inner.physics.data.ptr
    n_sub = round(inner.control_timestep() / inner.physics.timestep())
    assert env.window == round(inner.control_timestep() * 16000) == 320
    env.reset(seed=0)
    impacts, peak = 0, 0.0
    for _ in range(3):  # (zero joint targets: the arms swing to them, fingers strike)
        obs, _, _, _, info = env.step(np.zeros(14, np.float32))
        assert env.observation_space["audio"].contains(obs["audio"]) and set(obs) == {"top", "audio"}
        assert info["audio_samples"] == 320
        impacts += info["audio_impacts"]
        peak = max(peak, info["audio_peak_pa"])
    assert env.sim.steps == 3 * n_sub  # every substep of physics.step(n_sub_steps) heard
    assert impacts > 0 and peak > 0
    env.close()
    assert "step" not in vars(inner.physics)


def test_what_holds_no_mujoco_names_the_routes():
    with pytest.raises(TypeError, match="mjsound.dmc.AudioEnvironment.*sim.flush"):
        AudioObservation(gym.make("CartPole-v1"))


def robosuite_lift(hard_reset=True):
    import robosuite
    from robosuite.wrappers import GymWrapper

    return GymWrapper(robosuite.make("Lift", robots="Panda", has_renderer=False, has_offscreen_renderer=False,
                                     use_camera_obs=False, hard_reset=hard_reset, control_freq=20))


def test_robosuite_lift_own_loop_and_hard_reset_are_followed():
    env = AudioObservation(robosuite_lift(), sample_rate=16000, default_material=None, progress=False)
    assert isinstance(env._route, MjSimStepping)
    rs = env.unwrapped  # the robosuite env (robosuite.wrappers.Wrapper.unwrapped)
    n_sub = round(rs.control_timestep / rs.model_timestep)
    assert env.window == 800 and n_sub == 25
    models = []
    for episode in range(2):
        env.reset(seed=episode)
        # the hard reset built a new MjSim: the simulator is the one of the sim stepped now
        assert env.sim.model is rs.sim.model._model and env.sim.data is rs.sim.data._data
        models.append(rs.sim.model._model)
        impacts, samples = 0, 0
        for i in range(30):  # the gripper driven down, closing, onto the cube and the table
            obs, _, _, _, info = env.step(np.array([0, 0, -1.0, 0, 0, 0, 1.0 if i > 15 else -1.0]))
            impacts += info["audio_impacts"]
            samples += info["audio_samples"]
        assert env.sim.steps == 30 * n_sub  # every substep of robosuite's own loop (step1 / step2)
        assert samples == 30 * 800 and impacts > 0, f"episode {episode}"
    assert models[0] is not models[1]
    sim = rs.sim
    env.close()
    assert "step2" not in vars(sim) and "step" not in vars(sim)


def own_loop_run(env, steps):
    env.reset(seed=0)
    env.action_space.seed(0)
    samples, impacts, simulated, heard = 0, 0, 0.0, 0
    for _ in range(steps):
        t, n = float(env.sim.data.time), env.sim.steps
        _, _, term, trunc, info = env.step(env.action_space.sample())
        simulated += float(env.sim.data.time) - t
        heard += env.sim.steps - n
        samples += info["audio_samples"]
        impacts += info["audio_impacts"]
        assert not (term or trunc)
    return samples, impacts, simulated, heard


def test_myosuite_is_heard_with_its_frame_skip_window():
    import myosuite  # noqa: F401

    from mjsound.env_stepping import MyoStepping

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        env = AudioObservation(gym.make("myoChallengeDieReorientP1-v0"), sample_rate=16000, default_material=None,
                               progress=False)
        samples, impacts, simulated, heard = own_loop_run(env, 20)
    assert not [w for w in caught if "AudioSimulator" in str(w.message)]  # (the route uses no deprecated call)
    u = env.unwrapped
    assert isinstance(env._route, MyoStepping) and getattr(u, "dt", None) is None
    assert env.window == round(u.frame_skip * u.model.opt.timestep * 16000) == 160  # (was 32: one physics step)
    assert samples == round(simulated * 16000) == 20 * 160 and heard == 20 * u.frame_skip
    assert impacts > 0  # the die in the hand
    env.close()


def test_so101_own_mj_step_loop_is_heard():
    import sys

    import lerobot_env_so101

    from mjsound.env_stepping import ModuleStepping

    env = AudioObservation(gym.make(lerobot_env_so101.ENV_ID), sample_rate=16000, default_material=None,
                           progress=False)
    u = env.unwrapped
    assert isinstance(env._route, ModuleStepping)
    assert env.window == round(u.control_dt * 16000) == 1600  # (was 32: one physics step)
    samples, impacts, simulated, heard = own_loop_run(env, 5)
    assert samples == round(simulated * 16000) == 5 * 1600 and heard == 5 * 50
    (module,) = env._route.modules
    assert module.__name__ == "lerobot_env_so101.mujoco_env"  # (apply_action's substep loop)
    env.close()
    assert module.mujoco is sys.modules["mujoco"]
