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


def test_hostile_report_measures_a_refused_input_in_a_child(tmp_path):
    """The hostile section's machinery: a child ``mjsound`` refusing an input, its exit status,
    message, peak memory (its own, from RUSAGE_CHILDREN of the monitor) and no temp file."""
    import sys

    from mjsound.report.hostile import _mjsound, _refused, to_markdown

    xml = tmp_path / "s.xml"
    xml.write_text("<mujoco><worldbody><geom type='plane' size='1 1 .1'/></worldbody></mujoco>")
    d = tmp_path / "out"
    d.mkdir()
    row = _refused("sample rate", "sonify --sample-rate 100",
                   _mjsound("sonify", xml, "--sample-rate", "100", "-o", d / "a.wav"), d, "1000..768000")
    assert row.ok and row.outcome.startswith("exit 2: sample_rate=100 Hz")
    assert 10 < row.peak_mb < 2000  # a Python process with numpy, measured alone
    wrong = _refused("sample rate", "x", [sys.executable, "-c", "raise SystemExit(3)"], d, "anything")
    assert not wrong.ok and wrong.outcome.startswith("exit 3")
    md = to_markdown([row, wrong])
    assert "| PASS | sample rate |" in md and "| **FAIL** |" in md and "1 of 2 cases pass." in md
