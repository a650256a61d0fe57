#!/usr/bin/env python
"""The lines' rendering of actuator noise against the exact one (the drive forces through the
links' modes, ``sim.actuators.rendering = "modal"``), on the driven arm of
``tests/test_actuators.py`` (1 ms steps, 16 kHz, an air and a contact microphone on the link):
per preset and speed profile (held at 2 rad/s; a ramp 1 -> 2 rad/s), the RMS of each
rendering at both microphones after the first 0.25 s, and the RMS of their difference
relative to the exact one (the lines leave out the modes' ringing, and draw their own
broadband noise: docs/actuators.md).

    python scripts/compare_actuator_rendering.py
"""

import json
import os
import sys
from dataclasses import replace

import mujoco
import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests"))
from test_actuators import FS, ONE_TONE, arm_xml  # noqa: E402

from mjsound.sim.actuators import PRESETS  # noqa: E402
from mjsound.sim.simulator import AudioSimulator  # noqa: E402


def render(preset, ctrl, rendering, steps=1000):
    m = mujoco.MjModel.from_xml_string(arm_xml())
    d = mujoco.MjData(m)
    sim = AudioSimulator(m, d, microphones=[[0.5, 0.5, 0.8]], contact_mics=["s_link", "s_far"], progress=False,
                         sample_rate=FS, quality="draft", actuators={"m": preset})
    sim.actuators.rendering = rendering
    out = []
    for i in range(steps):
        d.ctrl[0] = ctrl(i)
        mujoco.mj_step(m, d)
        out.append(sim.step())
    return np.concatenate(out, axis=1).astype(np.float64)[:, FS // 4:]


def main():
    presets = {"one tone": ONE_TONE, "qdd": PRESETS["qdd"], "servo": PRESETS["servo"],
               "servo tones only": replace(PRESETS["servo"], broadband=0.0)}
    speeds = {"held": lambda i: 2.0, "ramp": lambda i: 1.0 + i / 1000}
    rms = lambda x: float(np.sqrt(np.mean(x ** 2)))  # noqa: E731
    for name, preset in presets.items():
        for sname, ctrl in speeds.items():
            exact, lines = render(preset, ctrl, "modal"), render(preset, ctrl, "lines")
            row = {"preset": name, "speed": sname}
            for ch, mic in ((0, "air"), (1, "contact")):
                row[mic] = {"exact_rms": rms(exact[ch]), "lines_rms": rms(lines[ch]),
                            "difference": rms(exact[ch] - lines[ch]) / rms(exact[ch])}
            print(json.dumps(row))


if __name__ == "__main__":
    main()
