"""Offline sonification of a scene or a recorded rollout, and the ``sonify`` / ``demo`` commands.

Rollout files
-------------
An ``.npz`` with ``time`` (T,) [s], ``qpos`` (T, nq), ``qvel`` (T, nv) and optionally
``ctrl`` (T, nu), ``act`` (T, na), ``mocap_pos`` (T, nmocap, 3), ``mocap_quat`` (T, nmocap, 4).
Frame ``i`` is the state at ``time[i]``; ``ctrl[i]`` (and the mocap poses) are held over
``[time[i], time[i+1])``.

Two ways to make sound from it
------------------------------
``resim`` (default when ``ctrl`` is present): start from frame 0 and re-run the physics with
the recorded controls at the model's timestep, reading contacts at every ``mj_step``. Exact
(every impact at physics resolution, the same sound as live) when the rollout was produced by
the same model, timestep and MuJoCo version; the summary reports the largest deviation of the
re-simulated ``qpos`` from the recording so a mismatch shows.

``replay`` (default without ``ctrl``, or forced): set each recorded state, ``mj_forward``, and
read the contacts of that state; the audio of ``[time[i], time[i+1])`` follows. Use it when the
recording cannot be reproduced (other simulator or version, a real robot log, missing
controls). Impacts are detected at the first frame with the contact, with the approach speed
from that frame's velocities, so the timing is only as fine as the frame rate, and an impact
that begins and ends between two frames (soft contacts last ~5-20 ms) is missed: record at
>= 100 Hz, or prefer ``resim``.
"""

from __future__ import annotations

import json
import os
import time as _time
import zipfile

import numpy as np

from ..limits import check_array_bytes, check_duration, check_sample_rate, check_steps, check_timestep
from ..user_frame import user_stacklevel

__all__ = ["load_rollout", "sonify", "write_spectrogram_png", "load_materials"]

_KEYS = ("time", "qpos", "qvel", "ctrl", "act", "mocap_pos", "mocap_quat")
#: Simulated seconds written per block when streaming a take to its file.
STREAM_BLOCK_S = 1.0


def _npz_shapes(path) -> dict:
    """``{key: (shape, dtype)}`` of the rollout arrays from the ``.npy`` headers inside the
    ``.npz`` (nothing is decompressed beyond the headers)."""
    shapes = {}
    with zipfile.ZipFile(os.fspath(path)) as zf:
        for info in zf.infolist():
            key = info.filename[:-4] if info.filename.endswith(".npy") else None
            if key not in _KEYS:
                continue
            with zf.open(info) as fh:
                fmt = np.lib.format
                read = fmt.read_array_header_1_0 if fmt.read_magic(fh) == (1, 0) else fmt.read_array_header_2_0
                shape, _, dtype = read(fh)
            shapes[key] = (tuple(int(n) for n in shape), dtype)
    return shapes


def _check_header(path, model) -> None:
    """Shapes and total size of a rollout, checked before anything is loaded."""
    try:
        shapes = _npz_shapes(path)
    except (zipfile.BadZipFile, ValueError, OSError, EOFError) as exc:
        raise ValueError(f"rollout {path}: cannot read ({type(exc).__name__}: {exc}); give a .npz of time, qpos, qvel") from exc
    for k in ("time", "qpos", "qvel"):
        if k not in shapes:
            raise ValueError(f"rollout {path}: missing array {k!r} (needs time, qpos, qvel)")
    tshape = shapes["time"][0]
    if len(tshape) != 1 or tshape[0] < 2:
        raise ValueError(f"rollout {path}: 'time' must be a 1-D array of at least 2 frames, has shape {tshape}")
    T = tshape[0]
    width = {"qpos": "nq", "qvel": "nv", "ctrl": "nu", "act": "na"}
    total = 0
    for k, (shape, dtype) in shapes.items():
        if dtype.kind not in "fiub":
            raise ValueError(f"rollout {path}: {k!r} has dtype {dtype}, not numbers")
        if not shape or shape[0] != T:
            raise ValueError(f"rollout {path}: {k!r} has shape {shape}, 'time' has {T} frames (needs ({T}, ...))")
        if k in width and len(shape) != 2 and not (len(shape) == 1 and k == "time"):
            raise ValueError(f"rollout {path}: {k!r} has shape {shape}; give ({T}, model.{width[k]})")
        if model is not None and k in width and shape[1] != getattr(model, width[k]):
            raise ValueError(f"rollout {path}: {k!r} has width {shape[1]}, the model needs "
                             f"{getattr(model, width[k])} (model.{width[k]})")
        total += int(np.prod(shape, dtype=np.float64)) * 8
    check_array_bytes(total, f"rollout {path} ({T} frames)", "split the rollout into shorter files")


def load_rollout(path, model=None) -> dict:
    """Read and check a rollout ``.npz`` (see the module docstring).

    Shapes and the total size are checked from the file's array headers before any array is
    loaded, so a small file that would inflate to gigabytes is refused up front.

    Raises
    ------
    ValueError
        Missing ``time``/``qpos``/``qvel``, wrong shapes, non-increasing time, NaN, a time
        span beyond :data:`mjsound.limits.MAX_DURATION_S`, over the memory budget.
    """
    _check_header(path, model)
    try:
        with np.load(os.fspath(path), allow_pickle=False) as z:
            r = {k: np.asarray(z[k], dtype=np.float64) for k in _KEYS if k in z.files}
    except Exception as exc:
        raise ValueError(f"rollout {path}: cannot read ({type(exc).__name__}: {exc})") from exc
    T = len(r["time"])
    if np.any(np.diff(r["time"]) <= 0) or not np.isfinite(r["time"]).all():
        raise ValueError(f"rollout {path}: 'time' must be finite and strictly increasing")
    check_duration(r["time"][-1] - r["time"][0], f"rollout {path}: time span")
    for k, v in r.items():
        if not np.isfinite(v).all():
            raise ValueError(f"rollout {path}: {k!r} contains NaN or Inf")
    if model is not None:
        for k, w in (("mocap_pos", 3), ("mocap_quat", 4)):
            if k in r and r[k].reshape(T, -1).shape[1] != model.nmocap * w:
                raise ValueError(f"rollout {path}: {k!r} does not match the model's {model.nmocap} mocap bodies")
    return r


def _set_frame(model, data, r, i, state=True):
    if state:
        data.qpos[:] = r["qpos"][i]
        data.qvel[:] = r["qvel"][i]
        if "act" in r and model.na:
            data.act[:] = r["act"][i]
    if "ctrl" in r and model.nu:
        data.ctrl[:] = r["ctrl"][i]
    if "mocap_pos" in r and model.nmocap:
        data.mocap_pos[:] = r["mocap_pos"][i].reshape(-1, 3)
    if "mocap_quat" in r and model.nmocap:
        data.mocap_quat[:] = r["mocap_quat"][i].reshape(-1, 4)


def load_materials(materials, name: str = "--materials"):
    """A ``{geom_or_body: material}`` dict from a dict, a JSON file or JSON text (``None`` stays)."""
    if materials is None or isinstance(materials, dict):
        return materials
    text = os.fspath(materials)
    try:
        if os.path.exists(text):
            try:
                with open(text, encoding="utf-8") as fh:
                    obj = json.load(fh)
            except UnicodeDecodeError as exc:
                raise ValueError(f"{name}: {text} is not a UTF-8 JSON file ({exc.reason})") from None
            where = text
        else:
            obj = json.loads(text)
            where = "the text"
    except json.JSONDecodeError as exc:
        raise ValueError(f"{name}: {text[:200]!r} is neither a JSON file nor a JSON object ({exc})") from None
    except RecursionError:
        raise ValueError(f"{name}: {text[:200]!r} is nested too deeply to be a material mapping") from None
    if not isinstance(obj, dict) or not all(isinstance(k, str) for k in obj):
        raise ValueError(f"{name}: {where} holds a JSON {type(obj).__name__}; give an object "
                         '{"geom_or_body": "material", ...}, e.g. {"bowl": "porcelain"}')
    return obj


_load_materials = load_materials  # the batch driver's name for it


class _Take:
    """Where the audio of a take goes: the file (streamed, block by block) and/or memory.
    ``file_gain`` (channels,) scales what is written (contact channels to the pressure full
    scale); ``peak`` is taken over the ``air`` channels (pressure)."""

    def __init__(self, writer, keep: bool, channels: int, file_gain=None, air=None):
        self.writer, self.keep, self.channels = writer, keep, channels
        self.file_gain = None if file_gain is None else np.asarray(file_gain, np.float32)[:, None]
        self.air = air
        self.blocks = []
        self.samples = 0
        self.peak = 0.0

    def add(self, block) -> None:
        if block is None or not block.shape[1]:
            return
        if self.writer is not None:
            self.writer.write(block if self.file_gain is None else block * self.file_gain)
        if self.keep:
            self.blocks.append(block)
        self.samples += block.shape[1]
        air = block if self.air is None else block[self.air]
        if air.size:
            self.peak = max(self.peak, float(np.abs(air).max()))

    def audio(self):
        if not self.keep:
            return None
        if not self.blocks:
            return np.zeros((self.channels, 0), np.float32)
        return self.blocks[0] if len(self.blocks) == 1 else np.concatenate(self.blocks, axis=1)


def sonify(
    scene_xml,
    duration: float | None = None,
    rollout=None,
    timestep: float | None = None,
    sample_rate: int = 48000,
    materials=None,
    out=None,
    *,
    mode: str = "auto",
    quality: str = "default",
    budget_modes: int | None = None,
    progress: bool = True,
    full_scale_pa: float | None = None,
    normalize: bool = False,
    on_block=None,
    models: dict | None = None,
    keep_audio: bool = True,
    clicks: bool = True,
    contact_mics=None,
    contact_full_scale: float | None = None,
    reflections=True,
    room=None,
) -> dict:
    """Simulate (or replay) a scene with sound and optionally write the audio.

    Every input is checked before the scene is analysed or anything is allocated (ranges in
    :mod:`mjsound.limits`). The audio is written to ``out`` block by block as it is rendered
    (``STREAM_BLOCK_S`` of simulation at a time) into a temporary file renamed into place at
    the end, so with ``keep_audio=False`` memory does not grow with the duration, and an
    exception or Ctrl-C leaves ``out`` as it was.

    Parameters
    ----------
    scene_xml : str | os.PathLike
        MJCF file.
    duration : float, optional
        Simulated seconds (default: the whole rollout, or 3 s without one).
    rollout : str | os.PathLike | dict, optional
        Rollout ``.npz`` (or an already loaded dict, see :func:`load_rollout`).
    timestep : float, optional
        Override the model's physics timestep [s] (no rollout, or ``resim``).
    sample_rate : int
        Audio sample rate [Hz], 1000..768000.
    materials : dict | str, optional
        ``{geom_or_body: material}`` or a JSON file / JSON text of one.
    out : str | os.PathLike, optional
        ``.wav`` (float) or ``.flac`` (24-bit) path (``mjsound.synth.output.AudioWriter``).
    mode : {'auto', 'resim', 'replay'}
        How to use a rollout (module docstring); auto = resim when it has ``ctrl``.
    quality, budget_modes, progress
        Passed to :meth:`SoundScene.from_model`.
    full_scale_pa : float, optional
        Pressure written as full scale [Pa] (default ``DEFAULT_FULL_SCALE_PA`` = 20 Pa).
    normalize : bool
        Peak-normalise the file to -1 dBFS instead (absolute level lost; a second pass over
        a raw temporary file, still streamed).
    on_block : callable, optional
        ``on_block(sim, block, n0)`` after every step (see ``AudioSimulator.on_block``).
    models : dict, optional
        Precomputed ``{geom_name: ModalModel}`` (skips their analysis; batch workers).
    keep_audio : bool
        Also return the whole take as ``audio`` (memory grows with the duration and is checked
        against the budget up front); ``False`` returns ``audio=None``.
    clicks : bool
        Acceleration noise of every impact (default True).
    reflections, room
        The scene's planes reflect (default True; False: free field), or a room's walls do
        (:class:`AudioSimulator`, ``docs/rooms.md``).
    contact_mics : list[str] | None
        Contact microphone sites (default: sites named ``contact_mic*``; ``[]``: none). Their
        channels [m/s^2] follow the air microphones' (``channel_names``).
    contact_full_scale : float, optional
        Acceleration written as full scale on the contact channels of ``out`` [m/s^2]
        (default ``DEFAULT_CONTACT_FULL_SCALE`` = 1000).

    Returns
    -------
    dict
        ``scene`` (SoundScene.summary()), ``events``, ``impacts``, ``sim_seconds``,
        ``wall_seconds``, ``observer_seconds`` (spent in ``on_block``), ``analysis_seconds``,
        ``warmup_seconds`` (wall time of :func:`mjsound.sim.warmup.warmup`, once per process:
        every kernel compiled or loaded, and of the first rendered block), ``realtime_factor``
        (``timed_sim_seconds`` simulated per ``timed_wall_seconds`` of wall time: after the first
        block, analysis, warm-up and ``on_block`` excluded), ``samples``, ``channels``,
        ``channel_names`` (air microphones, then contact microphones),
        ``peak_pa`` (air channels), ``clipped``, ``out``, ``mode``, ``max_qpos_error`` (resim
        of a rollout), and ``audio`` (the (channels, n) float32 pressure array [Pa], or None).
    """
    import mujoco

    from ..synth.output import AUDIO_SUFFIXES, DEFAULT_FULL_SCALE_PA, AudioWriter

    sample_rate = check_sample_rate(sample_rate)
    if duration is not None:
        duration = check_duration(duration)
    if timestep is not None:
        timestep = check_timestep(timestep)
    if mode not in ("auto", "resim", "replay"):
        raise ValueError(f"mode={mode!r}: choose 'auto', 'resim' or 'replay'")
    if out is not None:
        from ..io import check_output_file

        check_output_file(out, AUDIO_SUFFIXES, "out")
    fsp = DEFAULT_FULL_SCALE_PA if full_scale_pa is None else float(full_scale_pa)
    if not normalize and not (np.isfinite(fsp) and fsp > 0):
        raise ValueError(f"full_scale_pa={full_scale_pa!r} must be a positive pressure in Pa (e.g. 20)")
    from ..synth.contact_mic import check_contact_full_scale

    fsc = check_contact_full_scale(contact_full_scale)
    mats = load_materials(materials)
    model = mujoco.MjModel.from_xml_path(os.fspath(scene_xml))
    if timestep is not None:
        model.opt.timestep = timestep
    check_timestep(model.opt.timestep, f"{os.fspath(scene_xml)}: <option timestep>")
    r = None
    if rollout is not None:
        r = rollout if isinstance(rollout, dict) else load_rollout(rollout, model)
        if mode == "auto":
            mode = "resim" if "ctrl" in r else "replay"
        times = r["time"]
        t_end = times[-1] if duration is None else min(times[-1], times[0] + duration)
        last = int(np.searchsorted(times, t_end - 1e-12, side="left"))
        span = float(times[last] - times[0])
    else:
        mode = "simulate"
        span = 3.0 if duration is None else duration
    dt = float(model.opt.timestep)
    if mode != "replay":
        check_steps(span / dt, f"{span:g} s at timestep {dt:g} s")
    n_ch_max = max(1, sum(1 for s in range(model.nsite) if (mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SITE, s) or "").startswith("mic")))
    n_ch_max += model.nsite if contact_mics is None else len(contact_mics)  # (a bound)
    if keep_audio:
        check_array_bytes(4.0 * n_ch_max * span * sample_rate, f"keeping {span:g} s of audio in memory",
                          "pass keep_audio=False (the file is streamed) or shorten the take")

    from .scene import SoundScene
    from .simulator import AudioSimulator
    from .warmup import warmup

    data = mujoco.MjData(model)
    scene = SoundScene.from_model(
        model, materials=mats, sample_rate=sample_rate, quality=quality,
        budget_modes=budget_modes, progress=progress, models=models,
    )
    if r is None and model.nkey > 0:
        mujoco.mj_resetDataKeyframe(model, data, 0)
    if r is not None:
        data.time = float(r["time"][0])
        _set_frame(model, data, r, 0)
        mujoco.mj_forward(model, data)
    # the event log (up to 100 000 entries) only serves an observer such as a rerun recording
    sim = AudioSimulator(model, data, scene=scene, sample_rate=sample_rate, clicks=clicks, contact_mics=contact_mics,
                         reflections=reflections, room=room,
                         **({} if on_block is not None else {"keep_events": 0}))
    t_obs = [0.0]  # wall time spent in on_block (e.g. rerun logging): reported apart
    if on_block is not None:
        def timed_on_block(sim_, block, n0):
            t = _time.perf_counter()
            on_block(sim_, block, n0)
            t_obs[0] += _time.perf_counter() - t

        sim.on_block = timed_on_block
    writer = None
    if out is not None:
        writer = AudioWriter(out, sample_rate, sim.n_channels, full_scale_pa=None if normalize else fsp,
                             normalize=bool(normalize))
    contact = sim.contact_channels
    gain = np.ones(sim.n_channels)
    gain[contact] = fsp / fsc
    air = np.setdiff1d(np.arange(sim.n_channels), contact)
    take = _Take(writer, keep_audio, sim.n_channels, file_gain=gain if len(contact) else None,
                 air=air if len(contact) else None)
    warm = {}  # wall time and samples of the first rendered block (numba compiles there)
    max_err = None
    t_wall = _time.perf_counter()
    # every kernel the take will use compiled (cold numba cache) or loaded now, not in the timed part
    t_warm = warmup(verbose=False, once=True)

    def first_block_done():
        if not warm and take.samples:
            warm.update(wall=_time.perf_counter() - t_wall, samples=take.samples, obs=t_obs[0])

    try:
        if mode == "simulate":
            every = sim.steps_per_render
            total = int(round(span / dt))
            chunk = max(every, int(round(STREAM_BLOCK_S / dt)) // every * every)
            done = 0
            while done < total:
                m = min(every if done == 0 else chunk, total - done)
                take.add(sim.run(m * dt, nsteps=m))
                done += m
                first_block_done()
        elif mode == "resim":
            max_err = 0.0
            every = sim.steps_per_render
            k = 0
            for i in range(last):
                if i > 0:
                    max_err = max(max_err, float(np.abs(data.qpos - r["qpos"][i]).max()))
                _set_frame(model, data, r, i, state=False)
                n = max(1, int(round((times[i + 1] - times[i]) / dt)))
                for _ in range(n):
                    mujoco.mj_step(model, data)
                    k += 1
                    take.add(sim.step(render=k % every == 0))
                    first_block_done()
            take.add(sim.flush())
        else:  # replay
            fs = sample_rate
            n_prev = int(np.ceil(times[0] * fs - 1e-6))
            base = n_prev
            sim.reset()
            for i in range(last):
                _set_frame(model, data, r, i)
                data.time = float(times[i])
                mujoco.mj_forward(model, data)
                n1 = int(np.ceil(times[i + 1] * fs - 1e-6))
                take.add(sim.driver.replay(n_prev, n1, float(times[i]), float(times[i + 1]), origin=base))
                first_block_done()
                n_prev = n1
        wall = _time.perf_counter() - t_wall
        if writer is not None:
            writer.close()
    except BaseException:
        if writer is not None:
            writer.abort()
        raise
    sim_seconds = take.samples / float(sample_rate)
    w0, s0, o0 = warm.get("wall", 0.0), warm.get("samples", 0), warm.get("obs", 0.0)
    timed_wall = (wall - w0) - (t_obs[0] - o0)
    timed_sim = (take.samples - s0) / float(sample_rate)
    if timed_sim <= 0:  # one block only: nothing after the warm-up to time
        timed_wall, timed_sim = wall - t_warm - t_obs[0], sim_seconds
    return {
        "scene": scene.summary(),
        "mode": mode,
        "events": dict(sim.events),
        "impacts": len(sim.impacts),
        "sim_seconds": sim_seconds,
        "wall_seconds": wall,
        "observer_seconds": t_obs[0],
        "analysis_seconds": scene.analysis_seconds,
        "warmup_seconds": w0 if timed_sim < sim_seconds else t_warm,
        "realtime_factor": timed_sim / timed_wall if timed_wall > 0 else float("inf"),
        "timed_sim_seconds": timed_sim,
        "timed_wall_seconds": timed_wall,
        "samples": int(take.samples),
        "channels": int(sim.n_channels),
        "channel_names": list(sim.channel_names),
        "peak_pa": take.peak,
        "clipped": int(writer.n_clipped) if writer is not None else 0,
        "out": None if out is None else os.fspath(out),
        "max_qpos_error": max_err,
        "stats": sim.stats(),
        "audio": take.audio(),
    }


def write_spectrogram_png(path, audio, sample_rate, title="mjsound demo", labels=None) -> str | None:
    """Save a log-magnitude spectrogram of each channel (matplotlib, optional) atomically.

    ``audio`` (channels, samples) is drawn on one colour scale (its overall peak), so channels
    keep their relative levels; ``labels`` (one string per channel, e.g. ``"mic_left, peak
    32.1 Pa"``) name the channels and their units. Without labels the title gives the peak in Pa.

    Returns the path, or None (with a warning) when matplotlib is missing.
    """
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        import warnings

        warnings.warn("matplotlib not installed; no spectrogram picture (pip install 'mjsound[report]')",
                      stacklevel=user_stacklevel())
        return None
    from ..io import atomic_path

    audio = np.atleast_2d(audio)
    fig, axes = plt.subplots(len(audio), 1, figsize=(9, 2.4 * len(audio)), sharex=True, squeeze=False)
    peak = float(np.abs(audio).max()) or 1.0
    for k, (ch, ax) in enumerate(zip(audio, axes[:, 0])):
        ax.specgram(ch / peak, NFFT=1024, Fs=sample_rate, noverlap=768, cmap="magma", vmin=-120, vmax=-20)
        ax.set_ylabel("Hz")
        if labels is not None:
            ax.set_title(str(labels[k]), fontsize=9, loc="left")
    head = f"{title}: {audio.shape[1] / sample_rate:.1f} s"
    fig.suptitle(head if labels is not None else f"{head}, peak {peak:.3g} Pa")
    axes[-1, 0].set_xlabel("simulation time [s]")
    fig.tight_layout()
    try:
        with atomic_path(path, ".png") as tmp:
            fig.savefig(tmp, dpi=90, format="png")
    finally:
        plt.close(fig)
    return os.fspath(path)
