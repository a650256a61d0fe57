"""Measure live playback's timing on a real device chain: ``python scripts/live_timing.py [--runs N]``.

Plays the demo scene for ``--duration`` simulated seconds without the viewer
(tests/live_audio.py) into a private PulseAudio null sink through an ALSA file tap
(:class:`mjsound.live_tap.PulseTap`), ``--runs`` times, the last run with the simulation
stalled for ``--stall`` s at 1 s, and prints one Markdown row per run (docs/live.md quotes
them):

- ``exact``: the played samples equal the simulated ones, every one (before and after the gap);
- ``onsets``: each impact's onset (first sample above -40 dBFS after 20 ms of quiet) found in
  the recording at its simulated sample plus one constant offset: the spread of
  (played frame - simulated frame) over the onsets, in frames (0: none early, none late);
- ``heard after``: PortAudio's DAC time of each onset minus the wall time its block was
  simulated (``time.monotonic``), median and max [ms];
- ``clock``: the slope of DAC time against simulated time (1: paced to the wall clock);
- ``gaps``: the player's underflows (gaps), their length, and PortAudio's own underflow flags.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from mjsound.live_tap import PulseTap, align, read_tap  # noqa: E402

FS = 48000


def onsets(x: np.ndarray, level: float = 0.01, quiet_s: float = 0.02) -> np.ndarray:
    """Frames where ``|x|`` (max over channels) first exceeds ``level`` after ``quiet_s`` below it."""
    loud = np.flatnonzero(np.abs(x).max(axis=1) > level)
    if not len(loud):
        return loud
    keep = np.concatenate([[True], np.diff(loud) > quiet_s * FS])
    return loud[keep]


def measure(tap, out, duration, lead, latency, stall_at, stall_s) -> dict:
    r = subprocess.run([sys.executable, os.path.join(ROOT, "tests", "live_audio.py"), "view", os.path.join(ROOT, "assets", "demo_scene.xml"),
                        out, "livetap", str(duration), str(lead), str(latency), str(stall_at), str(stall_s)],
                       env=tap.env, capture_output=True, text=True, timeout=600)
    if r.returncode:
        raise SystemExit(r.stderr[-3000:])
    z = np.load(out)
    played, _ = read_tap(tap.wav)
    sent = np.clip(z["sent"], -1.0, 1.0)
    stats = json.loads(str(z["stats"]))
    first, n, dac, _ = z["callbacks"].T
    wall, pushed = z["pushes"].T
    gaps = stats["gaps"]
    edges = [0] + [s for s, _ in gaps] + [len(sent)]
    exact, offsets = True, np.zeros(len(sent), np.int64)
    for a, b in zip(edges[:-1], edges[1:]):  # the stretches between gaps, each at its own offset
        k, _ = align(played, sent[a:b])
        fade = 0 if a == 0 else int(0.002 * FS)
        exact &= bool(np.array_equal(played[k + fade:k + b - a], sent[a + fade:b]))
        offsets[a:b] = k - a
    on = onsets(sent)
    shift = offsets[on] - np.array([sum(g for s, g in gaps if s <= o) for o in on])
    play = n > 0
    heard = np.interp(on, first[play], dac[play]) + (on - np.interp(on, first[play], first[play])) / FS
    made = wall[np.searchsorted(pushed, on, side="right")]
    after = heard - made
    m = play & (first < (gaps[0][0] if gaps else len(sent)))
    slope = np.polyfit(first[m] / FS, dac[m], 1)[0]
    return dict(exact=exact, n_onsets=len(on), spread=int(shift.max() - shift.min()) if len(on) else 0,
                after_med=1000 * np.median(after), after_max=1000 * after.max(), slope=slope,
                underflows=stats["underflows"], gaps_at=" ".join(f"{s / FS:.2f}" for s, _ in gaps), behind_ms=1000 * stats["behind_s"],
                pa_underflows=stats["portaudio_underflows"], latency_ms=1000 * stats["latency_s"], lead=lead,
                stall=stall_s if stall_at else 0.0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=3, help="runs (the last one stalled; default 3)")
    ap.add_argument("--duration", type=float, default=4.0, help="simulated seconds per run (default 4)")
    ap.add_argument("--lead", type=float, default=0.05, help="the player's lead [s] (default 0.05)")
    ap.add_argument("--device-latency", type=float, default=0.0, help="latency asked of the device [s] (0: PortAudio's)")
    ap.add_argument("--stall", type=float, default=0.3, help="the last run's stall [s] (default 0.3)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        tap = PulseTap(d).start()
        try:
            print("| run | lead ms | stall ms | exact | onsets | onset spread (frames) | heard after, median / max ms "
                  "| clock slope | gaps (ms behind; at s) | PortAudio underflow flags | stream latency ms |")
            print("|---|---|---|---|---|---|---|---|---|---|---|")
            for i in range(args.runs):
                stalled = i == args.runs - 1
                m = measure(tap, os.path.join(d, f"run{i}.npz"), args.duration, args.lead, args.device_latency,
                            1.0 if stalled else 0,
                            args.stall)
                print(f"| {i + 1} | {1000 * m['lead']:.0f} | {1000 * m['stall']:.0f} | {'yes' if m['exact'] else 'NO'} "
                      f"| {m['n_onsets']} | {m['spread']} | {m['after_med']:.0f} / {m['after_max']:.0f} | {m['slope']:.4f} "
                      f"| {m['underflows']} ({m['behind_ms']:.0f}; {m['gaps_at'] or '-'}) | {m['pa_underflows']} | {m['latency_ms']:.0f} |",
                      flush=True)
        finally:
            tap.stop()


if __name__ == "__main__":
    main()
