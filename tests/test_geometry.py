import numpy as np
import pytest
import trimesh

from mjsound.geometry import builtin_mesh, load_mesh


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
