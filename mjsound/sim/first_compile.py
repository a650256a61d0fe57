"""Whether numba's cache holds mjsound's kernels, and the one line said when it does not.

numba compiles each kernel the first time a process calls it and keeps the machine code in
its on-disk cache (``cache=True``), so only the first run on a machine pays;
:func:`notice_first_compile` prints one line on stderr when the cache is cold
(:class:`mjsound.sim.AudioSimulator` calls it; :func:`mjsound.sim.warmup.warmup` compiles
ahead of time).
"""

from __future__ import annotations

import os
import sys

__all__ = ["kernels_cached", "kernel_cache_dir", "notice_first_compile"]

_NOTICED = [False]

def kernels_cached() -> bool:
    """Whether numba's disk cache holds the step kernel of the current sources already (then
    a process starts in about a second; after an edit or a ``git pull`` of a kernel module it
    does not: the index is stamped with its group's sources, :mod:`mjsound.jit`)."""
    from .step import advance

    try:
        return bool(advance._cache._cache_file._load_index())
    except Exception:  # (numba internals moved, a torn or foreign index: assume cold)
        return False


def kernel_cache_dir() -> str:
    """The folder of numba's on-disk cache that mjsound's kernels use (``$NUMBA_CACHE_DIR``
    when set, else ``__pycache__`` next to the sources or the user-wide cache)."""
    from ..jit import cache_folder
    from .step import advance

    return cache_folder(advance) or os.environ.get("NUMBA_CACHE_DIR", "numba's default cache")


def notice_first_compile(stream=None, quiet: bool = False) -> None:
    """Say once per process, on stderr, that numba compiles its kernels (cold cache only;
    ``quiet``: say nothing, now or later)."""
    if _NOTICED[0]:
        return
    _NOTICED[0] = True
    if not quiet and not kernels_cached():
        from ..jit import SHIPPED

        why = "they lack these kernels" if SHIPPED.used else SHIPPED.reason
        print("mjsound: compiling numba kernels, about half a minute of CPU (once per machine and mjsound "
              "version, cached afterwards; `mjsound warmup` does it ahead of time; the shipped kernels are not "
              f"used: {why})", file=stream or sys.stderr, flush=True)
