"""numba's ``njit`` for mjsound's kernels, with a disk cache that notices an edit to any kernel source.

numba stamps each cached kernel with the content of the one file that defines it. A kernel
compiled together with kernels of other modules (the step kernel in ``sim/step.py`` takes in
the contact reader's, the drive's and the synthesizer's) would then load stale machine code
after an edit to, or a ``git pull`` of, only those other modules: the old sound, without a word.
Here each kernel is stamped with the digest of every source of its group
(:data:`KERNEL_GROUPS`: the modules that hold the group's kernels and those they import at
load time, whose names and constants the kernels can read), so an edit to any of them
recompiles that group once, and an edit elsewhere (the simulator's Python, the scene, the
wrappers) recompiles nothing.

Whether the kernels shipped with mjsound (:mod:`mjsound.kernel_bundle`) fit is decided by
the group's *code* instead (:func:`code_digest`: the sources parsed, without docstrings,
comments, blank lines or formatting), so an edit to a docstring leaves them usable.

Importing this module registers the group-stamped cache locators with numba (in front of
numba's own, for mjsound's files only); kernel modules take ``njit`` from here so that the
registration always precedes their decorators. It also decides whether this process loads
the kernels shipped with mjsound (:data:`SHIPPED`): before any kernel is declared, which is
why ``mjsound/__init__`` imports this module first.

A kernel that only other kernels call is declared with :func:`njit_inner`: compiled without
the entries numba makes for calls from Python and C, which for kernels taking the state
records are a large part of a cold cache's compilation (:func:`call_inner` calls one from
Python, for tests).

Processes that start together on a machine whose cache is empty (the workers of a vectorised
env) would each compile the same kernels at once: :func:`compile_lock` lets one of them
compile a kernel while the others wait and then load it from the cache.
"""

from __future__ import annotations

import contextlib
import functools
import os

import numba
from numba.core import caching
from numba.core.registry import CPUDispatcher

from .io import file_lock
from .io import sources_digest as files_digest

__all__ = ["njit", "njit_inner", "call_inner", "InnerDispatcher", "KERNEL_GROUPS", "kernel_group", "sources_digest",
           "code_digest", "cache_folder", "folder_cache_path", "folder_stamp", "kernel_digests", "kernel_code_digests",
           "compile_lock", "COMPILE_WAIT_S", "SHIPPED", "seed_shipped_kernels"]

_ROOT = os.path.dirname(os.path.abspath(__file__))

#: The sources of each group's kernels: the modules that define them and every module of the
#: package those import at load time (files relative to the package). A kernel in ``modal/``
#: belongs to ``"modal"``, any other to ``"sim"``. ``tests/test_kernel_bundle.py`` checks that
#: each list holds its kernels' import closure: add a module here when a kernel module of the
#: group starts importing it.
KERNEL_GROUPS = {
    "modal": ("io.py", "jit.py", "materials.py", "modal/banded.py", "modal/bem.py", "modal/block_lanczos.py",
              "modal/discretization.py", "modal/facet_shell.py", "modal/hex.py", "modal/hex_cell.py",
              "modal/midsurface.py", "modal/node_mass.py", "modal/pencil.py", "modal/quadratic_forms.py",
              "modal/surface.py", "modal/voxelize.py"),
    "sim": ("audio_window.py", "io.py", "jit.py", "sim/click_kernels.py", "sim/drive.py", "sim/fused.py",
            "sim/images.py", "sim/impulses.py", "sim/pairs.py", "sim/records.py", "sim/step.py", "sim/surfaces.py",
            "synth/bandlimited.py",
            "synth/bank_loops.py", "synth/constants.py", "synth/contact_coupling.py", "synth/directivity.py",
            "synth/dispatch.py", "synth/drive_broadband.py", "synth/drive_gains.py", "synth/drive_housing.py",
            "synth/drive_directions.py", "synth/drive_lanes.py", "synth/drive_lines.py", "synth/drive_weights.py",
            "synth/drive_tones.py", "synth/impact_energy.py", "synth/interrupt.py", "synth/kernels.py", "synth/packing.py", "synth/pulse.py", "synth/queue.py",
            "synth/records.py", "synth/reverb.py", "synth/sorting.py", "synth/streams.py"),
}

njit = numba.njit


class InnerDispatcher(CPUDispatcher):
    """The dispatcher of an inner kernel (:func:`njit_inner`): a call from Python raises
    instead of running the missing entry (which would crash the interpreter)."""

    def __call__(self, *args, **kwargs):
        raise TypeError(f"mjsound: {self.py_func.__qualname__} is an inner kernel (njit_inner): other kernels "
                        "call it; from Python use mjsound.jit.call_inner(kernel, *args)")


def njit_inner(fn=None, **options):
    """``njit(**options)`` for a kernel that only other kernels call: without the entries numba
    compiles for calls from Python and C (``no_cpython_wrapper``, ``no_cfunc_wrapper``). Such
    an entry unboxes every argument, and for the state records (tens of arrays each) it costs
    about half a second of compilation per kernel on a cold cache, for code that never runs.
    Called from Python the kernel raises ``TypeError``."""
    def wrap(f):
        d = numba.njit(no_cpython_wrapper=True, no_cfunc_wrapper=True, **options)(f)
        if type(d) is CPUDispatcher:  # (numba's usual class: the guard has its layout)
            d.__class__ = InnerDispatcher
        return d

    return wrap if fn is None else wrap(fn)


def kernel_group(py_file: str, root: str = _ROOT) -> str | None:
    """The group of the kernel source ``py_file``, or None for a file outside ``root``."""
    rel = os.path.relpath(os.path.abspath(py_file), root)
    if rel.startswith(".."):
        return None
    return "modal" if rel.split(os.sep)[0] == "modal" else "sim"


@functools.lru_cache(maxsize=None)
def sources_digest(group: str, root: str = _ROOT) -> bytes:
    """The digest of the group's sources (:func:`mjsound.io.sources_digest`), numba's stamp."""
    return files_digest(root, KERNEL_GROUPS[group])


class _GroupStamped:
    """Stamp with the group's digest; locate only mjsound's own files."""

    def get_source_stamp(self):
        return sources_digest(kernel_group(self._py_file))

    @classmethod
    def from_function(cls, py_func, py_file):
        if kernel_group(py_file) is None:
            return None
        return super().from_function(py_func, py_file)


class GroupUserProvidedCacheLocator(_GroupStamped, caching.UserProvidedCacheLocator):
    """``$NUMBA_CACHE_DIR``, group-stamped."""


class GroupInTreeCacheLocator(_GroupStamped, caching.InTreeCacheLocator):
    """``__pycache__`` next to the source, group-stamped."""


class GroupUserWideCacheLocator(_GroupStamped, caching.UserWideCacheLocator):
    """The user-wide numba cache (a read-only install), group-stamped."""


def _register() -> None:
    ours = [GroupUserProvidedCacheLocator, GroupInTreeCacheLocator, GroupUserWideCacheLocator]
    classes = caching.CacheImpl._locator_classes  # (numba's list of locators, tried in order)
    if ours[0] not in classes:
        classes[:0] = ours


_register()


def _folder_file(folder: str) -> str:
    return os.path.normpath(os.path.join(_ROOT, folder, "__init__.py"))


def kernel_digests() -> dict:
    """``{group: hex digest}`` of the kernel sources' bytes as they are (numba's stamps)."""
    return {g: sources_digest(g).hex() for g in KERNEL_GROUPS}


@functools.lru_cache(maxsize=None)
def code_digest(group: str, root: str = _ROOT) -> bytes:
    """The digest of the group's code (:func:`mjsound.kernel_bundle.code_digest`: docstrings,
    comments and formatting left out), what the shipped kernels must match; kept in numba's
    cache folder of the package under the sources' byte digest."""
    from . import kernel_bundle

    memo = folder_cache_path(".") if root == _ROOT else None
    key = f"{group}-{sources_digest(group, root).hex()[:32]}"
    return kernel_bundle.code_digest(root, KERNEL_GROUPS[group], memo, key)


def kernel_code_digests() -> dict:
    """``{group: hex digest}`` of the kernels' code as it is (:func:`code_digest`): what a
    shipped bundle's manifest must carry (:mod:`mjsound.kernel_bundle`)."""
    return {g: code_digest(g).hex() for g in KERNEL_GROUPS}


def folder_stamp(folder: str) -> bytes:
    """numba's source stamp of the kernels of the package folder ``folder`` ("sim", "." ...):
    the digest of its group."""
    return sources_digest(kernel_group(_folder_file(folder)))


def folder_cache_path(folder: str) -> str | None:
    """numba's cache folder for the kernels of the package folder ``folder`` ("sim", "." ...):
    that of the first locator that takes the folder's files, in numba's order
    (:data:`caching.CacheImpl._locator_classes`, the group-stamped ones first), or None when
    none does."""
    def probe():
        pass

    for cls in caching.CacheImpl._locator_classes:
        locator = cls.from_function(probe, _folder_file(folder))
        if locator is not None:
            return locator.get_cache_path()
    return None


def _choose_shipped_kernels():
    """:func:`mjsound.kernel_bundle.activate` with this package's kernel sources; before any
    kernel is declared (numba fixes its CPU target with the first)."""
    from . import kernel_bundle

    try:
        return kernel_bundle.activate(kernel_digests(), lambda g: code_digest(g).hex())
    except Exception as e:  # (never fail an import over a cache: compile instead)
        kernel_bundle.STATUS.used, kernel_bundle.STATUS.reason = False, f"shipped kernels not used ({e!r})"
        return kernel_bundle.STATUS


def seed_shipped_kernels():
    """Copy the chosen shipped kernels into numba's cache folders of this package
    (:func:`mjsound.kernel_bundle.seed_cache`); ``mjsound/__init__`` calls it last."""
    from . import kernel_bundle

    return kernel_bundle.seed_cache(locate=folder_cache_path, stamp_of=folder_stamp,
                                    group_of=lambda folder: kernel_group(_folder_file(folder)),
                                    name_of=lambda folder, name: kernel_bundle.index_name_now(
                                        _ROOT, [m for g in KERNEL_GROUPS.values() for m in g], folder, name))


#: Whether this process loads mjsound's shipped kernels (:mod:`mjsound.kernel_bundle`), and why not.
SHIPPED = _choose_shipped_kernels()


@numba.njit
def _trampoline(kernel, args):
    return kernel(*args)


def call_inner(kernel, *args):
    """Call the inner kernel ``kernel`` (:func:`njit_inner`) from Python: through a compiled
    trampoline, itself compiled (not cached) for each kernel and argument types. For tests of
    a kernel against a plain reference and for one-off use, not for a hot loop."""
    return _trampoline(kernel, args)


#: Longest wait for another process's compilation of the same kernel [s]; then this one compiles too.
COMPILE_WAIT_S = 600.0


def cache_folder(dispatcher) -> str | None:
    """The folder of ``dispatcher``'s on-disk cache (its index and machine code), or None for a
    kernel without one (or when numba's internals moved)."""
    return getattr(getattr(dispatcher, "_cache", None), "_cache_path", None) or None


def compile_lock(dispatcher):
    """A lock (:func:`mjsound.io.file_lock`) beside ``dispatcher``'s cache index, for its first
    call in a process: if another process is compiling it, wait for it, then load the result
    from the cache instead of compiling it a second time. Nothing is locked for a kernel
    without a disk cache."""
    path = cache_folder(dispatcher)
    if path is None:
        return contextlib.nullcontext()
    return file_lock(os.path.join(path, f"{dispatcher.py_func.__qualname__}.compile.lock"), COMPILE_WAIT_S)
