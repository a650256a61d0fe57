"""Gymnasium wrapper: contact sound as an observation (:class:`AudioObservation`).

Any gymnasium environment built on MuJoCo (``env.unwrapped.model`` / ``env.unwrapped.data``)
gets an ``"audio"`` entry in its observation: the sound the simulation made, computed from the
contacts of *every* physics substep of an env step. The wrapper replaces the env's stepping
method on the unwrapped instance with :meth:`mjsound.sim.AudioSimulator.substeps` (single
``mj_step`` calls, each followed by reading its contacts, run in one numba call,
:mod:`mjsound.sim.fused`): gymnasium's ``MujocoEnv._step_mujoco_simulation`` (``frame_skip``
substeps, then ``mj_rnePostConstraint`` as gymnasium does) and gymnasium-robotics'
``MujocoRobotEnv._mujoco_step`` (``n_substeps``). An env whose stepping it cannot find is
refused at construction (``substeps="manual"`` lets you call :meth:`AudioObservation.on_substep`
yourself). :class:`EnvAudio` is the part shared with the dm_control wrapper
(:mod:`mjsound.dmc`).

Works unmodified on gymnasium's own Ant-v5, Humanoid-v5, HalfCheetah-v5, Pusher-v5, ... and on
gymnasium-robotics' Fetch and Shadow-hand envs: geoms with no acoustic material get
``default_material`` (aluminium unless told otherwise), so the robot's links ring like machined
aluminium parts.

Example
-------
>>> import gymnasium as gym                                           # doctest: +SKIP
>>> from mjsound.wrappers import AudioObservation                      # doctest: +SKIP
>>> env = AudioObservation(gym.make("Ant-v5"), sample_rate=16000)      # doctest: +SKIP
>>> obs, info = env.reset(seed=0)                                      # doctest: +SKIP
>>> obs["audio"].shape     # (channels, round(env.unwrapped.dt * 16000)) = (1, 800)  # doctest: +SKIP
"""

from __future__ import annotations

import functools
import math
import warnings

import gymnasium as gym
import numpy as np

from .jit import njit
from .synth.dispatch import EntryPoint
from .synth.contact_mic import DEFAULT_CONTACT_FULL_SCALE, check_contact_full_scale

__all__ = ["AudioObservation", "AudioWindow", "EnvAudio", "scene_materials", "stft_log1p"]


# ---------------------------------------------------------------------- materials
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


# ---------------------------------------------------------------------- spectrogram
def _stft_setup(window: int, n_fft: int, hop: int | None):
    n = int(n_fft)
    if window < n:
        n = 1 << int(math.floor(math.log2(max(window, 2))))
    hop = int(hop) if hop else n // 2
    hop = max(1, min(hop, n))
    frames = 1 + (window - n) // hop
    win = np.hanning(n + 1)[:-1].astype(np.float32)  # periodic Hann
    return n, hop, frames, win


@functools.lru_cache(maxsize=16)
def _frame_index(n: int, n_fft: int, hop: int) -> np.ndarray:
    """Sample indices (frames, n_fft) of the STFT frames of an ``n``-sample window."""
    frames = 1 + (n - n_fft) // hop
    return np.arange(n_fft)[None, :] + hop * np.arange(frames)[:, None]


def stft_log1p(x: np.ndarray, n_fft: int, hop: int, win: np.ndarray) -> np.ndarray:
    """``log1p(|STFT|)`` of ``x`` (channels, samples) -> (channels, n_fft // 2 + 1, frames) float32.

    Frames start at sample 0 and step by ``hop`` (no centring, no padding); each is multiplied
    by ``win`` and transformed with ``scipy.fft.rfft`` (no normalisation; float32 in, so
    single precision).
    """
    import scipy.fft

    x = np.ascontiguousarray(x, dtype=np.float32)
    seg = x[:, _frame_index(x.shape[1], int(n_fft), int(hop))] * win  # (C, T, n_fft)
    mag = np.abs(scipy.fft.rfft(seg, axis=-1))  # (C, T, F); single precision stays single
    return np.log1p(mag).transpose(0, 2, 1).astype(np.float32)


class AudioWindow:
    """The newest ``window`` samples of a pressure stream, as an observation.

    Pressure blocks [Pa] are divided by ``full_scale_pa``, clipped to [-1, 1] (clipped and
    non-finite samples counted; NaN becomes 0) and appended; :meth:`observe` gives the window
    (``"waveform"``) or its ``log1p(|STFT|)`` (``"spectrogram"``, see :func:`stft_log1p`).
    """

    def __init__(self, channels: int, window: int, full_scale_pa: float = 20.0, mode: str = "waveform",
                 n_fft: int = 256, hop: int | None = None):
        if mode not in ("waveform", "spectrogram"):
            raise ValueError(f"mode={mode!r}: choose 'waveform' or 'spectrogram'")
        fsp = float(full_scale_pa)
        if not (math.isfinite(fsp) and fsp > 0):
            raise ValueError(f"full_scale_pa={full_scale_pa!r} must be a positive pressure [Pa]")
        if int(window) < 2:
            raise ValueError(f"audio window of {window} samples is too short")
        self.channels, self.window, self.full_scale_pa, self.mode = int(channels), int(window), fsp, mode
        C, W = self.channels, self.window
        if mode == "waveform":
            self.space = gym.spaces.Box(-1.0, 1.0, (C, W), np.float32)
        else:
            self.n_fft, self.hop, frames, self.win = _stft_setup(W, n_fft, hop)
            top = float(np.log1p(self.win.astype(np.float64).sum())) + 1e-3
            self.space = gym.spaces.Box(0.0, top, (C, self.n_fft // 2 + 1, frames), np.float32)
        self.buf = np.zeros((C, W), np.float32)
        self._push = EntryPoint(_push_kernel)  # (its compiled entry point: numba's dispatch types every call)

    def reset(self) -> None:
        self.buf[:] = 0.0

    def observe(self) -> np.ndarray:
        if self.mode == "waveform":
            return self.buf.copy()
        return stft_log1p(self.buf, self.n_fft, self.hop, self.win)

    def push(self, block: np.ndarray) -> tuple[int, float]:
        """Append a (channels, n) pressure block; returns (clipped samples, peak |p| [Pa])."""
        if block.shape[1] == 0:
            return 0, 0.0
        block = np.ascontiguousarray(block, dtype=np.float32)  # (the block itself when it is already)
        fsp = self.full_scale_pa
        clipped, peak = self._push((self.buf,), block, 1.0 / fsp)  # (a Python int and float)
        return clipped, peak * fsp


@njit(cache=True)
def _push_kernel(buf, block, scale):
    """Shift ``buf`` (C, W) left and append ``block * scale`` clipped to [-1, 1] (NaN/Inf: 0 and
    counted as clipped). Returns (clipped samples, peak |x| before clipping, NaN excluded)."""
    C, W = buf.shape
    n = block.shape[1]
    clipped = 0
    peak = 0.0
    keep = W - n if n < W else 0
    for c in range(C):
        for k in range(keep):
            buf[c, k] = buf[c, k + n]
        for k in range(n):
            x = block[c, k] * scale
            if not np.isfinite(x):
                clipped += 1
                x = 0.0
            else:
                a = abs(x)
                if a > peak:
                    peak = a
                if a > 1.0:
                    clipped += 1
                    x = 1.0 if x > 0 else -1.0
            j = k - (n - W) if n > W else keep + k
            if j >= 0:
                buf[c, j] = x
    return clipped, peak


# ---------------------------------------------------------------------- shared core
class EnvAudio:
    """The audio side of an environment wrapper (gymnasium's :class:`AudioObservation` and
    dm_control's :class:`mjsound.dmc.AudioEnvironment`): scene, simulator, listener, window.

    Parameters are those of :class:`AudioObservation` (there documented), plus the physics
    ``model``, ``data`` and the env step ``dt`` [s]. The wrapper steps the physics through
    :attr:`sim` (``sim.substeps(n)`` or ``sim.step(render=False)`` after every ``mj_step``),
    calls :meth:`reset` after the env's reset and :meth:`end_step` after each env step.
    """

    def __init__(self, model, data, dt, sample_rate=16000, window_s=None, mode="waveform", mics=None,
                 materials=None, default_material="aluminium", full_scale_pa=20.0, n_fft=256, hop=None,
                 follow="auto", quality="draft", budget_modes=None, models=None, progress=True, sim_kwargs=None,
                 objects="body", sound_meshes=None, contact_mics=None, contact_full_scale=None, clicks=True):
        import mujoco

        from .sim.simulator import AudioSimulator

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
        window = int(round((dt if window_s is None else check_duration(window_s, "window_s")) * self.sample_rate))
        check_array_bytes(4.0 * window * max(1, len(mics) if mics is not None else 1), f"window_s={window_s}",
                          "give the audio window in seconds (default: one env step)")
        if window < 2:
            raise ValueError(f"audio window of {window} samples is too short (window_s={window_s}, dt={dt})")
        self.window = window
        mic_arg = None if mics is None else (list(mics) if len(mics) and isinstance(mics[0], str) else np.asarray(mics, float))
        self.scene = build_scene(model, scene_materials(materials, default_material), self.sample_rate,
                                 quality=quality, microphones=mic_arg, budget_modes=budget_modes, progress=progress,
                                 models=models, objects=objects, sound_meshes=sound_meshes)
        self.sim = AudioSimulator(model, data, scene=self.scene, sample_rate=self.sample_rate, progress=False,
                                  **{"keep_events": 0, "contact_mics": contact_mics, "clicks": clicks,
                                     **(sim_kwargs or {})})
        self.n_channels = self.sim.n_channels
        # contact channels [m/s^2] enter the window in the air channels' full-scale units
        self._contact = self.sim.contact_channels
        self._contact_gain = fsp / fsc
        # listener that follows a body (translation only; AudioSimulator.follow)
        if mics is None and not self.scene.mic_site_ids and follow is not None and self.sim.synth is not None:
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
        self.audio = AudioWindow(self.n_channels, window, fsp, mode, n_fft, hop)
        # (the step kernel counts the impacts on these geoms: info["audio_impacts"])
        self.sim.reader.set_audible(audible_geoms(model, self.scene, self.sim))
        self._rng = None
        self._audible_seen = 0
        self._clip_reported = False

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
        """Warn, once per env, that the observation clipped (the agent hears a distorted
        sound; ``info["audio_clipped"]`` keeps counting)."""
        self._clip_reported = True
        fsp = self.audio.full_scale_pa
        knobs = f"full_scale_pa (now {fsp:g} Pa)"
        if len(self._contact):
            knobs += f" or, for the contact channels, contact_full_scale (now {fsp / self._contact_gain:g} m/s^2)"
        warnings.warn(f"mjsound: the audio observation clipped: {clipped} sample(s) beyond full scale this step, "
                      f"peak {peak:.3g} Pa (NaN counts as clipped); a larger {knobs} keeps such steps undistorted. "
                      "The step's info counts every step's (audio_clipped; dm_control: last_info); reported once "
                      "per env", RuntimeWarning, stacklevel=4)

    def end_step(self) -> tuple[np.ndarray, dict]:
        """After an env step: render its audio; returns ``(audio observation, info entries)``."""
        block = self.sim.flush()
        if len(self._contact):
            block[self._contact] *= self._contact_gain
        audio = self.audio
        clipped, peak = audio.push(block)
        if clipped and not self._clip_reported:
            self._report_clipping(clipped, peak)
        info = {"audio_clipped": clipped, "audio_peak_pa": peak, "audio_samples": block.shape[1],
                "audio_impacts": self._audible_impacts()}
        return audio.observe(), info


def audible_geoms(model, scene, sim) -> np.ndarray:
    """(ngeom,) bool: whether an impact on the geom is heard: it belongs to a sounding object
    (modes), or its body clicks (clicks on, the body moves: not welded to the world, not mocap,
    with mass; :mod:`mjsound.sim.clicks`), or its body carries a contact microphone."""
    audible = np.zeros(model.ngeom, bool)
    for s in scene.sounding:
        audible[list(s.geom_ids)] = True
    audible |= sim.pulses.audible_bodies()[np.asarray(model.geom_bodyid)]
    return audible


# ---------------------------------------------------------------------- wrapper
class AudioObservation(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """Add the contact sound of the last env step to the observation.

    Parameters
    ----------
    env : gymnasium.Env
        A MuJoCo env: ``env.unwrapped`` has ``model`` and ``data``. Every physics substep is
        heard: the wrapper hooks gymnasium's ``MujocoEnv._step_mujoco_simulation(ctrl,
        n_frames)`` and gymnasium-robotics' ``MujocoRobotEnv._mujoco_step(action)``
        (``n_substeps`` steps). An env that steps another way is refused at construction
        (``TypeError``) unless ``substeps="manual"``: then call :meth:`on_substep` after every
        ``mj_step`` yourself.
    sample_rate : int
        Audio sample rate [Hz] (default 16 kHz, as SoundSpaces; modes above 0.45 fs are not
        computed).
    window_s : float, optional
        Length of the audio window [s]. Default: one env step, i.e.
        ``window = round(env.unwrapped.dt * sample_rate)`` samples (Ant-v5 at 16 kHz: 800,
        Humanoid-v5: 240). The window holds the newest samples, zero-padded after reset
        (a physics step renders ``ceil``-aligned sample ranges, so one env step brings
        ``window`` samples +-1 when ``dt * fs`` is not an integer).
    mode : {"waveform", "spectrogram"}
        ``"waveform"``: ``audio`` is float32 ``(channels, window)`` in full-scale units
        (pressure / ``full_scale_pa``, clipped to [-1, 1]).
        ``"spectrogram"``: ``audio`` is float32 ``(channels, n_fft // 2 + 1, frames)``,
        ``log1p(|STFT|)`` of that waveform (as SoundSpaces / Sonicverse): periodic Hann window
        of ``n_fft`` samples, hop ``hop`` (default ``n_fft // 2``), frames start at sample 0
        with no centring or padding, ``frames = 1 + (window - n_fft) // hop``, unnormalised
        ``scipy.fft.rfft``. If the window is shorter than ``n_fft``, ``n_fft`` becomes the
        largest power of two that fits. Values lie in ``[0, log1p(sum(hann))]``.
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
        Pressure mapped to 1.0 (default 20 Pa = 120 dB SPL, as ``mjsound.synth.output``).
        ``info["audio_clipped"]`` counts the new samples (all channels) beyond it.
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
    substeps : {"auto", "manual"}
        ``"auto"``: hook the env's stepping (above) or refuse the env; ``"manual"``: no hook,
        call :meth:`on_substep` after every ``mj_step``.

    Observation
    -----------
    ``Dict``: the wrapped observation under ``"observation"`` (or its own keys if it already
    was a Dict) plus ``"audio"``, whose channels are the air microphones, then the contact
    microphones (``env.sim.channel_names``).

    Info
    ----
    ``audio_clipped`` (int, samples x channels of this step beyond full scale, NaN included),
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
    ):
        gym.utils.RecordConstructorArgs.__init__(
            self, sample_rate=sample_rate, window_s=window_s, mode=mode, mics=mics, materials=materials,
            default_material=default_material, full_scale_pa=full_scale_pa, n_fft=n_fft, hop=hop,
            follow=follow, quality=quality, budget_modes=budget_modes, objects=objects, substeps=substeps,
            contact_mics=contact_mics, contact_full_scale=contact_full_scale, clicks=clicks,
        )
        gym.Wrapper.__init__(self, env)
        import mujoco

        self._mj = mujoco
        uw = env.unwrapped
        if not (hasattr(uw, "model") and hasattr(uw, "data")):
            raise TypeError("AudioObservation needs a MuJoCo env: env.unwrapped must have .model and .data")
        if substeps not in ("auto", "manual"):
            raise ValueError(f"substeps={substeps!r}: choose 'auto' (hook the env's stepping) or 'manual'")
        stepper, hook = _stepping_target(uw) if substeps == "auto" else (uw, None)
        if substeps == "auto" and hook is None:
            raise TypeError(
                f"AudioObservation cannot find how {type(uw).__name__} steps MuJoCo (neither gymnasium's "
                "MujocoEnv._step_mujoco_simulation nor gymnasium-robotics' MujocoRobotEnv._mujoco_step, on the "
                "env or on an inner env that shares its model), so it cannot hear its substeps. Pass "
                "substeps='manual' and call env.on_substep() after every mj_step of the env, or step the "
                "physics through env.sim.substeps(n)."
            )
        model, data = uw.model, uw.data
        dt = float(getattr(uw, "dt", getattr(stepper, "dt", model.opt.timestep)))
        self.core = EnvAudio(model, data, dt, sample_rate=sample_rate, window_s=window_s, mode=mode, mics=mics,
                             materials=materials, default_material=default_material, full_scale_pa=full_scale_pa,
                             n_fft=n_fft, hop=hop, follow=follow, quality=quality, budget_modes=budget_modes,
                             models=models, progress=progress, sim_kwargs=sim_kwargs, objects=objects,
                             sound_meshes=sound_meshes, contact_mics=contact_mics,
                             contact_full_scale=contact_full_scale, clicks=clicks)
        self.scene, self.sim, self.audio = self.core.scene, self.core.sim, self.core.audio
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

        self._hooked, self._stepper = None, stepper
        if hook is not None:
            self._install_hook(stepper, hook)

    # ------------------------------------------------------------------ substeps
    def _install_hook(self, uw, hook) -> None:
        """Replace the env's stepping method (on the instance) by one that hears every substep."""
        mj = self._mj
        model, data = uw.model, uw.data
        # mj_step + on_substep, n times, and the env step's audio rendered, in one numba call
        # (end_step's flush returns that block)
        step = self.sim.stepper()  # (substeps(n, render=True))
        if hook == "_step_mujoco_simulation":  # gymnasium MujocoEnv
            # (data.ctrl read once: each read of it makes a new view; its memory lives as the MjData)
            ctrl_now, rne_post_constraint = data.ctrl, mj.mj_rnePostConstraint

            def _step_mujoco_simulation(ctrl, n_frames):
                ctrl_now[:] = ctrl
                step(n_frames)
                rne_post_constraint(model, data)

            uw._step_mujoco_simulation = _step_mujoco_simulation
        else:  # gymnasium-robotics MujocoRobotEnv: mj_step(model, data, nstep=n_substeps)
            def _mujoco_step(action):
                step(uw.n_substeps)

            uw._mujoco_step = _mujoco_step
        self._hooked = hook

    def on_substep(self) -> None:
        """Read the contacts of the ``mj_step`` just taken and queue its sound (rendered once
        per env step, in :meth:`step`). A following listener is moved to its body whenever an
        event needs the microphone positions (:meth:`AudioSimulator.follow`)."""
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
        uw = self._stepper
        if self._hooked and self._hooked in vars(uw):
            delattr(uw, self._hooked)  # back to the class method
            self._hooked = None
        return super().close()


def _stepping_target(uw) -> tuple:
    """``(env, hook)``: the env whose stepping method to hook, and that method's name.

    Usually the unwrapped env itself. Some envs step another env that owns the physics
    (gymnasium-robotics' mazes: ``AntMazeEnv.ant_env``, ``PointMazeEnv.point_env``); such an
    inner env, found among the unwrapped env's attributes and sharing its ``model`` and
    ``data``, is hooked instead. ``(uw, None)``: no stepping method found.
    """
    hook = _stepping_hook(uw)
    if hook is not None:
        return uw, hook
    for inner in vars(uw).values():
        if isinstance(inner, gym.Env) and inner is not uw:
            iu = inner.unwrapped
            if getattr(iu, "model", None) is uw.model and getattr(iu, "data", None) is uw.data:
                hook = _stepping_hook(iu)
                if hook is not None:
                    return iu, hook
    return uw, None


def _stepping_hook(uw) -> str | None:
    """Which stepping method of the unwrapped env to hook: gymnasium's ``MujocoEnv`` steps
    through ``_step_mujoco_simulation(ctrl, n_frames)``; gymnasium-robotics' ``MujocoRobotEnv``
    through ``_mujoco_step(action)``, ``mj_step(model, data, nstep=n_substeps)``. None: neither."""
    import mujoco

    if callable(getattr(uw, "_step_mujoco_simulation", None)):
        return "_step_mujoco_simulation"
    if callable(getattr(uw, "_mujoco_step", None)) and isinstance(getattr(uw, "n_substeps", None), (int, np.integer)) \
            and isinstance(uw.model, mujoco.MjModel) and isinstance(uw.data, mujoco.MjData):
        return "_mujoco_step"
    return None
