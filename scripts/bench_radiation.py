"""Benchmark: the per-mode radiation's cost against the modal analysis's own, at f_max 20 kHz.

For each object it analyses three times in one process (``cache=False``, otherwise
``analyze``'s defaults, its frequency error estimate included; ``--no-error-estimate`` leaves
that out): ``radiation=False`` (the analysis alone, with the compact estimate), the ``default`` setting
and ``"draft"`` (what scenes use), and prints the CPU seconds of the analysis without
radiation and of each radiation solve (``model.info["radiation"]["cpu_seconds"]``: both
threads of the parallel assembly counted), its ratio to the analysis, the number of solves
(of them budget-limited clusters), the levels' element counts and the largest error estimate.
CPU seconds are less sensitive than wall seconds to the other load on a shared machine.
The goal (issue 35): the default's radiation at most the analysis's own time, and at most
10 s per object.

    python scripts/bench_radiation.py                 # table (markdown)
    python scripts/bench_radiation.py --json
    python scripts/bench_radiation.py --objects bowl --settings default

The third object is robosuite's ``milk.stl`` (polycarbonate) when robosuite is installed.
"""

from __future__ import annotations

import argparse
import json
import os
import time

OBJECTS = {
    "bowl": ("bowl:0.1,0.004", "aluminium"),
    "plate": ("box:0.2,0.2,0.002", "aluminium"),
    "milk": ("robosuite:models/assets/objects/meshes/milk.stl", "polycarbonate"),
}


def _mesh(spec):
    if not spec.startswith("robosuite:"):
        return spec
    try:
        import robosuite
    except ImportError:
        return None
    return os.path.join(os.path.dirname(robosuite.__file__), spec.split(":", 1)[1])


def measure(name, settings=("default", "draft"), f_max=20000.0, error_estimate=True):
    """One object's row: analysis CPU without radiation, and per setting its radiation's."""
    import mjsound

    mesh, material = OBJECTS[name]
    mesh = _mesh(mesh)
    if mesh is None:
        return None
    kw = dict(cache=False, error_estimate=error_estimate, progress=False, f_max=f_max)
    c0 = time.process_time()
    m = mjsound.analyze(mesh, material, radiation=False, **kw)
    row = dict(name=name, modes=int(m.n_modes), analysis_cpu=time.process_time() - c0, settings={})
    for s in settings:
        m = mjsound.analyze(mesh, material, radiation=s, **kw)
        r = m.info["radiation"]
        est = [e for e in r["error_db"] if e is not None]
        row["settings"][s] = dict(cpu=r["cpu_seconds"], wall=r["seconds"], solves=r["solves"],
                                  limited=r["budget_limited_clusters"], levels=r["levels"],
                                  max_error_db=max(est) if est else None)
    return row


def table(rows) -> str:
    settings = list(rows[0]["settings"]) if rows else []
    head = "| object | modes | analysis without radiation, CPU [s] | " + " | ".join(
        f"radiation `{s}`: CPU [s] (x analysis), solves (budget-limited), levels, largest estimate [dB]"
        for s in settings) + " |"
    out = [head, "|" + "---|" * (3 + len(settings))]
    for r in rows:
        cells = []
        for s in settings:
            v = r["settings"][s]
            cells.append(f"{v['cpu']:.1f} ({v['cpu'] / r['analysis_cpu']:.1f}x), {v['solves']} ({v['limited']}), "
                         f"{v['levels']}, {v['max_error_db']:.1f}")
        out.append(f"| {r['name']} | {r['modes']} | {r['analysis_cpu']:.1f} | " + " | ".join(cells) + " |")
    return "\n".join(out)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--objects", nargs="+", default=list(OBJECTS), choices=list(OBJECTS))
    ap.add_argument("--settings", nargs="+", default=["default", "draft"])
    ap.add_argument("--f-max", type=float, default=20000.0)
    ap.add_argument("--no-error-estimate", action="store_true")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    rows = [r for r in (measure(n, a.settings, a.f_max, not a.no_error_estimate) for n in a.objects) if r is not None]
    print(json.dumps(rows, indent=1) if a.json else table(rows))


if __name__ == "__main__":
    main()
