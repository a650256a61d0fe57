r"""Levels: each mode's radiated power and pattern against a converged reference, against run time.

For the four objects of :data:`mjsound.modal.radiation_check.LEVEL_OBJECTS` (aluminium plate
0.2 x 0.2 x 0.002 m, aluminium bar 0.3 x 0.02 x 0.02 m, ceramic bowl 10 cm, steel can with a
2 mm wall) the modal analysis runs with each radiation setting (``radiation=False``: the old
compact monopole + dipole estimate; ``draft``, ``default``, ``high``: the boundary elements of
:mod:`mjsound.modal.radiation`) and each mode's far field is compared with the stored reference
(``tests/data/radiation_<name>.npz``, ``scripts/reference_radiation.py``: the same solver on
3000 elements, one factorisation per mode):

* power error ``10 log10(W / W_ref)`` [dB] per degenerate group (pairs summed);
* direction error: the largest ``|10 log10(sum |F|^2 / sum |F_ref|^2)|`` over the directions
  where the reference is within 20 dB of its maximum (not defined for the compact estimate,
  which has no pattern beyond its dipole);
* the reference's own step from 1500 to 3000 elements (a group whose step exceeds 1 dB has not
  converged: its row is marked);
* the analysis's wall time and the radiation's share of it (CPU seconds of the solve).

``mjsound report accuracy --sections levels`` runs only this and rewrites only this section of
an existing ``accuracy.md`` (between its ``<!-- levels -->`` markers).
"""

from __future__ import annotations

import os
import time

import numpy as np

__all__ = ["run_levels", "levels_section", "splice_levels", "SETTINGS"]

#: radiation settings compared (label -> analyze's ``radiation=``)
SETTINGS = {"compact": False, "draft": "draft", "default": "default", "high": "high"}
BEGIN, END = "<!-- levels -->", "<!-- /levels -->"


def _data_dir():
    here = os.path.dirname(os.path.abspath(__file__))
    return os.path.join(os.path.dirname(os.path.dirname(here)), "tests", "data")


def run_levels(quick: bool = False, log=print) -> list:
    """Measure every object at every setting (``quick``: compact and default only).

    Returns a list of dicts (JSON-able), one per object."""
    from ..modal.analyze import analyze
    from ..modal.radiation_check import LEVEL_OBJECTS, REFERENCE_DEGREE, degenerate_groups, pattern_errors
    from ..modal.sph import sphere_quadrature

    dirs, w = sphere_quadrature(REFERENCE_DEGREE)
    out = []
    for name, (mesh, material, kw) in LEVEL_OBJECTS.items():
        path = os.path.join(_data_dir(), f"radiation_{name}.npz")
        if not os.path.exists(path):
            log(f"levels: {path} missing (scripts/reference_radiation.py); {name} skipped")
            continue
        z = np.load(path)
        groups = degenerate_groups(z["frequencies_hz"])
        first = np.r_[0, np.flatnonzero(np.diff(groups)) + 1]
        ref_step, _ = pattern_errors(z["check_far_field"], z["far_field"], w, groups)
        ref_power = np.array([w @ (np.abs(z["far_field"][:, groups == g]) ** 2).sum(axis=1)
                              for g in range(groups.max() + 1)])
        row = dict(name=name, mesh=mesh, material=material, options={k: v for k, v in kw.items()},
                   frequencies_hz=z["frequencies_hz"][first].round(1).tolist(),
                   reference_db=(10 * np.log10(ref_power / ref_power.max())).round(1).tolist(),
                   reference_step_db=ref_step.round(2).tolist(), settings={})
        for label, setting in SETTINGS.items():
            if quick and label in ("draft", "high"):
                continue
            t0, c0 = time.perf_counter(), time.process_time()
            m = analyze(mesh, material, cache=False, error_estimate=False, radiation=setting, **kw)
            wall, cpu = time.perf_counter() - t0, time.process_time() - c0
            if not np.allclose(m.frequencies_hz, z["frequencies_hz"], rtol=1e-6):
                log(f"levels: {name}'s modes differ from the reference's; regenerate it")
                break
            ri = m.info["radiation"]
            F = m.radiation_pattern(dirs)
            power, direction = pattern_errors(F, z["far_field"], w, groups)
            est = [None if e is None else e for e in ri.get("error_db", [None] * m.n_modes)]
            row["settings"][label] = dict(
                power_db=power.round(2).tolist(),
                direction_db=None if setting is False else direction.round(2).tolist(),
                estimate_db=[None if all(est[i] is None for i in np.flatnonzero(groups == g))
                             else round(max(est[i] or 0.0 for i in np.flatnonzero(groups == g)), 2)
                             for g in range(groups.max() + 1)],
                seconds=round(wall, 2), cpu_s=round(cpu, 2), radiation_cpu_s=round(ri.get("cpu_seconds", 0.0), 2),
                radiation_s=round(ri.get("seconds", 0.0), 2), solves=ri.get("solves"), levels=ri.get("levels"))
            log(f"levels: {name} {label}: power error {np.round(power, 1)} dB, {wall:.1f} s "
                f"(radiation {ri.get('seconds', 0.0):.1f} s)")
        out.append(row)
    return out


def levels_section(levels, command="mjsound report accuracy --sections levels") -> list:
    """Markdown lines of the levels section, between its markers."""
    L = [BEGIN, "## Levels: each mode's radiation against a converged reference, against run time", ""]
    w = L.append
    w(f"Generated by `{command}` ({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}). Error of each "
      "mode's radiated power (degenerate pairs summed) against the converged boundary-element reference "
      "(`tests/data/radiation_*.npz`, `scripts/reference_radiation.py`: 3000 elements, one factorisation "
      "per mode), and in brackets the largest error over the directions where the reference is within "
      "20 dB of its maximum. *compact* is the monopole + dipole estimate mjsound used before "
      "(`radiation=False`); *est* is the default setting's own error estimate (its last refinement "
      "step, combined with the wavenumber shift of a widened cluster, and at least what a mode capped "
      "at radiation efficiency 1 was over). Rows marked ~ are modes whose reference itself moved by more than 1 dB from 1500 to 3000 "
      "elements (thin edges converge slowly): their errors are not meaningful. On these small "
      "objects *high* can reach the reference's own finest mesh (the bowl and the can do): an error near "
      "0.0 dB there says only that. "
      "Times: wall and CPU seconds of the whole analysis (CPU counts every thread; the machine is "
      "shared, so wall times carry the load), and the radiation solve's CPU seconds (on one thread). Method and formulas: `docs/radiation.md`.")
    w("")
    for row in levels:
        labels = list(row["settings"])
        w(f"### {row['name']}: `{row['mesh']}` {row['material']} {row['options']}")
        w("")
        w("| f [Hz] | ref [dB re max] | ref step [dB] | " + " | ".join(f"{lb} [dB]" for lb in labels)
          + " | est [dB] |")
        w("|---" * (4 + len(labels)) + "|")
        for g, f in enumerate(row["frequencies_hz"]):
            mark = "~" if abs(row["reference_step_db"][g]) > 1.0 else ""
            cells = []
            for lb in labels:
                s = row["settings"][lb]
                c = f"{s['power_db'][g]:+.1f}"
                if s["direction_db"] is not None:
                    c += f" ({s['direction_db'][g]:.1f})"
                cells.append(c)
            est = row["settings"].get("default", {}).get("estimate_db", [None] * len(row["frequencies_hz"]))[g]
            w(f"| {mark}{f:.0f} | {row['reference_db'][g]:.1f} | {row['reference_step_db'][g]:+.2f} | "
              + " | ".join(cells) + f" | {'' if est is None else f'{est:.1f}'} |")
        w("| **analysis wall / CPU [s] (radiation CPU [s])** | | | " + " | ".join(
            f"{row['settings'][lb]['seconds']:.1f} / {row['settings'][lb].get('cpu_s', float('nan')):.1f} "
            f"({row['settings'][lb]['radiation_cpu_s']:.1f})" for lb in labels) + " | |")
        w("")
        conv = [g for g in range(len(row["frequencies_hz"])) if abs(row["reference_step_db"][g]) <= 1.0]
        for lb in labels:
            p = np.abs(np.array(row["settings"][lb]["power_db"])[conv]) if conv else np.zeros(0)
            if len(p):
                w(f"* {lb}: converged modes' power error RMS {np.sqrt(np.mean(p ** 2)):.1f} dB, largest {p.max():.1f} dB")
        w("")
    w(END)
    return L


def splice_levels(path, lines) -> None:
    """Put the levels section into the page at ``path``: replacing the one between the markers,
    or appended when there is none (a page written without it)."""
    from ..io import atomic_open

    text = open(path).read() if os.path.exists(path) else ""
    block = "\n".join(lines)
    if BEGIN in text and END in text:
        a = text.index(BEGIN)
        b = text.index(END) + len(END)
        text = text[:a] + block + text[b:]
    else:
        text = text.rstrip("\n") + ("\n\n" if text else "") + block + "\n"
    with atomic_open(path) as fh:
        fh.write(text)
