"""The per-sample oscillator loops of one bank's gathered modes (:mod:`.kernels` gathers
the active modes and their source gains, culls and corrects on the grid, and calls these
between grid points, events and source boundaries).

With ``z_i`` the gathered modes' complex state and ``p_i`` their rounded poles, each sample
``s`` adds the acting sources' forces ``g_{q,i} F_q[s]`` to ``z_i``, outputs ``sum_i Im z_i``
and advances ``z_i *= p_i``. The loops run in the bank's dtype with the fast-math flags
:data:`FAST` (the sum over modes is vectorised) and fuse a multiply and an add only where
they say so (:func:`fma`: ``z_i + g F``, and in ``z_i p_i`` the products with the pole's
real part: ``Re = fma(a, Re p, -(b Im p))``, ``Im = fma(b, Re p, a Im p)``), so a mode's
operations and their order are part of the sound and the same in every process, whether it
compiled the loops or loaded them from numba's cache. Any rewrite must keep both
(``tests/test_synth.py`` checks the loops against the plain recursion,
``tests/test_bank_loops.py`` the fusing).
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba.core import types
from numba.extending import intrinsic

from ..jit import njit, njit_inner

__all__ = ["bank_free", "bank_forced", "MAX_FOLD", "FAST", "fma", "fmuladd"]

#: The loops' fast-math flags: every one but ``contract`` (and ``afn``). Reassociation lets
#: the sum over modes vectorise; a multiply and an add fuse only where the code says so
#: (:func:`fma`). With ``contract`` LLVM chose where to fuse, and the choice differed between
#: a process that compiled the kernels and one that loaded them from numba's cache: the same
#: seeded run then differed in its last bits.
FAST = {"reassoc", "nsz", "arcp", "nnan", "ninf"}


def _multiply_add(llvm_name):
    """The code of ``a * b + c`` through LLVM's intrinsic ``llvm_name`` (``llvm.fma``,
    ``llvm.fmuladd``), the arguments cast to the result's float type."""

    def codegen(context, builder, signature, args):
        ty = signature.return_type
        vals = [context.cast(builder, v, t, ty) for v, t in zip(args, signature.args)]
        lt = context.get_value_type(ty)
        fn = builder.module.declare_intrinsic(llvm_name, [lt], ir.FunctionType(lt, [lt, lt, lt]))
        return builder.call(fn, vals)

    return codegen


@intrinsic
def fma(typingctx, a, b, c):
    """``a * b + c`` rounded once (LLVM's ``llvm.fma``), in ``a``'s float type."""
    if not all(isinstance(t, types.Float) for t in (a, b, c)):
        return None
    return a(a, b, c), _multiply_add("llvm.fma")


@intrinsic
def fmuladd(typingctx, a, b, c):
    """``a * b + c`` through LLVM's ``llvm.fmuladd`` (fused where the target has a fused
    multiply-add, as every x86-64 with FMA3; the fusing is this one expression's, not
    LLVM's choice over the kernel as with ``contract``): unlike :func:`fma`, a sum
    ``s = fmuladd(x, y, s)`` over a loop is recognised as a reduction and vectorised."""
    if not all(isinstance(t, types.Float) for t in (a, b, c)):
        return None
    return a(a, b, c), _multiply_add("llvm.fmuladd")


@njit(cache=True, fastmath=FAST)
def bank_free(work, na, out, o0, n, zero):
    """Advance ``na`` oscillators ``n`` samples, adding ``sum Im z`` to ``out[o0:o0+n]``.

    work   : (wr, wi, pr, pi), each (>=na,) dtype: real / imaginary state (updated in
             place) and real / imaginary pole
    out    : (N,) dtype      output (pressure, Pa)
    zero   : dtype scalar    0 of the bank's dtype (fixes the accumulator type)
    """
    wr, wi, pr, pi = work
    for s in range(o0, o0 + n):
        acc = zero
        for k in range(na):
            a = wr[k]
            b = wi[k]
            acc += b
            wr[k] = fma(a, pr[k], -(b * pi[k]))
            wi[k] = fma(b, pr[k], a * pi[k])
        out[s] += acc


#: Most acting sources :func:`bank_forced` folds into its oscillator loop (a fourth made
#: LLVM vectorise the loop another way, which sums the modes in another order: other last bits).
MAX_FOLD = 3


@njit_inner(cache=True, fastmath=FAST)
def bank_forced(work, na, out, o0, n, zero, gwr, gwi, F, act, nact, span):
    """Like :func:`bank_free` with forcing: ``z_i += sum_q g_{q,i} F[q, s]`` before output.

    gwr, gwi : (n_src, >=na) dtype  complex per-mode gain of each source (gathered)
    F        : (n_src, N) dtype     per-sample force values [N] of each source on this block
    act      : (nact,) int64        indices of the sources active on this segment (nact >= 1)
    span     : (2, n_src) int64     gathered modes ``span[0, q] <= k < span[1, q]`` outside
                                    which source q's gains are zero (:func:`_gather`)

    Acting sources with an empty span (no gathered mode has a gain of theirs, e.g. a source
    on another object at a contact microphone) are skipped. The last :data:`MAX_FOLD` of the
    others are folded into the oscillator loop (their gains laid out full width, zero outside
    their spans, their forces in contiguous rows: one pass over the modes per sample instead
    of a pass per source, whose short stores the next pass had to wait for; 2-3x faster with
    one or two sources); any before them are added first over their spans only. Every mode
    sees the same operations in the same order either way (``z += g_q F_q[s]`` for q in
    ``act`` order, then the pole; a zero gain adds nothing), so the sound does not depend on
    how many are folded."""
    wr, wi, pr, pi = work
    use = np.empty(nact, np.int64)  # the acting sources that drive a gathered mode, in act order
    nu = 0
    for i in range(nact):
        j = act[i]
        if span[1, j] > span[0, j]:
            use[nu] = j
            nu += 1
    # (a bank of fewer than 16 modes keeps the plain loop: its sum is not vectorised, and a
    # loop with more work per mode could be, which would round it differently)
    nfold = 0 if na < 16 else min(nu, MAX_FOLD)
    first = nu - nfold  # the sources added over their spans before the folded ones
    nf = np.int64(MAX_FOLD)  # (not a literal: np.zeros and np.empty of the types render_voice uses)
    G = np.zeros((2 * nf, na), wr.dtype)
    Ff = np.empty((nf, n), wr.dtype)
    for i in range(nfold):
        j = use[first + i]
        for k in range(span[0, j], span[1, j]):
            G[2 * i, k] = gwr[j, k]
            G[2 * i + 1, k] = gwi[j, k]
        for s in range(n):
            Ff[i, s] = F[j, o0 + s]
    g1r, g1i, g2r, g2i, g3r, g3i = G[0], G[1], G[2], G[3], G[4], G[5]
    for s in range(n):
        for q in range(first):
            j = use[q]
            fv = F[j, o0 + s]
            lo = span[0, j]
            hi = span[1, j]
            # (views from the span's start: indices from 0 need no wraparound check)
            vr, vi, ur, ui = wr[lo:hi], wi[lo:hi], gwr[j, lo:hi], gwi[j, lo:hi]
            for k in range(hi - lo):
                vr[k] = fma(ur[k], fv, vr[k])
                vi[k] = fma(ui[k], fv, vi[k])
        acc = zero
        if nfold == 3:
            f1 = Ff[0, s]
            f2 = Ff[1, s]
            f3 = Ff[2, s]
            for k in range(na):
                a = fma(g1r[k], f1, wr[k])
                b = fma(g1i[k], f1, wi[k])
                a = fma(g2r[k], f2, a)
                b = fma(g2i[k], f2, b)
                a = fma(g3r[k], f3, a)
                b = fma(g3i[k], f3, b)
                acc += b
                wr[k] = fma(a, pr[k], -(b * pi[k]))
                wi[k] = fma(b, pr[k], a * pi[k])
        elif nfold == 2:
            f1 = Ff[0, s]
            f2 = Ff[1, s]
            for k in range(na):
                a = fma(g1r[k], f1, wr[k])
                b = fma(g1i[k], f1, wi[k])
                a = fma(g2r[k], f2, a)
                b = fma(g2i[k], f2, b)
                acc += b
                wr[k] = fma(a, pr[k], -(b * pi[k]))
                wi[k] = fma(b, pr[k], a * pi[k])
        elif nfold == 1:
            f1 = Ff[0, s]
            for k in range(na):
                a = fma(g1r[k], f1, wr[k])
                b = fma(g1i[k], f1, wi[k])
                acc += b
                wr[k] = fma(a, pr[k], -(b * pi[k]))
                wi[k] = fma(b, pr[k], a * pi[k])
        else:  # (bank_free's loop, written out: calling bank_free per sample here was 25-30 %
            # slower on banks of 4-15 modes, same audio)
            for k in range(na):
                a = wr[k]
                b = wi[k]
                acc += b
                wr[k] = fma(a, pr[k], -(b * pi[k]))
                wi[k] = fma(b, pr[k], a * pi[k])
        out[o0 + s] += acc
