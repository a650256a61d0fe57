"""The quick stability table (``mjsound report stability --quick``): every row must pass.

A failing row names the case, its input and what was measured; fix the code, never drop
the row (issue 6).
"""

import time

import pytest

pytest.importorskip("mujoco")


def test_stability_quick_table_all_pass():
    from mjsound.report.stability import run_cases, to_markdown

    t0 = time.perf_counter()
    rows = run_cases(quick=True)
    seconds = time.perf_counter() - t0
    failed = [r for r in rows if not r.ok]
    assert len(rows) >= 30
    assert not failed, "stability cases failed:\n" + to_markdown(failed, f"({seconds:.0f} s)")
