"""Benchmark: the per-mode radiation's cost against the modal analysis's own, at f_max 20 kHz.

For each object it analyses three times in one process (``cache=False``, otherwise
``analyze``'s defaults, its frequency error estimate included; ``--no-error-estimate`` leaves
that out): ``radiation=False`` (the analysis alone, with the compact estimate), the ``default`` setting
and ``"draft"`` (what scenes use), and prints the CPU seconds of the analysis without
radiation and of each radiation solve (``model.info["radiation"]["cpu_seconds"]``: both
threads of the parallel assembly counted), its ratio to the analysis, the number of solves
(of them budget-limited clusters), the levels' element counts and the largest error estimate.
CPU seconds are less sensitive than wall seconds to the other load on a shared machine;
``--repeat N`` takes each figure's smallest of N runs, and the load average is printed with the
table. The goal (issue 35): the default's radiation at most the analysis's own time, and at
most 10 s per object.

    nice python scripts/bench_radiation.py --repeat 3      # table (markdown)
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


def measure(name, settings=("default", "draft"), f_max=20000.0, error_estimate=True, repeat=1):
    """One object's row: analysis CPU without radiation, and per setting its radiation's (each
    the smallest of ``repeat`` runs)."""
    import mjsound

    mesh, material = OBJECTS[name]
    mesh = _mesh(mesh)
    if mesh is None:
        return None
    kw = dict(cache=False, error_estimate=error_estimate, progress=False, f_max=f_max)
    cpu, wall = [], []
    for _ in range(repeat):
        c0, t0 = time.process_time(), time.perf_counter()
        m = mjsound.analyze(mesh, material, radiation=False, **kw)
        cpu.append(time.process_time() - c0)
        wall.append(time.perf_counter() - t0)
    row = dict(name=name, modes=int(m.n_modes), analysis_cpu=min(cpu), analysis_wall=min(wall), settings={})
    for s in settings:
        runs = [mjsound.analyze(mesh, material, radiation=s, **kw).info["radiation"] for _ in range(repeat)]
        r = runs[0]
        est = [e for e in r["error_db"] if e is not None]
        row["settings"][s] = dict(cpu=min(x["cpu_seconds"] for x in runs), wall=min(x["seconds"] for x in runs),
                                  solves=r["solves"], limited=r["budget_limited_clusters"], levels=r["levels"],
                                  max_error_db=max(est) if est else None, capped=r.get("capped"))
    return row


def table(rows) -> str:
    settings = list(rows[0]["settings"]) if rows else []
    head = "| object | modes | analysis without radiation, CPU / wall [s] | " + " | ".join(
        f"radiation `{s}`: CPU / wall [s] (CPU x analysis), solves (budget-limited clusters), levels, "
        "largest estimate [dB], capped modes" for s in settings) + " |"
    out = [head, "|" + "---|" * (3 + len(settings))]
    for r in rows:
        cells = []
        for s in settings:
            v = r["settings"][s]
            cells.append(f"{v['cpu']:.2f} / {v['wall']:.2f} ({v['cpu'] / r['analysis_cpu']:.2f}x), {v['solves']} "
                         f"({v['limited']}), {v['levels']}, {v['max_error_db']:.1f}, {v['capped']}")
        out.append(f"| {r['name']} | {r['modes']} | {r['analysis_cpu']:.2f} / {r['analysis_wall']:.2f} | "
                   + " | ".join(cells) + " |")
    return "\n".join(out)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--objects", nargs="+", default=list(OBJECTS), choices=list(OBJECTS))
    ap.add_argument("--settings", nargs="+", default=["default", "draft"])
    ap.add_argument("--f-max", type=float, default=20000.0)
    ap.add_argument("--no-error-estimate", action="store_true")
    ap.add_argument("--repeat", type=int, default=1, help="runs per figure, the smallest kept")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    load = os.getloadavg()
    rows = [r for r in (measure(n, a.settings, a.f_max, not a.no_error_estimate, a.repeat) for n in a.objects)
            if r is not None]
    load = [max(x, y) for x, y in zip(load, os.getloadavg())]
    if a.json:
        print(json.dumps(dict(rows=rows, load_average=load), indent=1))
    else:
        print(table(rows))
        print(f"\n(load average, the larger of before and after: {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}; "
              f"{os.cpu_count()} CPUs; smallest of {a.repeat} runs)")


if __name__ == "__main__":
    main()
