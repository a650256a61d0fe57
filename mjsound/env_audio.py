"""The audio side of an environment wrapper (:class:`EnvAudio`): the scene built from the env's
model with a default material (:func:`scene_materials`, :func:`build_scene`), the simulator, a
listener that follows the robot, the observation window (:mod:`mjsound.audio_window`) and the
step's info entries. Shared by gymnasium's :class:`mjsound.wrappers.AudioObservation` and
dm_control's :class:`mjsound.dmc.AudioEnvironment`."""

from __future__ import annotations

import math
import warnings

import numpy as np

from .audio_window import ATMOSPHERE_PA, AudioWindow
from .synth.contact_mic import check_contact_full_scale
from .user_frame import user_stacklevel

__all__ = ["EnvAudio", "audible_geoms", "build_scene", "model_signature", "scene_materials"]


def scene_materials(materials=None, default_material=None) -> dict:
    """The ``materials`` mapping for :meth:`SoundScene.from_model` with a default.

    ``default_material`` becomes the ``"*"`` entry (the material of every geom that has none
    otherwise) unless ``materials`` has its own ``"*"``; ``None`` leaves those geoms silent.
    Keys are checked by the scene (an unknown one is an error listing the closest names).
    """
    mapping = dict(materials or {})
    if default_material is not None:
        mapping.setdefault("*", default_material)
    return mapping


def build_scene(model, mapping, sample_rate, quality="draft", method="auto", microphones=None,
                budget_modes=None, progress=True, models=None, **scene_kw):
    """:meth:`SoundScene.from_model` as the wrappers use it: no error estimate (a second,
    coarser solve that only reports accuracy: about 2/3 of the time of a small model), models
    memoised per process (several copies of one env analyse once) and disk-cached."""
    from .sim.scene import SoundScene

    return SoundScene.from_model(model, materials=mapping, microphones=microphones, budget_modes=budget_modes,
                                 sample_rate=sample_rate, quality=quality, progress=progress, method=method,
                                 models=models, error_estimate=False, **scene_kw)


class EnvAudio:
    """The audio side of an environment wrapper (gymnasium's :class:`AudioObservation` and
    dm_control's :class:`mjsound.dmc.AudioEnvironment`): scene, simulator, listener, window.

    Parameters are those of :class:`AudioObservation` (there documented), plus the physics
    ``model``, ``data`` and the env step ``dt`` [s]. The wrapper steps the physics through
    :attr:`sim` (``sim.advance(n, render=False)`` or ``sim.step(render=False)`` after every ``mj_step``),
    calls :meth:`reset` after the env's reset and :meth:`end_step` after each env step.
    """

    def __init__(self, model, data, dt, sample_rate=16000, window_s=None, mode="waveform", mics=None,
                 materials=None, default_material="aluminium", full_scale_pa=20.0, n_fft=256, hop=None,
                 follow="auto", quality="draft", budget_modes=None, models=None, progress=True, sim_kwargs=None,
                 objects="body", sound_meshes=None, contact_mics=None, contact_full_scale=None, clicks=True,
                 reflections=True, room=None, dt_source="the env's dt", play=None, masses=None, clip=False):
        if mode not in ("waveform", "spectrogram"):
            raise ValueError(f"mode={mode!r}: choose 'waveform' or 'spectrogram'")
        fsp = float(full_scale_pa)
        if not (math.isfinite(fsp) and fsp > 0):
            raise ValueError(f"full_scale_pa={full_scale_pa!r} must be a positive pressure [Pa]")
        fsc = check_contact_full_scale(contact_full_scale)
        from .limits import check_array_bytes, check_duration, check_sample_rate

        self.sample_rate = check_sample_rate(sample_rate)
        if mode == "spectrogram" and (isinstance(n_fft, bool) or not isinstance(n_fft, (int, np.integer)) or n_fft < 2):
            raise ValueError(f"n_fft={n_fft!r} must be an integer >= 2 (samples per STFT frame), e.g. 256")
        if window_s is None and dt is None:
            raise ValueError(
                "mjsound cannot tell how much time one env step simulates (the env has no dt, control_timestep, "
                "control_dt, frame_skip or n_substeps), so it cannot size the audio window: pass window_s= the "
                "simulated seconds of one env step (e.g. frame_skip * model.opt.timestep)")
        window = int(round((dt if window_s is None else check_duration(window_s, "window_s")) * self.sample_rate))
        check_array_bytes(4.0 * window * max(1, len(mics) if mics is not None else 1), f"window_s={window_s}",
                          "give the audio window in seconds (default: one env step)")
        if window < 2:
            raise ValueError(f"audio window of {window} samples is too short (window_s={window_s}, dt={dt})")
        self.window = window
        # the window's duration is checked against the first env step's simulated time unless given
        self._dt_check = None if window_s is not None else (float(dt), dt_source)
        mic_arg = None if mics is None else (list(mics) if len(mics) and isinstance(mics[0], str) else np.asarray(mics, float))
        self._options = dict(
            scene=dict(mapping=scene_materials(materials, default_material), sample_rate=self.sample_rate,
                       quality=quality, microphones=mic_arg, budget_modes=budget_modes, progress=progress,
                       models=models, objects=objects, sound_meshes=sound_meshes, masses=masses),
            sim={"keep_events": 0, "contact_mics": contact_mics, "clicks": clicks, "reflections": reflections,
                 "room": room, **(sim_kwargs or {})},
            follow=follow if mics is None else None)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            self._build(model, data)
        self._said = {str(w.message) for w in caught}  # the scene's warnings, given once per env
        for w in caught:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
        self._signature = model_signature(model)
        self.n_channels = self.sim.n_channels
        # contact channels [m/s^2] enter the window in the air channels' full-scale units
        self._contact_gain = fsp / fsc
        self.audio = AudioWindow(self.n_channels, window, fsp, mode, n_fft, hop, clip=clip)
        self._rng = None
        self._audible_seen = 0
        self._clip_reported = False
        self._t_last = float(data.time)
        self.player = None  # (play: each step's audio also to a device, live: mjsound.live)
        if play is not None and play is not False:
            from .live import LivePlayer, output_channels

            self._heard = output_channels(self.n_channels, self._contact)
            self.player = LivePlayer(self.sample_rate, len(self._heard), device=None if play is True else play).start()

    def _build(self, model, data) -> None:
        """Scene and simulator for ``model`` / ``data`` (the modal models from the process's memo
        and the disk cache when an object's geometry and material were analysed before), a
        listener that follows the robot, and the geoms whose impacts count."""
        import mujoco

        from .sim.simulator import AudioSimulator

        opt = self._options
        sc = opt["scene"]
        self.scene = build_scene(model, sc["mapping"], sc["sample_rate"], quality=sc["quality"],
                                 microphones=sc["microphones"], budget_modes=sc["budget_modes"],
                                 progress=sc["progress"], models=sc["models"], objects=sc["objects"],
                                 sound_meshes=sc["sound_meshes"], masses=sc["masses"])
        self.sim = AudioSimulator(model, data, scene=self.scene, sample_rate=self.sample_rate, progress=False,
                                  **opt["sim"])
        self._contact = self.sim.contact_channels
        # listener that follows a body (translation only; AudioSimulator.follow)
        follow = opt["follow"]
        if not self.scene.mic_site_ids and follow is not None and self.sim.synth is not None:
            if follow == "auto":
                body = 1 if model.nbody > 1 and model.body_weldid[1] != 0 else None
            else:
                body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, str(follow))
                if body < 0:
                    raise ValueError(f"follow={follow!r}: no such body")
            if body is not None:
                d0 = mujoco.MjData(model)
                mujoco.mj_forward(model, d0)
                self.sim.follow(int(body), np.asarray(self.scene.mic_positions) - d0.xpos[body])
        # (the step kernel counts the impacts on these geoms: info["audio_impacts"])
        self.sim.reader.set_audible(audible_geoms(model, self.scene, self.sim))

    def follows(self, model, data) -> bool:
        """Whether the simulator steps with this ``model`` and ``data``."""
        return self.sim.model is model and self.sim.data is data

    def rebind(self, model, data) -> None:
        """Follow an env that built a new ``MjModel`` / ``MjData`` (composer's new ``Physics``
        at a reset, robosuite's hard reset); nothing of the old physics is kept.

        A model that sounds the same as the last one (:func:`model_signature`: geometry,
        masses, names, materials, sites) keeps the scene and synthesizer
        (:meth:`AudioSimulator.rebind`); another gets a scene and simulator of its own with the
        same options (modal models from the process's memo and the disk cache for objects
        analysed before). The observer ``sim.on_block`` carries over; the caller resets after.

        Raises
        ------
        RuntimeError
            The new model gives another number of channels (microphone sites) than the
            observation space was made for.
        """
        signature = model_signature(model)
        if signature == self._signature:
            self.sim.rebind(model, data)
            self.scene.model = model  # (the same geometry: the scene now reports from the live model)
        else:
            on_block = getattr(self.sim, "on_block", None)
            old_channels = self.sim.channel_names
            with warnings.catch_warnings(record=True) as caught:  # (said once: not again at every reset)
                warnings.simplefilter("always")
                self._build(model, data)
            for w in caught:
                if str(w.message) not in self._said:
                    self._said.add(str(w.message))
                    warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
            if self.sim.n_channels != self.n_channels:
                raise RuntimeError(
                    f"mjsound: the env rebuilt its model with {self.sim.n_channels} audio channel(s) "
                    f"({self.sim.channel_names}) where the observation has {self.n_channels} ({old_channels}): "
                    "give mics= (fixed positions) so that every model is heard by the same microphones")
            self.sim.on_block = on_block
            self._signature = signature
        self._t_last = float(data.time)

    def reset(self, seed=None) -> dict:
        """After the env's reset: silence, re-anchor the clock at ``data.time``, draw the noise
        seed from the wrapper's generator (seeded by ``seed`` when given). Returns the info
        entries."""
        if seed is not None or self._rng is None:
            self._rng = np.random.default_rng(seed)
        if self.sim.synth is not None:
            self.sim.synth.seed = int(self._rng.integers(2**31 - 1))
        self.sim.reset()  # (moves a following listener to its body)
        self.audio.reset()
        self._audible_seen = self.sim.reader.n_audible
        self._t_last = float(self.sim.data.time)
        return dict(audio_clipped=0, audio_peak_pa=0.0, audio_samples=0, audio_impacts=0)

    @property
    def _audible(self) -> np.ndarray:
        """(ngeom,) bool: the geoms whose impacts are heard (the reader's flags, set from
        :func:`audible_geoms`)."""
        return self.sim.reader.geoms["audible"].astype(bool)

    def _audible_impacts(self) -> int:
        """Impacts since the last call that make a sound (:func:`audible_geoms`, counted by
        the step kernel: ``ContactReader.set_audible``)."""
        n = self.sim.reader.n_audible
        new = n - self._audible_seen if n >= self._audible_seen else n  # (the reader was reset: a clock jump)
        self._audible_seen = n
        return new

    def _report_clipping(self, clipped: int, peak: float) -> None:
        """Warn, once per env, that the observation clipped (``info["audio_clipped"]`` keeps
        counting): at full scale with ``clip=True`` (the agent hears a distorted sound), else at
        one atmosphere, which no sound reaches (the simulation has gone wrong)."""
        self._clip_reported = True
        fsp = self.audio.full_scale_pa
        tail = ("The step's info counts every step's (audio_clipped; dm_control: last_info); reported once "
                "per env")
        if not self.audio.clip:
            warnings.warn(f"mjsound: the audio observation clipped {clipped} sample(s) this step at one atmosphere "
                          f"({ATMOSPHERE_PA:g} Pa), peak {peak:.3g} Pa (NaN counts as clipped): no sound is that "
                          "loud, so the simulation has most likely gone unstable (MuJoCo's warnings, "
                          "data.warning, say where; a smaller timestep or stiffer solver settings help). " + tail,
                          RuntimeWarning, stacklevel=user_stacklevel())
            return
        knobs = f"full_scale_pa (now {fsp:g} Pa)"
        if len(self._contact):
            knobs += f" or, for the contact channels, contact_full_scale (now {fsp / self._contact_gain:g} m/s^2)"
        warnings.warn(f"mjsound: the audio observation clipped: {clipped} sample(s) beyond full scale this step, "
                      f"peak {peak:.3g} Pa (NaN counts as clipped); a larger {knobs}, or clip=False, keeps such "
                      "steps undistorted. " + tail, RuntimeWarning, stacklevel=user_stacklevel())

    def _check_step_time(self) -> None:
        """The first env step: the window (one env step by default) must last what the step
        simulated (``data.time`` advance), else the observation would hold a part of each
        step's sound (or several steps'), silently."""
        dt, source = self._dt_check
        self._dt_check = None
        now = float(self.sim.data.time)
        elapsed, self._t_last = now - self._t_last, now
        timestep = float(self.sim.model.opt.timestep)
        if abs(elapsed - dt) > 0.5 * timestep and elapsed > 0:
            raise RuntimeError(
                f"mjsound: one env step simulated {elapsed:.6g} s ({elapsed / timestep:.3g} physics steps of "
                f"{timestep:g} s) but the audio window lasts {dt:.6g} s ({self.window} samples, from {source}): "
                f"each observation would hold {dt / elapsed:.3g} env step(s) of sound. "
                f"Make the wrapper again with window_s={elapsed:.6g}")

    def end_step(self) -> tuple[np.ndarray, dict]:
        """After an env step: render its audio; returns ``(audio observation, info entries)``."""
        if self._dt_check is not None:
            self._check_step_time()
        block = self.sim.flush()
        if len(self._contact):
            block[self._contact] *= self._contact_gain
        audio = self.audio
        clipped, peak = audio.push(block)
        if self.player is not None:  # (waits until the step is due: the env runs in real time)
            self.player.push(block[self._heard] * np.float64(1.0 / audio.full_scale_pa))  # (as the window rounds)
        if clipped and not self._clip_reported:
            self._report_clipping(clipped, peak)
        info = {"audio_clipped": clipped, "audio_peak_pa": peak, "audio_samples": block.shape[1],
                "audio_impacts": self._audible_impacts()}
        return audio.observe(), info

    def close(self) -> None:
        """Play what is queued and close the live player (``play``), if any."""
        if self.player is not None:
            self.player, player = None, self.player
            player.close()


#: the model fields a scene and simulator are made from (with the names and custom text, where
#: materials and microphones are named): equal fields, equal sound
_SOUND_FIELDS = ("geom_type", "geom_size", "geom_pos", "geom_quat", "geom_bodyid", "geom_dataid", "geom_contype",
                 "geom_conaffinity", "geom_matid", "geom_rbound", "body_parentid", "body_weldid", "body_mass",
                 "body_inertia", "body_mocapid", "body_dofnum", "mesh_vertadr", "mesh_vertnum", "mesh_vert",
                 "mesh_faceadr", "mesh_facenum", "mesh_face", "site_bodyid", "site_pos", "site_quat", "names",
                 "text_data")


def model_signature(model) -> bytes:
    """A digest of what a model's sound is made from (``_SOUND_FIELDS`` and the timestep): two
    models with the same digest get the same scene, so a simulator can move from one to the
    other (:meth:`EnvAudio.rebind`)."""
    import hashlib

    h = hashlib.blake2b(digest_size=16)
    for name in _SOUND_FIELDS:
        value = getattr(model, name, None)
        if value is not None:
            h.update(name.encode())
            h.update(np.ascontiguousarray(value).tobytes())
    h.update(np.float64(model.opt.timestep).tobytes())
    return h.digest()


def audible_geoms(model, scene, sim) -> np.ndarray:
    """(ngeom,) bool: whether an impact on the geom is heard: it belongs to a sounding object
    (modes), or its body clicks (clicks on, the body moves: not welded to the world, not mocap,
    with mass; :mod:`mjsound.sim.clicks`), or its body carries a contact microphone."""
    audible = np.zeros(model.ngeom, bool)
    for s in scene.sounding:
        audible[list(s.geom_ids)] = True
    audible |= sim.pulses.audible_bodies()[np.asarray(model.geom_bodyid)]
    return audible
