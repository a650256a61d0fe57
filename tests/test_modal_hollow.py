"""Hollow objects: wall= on closed and open surfaces (mjsound.modal.surface.hollow)."""

import numpy as np
import pytest
import trimesh

from mjsound import analyze
from mjsound.materials import parse_material
from mjsound.modal.surface import _delaunay_flips, hollow, refine_to_size, vertex_offsets

STEEL = parse_material("steel")


def test_closed_box_wall_is_exact():
    box = trimesh.creation.box(extents=[0.1, 0.2, 0.3])
    h = hollow(box, 0.01)
    assert h.is_watertight and h.volume == pytest.approx(0.1 * 0.2 * 0.3 - 0.08 * 0.18 * 0.28, rel=1e-12)
    # every inner vertex sits exactly one wall inside each of its outer faces
    assert np.allclose(np.abs(h.vertices[8:]), [0.04, 0.09, 0.14])


def test_cylinder_wall_keeps_facets_a_wall_apart():
    n, R, H, t = 48, 0.05, 0.1, 0.002
    can = hollow(trimesh.creation.cylinder(radius=R, height=H, sections=n), t)
    area = lambda r: 0.5 * n * r**2 * np.sin(2 * np.pi / n)  # noqa: E731  polygon of circumradius r
    inner = R - t / np.cos(np.pi / n)
    assert can.volume == pytest.approx(area(R) * H - area(inner) * (H - 2 * t), rel=1e-9)


def test_open_surface_wall_is_a_slab_of_exactly_that_thickness():
    v = np.array([[0, 0, 0], [0.1, 0, 0], [0.1, 0.1, 0], [0, 0.1, 0]], float)
    slab = hollow(trimesh.Trimesh(v, [[0, 1, 2], [0, 2, 3]], process=False), 0.003)
    assert slab.is_watertight and slab.volume == pytest.approx(0.1 * 0.1 * 0.003, rel=1e-12)
    assert np.ptp(slab.vertices[:, 2]) == pytest.approx(0.003)


def test_too_thick_wall_and_bad_input_named():
    with pytest.raises(ValueError, match="too thick"):
        hollow(trimesh.creation.box(extents=[0.1, 0.1, 0.1]), 0.06)
    with pytest.raises(ValueError, match="wall"):
        hollow(trimesh.creation.box(extents=[0.1, 0.1, 0.1]), -1)
    with pytest.raises(ValueError, match="wall"):
        analyze("box:0.1,0.1,0.1", "steel", wall="thin", cache=False)


def test_a_narrow_feature_thins_the_wall_under_it_only(monkeypatch):
    import mjsound.modal.surface as surface

    # a 5 cm can with a rolled rim 0.3 mm wide: a 0.4 mm wall would turn the inner surface
    # inside out under the rim; there (0.5 % of the area) the wall gets thinner
    profile = np.array([[0, 0], [25, 0], [25, 79.5], [25.3, 79.5], [25.3, 80], [0, 80]]) * 1e-3
    can = trimesh.creation.revolve(profile, sections=48)
    slab = hollow(can, 0.4e-3)
    assert slab.is_watertight and slab.is_winding_consistent and slab.volume > 0
    assert 0 < slab.metadata["thinned_area"] < surface.MAX_THINNED_AREA
    inner = np.asarray(slab.vertices)[len(can.vertices):]
    gap = np.linalg.norm(np.asarray(can.vertices) - inner, axis=1)
    r = np.hypot(*np.asarray(can.vertices)[:, :2].T)
    assert np.all(gap[(r < 24e-3) & (np.asarray(can.vertices)[:, 2] < 79e-3)] > 0.399e-3)  # the body keeps its wall
    assert 0 < gap.min() < 0.4e-3
    assert hollow(can, 0.1e-3).metadata["thinned_area"] == 0.0
    monkeypatch.setattr(surface, "MAX_THINNED_AREA", 1e-3)
    with pytest.raises(ValueError, match=r"too thick .* 0\.5 % of the surface"):
        hollow(can, 0.4e-3)


def test_offsets_smooth_surface_along_normals():
    s = trimesh.creation.icosphere(subdivisions=3, radius=0.1)
    d = vertex_offsets(s, 0.001)
    cos = np.einsum("ij,ij->i", d, s.vertex_normals) / np.linalg.norm(d, axis=1)
    assert cos.min() > 0.999 and np.allclose(np.linalg.norm(d, axis=1), 0.001, rtol=0.01)


def test_refinement_keeps_the_surface_and_bounds_edges():
    can = trimesh.creation.cylinder(radius=0.05, height=0.1, sections=48)
    V, F = refine_to_size(can.vertices, can.faces, 0.0125)
    m = trimesh.Trimesh(V, F, process=False)
    assert m.is_watertight and m.edges_unique_length.max() <= 0.0125
    assert m.volume == pytest.approx(can.volume, rel=1e-12) and m.area == pytest.approx(can.area, rel=1e-12)
    # flips keep flat regions flat and the mesh closed; a non-Delaunay pair is flipped
    sq = np.array([[0, 0, 0], [1, 0, 0], [1, 0.2, 0], [0, 0.2, 0]], float)
    F2 = _delaunay_flips(sq, np.array([[0, 1, 3], [1, 2, 3]]))
    assert {tuple(sorted(f)) for f in F2} in ({(0, 1, 3), (1, 2, 3)}, {(0, 1, 2), (0, 2, 3)})


def test_wall_material_spec_and_argument_agree_and_mass_follows():
    """A closed box with a 5 mm wall: 'steel,wall=5mm' and wall=0.005 give the same model; the
    mass is the wall's (exact volume x rho), not the solid box's."""
    kw = dict(method="hex", quality="draft", f_max=6000, cache=False, error_estimate=False)
    a = analyze("box:0.12,0.1,0.08", "steel,wall=5mm", **kw)
    b = analyze("box:0.12,0.1,0.08", "steel", wall=0.005, **kw)
    assert np.allclose(a.frequencies_hz, b.frequencies_hz)
    wall_volume = 0.12 * 0.1 * 0.08 - 0.11 * 0.09 * 0.07
    assert a.mass_kg == pytest.approx(wall_volume * STEEL.rho, rel=0.05)  # draft voxels: 3 % light
    solid = analyze("box:0.12,0.1,0.08", "steel", **kw)
    assert solid.mass_kg > 3 * a.mass_kg


def test_open_square_with_wall_rings_like_the_plate():
    """A zero-volume square with wall=2 mm is the 2 mm free square plate: first mode
    13.468 / (2 pi a^2) sqrt(D / rho t) (Leissa, NASA SP-160, table 4.49, nu = 0.3)."""
    v = np.array([[0, 0, 0], [0.1, 0, 0], [0.1, 0.1, 0], [0, 0.1, 0]], float)
    m = analyze((v, np.array([[0, 1, 2], [0, 2, 3]])), "steel", wall="2mm", f_max=5000, cache=False,
                error_estimate=False)
    D = STEEL.E * 0.002**3 / (12 * (1 - STEEL.nu**2))
    ref = 13.468 / (2 * np.pi * 0.1**2) * np.sqrt(D / (STEEL.rho * 0.002))
    assert m.frequencies_hz[0] == pytest.approx(ref, rel=0.02)
    assert m.mass_kg == pytest.approx(0.1 * 0.1 * 0.002 * STEEL.rho, rel=0.02)
    assert m.info["wall"] == 0.002 and "hex" in m.info["method_choice"]


def test_inward_part_is_a_cavity_only_inside_a_solid():
    from mjsound.modal.surface import cavities

    outer = trimesh.creation.box(extents=[0.1, 0.1, 0.1])
    inner = trimesh.creation.box(extents=[0.05, 0.05, 0.05])
    inner.invert()
    apart = trimesh.creation.box(extents=[0.05, 0.05, 0.05])
    apart.apply_translation([1.0, 0, 0])
    apart.invert()
    assert cavities([outer, inner, apart]) == [False, True, False]
    assert cavities([inner]) == [False]  # a lone flipped box is a solid
