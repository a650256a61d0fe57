"""The audio environments (envs/): registration, spaces, determinism, the state vector carries
no task information, and scripted policies that use only the audio beat chance.

Modal models are computed once per process (envs.base.modal_model), so the analyses (~20 s in
all) are paid once for the whole file.
"""

from __future__ import annotations

import os
import sys

import gymnasium as gym
import numpy as np
import pytest

# the repository's envs/ package (an editable install made before envs/__init__.py existed maps
# "envs" to a namespace package; the checkout wins this way)
sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
import envs  # noqa: E402,F401  (registers the envs)


@pytest.fixture(scope="module")
def drop_env():
    env = gym.make("mjsound/MaterialDrop-v0")
    yield env
    env.close()


@pytest.fixture(scope="module")
def tap_env():
    env = gym.make("mjsound/TapContainers-v0")
    yield env
    env.close()


def _power(x):
    return np.abs(np.fft.rfft(x * np.hanning(x.shape[-1]), axis=-1)) ** 2


def _signature(p):
    """Normalised log power spectrum (a policy feature built from audio only)."""
    s = np.log(p + 1e-12 * p.max() + 1e-30)
    s = s - s.mean()
    return s / (np.linalg.norm(s) + 1e-12)


# ---------------------------------------------------------------------- MaterialDrop
def _listen_episode(env, seed, options=None, after=3, max_steps=35):
    """Listen until the first sound and ``after`` more steps; the accumulated power spectrum."""
    obs, info = env.reset(seed=seed, options=options)
    acc, heard = 0.0, None
    for t in range(max_steps):
        obs, r, term, trunc, info = env.step(0)
        x = obs["audio"][0]
        if heard is None and np.abs(x).max() > 1e-4:
            heard = t
        if heard is not None:
            acc = acc + _power(x)
            if t - heard >= after:
                break
    return acc, info


def test_material_drop_spaces_and_check_env(drop_env):
    u = drop_env.unwrapped
    assert drop_env.observation_space["audio"].shape == (1, 320)
    assert drop_env.action_space.n == 1 + len(u.materials)
    obs, info = drop_env.reset(seed=0)
    assert drop_env.observation_space.contains(obs)
    assert not obs["audio"].any()
    from gymnasium.utils.env_checker import check_env

    check_env(drop_env.unwrapped, skip_render_check=True)


def test_material_drop_state_is_material_blind(drop_env):
    states, audio = [], []
    for k in (0, 2):
        obs, _ = drop_env.reset(seed=5, options={"material": k})
        for _ in range(15):
            obs, *_ = drop_env.step(0)
        states.append(obs["state"])
        audio.append(obs["audio"])
    assert np.array_equal(states[0], states[1])  # identical physics
    assert not np.allclose(audio[0], audio[1])  # different sound


def test_material_drop_audio_policy_beats_chance(drop_env):
    u = drop_env.unwrapped
    K = len(u.materials)
    templates = []
    for k in range(K):  # calibration: listen to each material twice
        sig = [_signature(_listen_episode(drop_env, 100 + 7 * k + j, {"material": k})[0]) for j in range(2)]
        templates.append(np.mean(sig, axis=0))
    templates = np.array(templates)
    correct, n = 0, 12
    for ep in range(n):
        acc, info = _listen_episode(drop_env, 1000 + ep)
        guess = int(np.argmax(templates @ _signature(acc)))
        obs, r, term, trunc, info = drop_env.step(1 + guess)
        assert term
        correct += r
    assert correct / n >= 0.6, f"accuracy {correct}/{n} (chance {1 / K:.2f})"


# ---------------------------------------------------------------------- TapContainers
def test_tap_containers_state_is_blind_and_reproducible(tap_env):
    runs = []
    for k in (0, 1, 1):
        obs, info = tap_env.reset(seed=3, options={"loaded": k})
        for i in range(3):
            obs, r, term, trunc, info = tap_env.step(i)
            assert r == pytest.approx(-0.01) and not term
            assert info["audio_impacts"] >= 1
        runs.append(obs)
    assert np.array_equal(runs[0]["state"], runs[1]["state"])
    assert not np.allclose(runs[0]["audio"], runs[1]["audio"])
    assert np.array_equal(runs[1]["audio"], runs[2]["audio"])  # same seed -> same audio
    assert tap_env.observation_space.contains(runs[0])


def test_tap_containers_audio_policy_beats_chance(tap_env):
    n_ok, n = 0, 9
    N = tap_env.unwrapped.n
    for ep in range(n):
        obs, info = tap_env.reset(seed=200 + ep)
        sigs = []
        for i in range(N):  # tap every container once
            obs, *_ = tap_env.step(i)
            sigs.append(_signature(_power(obs["audio"][0])))
        sigs = np.array(sigs)
        dist = 1.0 - sigs @ sigs.T
        guess = int(np.argmax(dist.sum(axis=1)))  # the odd one out
        obs, r, term, trunc, info = tap_env.step(N + guess)
        assert term
        n_ok += r == 1.0
    assert n_ok / n >= 0.7, f"accuracy {n_ok}/{n} (chance {1 / N:.2f})"


def test_spectrogram_mode():
    env = gym.make("mjsound/TapContainers-v0", mode="spectrogram")
    obs, _ = env.reset(seed=0, options={"loaded": 1})
    obs, *_ = env.step(1)
    a = obs["audio"]
    assert a.shape == env.observation_space["audio"].shape == (1, 129, 5)
    assert env.observation_space.contains(obs) and a.max() > 0
    env.close()


# ---------------------------------------------------------------------- PalmDrop (contact microphone)
@pytest.fixture(scope="module")
def palm_env():
    env = gym.make("mjsound/PalmDrop-v0")
    yield env
    env.close()


def _feel_episode(env, seed, options=None, after=3, max_steps=25):
    """Listen (contact microphone only) until the first sound and ``after`` more steps; the
    features a scripted policy uses: log energy and spectral centroid [kHz]."""
    obs, info = env.reset(seed=seed, options=options)
    x, heard = [], None
    for t in range(max_steps):
        obs, r, term, trunc, info = env.step(0)
        a = obs["audio"][0]
        if heard is None and np.abs(a).max() > 0:
            heard = t
        if heard is not None:
            x.append(a)
            if t - heard >= after:
                break
    x = np.concatenate(x) if x else np.zeros(2)
    p = _power(x)
    f = np.fft.rfftfreq(len(x), 1.0 / env.unwrapped.sample_rate)
    return np.array([np.log10(np.sum(x * x) + 1e-30), (p * f).sum() / max(p.sum(), 1e-300) / 1000.0]), info


def test_palm_drop_contact_channel_only_and_state_blind(palm_env):
    u = palm_env.unwrapped
    assert palm_env.observation_space["audio"].shape == (1, 320)
    states, audio = [], []
    for k in (0, 2):
        obs, _ = palm_env.reset(seed=4, options={"material": k})
        for _ in range(6):
            obs, *_ = palm_env.step(0)
        states.append(obs["state"])
        audio.append(obs["audio"])
    assert list(u.sim.contact_channels) == [1]
    assert u.sim.channel_names[1] == "contact_mic_plate"  # (channel 0: the default air listener, unused)
    assert np.array_equal(states[0], states[1])  # identical physics
    assert not np.allclose(audio[0], audio[1])  # different feel


def test_palm_drop_contact_mic_policy_beats_chance(palm_env):
    u = palm_env.unwrapped
    K = len(u.materials)
    cal = np.array([[_feel_episode(palm_env, 200 + 5 * k + j, {"material": k})[0] for j in range(2)] for k in range(K)])
    templates = cal.mean(axis=1)
    scale = cal.reshape(-1, 2).std(axis=0) + 1e-9
    correct, n = 0, 12
    for ep in range(n):
        feat, info = _feel_episode(palm_env, 2000 + ep)
        guess = int(np.argmin(np.sum(((templates - feat) / scale) ** 2, axis=1)))
        obs, r, term, trunc, info = palm_env.step(1 + guess)
        assert term
        correct += r
    assert correct / n >= 0.6, f"accuracy {correct}/{n} (chance {1 / K:.2f})"
