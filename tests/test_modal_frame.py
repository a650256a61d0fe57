"""Analysis along a mesh's principal axes (mjsound.modal.frame): a bar at an angle to the
coordinate axes rings as it does along them, and its model comes back in its own frame."""

import numpy as np
import pytest
import trimesh

from mjsound import analyze
from mjsound.geometry import load_mesh
from mjsound.modal.frame import into_frame, principal_frame
from mjsound.report.accuracy_modal import rod_bending_references

AXIS = np.array([1.0, 0.3, 0.0]) / np.linalg.norm([1.0, 0.3, 0.0])


def _turned(spec, degrees):
    tm = load_mesh(spec)
    tm.apply_transform(trimesh.transformations.rotation_matrix(np.radians(degrees), AXIS))
    return tm


def test_principal_frame_only_where_it_fits_much_better():
    for spec in ("box:0.5,0.01,0.01", "cylinder:0.01,0.5", "sphere:0.05", "bowl:0.1,0.004", "box:0.3,0.3,0.002"):
        assert principal_frame(load_mesh(spec)) is None, spec  # along the axes (or no clear axes)
    bar = _turned("box:0.5,0.02,0.01", 30)
    Q, c = principal_frame(bar)
    assert np.allclose(Q.T @ Q, np.eye(3), atol=1e-12) and np.linalg.det(Q) == pytest.approx(1.0)
    inner = into_frame(bar, (Q, c))
    assert np.allclose(np.sort(inner.extents), [0.01, 0.02, 0.5], atol=1e-9)
    assert inner.volume == pytest.approx(bar.volume, rel=1e-9) and inner.is_winding_consistent
    assert np.allclose(inner.bounds.mean(axis=0), 0.0, atol=1e-9)


def test_turned_rod_rings_as_the_straight_one_and_returns_in_its_frame():
    """The round rod turned by 30 degrees: its bounding box (92 mm at the smallest) made auto
    take it for a thin wall (quadratic tets through it: 114k dofs, a minute) and the axis-
    aligned voxels cut its section obliquely (+14 .. +17 cents). Along its principal axes it
    is the straight rod: the same bending pairs within 5 cents of Timoshenko's beam; the
    model's points lie on the turned surface and its bending modes move across the axis."""
    tm = _turned("cylinder:0.01,0.5", 30)
    m = analyze(tm, "aluminium", f_max=3000, cache=False)
    assert m.method == "hex" and m.info["grid"][:2] == [3, 3] and "analysis_frame" in m.info
    c = 1200 * np.log2(m.frequencies_hz[:6] / np.repeat(rod_bending_references()[:3], 2))
    assert len(m.frequencies_hz) == 6 and np.all(np.abs(c) < 5.0), c
    from mjsound.modal.analyze import surface_samples

    points, normals = surface_samples(tm)  # what an analysis in the given frame samples
    assert np.allclose(m.points, points, atol=1e-6) and np.allclose(m.normals, normals, atol=1e-5)
    frame = m.info["analysis_frame"]
    axes = np.asarray(frame["axes"])  # rows: the principal axes in the mesh's frame
    rod_axis = axes[np.argmax(np.ptp((np.asarray(tm.vertices) - frame["centre"]) @ axes.T, axis=0))]
    assert abs(abs(rod_axis @ np.array([0.0, 0.0, 1.0])) - 1.0) > 0.1  # the turned axis, not z
    U = m.shapes.astype(float)  # bending: mostly across the axis (the sections' turn moves some along it)
    along = (np.einsum("pcn,c->pn", U, rod_axis) ** 2).sum(axis=0) / (U**2).sum(axis=(0, 1))
    assert np.all(along < 0.05), along
