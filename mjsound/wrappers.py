"""Gymnasium wrapper: contact sound as an observation (:class:`AudioObservation`).

Any gymnasium environment built on MuJoCo (``env.unwrapped.model`` / ``env.unwrapped.data``)
gets an ``"audio"`` entry in its observation: the sound the simulation made, computed from the
contacts of *every* physics substep inside the env's ``frame_skip`` (the wrapper replaces
``MujocoEnv._step_mujoco_simulation`` on the unwrapped instance with
:meth:`mjsound.sim.AudioSimulator.substeps`: ``frame_skip`` single ``mj_step`` calls, each
followed by reading its contacts, run in one numba call (:mod:`mjsound.sim.fused`), then
``mj_rnePostConstraint`` as gymnasium does).

Works unmodified on gymnasium's own Ant-v5, Humanoid-v5, HalfCheetah-v5, Pusher-v5, ...: geoms
with no acoustic material get ``default_material`` (aluminium unless told otherwise), so the
robot's links ring like machined aluminium parts.

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
import hashlib
import math
import warnings

import gymnasium as gym
import numpy as np
from numba import njit

__all__ = ["AudioObservation", "AudioWindow", "build_scene", "resolve_materials", "stft_log1p"]

_SILENT_WORDS = {"none", "silent", "off", ""}

#: Process-wide memo of modal models by model geometry + materials + rate + quality, so
#: that several copies of one env (SyncVectorEnv, repeated gym.make) analyse once.
_SCENE_MEMO: dict = {}


# ---------------------------------------------------------------------- materials
def resolve_materials(model, materials=None, default_material=None) -> dict:
    """The ``materials`` mapping for :meth:`SoundScene.from_model`, with a default.

    Every geom that would otherwise have no acoustic material (no entry in ``materials`` for
    its name or its body's name, no ``mjsound:GEOM`` custom text, no MJCF material named like
    an acoustic one) gets ``default_material``. Named geoms are mapped by geom name; unnamed
    ones by their body's name (and then the body's named geoms are pinned to what they would
    have had, so the body entry changes nothing else).

    Parameters
    ----------
    model : mujoco.MjModel
    materials : dict, optional
        ``{geom_or_body_name: material}``; the key ``"*"`` is the same as ``default_material``.
    default_material : str | Material | None
        Material for geoms without one (``None``: they stay silent, SoundScene's rule).

    Returns
    -------
    dict
    """
    import mujoco

    mapping = dict(materials or {})
    star = mapping.pop("*", None)
    if star is not None:
        default_material = star
    if default_material is None:
        return mapping
    resolved = geom_materials(model, mapping)
    out = dict(mapping)
    name = lambda t, i: mujoco.mj_id2name(model, t, int(i)) or ""  # noqa: E731
    for g in range(model.ngeom):
        if resolved[g] is not None:
            continue
        raw = name(mujoco.mjtObj.mjOBJ_GEOM, g)
        if raw:
            out[raw] = default_material
            continue
        body = int(model.geom_bodyid[g])
        bname = name(mujoco.mjtObj.mjOBJ_BODY, body)
        if not bname:
            continue  # unnamed geom on an unnamed body: cannot be addressed, stays silent
        out.setdefault(bname, default_material)
        # pin the body's named geoms to their own material (the body entry must not change them)
        for h in np.flatnonzero(np.asarray(model.geom_bodyid) == body):
            hn = name(mujoco.mjtObj.mjOBJ_GEOM, h)
            if hn and hn not in out:
                out[hn] = resolved[h] if resolved[h] is not None else default_material
    return out


def geom_materials(model, mapping) -> list:
    """Each geom's material as SoundScene would resolve it from ``mapping`` (raw value: a name,
    a Material, ...; ``None`` when it has none)."""
    import mujoco

    from .materials import get_material
    from .sim.scene import _custom_materials

    custom = _custom_materials(model)
    name = lambda t, i: mujoco.mj_id2name(model, t, int(i)) or ""  # noqa: E731

    def own(g):
        """Material the geom has without a default (or None)."""
        raw = name(mujoco.mjtObj.mjOBJ_GEOM, g)
        body = name(mujoco.mjtObj.mjOBJ_BODY, model.geom_bodyid[g])
        for key in (raw, body):
            if key and key in mapping:
                return mapping[key]
        if raw and raw in custom:
            return custom[raw]
        if model.geom_matid[g] >= 0:
            try:
                return get_material(name(mujoco.mjtObj.mjOBJ_MATERIAL, model.geom_matid[g]))
            except KeyError:
                pass
        return None

    return [own(g) for g in range(model.ngeom)]


def _model_key(model, mapping, sample_rate, quality, method, budget_modes) -> str:
    h = hashlib.sha1()
    for arr in (model.geom_type, model.geom_size, model.geom_dataid, model.geom_contype,
                model.geom_conaffinity, model.geom_bodyid, model.body_weldid):
        h.update(np.ascontiguousarray(arr).tobytes())
    if model.nmesh:
        h.update(np.ascontiguousarray(model.mesh_vert).tobytes())
        h.update(np.ascontiguousarray(model.mesh_face).tobytes())
    h.update(repr(sorted((str(k), repr(v)) for k, v in mapping.items())).encode())
    h.update(repr((int(sample_rate), quality, method, budget_modes)).encode())
    return h.hexdigest()


def build_scene(model, mapping, sample_rate, quality="draft", method="hex", microphones=None,
                budget_modes=None, progress=False, models=None):
    """:meth:`SoundScene.from_model` with the process-wide model memo (see ``_SCENE_MEMO``)."""
    from .sim.scene import SoundScene

    key = _model_key(model, mapping, sample_rate, quality, method, budget_modes)
    memo = _SCENE_MEMO.get(key)
    mats = dict(mapping)
    given = dict(models or {})
    if memo is not None:
        given = {**memo["models"], **given}
        for gname in memo["silent"]:
            mats[gname] = "silent"  # analysed before: no audible modes; do not analyse again
    else:
        given = {**_analyse_geoms(model, mapping, sample_rate, quality, method, skip=set(given), progress=progress),
                 **given}
    scene = SoundScene.from_model(model, materials=mats, microphones=microphones, budget_modes=budget_modes,
                                  sample_rate=sample_rate, quality=quality, progress=progress,
                                  method=method, models=given)
    if memo is None:
        import mujoco

        silent = []
        for gname, why in scene.silent.items():
            if ("no audible modes" in why or "analysis failed" in why) and \
                    mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, gname) >= 0:
                silent.append(gname)  # named geoms only (a mapping can only address those)
        _SCENE_MEMO[key] = {"models": {s.name: s.model for s in scene.sounding}, "silent": silent}
    return scene


#: Process-wide memo of modal models by (mesh label, material, rate, quality, method).
_MODEL_MEMO: dict = {}


def _analyse_geoms(model, mapping, sample_rate, quality, method, skip=(), progress=False) -> dict:
    """Modal models of the geoms SoundScene would analyse, without ``analyze``'s error estimate
    (a second, coarser solve that only reports accuracy: about 2/3 of the time of a small
    primitive), identical shapes and materials analysed once. Geoms whose analysis fails are
    left to SoundScene (which retries, then warns and keeps them silent)."""
    import mujoco

    from .materials import Material, parse_material
    from .modal.analyze import analyze
    from .sim.scene import _sphere_inaudible, geom_mesh_spec, geom_name

    T = mujoco.mjtGeom
    pair = set(np.asarray(model.pair_geom1).tolist()) | set(np.asarray(model.pair_geom2).tolist())
    mats = geom_materials(model, mapping)
    todo = []
    for g in range(model.ngeom):
        gname = geom_name(model, g)
        raw = mats[g]
        if gname in skip or raw is None:
            continue
        if isinstance(raw, str) and raw.strip().lower() in _SILENT_WORDS:
            continue
        if not (model.geom_contype[g] or model.geom_conaffinity[g] or g in pair):
            continue
        if int(model.geom_type[g]) in (T.mjGEOM_PLANE, T.mjGEOM_HFIELD, getattr(T, "mjGEOM_SDF", -99)):
            continue
        try:
            mat = raw if isinstance(raw, Material) else parse_material(raw)
        except (KeyError, ValueError):
            continue  # SoundScene reports it
        if _sphere_inaudible(model, g, mat, sample_rate):
            continue
        todo.append((g, gname, mat))
    it = todo
    if progress and todo:
        try:
            from tqdm.auto import tqdm

            it = tqdm(todo, desc="mjsound: modal analysis", unit="geom")
        except ImportError:  # pragma: no cover
            pass
    out = {}
    for g, gname, mat in it:
        spec, label = geom_mesh_spec(model, g)
        if isinstance(spec, tuple):
            label = label + ":" + hashlib.sha1(np.ascontiguousarray(spec[0]).tobytes()).hexdigest()
        k = (label, repr(mat), int(sample_rate), quality, method)
        mm = _MODEL_MEMO.get(k)
        if mm is None:
            try:
                mm = analyze(spec, mat, method=method, quality=quality, sample_rate=sample_rate,
                             error_estimate=False, progress=False)
            except (ValueError, RuntimeError, MemoryError):
                continue
            _MODEL_MEMO[k] = mm
        out[gname] = mm  # zero modes included: SoundScene then marks it silent without re-analysing
    return out


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
        clipped, peak = _push_kernel(self.buf, np.ascontiguousarray(block, dtype=np.float32), 1.0 / self.full_scale_pa)
        return int(clipped), float(peak) * self.full_scale_pa


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


# ---------------------------------------------------------------------- wrapper
class AudioObservation(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """Add the contact sound of the last env step to the observation.

    Parameters
    ----------
    env : gymnasium.Env
        A MuJoCo env: ``env.unwrapped`` has ``model`` and ``data`` and steps through
        ``_step_mujoco_simulation(ctrl, n_frames)`` (every ``gymnasium.envs.mujoco.MujocoEnv``
        does). For another stepping scheme call :meth:`on_substep` after every ``mj_step``
        yourself.
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
    materials : dict, optional
        ``{geom_or_body_name: material}`` (``"*"``: default for all others); see
        :class:`mjsound.sim.SoundScene`.
    default_material : str | Material | None
        Material of geoms that have none (default ``"aluminium"``; ``None`` keeps them
        silent). Soft materials such as ``"rubber"`` make the modal analysis very expensive
        (slow waves need fine meshes) and are overdamped above a few kHz: prefer stiff ones.
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
        wrapper analyses each distinct (shape, material) once per process, without
        ``analyze``'s error estimate, and the results are also disk-cached by ``analyze``.
    budget_modes : int, optional
        Total modes of the scene (shared by importance), for speed.
    models : dict, optional
        Precomputed ``{geom_name: ModalModel}`` (skips their analysis).
    progress : bool
        Progress bar over the modal analyses.
    sim_kwargs : dict, optional
        Extra keyword arguments for :class:`mjsound.sim.AudioSimulator` (``sustained``,
        ``synth_kwargs``, ``reader_kwargs``...). ``keep_events`` defaults to 0 here: an
        environment keeps no event log (``env.sim.event_log``), which lets a whole
        ``frame_skip`` run in one numba call (:mod:`mjsound.sim.fused`); give e.g.
        ``keep_events=100_000`` to keep one.

    Observation
    -----------
    ``Dict``: the wrapped observation under ``"observation"`` (or its own keys if it already
    was a Dict) plus ``"audio"``.

    Info
    ----
    ``audio_clipped`` (int, samples x channels of this step beyond full scale, NaN included),
    ``audio_peak_pa`` (float, largest |pressure| of this step [Pa]), ``audio_samples`` (int,
    new samples per channel this step), ``audio_impacts`` (int, impacts this step).

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
        n_fft: int = 256,
        hop: int | None = None,
        follow="auto",
        quality: str = "draft",
        budget_modes: int | None = None,
        models: dict | None = None,
        progress: bool = False,
        sim_kwargs: dict | None = None,
    ):
        gym.utils.RecordConstructorArgs.__init__(
            self, sample_rate=sample_rate, window_s=window_s, mode=mode, mics=mics, materials=materials,
            default_material=default_material, full_scale_pa=full_scale_pa, n_fft=n_fft, hop=hop,
            follow=follow, quality=quality, budget_modes=budget_modes,
        )
        gym.Wrapper.__init__(self, env)
        import mujoco

        from .sim.simulator import AudioSimulator

        self._mj = mujoco
        uw = env.unwrapped
        if not (hasattr(uw, "model") and hasattr(uw, "data")):
            raise TypeError("AudioObservation needs a MuJoCo env: env.unwrapped must have .model and .data")
        if mode not in ("waveform", "spectrogram"):
            raise ValueError(f"mode={mode!r}: choose 'waveform' or 'spectrogram'")
        fsp = float(full_scale_pa)
        if not (math.isfinite(fsp) and fsp > 0):
            raise ValueError(f"full_scale_pa={full_scale_pa!r} must be a positive pressure [Pa]")
        self.sample_rate = int(sample_rate)
        self.mode = mode
        self.full_scale_pa = fsp
        model, data = uw.model, uw.data
        dt = float(getattr(uw, "dt", model.opt.timestep))
        if window_s is None:
            window = int(round(dt * self.sample_rate))
        else:
            window = int(round(float(window_s) * self.sample_rate))
        if window < 2:
            raise ValueError(f"audio window of {window} samples is too short (window_s={window_s}, dt={dt})")
        self.window = window

        mapping = resolve_materials(model, materials, default_material)
        mic_arg = None if mics is None else (list(mics) if len(mics) and isinstance(mics[0], str) else np.asarray(mics, float))
        scene = build_scene(model, mapping, self.sample_rate, quality=quality, microphones=mic_arg,
                            budget_modes=budget_modes, progress=progress, models=models)
        self.scene = scene
        self.sim = AudioSimulator(model, data, scene=scene, sample_rate=self.sample_rate, progress=False,
                                  **{"keep_events": 0, **(sim_kwargs or {})})
        self.n_channels = self.sim.n_channels

        # listener that follows a body (translation only; AudioSimulator.follow)
        if mics is None and not scene.mic_site_ids and follow is not None and self.sim.synth is not None:
            if follow == "auto":
                body = 1 if model.nbody > 1 and model.body_weldid[1] != 0 else None
            else:
                body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, str(follow))
                if body < 0:
                    raise ValueError(f"follow={follow!r}: no such body")
            if body is not None:
                d0 = mujoco.MjData(model)
                mujoco.mj_forward(model, d0)
                self.sim.follow(int(body), np.asarray(scene.mic_positions) - d0.xpos[body])

        self.audio = AudioWindow(self.n_channels, window, fsp, mode, n_fft, hop)
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

        self._rng = None
        self._hooked = False
        if hasattr(uw, "_step_mujoco_simulation"):
            self._install_hook(uw)
        else:
            warnings.warn("env.unwrapped has no _step_mujoco_simulation: call AudioObservation.on_substep() "
                          "after every mj_step, or the audio stays silent", stacklevel=2)

    # ------------------------------------------------------------------ substeps
    def _install_hook(self, uw) -> None:
        mj = self._mj
        model, data = uw.model, uw.data
        substeps = self.sim.substeps  # mj_step + on_substep, n_frames times (one numba call)

        def _step_mujoco_simulation(ctrl, n_frames):
            data.ctrl[:] = ctrl
            substeps(n_frames)
            mj.mj_rnePostConstraint(model, data)

        uw._step_mujoco_simulation = _step_mujoco_simulation
        self._hooked = True

    def on_substep(self) -> None:
        """Read the contacts of the ``mj_step`` just taken and queue its sound (rendered once
        per env step, in :meth:`step`). A following listener is moved to its body whenever an
        event needs the microphone positions (:meth:`AudioSimulator.follow`)."""
        self.sim.step(render=False)

    # ------------------------------------------------------------------ gym API
    def _observe(self, obs):
        audio = self.audio.observe()
        if self._dict_obs:
            out = dict(obs)
            out["audio"] = audio
            return out
        return {"observation": obs, "audio": audio}

    def reset(self, *, seed=None, options=None):
        obs, info = self.env.reset(seed=seed, options=options)
        if seed is not None or self._rng is None:
            self._rng = np.random.default_rng(seed)
        if self.sim.synth is not None:
            self.sim.synth.seed = int(self._rng.integers(2**31 - 1))
        self.sim.reset()  # (moves a following listener to its body)
        self.audio.reset()
        info = dict(info)
        info.update(audio_clipped=0, audio_peak_pa=0.0, audio_samples=0, audio_impacts=0)
        return self._observe(obs), info

    def step(self, action):
        n_imp = self.sim.n_impacts
        obs, reward, terminated, truncated, info = self.env.step(action)
        block = self.sim.flush()
        clipped, peak = self.audio.push(block)
        info = dict(info)
        info.update(audio_clipped=clipped, audio_peak_pa=peak, audio_samples=int(block.shape[1]),
                    audio_impacts=self.sim.n_impacts - n_imp)
        return self._observe(obs), reward, terminated, truncated, info

    def close(self):
        uw = self.env.unwrapped
        if self._hooked and "_step_mujoco_simulation" in vars(uw):
            del uw._step_mujoco_simulation  # back to the class method
            self._hooked = False
        return super().close()
