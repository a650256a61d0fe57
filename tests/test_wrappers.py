"""AudioObservation on gymnasium's own MuJoCo envs, unmodified (issue 5, gymnasium part).

The modal models of each env are analysed once per process (the scene's model memo, mjsound.sim.scene_analysis), so
the real analyses (a few seconds per env, draft quality at 16 kHz) are paid once per file.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from mjsound.wrappers import AudioObservation, scene_materials, stft_log1p

ENVS = ["Ant-v5", "Humanoid-v5", "HalfCheetah-v5", "Pusher-v5"]


def wrapped(env_id, **kw):
    return AudioObservation(gym.make(env_id), **kw)


def run(env, seed, n, action_seed=0):
    obs, info = env.reset(seed=seed)
    env.action_space.seed(action_seed)
    out = [obs]
    infos = [info]
    for _ in range(n):
        obs, r, term, trunc, info = env.step(env.action_space.sample())
        out.append(obs)
        infos.append(info)
        if term or trunc:
            break
    return out, infos


@pytest.mark.parametrize("env_id", ENVS)
def test_gymnasium_envs_unmodified(env_id):
    env = wrapped(env_id)
    u = env.unwrapped
    W = int(round(u.dt * 16000))
    assert env.observation_space["audio"].shape == (env.n_channels, W)
    assert env.scene.sounding, env.scene.report()  # the default material makes them sound
    obs, infos = run(env, 0, 12)
    for o in obs:
        assert env.observation_space.contains(o)
    # every physics substep went through the audio simulator, with exactly the step's samples
    steps = len(obs) - 1
    assert env.sim.steps == steps * u.frame_skip
    assert sum(i["audio_samples"] for i in infos) == round(steps * u.dt * 16000)
    # the physics is untouched: same observations as the bare env
    bare = gym.make(env_id)
    ref, _ = run(bare, 0, 12)
    for a, b in zip(obs, ref):
        np.testing.assert_array_equal(a["observation"], b)
    env.close()
    bare.close()


def test_check_env_ant_and_audio_is_reproducible():
    env = wrapped("Ant-v5")
    check_env(env, skip_render_check=True)
    a, ia = run(env, 7, 25)
    b, ib = run(env, 7, 25)
    heard = sum(i["audio_impacts"] for i in ia)
    assert heard > 0 and any(np.abs(o["audio"]).max() > 0 for o in a)
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x["audio"], y["audio"])
    env.close()


def test_substep_contacts_are_read():
    """Impacts inside frame_skip are heard: the hook counts the same impacts as a manual run
    of single mj_steps with an AudioSimulator on the same scene."""
    import mujoco

    from mjsound.sim import AudioSimulator

    env = wrapped("HalfCheetah-v5")
    obs, infos = run(env, 1, 20)
    n_wrapped = sum(i["audio_impacts"] for i in infos)
    u = env.unwrapped
    bare = gym.make("HalfCheetah-v5")
    bare.reset(seed=1)
    bare.action_space.seed(0)
    bu = bare.unwrapped
    sim = AudioSimulator(bu.model, bu.data, scene=env.scene, sample_rate=16000, progress=False)
    sim.reset()
    for _ in range(len(obs) - 1):
        a = bare.action_space.sample()
        bu.data.ctrl[:] = a
        for _ in range(u.frame_skip):
            mujoco.mj_step(bu.model, bu.data)
            sim.step()
    assert env.sim.reader.n_impacts == sim.events["impact"] > 0
    heard = env.core._audible  # audio_impacts: the impacts with a side that sounds or clicks
    assert n_wrapped == sum(1 for r in sim.impacts if heard[r.geom1] or heard[r.geom2]) > 0
    env.close()
    bare.close()


def test_clipping_is_counted_and_reported_once():
    env = wrapped("Ant-v5", full_scale_pa=1e-9, clip=True)
    assert env.observation_space["audio"].high.max() == 1.0
    with pytest.warns(RuntimeWarning, match="full_scale_pa \\(now 1e-09 Pa\\)") as record:
        obs, infos = run(env, 7, 25)
    clipped = sum(i["audio_clipped"] for i in infos)
    assert clipped > 0
    assert sum("audio observation clipped" in str(w.message) for w in record) == 1
    assert sum(i["audio_clipped"] > 0 for i in infos) > 1  # (later steps clipped too, unreported)
    assert all("audio_clipped" in i and "audio_peak_pa" in i for i in infos)
    assert max(float(np.abs(o["audio"]).max()) for o in obs) == 1.0
    env.close()


def test_default_observation_keeps_levels_beyond_full_scale():
    """clip=False (the default): a step louder than full scale reaches the agent unclipped, as
    pressure / full_scale_pa, inside the space (bounded at one atmosphere); nothing is counted
    as clipped and nothing warns. A sample beyond one atmosphere is not sound: the warning says
    the simulation has gone wrong."""
    import warnings

    from mjsound.audio_window import ATMOSPHERE_PA

    env = wrapped("Ant-v5", full_scale_pa=1e-3)
    high = env.observation_space["audio"].high
    assert np.all(high == np.float32(ATMOSPHERE_PA / 1e-3))
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        obs, infos = run(env, 7, 25)
    assert sum(i["audio_clipped"] for i in infos) == 0
    loud = max(i["audio_peak_pa"] for i in infos)
    assert loud > 2e-3  # Ant's feet on the floor: louder than this full scale
    top = max(float(np.abs(o["audio"]).max()) for o in obs)
    assert top == pytest.approx(loud / 1e-3, rel=1e-5)  # the peak, unclipped
    assert all(env.observation_space.contains(o) for o in obs)
    with pytest.warns(RuntimeWarning, match="one atmosphere .* gone unstable"):
        env.core._report_clipping(3, 2.0e5)
    env.close()


def test_spectrogram_mode_and_window():
    env = wrapped("Humanoid-v5", mode="spectrogram")
    # Humanoid: dt = 15 ms -> 240 samples < n_fft 256 -> n_fft 128, hop 64, 2 frames
    assert env.observation_space["audio"].shape == (env.n_channels, 65, 2)
    obs, _ = run(env, 0, 3)
    assert all(env.observation_space.contains(o) for o in obs)
    env.close()
    env = wrapped("Ant-v5", window_s=0.1, mode="waveform")
    assert env.observation_space["audio"].shape == (env.n_channels, 1600)
    env.close()


def test_stft_log1p_matches_numpy():
    rng = np.random.default_rng(0)
    x = rng.standard_normal((2, 800)).astype(np.float32)
    win = np.hanning(257)[:-1].astype(np.float32)
    S = stft_log1p(x, 256, 128, win)
    assert S.shape == (2, 129, 5)
    ref = np.log1p(np.abs(np.fft.rfft(x[1, 256:512] * win)))
    np.testing.assert_allclose(S[1, :, 2], ref, rtol=1e-4, atol=1e-5)


def test_materials_star_and_checked_keys_in_the_wrapper():
    assert scene_materials({"x": "oak"}, "steel") == {"x": "oak", "*": "steel"}
    assert scene_materials({"*": "glass"}, "steel") == {"*": "glass"}  # the mapping's own default wins
    assert scene_materials({"x": "oak"}, None) == {"x": "oak"}
    env = wrapped("Hopper-v5", materials={"*": "steel"}, default_material=None)
    assert env.scene.sounding and {s.material.name for s in env.scene.sounding} == {"steel"}
    env.close()
    with pytest.raises(ValueError, match=r"no geom or body named 'tosro'.*closest: 'torso'"):
        wrapped("Hopper-v5", materials={"tosro": "steel"})


def test_masses_option_reaches_the_scene():
    # default: the sound's objects weigh MuJoCo's masses; "material": each keeps its material's
    mujoco_env = wrapped("Hopper-v5", progress=False)
    kept = wrapped("Hopper-v5", progress=False, masses="material")
    rules = {s.mass_rule for s in mujoco_env.scene.sounding}
    assert rules and "kept" not in rules and {s.mass_rule for s in kept.scene.sounding} == {"kept"}
    for e in (mujoco_env, kept):
        e.close()
    with pytest.raises(ValueError, match="masses='solid'"):
        wrapped("Hopper-v5", progress=False, masses="solid")


def test_audio_impacts_count_audible_impacts_only():
    """Only the torso has modes. Without clicks the feet hitting the floor (geoms with no modes)
    are not heard and not counted; with clicks (the default) every moving foot clicks, so every
    impact counts."""
    silent = wrapped("HalfCheetah-v5", materials={"torso": "steel"}, default_material=None, clicks=False)
    assert [s.name for s in silent.scene.sounding] == ["torso"]
    _, infos = run(silent, 1, 20)
    assert silent.sim.reader.n_impacts > 0 and sum(i["audio_impacts"] for i in infos) == 0
    clicking = wrapped("HalfCheetah-v5", materials={"torso": "steel"}, default_material=None)
    _, infos = run(clicking, 1, 20)
    assert sum(i["audio_impacts"] for i in infos) == clicking.sim.reader.n_impacts > 0
    # modes only: the impacts with a side in a sounding object (some feet have no audible modes)
    heard = wrapped("HalfCheetah-v5", clicks=False)
    _, infos = run(heard, 1, 20)
    sounding = heard.scene.by_geom()
    n = sum(1 for r in heard.sim.reader.impacts if r.geom1 in sounding or r.geom2 in sounding)
    assert sum(i["audio_impacts"] for i in infos) == n > 0
    assert n < heard.sim.reader.n_impacts
    for env in (silent, clicking, heard):
        env.close()


class _HandSteppedEnv(gym.Env):
    """A MuJoCo env that steps with its own ``mj_step`` loop (no hook can find it)."""

    def __init__(self):
        import mujoco

        self.model = mujoco.MjModel.from_xml_string(
            '<mujoco><worldbody><geom type="plane" size="1 1 .1"/><body pos="0 0 .3"><freejoint/>'
            '<geom name="box" type="box" size=".15 .15 .005"/></body></worldbody></mujoco>')
        self.data = mujoco.MjData(self.model)
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, (1,), np.float64)
        self.action_space = gym.spaces.Box(-1, 1, (1,), np.float32)
        self.on_substep = None

    def reset(self, *, seed=None, options=None):
        import mujoco

        mujoco.mj_resetData(self.model, self.data)
        return np.array([self.data.time]), {}

    def step(self, action):
        import mujoco

        for _ in range(10):
            mujoco.mj_step(self.model, self.data)
            if self.on_substep is not None:
                self.on_substep()
        return np.array([self.data.time]), 0.0, False, False, {}


def test_an_env_whose_stepping_cannot_be_found_is_refused():
    with pytest.raises(TypeError, match="substeps='manual'"):
        AudioObservation(_HandSteppedEnv(), materials={"box": "steel"})
    inner = _HandSteppedEnv()
    env = AudioObservation(inner, materials={"box": "steel"}, substeps="manual", sample_rate=16000,
                           window_s=10 * inner.model.opt.timestep)  # (it has no dt: tests/test_env_window.py)
    inner.on_substep = lambda: env.sim.step(render=False)
    env.reset(seed=0)
    for _ in range(30):
        obs, _, _, _, info = env.step(env.action_space.sample())
    assert env.sim.steps == 300 and env.sim.reader.n_impacts > 0
    with pytest.raises(ValueError, match="substeps="):
        AudioObservation(_HandSteppedEnv(), substeps="magic")


def fetch_rollout(seed, steps=36):
    """FetchPickAndPlace (gymnasium-robotics): the gripper driven down onto the table, then random."""
    import gymnasium_robotics

    gym.register_envs(gymnasium_robotics)
    env = AudioObservation(gym.make("FetchPickAndPlace-v4"), sample_rate=16000)
    env.reset(seed=seed)
    env.action_space.seed(seed)
    audio, impacts = [], 0
    for i in range(steps):
        a = np.array([0.0, 0.0, -1.0, 0.0]) if i < 24 else env.action_space.sample()
        obs, _, _, _, info = env.step(a)
        assert env.observation_space.contains(obs)
        audio.append(obs["audio"])
        impacts += info["audio_impacts"]
    env.close()
    return env, np.concatenate(audio, axis=1), impacts


def test_gymnasium_robotics_fetch_is_heard_and_reproducible():
    env, a, impacts = fetch_rollout(3)
    u = env.unwrapped
    assert env.sim.steps == 36 * u.n_substeps  # every substep of _mujoco_step went through the simulator
    assert impacts > 0 and np.abs(a).max() > 0
    assert a.shape[1] == 36 * round(u.dt * 16000)
    _, b, _ = fetch_rollout(3)
    np.testing.assert_array_equal(a, b)


def test_vector_envs():
    fns = [lambda: wrapped("HalfCheetah-v5") for _ in range(2)]
    for cls in (gym.vector.SyncVectorEnv, gym.vector.AsyncVectorEnv):
        venv = cls(fns)
        obs, info = venv.reset(seed=[0, 1])
        assert obs["audio"].shape == (2, 1, 800) and obs["observation"].shape == (2, 17)
        for _ in range(3):
            obs, r, term, trunc, info = venv.step(venv.action_space.sample())
        assert obs["audio"].dtype == np.float32 and info["audio_clipped"].shape == (2,)
        venv.close()


def test_dict_observation_keeps_its_keys():
    inner = gym.make("Ant-v5")
    space = gym.spaces.Dict({"state": inner.observation_space})
    dict_env = gym.wrappers.TransformObservation(inner, lambda o: {"state": o}, space)
    env = AudioObservation(dict_env)
    assert set(env.observation_space.spaces) == {"state", "audio"}
    obs, _ = env.reset(seed=0)
    obs, *_ = env.step(env.action_space.sample())
    assert set(obs) == {"state", "audio"} and env.observation_space.contains(obs)
    env.close()


def test_rejects_non_mujoco_env():
    with pytest.raises(TypeError):
        AudioObservation(gym.make("CartPole-v1"))


@pytest.mark.parametrize("clip", [True, False])
def test_audio_window_push_matches_numpy_reference(clip):
    """The numba push: shift, scale, clip to [-limit, limit] (1 with ``clip``, else one
    atmosphere in full-scale units), NaN/Inf -> 0 and counted, peak before clipping; blocks
    shorter, equal and longer than the window."""
    from mjsound.audio_window import ATMOSPHERE_PA
    from mjsound.wrappers import AudioWindow

    rng = np.random.default_rng(3)
    win = AudioWindow(2, 50, full_scale_pa=2.0, clip=clip)
    limit = 1.0 if clip else ATMOSPHERE_PA / 2.0
    assert win.space.high.max() == np.float32(limit) and win.space.low.min() == np.float32(-limit)
    ref = np.zeros((2, 50), np.float32)
    for n in (7, 50, 64, 1, 30):
        block = (rng.normal(size=(2, n)) * 2.5).astype(np.float32)
        block[0, 0] = np.nan
        block[1, -1] = np.inf
        block[0, -1] = -3.0e5  # (beyond one atmosphere: clipped either way)
        clipped, peak = win.push(block)
        x = block / np.float32(2.0)
        bad = ~np.isfinite(x)
        x = np.where(bad, 0.0, x).astype(np.float32)
        assert clipped == int(bad.sum() + (np.abs(x) > limit).sum())
        assert peak == pytest.approx(float(np.abs(x).max()) * 2.0, rel=1e-6)
        ref = np.concatenate([ref, np.clip(x, -limit, limit)], axis=1)[:, -50:]
        np.testing.assert_array_equal(win.observe(), ref)
    assert win.push(np.zeros((2, 0), np.float32)) == (0, 0.0)
    with pytest.raises(ValueError, match="clip="):
        AudioWindow(1, 8, clip="yes")


def test_maze_env_is_heard_through_its_inner_env():
    """gymnasium-robotics' mazes step an inner MujocoEnv (``PointMazeEnv.point_env``) that shares the
    maze's model: that inner env's stepping is hooked, and the ball rolled into a wall is heard."""
    import gymnasium_robotics

    gym.register_envs(gymnasium_robotics)
    env = AudioObservation(gym.make("PointMaze_UMaze-v3"), sample_rate=16000, progress=False)
    env.reset(seed=0)
    inner = env.unwrapped.point_env
    assert "_step_mujoco_simulation" in vars(inner)  # the hook sits on the inner env
    peaks, impacts = [], 0
    for _ in range(40):  # pushed along -x from the seeded start, the ball meets a wall at step ~11
        obs, _, _, _, info = env.step(np.array([-1.0, 0.0]))
        peaks.append(info["audio_peak_pa"])
        impacts += info["audio_impacts"]
    assert env.sim.steps == 40 * inner.frame_skip  # every substep went through the simulator
    assert impacts >= 1 and max(peaks) > 0 and np.isfinite(peaks).all()
    env.close()
    assert "_step_mujoco_simulation" not in vars(inner)  # close() puts the class method back
