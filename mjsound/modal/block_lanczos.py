"""Block shift-invert Lanczos for every eigenpair below the band top (:func:`_block_band`),
with its two-core helpers (:class:`_SplitSolve`, :func:`_project_out`); used by
:func:`.eigen.solve_band`."""

from __future__ import annotations

import contextlib
from functools import partial

import numba as nb
import numpy as np
import scipy.linalg as sla

from .. import jit as _jit  # noqa: F401 (registers the kernel cache's stamps before the decorators below)
from .node_mass import mass_rows
from .quadratic_forms import quadratic_forms

__all__ = []

#: below this many dofs the eigensolver leaves BLAS's threads alone (:func:`.eigen.solve_band`;
#: from here on the solves split over two cores, :data:`.eigen.SPLIT_MIN_DOFS`), and the
#: basis products of at most :data:`SMALL_PRODUCTS` multiply-adds are numba kernels
#: (:func:`_project_small`, :func:`_combine_small`), which start no BLAS thread
SERIAL_PRODUCTS_DOFS = 10000
#: the beam's largest (56 basis vectors x 3123 dofs x 23 Ritz vectors): 4e6
SMALL_PRODUCTS = 8e6
#: floating-point liberties of the product kernels: reassociation (vectorised sums) and
#: fused multiply-adds
_FAST = {"reassoc", "contract", "nsz", "arcp"}


@nb.njit(cache=True, nogil=True, fastmath=_FAST)
def _project_small(F, MF, Q, C):
    """``C = Q MF^T`` (k, b) and ``F -= C^T Q`` for rows ``Q`` (k, n), ``F``, ``MF`` (b, n):
    :func:`_project_out` without BLAS."""
    k, n = Q.shape
    b = F.shape[0]
    for i in range(k):
        for j in range(b):
            acc = 0.0
            for t in range(n):
                acc += Q[i, t] * MF[j, t]
            C[i, j] = acc
    for j in range(b):
        for i in range(k):
            c = C[i, j]
            for t in range(n):
                F[j, t] -= c * Q[i, t]


@nb.njit(cache=True, nogil=True, fastmath=_FAST)
def _combine_small(Q, S, V):
    """``V = Q^T S`` (n, m) for rows ``Q`` (k, n) and ``S`` (k, m), without BLAS."""
    k, n = Q.shape
    m = S.shape[1]
    for t in range(n):
        for c in range(m):
            V[t, c] = 0.0
    for i in range(k):
        for t in range(n):
            q = Q[i, t]
            for c in range(m):
                V[t, c] += q * S[i, c]


def _small(k: int, n: int, m: int) -> bool:
    """Whether a product of ``k x n`` by ``n x m`` goes to a numba kernel (:data:`SMALL_PRODUCTS`)."""
    return n < SERIAL_PRODUCTS_DOFS and float(k) * n * m <= SMALL_PRODUCTS


def _project(F, MF, Q, both):
    """:func:`_project_out`, or its kernel for a small product (:func:`_small`)."""
    if not _small(Q.shape[0], Q.shape[1], F.shape[0]):
        return _project_out(F, MF, Q, both)
    C = np.empty((Q.shape[0], F.shape[0]))
    _project_small(F, np.ascontiguousarray(MF), np.ascontiguousarray(Q), C)
    return C


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


def _project_out(F, MF, Q, both=_in_turn):
    """``C = Q MF^T`` and ``F -= C^T Q`` (in place): F's rows M-orthogonalised against Q's,
    ``MF`` the rows of ``M F^T`` (``Q M F^T = (M Q^T)^T F^T`` for symmetric M: no M-image of
    the basis is kept, which saved its memory, about 100 MB on a 20 cm bowl, whose first
    touch costs more than the one mass product per step it takes instead).

    Over a long basis each product is cut in two, C by rows and F by columns, and
    ``both`` may run the halves on two cores (on the bowl's 19 908 dofs and 300 vectors:
    24 ms on one core, 14 on two). The cut depends only on the sizes, never on whether
    the second core is free, so the result is the same bit for bit either way. Returns C.
    """
    k = Q.shape[0]
    if k < PROJECT_SPLIT_MIN:
        C = Q @ MF.T
        F -= C.T @ Q
        return C
    h, m = k // 2, F.shape[1] // 2
    C = np.vstack(both(lambda: Q[:h] @ MF.T, lambda: Q[h:] @ MF.T))
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


def _full_pass(step: int) -> bool:
    """Whether Lanczos step ``step`` (1, 2, ...) reorthogonalises against the whole basis.

    Every other step: the step in between takes its second pass over the last two blocks
    only, and what rounding leaves along the older blocks (amplified at most by one
    application of T) goes at the next full pass. On a 20 cm bowl (basis 336) the basis
    stayed M-orthonormal to 1.8e-12 (every step: 1.6e-13), the eigenvalues moved by 1.9e-12
    and the Gram-Schmidt time about halved; every third step let the orthogonality go
    (the block solve gave up, and the fallback to ARPACK was many times slower). Frequencies against
    every step: bowl 9e-13, beam 4e-12, 30 cm plate 4e-11 relative (its analysis about a quarter
    faster; ``scripts/bench_modal.py --no-baseline --objects beam plate`` measures it).
    """
    return step % 2 == 0


def single_threaded_blas():
    """A context with BLAS on one thread. threadpoolctl's controller (the loaded libraries,
    found by scanning the process: 2..7 ms, a third of a small analysis's solve) is made
    once per process, when a solve first needs it (one BLAS loaded later is not limited:
    only speed is at stake)."""
    global _BLAS_CONTROLLER
    try:
        if _BLAS_CONTROLLER is None:
            from threadpoolctl import ThreadpoolController

            _BLAS_CONTROLLER = ThreadpoolController()
        return _BLAS_CONTROLLER.limit(limits=1, user_api="blas")
    except ImportError:  # optional: only speed is lost
        return contextlib.nullcontext()


_BLAS_CONTROLLER = None
#: from this basis size on, LAPACK's eigensolver of the projection (multithreaded in
#: OpenBLAS from about here, where on matrices this small the threads cost more than they
#: save) runs with
#: BLAS on one thread (below :data:`SERIAL_PRODUCTS_DOFS` dofs, where the solve leaves
#: BLAS's threads alone until then)
SERIAL_EIGH_DIM = 64


def _block_band(K, M, sigma, lam_max, n_target, solve, **options):
    """:func:`_block_lanczos` (its parameters), with BLAS on one thread once the basis
    outgrows :data:`SERIAL_EIGH_DIM` (below :data:`SERIAL_PRODUCTS_DOFS` dofs; above, the
    caller has limited it already)."""
    with contextlib.ExitStack() as limits:
        return _block_lanczos(K, M, sigma, lam_max, n_target, solve, limits=limits, **options)


def _block_lanczos(K, M, sigma, lam_max, n_target, solve, *, tol=None, seed=0, max_dim=None, apply_M=None,
                   both=None, fits=None, progress=None, b=None, limits=None):
    """Every eigenpair with ``lambda <= lam_max``, ``n_target`` of them (Sylvester count).

    Block Lanczos for ``T = (K - sigma M)^{-1} M`` (self-adjoint in the M inner product)
    with full reorthogonalisation: the basis ``Q`` (M-orthonormal, stored by rows) grows
    one block ``W`` at a time, ``W_next`` = ``T W`` M-orthogonalised twice (classical
    Gram-Schmidt: against the last two blocks, then against ``Q``, or every other step
    against the last two blocks again, :func:`_full_pass`) and orthonormalised within the
    block; the projection
    ``H = Q^T M T Q`` is filled from the Gram-Schmidt coefficients. Only the last two
    blocks' M-images are kept: the coefficients against the whole basis are ``Q (M F^T)``,
    one mass product of the new block per step instead of a stored ``M Q`` (which doubled
    the basis' memory, whose first touch cost more than the products). Ritz pairs
    ``(mu, y = Q s)`` have residual ``T y - mu y = F s_last`` where ``F = W_next R`` is
    what the last block's image left outside ``Q``, so ``||T y - mu y||_M = ||R s_last||``
    needs no extra operator product.

    The wanted eigenvalues are those with ``mu > 1 / (lam_max - sigma)`` and, for a shift
    ``sigma`` inside the band, those below it (``mu < 0``). The k-th largest Ritz value
    never exceeds the k-th largest ``mu`` and the k-th smallest never falls below the k-th
    smallest (Cauchy interlacing), so at most ``n_target`` Ritz values can lie in the
    wanted ranges; the solve stops when exactly
    ``n_target`` do and all have ``||T y - mu y||_M <= tol |mu|`` (tighter for low modes,
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
    ascending, or None if the basis would outgrow ``max_dim`` or ``fits`` said no. ``b``:
    the block width (default :func:`_block_size` of the count).
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
    if b is None:
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
    # pages are touched as the basis grows (growing by copies rewrote the basis each time)
    cap = int(max_dim + b)
    Q = np.empty((cap, n))
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
    MW_prev = np.zeros((0, n))
    steps = 0
    while True:
        bb = W.shape[0]
        Q[d:d + bb] = W
        d0, d = d, d + bb
        P = np.ascontiguousarray(solve(MW.T).T)  # T W, rows
        MP = apply_M(P)
        # Lanczos: T W lies in the last two blocks and the next one, so those two are
        # removed first (cheap), then a second Gram-Schmidt pass takes out what rounding
        # left: over the whole basis every other step, over the last two blocks between
        # (:func:`_full_pass`)
        steps += 1
        dl = max(0, d0 - b_prev)
        lo = 0 if _full_pass(steps) else dl
        # against the last two blocks Q[dl:d] (M-images MW_prev, MW), and F's M-image by
        # linearity (no mass product)
        C = np.vstack([MW_prev @ P.T, MW @ P.T])
        F = P - C.T @ Q[dl:d]
        MF = MP - C[:len(MW_prev)].T @ MW_prev
        MF -= C[len(MW_prev):].T @ MW
        C2 = _project(F, MF, Q[lo:d], both)
        C2[dl - lo:d - lo] += C
        Hjj = C2[d0 - lo:d - lo]
        H[d0:d, d0:d] = 0.5 * (Hjj + Hjj.T)
        MF = apply_M(F)
        MW_prev = MW
        W, MW, R = orthonormal(F, MF)
        b_prev = bb
        # F is what is left of T W after removing Q: when that is a tiny part of T W
        # (converged directions, rigid modes with their larger mu) one pass leaves W
        # orthogonal only to ~eps |T W| / |F|: then once more.
        left = np.einsum("ij,ij->i", F, MF) / np.maximum(np.einsum("ij,ij->j", C2, C2) + np.einsum("ij,ij->i", F, MF), 1e-300)
        if left.size and left.min() < 1e-8:
            _project(W, MW, Q[:d], both)
            W, MW, R2 = orthonormal(W, apply_M(W))
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
                _project(Z, apply_M(Z), Q[:d], both)
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
        if limits is not None and d > SERIAL_EIGH_DIM and n < SERIAL_PRODUCTS_DOFS:
            limits.enter_context(single_threaded_blas())
            limits = None  # (entered once)
        mu = sla.eigh(H[:d, :d], eigvals_only=True, driver="ev")
        ok = np.sum((mu > mu_cut) | (mu < 0)) == count
        if ok:
            mu, S = sla.eigh(H[:d, :d], driver="evd")
            want = (mu > mu_cut) | (mu < 0)
            ok = np.sum(want) == count
            mu, S = mu[want], S[:, want]
        if ok:
            est = np.linalg.norm(R @ S[d0:d], axis=0)
            if np.all(est <= tol * np.abs(mu) * _tol_scale(sigma + 1.0 / mu, lam_max)):
                # Ritz vectors as the columns of one C-ordered (n, count) array, ascending by
                # Ritz value, its rows in two halves (the cut depends on n only): no copy
                # of them is made from here to the caller (four 33 MB copies on the bowl)
                S = np.ascontiguousarray(S[:, np.argsort(sigma + 1.0 / mu)])
                V = np.empty((n, S.shape[1]))
                h = n // 2
                if _small(d, n, S.shape[1]):
                    _combine_small(Q[:d], S, V)
                else:
                    both(partial(np.matmul, Q[:d, :h].T, S, out=V[:h]), partial(np.matmul, Q[:d, h:].T, S, out=V[h:]))
                # Eigenvalues as Rayleigh quotients of the vectors (error ~ residual^2): the
                # Ritz values sigma + 1/mu carry rounding of order eps * mu_max / mu, and
                # mu_max (rigid modes, 1/|sigma|) is ~1e6 x the mu at the top of the band:
                # 1e-6 relative errors there, where the quotients agree to 1e-10.
                # y^T M y = s^T (Q M Q^T) s = 1 up to the basis' loss of M-orthonormality
                # (2e-12 on the bowl), so the quotient needs only K (the mass products
                # would add as much work again; eigenvalues moved by 2e-12). The forms run
                # on two threads.
                lam = quadratic_forms(K, V, threads=2, columns=True)
                order = np.argsort(lam, kind="stable")
                if np.any(np.diff(order) != 1):  # quotients of a near pair in the other order
                    lam, V = lam[order], V[:, order]
                return lam, V  # mass-normalised
        if d + W.shape[0] > max_dim:
            return None
