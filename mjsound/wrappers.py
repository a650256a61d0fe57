"""Gymnasium wrapper: contact sound as an observation (:class:`AudioObservation`).

Any gymnasium environment built on MuJoCo gets an ``"audio"`` entry in its observation: the
sound the simulation made, computed from the contacts of *every* physics substep of an env
step. The wrapper finds how the env steps MuJoCo (:mod:`mjsound.env_stepping`) and hooks it on
the instance: gymnasium's ``MujocoEnv._step_mujoco_simulation`` and gymnasium-robotics'
``MujocoRobotEnv._mujoco_step`` become the simulator's ``advance`` (single ``mj_step`` calls,
each followed by reading its contacts, in one numba call: :meth:`mjsound.sim.driver.StepDriver.substeps`); a dm_control
physics inside the env (gym-aloha) has its ``physics.step`` hooked; robosuite's ``MjSim``
(through ``robosuite.wrappers.GymWrapper``) its ``step`` / ``step2``. An env that rebuilds its
physics at reset (robosuite's hard reset, composer) is followed after each reset. An env whose
stepping it cannot find is refused at construction (``substeps="manual"``: call
``env.sim.step(render=False)`` after each of its ``mj_step`` calls yourself). :class:`mjsound.env_audio.EnvAudio` is the part
shared with the dm_control wrapper (:mod:`mjsound.dmc`).

Works unmodified on gymnasium's own Ant-v5, Humanoid-v5, HalfCheetah-v5, Pusher-v5, ..., on
Meta-World, gymnasium-robotics' Fetch and Shadow-hand envs, gym-aloha and robosuite (the last
three families, and the first two on mujoco 4, need an opt-in :mod:`mjsound.compat` call;
``docs/envs.md``): geoms with no acoustic material get ``default_material`` (aluminium unless
told otherwise), so the robot's links ring like machined aluminium parts.

Example
-------
>>> import gymnasium as gym                                           # doctest: +SKIP
>>> from mjsound.wrappers import AudioObservation                      # doctest: +SKIP
>>> env = AudioObservation(gym.make("Ant-v5"), sample_rate=16000)      # doctest: +SKIP
>>> obs, info = env.reset(seed=0)                                      # doctest: +SKIP
>>> obs["audio"].shape     # (channels, round(env.unwrapped.dt * 16000)) = (1, 800)  # doctest: +SKIP
"""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np

from .audio_window import AudioWindow, stft_log1p  # noqa: F401 (re-exported)
from .env_audio import EnvAudio, audible_geoms, build_scene, scene_materials  # noqa: F401 (re-exported)
from .env_stepping import find_stepping, steps_of
from .synth.contact_mic import DEFAULT_CONTACT_FULL_SCALE

__all__ = ["AudioObservation", "AudioWindow", "EnvAudio", "scene_materials", "stft_log1p"]


class AudioObservation(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """Add the contact sound of the last env step to the observation.

    Parameters
    ----------
    env : gymnasium.Env
        A MuJoCo env: ``env.unwrapped`` has ``model`` and ``data``, or holds a dm_control
        environment or a robosuite ``MjSim`` (:func:`mjsound.env_stepping.find_stepping`).
        Every physics substep is heard: the wrapper hooks gymnasium's
        ``MujocoEnv._step_mujoco_simulation(ctrl, n_frames)``, gymnasium-robotics'
        ``MujocoRobotEnv._mujoco_step(action)`` (``n_substeps`` steps), dm_control's
        ``physics.step(n)`` or robosuite's ``MjSim.step`` / ``step2``. An env that steps another
        way is refused at construction (``TypeError``) unless ``substeps="manual"``: then call
        ``env.sim.step(render=False)`` after every ``mj_step`` yourself.
    sample_rate : int
        Audio sample rate [Hz] (default 16 kHz, as SoundSpaces; modes above 0.45 fs are not
        computed).
    window_s : float, optional
        Length of the audio window [s]. Default: one env step, i.e.
        ``window = round(dt * sample_rate)`` samples (Ant-v5 at 16 kHz: 800, Humanoid-v5:
        240), ``dt`` from the env: its ``dt``, ``control_timestep``, ``control_dt``, or
        ``frame_skip`` / ``n_substeps`` times the timestep (:func:`mjsound.env_stepping.steps_of`);
        the first step's simulated time must agree (else a ``RuntimeError`` gives the
        ``window_s`` to pass), and an env that says none of these must be given ``window_s``. The window holds the newest samples, zero-padded after reset
        (a physics step renders ``ceil``-aligned sample ranges, so one env step brings
        ``window`` samples +-1 when ``dt * fs`` is not an integer).
    mode : {"waveform", "spectrogram"}
        ``"waveform"``: ``audio`` is float32 ``(channels, window)`` in full-scale units
        (pressure / ``full_scale_pa``; see ``clip``).
        ``"spectrogram"``: ``audio`` is float32 ``(channels, n_fft // 2 + 1, frames)``,
        ``log1p(|STFT|)`` of that waveform (as SoundSpaces / Sonicverse): periodic Hann window
        of ``n_fft`` samples, hop ``hop`` (default ``n_fft // 2``), frames start at sample 0
        with no centring or padding, ``frames = 1 + (window - n_fft) // hop``, unnormalised
        ``scipy.fft.rfft``. If the window is shorter than ``n_fft``, ``n_fft`` becomes the
        largest power of two that fits. Values lie in ``[0, log1p(sum(hann) * limit)]``, ``limit``
        the waveform's bound (``clip``).
    mics : list[str] | (m, 3) array | None
        Microphone sites (follow their bodies) or fixed world positions [m]; one channel each.
        Default: the model's sites named ``mic*``; without any, one listener 1 m from the
        scene (``SoundScene``'s rule) that keeps its offset from ``follow``'s body.
    contact_mics : list[str] | None
        Contact microphone sites (their body's surface acceleration [m/s^2], one channel each,
        after the air microphones); default: the model's sites named ``contact_mic*``
        (``[]``: none). See :class:`mjsound.sim.AudioSimulator`.
    contact_full_scale : float
        Acceleration mapped to 1.0 on the contact channels [m/s^2] (default 1000).
    clicks : bool
        Acceleration noise of every impact at the air microphones (default True).
    reflections : bool | dict
        The scene's planes (the floor) reflect as image sources (default True; False: free
        field); ``{plane name: surface or None}`` sets their surfaces. See
        :class:`mjsound.sim.AudioSimulator` and ``docs/rooms.md``.
    room : mjsound.sim.rooms.Room, optional
        A room around the scene whose walls reflect instead, with its late reverberant tail
        (``Room(..., tail=False)``: the walls' images only).
    materials : dict, optional
        ``{key: material}``, key a geom name, ``geom<ID>`` / id of an unnamed geom, a body name
        or ``"*"`` (the default for all others); see :class:`mjsound.sim.SoundScene`. An
        unknown key is an error listing the closest names.
    default_material : str | Material | None
        Material of geoms that have none (default ``"aluminium"``; ``None`` keeps them
        silent); the same as ``materials["*"]``. Soft materials such as ``"rubber"`` make the
        modal analysis very expensive (slow waves need fine meshes) and are overdamped above a
        few kHz: prefer stiff ones.
    full_scale_pa : float
        Pressure mapped to 1.0 (default 20 Pa = 120 dB SPL, as ``mjsound.synth.output``): the
        observation's unit. Ordinary contact sounds lie well inside it; a metal limb striking
        the floor at several m/s (random actions on dmc humanoid, Walker2d) makes 50-400 Pa.
    clip : bool
        False (default): the observation keeps every level, bounded only at one atmosphere
        (``mjsound.audio_window.ATMOSPHERE_PA`` / ``full_scale_pa``, 5066 at 20 Pa, beyond which
        nothing is sound: such samples are clipped, counted and warned about once). True: clip
        at full scale, [-1, 1], as a microphone that saturates; ``info["audio_clipped"]``
        counts the new samples (all channels) clipped either way.
    n_fft, hop : int
        STFT parameters of the spectrogram mode (default 256 and 128: 16 ms / 8 ms at 16 kHz).
    follow : "auto" | str | None
        Body the default listener moves with (translation only): ``"auto"`` = body 1 when the
        model has no microphone sites and body 1 is not welded to the world (the torso of
        Ant, Humanoid, HalfCheetah), so a walking robot does not walk away from its ears.
        Only used when ``mics`` is None and the model has no ``mic*`` sites.
    quality : str
        Modal analysis quality (default ``"draft"``: cheap, within a few per cent). The
        wrapper analyses each distinct object once per process, without ``analyze``'s error
        estimate, and the results are also disk-cached by ``analyze``.
    budget_modes : int, optional
        Total modes of the scene (shared by importance), for speed.
    models : dict, optional
        Precomputed ``{object_name: ModalModel}`` (skips their analysis).
    progress : bool
        Progress bar (stderr) over the modal analyses, shown once they take over a second
        (default True).
    sim_kwargs : dict, optional
        Extra keyword arguments for :class:`mjsound.sim.AudioSimulator` (``sustained``,
        ``synth_kwargs``, ``reader_kwargs``...). ``keep_events`` defaults to 0 here: an
        environment keeps no event log (``env.sim.event_log``), which lets a whole
        ``frame_skip`` run in one numba call (:mod:`mjsound.sim.fused`); give e.g.
        ``keep_events=100_000`` to keep one.
    objects : {"body", "geom"}
        Sounding objects are bodies (default: a body's collision geoms ring as one) or geoms.
    sound_meshes : dict, optional
        ``{body: geom or mesh}``: the surface a body's sound is computed from (e.g. its
        visual mesh); see :class:`mjsound.sim.SoundScene`.
    masses : {"mujoco", "material"}, optional
        The sound's objects weigh what MuJoCo says (``"mujoco"``, the default: a lighter
        object becomes a hollow wall, a heavier one denser and stiffer) or what their material
        and volume give (``"material"``); see :class:`mjsound.sim.SoundScene`.
    substeps : {"auto", "manual"}
        ``"auto"``: hook the env's stepping (above) or refuse the env; ``"manual"``: no hook,
        call ``env.sim.step(render=False)`` after every ``mj_step``.
    play : bool | str | int, optional
        Also play the audio live (True: the default output device; a name or number: that
        device; docs/live.md): each step waits until its sound is due, so the env runs in
        real time (the inner env's ``render_mode="human"`` shows the picture).

    Observation
    -----------
    ``Dict``: the wrapped observation under ``"observation"`` (or its own keys if it already
    was a Dict) plus ``"audio"``, whose channels are the air microphones, then the contact
    microphones (``env.sim.channel_names``).

    Info
    ----
    ``audio_clipped`` (int, samples x channels of this step clipped, NaN included; ``clip``),
    ``audio_peak_pa`` (float, largest |pressure| of this step [Pa]; a contact channel counts as
    its acceleration times ``full_scale_pa / contact_full_scale``), ``audio_samples`` (int,
    new samples per channel this step), ``audio_impacts`` (int, impacts this step that
    are heard: on a sounding object, a moving body that clicks, or a body with a contact
    microphone; :func:`audible_geoms`).

    Seeding
    -------
    ``reset(seed=s)`` seeds the wrapper's own generator, from which every reset draws the seed
    of the sliding / rolling noise; the same seed and actions give bit-identical audio. The
    audio state is silenced at every reset.
    """

    def __init__(
        self,
        env: gym.Env,
        sample_rate: int = 16000,
        window_s: float | None = None,
        mode: str = "waveform",
        mics=None,
        materials: dict | None = None,
        default_material="aluminium",
        full_scale_pa: float = 20.0,
        contact_mics=None,
        contact_full_scale: float = DEFAULT_CONTACT_FULL_SCALE,
        clicks: bool = True,
        reflections=True,
        room=None,
        n_fft: int = 256,
        hop: int | None = None,
        follow="auto",
        quality: str = "draft",
        budget_modes: int | None = None,
        models: dict | None = None,
        progress: bool = True,
        sim_kwargs: dict | None = None,
        objects: str = "body",
        sound_meshes: dict | None = None,
        substeps: str = "auto",
        play=None,
        masses: str | None = None,
        clip: bool = False,
    ):
        gym.utils.RecordConstructorArgs.__init__(
            self, sample_rate=sample_rate, window_s=window_s, mode=mode, mics=mics, materials=materials,
            default_material=default_material, full_scale_pa=full_scale_pa, n_fft=n_fft, hop=hop,
            follow=follow, quality=quality, budget_modes=budget_modes, objects=objects, substeps=substeps,
            contact_mics=contact_mics, contact_full_scale=contact_full_scale, clicks=clicks, play=play,
            reflections=reflections, room=room, masses=masses, clip=clip,
        )
        gym.Wrapper.__init__(self, env)
        uw = env.unwrapped
        if substeps not in ("auto", "manual"):
            raise ValueError(f"substeps={substeps!r}: choose 'auto' (hook the env's stepping) or 'manual'")
        route = find_stepping(uw)
        if route is not None:
            self._current = route.current
        elif _has_mujoco(uw):
            self._current = lambda: (uw.model, uw.data)
        else:
            raise TypeError(
                f"AudioObservation needs a MuJoCo env: {type(uw).__name__} (env.unwrapped) has no MjModel / MjData "
                "(.model, .data), no dm_control environment or Physics, no robosuite MjSim (.sim), itself or in one "
                "of its attributes. A dm_control environment: mjsound.dmc.AudioEnvironment; any other binding: "
                "AudioSimulator(model, data), sim.step(render=False) after each mj_step, sim.flush() per env step "
                "(docs/envs.md)")
        if substeps == "auto" and route is None:
            raise TypeError(
                f"AudioObservation cannot find how {type(uw).__name__} steps MuJoCo (gymnasium's "
                "MujocoEnv._step_mujoco_simulation, gymnasium-robotics' MujocoRobotEnv._mujoco_step, a dm_control "
                "physics.step or a robosuite MjSim, on the env or on an object it holds), so it cannot hear its "
                "substeps. Pass substeps='manual' and call env.sim.step(render=False) after every mj_step of the "
                "env, or step the physics through env.sim.advance(n, render=False).")
        model, data = self._current()
        dt, dt_source = steps_of(uw, route)
        self.core = EnvAudio(model, data, dt, sample_rate=sample_rate, window_s=window_s, mode=mode, mics=mics,
                             materials=materials, default_material=default_material, full_scale_pa=full_scale_pa,
                             n_fft=n_fft, hop=hop, follow=follow, quality=quality, budget_modes=budget_modes,
                             models=models, progress=progress, sim_kwargs=sim_kwargs, objects=objects,
                             sound_meshes=sound_meshes, contact_mics=contact_mics,
                             contact_full_scale=contact_full_scale, clicks=clicks, dt_source=dt_source,
                             play=play, reflections=reflections, room=room, masses=masses, clip=clip)
        self.audio = self.core.audio
        self.sample_rate, self.window, self.n_channels = self.core.sample_rate, self.core.window, self.core.n_channels
        self.mode, self.full_scale_pa = mode, self.core.audio.full_scale_pa

        audio_space = self.audio.space
        inner = env.observation_space
        if isinstance(inner, gym.spaces.Dict):
            if "audio" in inner.spaces:
                raise ValueError("the wrapped observation already has an 'audio' key")
            self._dict_obs = True
            self.observation_space = gym.spaces.Dict({**inner.spaces, "audio": audio_space})
        else:
            self._dict_obs = False
            self.observation_space = gym.spaces.Dict({"observation": inner, "audio": audio_space})

        # the hooks (none with substeps="manual": the caller calls sim.step(render=False))
        self._route = route if substeps == "auto" else None
        if self._route is not None:
            self._route.install(self.core.sim)

    @property
    def sim(self):
        """The :class:`mjsound.sim.AudioSimulator` of the physics the env steps now (a new one
        after an env rebuilt its model at a reset)."""
        return self.core.sim

    @property
    def scene(self):
        """The :class:`mjsound.sim.SoundScene` of the physics the env steps now."""
        return self.core.scene

    # ------------------------------------------------------------------ substeps
    def _follow_physics(self) -> None:
        """After the env's reset: follow a physics it rebuilt (composer, robosuite's hard reset)."""
        model, data = self._current()
        if not self.core.follows(model, data):
            self.core.rebind(model, data)
            if self._route is not None:
                self._route.install(self.core.sim)

    def on_substep(self) -> None:
        """Deprecated: ``env.sim.step(render=False)`` after each ``mj_step`` (the wrapper
        flushes once per env step)."""
        warnings.warn("AudioObservation.on_substep() is deprecated: call env.sim.step(render=False) after each "
                      "mj_step", DeprecationWarning, stacklevel=2)
        self.sim.step(render=False)

    # ------------------------------------------------------------------ gym API
    def _observe(self, obs, audio):
        if self._dict_obs:
            out = dict(obs)
            out["audio"] = audio
            return out
        return {"observation": obs, "audio": audio}

    def reset(self, *, seed=None, options=None):
        obs, info = self.env.reset(seed=seed, options=options)
        self._follow_physics()
        info = {**info, **self.core.reset(seed)}
        return self._observe(obs, self.audio.observe()), info

    def step(self, action):
        if self._closed:
            raise RuntimeError("AudioObservation.step() after close(): make a new environment")
        obs, reward, terminated, truncated, info = self.env.step(action)
        audio, extra = self.core.end_step()
        info.update(extra)  # (the env's own dict, made for this step: gymnasium's wrappers add to it so too)
        return self._observe(obs, audio), reward, terminated, truncated, info

    _closed = False

    def close(self):
        self._closed = True
        self.core.close()
        if self._route is not None:
            self._route.remove()  # (back to the class methods)
        return super().close()


def _has_mujoco(uw) -> bool:
    import mujoco

    return isinstance(getattr(uw, "model", None), mujoco.MjModel) and isinstance(getattr(uw, "data", None), mujoco.MjData)
