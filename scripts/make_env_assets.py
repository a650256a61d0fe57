#!/usr/bin/env python
"""Generate assets/envs/ deterministically: MJCF and meshes of the mjsound gymnasium envs.

Usage: python scripts/make_env_assets.py [--out assets/envs]
Running it twice gives byte-identical files (the envs import the same builders, so the files
are only a copy for people who want to look at or load the scenes without Python).

Files
-----
material_drop.xml         a bar dropped onto a floor (MaterialDrop-v0)
tap_containers.xml        three sealed containers and a steel hammer ball (TapContainers-v0)
palm_drop.xml             a ball dropped on a plate with a contact microphone (PalmDrop-v0)
container_empty.obj       container surface (walls, lid with a vent hole)
container_loaded.obj      the same container with a heavy block fused to its floor
"""

from __future__ import annotations

import argparse
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from envs.assets import write_env_assets  # noqa: E402


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "assets", "envs"))
    args = p.parse_args(argv)
    for path in write_env_assets(args.out):
        print(f"wrote {os.path.normpath(path)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
