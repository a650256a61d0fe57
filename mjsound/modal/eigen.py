r"""Generalized symmetric eigensolver: every mode of ``K phi = lambda M phi`` in a band.

Strategy (chosen by measurement, see ``scripts/bench_modal.py``):

* **small systems** (n <= ``dense_max``): dense LAPACK ``eigh`` with ``subset_by_value``.
* **large systems**: shift-invert Lanczos (ARPACK) with *spectrum slicing*. Each slice
  factors ``K - sigma M`` once (SuperLU with minimum-degree ordering on ``A + A^T`` and
  diagonal pivots; the first, positive definite slice of a large system uses Intel MKL
  PARDISO through ``pypardiso`` when installed) and asks ARPACK for the ``k`` eigenvalues
  nearest ``sigma``. If the
  farthest of them lies at distance ``rho``, then *every* eigenvalue in
  ``(sigma - rho, sigma + rho)`` has been found (the ``k`` largest ``|1/(lambda-sigma)|``),
  so a slice whose radius reaches back to the explored top ``lo`` contributes exactly
  the eigenvalues in ``[lo, sigma + rho)``; the next shift goes half a radius above that
  (a slice that falls short of ``lo`` is redone at ``sigma = lo``). Slices never overlap,
  repeated eigenvalues are never split or duplicated, and the cost of each slice stays
  ``O(n k^2)`` instead of growing with the total number of modes.

Eigenvectors are mass-normalised (``phi^T M phi = 1``). Eigenvalues below the band
(rigid-body modes, ``lambda ~ 0``) are counted and discarded.
"""

from __future__ import annotations

import time
import warnings

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

__all__ = ["solve_band", "factorize", "count_below", "BandSolution", "backend_name"]


class BandSolution:
    """Result of :func:`solve_band`.

    Attributes
    ----------
    eigenvalues : (k,) float, ascending [rad^2/s^2]
    vectors : (n, k) float, mass-normalised
    n_below : int, eigenvalues found below the band (rigid modes)
    seconds : float
    n_slices : int
    backend : str
    """

    def __init__(self, eigenvalues, vectors, n_below, seconds, n_slices, backend):
        self.eigenvalues = eigenvalues
        self.vectors = vectors
        self.n_below = n_below
        self.seconds = seconds
        self.n_slices = n_slices
        self.backend = backend


def backend_name() -> str:
    """'pardiso' if pypardiso (MKL) can be imported, else 'superlu'."""
    try:
        import pypardiso  # noqa: F401

        return "pardiso"
    except Exception:
        return "superlu"


#: below this size SuperLU (minimum degree on A+A^T) beats PARDISO's set-up cost here
PARDISO_MIN_DOFS = 20000


def factorize(A: sp.spmatrix, backend: str | None = None, definite: bool = False):
    """Return ``solve(b)`` for the sparse symmetric matrix ``A`` (factored once).

    ``backend=None`` picks PARDISO for *positive definite* systems (``definite=True``) of
    at least :data:`PARDISO_MIN_DOFS` dofs when pypardiso is installed, SuperLU otherwise.
    PARDISO's symmetric-indefinite mode perturbs small pivots (1e-8), which made interior
    slices gain or lose a mode at their edges; SuperLU (minimum degree on A+A^T, diagonal
    pivots) is exact there and about as fast at these sizes.
    """
    if backend is None:
        use = definite and A.shape[0] >= PARDISO_MIN_DOFS
        backend = backend_name() if use else "superlu"
    A = sp.csr_matrix(A)
    if backend == "pardiso":
        return _pardiso_solver(A, definite)
    lu = spla.splu(sp.csc_matrix(A), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                   options={"SymmetricMode": True})
    return lu.solve


def _pardiso_solver(A: sp.csr_matrix, definite: bool = False):
    """Factor with MKL PARDISO (symmetric indefinite, METIS ordering) and return a solve.

    ``pypardiso.PyPardisoSolver.solve`` compares the whole matrix with the factored one on
    every call (~10 ms here); Lanczos calls solve hundreds of times, so the solve phase
    (33) is called directly with the factorization kept in ``pt``.
    """
    import ctypes

    import pypardiso

    solver = pypardiso.PyPardisoSolver(mtype=2 if definite else -2)  # SPD or symmetric indefinite
    Au = sp.triu(A, format="csr")
    Au.sort_indices()
    solver.factorize(Au)
    n = Au.shape[0]
    ia = (Au.indptr.astype(np.int32) + 1)
    ja = (Au.indices.astype(np.int32) + 1)
    data = np.ascontiguousarray(Au.data, dtype=np.float64)
    i32 = ctypes.c_int32
    p_i32 = ctypes.POINTER(i32)
    p_f64 = ctypes.POINTER(ctypes.c_double)
    try:
        fn = solver._mkl_pardiso
        pt = solver.pt.ctypes.data_as(ctypes.POINTER(solver._pt_type[0]))
    except AttributeError:  # private API moved: fall back to the public (slower) call
        return lambda b: solver.solve(Au, np.asarray(b, dtype=np.float64))
    consts = [i32(1), i32(1), i32(solver.mtype), i32(33), i32(n), i32(1), i32(solver.msglvl)]

    def solve(b):
        b = np.array(b, dtype=np.float64, order="F").reshape(n)
        x = np.zeros_like(b)
        err = i32(0)
        fn(pt, ctypes.byref(consts[0]), ctypes.byref(consts[1]), ctypes.byref(consts[2]),
           ctypes.byref(consts[3]), ctypes.byref(consts[4]), data.ctypes.data_as(p_f64),
           ia.ctypes.data_as(p_i32), ja.ctypes.data_as(p_i32), solver.perm.ctypes.data_as(p_i32),
           ctypes.byref(consts[5]), solver.iparm.ctypes.data_as(p_i32), ctypes.byref(consts[6]),
           b.ctypes.data_as(p_f64), x.ctypes.data_as(p_f64), ctypes.byref(err))
        if err.value != 0:
            raise RuntimeError(f"PARDISO solve failed with error {err.value}")
        return x

    solve._keep = (solver, Au, ia, ja, data)  # keep the factorization alive
    return solve


def count_below(K: sp.spmatrix, M: sp.spmatrix, lam: float) -> int | None:
    """Number of eigenvalues of ``K phi = lambda M phi`` below ``lam`` (Sylvester inertia).

    SuperLU with a symmetric ordering and no row pivoting factors ``K - lam M = L D L^T``
    (``U = D L^T``); the count is the number of negative entries of ``D``. Returns None if
    the factorization pivoted (then the count is not an inertia).
    """
    try:
        lu = spla.splu(sp.csc_matrix(K - lam * M), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                       options={"SymmetricMode": True})
    except RuntimeError:  # exactly singular: lam is an eigenvalue
        return None
    if not np.array_equal(lu.perm_r, lu.perm_c):
        return None
    return int(np.sum(lu.U.diagonal() < 0))


def solve_band(
    K: sp.spmatrix,
    M: sp.spmatrix,
    lam_min: float,
    lam_max: float,
    *,
    dense_max: int = 300,
    slice_modes: int = 100,
    backend: str | None = None,
    progress=None,
    max_modes: int | None = None,
) -> BandSolution:
    """All eigenpairs with ``lam_min <= lambda <= lam_max``.

    Parameters
    ----------
    K, M : (n, n) sparse symmetric; M positive definite, K positive semi-definite.
    lam_min, lam_max : float
        Band in rad^2/s^2 (``(2 pi f)^2``).
    dense_max : int
        Use dense LAPACK at or below this size.
    slice_modes : int
        Eigenvalues asked per Lanczos slice.
    backend : 'pardiso' | 'superlu' | None (best available)
    progress : callable(fraction) or None
        Called with the fraction of the band covered so far.
    max_modes : int, optional
        Stop after this many modes in the band (a budget); the top of the band is then
        lowered and the result says so through its length.

    Returns
    -------
    BandSolution
    """
    t0 = time.perf_counter()
    n = K.shape[0]
    K = sp.csr_matrix(K)
    M = sp.csr_matrix(M)
    # ARPACK's level-2 BLAS on vectors of a few thousand entries is ~10x slower with
    # OpenBLAS threads than without (thread wake-ups dominate): run the solve on one thread.
    with _single_threaded_blas():
        return _solve_band(K, M, lam_min, lam_max, dense_max, slice_modes, backend, progress, max_modes, t0)


def _single_threaded_blas():
    try:
        from threadpoolctl import threadpool_limits

        return threadpool_limits(limits=1, user_api="blas")
    except ImportError:  # optional: only speed is lost
        import contextlib

        return contextlib.nullcontext()


def _solve_band(K, M, lam_min, lam_max, dense_max, slice_modes, backend, progress, max_modes, t0):
    n = K.shape[0]
    if n <= dense_max:
        w, V = sla.eigh(K.toarray(), M.toarray(), driver="gvd")
        n_below = int(np.sum(w < lam_min))
        sel = (w >= lam_min) & (w <= lam_max)
        w, V = w[sel], V[:, sel]
        if max_modes is not None:
            w, V = w[:max_modes], V[:, :max_modes]
        if progress:
            progress(1.0)
        return BandSolution(w, _mass_normalise(V, M), n_below, time.perf_counter() - t0, 1, "lapack")

    # Sylvester's law of inertia: the negative pivots of K - lam_max M (an LDL^T with a
    # symmetric permutation) count the eigenvalues below lam_max, so the first slice can ask
    # for exactly that many (+ a margin) and usually finds the whole band at once.
    n_target = count_below(K, M, lam_max)
    k_max = 2 * int(slice_modes)
    vals, vecs = [], []
    n_below = 0
    # Start just below zero so the (semi-definite) K - sigma M is definite and the rigid
    # modes come out of the first slice.
    scale = max(float(lam_min), 1e-6 * float(lam_max), 1.0)
    sigma = -0.5 * scale
    lo = -np.inf
    n_slices = 0
    k = int(min(slice_modes if n_target is None or n_target + 4 > k_max else n_target + 4, n - 2))
    total = 0
    while lo <= lam_max:
        n_slices += 1
        solve = factorize(K - sigma * M, backend, definite=sigma < 0)
        op = spla.LinearOperator((n, n), matvec=solve, dtype=np.float64)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            # a fixed start vector makes the result deterministic (ARPACK's default is random)
            v0 = np.random.default_rng(n_slices).standard_normal(n)
            w, V = spla.eigsh(K, k=k, M=M, sigma=sigma, which="LM", OPinv=op, tol=1e-10,
                              ncv=min(n - 1, 2 * k + 1), v0=v0)
        order = np.argsort(w)
        w, V = w[order], V[:, order]
        rho = np.max(np.abs(w - sigma)) * (1.0 - 1e-9)
        if np.isfinite(lo) and sigma - rho > lo:  # shifted too far: [lo, sigma - rho] unexplored, redo from lo
            sigma = lo
            n_slices -= 1
            continue
        hi = sigma + rho
        complete = (w >= lo) & (w < hi)
        if k >= n - 2:  # asked for (almost) everything: the slice is the whole spectrum
            complete = w >= lo
            hi = np.inf
        n_below += int(np.sum(complete & (w < lam_min)))
        take = complete & (w >= lam_min) & (w <= lam_max)
        vals.append(w[take])
        vecs.append(V[:, take])
        total += int(take.sum())
        if progress:
            progress(float(min(1.0, max(0.0, hi) / lam_max)))
        if max_modes is not None and total >= max_modes:
            break
        if not np.isfinite(hi) or hi <= lo:
            break
        # Next shift: above the explored top by most of this slice's radius, so that most
        # of the k eigenvalues it finds are new; its radius must still reach back to hi.
        sigma = hi + 0.5 * rho
        lo = hi
        if n_target is not None:
            left = n_target - (n_below + total)
            if left <= 0:
                break
            k = int(min(max(slice_modes, 2 * left + 4) if 2 * left + 4 <= k_max else slice_modes, n - 2))
    if n_target is not None and max_modes is None and n_below + total != n_target:
        warnings.warn(
            f"eigensolver found {n_below + total} eigenvalues below the band top but the inertia "
            f"count is {n_target}; the factorization may be inaccurate (badly scaled K, M?)",
            RuntimeWarning,
            stacklevel=3,
        )
    w = np.concatenate(vals) if vals else np.zeros(0)
    V = np.concatenate(vecs, axis=1) if vecs else np.zeros((n, 0))
    order = np.argsort(w)
    w, V = w[order], V[:, order]
    if max_modes is not None:
        w, V = w[:max_modes], V[:, :max_modes]
    used = backend or ("pardiso+superlu" if n >= PARDISO_MIN_DOFS and backend_name() == "pardiso" else "superlu")
    return BandSolution(w, _mass_normalise(V, M), n_below, time.perf_counter() - t0, n_slices, used)


def _mass_normalise(V: np.ndarray, M: sp.spmatrix) -> np.ndarray:
    if V.shape[1] == 0:
        return V
    norms = np.sqrt(np.einsum("ij,ij->j", V, M @ V))
    return V / norms
