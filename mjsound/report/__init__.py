"""Reproducible reports: accuracy against run time, and stability on stiff, extreme and hostile cases.

:func:`mjsound.report.accuracy.run_report` writes ``DIR/accuracy.md`` and PNG plots
(matplotlib is needed for the plots only); :func:`mjsound.report.stability.run_report` prints
a PASS/FAIL table with the measured quantity of every case. On the command line:
``mjsound report accuracy`` / ``mjsound report stability`` (:mod:`mjsound.cli.report`).
"""
