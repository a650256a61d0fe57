"""``mjsound warmup``: compile every numba kernel once, into numba's on-disk cache.

A process on a machine whose cache is empty compiles the kernels before its first audio
(tens of seconds; see docs/kernels.md); every later process loads them in about
a second. Running this once where processes will start (a container image's build, a node
before it launches vectorised environments) moves that compilation out of every run.
"""

from __future__ import annotations

import sys
import time

__all__ = ["register", "warm_kernels"]


def register(sub) -> None:
    """Add ``warmup`` to an argparse ``subparsers``."""
    p = sub.add_parser(
        "warmup",
        help="compile every numba kernel once into numba's on-disk cache (a new machine or image)",
        description=(
            "Compile (or load, when cached) every numba kernel mjsound runs: the per-step and "
            "render kernels, the gymnasium wrapper's and the modal analysis's, so that later "
            "processes on this machine load them instead of compiling. The cache is numba's: "
            "$NUMBA_CACHE_DIR when set, else __pycache__ next to the sources. Where mjsound's "
            "shipped kernels fit (x86-64 with AVX2, the numba they were built with) they are "
            "loaded instead of compiled; MJSOUND_SHIPPED_KERNELS=0 compiles for this host."
        ),
    )
    p.set_defaults(func=run)


def _warm_sim() -> None:
    from ..sim.warmup import warmup

    warmup(verbose=False, once=True)


def _warm_wrapper() -> None:
    import numpy as np

    from ..wrappers import AudioWindow

    AudioWindow(1, 64).push(np.zeros((1, 16), dtype=np.float32))


def _warm_modal() -> None:
    from ..modal.analyze import analyze

    # a solid (voxel hexahedra), a thin wall (shell triangles), a curved rod (quadratic cells
    # that place their surface voxels' material by its moments: the rods, legs and handles of
    # robot scenes) and an open surface (a box without its lid, analysed as a wall around the
    # surface: robot meshes that are not closed): the modal kernels of every common analysis
    analyze("box:0.1,0.06,0.02", "steel", quality="draft", f_max=8000.0, cache=False, progress=False)
    analyze("sphere:0.1", "aluminium,wall=2mm", quality="draft", f_max=4000.0, cache=False, progress=False)
    analyze("cylinder:0.01,0.1", "steel", quality="draft", f_max=4000.0, cache=False, progress=False)
    analyze(_open_box(), "steel", quality="draft", f_max=4000.0, cache=False, progress=False)
    # a plate with modes in the band: its radiation is solved by boundary elements (modal/bem.py)
    analyze("box:0.2,0.1,0.005", "steel", quality="draft", f_max=2000.0, cache=False, progress=False)


def _open_box():
    """``(vertices, faces)`` of a 20 x 12 x 8 cm box without its top face (an open surface)."""
    import trimesh

    box = trimesh.creation.box((0.2, 0.12, 0.08))
    return box.vertices, box.faces[box.face_normals[:, 2] < 0.5]


#: The kernel groups, in the order they are warmed: the per-step path, the gymnasium wrapper,
#: the modal analysis.
PARTS = {"sim": _warm_sim, "wrapper": _warm_wrapper, "modal": _warm_modal}


def warm_kernels(progress=None) -> dict:
    """Compile or load every kernel group; returns ``{part: seconds}`` for each of
    :data:`PARTS`. ``progress(part)`` is called before each part."""
    times = {}
    for part, warm in PARTS.items():
        if progress:
            progress(part)
        t = time.perf_counter()
        warm()
        times[part] = time.perf_counter() - t
    return times


def run(args) -> int:
    """Handler of ``mjsound warmup``."""
    from ..jit import SHIPPED
    from ..sim.warmup import kernel_cache_dir, kernels_cached

    cold = not kernels_cached()
    print(f"mjsound warmup: numba cache {kernel_cache_dir()} ({'empty: compiling, about a minute' if cold else 'filled: loading'}); "
          + (f"{SHIPPED.reason}, {SHIPPED.added} entries copied in by this process" if SHIPPED.used
             else f"shipped kernels not used: {SHIPPED.reason}"), file=sys.stderr, flush=True)
    times = warm_kernels(progress=lambda part: print(f"  {part} kernels ...", file=sys.stderr, flush=True))
    print("mjsound warmup: " + ", ".join(f"{k} {v:.1f} s" for k, v in times.items()) + f"; total {sum(times.values()):.1f} s")
    return 0
