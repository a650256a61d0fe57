import numpy as np
import pytest
import trimesh

from mjsound.geometry import builtin_mesh, load_mesh, surface_report


def test_builtins_have_the_right_size():
    assert np.allclose(load_mesh("box:0.5,0.01,0.02").extents, [0.5, 0.01, 0.02])
    cyl = load_mesh("cylinder:0.01,0.5")
    assert np.allclose(cyl.extents, [0.02, 0.02, 0.5], rtol=2e-3)
    bowl = builtin_mesh("bowl:0.1,0.004")
    assert bowl.is_watertight and bowl.volume > 0
    # hemispherical shell volume 2/3 pi (R^3 - r^3)
    assert bowl.volume == pytest.approx(2 / 3 * np.pi * (0.1**3 - 0.096**3), rel=0.02)


def test_bad_meshes_are_refused_with_a_reason():
    with pytest.raises(ValueError, match="empty|non-empty"):
        load_mesh((np.zeros((0, 3)), np.zeros((0, 3), int)))
    v = np.array([[0, 0, 0], [1, 0, 0], [0, np.nan, 0]], float)
    with pytest.raises(ValueError, match="NaN"):
        load_mesh((v, [[0, 1, 2]]))
    flat = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0]], float)  # collinear: zero area
    with pytest.raises(ValueError, match="zero area"):
        load_mesh((flat, [[0, 1, 2]]))
    with pytest.raises(ValueError, match="face indices"):
        load_mesh((flat, [[0, 1, 5]]))
    with pytest.raises(ValueError, match="built-in"):
        load_mesh("no/such/file.obj")
    with pytest.raises(ValueError, match="positive"):
        load_mesh("box:1,0,1")


def test_millimetre_mesh_warns():
    with pytest.warns(UserWarning, match="millimetres"):
        load_mesh(trimesh.creation.box(extents=[500, 10, 10]))


def test_duplicate_vertices_and_faces_are_cleaned():
    box = trimesh.creation.box()
    v = np.vstack([box.vertices, box.vertices])  # every vertex twice
    f = np.vstack([box.faces, box.faces + 8, box.faces])  # faces through both copies, plus duplicates
    tm = load_mesh((v, f))
    assert len(tm.vertices) == 8 and len(tm.faces) == 12


def write_textured_box_obj(path, extents):
    """An OBJ box as exporters write it: 4 vertices per face (24), each with its own texture
    coordinate and normal, so no face shares a vertex index with its neighbours."""
    box = trimesh.creation.box(extents=extents)
    lines, faces, nxt = [], [], 1
    for f in range(6):
        tri = box.faces[2 * f : 2 * f + 2]
        n = box.face_normals[2 * f]
        corners = list(dict.fromkeys(tri.ravel().tolist()))
        idx = {}
        for j, k in enumerate(corners):
            lines += ["v %.9f %.9f %.9f" % tuple(box.vertices[k]), f"vt {j % 2} {j // 2}", "vn %g %g %g" % tuple(n)]
            idx[k] = nxt + j
        faces += ["f " + " ".join(f"{idx[k]}/{idx[k]}/{idx[k]}" for k in t) for t in tri]
        nxt += len(corners)
    path.write_text("\n".join(lines + faces) + "\n")
    return path


def test_textured_obj_is_welded_into_a_closed_surface(tmp_path):
    p = write_textured_box_obj(tmp_path / "cube.obj", [0.05, 0.05, 0.05])
    raw = trimesh.load(p, force="mesh", process=False)
    assert not raw.is_watertight  # as the file says: 6 separate quads
    tm = load_mesh(p)
    assert len(tm.vertices) == 8 and len(tm.faces) == 12 and tm.is_watertight
    rep = surface_report(tm)
    assert rep["closed"] and rep["boundary_edges"] == 0
    assert rep["volume_m3"] == pytest.approx(0.05**3, rel=1e-9)


def test_zero_area_faces_that_close_a_surface_are_kept():
    """A T-junction: a vertex m on the cube edge a-b splits one face into two; the sliver
    face (b, m, a) of zero area is what closes the surface. Removing it would open the cube
    (and the analysis would make it a hollow shell)."""
    box = trimesh.creation.box(extents=[1, 1, 1])
    v, f = np.array(box.vertices), [list(x) for x in box.faces]
    edges = {}
    for i, (p, q, r) in enumerate(f):
        for a, b in ((p, q), (q, r), (r, p)):
            edges[(a, b)] = i
    (a, b), i1 = next(iter(edges.items()))
    c = [x for x in f[i1] if x not in (a, b)][0]
    m = len(v)
    v = np.vstack([v, 0.5 * (v[a] + v[b])])
    # face i1 = (a, b, c) in some rotation: replace it by (a, m, c) and (m, b, c)
    f[i1] = [a, m, c]
    f.append([m, b, c])
    f.append([b, m, a])  # the zero-area sliver
    tm = load_mesh((v, np.array(f)))
    assert tm.is_watertight and abs(tm.volume) == pytest.approx(1.0)
    # a zero-area face on an open surface still goes
    sheet = (np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0]], float), np.array([[0, 1, 2], [0, 1, 3]]))
    assert len(load_mesh(sheet).faces) == 1
    assert not surface_report(load_mesh(sheet))["closed"]


def test_textured_obj_bar_analyses_like_the_solid_bar(tmp_path):
    """The textured OBJ of a 30 cm x 2 cm x 2 cm aluminium bar has the mass and the modes of the
    built-in box: a solid, not a hollow voxel shell."""
    from mjsound.modal.analyze import analyze

    p = write_textured_box_obj(tmp_path / "bar.obj", [0.3, 0.02, 0.02])
    kw = dict(quality="draft", sample_rate=16000, error_estimate=False, cache=False)
    obj = analyze(str(p), "aluminium", **kw)
    ref = analyze("box:0.3,0.02,0.02", "aluminium", **kw)
    assert obj.mass_kg == pytest.approx(2700 * 0.3 * 0.02 * 0.02, rel=1e-6)
    assert obj.info["watertight"]
    assert obj.n_modes == ref.n_modes >= 2
    np.testing.assert_allclose(obj.frequencies_hz, ref.frequencies_hz, rtol=1e-6)
