"""dm_control wrapper: contact sound as an observation of a ``dm_env.Environment``.

:class:`AudioEnvironment` wraps a dm_control suite environment (``suite.load(...)``, an
``rl.control.Environment``) and adds an ``"audio"`` entry to its observation, with the same
options, spec and reset semantics as the gymnasium wrapper
:class:`mjsound.wrappers.AudioObservation` (they share :class:`mjsound.wrappers.EnvAudio`):

* every physics substep is heard: the wrapper replaces ``physics.step`` on the env's
  ``Physics`` instance by one that runs the same MuJoCo calls (dm_control's legacy step:
  ``mj_step2``, ``nstep - 1`` ``mj_step``, ``mj_step1``; or ``nstep`` ``mj_step``) and reads
  the contacts after each completed step;
* ``reset()`` (and the reset dm_control does by itself on the step after a ``LAST`` step)
  silences the ringing and re-anchors the audio clock (``AudioSimulator.reset``), so nothing of
  the last episode carries over;
* ``observation_spec()["audio"]`` is a ``dm_env.specs.BoundedArray`` float32 in [-1, 1]
  (waveform) or [0, log1p(sum(hann))] (spectrogram), the shape of ``AudioObservation``'s.

Example
-------
>>> from dm_control import suite                                   # doctest: +SKIP
>>> from mjsound.dmc import AudioEnvironment                       # doctest: +SKIP
>>> env = AudioEnvironment(suite.load("ball_in_cup", "catch"))     # doctest: +SKIP
>>> ts = env.reset()                                               # doctest: +SKIP
>>> ts.observation["audio"].shape   # (1, round(control_timestep * 16000)) = (1, 320)  # doctest: +SKIP

(This module is ``mjsound.dmc``, not ``mjsound.dm_control``, so that it never shadows the
``dm_control`` package.)
"""

from __future__ import annotations

import collections

import dm_env
import numpy as np

from .wrappers import EnvAudio

__all__ = ["AudioEnvironment"]


class AudioEnvironment(dm_env.Environment):
    """A ``dm_env.Environment`` with an ``"audio"`` observation (module docstring).

    Parameters
    ----------
    env : dm_control.rl.control.Environment
        A dm_control environment with a MuJoCo ``physics`` (``suite.load(...)``).
    seed : int, optional
        Seed of the wrapper's generator, from which every reset draws the seed of the sliding /
        rolling noise (the same seed, task seed and actions give bit-identical audio; None:
        a fresh generator, as ``AudioObservation.reset()`` without a seed).
    **options
        Those of :class:`mjsound.wrappers.AudioObservation`: ``sample_rate`` (16 kHz),
        ``window_s`` (default one control step), ``mode``, ``mics``, ``materials``,
        ``default_material`` ("aluminium"), ``full_scale_pa``, ``n_fft``, ``hop``,
        ``follow``, ``quality`` ("draft"), ``budget_modes``, ``models``, ``progress``,
        ``sim_kwargs``, ``objects``, ``sound_meshes``.

    Attributes
    ----------
    scene, sim : the :class:`mjsound.sim.SoundScene` and :class:`mjsound.sim.AudioSimulator`.
    last_info : dict
        ``audio_clipped``, ``audio_peak_pa``, ``audio_samples``, ``audio_impacts`` of the last
        step (as the gymnasium wrapper's ``info``; a ``TimeStep`` has no info).
    """

    def __init__(self, env, seed: int | None = None, **options):
        physics = getattr(env, "physics", None)
        model = getattr(getattr(physics, "model", None), "ptr", None)
        data = getattr(getattr(physics, "data", None), "ptr", None)
        if model is None or data is None or not callable(getattr(physics, "step", None)):
            raise TypeError("AudioEnvironment needs a dm_control environment with a MuJoCo physics "
                            "(env.physics.model.ptr / env.physics.data.ptr), e.g. dm_control.suite.load(...)")
        self._env = env
        self._physics = physics
        self._seed = seed
        self.core = EnvAudio(model, data, float(env.control_timestep()), **options)
        self.scene, self.sim, self.audio = self.core.scene, self.core.sim, self.core.audio
        self.last_info = {}
        self._hook()

    # ------------------------------------------------------------------ stepping
    def _hook(self) -> None:
        """Replace ``physics.step`` (on the instance) by the same MuJoCo calls with every
        completed step read (dm_control's ``Physics.step``: legacy or plain)."""
        import mujoco

        physics, sim = self._physics, self.sim
        model, data = physics.model.ptr, physics.data.ptr

        def step(nstep: int = 1) -> None:
            nstep = int(nstep)
            with physics.check_invalid_state():
                if getattr(physics, "legacy_step", False):
                    if model.opt.integrator != mujoco.mjtIntegrator.mjINT_RK4.value:
                        mujoco.mj_step2(model, data)  # completes the step mj_step1 began
                        sim.step(render=False)
                        if nstep > 1:
                            sim.substeps(nstep - 1, render=True)
                    else:
                        sim.substeps(nstep, render=True)
                    mujoco.mj_step1(model, data)
                else:
                    sim.substeps(nstep, render=True)  # (rendered in the same numba call; end_step flushes)

        physics.step = step

    _closed = False

    def close(self) -> None:
        """Give the physics its own ``step`` back and close the wrapped env."""
        self._closed = True
        if "step" in vars(self._physics):
            del self._physics.step
        close = getattr(self._env, "close", None)
        if close is not None:
            close()

    # ------------------------------------------------------------------ dm_env API
    def _with_audio(self, ts, audio):
        obs = ts.observation
        if isinstance(obs, dict):
            out = collections.OrderedDict(obs)
        else:
            out = collections.OrderedDict(observations=obs)
        out["audio"] = audio
        return ts._replace(observation=out)

    def reset(self):
        ts = self._env.reset()
        return self._after_reset(ts)

    def _after_reset(self, ts):
        seed, self._seed = self._seed, None  # (seeds the generator once; later resets draw from it)
        self.last_info = self.core.reset(seed)
        return self._with_audio(ts, self.audio.observe())

    def step(self, action):
        if self._closed:
            raise RuntimeError("AudioEnvironment.step() after close(): make a new environment")
        ts = self._env.step(action)
        if ts.first():  # dm_control reset by itself after a LAST step
            return self._after_reset(ts)
        audio, self.last_info = self.core.end_step()
        return self._with_audio(ts, audio)

    def observation_spec(self):
        spec = self._env.observation_spec()
        space = self.audio.space
        audio = dm_env.specs.BoundedArray(shape=space.shape, dtype=np.float32, minimum=float(space.low.min()),
                                                maximum=float(space.high.max()), name="audio")
        out = collections.OrderedDict(spec) if isinstance(spec, dict) else collections.OrderedDict(observations=spec)
        if "audio" in out:
            raise ValueError("the wrapped observation already has an 'audio' key")
        out["audio"] = audio
        return out

    def action_spec(self):
        return self._env.action_spec()

    def reward_spec(self):
        return self._env.reward_spec()

    def discount_spec(self):
        return self._env.discount_spec()

    @property
    def physics(self):
        return self._physics

    def __getattr__(self, name):
        if name.startswith("_"):
            raise AttributeError(name)
        return getattr(self._env, name)
