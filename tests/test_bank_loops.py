"""The oscillator loops fuse multiplies and adds only where they say so (mjsound.synth.bank_loops)."""

import numba
import numpy as np

from mjsound.jit import njit
from mjsound.synth.bank_loops import FAST, bank_free, fma


@njit
def _fma32(a, b, c):
    return fma(np.float32(a), np.float32(b), np.float32(c))


@njit
def _fma64(a, b, c):
    return fma(a, b, c)


def test_fma_rounds_once():
    """``a * b + c`` with one rounding: (1 + 2^-12)^2 - (1 + 2^-11) is 2^-24 exactly, while the
    float32 product rounded first (1 + 2^-11 + 2^-24 is a tie, rounded to even) loses it; the
    same one level down in float64."""
    a, c = 1.0 + 2.0**-12, -(1.0 + 2.0**-11)
    assert np.float32(_fma32(a, a, c)) == np.float32(2.0**-24)
    assert np.float32(np.float32(a) * np.float32(a)) + np.float32(c) == 0.0
    a64, c64 = 1.0 + 2.0**-27, -(1.0 + 2.0**-26)
    assert _fma64(a64, a64, c64) == 2.0**-54
    assert a64 * a64 + c64 == 0.0


def test_fma_refuses_non_floats():
    with np.testing.assert_raises(numba.core.errors.TypingError):
        _fma64(1, 2, 3)


def test_loops_leave_fusing_to_the_code():
    """No ``contract`` flag in the compiled loop (LLVM may not fuse on its own: where it did,
    a compiling process and one loading numba's cache fused differently and a seeded run
    differed in its last bits); the explicit fused multiply-adds are there, and the loop
    still advances a mode as ``z *= p`` does."""
    assert "contract" not in FAST and "fast" not in FAST
    loop = numba.njit(fastmath=FAST)(bank_free.py_func)  # (uncached: a cached kernel keeps no IR)
    na, n = 20, 5
    rng = np.random.default_rng(0)
    z = rng.normal(size=na) + 1j * rng.normal(size=na)
    p = 0.999 * np.exp(1j * rng.uniform(0, np.pi, na))
    work = tuple(np.ascontiguousarray(x, np.float32) for x in (z.real, z.imag, p.real, p.imag))
    out = np.zeros(n, np.float32)
    loop(work, na, out, 0, n, np.float32(0))
    ir = "\n".join(loop.inspect_llvm().values())
    assert "@llvm.fma" in ir
    assert " contract " not in ir and " fast " not in ir
    ref = np.array([(z * p**s).imag.sum() for s in range(n)])
    np.testing.assert_allclose(out, ref, rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(work[0] + 1j * work[1], z * p**n, rtol=1e-5)
