r"""Generalized symmetric eigensolver: every mode of ``K phi = lambda M phi`` in a band.

Strategy (chosen by measurement, see ``scripts/bench_modal.py``):

* **small systems** (n <= ``dense_max``): dense LAPACK ``eigh`` with ``subset_by_value``.
* **large systems**: first the Sylvester count ``n_target`` of eigenvalues below the band
  top (negative pivots of an ``L D L^T`` of ``K - lambda_max M``: PARDISO when it perturbed
  no pivot, else SuperLU), computed side by side with the factorization of the definite
  ``K - sigma M``, ``sigma`` a little below zero.

  - **one block solve** (``n_target <= BLOCK_MAX_MODES``): block Lanczos with full
    reorthogonalisation on ``(K - sigma M)^{-1} M`` (:func:`_block_band`). Its solves run on
    blocks of 4..16 vectors, where PARDISO's substitution is BLAS-3 (a 20 cm bowl: 5 ms per
    vector in blocks of 12 against 15..60 ms one at a time), and it stops when exactly
    ``n_target`` Ritz values lie below the band top, all converged: complete by Sylvester,
    whatever the multiplicities. Eigenvalues are the Rayleigh quotients of the vectors.
    From :data:`SPLIT_MIN_DOFS` on, the Lanczos run starts right after the definite
    factorization while the second core counts and then factors a copy of ``K - sigma M``,
    which takes half of every later block solve and long Gram-Schmidt pass
    (:class:`_SplitSolve`, :func:`_project_out`; same result bit for bit).
  - **spectrum slicing** otherwise (or if the block solve does not converge in its basis
    budget): shift-invert Lanczos (ARPACK). Each
    slice factors ``K - sigma M`` once (SuperLU with minimum-degree ordering on ``A + A^T`` and
    diagonal pivots; the first, definite one is the factorization above) and asks ARPACK for
    the ``k`` eigenvalues nearest ``sigma``. If the
    farthest of them lies at distance ``rho``, then *every* eigenvalue in
    ``(sigma - rho, sigma + rho)`` has been found (the ``k`` largest ``|1/(lambda-sigma)|``),
    so a slice whose radius reaches back to the explored top ``lo`` contributes exactly
    the eigenvalues in ``[lo, sigma + rho)``; the next shift goes half a radius above that
    (a slice that falls short of ``lo`` is redone at ``sigma = lo``). The total is checked
    against the inertia count.

Eigenvectors are mass-normalised (``phi^T M phi = 1``). Eigenvalues below the band
(rigid-body modes, ``lambda ~ 0``) are counted and discarded.
"""

from __future__ import annotations

import os
import time
import warnings
from functools import partial

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .node_mass import mass_rows
from .quadratic_forms import quadratic_forms

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


def _import_pypardiso():
    """``import pypardiso``, telling it where pip's mkl put ``mkl_rt`` first.

    pypardiso finds MKL by a recursive glob of ``sys.prefix`` when it is imported and on
    every solver construction (0.4..1 s each in a virtual environment); its own variable
    ``PYPARDISO_MKL_RT`` skips that."""
    if not os.environ.get("PYPARDISO_MKL_RT"):
        import glob
        import sys

        for pattern in ("lib/libmkl_rt.so*", "lib/libmkl_rt*.dylib", "Library/bin/mkl_rt*.dll"):
            found = sorted(glob.glob(os.path.join(sys.prefix, pattern)), key=len)
            if found:
                os.environ["PYPARDISO_MKL_RT"] = found[0]
                break
    import pypardiso

    return pypardiso


def backend_name() -> str:
    """'pardiso' if pypardiso (MKL) can be imported, else 'superlu'."""
    try:
        _import_pypardiso()
        return "pardiso"
    except Exception:
        return "superlu"


#: below this size SuperLU (minimum degree on A+A^T) beats PARDISO's set-up cost here (measured:
#: PARDISO 0.19 s against 0.28 s at 3.5k dofs, 0.5 against 1.5 s at 9k, with its 3x3 blocks)
PARDISO_MIN_DOFS = 3000


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


class _Pardiso:
    """MKL PARDISO factorization of a symmetric matrix, called through ctypes.

    The parameters are set explicitly (``iparm[0] = 1``): with PARDISO's defaults every
    solve runs two steps of iterative refinement (3x the cost, no gain in the residual
    here) and the forward/backward substitution is sequential. METIS ordering, no
    scaling or matching, pivot perturbation 1e-8 (indefinite: Bunch-Kaufman 1x1/2x2
    pivots; ``iparm[13]`` counts perturbed pivots, ``iparm[21:23]`` the inertia).

    A matrix of 3 dofs per node (every one here) goes in as 3x3 blocks (``iparm[36] = 3``,
    upper block triangle): the factorization of a 20 cm bowl took half the time (0.49
    against 0.93 s definite, 0.63 against 1.33 s indefinite), with the same inertia.
    ``pypardiso.PyPardisoSolver.solve`` compares the whole matrix with the factored one and
    converts its index arrays on every call (~10 ms here); Lanczos solves hundreds of times,
    so the phases are called directly with the factorization kept in ``pt``.
    """

    def __init__(self, A: sp.spmatrix, mtype: int):
        import ctypes

        pypardiso = _import_pypardiso()
        _quiet_openmp()
        solver = pypardiso.PyPardisoSolver(mtype=mtype)
        _pardiso_single_thread(solver.libmkl)
        if not os.environ.get("PYPARDISO_MKL_RT") and getattr(solver.libmkl, "_name", None):
            os.environ["PYPARDISO_MKL_RT"] = solver.libmkl._name
        solver.iparm[0] = 1  # use the values below, not PARDISO's defaults
        for i, v in {2: 2, 8: 0, 10: 8, 11: 0, 13: 0, 21: 1 if mtype == -2 else 0, 25: 2}.items():
            solver.iparm[i - 1] = v  # 1-based numbering of the PARDISO documentation
        n = A.shape[0]
        if n % 3 == 0 and n >= 3:
            B = sp.bsr_matrix(A, blocksize=(3, 3))
            B.sort_indices()
            rows = np.repeat(np.arange(n // 3), np.diff(B.indptr))
            keep = B.indices >= rows
            indptr = np.r_[0, np.cumsum(np.bincount(rows[keep], minlength=n // 3))]
            indices = B.indices[keep]
            data = np.ascontiguousarray(B.data[keep].transpose(0, 2, 1)).ravel()  # column-major blocks
            solver.iparm[36] = 3
            self.nn = n // 3
        else:
            Au = sp.triu(A, format="csr")
            Au.sort_indices()
            indptr, indices, data = Au.indptr, Au.indices, np.ascontiguousarray(Au.data, dtype=np.float64)
            self.nn = n
        self.n, self.mtype, self.solver = n, mtype, solver
        self.ia = indptr.astype(np.int32) + 1
        self.ja = indices.astype(np.int32) + 1
        self.data = np.asarray(data, dtype=np.float64)
        self._ct = ctypes
        self._pt = solver.pt.ctypes.data_as(ctypes.POINTER(solver._pt_type[0]))
        self._call(12, np.zeros((n, 1), order="F"))

    def _call(self, phase: int, B: np.ndarray) -> np.ndarray:
        ct = self._ct
        i32 = ct.c_int32
        p_i32, p_f64 = ct.POINTER(i32), ct.POINTER(ct.c_double)
        X = np.zeros_like(B)
        err = i32(0)
        self.solver._mkl_pardiso(
            self._pt, ct.byref(i32(1)), ct.byref(i32(1)), ct.byref(i32(self.mtype)), ct.byref(i32(phase)),
            ct.byref(i32(self.nn)), self.data.ctypes.data_as(p_f64), self.ia.ctypes.data_as(p_i32),
            self.ja.ctypes.data_as(p_i32), self.solver.perm.ctypes.data_as(p_i32), ct.byref(i32(B.shape[1])),
            self.solver.iparm.ctypes.data_as(p_i32), ct.byref(i32(0)), B.ctypes.data_as(p_f64),
            X.ctypes.data_as(p_f64), ct.byref(err))
        if err.value != 0:
            raise RuntimeError(f"PARDISO phase {phase} failed with error {err.value}")
        return X

    def solve(self, b):
        """Solution for a vector (n,) or a block (n, m)."""
        b = np.asarray(b, dtype=np.float64)
        return self._call(33, np.asfortranarray(b.reshape(self.n, -1))).reshape(b.shape)

    def inertia(self):
        """(negative, positive, perturbed) pivots."""
        ip = self.solver.iparm
        return int(ip[22]), int(ip[21]), int(ip[13])

    def free(self):
        self._call(-1, np.zeros((self.n, 1), order="F"))


def _pardiso_single_thread(libmkl):
    """PARDISO on one thread (MKL's PARDISO domain, process-wide).

    On 2 cores its second OpenMP thread mostly spun: a 20 cm bowl's block Lanczos took
    3.6..4.1 s wall and 6.8..7.4 s CPU with it, 3.6..4.3 s wall and CPU without (three
    alternating runs); the two factorizations that run side by side want one core each,
    and the error estimate's discretization runs on the other core meanwhile."""
    global _PARDISO_THREADS_SET
    if _PARDISO_THREADS_SET:
        return
    _PARDISO_THREADS_SET = True
    try:
        libmkl.MKL_Domain_Set_Num_Threads(1, 4)  # 4 = MKL_DOMAIN_PARDISO
    except Exception:  # only speed is at stake
        pass


_PARDISO_THREADS_SET = False


def _quiet_openmp():
    """Let Intel OpenMP threads sleep right after a parallel region (KMP_BLOCKTIME=0).

    By default they spin for 200 ms after every PARDISO call and take the cores from the
    BLAS work between solves (block orthogonalisation ran 3x slower on 2 cores)."""
    global _OMP_QUIETED
    if _OMP_QUIETED:
        return
    _OMP_QUIETED = True
    try:
        import ctypes

        from threadpoolctl import threadpool_info

        for lib in threadpool_info():
            if lib.get("internal_api") == "openmp" and "iomp" in str(lib.get("prefix", "")):
                ctypes.CDLL(lib["filepath"]).kmp_set_blocktime(0)
    except Exception:  # only speed is at stake
        pass


_OMP_QUIETED = False


def _pardiso_solver(A: sp.spmatrix, definite: bool = False):
    """Factor with MKL PARDISO (:class:`_Pardiso`) and return ``solve(b)`` for vectors
    (n,) or blocks (n, m)."""
    fac = _Pardiso(A, 2 if definite else -2)
    solve = fac.solve
    return solve


def _pardiso_inertia(A: sp.spmatrix):
    """(negative, positive, perturbed) pivots of PARDISO's LDL^T of ``A``, or None."""
    try:
        fac = _Pardiso(A, -2)
    except Exception:
        return None
    out = fac.inertia()
    fac.free()
    return out


def count_below(K: sp.spmatrix, M: sp.spmatrix, lam: float, backend: str | None = None) -> int | None:
    """Number of eigenvalues of ``K phi = lambda M phi`` below ``lam`` (Sylvester inertia).

    Any ``L D L^T`` factorization of ``K - lam M`` with a symmetric permutation has as many
    negative pivots as there are eigenvalues below ``lam``. PARDISO (symmetric
    indefinite, Bunch-Kaufman pivots; ``backend=None`` uses it from
    :data:`PARDISO_MIN_DOFS` dofs when installed) reports that count; its answer is taken
    only when no pivot was perturbed and no pivot is zero, otherwise SuperLU with a
    symmetric ordering and no row pivoting factors ``K - lam M = L D L^T`` (``U = D L^T``)
    and the count is the number of negative entries of ``D``. Returns None if that
    factorization pivoted too (then the count is not an inertia).
    """
    A = K - lam * M
    n = A.shape[0]
    if backend is None:
        backend = backend_name() if n >= PARDISO_MIN_DOFS else "superlu"
    if backend == "pardiso":
        inertia = _pardiso_inertia(A)
        if inertia is not None and inertia[2] == 0 and inertia[0] + inertia[1] == n:
            return inertia[0]
    try:
        lu = spla.splu(sp.csc_matrix(A), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
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
    # Start below zero so the (semi-definite) K - sigma M is definite and the rigid modes
    # come out of the first slice. The shift sits a thousandth of the band below zero:
    # right below zero the rigid modes' mu = 1/|sigma| is ~1e7 x the band top's (cube to
    # 60 kHz), and rounding of that size cost the block basis its orthogonality (5e-6) and
    # mixed close clusters; at 1e-3 it stays orthonormal to 1e-13, and the basis size
    # (bowl, beam, cube) did not change.
    scale = max(float(lam_min), 1e-6 * float(lam_max), 1.0)
    sigma0 = -max(0.5 * scale, 1e-3 * float(lam_max))
    used = backend or (backend_name() if n >= PARDISO_MIN_DOFS else "superlu")

    def block_fits(count):
        return count is not None and 0 < count <= BLOCK_MAX_MODES and count < n // 4 and (
            max_modes is None or count <= 2 * max_modes + 12)

    pool = None
    res = None
    try:
        if used == "pardiso":
            # PARDISO releases the GIL: the worker counts (indefinite LDL^T) while this
            # thread factors the definite K - sigma0 M
            from concurrent.futures import ThreadPoolExecutor

            pool = ThreadPoolExecutor(1)
            counting = pool.submit(count_below, K, M, lam_max, backend)
        if used == "pardiso" and n >= SPLIT_MIN_DOFS:
            # Two cores for the whole solve: the worker then factors a second copy, this
            # thread starts block Lanczos at once; the count is waited for only when the
            # basis could hold the band, and the copy takes half of every block solve from
            # when it is ready.
            A0 = K - sigma0 * M
            second = pool.submit(factorize, A0, backend, definite=True)
            solve0 = factorize(A0, backend, definite=True)
            res = _block_band(K, M, sigma0, lam_max, counting, _SplitSolve(solve0, pool, second),
                              fits=block_fits, progress=progress)
            n_target = counting.result()
        else:
            solve0 = factorize(K - sigma0 * M, backend, definite=True) if used == "pardiso" else None
            n_target = counting.result() if used == "pardiso" else count_below(K, M, lam_max, backend)
            if block_fits(n_target):
                # The whole band from one definite factorization, by block Lanczos (its
                # solves run as BLAS-3 on blocks of vectors), complete by the Sylvester count.
                if solve0 is None:
                    solve0 = factorize(K - sigma0 * M, backend, definite=True)
                res = _block_band(K, M, sigma0, lam_max, n_target, solve0, progress=progress)
    finally:
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)
    if res is not None:
        w, V = res
        n_below = int(np.sum(w < lam_min))
        sel = w >= lam_min
        w, V = w[sel], V[:, sel]
        if max_modes is not None:
            w, V = w[:max_modes], V[:, :max_modes]
        if progress:
            progress(1.0)
        return BandSolution(w, V, n_below, time.perf_counter() - t0, 1, f"block-lanczos+{used}")
    k_max = 2 * int(slice_modes)
    vals, vecs = [], []
    n_below = 0
    sigma = sigma0
    lo = -np.inf
    n_slices = 0
    k = int(min(slice_modes if n_target is None or n_target + 4 > k_max else n_target + 4, n - 2))
    total = 0
    while lo <= lam_max:
        n_slices += 1
        if n_slices == 1 and solve0 is not None and sigma == sigma0:
            solve = solve0
        else:
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
    used = "pardiso+superlu" if used == "pardiso" and backend is None else used
    return BandSolution(w, _mass_normalise(V, M), n_below, time.perf_counter() - t0, n_slices, used)


#: from this size on, block Lanczos solves on two PARDISO factorizations at once
SPLIT_MIN_DOFS = 10000


class _SplitSolve:
    """``solve(B)`` for blocks, on two copies of one factorization once the second is ready.

    A block of ``m >= 8`` columns is cut in two: the first half is solved here, the second
    on the worker thread with the second copy (PARDISO releases the GIL). One thread
    solves 8 columns in 32 ms and 16 in 47 ms on a 20 cm bowl, so a Lanczos step's solve
    takes about two thirds of the time. PARDISO solves each column of a block of two or
    more with the same operations whatever the others are, and the two copies factor the
    same matrix identically, so the result is the same bit for bit whether or when the
    second copy joins in (test). ``second`` is a future of the second ``solve``.
    """

    def __init__(self, first, pool, second):
        self.first, self.pool, self.second = first, pool, second

    def _ready(self) -> bool:
        return self.second.done() and self.second.exception() is None

    def both(self, f, g):
        """``(f(), g())``, g on the worker thread once the second copy is done."""
        if not self._ready():
            return f(), g()
        other = self.pool.submit(g)
        return f(), other.result()

    def __call__(self, B: np.ndarray) -> np.ndarray:
        m = B.shape[1] if B.ndim == 2 else 1
        if m < 8 or not self._ready():
            return self.first(B)
        h = m // 2
        other = self.pool.submit(self.second.result(), B[:, h:])
        X = self.first(B[:, :h])
        return np.hstack([X, other.result()])


#: most eigenvalues :func:`_block_band` is asked for in one go (else: ARPACK slices)
BLOCK_MAX_MODES = 400
#: Ritz residual ||T y - mu y||_M / mu at which a pair is accepted. The eigenvalues are
#: Rayleigh quotients, whose error goes as the residual squared. On a 20 cm bowl (19 908
#: dofs, 120 eigenvalues, blocks of 16) against 1e-7 (basis 368): 1e-6 -> basis 352,
#: eigenvalues within 1.4e-11; 1e-5 -> 336, 1.3e-9 (2e-6 cent), mode shapes spanning the
#: same subspaces to 1e-11 (1 - |cos|); 1e-4 -> 320, 6e-8. Each step saved is a block
#: solve and a Gram-Schmidt pass (0.1..0.15 s for 1e-5).
BLOCK_TOL = 1e-5
#: block Krylov basis memory cap [bytes] (basis and its M-image, float64)
BLOCK_MAX_BYTES = 1.5e9


def _in_turn(f, g):
    return f(), g()


#: a Gram-Schmidt pass over at least this many basis vectors is cut in two halves
PROJECT_SPLIT_MIN = 64


def _project_out(F, Q, MQ, both=_in_turn):
    """``C = MQ F^T`` and ``F -= C^T Q`` (in place): F's rows M-orthogonalised against Q's.

    Over a long basis each product is cut in two, C by rows and F by columns, and
    ``both`` may run the halves on two cores (on the bowl's 19 908 dofs and 300 vectors:
    24 ms on one core, 14 on two). The cut depends only on the sizes, never on whether
    the second core is free, so the result is the same bit for bit either way. Returns C.
    """
    k = Q.shape[0]
    if k < PROJECT_SPLIT_MIN:
        C = MQ @ F.T
        F -= C.T @ Q
        return C
    h, m = k // 2, F.shape[1] // 2
    C = np.vstack(both(lambda: MQ[:h] @ F.T, lambda: MQ[h:] @ F.T))
    Ct = C.T

    def left():
        F[:, :m] -= Ct @ Q[:, :m]

    def right():
        F[:, m:] -= Ct @ Q[:, m:]

    both(left, right)
    return C


def _tol_scale(lam, lam_max):
    """Per-pair factor on the Ritz tolerance: ``sqrt(lam / lam_max)``, at least 1e-3.

    What a Ritz vector keeps of the modes near the top of the spectrum raises its
    Rayleigh quotient by about ``(residual)^2 lam_max``, which is a relative error of
    ``tol^2 lam_max / lam``: low modes need a tighter residual for the same relative
    accuracy, and the rigid modes (``lam ~ 0``) one that keeps them below any audible band
    (a 2 mm steel bead with one tolerance for all got a rigid mode at 37.8 Hz). They
    converge first, so it costs no step on the bowl. The floor 1e-3 is the 20 Hz / 20 kHz
    band ratio.
    """
    return np.sqrt(np.clip(np.asarray(lam) / lam_max, 1e-6, 1.0))


#: widest block; also the width when block Lanczos starts before the count is known
BLOCK_MAX_WIDTH = 16
#: with the count still under way, no convergence test before the basis has this many vectors
EARLY_MIN_DIM = 64


def _block_size(n_target: int) -> int:
    """Block width: wide blocks make each PARDISO solve cheaper per vector (its
    forward/backward substitution runs as BLAS-3: 13.7 ms for one vector, 41 ms for 12, 47
    for 16, 60 for 24 on a 20 cm bowl's 19 908 dofs), narrow ones converge in a smaller
    basis (same bowl, 120 eigenvalues: 8 -> basis 304, 12 -> 336, 16 -> 368, 20 -> 400).
    16 was the fastest there with the solves split over two factorizations
    (:class:`_SplitSolve`; medians of 4 alternated solves 2.55 s against 2.78 s for 12)."""
    return int(np.clip(n_target // 7, 4, BLOCK_MAX_WIDTH))


_LAST = {}


def _full_pass(step: int) -> bool:
    """Whether Lanczos step ``step`` (1, 2, ...) reorthogonalises against the whole basis.

    Every other step: the step in between takes its second pass over the last two blocks
    only, and what rounding leaves along the older blocks (amplified at most by one
    application of T) goes at the next full pass. On a 20 cm bowl (basis 336) the basis
    stayed M-orthonormal to 1.8e-12 (every step: 1.6e-13), the eigenvalues moved by 1.9e-12
    and the Gram-Schmidt time dropped from 1.0 to ~0.55 s; every third step let the
    orthogonality go (the block solve gave up and ARPACK took 20 s). Frequencies against
    every step: bowl 9e-13, beam 4e-12, 30 cm plate 4e-11 relative (its analysis 25.0 ->
    18.9 s; ``scripts/bench_modal.py --no-baseline --objects beam plate``).
    """
    return step % 2 == 0


def _block_band(K, M, sigma, lam_max, n_target, solve, *, tol=None, seed=0, max_dim=None, apply_M=None,
                both=None, fits=None, progress=None):
    """Every eigenpair with ``lambda <= lam_max``, ``n_target`` of them (Sylvester count).

    Block Lanczos for ``T = (K - sigma M)^{-1} M`` (self-adjoint in the M inner product)
    with full reorthogonalisation: the basis ``Q`` (M-orthonormal, stored by rows) grows
    one block ``W`` at a time, ``W_next`` = ``T W`` M-orthogonalised twice (classical
    Gram-Schmidt: against the last two blocks, then against ``Q``, or every other step
    against the last two blocks again, :func:`_full_pass`) and orthonormalised within the
    block; the projection
    ``H = Q^T M T Q`` is filled from the Gram-Schmidt coefficients. Ritz pairs
    ``(mu, y = Q s)`` have residual ``T y - mu y = F s_last`` where ``F = W_next R`` is
    what the last block's image left outside ``Q``, so ``||T y - mu y||_M = ||R s_last||``
    needs no extra operator product.

    Ritz values of the largest ``mu`` never exceed the true ones (Cauchy interlacing), so
    at most ``n_target`` Ritz values can lie below ``lam_max``; the solve stops when exactly
    ``n_target`` do and all have ``||T y - mu y||_M <= tol mu`` (tighter for low modes,
    :func:`_tol_scale`): every eigenvalue below
    ``lam_max`` is then found exactly once (Sylvester). ``solve`` takes blocks (n, b);
    ``apply_M(X) = (M X^T)^T`` for rows ``X`` (default :func:`.node_mass.mass_rows`);
    ``both(f, g)`` returns ``(f(), g())`` and may run them side by side (default: the
    ``both`` of ``solve``, :meth:`_SplitSolve.both`, if it has one).

    ``n_target`` may also be a future of the count (it is then waited for once the basis
    has :data:`EARLY_MIN_DIM` vectors, and no convergence test runs before that: the
    result does not depend on when the count arrives); blocks are then
    :data:`BLOCK_MAX_WIDTH` wide, and ``fits(count)`` says whether the block solve should
    go on with that many. ``progress(fraction)`` hears the basis size against three times
    the count (what the bowl needed), at most 0.95 before convergence. Returns ``(w, V)``
    ascending, or None if the basis would outgrow ``max_dim`` or ``fits`` said no.
    """
    n = K.shape[0]
    if both is None:
        both = getattr(solve, "both", _in_turn)
    early = not isinstance(n_target, (int, np.integer))  # a future: the count is under way
    count = None if early else int(n_target)
    if apply_M is None:
        apply_M = mass_rows(M)
    if tol is None:
        tol = BLOCK_TOL
    b = _block_size(count) if count is not None else BLOCK_MAX_WIDTH
    dim_cap = max_dim

    def dim_limit(count):
        if dim_cap is not None:
            return int(dim_cap)
        room = min(n - b, BLOCK_MAX_BYTES / (16 * n))
        return int(room if count is None else min(room, max(4 * count + 8 * b, 64)))

    max_dim = dim_limit(count)
    rng = np.random.default_rng(seed)
    # storage for the largest basis at once: np.empty/zeros only reserve address space, the
    # pages are touched as the basis grows (growing by copies cost 0.2 s on the bowl)
    cap = int(max_dim + b)
    Q = np.empty((cap, n))
    MQ = np.empty((cap, n))
    H = np.zeros((cap + b, cap + b))  # + b: room for the next block's coupling
    mu_cut = 1.0 / (lam_max - sigma)

    def orthonormal(F, MF):
        """M-orthonormal rows spanning F's (drops directions already in Q); F = X^T W."""
        G = F @ MF.T
        g, U = np.linalg.eigh(0.5 * (G + G.T))
        keep = g > 1e-13 * max(g.max(), 1e-300)
        X = U[:, keep] / np.sqrt(g[keep])
        return X.T @ F, X.T @ MF, np.sqrt(g[keep])[:, None] * U[:, keep].T

    W = rng.standard_normal((b, n))
    W, MW, _ = orthonormal(W, apply_M(W))
    d = 0
    b_prev = 0
    steps = 0
    while True:
        bb = W.shape[0]
        Q[d:d + bb] = W
        MQ[d:d + bb] = MW
        d0, d = d, d + bb
        P = np.ascontiguousarray(solve(MW.T).T)  # T W, rows
        # Lanczos: T W lies in the last two blocks and the next one, so those two are
        # removed first (cheap), then a second Gram-Schmidt pass takes out what rounding
        # left: over the whole basis every other step, over the last two blocks between
        # (:func:`_full_pass`)
        steps += 1
        dl = max(0, d0 - b_prev)
        lo = 0 if _full_pass(steps) else dl
        C = MQ[dl:d] @ P.T
        F = P - C.T @ Q[dl:d]
        C2 = _project_out(F, Q[lo:d], MQ[lo:d], both)
        C2[dl - lo:d - lo] += C
        Hjj = C2[d0 - lo:d - lo]
        H[d0:d, d0:d] = 0.5 * (Hjj + Hjj.T)
        MF = apply_M(F)
        W, MW, R = orthonormal(F, MF)
        b_prev = bb
        # F is what is left of T W after removing Q: when that is a tiny part of T W
        # (converged directions, rigid modes with their larger mu) one pass leaves W
        # orthogonal only to ~eps |T W| / |F|: then once more.
        left = np.einsum("ij,ij->i", F, MF) / np.maximum(np.einsum("ij,ij->j", C2, C2) + np.einsum("ij,ij->i", F, MF), 1e-300)
        if left.size and left.min() < 1e-8:
            C3 = MQ[:d] @ W.T
            W -= C3.T @ Q[:d]
            MW -= C3.T @ MQ[:d]
            W, MW, R2 = orthonormal(W, MW)
            R = R2 @ R
        # block tridiagonal, as in Lanczos: T W = W H_jj + W_prev H_(j-1)j + W_next R (what
        # reorthogonalisation removes beyond that is rounding and is dropped, not projected:
        # keeping it, the solves' error on the rigid modes (mu 1e6 x the top of the band)
        # leaked into the small Ritz values)
        H[d:d + R.shape[0], d0:d] = R
        H[d0:d, d:d + R.shape[0]] = R.T
        if W.shape[0] < bb:  # the Krylov space closed up (or nearly): restart with fresh directions
            Z = rng.standard_normal((bb - W.shape[0], n))
            for _ in range(2):
                Z -= (Z @ MQ[:d].T) @ Q[:d]
                if W.shape[0]:
                    Z -= (Z @ MW.T) @ W
            Z, MZ, _ = orthonormal(Z, apply_M(Z))
            W, MW = np.vstack([W, Z]), np.vstack([MW, MZ])
        if count is None:
            if d < EARLY_MIN_DIM and d + W.shape[0] <= max_dim:
                continue
            count = n_target.result()
            if fits is not None and not fits(count):
                return None
            max_dim = dim_limit(count)
        if progress is not None:
            progress(min(0.95, d / (3.0 * max(count, 1))))
        if d < max(2 * count, EARLY_MIN_DIM if early else 0):
            # no basis this small held all of them (bowl 3.1 n, beam 2.4 n)
            if d + W.shape[0] > max_dim:
                return None
            continue
        # the count first, from the eigenvalues alone (LAPACK syev without vectors: 10 ms
        # at d = 372 against 47 for selected pairs by syevr); the pairs (syevd, 22 ms) only
        # when the count is complete
        mu = sla.eigh(H[:d, :d], eigvals_only=True, driver="ev")
        ok = np.sum(mu > mu_cut) == count
        if ok:
            mu, S = sla.eigh(H[:d, :d], driver="evd")
            want = mu > mu_cut
            ok = np.sum(want) == count
            mu, S = mu[want], S[:, want]
        if ok:
            est = np.linalg.norm(R @ S[d0:d], axis=0)
            if np.all(est <= tol * mu * _tol_scale(sigma + 1.0 / mu, lam_max)):
                _LAST["dim"] = d
                # Ritz vectors as rows, in two halves (the cut depends on the count only)
                h = S.shape[1] // 2
                Qd = Q[:d]
                Y = np.vstack(both(partial(np.matmul, S[:, :h].T, Qd), partial(np.matmul, S[:, h:].T, Qd)))
                # Eigenvalues as Rayleigh quotients of the vectors (error ~ residual^2): the
                # Ritz values sigma + 1/mu carry rounding of order eps * mu_max / mu, and
                # mu_max (rigid modes, 1/|sigma|) is ~1e6 x the mu at the top of the band:
                # 1e-6 relative errors there, where the quotients agree to 1e-10.
                # y^T M y = s^T (Q M Q^T) s = 1 up to the basis' loss of M-orthonormality
                # (2e-12 on the bowl), so the quotient needs only K (the mass products
                # of the 120 vectors took 0.12..0.18 s; eigenvalues moved by 2e-12). The
                # forms run on two threads (0.25 s on one).
                lam = quadratic_forms(K, Y, threads=2)
                order = np.argsort(lam)
                return lam[order], Y[order].T  # mass-normalised
        if d + W.shape[0] > max_dim:
            return None


def _mass_normalise(V: np.ndarray, M: sp.spmatrix) -> np.ndarray:
    if V.shape[1] == 0:
        return V
    norms = np.sqrt(np.einsum("ij,ij->j", V, M @ V))
    return V / norms
