"""The eigensolver's fast mass product (mjsound.modal.node_mass)."""

import numpy as np
import scipy.sparse as sp

from mjsound.modal import analyze as A
from mjsound.modal.node_mass import mass_rows, node_mass


def _hex(order=2):
    tm = A.load_mesh("box:0.1,0.04,0.02")
    mat = A.parse_material("aluminium")
    h = A.element_size(tm, mat, 20000.0, "default", 4, order=order)
    pts, _ = A.surface_samples(tm, 32)
    return A._discretize("hex", tm, mat, h, pts, "default", None, order, None)


def test_hex_mass_is_node_mass_times_identity():
    for order in (1, 2):
        d = _hex(order)
        m = node_mass(d.M)
        assert m is not None and m.shape[0] * 3 == d.dofs
        assert abs(sp.kron(m, sp.identity(3)) - d.M).max() == 0.0


def test_mass_rows_equals_sparse_product():
    d = _hex()
    rng = np.random.default_rng(0)
    apply = mass_rows(d.M)
    for b in (1, 5, 12):
        X = rng.standard_normal((b, d.dofs))
        ref = (d.M @ X.T).T
        assert np.max(np.abs(apply(X) - ref)) <= 1e-12 * np.max(np.abs(ref))
    x = rng.standard_normal(d.dofs)
    assert np.allclose(apply(x), d.M @ x, rtol=0, atol=1e-12 * np.abs(d.M @ x).max())


def test_general_mass_falls_back_to_the_sparse_product():
    rng = np.random.default_rng(1)
    n = 30
    B = sp.random(n, n, density=0.2, random_state=2)
    M = (B @ B.T + sp.identity(n)).tocsr()  # couples x and y dofs: no node structure
    assert node_mass(M) is None
    m = sp.diags(np.arange(1.0, 11.0)).tocsr()
    M2 = sp.kron(m, sp.identity(3), format="csr").tolil()
    M2[0, 4] = M2[4, 0] = 1e-3  # one off-axis coupling
    assert node_mass(M2.tocsr()) is None
    assert node_mass(sp.identity(7)) is None  # not 3 dofs per node
    X = rng.standard_normal((4, n))
    assert np.allclose(mass_rows(M)(X), (M @ X.T).T, rtol=1e-14, atol=0)


def test_quadratic_forms_equal_the_dense_products(monkeypatch):
    from mjsound.modal.quadratic_forms import quadratic_forms

    d = _hex()
    Y = np.random.default_rng(3).standard_normal((7, d.dofs))
    ref = np.einsum("ij,ji->i", Y, d.K @ Y.T)
    assert np.allclose(quadratic_forms(d.K, Y), ref, rtol=1e-12, atol=0)
    V = np.ascontiguousarray(Y.T)  # the same vectors as columns, on two threads
    from mjsound.modal import quadratic_forms as qf

    monkeypatch.setattr(qf, "QUADRATIC_PRODUCTS_PER_THREAD", 1)  # small work: split all the same
    assert np.allclose(quadratic_forms(d.K, V, threads=2, columns=True), ref, rtol=1e-12, atol=0)
    B = sp.random(9, 9, density=0.4, random_state=4, format="csr")  # not symmetric
    Z = np.random.default_rng(5).standard_normal((3, 9))
    assert np.allclose(quadratic_forms(B, Z), np.einsum("ij,ji->i", Z, B @ Z.T), rtol=1e-12, atol=1e-14)


def test_kron_identity3_is_scipys_kron():
    from mjsound.modal.node_mass import kron_identity3

    m = sp.random(30, 30, density=0.15, random_state=6, format="csr")
    m = sp.csr_matrix(m + m.T + sp.identity(30))
    m.sort_indices()
    got, ref = kron_identity3(m), sp.kron(m, sp.identity(3), format="csr")
    ref.sort_indices()
    assert got.shape == (90, 90) and got.has_sorted_indices
    assert np.array_equal(got.indptr, ref.indptr) and np.array_equal(got.indices, ref.indices)
    assert np.array_equal(got.data, ref.data)
