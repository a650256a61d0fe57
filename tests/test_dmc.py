"""dm_control suite environments through :class:`mjsound.dmc.AudioEnvironment` (issue 15).

dm_control 1.0.50 fails on mujoco 4.0.0; tests/conftest.py applies
``mjsound.compat.patch_dm_control`` (documented there)."""

from __future__ import annotations

import dm_env
import numpy as np
import pytest
from dm_control import suite

from mjsound.dmc import AudioEnvironment


def rollout(seed, steps=60, **kw):
    env = AudioEnvironment(suite.load("ball_in_cup", "catch", task_kwargs={"random": 0}), seed=seed, **kw)
    ts = env.reset()
    assert ts.first() and not np.any(ts.observation["audio"])
    spec = env.action_spec()
    rng = np.random.default_rng(0)
    audio, impacts = [], 0
    for _ in range(steps):
        ts = env.step(rng.uniform(spec.minimum, spec.maximum, spec.shape))
        audio.append(ts.observation["audio"])
        impacts += env.last_info["audio_impacts"]
    return env, np.concatenate(audio, axis=1), impacts


def test_dm_control_suite_env_is_heard_and_reproducible():
    env, a, impacts = rollout(3)
    assert isinstance(env, dm_env.Environment)
    n_sub = round(env.control_timestep() / env.physics.timestep())
    assert env.sim.steps == 60 * n_sub  # every physics substep went through the simulator
    # the cup's five capsules ring as one object
    (cup,) = env.scene.sounding
    assert cup.name == "cup" and len(cup.geom_ids) == 5
    assert env.sim._dyn_geoms.tolist() == [cup.geom_id]  # the synthesizer follows the anchor's pose
    assert impacts > 0 and np.abs(a).max() > 0
    spec = env.observation_spec()["audio"]
    W = round(env.control_timestep() * 16000)
    assert spec.shape == (1, W) and spec.dtype == np.float32 and a.shape == (1, 60 * W)
    spec.validate(a[:, :W])
    assert set(env.observation_spec()) == {"position", "velocity", "audio"}
    _, b, _ = rollout(3)
    np.testing.assert_array_equal(a, b)


def test_reset_silences_the_last_episode():
    env, a, _ = rollout(3)
    assert np.abs(a[:, -4000:]).max() > 0  # still ringing at the end
    ts = env.reset()
    assert ts.first() and not np.any(ts.observation["audio"])
    assert env.sim.samples == 0 and env.sim.steps == 0
    ringing = env.sim.synth.render(800)  # what the synthesizer holds after the reset: nothing
    assert not np.any(ringing)


def test_automatic_reset_after_the_last_step_and_close():
    env = AudioEnvironment(suite.load("ball_in_cup", "catch", task_kwargs={"random": 0, "time_limit": 0.1}),
                           seed=0, progress=False)
    ts = env.reset()
    steps = 0
    while not ts.last():
        ts = env.step(np.zeros(2))
        steps += 1
    ts = env.step(np.zeros(2))  # dm_control resets by itself
    assert ts.first() and not np.any(ts.observation["audio"]) and env.sim.steps == 0
    physics = env.physics
    env.close()
    assert "step" not in vars(physics)
    with pytest.raises(RuntimeError, match="after close"):
        env.step(np.zeros(2))


def test_refuses_what_is_not_a_dm_control_env():
    with pytest.raises(TypeError, match="dm_control environment"):
        AudioEnvironment(object())


def test_composer_task_is_heard_in_every_episode():
    """dm_control.manipulation (composer) builds a new Physics at the first reset and at every
    reset (its MJCF is recompiled each episode) and frees the old one: the wrapper follows
    it. Each episode a brick is lifted 5 cm and falls: its impact clicks (no modal analysis:
    default_material=None keeps the test fast)."""
    import gc
    import weakref

    import mujoco
    from dm_control import manipulation

    env = AudioEnvironment(manipulation.load("stack_2_bricks_features", seed=0), seed=0, default_material=None,
                           progress=False)
    n_sub = round(env.control_timestep() / env.physics.timestep())
    zero = np.zeros(env.action_spec().shape)
    old = []
    for episode in range(3):
        ts = env.reset()
        assert ts.first() and not np.any(ts.observation["audio"])
        model, data = env.physics.model.ptr, env.physics.data.ptr
        gc.collect()
        assert all(ref() is None for ref in old)  # the freed physics of past episodes are gone
        assert env.sim.model is model and env.sim.data is data  # the physics composer steps now
        old += [weakref.ref(env.physics.__init__.__self__), weakref.ref(data)]
        brick = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "duplo2x4/")
        data.qpos[model.jnt_qposadr[model.body_jntadr[brick]] + 2] += 0.05
        peak, impacts = 0.0, 0
        for _ in range(10):
            ts = env.step(zero)
            peak = max(peak, env.last_info["audio_peak_pa"])
            impacts += env.last_info["audio_impacts"]
        assert env.sim.steps == 10 * n_sub  # every substep of this episode's physics heard
        assert impacts >= 1 and peak > 0, f"episode {episode} silent"
    assert len({id(r()) for r in old[::2] if r() is not None}) == 1  # only the last physics lives
    last = env.physics.__init__.__self__
    env.close()
    assert "step" not in vars(last)  # its own step back
