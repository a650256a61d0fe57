#!/usr/bin/env python
"""Vibration energy one impact puts into an object's modes, against the energy the impact has (diagnostic).

An object of mass ``m`` dropped flat-out onto a rigid floor at ``v`` [m/s] (restitution
``e`` of its material) takes the impulse ``J = m v (1 + e)`` at its lowest surface sample; the
collision dissipates ``E_lost = m v^2 (1 - e^2) / 2``. mjsound excites mode ``i`` (mass-
normalised shape ``phi_i``) with the modal velocity ``phi_i(x) . J S(w_i tau)`` (``S`` the
half-sine pulse spectrum of the Hertz contact time ``tau``), so the vibration energy is
``E_modes = sum_i |phi_i(x) . J S(w_i tau)|^2 / 2``. Physically ``E_modes`` is a small part of
``E_lost`` (a few per cent for hard solids); a ratio ``E_modes / E_lost`` above one means the
model gives the impact more vibration than it has energy, and the object sounds too loud by
about the square root of that ratio.

Usage: python scripts/impact_energy.py [--speed 2.0] [--quality default]
"""

from __future__ import annotations

import argparse

import numpy as np

from mjsound import analyze
from mjsound.materials import parse_material
from mjsound.synth.pulse import half_sine_spectrum, hertz_contact_time

#: (label, mesh spec, material)
OBJECTS = [
    ("steel plate 30x30x0.6 cm", "box:0.3,0.3,0.006", "steel"),
    ("aluminium beam 50 cm", "box:0.5,0.01,0.01", "aluminium"),
    ("ceramic bowl 20 cm, 4 mm", "bowl:0.1,0.004", "ceramic"),
    ("aluminium can 5 cm, 1 mm wall", "cylinder:0.025,0.08", "aluminium,wall=1mm"),
    ("aluminium can 5 cm, 0.3 mm wall", "cylinder:0.025,0.08", "aluminium,wall=0.3mm"),
]


def impact_energy(spec, material, speed, quality):
    mat = parse_material(material)
    mm = analyze(spec, mat, quality=quality, sample_rate=48000, progress=False)
    m = float(mm.mass_kg)
    e = float(mat.restitution)
    i = int(np.argmin(mm.points[:, 2]))
    J = m * speed * (1.0 + e)
    R = 0.5 * float(np.max(np.ptp(mm.points, axis=0)))  # (a blunt contact: half the object's size)
    tau = hertz_contact_time(m, np.inf, R, np.inf, mat, parse_material("concrete"), speed)
    g = mm.gains(mm.points[i][None], np.array([[0.0, 0.0, J]]))[0]
    S = np.abs(half_sine_spectrum(2 * np.pi * mm.frequencies_hz, tau))
    e_modes = 0.5 * float(np.sum((g * S) ** 2))
    e_lost = 0.5 * m * speed**2 * (1.0 - e * e)
    return mm, m, tau, e_modes, e_lost


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--speed", type=float, default=2.0, help="drop speed [m/s]")
    p.add_argument("--quality", default="default")
    args = p.parse_args(argv)
    print("| object | method | mass [g] | modes | tau [us] | E_modes [mJ] | E_lost [mJ] | ratio |")
    print("|---|---|---:|---:|---:|---:|---:|---:|")
    for label, spec, material in OBJECTS:
        mm, m, tau, e_modes, e_lost = impact_energy(spec, material, args.speed, args.quality)
        print(f"| {label} | {mm.method} | {1e3 * m:.1f} | {mm.n_modes} | {1e6 * tau:.0f} | {1e3 * e_modes:.3g} | "
              f"{1e3 * e_lost:.3g} | {e_modes / e_lost:.3g} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
