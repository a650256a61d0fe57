"""The band eigensolver (mjsound.modal.eigen) against dense LAPACK on small hex models."""

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp

from mjsound.modal import analyze as A
from mjsound.modal import eigen as E
from mjsound.modal.hex import _sum_blocks


def _model(spec="box:0.1,0.1,0.1", material="steel", resolution=3):
    tm = A.load_mesh(spec)
    mat = A.parse_material(material)
    h = A.element_size(tm, mat, 20000.0, "default", resolution, order=2)
    pts, _ = A.surface_samples(tm, 64)
    return A._discretize("hex", tm, mat, h, pts, "default", None, 2, None)


@pytest.fixture(scope="module")
def cube():
    d = _model()
    w = sla.eigh(d.K.toarray(), d.M.toarray(), eigvals_only=True)
    return d, w


def _band(w, lo, hi):
    return w[(w >= lo) & (w <= hi)]


def _cut(w, i):
    """A band top in the first clear gap of the spectrum at or after index i (the cube's
    eigenvalues come in pairs and triples)."""
    while w[i + 1] < w[i] * (1 + 1e-3):
        i += 1
    return 0.5 * (w[i] + w[i + 1])


@pytest.mark.parametrize("backend", ["superlu", "pardiso"])
def test_block_band_matches_dense(cube, backend):
    if backend == "pardiso" and E.backend_name() != "pardiso":
        pytest.skip("pypardiso not installed")
    d, w = cube
    lo, hi = (2 * np.pi * 20) ** 2, _cut(w, 66)
    sol = E.solve_band(d.K, d.M, lo, hi, dense_max=10, backend=backend)
    ref = _band(w, lo, hi)
    assert sol.backend.startswith("block-lanczos")
    assert len(sol.eigenvalues) == len(ref) and sol.n_below == 6
    assert np.allclose(sol.eigenvalues, ref, rtol=1e-9)
    V = sol.vectors
    assert np.allclose(V.T @ (d.M @ V), np.eye(V.shape[1]), atol=1e-9)
    # eigenpairs: K v = lambda M v, to the Ritz tolerance (the eigenvalues, Rayleigh
    # quotients, are exact to its square: 1e-9 above), in the norm the shift-invert
    # criterion bounds: ||(K - sigma M)^-1 r||_M = (lambda - sigma) ||T v - mu v||_M <= tol
    # for a shift sigma below the band (the residual r itself is dominated by traces of
    # the cells' stiff internal modes, which move no eigenvalue)
    import scipy.sparse.linalg as spla

    R = d.K @ V - (d.M @ V) * sol.eigenvalues
    Z = spla.splu((d.K + 1e-3 * hi * d.M).tocsc()).solve(R)
    assert np.max(np.sqrt(np.einsum("ij,ij->j", Z, d.M @ Z))) < 2 * E.BLOCK_TOL


def test_slicing_fallback_gives_the_same_band(cube, monkeypatch):
    """ARPACK slices find the block solve's band, exact triples included (one copy of a
    triple was left out until the slices were searched again, deflated, on a short count)."""
    d, w = cube
    lo, hi = (2 * np.pi * 20) ** 2, _cut(w, 40)
    block = E.solve_band(d.K, d.M, lo, hi, dense_max=10)
    monkeypatch.setattr(E, "BLOCK_MAX_MODES", 4)  # too many for one block solve: ARPACK slices
    sliced = E.solve_band(d.K, d.M, lo, hi, dense_max=10, slice_modes=20)
    assert not sliced.backend.startswith("block") and sliced.n_slices > 1
    assert np.allclose(block.eigenvalues, sliced.eigenvalues, rtol=1e-8)
    assert np.allclose(block.eigenvalues, _band(w, lo, hi), rtol=1e-9)


def test_inertia_count_pardiso_equals_superlu(cube):
    d, w = cube
    lam = _cut(w, 30)
    expect = int(np.sum(w < lam))
    assert E.count_below(d.K, d.M, lam, backend="superlu") == expect
    if E.backend_name() == "pardiso":
        assert E.count_below(d.K, d.M, lam, backend="pardiso") == expect


def test_pardiso_block_solve_matches_vector_solves(cube):
    """A block solve agrees with one-vector solves, and the same block cut in halves over
    two factorizations (:class:`_SplitSolve`) gives the same bits."""
    if E.backend_name() != "pardiso":
        pytest.skip("pypardiso not installed")
    from concurrent.futures import ThreadPoolExecutor

    d, _ = cube
    A_ = (d.K + 1e7 * d.M).tocsr()
    solve = E.factorize(A_, "pardiso", definite=True)
    B = np.random.default_rng(0).standard_normal((A_.shape[0], 5))
    X = solve(B)
    assert np.allclose(X[:, 2], solve(B[:, 2]), rtol=1e-12, atol=0)
    assert np.linalg.norm(A_ @ X - B) < 1e-8 * np.linalg.norm(B)
    B16 = np.random.default_rng(1).standard_normal((A_.shape[0], 16))
    with ThreadPoolExecutor(1) as pool:
        split = E._SplitSolve(solve, pool, pool.submit(E.factorize, A_, "pardiso", True))
        split.second.result()
        assert np.array_equal(split(B16), solve(B16))


def test_pardiso_factor_is_released_once_when_dropped(cube, monkeypatch):
    """PARDISO keeps its factor in MKL's memory, out of the garbage collector's sight: a
    dropped solve must release it (phase -1), and an explicit free must not release twice
    (an 81k-dof factor is ~300 MB; six dropped solves held 1.9 GB)."""
    if E.backend_name() != "pardiso":
        pytest.skip("pypardiso not installed")
    import gc

    from mjsound.modal import pardiso as P

    phases = []
    call = P._Pardiso._call

    def spy(self, phase, B):
        phases.append(phase)
        return call(self, phase, B)

    monkeypatch.setattr(P._Pardiso, "_call", spy)
    d, _ = cube
    A_ = (d.K + 1e7 * d.M).tocsr()
    solve = E.factorize(A_, "pardiso", definite=True)
    solve(np.ones(A_.shape[0]))
    assert phases == [12, 33]
    del solve
    gc.collect()
    assert phases == [12, 33, -1]
    fac = P._Pardiso(A_, -2)
    fac.free()
    fac.free()
    del fac
    gc.collect()
    assert phases == [12, 33, -1, 12, -1]


def test_early_start_and_split_solves_give_the_band_bit_for_bit(cube, monkeypatch):
    """With two cores, block Lanczos starts before the count is known and shares its solves
    and Gram-Schmidt passes with a second factorization once that is ready: the band is
    right, and the same bit for bit whether the second copy joins in early or never."""
    if E.backend_name() != "pardiso":
        pytest.skip("pypardiso not installed")
    d, w = cube
    lo, hi = (2 * np.pi * 20) ** 2, _cut(w, 66)
    monkeypatch.setattr(E, "INTERIOR_SHIFT", None)  # the definite shift below zero
    monkeypatch.setattr(E, "SPLIT_MIN_DOFS", 0)
    split_calls = []
    split_call = E._SplitSolve.__call__

    def spy(self, B):
        split_calls.append(self._ready() and B.shape[1] >= 8)
        return split_call(self, B)

    monkeypatch.setattr(E._SplitSolve, "__call__", spy)
    fractions = []
    joined = E.solve_band(d.K, d.M, lo, hi, dense_max=10, backend="pardiso", progress=fractions.append)
    assert sum(split_calls) > 0  # some block solves really were shared
    # the progress bar moves with the basis and ends full
    assert len(fractions) > 3 and fractions[-1] == 1.0 and np.all(np.diff(fractions) >= 0)
    assert max(fractions[:-1]) <= 0.95
    assert len(joined.eigenvalues) == len(_band(w, lo, hi)) and joined.n_below == 6
    assert np.allclose(joined.eigenvalues, _band(w, lo, hi), rtol=1e-9)
    monkeypatch.setattr(E._SplitSolve, "_ready", lambda self: False)
    alone = E.solve_band(d.K, d.M, lo, hi, dense_max=10, backend="pardiso")
    assert np.array_equal(joined.eigenvalues, alone.eigenvalues)
    assert np.array_equal(joined.vectors, alone.vectors)


def test_early_start_gives_up_when_the_count_is_too_large(cube, monkeypatch):
    """A count above BLOCK_MAX_MODES, known only after the early start, hands the band to
    spectrum slicing, which finds it all."""
    if E.backend_name() != "pardiso":
        pytest.skip("pypardiso not installed")
    d, w = cube
    lo, hi = (2 * np.pi * 20) ** 2, _cut(w, 40)
    monkeypatch.setattr(E, "INTERIOR_SHIFT", None)  # the definite shift below zero
    monkeypatch.setattr(E, "SPLIT_MIN_DOFS", 0)
    monkeypatch.setattr(E, "BLOCK_MAX_MODES", 10)
    sol = E.solve_band(d.K, d.M, lo, hi, dense_max=10, slice_modes=20, backend="pardiso")
    assert not sol.backend.startswith("block")
    assert np.allclose(sol.eigenvalues, _band(w, lo, hi), rtol=1e-8)


def test_interior_shift_finds_the_band_and_falls_back_when_refused(cube, monkeypatch):
    """With PARDISO the block Lanczos run shifts inside the band (an indefinite
    factorization, both ends of its spectrum wanted): the band matches dense LAPACK, rigid
    modes included; when that factorization is refused (a perturbed pivot) the definite
    shift below zero finds the same band; and when the count is too large for one block
    solve, spectrum slicing does, without the interior factorization."""
    if E.backend_name() != "pardiso":
        pytest.skip("pypardiso not installed")
    d, w = cube
    lo, hi = (2 * np.pi * 20) ** 2, _cut(w, 66)
    shifts = []
    block_band = E._block_band

    def spy(K, M, sigma, *args, **kw):
        shifts.append(sigma)
        return block_band(K, M, sigma, *args, **kw)

    monkeypatch.setattr(E, "_block_band", spy)
    inside = E.solve_band(d.K, d.M, lo, hi, dense_max=10, backend="pardiso")
    assert shifts == [E.INTERIOR_SHIFT * hi] and inside.backend == "block-lanczos+pardiso"
    assert inside.n_below == 6 and np.allclose(inside.eigenvalues, _band(w, lo, hi), rtol=1e-9)
    V = inside.vectors
    assert np.allclose(V.T @ (d.M @ V), np.eye(V.shape[1]), atol=1e-9)
    monkeypatch.setattr(E, "factorize_indefinite", lambda A: None)
    below = E.solve_band(d.K, d.M, lo, hi, dense_max=10, backend="pardiso")
    assert shifts[1] < 0 and below.n_below == 6
    assert np.allclose(below.eigenvalues, inside.eigenvalues, rtol=1e-9)
    monkeypatch.undo()
    monkeypatch.setattr(E, "BLOCK_MAX_MODES", 10)
    sliced = E.solve_band(d.K, d.M, lo, hi, dense_max=10, slice_modes=20, backend="pardiso")
    assert not sliced.backend.startswith("block")
    assert np.allclose(sliced.eigenvalues, inside.eigenvalues, rtol=1e-8)


def test_indefinite_factorization_counts_and_refuses_a_singular_matrix(cube):
    """PARDISO's L D L^T of K - sigma M counts the eigenvalues below sigma (Sylvester) and
    solves with it; a singular matrix (K itself, six rigid modes; a shift on an eigenvalue),
    which PARDISO factors without a word, is refused by the residual of a solve."""
    if E.backend_name() != "pardiso":
        pytest.skip("pypardiso not installed")
    d, w = cube
    sigma = _cut(w, 30)
    A_ = (d.K - sigma * d.M).tocsr()
    solve, negative = E.factorize_indefinite(A_)
    assert negative == int(np.sum(w < sigma))
    B = np.random.default_rng(4).standard_normal((A_.shape[0], 3))
    assert np.linalg.norm(A_ @ solve(B) - B) < 1e-8 * np.linalg.norm(B)
    assert E.factorize_indefinite(d.K.tocsr()) is None
    assert E.factorize_indefinite((d.K - w[40] * d.M).tocsr()) is None  # the shift on an eigenvalue


def test_project_out_halves_on_two_threads_match_in_turn():
    """The Gram-Schmidt pass cut in halves gives the same bits on one thread or two, and
    leaves F M-orthogonal to the basis."""
    from concurrent.futures import ThreadPoolExecutor

    rng = np.random.default_rng(2)
    n, k = 500, 80
    Mdiag = rng.uniform(1.0, 2.0, n)
    Q = np.linalg.qr(rng.standard_normal((n, k)) / np.sqrt(Mdiag)[:, None])[0].T
    # M-orthonormal rows: Q M Q^T = I
    L = np.linalg.cholesky((Q * Mdiag) @ Q.T)
    Q = np.linalg.solve(L, Q)
    MQ = Q * Mdiag
    F0 = rng.standard_normal((6, n))
    F1, F2 = F0.copy(), F0.copy()
    C1 = E._project_out(F1, F0 * Mdiag, Q)
    with ThreadPoolExecutor(1) as pool:
        def both(f, g):
            other = pool.submit(g)
            return f(), other.result()

        C2 = E._project_out(F2, F0 * Mdiag, Q, both)
    assert k >= E.PROJECT_SPLIT_MIN
    assert np.array_equal(C1, C2) and np.array_equal(F1, F2)
    assert np.abs(MQ @ F1.T).max() < 1e-12 * np.abs(F0).max()
    np.testing.assert_allclose(C1, MQ @ F0.T, rtol=1e-12, atol=1e-12)


def test_sum_blocks_adds_equal_keys():
    key = np.array([5, 1, 5, 3, 1, 5])
    a = np.arange(12.0).reshape(6, 2)
    k, s = _sum_blocks(key, a)
    assert k.tolist() == [1, 3, 5]
    assert s.tolist() == [[2 + 8, 3 + 9], [6, 7], [0 + 4 + 10, 1 + 5 + 11]]


def test_hex_matrices_symmetric_with_rigid_null_space(cube):
    d, _ = cube
    K, M = d.K.tocsr(), d.M.tocsr()
    assert abs(K - K.T).max() <= 1e-12 * abs(K).max()
    assert abs(M - M.T).max() <= 1e-12 * abs(M).max()
    n = K.shape[0] // 3
    t = np.zeros((3 * n, 3))
    for c in range(3):
        t[c::3, c] = 1.0  # rigid translations
    assert np.abs(K @ t).max() < 1e-9 * abs(K).max()
    assert float(t[:, 0] @ (M @ t[:, 0])) == pytest.approx(0.1**3 * A.parse_material("steel").rho, rel=1e-9)


def test_block_band_with_a_mass_not_of_node_form(cube):
    """The block solve's general mass product (scipy) when M is not m (x) I3."""
    from mjsound.modal.node_mass import node_mass

    d, _ = cube
    assert node_mass(d.M) is not None  # the hex mass is of node form ...
    scale = np.ones(d.dofs)
    scale[0::3] = 1.01  # ... x dofs 1 % heavier: no longer
    S = sp.diags(np.sqrt(scale))
    M2 = (S @ d.M @ S).tocsr()
    assert node_mass(M2) is None
    w = sla.eigh(d.K.toarray(), M2.toarray(), eigvals_only=True)
    lo, hi = (2 * np.pi * 20) ** 2, _cut(w, 50)
    sol = E.solve_band(d.K, M2, lo, hi, dense_max=10)
    assert sol.backend.startswith("block-lanczos")
    assert np.allclose(sol.eigenvalues, _band(w, lo, hi), rtol=1e-9)
    V = sol.vectors
    assert np.allclose(V.T @ (M2 @ V), np.eye(V.shape[1]), atol=1e-9)
