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
import sys
import time as _time

import numpy as np

__all__ = ["load_rollout", "sonify", "register_cli"]

_KEYS = ("time", "qpos", "qvel", "ctrl", "act", "mocap_pos", "mocap_quat")


def load_rollout(path, model=None) -> dict:
    """Read and check a rollout ``.npz`` (see the module docstring).

    Raises
    ------
    ValueError
        Missing ``time``/``qpos``/``qvel``, wrong shapes, non-increasing time, NaN.
    """
    try:
        with np.load(os.fspath(path), allow_pickle=False) as z:
            r = {k: np.asarray(z[k], dtype=np.float64) for k in _KEYS if k in z.files}
    except Exception as exc:
        raise ValueError(f"rollout {path}: cannot read ({type(exc).__name__}: {exc})") from exc
    for k in ("time", "qpos", "qvel"):
        if k not in r:
            raise ValueError(f"rollout {path}: missing array {k!r} (needs time, qpos, qvel)")
    T = len(r["time"])
    if T < 2 or r["time"].ndim != 1:
        raise ValueError(f"rollout {path}: 'time' must be a 1-D array of at least 2 frames")
    if np.any(np.diff(r["time"]) <= 0) or not np.isfinite(r["time"]).all():
        raise ValueError(f"rollout {path}: 'time' must be finite and strictly increasing")
    for k, v in r.items():
        if len(v) != T:
            raise ValueError(f"rollout {path}: {k!r} has {len(v)} frames, 'time' has {T}")
        if not np.isfinite(v).all():
            raise ValueError(f"rollout {path}: {k!r} contains NaN or Inf")
    if model is not None:
        dims = {"qpos": model.nq, "qvel": model.nv, "ctrl": model.nu, "act": model.na}
        for k, n in dims.items():
            if k in r and r[k].reshape(T, -1).shape[1] != n:
                raise ValueError(f"rollout {path}: {k!r} has width {r[k].reshape(T, -1).shape[1]}, the model needs {n}")
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


def _load_materials(materials):
    if materials is None or isinstance(materials, dict):
        return materials
    text = os.fspath(materials)
    if os.path.exists(text):
        with open(text) as fh:
            return json.load(fh)
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(f"--materials: {text!r} is neither a JSON file nor a JSON object ({exc})") from None


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
) -> dict:
    """Simulate (or replay) a scene with sound and optionally write the audio.

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
        Audio sample rate [Hz].
    materials : dict | str, optional
        ``{geom_or_body: material}`` or a JSON file / JSON text of one.
    out : str | os.PathLike, optional
        WAV/FLAC path, written atomically (``mjsound.synth.output.write_audio``).
    mode : {'auto', 'resim', 'replay'}
        How to use a rollout (module docstring); auto = resim when it has ``ctrl``.
    quality, budget_modes, progress
        Passed to :meth:`SoundScene.from_model`.
    full_scale_pa : float, optional
        Pressure written as full scale [Pa] (default ``DEFAULT_FULL_SCALE_PA`` = 20 Pa).
    normalize : bool
        Peak-normalise the file to -1 dBFS instead (absolute level lost).
    on_block : callable, optional
        ``on_block(sim, block, n0)`` after every step (see ``AudioSimulator.on_block``).
    models : dict, optional
        Precomputed ``{geom_name: ModalModel}`` (skips their analysis; batch workers).

    Returns
    -------
    dict
        ``scene`` (SoundScene.summary()), ``events``, ``impacts``, ``sim_seconds``,
        ``wall_seconds``, ``observer_seconds`` (spent in ``on_block``), ``analysis_seconds``,
        ``realtime_factor`` (simulated seconds per wall second, analysis and ``on_block``
        excluded), ``samples``, ``channels``, ``peak_pa``, ``clipped``,
        ``out``, ``mode``, ``max_qpos_error`` (resim of a rollout), and ``audio`` (the
        (channels, n) float32 pressure array [Pa]).
    """
    import mujoco

    from .scene import SoundScene
    from .simulator import AudioSimulator

    model = mujoco.MjModel.from_xml_path(os.fspath(scene_xml))
    if timestep is not None:
        if not (timestep > 0 and np.isfinite(timestep)):
            raise ValueError(f"timestep={timestep} must be a positive number of seconds")
        model.opt.timestep = float(timestep)
    data = mujoco.MjData(model)
    scene = SoundScene.from_model(
        model, materials=_load_materials(materials), sample_rate=sample_rate, quality=quality,
        budget_modes=budget_modes, progress=progress, models=models,
    )
    r = None
    if rollout is not None:
        r = rollout if isinstance(rollout, dict) else load_rollout(rollout, model)
        if mode == "auto":
            mode = "resim" if "ctrl" in r else "replay"
    else:
        mode = "simulate"
        if model.nkey > 0:
            mujoco.mj_resetDataKeyframe(model, data, 0)
    if mode not in ("simulate", "resim", "replay"):
        raise ValueError(f"mode={mode!r}: choose 'auto', 'resim' or 'replay'")
    if r is not None:
        data.time = float(r["time"][0])
        _set_frame(model, data, r, 0)
        mujoco.mj_forward(model, data)
    sim = AudioSimulator(model, data, scene=scene, sample_rate=sample_rate)
    t_obs = [0.0]  # wall time spent in on_block (e.g. rerun logging): reported apart
    if on_block is not None:
        def timed_on_block(sim_, block, n0):
            t = _time.perf_counter()
            on_block(sim_, block, n0)
            t_obs[0] += _time.perf_counter() - t

        sim.on_block = timed_on_block
    blocks = []
    max_err = None
    t_wall = _time.perf_counter()
    if mode == "simulate":
        blocks.append(sim.run(3.0 if duration is None else float(duration)))
    else:
        times = r["time"]
        t_end = times[-1] if duration is None else min(times[-1], times[0] + float(duration))
        last = int(np.searchsorted(times, t_end - 1e-12, side="left"))
        if mode == "resim":
            max_err = 0.0
            dt = float(model.opt.timestep)
            every = sim._render_every()
            k = 0
            for i in range(last):
                if i > 0:
                    max_err = max(max_err, float(np.abs(data.qpos - r["qpos"][i]).max()))
                _set_frame(model, data, r, i, state=False)
                n = max(1, int(round((times[i + 1] - times[i]) / dt)))
                for _ in range(n):
                    mujoco.mj_step(model, data)
                    k += 1
                    b = sim.step(render=k % every == 0)
                    if b is not None:
                        blocks.append(b)
            blocks.append(sim.flush())
        else:  # replay
            fs = int(sample_rate)
            n_prev = int(np.ceil(times[0] * fs - 1e-6))
            base = n_prev
            sim.reset()
            for i in range(last):
                _set_frame(model, data, r, i)
                data.time = float(times[i])
                mujoco.mj_forward(model, data)
                n1 = int(np.ceil(times[i + 1] * fs - 1e-6))
                sim._origin = base
                blocks.append(sim._process(n_prev, n1, float(times[i]), float(times[i + 1])))
                n_prev = n1
    wall = _time.perf_counter() - t_wall
    audio = np.concatenate(blocks, axis=1) if blocks else np.zeros((sim.n_channels, 0), np.float32)
    sim_seconds = audio.shape[1] / float(sample_rate)
    clipped = 0
    if out is not None:
        from ..synth.output import DEFAULT_FULL_SCALE_PA, write_audio

        fsp = DEFAULT_FULL_SCALE_PA if full_scale_pa is None else float(full_scale_pa)
        clipped = write_audio(out, audio, sample_rate, full_scale_pa=None if normalize else fsp, normalize=normalize)
    peak = float(np.abs(audio).max()) if audio.size else 0.0
    return {
        "scene": scene.summary(),
        "mode": mode,
        "events": dict(sim.events),
        "impacts": len(sim.impacts),
        "sim_seconds": sim_seconds,
        "wall_seconds": wall,
        "observer_seconds": t_obs[0],
        "analysis_seconds": scene.analysis_seconds,
        "realtime_factor": sim_seconds / (wall - t_obs[0]) if wall > t_obs[0] else float("inf"),
        "samples": int(audio.shape[1]),
        "channels": int(audio.shape[0]),
        "peak_pa": peak,
        "clipped": int(clipped),
        "out": None if out is None else os.fspath(out),
        "max_qpos_error": max_err,
        "stats": sim.stats(),
        "audio": audio,
    }


# ---------------------------------------------------------------------- CLI
def add_sonify_options(p) -> None:
    """The options ``sonify`` and ``sonify-batch`` share (they map onto :func:`sonify`)."""
    p.add_argument("--replay", action="store_true", help="replay recorded states instead of re-simulating")
    p.add_argument("--timestep", type=float, default=None, help="physics timestep in s (overrides the MJCF)")
    p.add_argument("--sample-rate", type=int, default=48000, help="audio sample rate in Hz (default 48000)")
    p.add_argument("--materials", default=None, help="JSON file or text {geom_or_body: material}")
    p.add_argument("--quality", choices=["draft", "default", "high"], default="default", help="modal analysis quality")
    p.add_argument("--budget-modes", type=int, default=None, help="total modes for the scene (shared by importance)")
    p.add_argument("--full-scale-pa", type=float, default=None, help="pressure written as full scale (default 20 Pa)")
    p.add_argument("--normalize", action="store_true", help="peak-normalise each file (absolute level lost)")


def register_cli(subparsers) -> None:
    """Add the ``sonify`` and ``demo`` subcommands to an argparse ``subparsers``."""
    p = subparsers.add_parser(
        "sonify",
        help="simulate an MJCF scene (or a recorded rollout) with sound and write a WAV",
        description="Simulate SCENE.xml with contact sound, or sonify a recorded rollout (.npz with "
        "time, qpos, qvel [, ctrl, act, mocap_pos, mocap_quat]): re-simulated from its controls "
        "(exact) or replayed state by state (--replay).",
    )
    p.add_argument("scene", help="MJCF scene file")
    p.add_argument("-o", "--output", default="out.wav", help="audio file to write (default out.wav)")
    p.add_argument("--duration", type=float, default=None, help="simulated seconds (default: 3, or the whole rollout)")
    p.add_argument("--rollout", default=None, help="rollout .npz to sonify")
    add_sonify_options(p)
    p.add_argument("--json", action="store_true", help="print one JSON summary object")
    p.add_argument("--rrd", default=None, help="also write a rerun recording (.rrd) of the take")
    p.set_defaults(func=_run_sonify)

    d = subparsers.add_parser(
        "demo",
        help="run the built-in demo scene (bowl, bar, disc, ball, box on an oak table) and write demo.wav",
    )
    d.add_argument("-o", "--output", default="demo.wav", help="audio file to write (default demo.wav)")
    d.add_argument("--duration", type=float, default=4.0, help="simulated seconds (default 4)")
    d.add_argument("--sample-rate", type=int, default=48000, help="audio sample rate in Hz (default 48000)")
    d.add_argument("--quality", choices=["draft", "default", "high"], default="default", help="modal analysis quality")
    d.add_argument("--no-normalize", action="store_true", help="write absolute pressure (20 Pa full scale)")
    d.add_argument("--json", action="store_true", help="print one JSON summary object")
    d.add_argument("--rrd", default="demo.rrd", help="rerun recording to write (default demo.rrd; '' for none)")
    d.add_argument("--png", default="demo.png", help="spectrogram picture to write (default demo.png; '' for none; needs matplotlib)")
    d.set_defaults(func=_run_demo)


def _report(summary, args) -> int:
    s = dict(summary)
    s.pop("audio", None)
    if args.json:
        print(json.dumps(s, default=float))
        return 0
    sc = s["scene"]
    print(f"scene      {args.scene if hasattr(args, 'scene') else 'demo'}  ({s['mode']})")
    print(f"sounding   {len(sc['sounding'])} geom(s), {sc['n_modes']} modes, analysis {s['analysis_seconds']:.1f} s")
    for g in sc["sounding"]:
        extra = f" of {g['n_modes_analysed']}" if g["n_modes"] != g["n_modes_analysed"] else ""
        rng = f"{g['f_min_hz']:.0f}-{g['f_max_hz']:.0f} Hz" if g["f_min_hz"] else "-"
        print(f"  {g['geom']:<16s} {g['material']:<12s} {g['n_modes']:4d}{extra} modes  {rng}")
    for name, why in sc["silent"].items():
        print(f"  silent {name}: {why}")
    for note in sc["budget_notes"]:
        print(f"  budget: {note}")
    ev = s["events"]
    print(f"events     {ev.get('impact', 0)} impacts, {ev.get('slide', 0)} slide steps, {ev.get('roll', 0)} roll steps")
    print(f"audio      {s['samples']} samples x {s['channels']} ch ({s['sim_seconds']:.2f} s), peak {s['peak_pa']:.3g} Pa"
          + (f", {s['clipped']} clipped" if s["clipped"] else ""))
    obs = s.get("observer_seconds", 0.0)
    extra = f"; rerun logging {obs:.2f} s more" if obs > 0 else ""
    print(f"speed      {s['realtime_factor']:.1f}x real time ({s['wall_seconds'] - obs:.2f} s wall for simulation and "
          f"audio, analysis excluded{extra})")
    if s["max_qpos_error"] is not None:
        print(f"resim      max |qpos - recorded| = {s['max_qpos_error']:.3g}")
    if s["out"]:
        print(f"wrote      {s['out']}")
    if s.get("rrd"):
        print(f"wrote      {s['rrd']}")
    if s.get("png"):
        print(f"wrote      {s['png']}")
    return 0


def _sonify_maybe_logged(args, scene, **kw) -> dict:
    if args.rrd:
        from ..rerun_log import log_sonify

        return log_sonify(args.rrd, scene, **kw)
    return sonify(scene, **kw)


def _run_sonify(args) -> int:
    summary = _sonify_maybe_logged(
        args, args.scene, duration=args.duration, rollout=args.rollout, timestep=args.timestep,
        sample_rate=args.sample_rate, materials=args.materials, out=args.output,
        mode="replay" if args.replay else "auto", quality=args.quality, budget_modes=args.budget_modes,
        progress=not args.json and sys.stderr.isatty(), full_scale_pa=args.full_scale_pa, normalize=args.normalize,
    )
    return _report(summary, args)


def _run_demo(args) -> int:
    from .demo import find_demo_scene

    scene = find_demo_scene()
    args.scene = scene
    summary = _sonify_maybe_logged(
        args, scene, duration=args.duration, sample_rate=args.sample_rate, out=args.output, quality=args.quality,
        progress=not args.json and sys.stderr.isatty(), normalize=not args.no_normalize,
    )
    if args.png:
        summary["png"] = write_spectrogram_png(args.png, summary["audio"], args.sample_rate)
    return _report(summary, args)


def write_spectrogram_png(path, audio, sample_rate, title="mjsound demo") -> str | None:
    """Save a log-magnitude spectrogram of each channel (matplotlib, optional) atomically.

    Returns the path, or None (with a message on stderr) when matplotlib is missing.
    """
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("mjsound: matplotlib not installed; no spectrogram picture (pip install 'mjsound[report]')",
              file=sys.stderr)
        return None
    from ..io import commit_temp, temp_beside

    audio = np.atleast_2d(audio)
    fig, axes = plt.subplots(len(audio), 1, figsize=(9, 2.4 * len(audio)), sharex=True, squeeze=False)
    peak = float(np.abs(audio).max()) or 1.0
    for ch, ax in zip(audio, axes[:, 0]):
        ax.specgram(ch / peak, NFFT=1024, Fs=sample_rate, noverlap=768, cmap="magma", vmin=-120, vmax=-20)
        ax.set_ylabel("Hz")
    axes[0, 0].set_title(f"{title}: {audio.shape[1] / sample_rate:.1f} s, peak {peak:.3g} Pa")
    axes[-1, 0].set_xlabel("simulation time [s]")
    fig.tight_layout()
    fd, tmp = temp_beside(path, ".png")
    os.close(fd)
    fig.savefig(tmp, dpi=90, format="png")
    plt.close(fig)
    commit_temp(tmp, path)
    return os.fspath(path)
