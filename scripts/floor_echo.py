#!/usr/bin/env python
"""What the floor does to a drop (figures for docs/rooms.md; not a test).

A 20 mm steel ball (33 g) dropped 10 cm on a floor plane, microphone 1 m above it, 48 kHz:
the peak pressure [Pa] at the microphone in free field, above a rigid floor, the default
(concrete) floor, a carpeted floor, and in a 4 x 4 x 2.5 m plastered room (first and second
order images). Then the demo scene's air channels, free field against its concrete floor.

Usage: python scripts/floor_echo.py [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import warnings

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from mjsound.sim import AudioSimulator  # noqa: E402
from mjsound.sim.demo import find_demo_scene  # noqa: E402
from mjsound.sim.rooms import Room  # noqa: E402

BALL_XML = """<mujoco><option timestep="0.001"/>
<custom><text name="mjsound:ball" data="steel"/></custom>
<worldbody>
  <geom name="floor" type="plane" size="2 2 0.1"/>
  <site name="mic0" pos="0 0 1.01"/>
  <body name="ball" pos="0 0 0.11"><freejoint/><geom name="ball" type="sphere" size="0.01" density="7850"/></body>
</worldbody></mujoco>"""


def ball(reflections=True, room=None) -> float:
    m = mujoco.MjModel.from_xml_string(BALL_XML)
    d = mujoco.MjData(m)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # (the ball has no audible modes: it is heard by its click)
        sim = AudioSimulator(m, d, sample_rate=48000, quality="draft", progress=False, reflections=reflections,
                             room=room)
    return float(np.abs(sim.run(0.2)[0]).max())


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--json", action="store_true")
    args = p.parse_args(argv)
    out = {
        "ball_free_pa": ball(False),
        "ball_rigid_floor_pa": ball({"floor": "rigid"}),
        "ball_concrete_floor_pa": ball(True),
        "ball_carpet_floor_pa": ball({"floor": "carpet"}),
    }
    for order in (1, 2):
        out[f"ball_room_order{order}_pa"] = ball(room=Room((-2, -2, 0), (2, 2, 2.5), walls="plaster", order=order))
    path = find_demo_scene()
    for refl in (False, True):
        m = mujoco.MjModel.from_xml_path(path)
        d = mujoco.MjData(m)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            sim = AudioSimulator(m, d, progress=False, reflections=refl)
        a = sim.run(3.0)[: sim.n_air].astype(np.float64)
        key = "demo_floor" if refl else "demo_free"
        out[key + "_rms_pa"] = float(np.sqrt(np.mean(a**2)))
        out[key + "_peak_pa"] = float(np.abs(a).max())
    if args.json:
        print(json.dumps(out))
    else:
        for k, v in out.items():
            print(f"{k:28s} {v:.4g}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
