#!/usr/bin/env python
"""Stability table (issue 6): same as ``mjsound report stability [--quick] [-o FILE]``.

    python scripts/report_stability.py --quick               # the test-suite form
    python scripts/report_stability.py -o reports/stability.md
"""

import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from mjsound.cli import main  # noqa: E402

if __name__ == "__main__":
    sys.exit(main(["report", "stability", *sys.argv[1:]]))
