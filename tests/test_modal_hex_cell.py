"""The exact quadratic hex cell (mjsound.modal.hex_cell) against closed forms and the
voxel-children sum it is the limit of."""

import numpy as np
import pytest

from mjsound.materials import parse_material
from mjsound.modal.hex import (_child_interpolations_lagrange, _congruence, _elasticity_matrix,
                               _serendipity_embedding, _serendipity_nodes, hex_element_matrices)
from mjsound.modal.hex_cell import CellSum, quadratic_cell_matrices

AL = parse_material("aluminium")
SIZE = np.array([0.03, 0.02, 0.01])


def _nodes(embed):
    loc = np.array([[a, b, c] for c in range(3) for b in range(3) for a in range(3)]) / 2.0 * SIZE
    return loc if embed is None else loc[_serendipity_nodes()]


@pytest.mark.parametrize("embed", [None, _serendipity_embedding()])
def test_rigid_motions_cost_nothing_and_constant_strain_is_exact(embed):
    K, m = quadratic_cell_matrices(SIZE, AL, 3, embed)
    x = _nodes(embed)
    n = len(x)
    assert K.shape == (3 * n, 3 * n) and m.shape == (n, n)
    for W in [np.eye(3)[i] * np.ones((n, 1)) for i in range(3)] + [np.cross(np.eye(3)[i], x) for i in range(3)]:
        assert np.abs(K @ W.ravel()).max() < 1e-6 * np.abs(K).max()
    eps = np.array([[1.0, 0.3, -0.2], [0.3, -0.5, 0.4], [-0.2, 0.4, 0.7]]) * 1e-4
    u = (x @ eps.T).ravel()
    voigt = np.array([eps[0, 0], eps[1, 1], eps[2, 2], 2 * eps[0, 1], 2 * eps[1, 2], 2 * eps[0, 2]])
    vol = np.prod(SIZE)
    assert u @ K @ u == pytest.approx(vol * voigt @ _elasticity_matrix(AL) @ voigt, rel=1e-10)
    assert m.sum() == pytest.approx(AL.rho * vol, rel=1e-12)


def test_children_sum_converges_to_the_exact_cell():
    """The voxel children's sum (incompatible-mode trilinear children of the quadratic
    field) approaches the exact cell as 1/r^2: what a full cell used to cost r^3 congruences for."""
    embed = _serendipity_embedding()
    K, m = quadratic_cell_matrices(SIZE, AL, 3, embed)
    err = []
    for r in (2, 4, 8):
        Lu = _child_interpolations_lagrange(r, 3) @ np.kron(embed, np.eye(3))
        Kf, Mf = hex_element_matrices(SIZE / r, AL)
        Kr = _congruence(Lu, Kf).sum(axis=0)
        Mr = _congruence(Lu[:, 0::3, 0::3], Mf[0::3, 0::3]).sum(axis=0)
        err.append((np.linalg.norm(Kr - K) / np.linalg.norm(K), np.linalg.norm(Mr - m) / np.linalg.norm(m)))
    err = np.array(err)
    assert np.all(err[1:] < err[:-1] / 3.5), err  # 1/r^2: ~4x per halving, towards this limit
    assert err[-1, 0] < 0.03 and err[-1, 1] < 0.04, err


def test_cell_sum_uses_the_full_cell_and_builds_the_table_only_when_needed():
    rng = np.random.default_rng(0)
    A = rng.normal(size=(8, 4, 4))
    A = A + np.swapaxes(A, 1, 2)
    full = rng.normal(size=(4, 4))
    full = full + full.T
    calls = []

    def build():
        calls.append(1)
        return A

    s = CellSum(build, 4, full=full)
    assert np.allclose(s(np.ones((3, 8))), np.tile(full.ravel(), (3, 1))) and not calls
    w = np.vstack([np.ones(8), rng.uniform(size=8)])
    out = s(w)
    assert len(calls) == 1
    assert np.allclose(out[0], full.ravel()) and np.allclose(out[1], np.einsum("c,cij->ij", w[1], A).ravel())
    plain = CellSum(lambda: A, 4)  # no full matrix given: the children's sum
    assert np.allclose(plain(np.ones((1, 8)))[0], A.sum(axis=0).ravel())


def _cut_cell_children(r, z0):
    """Occupancy and first moments (r^3,), (r^3, 3) of the children of a cell filled below
    the height z0 (a fraction of the cell): layer k holds ``o = clip(z0 r - k, 0, 1)`` with
    its centroid ``o / 2 - 1 / 2`` children below the layer's centre."""
    abc = np.stack(np.meshgrid(np.arange(r), np.arange(r), np.arange(r), indexing="ij"), -1).reshape(-1, 3)
    o = np.clip(z0 * r - abc[:, 2], 0.0, 1.0)
    mom = np.zeros((r**3, 3))
    mom[:, 2] = o * (o / 2 - 0.5)
    return o, mom


def test_moments_place_the_mass_of_partly_filled_children():
    """A quadratic cell filled below 0.3 of its height with 4 children per axis: the first
    moment of its mass (1^T M z) is exact with the children's moments and off without
    (their material counted at their centres); the stiffness stays positive semi-definite
    even for children a sliver full at their far side."""
    from mjsound.modal.hex import _cell_operators

    embed = _serendipity_embedding()
    r, z0 = 4, 0.3
    hf = SIZE / r
    o, mom = _cut_cell_children(r, z0)
    z = _nodes(embed)[:, 2]
    want = AL.rho * SIZE[0] * SIZE[1] * (z0 * SIZE[2]) ** 2 / 2  # rho * integral of z over the filled part
    got = {}
    for moments in (False, True):
        cell_K, cell_M = _cell_operators(hf, r, AL, 2, True, embed, moments=moments)
        m = cell_M(o[None], mom[None, :, :]).reshape(20, 20)
        assert m.sum() == pytest.approx(AL.rho * np.prod(SIZE) * z0, rel=1e-9)  # the mass either way
        got[moments] = m.sum(axis=0) @ z
    assert got[True] == pytest.approx(want, rel=1e-9)
    assert abs(got[False] / want - 1) > 0.01
    rng = np.random.default_rng(3)
    occ = rng.uniform(0.0, 0.05, (2, r**3))  # slivers at the children's corners
    d = rng.choice([-0.49, 0.49], (2, r**3, 3))
    cell_K, _ = _cell_operators(hf, r, AL, 2, True, embed, moments=True)
    # node-block order (a, b, i, j) -> dofs (3 a + i, 3 b + j)
    K = cell_K(occ, occ[:, :, None] * d).reshape(2, 20, 20, 3, 3).transpose(0, 1, 3, 2, 4).reshape(2, 60, 60)
    for k in K:
        assert np.allclose(k, k.T, atol=1e-9 * np.abs(k).max())
        w = np.linalg.eigvalsh(k)
        assert w.min() > -1e-9 * w.max(), w[:3]
