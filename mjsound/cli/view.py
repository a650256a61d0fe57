"""``mjsound view``: MuJoCo's viewer on a scene, its sound played live (:mod:`mjsound.live_view`)."""

from __future__ import annotations

import json
import sys

__all__ = ["register"]


def register(subparsers) -> None:
    """Add ``view`` to an argparse ``subparsers``."""
    p = subparsers.add_parser(
        "view",
        help="open MuJoCo's viewer on a scene and hear it live (drag a body: Ctrl + right mouse)",
        description="Simulate SCENE.xml in real time in MuJoCo's viewer and play its sound on an audio device as it "
        "happens (needs the extra mjsound[live] and PortAudio). The simulation is paced by the audio device; when it "
        "falls behind real time the sound pauses cleanly and a line says by how much. See docs/live.md.",
    )
    p.add_argument("scene", help="MJCF scene file")
    p.add_argument("--duration", type=float, default=None,
                   help="simulated seconds, then exit (default: until the viewer is closed)")
    p.add_argument("--audio-device", default=None,
                   help="output device: a name (or part of it) or a number (default: the system's default output)")
    p.add_argument("--no-viewer", action="store_true", help="audio only, no window (needs --duration)")
    p.add_argument("--sample-rate", type=int, default=48000, help="audio sample rate in Hz (default 48000)")
    p.add_argument("--full-scale-pa", type=float, default=20.0, help="pressure played at full scale (default 20 Pa)")
    p.add_argument("--lead", type=float, default=0.05,
                   help="seconds the simulation may run ahead of the sound heard (default 0.05)")
    p.add_argument("--device-latency", type=float, default=None,
                   help="latency asked of the audio device in s (default: PortAudio's, about 0.04; more for a busy machine)")
    p.add_argument("--timestep", type=float, default=None, help="physics timestep in s (overrides the MJCF)")
    p.add_argument("--materials", default=None, help="JSON file or text {geom_or_body: material}")
    p.add_argument("--quality", choices=["draft", "default", "high"], default="default", help="modal analysis quality")
    p.add_argument("--budget-modes", type=int, default=None, help="total modes for the scene (shared by importance)")
    p.add_argument("--json", action="store_true", help="print one JSON summary object at the end")
    p.set_defaults(func=_run_view)


def _device(name):
    """``--audio-device``: a PortAudio index when it is a number, else a name."""
    return int(name) if name is not None and name.strip().isdigit() else name


def _run_view(args) -> int:
    from ..live_view import view

    s = view(args.scene, duration=args.duration, device=_device(args.audio_device), viewer=not args.no_viewer,
             sample_rate=args.sample_rate, full_scale_pa=args.full_scale_pa, lead_s=args.lead, device_latency_s=args.device_latency,
             quality=args.quality,
             materials=args.materials, budget_modes=args.budget_modes, timestep=args.timestep,
             progress=not args.json and sys.stderr.isatty())
    if args.json:
        print(json.dumps(s))
        return 0
    print(f"played     {s['sim_seconds']:.2f} s simulated ({', '.join(s['channels'])}); paced at {s['pace']:.3f} "
          f"simulated s per wall s")
    print(f"audio      {s['underflows']} gap(s) where the simulation fell behind ({1000 * s['behind_s']:.0f} ms), "
          f"{s['clipped']} sample(s) clipped, device latency {1000 * s['latency_s']:.0f} ms + lead "
          f"{1000 * s['lead_s']:.0f} ms")
    return 0
