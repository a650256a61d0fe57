"""``mjsound sonify``, ``mjsound demo`` and ``mjsound sonify-batch``: scenes and rollouts to sound."""

from __future__ import annotations

import contextlib
import json
import os
import sys

__all__ = ["register", "add_sonify_options"]


def add_sonify_options(p) -> None:
    """The options ``sonify`` and ``sonify-batch`` share (they map onto ``mjsound.sim.rollout.sonify``)."""
    p.add_argument("--replay", action="store_true", help="replay recorded states instead of re-simulating")
    p.add_argument("--timestep", type=float, default=None, help="physics timestep in s (overrides the MJCF)")
    p.add_argument("--sample-rate", type=int, default=48000, help="audio sample rate in Hz (default 48000; 8000..384000)")
    p.add_argument("--materials", default=None, help="JSON file or text {geom_or_body: material}")
    p.add_argument("--quality", choices=["draft", "default", "high"], default="default", help="modal analysis quality")
    p.add_argument("--budget-modes", type=int, default=None, help="total modes for the scene (shared by importance)")
    p.add_argument("--full-scale-pa", type=float, default=None, help="pressure written as full scale (default 20 Pa)")
    p.add_argument("--normalize", action="store_true", help="peak-normalise each file (absolute level lost)")
    p.add_argument("--max-memory-gb", type=float, default=None,
                   help="memory cap in GB of each modal analysis and in-memory array (sets $MJSOUND_MAX_MEMORY_GB "
                        "for this run and its workers; default 8)")


@contextlib.contextmanager
def _memory_cap(args):
    """``--max-memory-gb`` as ``$MJSOUND_MAX_MEMORY_GB`` while the command runs (its workers
    inherit it); the variable is restored afterwards."""
    from ..limits import MAX_MEMORY_ENV, finite_number

    gb = getattr(args, "max_memory_gb", None)
    if gb is None:
        yield
        return
    if not finite_number(gb, "--max-memory-gb") > 0:
        raise ValueError(f"--max-memory-gb={gb:g} must be a positive number of gigabytes")
    before = os.environ.get(MAX_MEMORY_ENV)
    os.environ[MAX_MEMORY_ENV] = repr(float(gb))
    try:
        yield
    finally:
        if before is None:
            del os.environ[MAX_MEMORY_ENV]
        else:
            os.environ[MAX_MEMORY_ENV] = before


def register(subparsers) -> None:
    """Add ``sonify``, ``demo`` and ``sonify-batch`` to an argparse ``subparsers``."""
    p = subparsers.add_parser(
        "sonify",
        help="simulate an MJCF scene (or a recorded rollout) with sound and write a WAV",
        description="Simulate SCENE.xml with contact sound, or sonify a recorded rollout (.npz with "
        "time, qpos, qvel [, ctrl, act, mocap_pos, mocap_quat]): re-simulated from its controls "
        "(exact) or replayed state by state (--replay). The audio is written block by block as it is "
        "rendered (memory does not grow with --duration) to a temporary file renamed into place at the end.",
    )
    p.add_argument("scene", help="MJCF scene file")
    p.add_argument("-o", "--output", default="out.wav", help="audio file to write, .wav or .flac (default out.wav)")
    p.add_argument("--duration", type=float, default=None, help="simulated seconds (default: 3, or the whole rollout)")
    p.add_argument("--rollout", default=None, help="rollout .npz to sonify")
    add_sonify_options(p)
    p.add_argument("--no-clicks", action="store_true", help="no acceleration noise (clicks) from impacts")
    p.add_argument("--no-reflections", action="store_true",
                   help="free field: the scene's planes (the floor) do not reflect (docs/rooms.md)")
    p.add_argument("--contact-mics", default=None,
                   help="comma-separated contact microphone sites (default: sites named contact_mic*; '' for none)")
    p.add_argument("--contact-full-scale", type=float, default=None,
                   help="acceleration written as full scale on contact channels, m/s^2 (default 1000)")
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

    b = subparsers.add_parser(
        "sonify-batch",
        help="sonify many rollouts of one scene (local process pool, or Ray with --address)",
        description="Sonify every rollout .npz (files or directories of them) of SCENE into OUTDIR/<stem>.wav, "
        "each identical to `mjsound sonify SCENE --rollout R`. Modal models are computed once and shared with the "
        "workers. Reruns skip finished outputs (checked against a <stem>.json sidecar); a failing rollout is "
        "reported and the others go on (exit status 1 if any failed). Workers end with the driver.",
    )
    b.add_argument("rollouts", nargs="+", help="rollout .npz files or directories of them")
    b.add_argument("--scene", required=True, help="MJCF scene file")
    b.add_argument("-o", "--outdir", required=True, help="output directory")
    b.add_argument("--workers", type=int, default=None, help="worker processes (default: all CPUs); on Ray: tasks in flight")
    b.add_argument("--address", default=None,
                   help="run on Ray: 'auto' (running cluster), a Ray address, or 'local' (private instance)")
    b.add_argument("--rrd", action="store_true", help="also write a rerun recording <stem>.rrd per rollout")
    b.add_argument("--duration", type=float, default=None, help="simulated seconds per rollout (default: all)")
    add_sonify_options(b)
    b.add_argument("--force", action="store_true", help="redo every rollout (do not skip finished outputs)")
    b.add_argument("--retries", type=int, default=2, help="retries of a task whose worker process died (default 2)")
    b.add_argument("--json", action="store_true", help="print one JSON summary object")
    b.set_defaults(func=_run_batch)


def _report(summary, args) -> int:
    s = dict(summary)
    s.pop("audio", None)
    if args.json:
        print(json.dumps(s, default=float))
        return 0
    sc = s["scene"]
    print(f"scene      {args.scene if hasattr(args, 'scene') else 'demo'}  ({s['mode']})")
    print(f"sounding   {len(sc['sounding'])} object(s), {sc['n_modes']} modes, analysis {s['analysis_seconds']:.1f} s")
    for g in sc["sounding"]:
        extra = f" of {g['n_modes_analysed']}" if g["n_modes"] != g["n_modes_analysed"] else ""
        rng = f"{g['f_min_hz']:.0f}-{g['f_max_hz']:.0f} Hz" if g["f_min_hz"] else "-"
        err = g.get("error_estimate_cents")
        est = "" if err is None else f"  +-{err:.0f} c" + (" (!)" if err > 50 else "")
        print(f"  {g['geom']:<16s} {g['material']:<12s} {g['n_modes']:4d}{extra} modes  {rng}{est}")
        for note in g.get("notes", ()):
            print(f"      {note}")
    for name, why in sc["silent"].items():
        print(f"  silent {name}: {why}")
    for note in sc["budget_notes"]:
        print(f"  budget: {note}")
    ev = s["events"]
    print(f"events     {ev.get('impact', 0)} impacts, {ev.get('slide', 0)} slide steps, {ev.get('roll', 0)} roll steps")
    if s.get("channel_names"):
        print(f"channels   {', '.join(s['channel_names'])}")
    print(f"audio      {s['samples']} samples x {s['channels']} ch ({s['sim_seconds']:.2f} s), peak {s['peak_pa']:.3g} Pa"
          + (f", {s['clipped']} clipped" if s["clipped"] else ""))
    obs = s.get("observer_seconds", 0.0)
    extra = f"; rerun logging {obs:.2f} s more" if obs > 0 else ""
    warm = s.get("warmup_seconds", 0.0)
    extra += f"; kernel warm-up (numba compiles on a first run) and first block {warm:.2f} s excluded" if warm > 0 else ""
    print(f"speed      {s['realtime_factor']:.1f}x real time ({s['timed_sim_seconds']:.2f} s simulated with its audio in "
          f"{s['timed_wall_seconds']:.2f} s wall, analysis excluded{extra})")
    if s["max_qpos_error"] is not None:
        print(f"resim      max |qpos - recorded| = {s['max_qpos_error']:.3g}")
    for key in ("out", "rrd", "png"):
        if s.get(key):
            print(f"wrote      {s[key]}")
    return 0


def _check_outputs(args) -> None:
    from ..io import check_output_file
    from ..synth.output import AUDIO_SUFFIXES

    if args.output:
        check_output_file(args.output, AUDIO_SUFFIXES, "-o")
    if args.rrd:
        check_output_file(args.rrd, (".rrd",), "--rrd")
    if getattr(args, "png", None):
        check_output_file(args.png, (".png",), "--png")


def _sonify_maybe_logged(args, scene, **kw) -> dict:
    from ..sim.rollout import sonify

    _check_outputs(args)
    with _memory_cap(args):
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
        keep_audio=False,
        clicks=not args.no_clicks, reflections=not args.no_reflections, contact_full_scale=args.contact_full_scale,
        contact_mics=None if args.contact_mics is None else [n.strip() for n in args.contact_mics.split(",") if n.strip()],
    )
    return _report(summary, args)


def _run_demo(args) -> int:
    from ..sim.demo import find_demo_scene
    from ..sim.rollout import write_spectrogram_png

    scene = find_demo_scene()
    args.scene = scene
    summary = _sonify_maybe_logged(
        args, scene, duration=args.duration, sample_rate=args.sample_rate, out=args.output, quality=args.quality,
        progress=not args.json and sys.stderr.isatty(), normalize=not args.no_normalize,
        keep_audio=bool(args.png),
    )
    if args.png:
        import numpy as np

        from ..synth.contact_mic import DEFAULT_CONTACT_FULL_SCALE
        from ..synth.output import DEFAULT_FULL_SCALE_PA

        audio = summary["audio"].copy()  # contact channels (after the air ones) in full-scale units
        n_air = len(summary["scene"]["microphones"])
        peaks = np.abs(audio).max(axis=1) if audio.size else np.zeros(len(audio))
        names = summary.get("channel_names") or [f"channel {k}" for k in range(len(audio))]
        labels = [f"{name}: peak {pk:.3g} {'Pa' if k < n_air else 'm/s²'}" for k, (name, pk) in enumerate(zip(names, peaks))]
        audio[n_air:] *= DEFAULT_FULL_SCALE_PA / DEFAULT_CONTACT_FULL_SCALE
        summary["png"] = write_spectrogram_png(args.png, audio, args.sample_rate, labels=labels)
    return _report(summary, args)


def _run_batch(args) -> int:
    from ..batch import _json_default, sonify_batch

    with _memory_cap(args):
        s = sonify_batch(
            args.rollouts, args.scene, args.outdir, workers=args.workers, address=args.address,
            duration=args.duration, timestep=args.timestep, sample_rate=args.sample_rate, materials=args.materials,
            mode="replay" if args.replay else "auto", quality=args.quality, budget_modes=args.budget_modes,
            full_scale_pa=args.full_scale_pa, normalize=args.normalize, rrd=args.rrd, resume=not args.force,
            max_retries=args.retries, progress=not args.json and sys.stderr.isatty(),
        )
    if args.json:
        out = dict(s)
        out["failed"] = [{k: v for k, v in f.items() if k != "traceback"} for f in s["failed"]]
        print(json.dumps(out, default=_json_default))
    else:
        print(f"rollouts   {s['n_rollouts']}: {len(s['done'])} sonified, {len(s['skipped'])} skipped (complete), "
              f"{len(s['failed'])} failed")
        print(f"backend    {s['backend']}, {s['workers']} worker(s); modal analysis {s['analysis_seconds']:.1f} s (once)")
        print(f"throughput {s['audio_seconds']:.1f} s of audio in {s['wall_seconds']:.1f} s wall = "
              f"{s['throughput']:.2f} audio-s/s")
        for f in s["failed"]:
            print(f"  FAILED {f['rollout']}: {f['error']}", file=sys.stderr)
        print(f"outputs    {s['outdir']}")
    return 1 if s["failed"] else 0
