#!/usr/bin/env python
"""Accuracy against run time (issue 6): same as ``mjsound report accuracy [--quick] [-o DIR]``.

    python scripts/report_accuracy.py            # full report into reports/ (~10-15 min on 2 cores)
    python scripts/report_accuracy.py --quick -o /tmp/acc   # under a minute
"""

import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from mjsound.cli import main  # noqa: E402

if __name__ == "__main__":
    sys.exit(main(["report", "accuracy", *sys.argv[1:]]))
