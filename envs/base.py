"""`AudioMujocoEnv`: a gymnasium MuJoCo env whose observation carries its own contact sound.

Subclasses pick, at every reset, one *acoustic variant* of the same physical scene (a material,
which container holds the part, ...): each variant is an :class:`mjsound.sim.AudioSimulator` on
the env's own ``model`` / ``data`` with its own modal models, built once and kept. The physics
is identical across variants, so only the sound tells them apart.

Contacts are read at every physics substep (``_step_mujoco_simulation`` steps one ``mj_step``
at a time), the audio window and its scaling are :class:`mjsound.wrappers.AudioWindow`'s
(pressure / ``full_scale_pa`` clipped to [-1, 1], or ``log1p(|STFT|)``).
"""

from __future__ import annotations

import mujoco
import numpy as np
from gymnasium import spaces
from gymnasium.envs.mujoco import MujocoEnv

from mjsound.wrappers import AudioWindow

__all__ = ["AudioMujocoEnv", "NameTheMaterialEnv", "modal_model"]

#: Process-wide memo of modal models: (mesh key, material, sample rate, analysis kwargs) -> ModalModel.
_MODELS: dict = {}


def modal_model(mesh, material: str, sample_rate: int, key=None, **kw):
    """``mjsound.analyze(mesh, material, sample_rate=..., **kw)`` computed once per process
    (and disk-cached by ``analyze`` itself)."""
    k = (key if key is not None else mesh, material, int(sample_rate), tuple(sorted(kw.items())))
    mm = _MODELS.get(k)
    if mm is None:
        from mjsound.modal.analyze import analyze
        from mjsound.sim.scene_analysis import SCENE_RADIATION

        # an env's objects take a scene's radiation setting (SCENE_RADIATION), not analyze's own
        kw.setdefault("radiation", SCENE_RADIATION.get(kw.get("quality", "default")))
        mm = analyze(mesh, material, sample_rate=sample_rate, progress=False, **kw)
        _MODELS[k] = mm
    return mm


class AudioMujocoEnv(MujocoEnv):
    """Base class (see the module docstring). Subclasses define ``_variant_scene(key)``
    (``(materials, models)`` for :meth:`SoundScene.from_model`) and the task, and whether the
    observation is the air microphone (``listen_to = "air"``) or the scene's contact
    microphone (``"contact"``: its surface acceleration [m/s^2] / ``full_scale_pa``)."""

    listen_to = "air"

    def __init__(self, model_path, frame_skip, state_space, action_space, *, sample_rate=16000, window_s=None,
                 mode="waveform", n_fft=256, hop=None, full_scale_pa=20.0, render_mode=None, **kw):
        self._action_space_spec = action_space
        MujocoEnv.__init__(self, model_path, frame_skip, observation_space=None, render_mode=render_mode, **kw)
        self.sample_rate = int(sample_rate)
        window = int(round((self.dt if window_s is None else float(window_s)) * self.sample_rate))
        self.audio = AudioWindow(1, window, full_scale_pa, mode, n_fft, hop)
        self.observation_space = spaces.Dict({"audio": self.audio.space, "state": state_space})
        self._sims = {}
        self.sim = None

    def _set_action_space(self):
        self.action_space = self._action_space_spec
        return self.action_space

    # ------------------------------------------------------------------ audio
    def _variant_scene(self, key):  # pragma: no cover - abstract
        raise NotImplementedError

    def _use_variant(self, key) -> None:
        """Make ``key``'s simulator the active one (built on first use), silence it, seed it."""
        sim = self._sims.get(key)
        if sim is None:
            from mjsound.sim import AudioSimulator, SoundScene

            materials, models = self._variant_scene(key)
            scene = SoundScene.from_model(self.model, materials=materials, models=models,
                                          sample_rate=self.sample_rate, progress=False)
            sim = AudioSimulator(self.model, self.data, scene=scene, sample_rate=self.sample_rate, progress=False)
            self._sims[key] = sim
        self.sim = sim
        if sim.synth is not None:
            sim.synth.seed = int(self.np_random.integers(2**31 - 1))
        sim.reset()
        self.audio.reset()

    def _step_mujoco_simulation(self, ctrl, n_frames):
        if self.model.nu:
            self.data.ctrl[:] = ctrl
        for _ in range(int(n_frames)):
            mujoco.mj_step(self.model, self.data)
            self.sim.step(render=False)  # rendered once per env step, in _listen
        mujoco.mj_rnePostConstraint(self.model, self.data)

    def _listen(self, n_frames=None) -> dict:
        """Run ``n_frames`` substeps (default ``frame_skip``) with sound; the audio info."""
        n_imp = self.sim.events["impact"]
        self._step_mujoco_simulation(np.zeros(self.model.nu), self.frame_skip if n_frames is None else n_frames)
        block = self.sim.flush()
        if self.listen_to == "contact":
            block = block[self.sim.contact_channels]
        clipped, peak = self.audio.push(block)
        return {"audio_clipped": clipped, "audio_peak_pa": peak, "audio_samples": int(block.shape[1]),
                "audio_impacts": int(self.sim.events["impact"] - n_imp)}

    def _silent_info(self) -> dict:
        return {"audio_clipped": 0, "audio_peak_pa": 0.0, "audio_samples": 0, "audio_impacts": 0}

    def _obs(self) -> dict:
        return {"audio": self.audio.observe(), "state": self._state()}

    def _state(self) -> np.ndarray:
        return np.concatenate([self.data.qpos, self.data.qvel]).astype(np.float64)


class NameTheMaterialEnv(AudioMujocoEnv):
    """The task of MaterialDrop and PalmDrop: one free body (state: its ``qpos`` (7) and
    ``qvel`` (6)) gets one of ``materials`` at every reset; action 0 listens for one step,
    action ``1 + k`` names material ``k`` and ends the episode (+1 if right).

    Subclasses place the body in ``reset_model`` after ``k = self._pick_material()`` and end
    it with ``self._use_variant(k)``; ``reset(options={"material": name_or_index})`` fixes it."""

    def __init__(self, model_path, materials, task: str, **kw):
        self.materials = tuple(materials)
        if len(self.materials) < 2:
            raise ValueError(f"{task} needs at least two materials")
        state_space = spaces.Box(-np.inf, np.inf, (13,), np.float64)
        super().__init__(model_path, 20, state_space, spaces.Discrete(1 + len(self.materials)), **kw)
        self._material = 0

    def _pick_material(self) -> int:
        opt = self._options or {}
        if "material" in opt:
            m = opt["material"]
            k = self.materials.index(m) if isinstance(m, str) else int(m)
        else:
            k = int(self.np_random.integers(len(self.materials)))
        self._material = k
        return k

    def reset(self, *, seed=None, options=None):
        self._options = options
        obs, info = super().reset(seed=seed, options=options)
        return obs, {**info, **self._silent_info(), "material": self.materials[self._material]}

    def step(self, action):
        a = int(action)
        if not self.action_space.contains(a):
            raise ValueError(f"action {action!r} not in {self.action_space}")
        if a == 0:
            info = self._listen()
            reward, terminated = 0.0, False
        else:
            info = self._silent_info()
            reward, terminated = float(a - 1 == self._material), True
        info["material"] = self.materials[self._material]
        if self.render_mode == "human":
            self.render()
        return self._obs(), reward, terminated, False, info
