"""dm_control wrapper: contact sound as an observation of a ``dm_env.Environment``.

:class:`AudioEnvironment` wraps a dm_control suite environment (``suite.load(...)``, an
``rl.control.Environment``) and adds an ``"audio"`` entry to its observation, with the same
options, spec and reset semantics as the gymnasium wrapper
:class:`mjsound.wrappers.AudioObservation` (they share :class:`mjsound.wrappers.EnvAudio`):

* every physics substep is heard: the wrapper replaces ``physics.step`` on the env's
  ``Physics`` instance by one that runs the same MuJoCo calls (dm_control's legacy step:
  ``mj_step2``, ``nstep - 1`` ``mj_step``, ``mj_step1``; or ``nstep`` ``mj_step``) and reads
  the contacts after each completed step (:class:`mjsound.env_stepping.DmPhysicsStepping`);
* composer environments (``dm_control.manipulation``, ``composer.Environment``) build a new
  ``Physics`` at the first reset and, while they recompile the MJCF every episode (the
  default of manipulation tasks), at every reset, and free the old one: after each reset the
  wrapper follows the physics the env steps now (a scene and simulator for it, modal models
  from the memo and the disk cache when the geometry is the same) and keeps no reference to
  a freed one;
* ``reset()`` (and the reset dm_control does by itself on the step after a ``LAST`` step)
  silences the ringing and re-anchors the audio clock (``AudioSimulator.reset``), so nothing of
  the last episode carries over;
* ``observation_spec()["audio"]`` is a ``dm_env.specs.BoundedArray`` float32, the bounds and
  shape of ``AudioObservation``'s (waveform: one atmosphere in full-scale units, [-1, 1] with
  ``clip=True``).

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

from .env_audio import EnvAudio

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
        ``sim_kwargs``, ``objects``, ``sound_meshes``, ``play`` (live audio, docs/live.md),
        ``reflections`` (default True: the floor reflects; docs/rooms.md), ``room``, ``masses``,
        ``clip`` (default False: no clipping at full scale).

    Attributes
    ----------
    scene, sim : the :class:`mjsound.sim.SoundScene` and :class:`mjsound.sim.AudioSimulator`.
    last_info : dict
        ``audio_clipped``, ``audio_peak_pa``, ``audio_samples``, ``audio_impacts`` of the last
        step (as the gymnasium wrapper's ``info``; a ``TimeStep`` has no info).
    """

    def __init__(self, env, seed: int | None = None, **options):
        from .env_stepping import DmPhysicsStepping, _is_dm_env

        if not _is_dm_env(env):
            raise TypeError("AudioEnvironment needs a dm_control environment with a MuJoCo physics "
                            "(env.physics.model.ptr / env.physics.data.ptr, env.control_timestep()), e.g. "
                            "dm_control.suite.load(...) or a composer.Environment")
        self._env = env
        self._seed = seed
        self._route = DmPhysicsStepping(env)
        model, data = self._route.current()
        self.core = EnvAudio(model, data, self._route.step_dt(), dt_source="env.control_timestep()", **options)
        self.audio = self.core.audio
        self.last_info = {}
        self._route.install(self.core.sim)

    @property
    def sim(self):
        """The :class:`mjsound.sim.AudioSimulator` of the physics the env steps now (composer
        builds a new one at resets)."""
        return self.core.sim

    @property
    def scene(self):
        """The :class:`mjsound.sim.SoundScene` of the physics the env steps now."""
        return self.core.scene

    def _follow_physics(self) -> None:
        """After a reset: follow the physics composer built (at the first reset, and at every
        reset while it recompiles the MJCF each episode; it frees the old one)."""
        model, data = self._route.current()
        if not self.core.follows(model, data):
            self.core.rebind(model, data)
            self._route.install(self.core.sim)

    _closed = False

    def close(self) -> None:
        """Give the physics its own ``step`` back and close the wrapped env."""
        self._closed = True
        self.core.close()
        self._route.remove()
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
        self._follow_physics()
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
        """The env's physics now (composer's: a weak proxy that dies at its next recompilation)."""
        return self._env.physics

    def __getattr__(self, name):
        if name.startswith("_"):
            raise AttributeError(name)
        return getattr(self._env, name)
