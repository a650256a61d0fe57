"""``mjsound render-events``: sound from a JSON list of timed events, no simulator."""

from __future__ import annotations

import argparse

__all__ = ["register"]


def register(sub) -> argparse.ArgumentParser:
    """Add ``render-events`` to an argparse ``subparsers``; returns its parser."""
    from ..synth.events import EVENTS_HELP

    p = sub.add_parser(
        "render-events",
        help="render a JSON list of timed impacts/slides/rolls to a WAV/FLAC file",
        description=EVENTS_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("events", help="EVENTS.json (format above)")
    p.add_argument("-o", "--output", help="output .wav or .flac (default: EVENTS.wav next to the JSON)")
    p.add_argument("--full-scale-pa", type=float, default=None,
                   help="pressure [Pa] mapped to full scale (default: the file's full_scale_pa or 20)")
    p.add_argument("--normalize", action="store_true", help="peak-normalise to -1 dBFS (loses the level)")
    p.add_argument("--sample-rate", type=int, default=None, help="override the file's sample_rate [Hz]")
    p.set_defaults(func=run)
    return p


def run(args) -> int:
    """Handler of ``mjsound render-events``."""
    import os

    import numpy as np

    from ..io import check_output_file
    from ..synth.events import load_events, render_events
    from ..synth.output import AUDIO_SUFFIXES, DEFAULT_FULL_SCALE_PA, write_audio

    out = args.output or os.path.splitext(args.events)[0] + ".wav"
    check_output_file(out, AUDIO_SUFFIXES, "-o")
    spec = load_events(args.events)
    if args.sample_rate is not None:
        spec["sample_rate"] = args.sample_rate
    audio, fs = render_events(spec)
    fsp = args.full_scale_pa if args.full_scale_pa is not None else spec.get("full_scale_pa", DEFAULT_FULL_SCALE_PA)
    normalize = args.normalize or bool(spec.get("normalize", False))
    n_clipped = write_audio(out, audio, fs, full_scale_pa=fsp, normalize=normalize)
    peak = float(np.abs(audio).max()) if audio.size else 0.0
    msg = f"wrote {out}: {audio.shape[0]} channel(s), {audio.shape[1]} samples at {fs} Hz, peak {peak:.3g} Pa"
    if not normalize:
        msg += f", full scale {fsp:g} Pa, {n_clipped} clipped sample(s)"
    print(msg)
    return 0
