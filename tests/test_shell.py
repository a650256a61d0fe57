"""Raghuvanshi spring-mass shell (mjsound.modal.shell): structure and exact scaling laws."""

import json

import numpy as np
import pytest
import scipy.linalg as sl
import trimesh

from mjsound.materials import Material
from mjsound.modal.shell import discretize_shell

AL = Material(E=70e9, nu=0.33, rho=2700, name="aluminium")


def freqs(d):
    lam = sl.eigh(d.K.toarray(), d.M.toarray(), eigvals_only=True)
    return np.sign(lam) * np.sqrt(np.abs(lam)) / (2 * np.pi)


def n_zero(f):
    return int(np.sum(np.abs(f) < 1e-4 * np.abs(f).max()))


@pytest.mark.parametrize(
    "mesh",
    [trimesh.creation.icosphere(subdivisions=2, radius=0.1),
     trimesh.creation.box(extents=[0.1, 0.2, 0.3])],
    ids=["icosphere", "box"],
)
def test_closed_convex_surface_has_six_rigid_modes(mesh):
    d = discretize_shell(mesh, AL, mesh.vertices, thickness=0.002)
    json.dumps(d.info)
    f = freqs(d)
    assert n_zero(f) == 6
    assert d.n_rigid == 6
    assert abs(d.K - d.K.T).max() == 0


def test_flat_regions_and_open_surfaces_have_mechanisms():
    # documented limitation: no bending stiffness; a vertex inside a flat region can move
    # out of plane for free (subdivided box: 6 face-centre vertices -> 6 extra zeros)
    box = trimesh.creation.box(extents=[0.1, 0.2, 0.3]).subdivide()
    assert n_zero(freqs(discretize_shell(box, AL, box.vertices, 0.002))) == 12
    # an open flat plate: all 25 vertices move out of plane for free (25 + 3 in-plane
    # rigid modes; the springs are all in the plane)
    plate = trimesh.Trimesh(*_grid_plate(5))
    assert n_zero(freqs(discretize_shell(plate, AL, plate.vertices, 0.002))) == 25 + 3


def _grid_plate(n, size=0.1):
    x, y = np.meshgrid(np.linspace(0, size, n), np.linspace(0, size, n), indexing="ij")
    V = np.c_[x.ravel(), y.ravel(), np.zeros(n * n)]
    i = np.arange(n - 1)
    a = (i[:, None] * n + i[None, :]).ravel()
    F = np.vstack([np.c_[a, a + n, a + 1], np.c_[a + 1, a + n, a + n + 1]])
    return V, F


@pytest.fixture(scope="module")
def sphere_f():
    m = trimesh.creation.icosphere(subdivisions=2, radius=0.1)
    return m, freqs(discretize_shell(m, AL, m.vertices, 0.002))[6:]


def test_scaling_E(sphere_f):
    m, f = sphere_f
    f4 = freqs(discretize_shell(m, AL.scaled(stiffness=4.0), m.vertices, 0.002))[6:]
    np.testing.assert_allclose(f4, 2 * f, rtol=1e-6)


@pytest.mark.parametrize("scale_t", [True, False])
def test_scaling_geometry(sphere_f, scale_t):
    # omega^2 = k/m = E t / (rho t a) = E / (rho a): frequencies go as 1/s whether or not
    # the thickness scales with the geometry
    m, f = sphere_f
    s = 3.0
    ms = m.copy()
    ms.apply_scale(s)
    fs = freqs(discretize_shell(ms, AL, ms.vertices, 0.002 * (s if scale_t else 1.0)))[6:]
    np.testing.assert_allclose(fs, f / s, rtol=1e-6)


def test_thickness_cancels(sphere_f):
    m, f = sphere_f
    f2 = freqs(discretize_shell(m, AL, m.vertices, 0.01))[6:]
    np.testing.assert_allclose(f2, f, rtol=1e-6)


def test_mass_springs_and_interp():
    m = trimesh.creation.icosphere(subdivisions=2, radius=0.1)
    pts = np.vstack([trimesh.sample.sample_surface(m, 300, seed=3)[0], m.vertices])
    d = discretize_shell(m, AL, pts, 0.002)
    assert d.interp.shape == (3 * len(pts), d.dofs)
    ex = np.zeros(d.dofs)
    ex[0::3] = 1
    assert ex @ (d.M @ ex) == pytest.approx(AL.rho * 0.002 * m.area, rel=1e-12)
    assert d.info["spring_k"] == pytest.approx(AL.E * 0.002)
    rng = np.random.default_rng(0)
    t = rng.normal(size=3)
    np.testing.assert_allclose(d.interp @ np.tile(t, d.dofs // 3), np.tile(t, len(pts)),
                               atol=1e-12)
    # vertices are reproduced exactly; infinitesimal rotations cost no spring energy
    X = m.vertices
    u = np.cross(rng.normal(size=3), X).reshape(-1)
    np.testing.assert_allclose((d.interp @ u)[-3 * len(X):], u, atol=1e-12)
    assert np.abs(d.K @ u).max() < 1e-9 * abs(d.K).max() * np.abs(u).max()
    assert d.info["max_point_distance"] < 0.01  # samples lie on the mesh (within faceting)


def test_duplicate_vertices_are_merged():
    m = trimesh.creation.icosphere(subdivisions=1, radius=0.1)
    soup = trimesh.Trimesh(m.vertices[m.faces].reshape(-1, 3),
                           np.arange(3 * len(m.faces)).reshape(-1, 3), process=False)
    d = discretize_shell(soup, AL, m.vertices, 0.002)
    assert d.dofs == 3 * len(m.vertices)
    assert n_zero(freqs(d)) == 6


@pytest.mark.parametrize("t", [0.0, -1e-3, float("nan")])
def test_bad_thickness(t):
    m = trimesh.creation.icosphere(subdivisions=1)
    with pytest.raises(ValueError, match="thickness"):
        discretize_shell(m, AL, m.vertices, t)
