"""The drives' float32 direction factors (mjsound.synth.drive_directions) against the float64
harmonics and fits of mjsound.synth.directivity."""

from typing import NamedTuple

import numpy as np
import pytest

from mjsound.synth.directivity import DIRECTION_FLOOR, real_sh, sh_count, sh_tables
from mjsound.synth.drive_directions import CHUNK, drive_directions, direction_factors, sh_pair
from mjsound.synth.drive_lines import SceneView
from drive_directions_reference import direction_factors_f64
from mjsound.synth.records import AIR, CHANNEL, DIRECTIONS


def test_harmonic_pairs_are_real_sh_rounded_to_float32():
    """sh_pair's two rows are real_sh's float64 values at each direction, rounded to float32
    (the same recurrence and products: equal to the last bit), at orders 0 to 16, the poles
    included."""
    rng = np.random.default_rng(3)
    dirs = rng.normal(size=(12, 3))
    dirs = np.vstack([dirs / np.linalg.norm(dirs, axis=1, keepdims=True), [[0, 0, 1], [0, 0, -1]]])
    for L in (0, 1, 2, 10, 16):
        tab = sh_tables(L)
        k = sh_count(L)
        for u0, u1 in zip(dirs[::2], dirs[1::2]):
            Y = np.full((2, k + 3), 7.0, np.float32)
            sh_pair(L, *u0, *u1, tab, Y[0], Y[1])
            for d, u in enumerate((u0, u1)):
                ref = np.empty(k)
                real_sh(L, *u, ref, tab)
                np.testing.assert_array_equal(Y[d, :k], ref.astype(np.float32))
            assert np.all(Y[:, k:] == 7.0)  # (nothing written past the object's harmonics)


class _Dirs(NamedTuple):  # (the fields of records.DirectionState that drive_directions reads)
    order: np.ndarray
    msh_off: np.ndarray
    coef_r: np.ndarray
    coef_i: np.ndarray


def _scene(rng, L, orders, M, owners):
    """Object 0 without a direction (3 modes), object 1 of order ``L`` with modes of ``orders``;
    ``M`` microphones of owners ``owners``: a SceneView with the fits' float32 copy."""
    n = len(orders)
    msh = np.array([sh_count(o) for o in orders])
    msh_off = np.concatenate([[0, 0, 0, 0], np.cumsum(msh)]).astype(np.int64)
    coef = rng.normal(size=(msh_off[-1], 2)) * 0.3
    coef[msh_off[3 + 2]:msh_off[3 + 3]] = 0.0  # (mode 2 of object 1: a null everywhere, floored)
    mode_off = np.array([0, 3, 3 + n])
    order = np.array([-1, L])
    dr = _Dirs(order, msh_off, np.ascontiguousarray(coef[:, 0]), np.ascontiguousarray(coef[:, 1]))
    dd = drive_directions(dr, mode_off)
    channels = np.zeros(M, CHANNEL)
    channels["owner"] = owners
    channels["w_off"] = -1
    params = np.zeros(1, DIRECTIONS)
    params["cos_step"], params["floor"] = np.cos(np.radians(1.0)), DIRECTION_FLOOR
    mics = rng.normal(size=(M, 3))
    pos = rng.normal(size=(2, 3))
    R = np.stack([np.linalg.qr(rng.normal(size=(3, 3)))[0] for _ in range(2)])
    view = SceneView(None, None, mode_off, mics, pos, R, channels, order, msh_off, dr.coef_r, dr.coef_i,
                     np.zeros((M, sh_count(16))), sh_tables(16), params, dd)
    return view, dd, coef, msh_off


def test_float32_blocks_hold_each_modes_coefficients():
    """drive_directions: object 1's modes in blocks of CHUNK, real rows then imaginary rows,
    each mode's coefficients (to its own order) then zeros up to the padded row; object 0
    (no direction) has none."""
    rng = np.random.default_rng(2)
    orders = [10, 3, 10, 0, 7, 10]
    view, dd, coef, msh_off = _scene(rng, 10, orders, 2, [AIR, AIR])
    assert dd.off[0] == -1 and dd.off[1] == 0 and dd.K[1] == 128 and dd.coef.dtype == np.float32
    blocks = dd.coef.reshape(-1, 2 * CHUNK, 128)
    assert len(blocks) == 2 and dd.coef.size == 2 * 2 * CHUNK * 128
    for i, o in enumerate(orders):
        c = coef[msh_off[3 + i]:msh_off[4 + i]]
        row_r, row_i = blocks[i // CHUNK, i % CHUNK], blocks[i // CHUNK, CHUNK + i % CHUNK]
        np.testing.assert_array_equal(row_r[:sh_count(o)], c[:, 0].astype(np.float32))
        np.testing.assert_array_equal(row_i[:sh_count(o)], c[:, 1].astype(np.float32))
        assert not row_r[sh_count(o):].any() and not row_i[sh_count(o):].any()
    assert not blocks[1, [2, 3, 6, 7]].any()  # (the last block's two empty modes)


@pytest.mark.parametrize("L, M, owners", [(10, 4, [AIR, AIR, 1, AIR]), (16, 1, [AIR]), (2, 3, [AIR, AIR, AIR])])
def test_float32_factors_are_the_float64_fits_within_float32_rounding(L, M, owners):
    """direction_factors against the float64 kernel (direction_factors_f64: the fits' sums at
    u = R^T (mic - pos) / |mic - pos|, floored) and a plain numpy sum: gains times factors
    within 1e-5 of the mode's RMS gain (float32 sums of (L + 1)^2 terms; the fits' own error
    is up to 1e-2), a null mode at the floor, a contact microphone left alone; microphones
    made two at a time and an odd one alone; the cache kept under the step and made again
    beyond it, as the float64 kernel's."""
    rng = np.random.default_rng(11 + L)
    orders = [min(L, o) for o in (10, 10, 3, 0, 16, 5, 1)]
    n = len(orders)
    view, dd, coef, msh_off = _scene(rng, L, orders, M, owners)
    g = rng.normal(size=(M, n + 2)) + 1j * rng.normal(size=(M, n + 2))
    state = {k: (np.full((M, 3), np.nan), np.zeros((M, n + 2), np.complex128)) for k in ("f32", "f64")}

    def run(kind):
        xr, xi = g.real.copy(), g.imag.copy()
        U, Fd = state[kind]
        if kind == "f32":
            direction_factors(xr, xi, n, 1, view, U, Fd, np.zeros(M))
        else:
            direction_factors_f64(xr, xi, n, 1, 3, view, U, Fd, np.zeros(M))
        return xr + 1j * xi

    def plain():
        out = g.copy()
        for m in range(M):
            if owners[m] != AIR:
                continue
            u = view.R[1].T @ (view.mics[m] - view.pos[1])
            Y = np.empty(sh_count(L))
            real_sh(L, *(u / np.linalg.norm(u)), Y, sh_tables(L))
            for k in range(n):
                c = coef[msh_off[3 + k]:msh_off[4 + k]]
                f = Y[:len(c)] @ (c[:, 0] + 1j * c[:, 1])
                if abs(f) < DIRECTION_FLOOR:
                    f = DIRECTION_FLOOR * (f / abs(f) if f != 0 else 1.0)
                out[m, k] *= f
        return out

    def check():
        got, f64, ref = run("f32"), run("f64"), plain()
        np.testing.assert_allclose(f64, ref, rtol=1e-11, atol=1e-14)
        scale = np.abs(g[:, :n, None]).max()
        assert np.abs(got - ref).max() <= 1e-5 * scale
        np.testing.assert_array_equal(got[:, n:], g[:, n:])  # (the modes past n untouched)
        return got

    got = check()
    air = np.array(owners) == AIR
    np.testing.assert_array_equal(got[~air], g[~air])
    assert np.all(np.isnan(state["f32"][0][~air])) and np.all(np.isfinite(state["f32"][0][air]))
    assert np.abs(state["f32"][1][air, 2]) == pytest.approx(DIRECTION_FLOOR)
    R0 = view.R[1].copy()
    for deg, kept in ((0.5, True), (2.0, False)):
        a = np.radians(deg)
        view.R[1] = R0 @ np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
        before = state["f32"][1].copy()
        if kept:
            got = run("f32")
            np.testing.assert_array_equal(state["f32"][1], before)
            assert not np.allclose(got[air], plain()[air], rtol=1e-6)  # (the old factors)
        else:
            check()
