"""``mjsound/TapContainers-v0``: tap identical sealed containers to find the one with the part.

Task
----
Three identical-looking sealed aluminium containers (0.12 x 0.12 x 0.08 m, 8 mm walls, a small
vent in the lid; ``assets/envs/container_empty.obj``) stand welded to a table in a row 0.2 m
apart. At every reset one of them, chosen uniformly at random, holds a heavy block
(0.072 x 0.048 x 0.048 m, off-centre) fused to its floor (``container_loaded.obj``). The agent
can drop a small steel hammer ball (r = 1 cm, 33 g) onto the lid of any container and then
must say which container holds the block. The containers are welded, their collision shape is
the same box, so the hammer's motion and the state vector are identical whichever one is
loaded: only the sound differs (the block changes the container's modes: mjsound's modal
analysis of each surface, hex method, resolution 15).

Spaces
------
action : ``Discrete(2 N)`` (N = 3). ``i < N``: tap container ``i`` (the hammer is placed 1.2 cm
    above a random point within 1 cm of the lid's centre, moving down at 0.8-1.2 m/s, and the
    physics runs for one step, ``dt = 0.05 s`` = 50 steps of 1 ms); ``N + i``: answer
    container ``i`` (ends the episode).
observation : ``Dict``
    ``"audio"``: float32 ``(1, window)`` (default one step: 800 samples at 16 kHz) in
    full-scale units (20 Pa -> 1), or ``log1p(|STFT|)`` with ``mode="spectrogram"``;
    ``"state"``: float64 ``(13,)``, the hammer's free-joint ``qpos`` and ``qvel``.

Reward
------
``+1`` for the right container, ``0`` for a wrong one, ``-tap_cost`` (default 0.01) per tap.
Truncated after 12 steps by the registration. Chance: ``1 / N``.

Info
----
``loaded`` (the true index, for evaluation only) and the audio keys (``audio_clipped``,
``audio_peak_pa``, ``audio_samples``, ``audio_impacts``).

Options
-------
``reset(options={"loaded": i})`` fixes the loaded container.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from .assets import asset_path, container_mesh
from .base import AudioMujocoEnv, modal_model

__all__ = ["TapContainersEnv", "N_CONTAINERS", "CONTAINER_ANALYSIS"]

N_CONTAINERS = 3
#: Modal analysis of the container surfaces (quadratic hex cells, 10 along the longest side:
#: the 8 mm walls' plate modes in a few seconds; the scripted policy scores >= 0.7 with it).
CONTAINER_ANALYSIS = {"method": "hex", "quality": "draft", "resolution": 10, "error_estimate": False}
PARK = np.array([0.5, 0.0, 0.03, 1.0, 0.0, 0.0, 0.0])


class TapContainersEnv(AudioMujocoEnv):
    metadata = {"render_modes": ["human", "rgb_array", "depth_array"], "render_fps": 20}

    def __init__(self, sample_rate: int = 16000, window_s: float | None = None, mode: str = "waveform",
                 n_fft: int = 256, hop: int | None = None, full_scale_pa: float = 20.0, tap_cost: float = 0.01,
                 render_mode=None, **kw):
        self.n = N_CONTAINERS
        self.tap_cost = float(tap_cost)
        state_space = spaces.Box(-np.inf, np.inf, (13,), np.float64)
        super().__init__(asset_path("tap_containers.xml"), 50, state_space, spaces.Discrete(2 * self.n),
                         sample_rate=sample_rate, window_s=window_s, mode=mode, n_fft=n_fft, hop=hop,
                         full_scale_pa=full_scale_pa, render_mode=render_mode, **kw)
        import mujoco

        self._top = []
        for i in range(self.n):
            g = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_GEOM, f"container{i}")
            b = self.model.geom_bodyid[g]
            self._top.append(np.array(self.model.body_pos[b]) + [0, 0, self.model.geom_size[g][2]])
        self._loaded = 0

    def _variant_scene(self, k):
        fs = self.sample_rate
        empty = modal_model(container_mesh(False), "aluminium", fs, key="container_empty", **CONTAINER_ANALYSIS)
        loaded = modal_model(container_mesh(True), "aluminium", fs, key="container_loaded", **CONTAINER_ANALYSIS)
        models = {f"container{i}": (loaded if i == k else empty) for i in range(self.n)}
        return None, models

    def reset_model(self):
        opt = self._options or {}
        k = int(opt["loaded"]) if "loaded" in opt else int(self.np_random.integers(self.n))
        self._loaded = k
        qpos = self.init_qpos.copy()
        qpos[:7] = PARK
        self.set_state(qpos, np.zeros(self.model.nv))
        self._use_variant(k)
        return self._obs()

    def reset(self, *, seed=None, options=None):
        self._options = options
        obs, info = super().reset(seed=seed, options=options)
        return obs, {**info, **self._silent_info(), "loaded": self._loaded}

    def step(self, action):
        a = int(action)
        if not self.action_space.contains(a):
            raise ValueError(f"action {action!r} not in {self.action_space}")
        if a < self.n:
            rng = self.np_random
            qpos = self.data.qpos.copy()
            qvel = np.zeros(self.model.nv)
            r, phi = 0.01 * np.sqrt(rng.uniform()), rng.uniform(0, 2 * np.pi)
            qpos[:3] = self._top[a] + [r * np.cos(phi), r * np.sin(phi), 0.012 + 0.01]
            qpos[3:7] = [1, 0, 0, 0]
            qvel[2] = -rng.uniform(0.8, 1.2)
            self.set_state(qpos, qvel)
            info = self._listen()
            reward, terminated = -self.tap_cost, False
        else:
            info = self._silent_info()
            reward, terminated = float(a - self.n == self._loaded), True
        info["loaded"] = self._loaded
        if self.render_mode == "human":
            self.render()
        return self._obs(), reward, terminated, False, info
