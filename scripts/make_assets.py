#!/usr/bin/env python
"""Generate assets/ deterministically: the demo scene (demo_scene.xml) and its bowl mesh.

Usage: python scripts/make_assets.py [--out assets]
Running it twice gives byte-identical files.
"""

from __future__ import annotations

import argparse
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from mjsound.sim.demo import write_demo_assets  # noqa: E402


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "assets"))
    args = p.parse_args(argv)
    path = write_demo_assets(args.out)
    print(f"wrote {os.path.normpath(path)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
