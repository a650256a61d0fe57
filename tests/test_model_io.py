import json
import os

import numpy as np
import pytest

from mjsound import ModalModel, analyze
from mjsound.cli import main
from mjsound.modal import analyze as analyze_mod


@pytest.fixture(scope="module")
def model():
    return analyze("box:0.2,0.03,0.02", "brass", f_max=6000, cache=False, error_estimate=False)


def test_save_load_round_trip_without_pickle(model, tmp_path):
    p = tmp_path / "m.npz"
    model.save(p)
    with np.load(p, allow_pickle=False) as z:  # readable without pickle
        assert "meta" in z
    back = ModalModel.load(p)
    assert np.array_equal(back.frequencies_hz, model.frequencies_hz)
    assert np.array_equal(back.shapes, model.shapes)
    assert back.material == model.material and back.method == model.method and back.dofs == model.dofs
    assert not [f for f in os.listdir(tmp_path) if f.startswith(".tmp")]  # atomic write left no temp


def test_corrupt_file_is_refused(tmp_path):
    p = tmp_path / "bad.npz"
    p.write_bytes(b"PK\x03\x04 not really a zip")
    with pytest.raises(ValueError, match="not a valid mjsound model"):
        ModalModel.load(p)


def test_gains_follow_direction_and_truncation(model):
    pts = model.points[:3]
    gz = model.gains(pts, np.tile([0, 0, 1.0], (3, 1)))
    gx = model.gains(pts, np.tile([1.0, 0, 0], (3, 1)))
    gxz = model.gains(pts, np.tile([1.0, 0, 1.0], (3, 1)))
    assert np.allclose(gxz, gx + gz)
    t = model.truncated(n_modes=3)
    assert t.n_modes == 3 and np.array_equal(t.frequencies_hz, model.frequencies_hz[:3])


def test_nearest_points_direct_and_tree_agree(model, monkeypatch):
    import mjsound.modal.model as mm

    rng = np.random.default_rng(1)
    lo, hi = model.points.min(axis=0), model.points.max(axis=0)
    q = rng.uniform(lo - 0.01, hi + 0.01, size=(200, 3))
    direct = model.nearest_points(q)
    d2 = ((q[:, None] - model.points[None]) ** 2).sum(-1)
    np.testing.assert_array_equal(d2[np.arange(len(q)), direct], d2.min(axis=1))
    monkeypatch.setattr(mm, "BRUTE_FORCE_PAIRS", 0)
    np.testing.assert_array_equal(model.nearest_points(q), direct)
    assert model.nearest_points(model.points[7]).tolist() == [7]


def test_cache_hit_skips_the_analysis_and_corrupt_entry_is_recomputed(monkeypatch):
    a = analyze("box:0.1,0.02,0.01", "steel", f_max=5000, error_estimate=False)
    calls = []
    real = analyze_mod._discretize
    monkeypatch.setattr(analyze_mod, "_discretize", lambda *a, **k: calls.append(1) or real(*a, **k))
    b = analyze("box:0.1,0.02,0.01", "steel", f_max=5000, error_estimate=False)
    assert calls == [] and np.array_equal(a.frequencies_hz, b.frequencies_hz)
    # a different material is a different key
    analyze("box:0.1,0.02,0.01", "brass", f_max=5000, error_estimate=False)
    assert calls == [1]
    # truncate every cache file: it must be recomputed, with a warning, never trusted
    d = analyze_mod.cache_dir()
    for f in os.listdir(d):
        with open(os.path.join(d, f), "r+b") as fh:
            fh.truncate(100)
    with pytest.warns(UserWarning, match="corrupt"):
        c = analyze("box:0.1,0.02,0.01", "steel", f_max=5000, error_estimate=False)
    assert calls == [1, 1] and np.allclose(c.frequencies_hz, a.frequencies_hz)


def test_cli_analyze_json_contract(capsys, tmp_path):
    out = tmp_path / "m.npz"
    rc = main(["analyze", "box:0.3,0.02,0.01", "--material", "E=70e9,nu=0.33,rho=2700", "--f-max", "3000",
               "--json", "-o", str(out)])
    assert rc == 0
    d = json.loads(capsys.readouterr().out)
    for key in ["frequencies_hz", "damped_frequencies_hz", "decay_per_s", "n_modes", "method", "dofs", "seconds",
                "error_estimate_cents"]:
        assert key in d
    assert d["method"] == "hex" and d["n_modes"] == len(d["frequencies_hz"]) > 0
    assert d["frequencies_hz"] == sorted(d["frequencies_hz"])
    assert ModalModel.load(out).n_modes == d["n_modes"]


def test_cli_errors_are_clear(capsys):
    assert main(["analyze", "box:0.1,0.1,0.1", "--material", "kryptonite"]) == 2
    err = capsys.readouterr().err
    assert "unknown material" in err and "steel" in err
    assert main(["analyze", "box:0.1,0.1,0.1", "--material", "E=1e9,nu=0.7,rho=1000"]) == 2
    assert "nu" in capsys.readouterr().err


def test_every_subcommand_has_help(capsys):
    from mjsound.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    assert "analyze" in sub.choices
    for name in sub.choices:
        with pytest.raises(SystemExit) as e:
            main([name, "--help"])
        assert e.value.code == 0
        assert "usage" in capsys.readouterr().out
