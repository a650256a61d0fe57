#!/usr/bin/env python
"""Build the kernels shipped with mjsound (``mjsound/kernel_bundle/``, :mod:`mjsound.kernel_bundle`).

1. A child process with an empty numba cache, numba's CPU target set to ``x86-64-v3``
   (``NUMBA_CPU_NAME``, no host-specific features) and the shipped kernels switched off,
   compiles every kernel ``mjsound warmup`` compiles (the per-step and render path, the
   gymnasium wrapper's, the modal analysis's).
2. Its cache folders, one per package folder, are packed into ``kernels.tar.xz`` with a
   ``manifest.json``: numba's and Python's versions, the platform, the CPU target and the
   instructions it needs, and per kernel group (:data:`mjsound.jit.KERNEL_GROUPS`) the digests
   of its sources' bytes and of its code (docstrings, comments and formatting left out).
3. A second child with another empty cache and the new bundle runs the same warm-up and must
   compile nothing of mjsound's: the bundle is whole.

Run it once per release, on the release commit (``docs/kernels.md``): not after every edit
(until then a group whose code changed compiles once per machine, and the test suite warns).
It refuses to build with a numba other than the one ``pyproject.toml`` pins. ``--check``
only says whether the bundle matches the kernels' code and this numba (exit status 1 when
not). About two minutes on two cores.

Usage: python scripts/build_kernel_bundle.py [--check]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

ROOT = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
sys.path.insert(0, ROOT)

#: The CPU model the shipped kernels are compiled for, and the instructions it implies (LLVM's
#: feature names): x86-64-v3 of the x86-64 psABI levels, AVX2 and FMA.
CPU_NAME = "x86-64-v3"
CPU_REQUIRES = ["avx", "avx2", "bmi", "bmi2", "cx16", "f16c", "fma", "lzcnt", "movbe", "popcnt", "sahf",
                "sse4.1", "sse4.2", "ssse3", "xsave"]

#: Counts the compilations of mjsound's functions in a child, printed as one JSON line at exit.
COUNT_COMPILES = """
import atexit, json, sys
from numba.core import event as _ev
_compiled = []
class _Count(_ev.Listener):
    def on_start(self, e):
        f = getattr(e.data.get("dispatcher"), "py_func", None)
        if f is not None and f.__module__.startswith("mjsound"):
            _compiled.append(f"{f.__module__}.{f.__qualname__}")
    def on_end(self, e):
        pass
_ev.register("numba:compile", _Count())
"""

WARM = """
from mjsound.cli.warmup import warm_kernels
import mjsound.jit
warm_kernels()
from numba.core.registry import cpu_target
print("RESULT " + json.dumps({"magic": list(cpu_target.target_context.codegen().magic_tuple()),
                              "shipped": mjsound.jit.SHIPPED.used, "reason": mjsound.jit.SHIPPED.reason,
                              "compiled": _compiled}))
"""


def run_child(cache_dir: str, build: bool) -> dict:
    env = dict(os.environ, NUMBA_CACHE_DIR=cache_dir, PYTHONPATH=ROOT)
    for k in ("NUMBA_CPU_NAME", "NUMBA_CPU_FEATURES", "MJSOUND_SHIPPED_KERNELS"):
        env.pop(k, None)
    if build:
        env.update(NUMBA_CPU_NAME=CPU_NAME, NUMBA_CPU_FEATURES="", MJSOUND_SHIPPED_KERNELS="0")
    out = subprocess.run([sys.executable, "-c", COUNT_COMPILES + WARM], env=env, capture_output=True, text=True)
    if out.returncode != 0:
        raise SystemExit(f"build_kernel_bundle: the warm-up child failed:\n{out.stderr[-4000:]}")
    line = [x for x in out.stdout.splitlines() if x.startswith("RESULT ")][-1]
    return json.loads(line.split(" ", 1)[1])


def package_folders(cache_dir: str) -> dict:
    """``{package folder: cache folder}`` for the folders of ``cache_dir`` (numba names each
    after its source folder and that folder's path digest)."""
    from numba.core.caching import _CacheLocator

    pkg = os.path.join(ROOT, "mjsound")
    out = {}
    for dirpath, _, files in os.walk(pkg):
        if "__init__.py" not in files or "__pycache__" in dirpath:
            continue
        sub = _CacheLocator.get_suitable_cache_subpath(os.path.join(dirpath, "__init__.py"))
        if os.path.isdir(os.path.join(cache_dir, sub)):
            out[os.path.relpath(dirpath, pkg)] = os.path.join(cache_dir, sub)
    unknown = set(os.listdir(cache_dir)) - {os.path.basename(p) for p in out.values()}
    if unknown:
        raise SystemExit(f"build_kernel_bundle: cache folders of no mjsound package folder: {sorted(unknown)}")
    return out


def pinned_numba() -> str | None:
    """The numba version ``pyproject.toml`` pins (``numba==X``), or None."""
    import re

    with open(os.path.join(ROOT, "pyproject.toml")) as f:
        m = re.search(r'"numba==([0-9][0-9a-z.]*)"', f.read())
    return m.group(1) if m else None


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--check", action="store_true", help="only check that the bundle matches the sources and numba")
    args = p.parse_args(argv)
    import numba

    from mjsound import kernel_bundle
    from mjsound.jit import code_digest, kernel_code_digests, kernel_digests

    manifest = kernel_bundle.read_manifest()
    if args.check:
        stale = kernel_bundle.mismatches(manifest or {}, kernel_digests(), code_digest=lambda g: code_digest(g).hex())
        print("build_kernel_bundle: " + (f"stale ({', '.join(stale)})" if stale else "the bundle matches"))
        return 1 if stale else 0
    if numba.__version__ != pinned_numba():
        raise SystemExit(f"build_kernel_bundle: this is numba {numba.__version__}, pyproject.toml pins "
                         f"{pinned_numba()}: build with the pinned numba (or change the pin and the docs with it)")

    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="mjsound-bundle-") as cache:
        print("build_kernel_bundle: compiling every kernel for " + CPU_NAME + " ...", flush=True)
        built = run_child(cache, build=True)
        if built["magic"][1:] != [CPU_NAME, ""]:
            raise SystemExit(f"build_kernel_bundle: the child compiled for {built['magic']}, not {CPU_NAME}")
        import llvmlite.binding as ll

        manifest = dict(kernel_bundle.host_platform(), cpu_name=CPU_NAME, cpu_features="", cpu_requires=CPU_REQUIRES,
                        digests=kernel_digests(), code_digests=kernel_code_digests(),
                        built={"host_cpu": ll.get_host_cpu_name(), "functions": len(built["compiled"])})
        archive = kernel_bundle.write_bundle(kernel_bundle.BUNDLE_DIR, package_folders(cache), manifest)
    print(f"build_kernel_bundle: {len(built['compiled'])} functions compiled in {time.perf_counter() - t0:.0f} s; "
          f"{os.path.relpath(archive, ROOT)} {os.path.getsize(archive) / 1e6:.2f} MB", flush=True)

    t1 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="mjsound-bundle-check-") as cache:
        check = run_child(cache, build=False)
    if not check["shipped"] or check["compiled"]:
        raise SystemExit(f"build_kernel_bundle: a fresh cache with the new bundle still compiled: shipped "
                         f"{check['shipped']} ({check['reason']}), compiled {check['compiled']}")
    print(f"build_kernel_bundle: checked: a fresh process with an empty cache loads every kernel from the bundle, "
          f"warm-up {time.perf_counter() - t1:.1f} s, nothing compiled")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
