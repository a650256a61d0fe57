"""The audio window is what one env step simulates (issue 40 item 1): taken from the env's own
attributes (dt, control_timestep, control_dt, frame_skip, n_substeps), checked against the first
step's simulated time, or asked for (window_s) when the env does not say."""

from __future__ import annotations

import gymnasium as gym
import mujoco
import numpy as np
import pytest

from mjsound.wrappers import AudioObservation

XML = ('<mujoco><option timestep="0.002"/><worldbody><geom type="plane" size="1 1 .1"/><body pos="0 0 .3">'
       '<freejoint/><geom name="box" type="box" size=".15 .15 .005"/></body></worldbody></mujoco>')


class OwnLoopEnv(gym.Env):
    """A MuJoCo env stepping 5 physics steps per env step in its own loop, telling the wrapper
    after each (``on_substep``), with whatever step-length attributes it is given."""

    def __init__(self, **attrs):
        self.model = mujoco.MjModel.from_xml_string(XML)
        self.data = mujoco.MjData(self.model)
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, (1,), np.float64)
        self.action_space = gym.spaces.Box(-1, 1, (1,), np.float32)
        self.on_substep = None
        for k, v in attrs.items():
            setattr(self, k, v)

    def reset(self, *, seed=None, options=None):
        mujoco.mj_resetData(self.model, self.data)
        return np.array([self.data.time]), {}

    def step(self, action):
        for _ in range(5):
            mujoco.mj_step(self.model, self.data)
            if self.on_substep is not None:
                self.on_substep()
        return np.array([self.data.time]), 0.0, False, False, {}


def wrapped(inner, **kw):
    env = AudioObservation(inner, materials={"box": "steel"}, substeps="manual", sample_rate=16000,
                           progress=False, **kw)
    inner.on_substep = lambda: env.sim.step(render=False)
    return env


def run(env, steps=40):
    env.reset(seed=0)
    samples = []
    for _ in range(steps):
        obs, _, _, _, info = env.step(env.action_space.sample())
        samples.append(info["audio_samples"])
    return obs, samples


def test_an_env_that_does_not_say_its_step_length_is_asked_for_it():
    with pytest.raises(ValueError, match=r"window_s=.*frame_skip \* model.opt.timestep"):
        wrapped(OwnLoopEnv())
    env = wrapped(OwnLoopEnv(), window_s=0.01)
    assert env.window == 160
    obs, samples = run(env)
    assert samples == [160] * 40  # each observation is exactly one env step's sound
    assert env.sim.reader.n_impacts > 0 and np.any(obs["audio"])


@pytest.mark.parametrize("attrs", [{"frame_skip": 5}, {"control_dt": 0.01}, {"dt": 0.01}])
def test_the_window_comes_from_the_envs_own_attributes(attrs):
    env = wrapped(OwnLoopEnv(**attrs))
    assert env.window == 160  # 5 x 0.002 s at 16 kHz, not one physics step's 32
    _, samples = run(env, 3)
    assert samples == [160] * 3


def test_a_window_that_disagrees_with_the_first_step_is_refused():
    env = wrapped(OwnLoopEnv(frame_skip=1))  # says 1 physics step, takes 5
    assert env.window == 32
    env.reset(seed=0)
    with pytest.raises(RuntimeError, match=r"simulated 0\.01 s .* window_s=0\.01"):
        env.step(env.action_space.sample())
    # a window given by the caller is theirs (e.g. several steps of history): no check
    env = wrapped(OwnLoopEnv(frame_skip=1), window_s=0.05)
    _, samples = run(env, 3)
    assert env.window == 800 and samples == [160] * 3


def test_an_own_loop_env_is_heard_through_its_modules_mj_step():
    """No hook, no on_substep: the env's module calls mujoco.mj_step itself (as
    lerobot-env-so101 does); the wrapper hears each of those steps on this env's data."""
    import sys

    from mjsound.env_stepping import ModuleStepping

    here = sys.modules[OwnLoopEnv.__module__]
    env = AudioObservation(OwnLoopEnv(frame_skip=5), materials={"box": "steel"}, sample_rate=16000, progress=False)
    assert isinstance(env._route, ModuleStepping) and env._route.modules == [here]
    bare = OwnLoopEnv()
    bare.reset()
    _, samples = run(env, 40)
    assert samples == [160] * 40 and env.sim.steps == 200  # every substep of the own loop heard
    assert env.sim.reader.n_impacts > 0
    bare.step(None)  # another env of the module: its steps pass through, unheard
    assert env.sim.steps == 200 and bare.data.time > 0
    env.close()
    assert here.mujoco is mujoco  # the module's own mujoco back
