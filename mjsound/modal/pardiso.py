"""Sparse symmetric factorizations for the eigensolver: MKL PARDISO (through pypardiso's
ctypes handle, 3x3 blocks, one thread) or SuperLU, and Sylvester inertia counts."""

from __future__ import annotations

import os

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .banded import band_count

__all__ = ["factorize", "factorize_indefinite", "count_below", "backend_name", "superlu", "PARDISO_MIN_DOFS"]


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
    return superlu(A).solve


#: SuperLU keeps a matrix's own order when the lower envelope (row ``i`` from its first
#: stored column to the diagonal), which a factorization in that order fills, holds at most
#: this many times the matrix's lower entries: a bar numbered along its length (the beam,
#: 3123 dofs: 1.8 x, L + U 599k entries against 585k after minimum degree, whose ``A + A^T``
#: and ordering cost more than they save); a compact solid numbered the same way
#: has a far wider envelope and gets the minimum-degree order.
NATURAL_ENVELOPE = 2.0


def superlu(A: sp.spmatrix):
    """SuperLU's ``L U`` of the symmetric ``A`` with diagonal pivots (an ``L D L^T`` when no
    row was exchanged): minimum degree on ``A + A^T``, or the matrix's own order when its
    envelope is narrow (:data:`NATURAL_ENVELOPE`). ``A``'s CSR arrays are handed over as
    those of its CSC (``A = A^T``: no transposed copy)."""
    A = sp.csr_matrix(A)
    if not A.has_sorted_indices:
        A = A.sorted_indices()
    n = A.shape[0]
    order = "MMD_AT_PLUS_A"
    rows = np.diff(A.indptr)
    if n and np.all(rows > 0):
        first = A.indices[A.indptr[:-1]]
        envelope = float(np.sum(np.maximum(np.arange(n) - first, 0)))
        if envelope <= NATURAL_ENVELOPE * 0.5 * (A.nnz + n):
            order = "NATURAL"
    C = sp.csc_matrix((A.data, A.indices, A.indptr), shape=A.shape)
    return spla.splu(C, permc_spec=order, diag_pivot_thresh=0.0, options={"SymmetricMode": True})


class _Pardiso:
    """MKL PARDISO factorization of a symmetric matrix, called through ctypes.

    The parameters are set explicitly (``iparm[0] = 1``): with PARDISO's defaults every
    solve runs two steps of iterative refinement (3x the cost, no gain in the residual
    here) and the forward/backward substitution is sequential. METIS ordering, no
    scaling or matching, pivot perturbation 1e-8 (indefinite: Bunch-Kaufman 1x1/2x2
    pivots; ``iparm[13]`` counts perturbed pivots, ``iparm[21:23]`` the inertia).

    A matrix of 3 dofs per node (every one here) goes in as 3x3 blocks (``iparm[36] = 3``,
    upper block triangle): the factorization of a 20 cm bowl took about half the time,
    definite and indefinite, with the same inertia.
    ``pypardiso.PyPardisoSolver.solve`` compares the whole matrix with the factored one and
    converts its index arrays on every call; Lanczos solves hundreds of times,
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
        self._freed = False
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
        """Release PARDISO's factor (phase -1; it lives in MKL's memory, which Python's
        garbage collector does not see). Once only; also when the object is collected."""
        if not self._freed:
            self._freed = True
            self._call(-1, np.zeros((self.n, 1), order="F"))

    def __del__(self):
        # every factorization a solve drops (a 81k-dof factor: ~300 MB) stayed allocated
        # until the process ended
        try:
            self.free()
        except Exception:  # interpreter shutdown, or a factorization that never completed
            pass


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
    return _Pardiso(A, 2 if definite else -2).solve


#: largest relative residual ``||A x - b|| / ||b||`` of a random right-hand side at which
#: :func:`factorize_indefinite` takes a factorization (a 20 cm bowl's shifted stiffness:
#: 6e-12; a shift within 1e-12 of an eigenvalue, or a singular matrix: 4e-4 .. 1)
INDEFINITE_RESIDUAL = 1e-8


def factorize_indefinite(A: sp.spmatrix):
    """``(solve, negative)`` for the symmetric indefinite ``A`` by PARDISO's ``L D L^T``
    (Bunch-Kaufman pivots within supernodes), ``negative`` its count of negative pivots
    (Sylvester: the eigenvalues below the shift), or None when PARDISO is not installed,
    perturbed a pivot (its solves would be those of a nearby matrix), or solves a random
    right-hand side worse than :data:`INDEFINITE_RESIDUAL` (PARDISO factored the singular
    stiffness of a free cube, six zero eigenvalues, reporting no perturbation and 624
    positive pivots: its solves were off by 13 %)."""
    A = sp.csr_matrix(A)
    try:
        fac = _Pardiso(A, -2)
    except Exception:
        return None
    negative, positive, perturbed = fac.inertia()
    b = np.random.default_rng(0).standard_normal(A.shape[0])
    if perturbed or negative + positive != A.shape[0] or not (
            np.linalg.norm(A @ fac.solve(b) - b) <= INDEFINITE_RESIDUAL * np.linalg.norm(b)):
        fac.free()
        return None
    return fac.solve, negative


def _pardiso_inertia(A: sp.spmatrix):
    """(negative, positive, perturbed) pivots of PARDISO's LDL^T of ``A``, or None."""
    try:
        fac = _Pardiso(A, -2)
    except Exception:
        return None
    out = fac.inertia()
    fac.free()
    return out


def count_below(K: sp.spmatrix, M: sp.spmatrix, lam: float, backend: str | None = None, shift=None,
                band: bool = True) -> int | None:
    """Number of eigenvalues of ``K phi = lambda M phi`` below ``lam`` (Sylvester inertia).

    Any ``L D L^T`` factorization of ``K - lam M`` with a symmetric permutation has as many
    negative pivots as there are eigenvalues below ``lam``. PARDISO (symmetric
    indefinite, Bunch-Kaufman pivots; ``backend=None`` uses it from
    :data:`PARDISO_MIN_DOFS` dofs when installed) reports that count; its answer is taken
    only when no pivot was perturbed and no pivot is zero. A narrow band is factored in
    band storage first (:func:`.banded.band_count`; unless ``backend="pardiso"``), anything
    else by SuperLU with a symmetric ordering and no row pivoting, ``K - lam M = L D L^T``
    (``U = D L^T``),
    and the count is the number of negative entries of ``D``. Returns None if that
    factorization pivoted too (then the count is not an inertia). ``shift(sigma)``: ``K -
    sigma M`` (:class:`.pencil.Pencil`), default scipy's sum; ``band=False``: the caller
    tried the band already (:func:`.banded.band_ldlt`).
    """
    n = K.shape[0]
    if band and backend != "pardiso":  # a narrow band: no sparse factorization
        counted = band_count(K, M, lam)
        if counted is not None:
            return counted
    if backend is None:
        backend = backend_name() if n >= PARDISO_MIN_DOFS else "superlu"
    A = K - lam * M if shift is None else shift(lam)
    if backend == "pardiso":
        inertia = _pardiso_inertia(A)
        if inertia is not None and inertia[2] == 0 and inertia[0] + inertia[1] == n:
            return inertia[0]
    try:
        lu = superlu(A)
    except RuntimeError:  # exactly singular: lam is an eigenvalue
        return None
    if not np.array_equal(lu.perm_r, lu.perm_c):
        return None
    return int(np.sum(lu.U.diagonal() < 0))


