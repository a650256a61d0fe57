#!/usr/bin/env python
"""Figures of the per-env-step path (issue 37's note): private cross-class accesses in the
package, and the Python frames and files one wrapped env step runs through.

* ``private``: every ``obj._name`` attribute access in ``mjsound/`` (AST) where ``obj`` is not
  ``self`` / ``cls`` (dunder names and a module's own names excluded: a module-level
  ``_name`` reached through an imported module counts); listed with ``--list``.
* ``frames``: ``AudioObservation(gym.make("Ant-v5"))``, one env step traced with
  :func:`sys.setprofile`: the mjsound Python frames on the stack when the step kernel's numba
  entry is entered, from ``AudioObservation.step`` down (gymnasium's frames not counted),
  and the mjsound files whose Python code ran during the step.

Usage: python scripts/step_path_stats.py [--list] [--no-frames]
"""

from __future__ import annotations

import argparse
import ast
import os
import sys

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
sys.path.insert(0, ROOT)


def private_accesses(pkg: str) -> list[tuple[str, int, str]]:
    out = []
    for dirpath, _, files in os.walk(pkg):
        for f in files:
            if not f.endswith(".py"):
                continue
            path = os.path.join(dirpath, f)
            tree = ast.parse(open(path).read())
            for node in ast.walk(tree):
                if isinstance(node, ast.Attribute) and node.attr.startswith("_") and not node.attr.startswith("__"):
                    v = node.value
                    if isinstance(v, ast.Name) and v.id in ("self", "cls"):
                        continue
                    out.append((os.path.relpath(path, ROOT), node.lineno, ast.unparse(node)))
    return out


def frames_and_files():
    import warnings

    import gymnasium as gym
    import numpy as np

    from mjsound.wrappers import AudioObservation

    warnings.simplefilter("ignore")
    env = AudioObservation(gym.make("Ant-v5"), sample_rate=16000)
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    for _ in range(30):
        env.step(rng.uniform(-1, 1, env.action_space.shape).astype(np.float32))
    pkg = os.path.realpath(os.path.join(ROOT, "mjsound"))
    files, depth_at_kernel = set(), []

    def mjsound_stack(frame):
        stack = []
        while frame is not None:
            fn = os.path.realpath(frame.f_code.co_filename)
            if fn.startswith(pkg):
                stack.append(f"{os.path.relpath(fn, ROOT)}:{frame.f_code.co_qualname}")
            if frame.f_code.co_qualname == "AudioObservation.step":
                break
            frame = frame.f_back
        return stack

    def prof(frame, event, arg):
        fn = os.path.realpath(frame.f_code.co_filename)
        if event == "call" and fn.startswith(pkg):
            files.add(os.path.relpath(fn, ROOT))
        if event == "c_call" and getattr(arg, "__name__", "") == "advance" and not depth_at_kernel:
            depth_at_kernel.append(mjsound_stack(frame))

    a = rng.uniform(-1, 1, env.action_space.shape).astype(np.float32)
    sys.setprofile(prof)
    try:
        env.step(a)
    finally:
        sys.setprofile(None)
    env.close()
    return depth_at_kernel[0] if depth_at_kernel else None, sorted(files)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--list", action="store_true")
    p.add_argument("--no-frames", action="store_true")
    args = p.parse_args(argv)
    acc = private_accesses(os.path.join(ROOT, "mjsound"))
    print(f"private cross-class accesses: {len(acc)}")
    if args.list:
        for a in acc:
            print("  %s:%d %s" % a)
    if not args.no_frames:
        stack, files = frames_and_files()
        print(f"mjsound frames from AudioObservation.step to the step kernel: {len(stack) if stack else '?'}")
        for s in reversed(stack or []):
            print("  " + s)
        print(f"mjsound files whose Python runs in one env step: {len(files)}")
        for f in files:
            print("  " + f)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
