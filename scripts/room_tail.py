#!/usr/bin/env python
"""A room's late tail measured (docs/rooms.md): the decay per octave band and the late energy.

A bar of 600 modes (88 Hz .. 5.7 kHz, each decaying at 150 /s: a short broadband source) is
struck in a 5 x 4 x 3 m room (window-glass walls and ceiling, a carpet floor; images to order
2 and the late tail), microphone 1 m away, float64 at 16 kHz. Per octave band: T20 and T30 of
the rendered response (Schroeder's backward integral, ISO 3382's ranges) against Eyring's and
Sabine's times, and the energy after 80 ms against the statistical late energy
``E_1 4 pi c / V int exp(-t / tau) dt`` (E_1: the direct sound's energy at 1 m, from a
free-field run), and the whole reverberant energy (all but the direct sound) over E_1 against
``16 pi / R``, R = S alpha / (1 - alpha) the room constant. The same checks run in
``tests/test_room_tail.py``.

Usage: python scripts/room_tail.py [--order 2] [--rt60 SECONDS | --walls "walls=plywood, floor=carpet"]
"""

from __future__ import annotations

import argparse
import math
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

FS = 16000
TE = 0.0051


def main(argv=None) -> int:
    import mujoco
    import numpy as np
    from scipy import signal

    from mjsound import ModalModel, get_material
    from mjsound.sim import AudioSimulator
    from mjsound.sim.room_tail import late_energy_rate
    from mjsound.sim.rooms import Room
    from mjsound.sim.scene import SoundScene

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--order", type=int, default=2)
    p.add_argument("--rt60", type=float, default=None, help="a uniform room of this Eyring time instead")
    p.add_argument("--walls", default="walls=window, floor=carpet",
                   help="the walls' surfaces (default: %(default)s)")
    args = p.parse_args(argv)
    src, mic = np.array([2.2, 1.7, 1.3]), np.array([3.1, 2.1, 1.55])
    xml = f"""<mujoco><option timestep="0.001"/><worldbody>
      <geom name="bar" type="box" size="0.02 0.02 0.02" pos="{src[0]} {src[1]} {src[2]}"/>
      <site name="mic0" pos="{mic[0]} {mic[1]} {mic[2]}"/></worldbody></mujoco>"""
    n = 600
    freqs = np.geomspace(88.0, 5700.0, n) * np.random.default_rng(0).uniform(0.99, 1.01, n)
    bar = ModalModel(freqs, np.full(n, 150.0), [[0, 0, 0]], [[0, 0, 1]], np.ones((1, 3, n)), np.ones(n),
                     get_material("steel"), mass_kg=0.5)

    def struck(room, reflections=True):
        model = mujoco.MjModel.from_xml_string(xml)
        scene = SoundScene.from_model(model, materials={"bar": "steel"}, models={"bar": bar}, sample_rate=FS,
                                      progress=False)
        sim = AudioSimulator(model, mujoco.MjData(model), scene=scene, sample_rate=FS, room=room,
                             reflections=reflections, clicks=False, synth_kwargs={"dtype": "float64", "cull_db": None})
        sim.synth.impact("bar", src, [0, 0, 1e-3], TE, pulse_s=0.0)
        return sim.run(1.5)[0].astype(np.float64)

    walls = dict(kv.strip().split("=") for kv in args.walls.split(","))
    room = Room((0, 0, 0), (5, 4, 3), order=args.order, **({"rt60": args.rt60} if args.rt60 else {"walls": walls}))
    p_room, p_free = struck(room), struck(None, reflections=False)
    eyring = room.rt60("eyring") if args.rt60 is None else np.full(6, args.rt60)
    sabine = room.rt60("sabine")
    r = float(np.linalg.norm(mic - src))
    t = np.arange(p_room.size) / FS - TE
    S = float(room.areas.sum())
    alpha = (room.areas @ np.array([s.absorption for s in room.surfaces])) / S
    R = S * alpha / (1 - alpha)
    print(f"{room!r}\n| band [Hz] | T20 [s] | T30 [s] | Eyring [s] | Sabine [s] | late energy against statistical "
          "[dB] | reverberant / direct at 1 m against 16 pi / R [dB] |")
    print("|---|---|---|---|---|---|---|")
    for k, band in enumerate((125, 250, 500, 1000, 2000, 4000)):
        sos = signal.butter(4, [band / math.sqrt(2), min(band * math.sqrt(2), 0.49 * FS)], "bandpass", fs=FS,
                            output="sos")
        e = signal.sosfiltfilt(sos, p_room) ** 2
        edc = np.cumsum(e[::-1])[::-1]
        level = 10 * np.log10(edc / edc[0])
        tt = np.arange(e.size) / FS

        def decay(lo, hi):
            a, b = np.argmax(level < lo), np.argmax(level < hi)
            return -60.0 / np.polyfit(tt[a:b], level[a:b], 1)[0]

        e_direct = (signal.sosfiltfilt(sos, p_free) ** 2).sum()
        e1 = e_direct * r * r
        tau = eyring[k] / (6 * math.log(10))
        want = e1 * late_energy_rate(room) * tau * math.exp(-0.08 / tau)
        print(f"| {band} | {decay(-5, -25):.3f} | {decay(-5, -35):.3f} | {eyring[k]:.3f} | {sabine[k]:.3f} | "
              f"{10 * math.log10(e[t > 0.08].sum() / want):+.2f} | "
              f"{10 * math.log10((e.sum() - e_direct) / e1 / (16 * math.pi / R[k])):+.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
