"""AudioObservation on gymnasium's own MuJoCo envs, unmodified (issue 5, gymnasium part).

The modal models of each env are analysed once per process (mjsound.wrappers' scene memo), so
the real analyses (a few seconds per env, draft quality at 16 kHz) are paid once per file.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from mjsound.wrappers import AudioObservation, resolve_materials, stft_log1p

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
    assert n_wrapped == sim.events["impact"] > 0
    env.close()
    bare.close()


def test_clipping_is_counted():
    env = wrapped("Ant-v5", full_scale_pa=1e-9)
    _, infos = run(env, 7, 25)
    clipped = sum(i["audio_clipped"] for i in infos)
    assert clipped > 0
    assert all("audio_clipped" in i and "audio_peak_pa" in i for i in infos)
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


def test_default_material_mapping_unnamed_geoms():
    import mujoco

    xml = """<mujoco><custom><text name="mjsound:named" data="glass"/></custom><worldbody>
      <body name="b"><freejoint/><geom type="box" size=".01 .01 .01"/>
        <geom name="named" type="sphere" size=".01"/><geom name="other" type="sphere" size=".01" pos=".02 0 0"/></body>
    </worldbody></mujoco>"""
    m = mujoco.MjModel.from_xml_string(xml)
    mp = resolve_materials(m, {"*": "steel"})
    assert mp["b"] == "steel" and mp["named"] == "glass" and mp["other"] == "steel"
    assert resolve_materials(m, {"x": "oak"}, None) == {"x": "oak"}


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


def test_audio_window_push_matches_numpy_reference():
    """The numba push: shift, scale, clip to [-1, 1], NaN/Inf -> 0 and counted, peak before
    clipping; blocks shorter, equal and longer than the window."""
    from mjsound.wrappers import AudioWindow

    rng = np.random.default_rng(3)
    win = AudioWindow(2, 50, full_scale_pa=2.0)
    ref = np.zeros((2, 50), np.float32)
    for n in (7, 50, 64, 1, 30):
        block = (rng.normal(size=(2, n)) * 2.5).astype(np.float32)
        block[0, 0] = np.nan
        block[1, -1] = np.inf
        clipped, peak = win.push(block)
        x = block / np.float32(2.0)
        bad = ~np.isfinite(x)
        x = np.where(bad, 0.0, x).astype(np.float32)
        assert clipped == int(bad.sum() + (np.abs(x) > 1).sum())
        assert peak == pytest.approx(float(np.abs(x).max()) * 2.0, rel=1e-6)
        ref = np.concatenate([ref, np.clip(x, -1, 1)], axis=1)[:, -50:]
        np.testing.assert_array_equal(win.observe(), ref)
    assert win.push(np.zeros((2, 0), np.float32)) == (0, 0.0)
