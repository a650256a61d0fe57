"""``python tests/live_audio.py SCENE OUT.npz DEVICE DURATION LEAD DEVICE_LATENCY STALL_AT STALL_S``: the
live player's side of tests/test_live.py and scripts/live_timing.py, run in a process of its
own (the tap's variables must be set before sounddevice is imported:
:class:`mjsound.live_tap.PulseTap`)."""

from __future__ import annotations

import time

import numpy as np


def _play_main(argv) -> None:
    """``python tests/live_audio.py SCENE OUT.npz DEVICE DURATION LEAD DEVICE_LATENCY STALL_AT STALL_S``:
    :func:`mjsound.live_view.view` without the viewer, keeping every block it sent; the
    simulation stalls once for ``STALL_S`` seconds of wall time after ``STALL_AT`` seconds
    of audio (0: never), as a slow simulation would. Writes what was sent, the player's
    statistics and timing logs, and the log lines to ``OUT.npz``."""
    import json
    import logging

    from mjsound.live_view import view

    scene, out, device, duration, lead, latency, stall_at, stall_s = argv
    records = []
    logging.basicConfig(level=logging.WARNING, handlers=[_Keep(records)])
    sent, taken = [], [0]

    def keep(frames):
        sent.append(frames.copy())
        taken[0] += frames.shape[1]
        if float(stall_at) > 0 and taken[0] - frames.shape[1] < float(stall_at) * 48000 <= taken[0]:  # (view: 48 kHz)
            time.sleep(float(stall_s))

    timing = {}
    stats = view(scene, duration=float(duration), device=device, viewer=False, lead_s=float(lead),
                 device_latency_s=float(latency) if float(latency) > 0 else None, progress=False,
                 on_block=keep, on_timing=timing.update)
    np.savez(out, sent=np.concatenate(sent, axis=1).T, stats=json.dumps(stats), log=json.dumps(records),
             callbacks=timing["callbacks"], pushes=timing["pushes"])


class _Keep(__import__("logging").Handler):
    def __init__(self, records):
        super().__init__()
        self.records = records

    def emit(self, record):
        self.records.append([record.name, record.getMessage()])


if __name__ == "__main__":
    import sys

    _play_main(sys.argv[1:])
