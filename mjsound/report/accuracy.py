r"""Accuracy against run time: modal analysis, synthesis and end to end, all measured.

``mjsound report accuracy [--quick] [-o DIR]`` (or ``python scripts/report_accuracy.py``)
runs every measurement below and writes ``DIR/accuracy.md`` with PNG plots.

Modal analysis
--------------
Frequency error in cents, ``1200 log2(f / f_ref)``, of the first modes of

* the aluminium beam 0.5 m x 10 mm x 10 mm, free-free: bending pairs against the converged 3D
  values of ``docs/design.md`` ("Reference values") (209.06, 574.7, 1122.3, 1845.7 Hz) and the longitudinal mode
  (5091.6 Hz, Rayleigh-Love);
* the aluminium rod r = 10 mm, L = 0.5 m: torsion, exact in 3D, ``f_n = n c_s / (2 L)``
  (3122.0, 6243.9, 9365.9 Hz);
* a free solid aluminium sphere of radius 0.1 m (Lamb 1882): the lowest torsional
  (toroidal) multiplet 0T2 and spheroidal multiplet 0S2, from the exact frequency equations
  (:func:`lamb_sphere`);
* the aluminium bowl ``bowl:0.1,0.004`` against a converged quadratic-tet solve
  (:data:`BOWL_REFERENCE`),

for hex (draft / default / high and explicit resolutions), tet4 and tet10 at several element
sizes, the spring-mass shell, and an independent peer: scikit-fem's quadratic tetrahedra
(``ElementTetP2``, linear elasticity) on the same TetGen mesh, with SciPy's shift-invert
``eigsh``. Every point runs in a forked child process; its wall time is measured around the
analysis call (imports and JIT compilation excluded, as they are paid once per process) and
its peak memory is the rise of the child's peak resident set (``VmHWM`` after a reset through
``/proc/self/clear_refs``) over its resident set at the start.

Modes are matched to references by their shape, not their order: bending / torsion /
longitudinal by the share of the surface motion in each direction (beam), the share of
tangential motion around the axis (rod torsion) and of radial motion (sphere: toroidal
modes have none); the bowl's first eight modes are compared in order.

Synthesis (:mod:`.accuracy_synth`) and end to end (:mod:`.accuracy_e2e`) are measured in
their own modules; :mod:`.accuracy_page` writes the plots and the Markdown page.
"""

from __future__ import annotations

import json
import os
import sys
import time

from ..io import atomic_open
from .accuracy_e2e import E2E_MATERIALS, E2E_MIC, E2E_XML, run_e2e, third_octave_levels  # noqa: F401
from .accuracy_modal import (ALU, BEAM_BENDING_3D, BEAM_BENDING_EB, BOWL_REFERENCE, ROD_BENDING_3D, SHAPES,  # noqa: F401
                             lamb_sphere, references, rod_bending_references, run_fmax, run_modal, sphere_references)
from . import accuracy_page
from .accuracy_synth import run_synth
from .measure import cents, machine_info, measure  # noqa: F401

__all__ = ["run_report", "lamb_sphere", "machine_info", "measure", "BOWL_REFERENCE", "cents"]


def run_report(output="reports", quick: bool = False, plots: bool = True, sections="modal,fmax,synth,e2e,levels",
               json_path=None, from_json=None) -> int:
    """Run the measurements (``sections``: comma list of modal, fmax, synth, e2e, levels) and write
    ``output/accuracy.md`` with PNG plots; ``json_path`` also dumps every number,
    ``from_json`` rewrites the Markdown and plots from such a dump without running anything.
    ``sections="levels"`` alone rewrites only the levels section of an existing page
    (:mod:`.accuracy_levels`)."""
    t_start = time.perf_counter()
    os.makedirs(output, exist_ok=True)
    if from_json:
        with open(from_json) as fh:
            d = json.load(fh)
        plots = [] if not plots else accuracy_page.plots(output, d["modal"], d["synth"], d["e2e"], d["f_max"])
        accuracy_page.write_markdown(os.path.join(output, "accuracy.md"), d["machine"], d["command"], d["modal"],
                                     d["f_max"], d["synth"], d["e2e"], plots, "--quick" in d["command"], d["seconds"])
        return 0
    command = "mjsound report accuracy" + (" --quick" if quick else "") + f" -o {output}"
    sections = set(sections.split(","))

    def log(msg):
        print(msg, file=sys.stderr, flush=True)

    if sections == {"levels"}:  # this section alone, spliced into the page as it is
        from .accuracy_levels import levels_section, run_levels, splice_levels

        path = os.path.join(output, "accuracy.md")
        splice_levels(path, levels_section(run_levels(quick, log), command + " --sections levels"))
        log(f"wrote the levels section of {path} ({time.perf_counter() - t_start:.0f} s)")
        return 0

    info = machine_info()
    log(f"mjsound report accuracy{' --quick' if quick else ''}: {info['cpus']} CPUs, load {info['load_start']}")
    # warm up in the parent (numba caches, imports) so children time the work, not the set-up
    from ..modal.analyze import analyze

    analyze("box:0.05,0.04,0.03", ALU, resolution=2, f_max=200000, error_estimate=False, cache=False)
    analyze("box:0.5,0.01,0.01", ALU, quality="draft", f_max=500, error_estimate=False, cache=False)
    try:
        analyze("box:0.05,0.04,0.03", ALU, method="tet", order=2, resolution=2, f_max=200000,
                error_estimate=False, cache=False)
        import skfem  # noqa: F401
    except Exception:
        pass
    modal = run_modal(quick, log) if "modal" in sections else []
    fmax = run_fmax(quick, log) if "fmax" in sections else []
    synth = run_synth(quick, log) if "synth" in sections else None
    e2e = run_e2e(quick, log) if "e2e" in sections else None
    levels = None
    if "levels" in sections:
        from .accuracy_levels import run_levels

        levels = run_levels(quick, log)
    info["load_end"] = [round(x, 2) for x in os.getloadavg()]
    plots = [] if not plots else accuracy_page.plots(output, modal, synth, e2e, fmax)
    seconds = time.perf_counter() - t_start
    path = os.path.join(output, "accuracy.md")
    accuracy_page.write_markdown(path, info, command, modal, fmax, synth, e2e, plots, quick, seconds)
    if levels is not None:
        from .accuracy_levels import levels_section, splice_levels

        splice_levels(path, levels_section(levels, command))
    if json_path:
        with atomic_open(json_path) as fh:
            json.dump({"machine": info, "command": command, "seconds": seconds, "modal": modal, "f_max": fmax,
                       "synth": synth, "e2e": e2e, "levels": levels}, fh,
                      default=lambda o: o.tolist() if hasattr(o, "tolist") else str(o), indent=1)
    log(f"wrote {path} ({seconds:.0f} s)")
    return 0
