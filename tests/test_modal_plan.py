"""Planning before building: method choice, mode-count estimate, memory budget."""

import numpy as np
import pytest
import trimesh

from mjsound import analyze
from mjsound.geometry import load_mesh
from mjsound.materials import parse_material
from mjsound.modal.plan import (DEFAULT_MAX_MEMORY_GB, MAX_MEMORY_ENV, AnalysisBudgetError, choose_method,
                                estimate_modes, max_memory_gb, plan_analysis)

AL = parse_material("aluminium")


def test_method_choice_per_object(monkeypatch):
    kind, reason = choose_method(load_mesh("bowl:0.1,0.004"))
    assert kind == "facet" and "98 % of its surface pairs across the wall" in reason
    import mjsound.modal.plan as P

    monkeypatch.setattr(P, "FACET_MIN_COVERAGE", 1.01)  # a thin wall that does not pair up: tets
    kind, reason = choose_method(load_mesh("bowl:0.1,0.004"))
    assert kind == "tet-wall" and "only 98 %" in reason
    monkeypatch.undo()
    # thin walls folded at sharp edges: a 1 mm can is a shell (43 c at its rim), a box with a
    # 5 mm wall is not (its creases would cost ~216 c)
    from mjsound.modal.surface import hollow

    assert choose_method(hollow(load_mesh("cylinder:0.04,0.12"), 0.001))[0] == "facet"
    kind, reason = choose_method(hollow(load_mesh("box:0.12,0.1,0.08"), 0.005))
    assert kind == "tet-wall" and "creases" in reason and "216 cents" in reason
    for spec in ("box:0.5,0.01,0.01", "sphere:0.1", "cylinder:0.01,0.5", "box:0.2,0.15,0.008"):
        kind, reason = choose_method(load_mesh(spec))
        assert kind == "hex" and "solid, bar or plate" in reason, spec
    box = trimesh.creation.box(extents=[0.1, 0.1, 0.1])
    kind, reason = choose_method(trimesh.Trimesh(box.vertices, box.faces[2:], process=False))
    assert kind == "hex" and "open" in reason


def test_unions_of_overlapping_parts_go_to_the_voxels():
    """A body of several geoms is a union whose closed parts cut into each other (a kitchen
    cabinet of gymnasium-robotics' FrankaKitchen: 13 thin boards; TetGen crashed the process on
    it): auto gives it to hex, and the tet method refuses it with an error. Parts apart, or a
    cavity inside its shell, are not overlaps."""
    from mjsound.modal.plan import overlapping_parts
    from mjsound.modal.surface import hollow
    from mjsound.modal.tet import tetrahedralize

    def board(extents, at):
        b = trimesh.creation.box(extents=extents)
        b.apply_translation(at)
        return b

    # two thin boards crossing (an L of a cabinet's side and shelf), a third one apart
    parts = [board([0.2, 0.004, 0.1], [0, 0, 0]), board([0.004, 0.1, 0.1], [0.05, 0.02, 0]),
             board([0.1, 0.1, 0.004], [0.5, 0, 0])]
    union = trimesh.util.concatenate(parts)
    assert union.is_watertight and overlapping_parts(union) == 2
    kind, reason = choose_method(union)
    assert kind == "hex" and "2 of which overlap" in reason
    with pytest.raises(ValueError, match="union of closed parts"):
        tetrahedralize(union, 0.01)
    assert overlapping_parts(trimesh.util.concatenate([parts[0], parts[2]])) == 0
    assert overlapping_parts(hollow(load_mesh("cylinder:0.04,0.12"), 0.001)) == 0


def test_mode_estimate_against_measured_counts():
    """Weyl / thin-wall / bar estimates within a factor of two of counts the analysis found:
    bowl 114 modes to 20 kHz, beam 9 modes to 6 kHz (reports/accuracy.md)."""
    bowl = load_mesh("bowl:0.1,0.004")
    t = 2 * bowl.volume / bowl.area
    n = estimate_modes(AL, bowl.volume, bowl.area, t, 0.2, 20000)
    assert 57 < n < 228
    n = estimate_modes(AL, 0.5 * 1e-4, 2 * 0.5 * 0.04 + 2e-4, 0.005, 0.5, 6000)
    assert 4.5 < n < 18


def test_memory_cap_from_argument_environment_and_default(monkeypatch):
    monkeypatch.delenv(MAX_MEMORY_ENV, raising=False)
    assert max_memory_gb() == DEFAULT_MAX_MEMORY_GB <= 12  # leaves room on a 24 GB machine
    monkeypatch.setenv(MAX_MEMORY_ENV, "2.5")
    assert max_memory_gb() == 2.5 and max_memory_gb(1) == 1.0
    monkeypatch.setenv(MAX_MEMORY_ENV, "lots")
    with pytest.raises(ValueError, match=MAX_MEMORY_ENV):
        max_memory_gb()
    for bad in (0, -1, float("nan"), "x"):
        with pytest.raises(ValueError, match="max_memory_gb"):
            max_memory_gb(bad)


@pytest.mark.parametrize("spec, material", [("box:10,1,1", "aluminium"), ("box:10,10,0.1", "concrete")])
def test_huge_objects_refused_before_anything_is_built(spec, material, monkeypatch):
    """A 10 x 1 x 1 m aluminium bar and a 10 x 10 x 0.1 m concrete floor to 20 kHz need
    far more than any cap: refused from the estimate, with the numbers and the options."""
    import mjsound.modal.analyze as A

    def never(*a, **k):
        raise AssertionError("discretized despite the budget")

    monkeypatch.setattr(A, "_discretize", never)
    with pytest.raises(AnalysisBudgetError) as e:
        analyze(spec, material, cache=False, max_memory_gb=0.5)
    msg = str(e.value)
    assert "GB" in msg and "max_memory_gb" in msg and "max_modes" in msg and "f_max" in msg


def test_f_max_a_megahertz_is_bounded():
    with pytest.raises(AnalysisBudgetError, match="dofs"):
        analyze("box:0.1,0.1,0.1", "steel", f_max=1e6, cache=False)


@pytest.mark.parametrize("spec, material", [("box:10,1,1", "aluminium"), ("box:10,10,0.1", "concrete")])
def test_max_modes_sizes_the_band_before_the_solve(spec, material):
    """With max_modes the band and the mesh are sized for the modes kept: the floor and the
    bar fit a small cap and come back with at most that many modes."""
    m = analyze(spec, material, quality="draft", max_modes=12, max_memory_gb=0.5, cache=False, error_estimate=False)
    assert 0 < m.n_modes <= 12
    assert m.info["estimate"]["memory_gb"] <= 0.5
    assert m.info["f_max"] < 20000 and any("narrowed" in n for n in m.info["budget_notes"])
    assert m.dofs < 60000


def test_over_budget_coarsens_with_a_warning_or_refuses():
    tm = load_mesh("box:0.3,0.2,0.1")
    fine = plan_analysis(tm, AL, 20000.0, method="hex", max_memory=100)
    assert fine.quality == "default"
    cap = 0.5 * fine.memory_gb
    with pytest.warns(RuntimeWarning, match="over the cap"):
        p = plan_analysis(tm, AL, 20000.0, method="hex", max_memory=cap)
    assert p.quality in ("draft",) and p.memory_gb <= cap and p.h > fine.h and p.notes
    with pytest.raises(AnalysisBudgetError):
        plan_analysis(tm, AL, 20000.0, method="hex", max_memory=cap, over_budget="refuse")
    with pytest.raises(ValueError, match="over_budget"):
        plan_analysis(tm, AL, 20000.0, over_budget="maybe")


def test_memory_estimate_tracks_measured_dofs():
    """The dof estimate (made before meshing) is within a factor of two of the built one."""
    for spec, method in [("box:0.5,0.01,0.01", "auto"), ("sphere:0.1", "auto")]:
        tm = load_mesh(spec)
        p = plan_analysis(tm, AL, 6000.0, method=method)
        m = analyze(spec, AL, f_max=6000.0, cache=False, error_estimate=False)
        assert 0.5 < p.dofs / m.dofs < 2.0, (spec, p.dofs, m.dofs)
    assert np.isfinite(p.memory_gb)


def test_auto_falls_back_to_hex_when_tetgen_refuses(monkeypatch):
    """A thin wall TetGen cannot mesh (here: made to fail) is voxelized, and the model says why."""
    import mjsound.modal.plan as P
    import mjsound.modal.tet as T

    monkeypatch.setattr(P, "FACET_MIN_COVERAGE", 1.01)  # as if the wall did not pair up (no shell)

    def refuse(*a, **k):
        raise ValueError("tet method: TetGen could not tetrahedralize this mesh (test)")

    monkeypatch.setattr(T, "tetrahedralize", refuse)
    m = analyze("bowl:0.1,0.004", "aluminium", quality="draft", f_max=1500, cache=False, error_estimate=False)
    assert m.method == "hex" and "failed" in m.info["method_choice"] and m.n_modes > 0


def test_thin_wall_over_budget_is_planned_as_hex(monkeypatch):
    bowl = load_mesh("bowl:0.1,0.004")
    facet = plan_analysis(bowl, AL, 20000.0)
    assert facet.method == "facet" and 20000 < facet.dofs < 60000 and facet.memory_gb > 0.7  # built: 34 494
    p = plan_analysis(bowl, AL, 20000.0, max_memory=0.7, over_budget="refuse")  # facet 0.89 GB, hex 0.54
    assert p.method == "hex" and "shell triangles" in p.reason and "over the cap" in p.reason
    import mjsound.modal.plan as P

    monkeypatch.setattr(P, "FACET_MIN_COVERAGE", 1.01)
    tet = plan_analysis(bowl, AL, 20000.0)
    assert tet.method == "tet" and not tet.through_wall and 50000 < tet.dofs < 200000  # built: 98 793
    p = plan_analysis(bowl, AL, 20000.0, max_memory=0.6, over_budget="refuse")
    assert p.method == "hex" and "quadratic tets" in p.reason and p.memory_gb <= 0.6
