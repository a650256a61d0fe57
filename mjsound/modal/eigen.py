r"""Generalized symmetric eigensolver: every mode of ``K phi = lambda M phi`` in a band.

Strategy (chosen by measurement, see ``scripts/bench_modal.py``):

* **small systems** (n <= ``dense_max``): dense LAPACK ``eigh`` with ``subset_by_value``.
* **narrow bands** (a bar numbered along its length, :func:`.banded.band_width`; any size
  under its cost bound): the count and the definite shift's factorization are band
  ``L D L^T`` (:mod:`.banded`) on SuperLU's route, and block Lanczos below; the beam's 3123
  dofs solved in 0.061 s against 0.098 s with PARDISO, 0.071 s with SuperLU (one process,
  medians of alternated runs), and wrote a fraction of the fresh memory.
* **large systems**: first the Sylvester count ``n_target`` of eigenvalues below the band
  top (negative pivots of an ``L D L^T`` of ``K - lambda_max M``: PARDISO when it perturbed
  no pivot, else SuperLU), computed side by side with the factorization of the definite
  ``K - sigma M``, ``sigma`` a little below zero.

  With PARDISO the shift goes inside the band instead, ``sigma = INTERIOR_SHIFT *
  lambda_max``: the indefinite ``K - sigma M`` is factored by PARDISO's Bunch-Kaufman
  ``L D L^T`` (taken only when it perturbed no pivot, else the definite shift below) while
  the worker counts. The operator's spectrum ``mu = 1 / (lambda - sigma)`` then has the
  wanted eigenvalues at both ends (``mu < 0`` below the shift, ``mu > 1 / (lambda_max -
  sigma)`` above it) and the unwanted ones (above ``lambda_max``) squeezed into
  ``(0, 1 / (lambda_max - sigma))``: the band's top modes stand ``1 / (1 - 0.45)`` times
  further apart relative to that interval, and the rigid modes at ``mu = -1 / sigma`` are
  no longer a million times the top's. The 20 cm bowl's band (120 eigenvalues) took a
  basis of 240 vectors in blocks of 8 against 352 in blocks of 16 below zero, with one
  factorization instead of two copies (Lanczos 1.5 s against 2.3 s CPU on one core).

  - **one block solve** (``n_target <= BLOCK_MAX_MODES``): block Lanczos with full
    reorthogonalisation on ``(K - sigma M)^{-1} M`` (:func:`_block_band`). Its solves run on
    blocks of 4..16 vectors, where PARDISO's substitution is BLAS-3 (on a 20 cm bowl a
    vector costs several times less in blocks of 12 than one at a time), and it stops when exactly
    ``n_target`` Ritz values lie below the band top, all converged: complete by Sylvester,
    whatever the multiplicities. Eigenvalues are the Rayleigh quotients of the vectors.
    With the shift below zero (no PARDISO for the interior one), from
    :data:`SPLIT_MIN_DOFS` on, the Lanczos run starts right after the definite
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

The factorizations and inertia counts live in :mod:`.pardiso`, the block Lanczos run in
:mod:`.block_lanczos`. Eigenvectors are mass-normalised (``phi^T M phi = 1``). Eigenvalues below the band
(rigid-body modes, ``lambda ~ 0``) are counted and discarded.
"""

from __future__ import annotations

import contextlib
import time
import warnings

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .band import F_MIN_HZ
from .banded import band_ldlt, band_solver, band_width
from .block_lanczos import (BLOCK_TOL, PROJECT_SPLIT_MIN, SERIAL_PRODUCTS_DOFS, _block_band, _project_out,  # noqa: F401
                            _SplitSolve, single_threaded_blas)
from .node_mass import mass_rows
from .pardiso import PARDISO_MIN_DOFS, backend_name, count_below, factorize, factorize_indefinite  # noqa: F401
from .pencil import Pencil
from ..user_frame import user_stacklevel

__all__ = ["solve_band", "solve_modes", "factorize", "count_below", "BandSolution", "backend_name"]


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
    node_mass: sp.spmatrix | None = None,
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
    node_mass : (n/3, n/3) sparse, optional
        ``m`` with ``M = kron(m, I3)`` exactly, when the caller has it (the discretization
        built ``M`` from it): the mass products use it without finding it from ``M``.

    Returns
    -------
    BandSolution
    """
    t0 = time.perf_counter()
    K = sp.csr_matrix(K)
    M = sp.csr_matrix(M)
    # ARPACK's level-2 BLAS on vectors of a few thousand entries is ~10x slower with
    # OpenBLAS threads than without (thread wake-ups dominate): run the solve on one thread.
    # Below SERIAL_PRODUCTS_DOFS BLAS's threads are left alone (only ARPACK's slices take the
    # limit) and the block solve's small products are numba kernels: in a process just
    # forked, setting OpenBLAS's thread count starts its thread pool afresh, whose threads
    # then spin for ~0.1 s beside the solve (the beam's whole analysis 0.15 s against 0.09 s).
    with contextlib.nullcontext() if K.shape[0] < SERIAL_PRODUCTS_DOFS else single_threaded_blas():
        return _solve_band(K, M, lam_min, lam_max, dense_max, slice_modes, backend, progress, max_modes, t0,
                           node_mass)


def solve_modes(disc, f_max: float, progress: bool = False, max_modes=None) -> BandSolution:
    """Every mode of a discretization from :data:`.band.F_MIN_HZ` to ``f_max`` [Hz]
    (:func:`solve_band` on ``disc.K``, ``disc.M``), with a progress bar if ``progress``.

    Parameters
    ----------
    disc : Discretization
        Stiffness ``K``, mass ``M`` and optional lumped ``node_mass``.
    f_max : float
        Top of the band [Hz].
    progress : bool
        Show a tqdm bar of the solve's progress.
    max_modes : int, optional
        Keep at most this many (lowest) modes.
    """
    lam_min = (2 * np.pi * F_MIN_HZ) ** 2
    lam_max = (2 * np.pi * f_max) ** 2
    bar = None
    cb = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=100, desc=f"modes to {f_max / 1000:.1f} kHz ({disc.dofs} dofs)", unit="%", leave=False)

        def cb(frac):
            bar.n = int(round(100 * frac))
            bar.refresh()

    try:
        return solve_band(disc.K, disc.M, lam_min, lam_max, progress=cb, max_modes=max_modes, node_mass=disc.node_mass)
    finally:
        if bar is not None:
            bar.close()

def _one_thread_if_small(n: int):
    """BLAS on one thread for a solve of ``n < SERIAL_PRODUCTS_DOFS`` dofs (the dense path,
    ARPACK's slices), where :func:`solve_band` left its threads alone; else nothing."""
    return single_threaded_blas() if n < SERIAL_PRODUCTS_DOFS else contextlib.nullcontext()


def _solve_band(K, M, lam_min, lam_max, dense_max, slice_modes, backend, progress, max_modes, t0, node_mass=None):
    n = K.shape[0]
    if n <= dense_max:
        with _one_thread_if_small(n):
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
    # a narrow band (a bar numbered along its length) is counted and factored as a band
    # (:mod:`.banded`) on SuperLU's route, whatever its size
    used = backend or (backend_name() if n >= PARDISO_MIN_DOFS and band_width(K, M) is None else "superlu")
    shift = Pencil(K, M)  # K - sigma M on K's pattern

    def apply_M():
        return mass_rows(M, None if node_mass is None else sp.csr_matrix(node_mass))

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
            counting = pool.submit(count_below, K, M, lam_max, backend, shift)
        interior = None
        if used == "pardiso" and INTERIOR_SHIFT is not None:
            # the shift inside the band (module docstring); the worker counts meanwhile
            interior = factorize_indefinite(shift(INTERIOR_SHIFT * lam_max))
        if interior is not None:
            n_target = counting.result()
            solve0 = None
            if block_fits(n_target):
                res = _block_band(K, M, INTERIOR_SHIFT * lam_max, lam_max, n_target, interior[0],
                                  progress=progress, b=_interior_block_size(n_target), apply_M=apply_M())
        elif used == "pardiso" and n >= SPLIT_MIN_DOFS:
            # Two cores for the whole solve: the worker then factors a second copy, this
            # thread starts block Lanczos at once; the count is waited for only when the
            # basis could hold the band, and the copy takes half of every block solve from
            # when it is ready.
            A0 = shift(sigma0)
            second = pool.submit(factorize, A0, backend, definite=True)
            solve0 = factorize(A0, backend, definite=True)
            res = _block_band(K, M, sigma0, lam_max, counting, _SplitSolve(solve0, pool, second),
                              fits=block_fits, progress=progress, apply_M=apply_M())
            n_target = counting.result()
        else:
            solve0 = factorize(shift(sigma0), backend, definite=True) if used == "pardiso" else None
            # SuperLU's route: a narrow band is counted in band storage, which the shift's
            # factorization then reuses
            counted = band_ldlt(K, M, lam_max) if used != "pardiso" else None
            if counted is not None:
                work, n_target = counted
            else:
                work = None
                n_target = counting.result() if used == "pardiso" else count_below(K, M, lam_max, backend, shift, band=False)
            if block_fits(n_target):
                # The whole band from one definite factorization, by block Lanczos (its
                # solves run as BLAS-3 on blocks of vectors), complete by the Sylvester count.
                if solve0 is None:
                    solve0 = band_solver(K, M, sigma0, work) or factorize(shift(sigma0), backend, definite=True)
                res = _block_band(K, M, sigma0, lam_max, n_target, solve0, progress=progress, apply_M=apply_M())
    finally:
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)
    if res is not None:
        w, V = res  # ascending
        n_below = int(np.sum(w < lam_min))
        w, V = w[n_below:], V[:, n_below:]  # a view: the vectors are not copied
        if max_modes is not None:
            w, V = w[:max_modes], V[:, :max_modes]
        if progress:
            progress(1.0)
        return BandSolution(w, V, n_below, time.perf_counter() - t0, 1, f"block-lanczos+{used}")
    # ARPACK's level-2 BLAS on vectors of a few thousand entries: one thread (solve_band)
    with _one_thread_if_small(n):
        return _slice_band(K, M, lam_min, lam_max, slice_modes, backend, progress, max_modes, t0, used, n_target,
                           solve0, sigma0, shift)


def _slice_band(K, M, lam_min, lam_max, slice_modes, backend, progress, max_modes, t0, used, n_target, solve0,
                sigma0, shift):
    """Spectrum slicing by shift-invert ARPACK (module docstring): :func:`_solve_band`'s way
    when the block solve does not apply or did not converge."""
    n = K.shape[0]
    k_max = 2 * int(slice_modes)
    vals, vecs = [], []
    n_below = 0
    sigma = sigma0
    lo = -np.inf
    n_slices = 0
    k = int(min(slice_modes if n_target is None or n_target + 4 > k_max else n_target + 4, n - 2))
    total = 0
    slices = []
    while lo <= lam_max:
        n_slices += 1
        if n_slices == 1 and solve0 is not None and sigma == sigma0:
            solve = solve0
        else:
            solve = factorize(shift(sigma), backend, definite=sigma < 0)
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
        slices.append((sigma, lo, hi, w[complete], V[:, complete]))
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
    if n_target is not None and max_modes is None and n_below + total < n_target:
        for w_add, V_add in _missing_copies(K, M, slices, n_target - n_below - total, backend):
            n_below += int(np.sum(w_add < lam_min))
            take = (w_add >= lam_min) & (w_add <= lam_max)
            vals.append(w_add[take])
            vecs.append(V_add[:, take])
            total += int(take.sum())
    if n_target is not None and max_modes is None and n_below + total != n_target:
        warnings.warn(
            f"eigensolver found {n_below + total} eigenvalues below the band top but the inertia "
            f"count is {n_target}; the factorization may be inaccurate (badly scaled K, M?)",
            RuntimeWarning,
            stacklevel=user_stacklevel(),
        )
    w = np.concatenate(vals) if vals else np.zeros(0)
    V = np.concatenate(vecs, axis=1) if vecs else np.zeros((n, 0))
    order = np.argsort(w)
    w, V = w[order], V[:, order]
    if max_modes is not None:
        w, V = w[:max_modes], V[:, :max_modes]
    used = "pardiso+superlu" if used == "pardiso" and backend is None else used
    return BandSolution(w, _mass_normalise(V, M), n_below, time.perf_counter() - t0, n_slices, used)


#: shift of the block Lanczos run as a fraction of the band top (PARDISO: module docstring;
#: None: below zero, definite). On a 20 cm bowl (34 494 dofs, 120 eigenvalues) the basis
#: held the band at 352 vectors with the shift below zero (blocks of 16), at 304 with 0.45
#: (16) and 240 (8); 0.3 needed 248..320, 0.6 about as many as 0.45 at a higher cost
INTERIOR_SHIFT = 0.45
#: eigenvalues per block vector with the shift inside the band (bowl: blocks of 8 for its
#: 120, Lanczos CPU 1.5 s against 1.9 s for 12 and 2.3 s for 16 below zero)
INTERIOR_BLOCK = 15


def _interior_block_size(count: int) -> int:
    """Block width for the interior shift: ``count / INTERIOR_BLOCK``, 4 to 16."""
    return int(np.clip(count // INTERIOR_BLOCK, 4, 16))


#: from this size on, block Lanczos solves on two PARDISO factorizations at once
SPLIT_MIN_DOFS = 10000

#: most eigenvalues :func:`_block_band` is asked for in one go (else: ARPACK slices)
BLOCK_MAX_MODES = 400


def _missing_copies(K, M, slices, missing: int, backend):
    """Eigenpairs a slice's ARPACK run left out, ``[(w, V)]`` per slice.

    Single-vector Lanczos finds an exactly repeated eigenvalue (a symmetric object's
    pairs and triples) only through rounding and may return two copies of a triple (the
    cube of exact quadratic cells did). When the slices found fewer eigenvalues than the
    Sylvester count, each slice is searched again with its shift-invert operator deflated
    by the pairs it found (``x -> (I - V V^T M) (K - sigma M)^{-1} x``, whose found
    directions have eigenvalue 0), keeping what falls inside the slice, until the count
    is met.
    """
    n = K.shape[0]
    out = []
    for sigma, lo, hi, w_s, V_s in slices:
        if missing <= 0:
            break
        solve = factorize(K - sigma * M, backend, definite=sigma < 0)
        MV = M @ V_s

        def op(x, solve=solve, V_s=V_s, MV=MV):
            y = solve(x)
            return y - V_s @ (MV.T @ y)

        k = int(min(missing + 2, n - len(w_s) - 2))
        if k < 1:
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            v0 = np.random.default_rng(len(w_s)).standard_normal(n)
            w, V = spla.eigsh(K, k=k, M=M, sigma=sigma, which="LM", tol=1e-10, v0=v0,
                              OPinv=spla.LinearOperator((n, n), matvec=op, dtype=np.float64),
                              ncv=min(n - 1, 2 * k + 1 + len(w_s)))
        new = (w >= lo) & (w < hi)
        if new.any():
            out.append((w[new], V[:, new]))
            missing -= int(new.sum())
    return out


def _mass_normalise(V: np.ndarray, M: sp.spmatrix) -> np.ndarray:
    if V.shape[1] == 0:
        return V
    norms = np.sqrt(np.einsum("ij,ij->j", V, M @ V))
    return V / norms
