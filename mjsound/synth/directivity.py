"""Each air microphone hears each object's modes with the object's radiation pattern in the
direction from the object to the microphone.

A model's pattern ``P_i(u)`` (:meth:`mjsound.modal.model.ModalModel.radiation_pattern`: far-field
pressure at 1 m per unit modal coordinate [Pa m] in the direction ``u``, a unit vector of the
object's frame; complex, for a mode ``q(t) = Re(Q e^{-j w t})``) is heard through its
*direction factor*

    D_i(u) = conj(P_i(u)) / w_i,      w_i = model.radiation[i] (the RMS of |P_i| over directions),

so that the events and streams keep their gains ``w_i / r`` (:mod:`.kernels`) and a pattern the
same in every direction has ``D = 1``: such an object takes none of the steps below and sounds
bit for bit as before. ``D`` multiplies the mode's complex state ``z_i`` (the output is
``Im z_i``): a mode ``q = Im(c e^{lambda t})`` is heard as ``Im(D c e^{lambda t})``. The
oscillators turn as ``e^{+j w t}``, the pattern's convention as ``e^{-j w t}``: with
``q = Re(Q e^{-j w t}) = Im(c e^{j w t})``, ``Re(P Q e^{-j w t}) = Im(conj(P) c e^{j w t})``,
hence the conjugate. The pattern's phase is referred to the model's ``radiation_centre``; the
delay ``r / c`` is taken from the object's origin (a centre off the origin by ``x`` shifts the
phase by ``k u.x``, which is not added).

**Stored compactly.** At :func:`fit_directions` (once per object) ``D`` is projected on real
orthonormal spherical harmonics ``Y_lm`` up to order ``DIRECTION_ORDER`` (Gauss-Legendre in
``cos theta`` times a uniform grid in ``phi``, at the stored pattern's own degree when finer:
exact for a band-limited pattern); each mode keeps the lowest order that leaves at most
``ORDER_TOL`` of its energy above it (a dipole: 1; a mode of low ``ka`` few, one of high
``ka`` up to 16), and the fit's relative RMS error on an independent set of directions is
reported (:attr:`DirectionFit.error`).

**Heard per render block.** :func:`hear_directions` runs at the start of each block, for the
(object, air microphone) voices that sound in it (ringing modes, or events or forcing rows in
the block): the direction ``u = R^T (mic - pos) / |mic - pos|`` in the object's current pose;
only when it turned by more than ``DIRECTION_STEP_DEG`` since the voice's factors were made
are they evaluated again (``sum_lm Y_lm(u) c_lm`` up to each mode's order, numba). The voice's state carries its
applied factor ``A``; a new target ``T`` is reached *across the block*: the ringing modes'
poles are multiplied by ``rho = (T / A)^(1 / n)`` for the block's ``n`` samples (an exponential
ramp of the gain at no cost per sample: no zipper noise), an event at sample ``s`` of the block
is added with ``A rho^s`` and forcing rows with ``A rho^(n/2)``; at the block's end ``A = T``.
A voice with nothing ringing takes ``T`` at once. ``|D|`` is floored at ``DIRECTION_FLOOR``
(a mode in an exact null keeps its state, so it comes back when the object turns), and the
culling peak is rescaled with the gain so that culling stays relative to the mode's own decay.
The distance ``r`` of ringing modes stays that of their event (as before).

Contact microphones hear their own object's surface (:mod:`.contact_mic`): no direction.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..jit import njit, njit_inner
from .bank_loops import FAST
from .records import AIR, DIRECTIONS

__all__ = ["DIRECTION_ORDER", "DIRECTION_STEP_DEG", "DIRECTION_FLOOR", "ORDER_TOL", "DirectionFit", "real_sh",
           "sh_count", "sh_tables",
           "fit_directions", "evaluate_fit", "hear_directions", "ModeGains", "gain_at", "ramp_poles", "scale_sources",
           "commit_ramp"]

#: Highest spherical-harmonic order of a fitted direction factor (the analysis stores up to 16
#: at its default quality).
DIRECTION_ORDER = 16
#: The direction to a microphone must turn by more than this [degrees] before the factors are
#: evaluated again.
DIRECTION_STEP_DEG = 1.0
#: Smallest ``|D|`` heard (-80 dB under the mode's RMS over directions): a null keeps the state.
DIRECTION_FLOOR = 1e-4
#: Energy a mode's fit may leave above its order, relative to the mode's (1 % of the RMS
#: amplitude): each mode keeps the lowest order that leaves no more.
ORDER_TOL = 1e-4


def sh_count(order: int) -> int:
    """Number of real spherical harmonics up to ``order``: ``(order + 1)^2``."""
    return (order + 1) ** 2


def sh_tables(order: int) -> np.ndarray:
    """(3, (order+1)^2) recurrence factors of :func:`real_sh` at index ``l^2 + l + m`` (m >= 0):
    ``a_lm = sqrt((4 l^2 - 1) / (l^2 - m^2))``, ``b_lm = sqrt(((l-1)^2 - m^2) / (4 (l-1)^2 - 1))``
    (l >= m + 1; at l = m + 1, ``a = sqrt(2m + 3)`` and ``b = 0``) and ``s_m = sqrt((2m + 1) / (2m))``
    (at l = m)."""
    tab = np.zeros((3, sh_count(order)))
    for m in range(order + 1):
        for l in range(m, order + 1):
            i = l * l + l + m
            if l >= m + 1:
                tab[0, i] = np.sqrt((4 * l * l - 1) / (l * l - m * m))
                tab[1, i] = np.sqrt(((l - 1) ** 2 - m * m) / (4 * (l - 1) ** 2 - 1))
            if l == m and m > 0:
                tab[2, i] = np.sqrt((2 * m + 1) / (2 * m))
    return tab


@njit(cache=True)
def real_sh(order, x, y, z, out, tab):
    """Real orthonormal spherical harmonics at the unit vector ``(x, y, z)`` into
    ``out[l^2 + l + m]`` for ``0 <= l <= order``, ``-l <= m <= l``::

        Y_l0 = a_l0(z),   Y_l,+m = sqrt(2) a_lm(z) Re (x + j y)^m,   Y_l,-m = sqrt(2) a_lm(z) Im (x + j y)^m

    with ``a_lm = N_lm P_l^m(z) / sin^m(theta)``, ``N_lm = sqrt((2l+1)/(4 pi) (l-m)!/(l+m)!)``
    (no Condon-Shortley sign), ``(x + j y)^m = sin^m(theta) e^{j m phi}``, from the normalised
    recurrences ``a_00 = 1 / sqrt(4 pi)``, ``a_mm = s_m a_m-1,m-1``, ``a_m+1,m = sqrt(2m+3) z a_mm``,
    ``a_lm = a_lm' (z a_l-1,m - b_lm a_l-2,m)`` with the factors ``tab`` of :func:`sh_tables`
    (``a_lm'``, ``b_lm``, ``s_m``; ``a_m+1,m`` is the recurrence's with ``a_m-1,m = 0``). The
    basis is orthonormal: ``int Y_a Y_b dOmega = delta_ab``. (Each step is one multiply-add on
    the recurrence's chain, ``(a' z) a_l-1,m - (a' b) a_l-2,m``; the orders m one after the other.)"""
    amm = 0.5 / np.sqrt(np.pi)  # a_mm
    out[0] = amm
    p2 = 0.0
    p1 = amm
    for l in range(1, order + 1):  # m = 0
        i = l * l + l
        a = tab[0, i]
        p = (a * z) * p1 - (a * tab[1, i]) * p2
        out[i] = p
        p2 = p1
        p1 = p
    r2 = np.sqrt(2.0)
    cm = 1.0  # Re (x + j y)^m
    sm = 0.0  # Im
    for m in range(1, order + 1):
        cm, sm = cm * x - sm * y, cm * y + sm * x
        amm *= tab[2, m * m + 2 * m]
        rc = r2 * cm
        rs = r2 * sm
        out[m * m + 2 * m] = amm * rc
        out[m * m] = amm * rs
        p2 = 0.0
        p1 = amm
        for l in range(m + 1, order + 1):
            i = l * l + l
            a = tab[0, i + m]
            p = (a * z) * p1 - (a * tab[1, i + m]) * p2
            p2 = p1
            p1 = p
            out[i + m] = p * rc
            out[i - m] = p * rs


def _basis(order: int, dirs: np.ndarray) -> np.ndarray:
    """(n_dirs, (order+1)^2) real spherical harmonics at unit vectors ``dirs`` (n_dirs, 3)."""
    out = np.empty((len(dirs), sh_count(order)))
    tab = sh_tables(order)
    for k, (x, y, z) in enumerate(dirs):
        real_sh(order, float(x), float(y), float(z), out[k], tab)
    return out


def _quadrature(order: int) -> tuple[np.ndarray, np.ndarray]:
    """Directions (q, 3) and weights (q,) integrating exactly over the sphere every product of
    two spherical harmonics up to ``order``: Gauss-Legendre in ``cos theta`` (``order + 1``
    nodes) times ``2 order + 1`` equal steps in ``phi`` (offset by half a step)."""
    zc, wz = np.polynomial.legendre.leggauss(order + 1)
    nphi = 2 * order + 1
    phi = (np.arange(nphi) + 0.5) * 2 * np.pi / nphi
    s = np.sqrt(1 - zc**2)
    dirs = np.stack([np.outer(s, np.cos(phi)), np.outer(s, np.sin(phi)), np.repeat(zc[:, None], nphi, 1)], -1)
    return dirs.reshape(-1, 3), np.repeat(wz * 2 * np.pi / nphi, nphi)


def _check_directions(n: int) -> np.ndarray:
    """``n`` well-spread unit vectors (a Fibonacci lattice), independent of any quadrature grid."""
    k = np.arange(n) + 0.5
    z = 1 - 2 * k / n
    phi = np.pi * (1 + 5**0.5) * k
    s = np.sqrt(1 - z**2)
    return np.stack([s * np.cos(phi), s * np.sin(phi), z], -1)


class DirectionFit(NamedTuple):
    """:func:`fit_directions`' result for one object's kept modes."""

    order: int  #: highest spherical-harmonic order of its modes; -1: the same in every direction (D = 1)
    orders: np.ndarray  #: (n_modes,) int64 each mode's order (its coefficients beyond are zero)
    coef: np.ndarray  #: (n_modes, (order+1)^2) complex128 coefficients of D on Y_lm
    error: np.ndarray  #: (n_modes,) relative RMS error of the fit on independent directions

    @classmethod
    def none(cls, n: int) -> "DirectionFit":
        """``n`` modes heard the same in every direction."""
        return cls(-1, np.full(n, -1, np.int64), np.zeros((n, 0), np.complex128), np.zeros(n))


def _pattern(model, directions: np.ndarray, name: str) -> np.ndarray:
    """The model's (n_dirs, n_modes) pattern at ``directions``, its shape and values checked."""
    P = np.asarray(model.radiation_pattern(directions))
    n = len(model.frequencies_hz)
    if P.shape != (len(directions), n):
        raise ValueError(f"model of {name!r}: radiation_pattern(directions) gave shape {P.shape}, expected "
                         f"({len(directions)}, {n}) (directions x modes); fix the model's pattern")
    if not np.all(np.isfinite(P)):
        raise ValueError(f"model of {name!r}: radiation_pattern has non-finite values; recompute the model's "
                         "radiation or use Synthesizer(directivity=False)")
    return P


def fit_directions(model, keep: np.ndarray, weights: np.ndarray, name: str = "object",
                   order_max: int = DIRECTION_ORDER) -> DirectionFit:
    """The direction factors ``D = conj(P) / w`` of the modes ``keep`` of ``model`` as
    spherical-harmonic coefficients, each mode cut at its own order (module docstring).

    Parameters
    ----------
    model : ModalModel
        Its ``radiation_pattern(directions)`` -> (n_dirs, n_modes) [Pa m] (complex, in the
        ``e^{-j w t}`` convention).
    keep : (n,) int
        The modes the synthesizer keeps.
    weights : (n,) float
        Their gains ``w`` [Pa m] (``model.radiation[keep]``); a mode with ``w = 0`` gets
        ``D = 1`` (it is silent anyway).
    name : str
        For error messages.
    order_max : int
        Highest order kept (a finer stored pattern is sampled at its own degree and smoothed).

    Returns
    -------
    DirectionFit
        ``order = -1`` when the pattern is exactly ``w`` in every sampled direction.

    Examples
    --------
    A pattern ``w sqrt(3) cos(theta)`` (a dipole along z, RMS ``w``) is order 1::

        >>> fit = fit_directions(dipole_model, np.arange(1), np.ones(1))  # doctest: +SKIP
        >>> fit.order
        1
    """
    keep = np.asarray(keep, np.int64)
    w = np.asarray(weights, np.float64)
    n = len(keep)
    sh = getattr(model, "radiation_sh", None)  # (sampled at its own degree when finer: no aliasing)
    q_order = max(order_max, int(round(np.sqrt(np.shape(sh)[1]))) - 1 if np.ndim(sh) == 2 else 0)
    dirs, wq = _quadrature(q_order)
    P = _pattern(model, dirs, name)
    if n == 0:
        return DirectionFit.none(n)
    P = P[:, keep]
    if np.array_equal(P, np.broadcast_to(w, P.shape)):
        return DirectionFit.none(n)
    safe = np.where(w != 0, w, 1.0)
    D = np.where(w != 0, np.conj(P) / safe, 1.0)  # (e^{-j w t} -> the oscillators' e^{+j w t})
    Y = _basis(order_max, dirs)
    C = (Y * wq[:, None]).T @ D  # ((L+1)^2, n): c_lm = sum_q w_q Y_lm(u_q) D(u_q)
    energy = np.abs(C) ** 2
    # each mode's order: the lowest that leaves at most ORDER_TOL of its energy above it
    tail = energy.sum(0)[None, :] - np.cumsum(np.add.reduceat(energy, [l * l for l in range(order_max + 1)], 0), 0)
    orders = np.argmax(tail <= ORDER_TOL * energy.sum(0)[None, :] + 1e-300, axis=0).astype(np.int64)
    orders[~np.any(tail <= ORDER_TOL * energy.sum(0)[None, :] + 1e-300, axis=0)] = order_max
    order = int(orders.max(initial=0))
    C = C[: sh_count(order)].T.copy()
    for j in range(n):
        C[j, sh_count(orders[j]):] = 0.0
    coef = np.ascontiguousarray(C, np.complex128)
    chk = _check_directions(200)
    Pc = _pattern(model, chk, name)[:, keep]
    Dc = np.where(w != 0, np.conj(Pc) / safe, 1.0)
    fit = _basis(order, chk) @ coef.T
    err = np.sqrt(np.mean(np.abs(fit - Dc) ** 2, 0) / np.maximum(np.mean(np.abs(Dc) ** 2, 0), 1e-300))
    return DirectionFit(order, orders, coef, err)


def evaluate_fit(fit: DirectionFit, directions) -> np.ndarray:
    """(n_dirs, n_modes) complex direction factors of ``fit`` at unit vectors ``directions``
    (n_dirs, 3) of the object's frame (1 everywhere for ``order = -1``), before the floor."""
    d = np.asarray(directions, np.float64).reshape(-1, 3)
    if fit.order < 0:
        return np.ones((len(d), len(fit.coef)), np.complex128)
    return _basis(fit.order, d / np.linalg.norm(d, axis=1, keepdims=True)) @ fit.coef.T


@njit_inner(cache=True, inline="always")  # (numba IR: no call that reference-counts the records)
def _row_columns(ptr, re, im, m, hit):
    """``hit[j] |= `` whether column ``j`` of rows ``ptr[m] .. ptr[m + 1]`` of ``re + j im``
    (events or forcing rows of bank ``m`` in the block) is non-zero: one pass over the rows
    (a branch-free loop), not one per voice."""
    for e in range(ptr[m], ptr[m + 1]):
        for j in range(re.shape[1]):
            hit[j] |= (re[e, j] != 0.0) | (im[e, j] != 0.0)


@njit_inner(cache=True, fastmath=FAST)
def _factor(Y, cr, ci):
    """``sum_k Y[k] (cr + j ci)[k]`` over the views' length (one mode's factor at one direction).
    Its own kernel with ``fastmath``, over views that start at 0, so that LLVM vectorises the
    sum (inlined into :func:`hear_directions`, whose NaN tests need strict IEEE semantics, or
    indexed from an offset, it runs one coefficient at a time: about 4x slower at order 10)."""
    re = 0.0
    im = 0.0
    for k in range(cr.shape[0]):
        re += Y[k] * cr[k]
        im += Y[k] * ci[k]
    return re, im


@njit_inner(cache=True, inline="always")
def _cmul(ar, ai, br, bi):
    """``(ar + j ai)(br + j bi)`` as its real and imaginary parts."""
    return ar * br - ai * bi, ar * bi + ai * br


@njit_inner(cache=True, inline="always")
def _root(qr, qi, n):
    """``(xr, xi, rr, ri)``: ``x = log(q) / n`` (principal branch) and ``rho = e^x``, the
    per-sample factor whose ``n``-th power is ``q = qr + j qi``. Near 1 (``|q - 1| < 1/4``: a
    turn of a few degrees per block, the common case) from ``log q = 2 atanh w``,
    ``w = (q - 1) / (q + 1)``, to the ninth power of ``w`` (``|w| < 0.15``: relative error
    below 1e-9) and ``e^x`` to the fourth power of ``x`` (``|x| < 1e-3 / n``), in real
    arithmetic; else from the real ``log`` of ``|q|^2``, ``arctan2`` and ``e^x`` to the eighth
    power of ``x`` (``|x| < 0.05``) or ``exp``, ``cos`` and ``sin``."""
    dr = qr - 1.0
    inv_n = 1.0 / n
    if dr * dr + qi * qi < 0.0625:
        sr = qr + 1.0
        den = sr * sr + qi * qi
        wr, wi = _cmul(dr, qi, sr / den, -qi / den)
        w2r, w2i = _cmul(wr, wi, wr, wi)
        pr, pi = 1.0 / 7.0 + w2r / 9.0, w2i / 9.0  # Horner: 1 + w2 (1/3 + w2 (1/5 + w2 (1/7 + w2/9)))
        pr, pi = _cmul(w2r, w2i, pr, pi)
        pr, pi = _cmul(w2r, w2i, pr + 0.2, pi)
        pr, pi = _cmul(w2r, w2i, pr + 1.0 / 3.0, pi)
        zr, zi = _cmul(wr, wi, pr + 1.0, pi)
        xr = 2.0 * zr * inv_n
        xi = 2.0 * zi * inv_n
        er, ei = xr * (1.0 / 24.0) + 1.0 / 6.0, xi * (1.0 / 24.0)  # e^x = 1 + x (1 + x (1/2 + x (1/6 + x/24)))
        er, ei = _cmul(xr, xi, er, ei)
        er, ei = _cmul(xr, xi, er + 0.5, ei)
        er, ei = _cmul(xr, xi, er + 1.0, ei)
        return xr, xi, er + 1.0, ei
    # (the real functions: numba's complex log and exp take the modulus by hypot and guard
    # every special value; q is finite and not 0 here, |T| and |A| >= the floor)
    xr = 0.5 * np.log(qr * qr + qi * qi) * inv_n
    xi = np.arctan2(qi, qr) * inv_n
    if xr * xr + xi * xi < 0.0025:  # e^x to the eighth power of x (|x| < 0.05: error below 1e-17)
        er, ei = xr * (1.0 / 40320.0) + 1.0 / 5040.0, xi * (1.0 / 40320.0)
        er, ei = _cmul(xr, xi, er, ei)
        er, ei = _cmul(xr, xi, er + 1.0 / 720.0, ei)
        er, ei = _cmul(xr, xi, er + 1.0 / 120.0, ei)
        er, ei = _cmul(xr, xi, er + 1.0 / 24.0, ei)
        er, ei = _cmul(xr, xi, er + 1.0 / 6.0, ei)
        er, ei = _cmul(xr, xi, er + 0.5, ei)
        er, ei = _cmul(xr, xi, er + 1.0, ei)
        return xr, xi, er + 1.0, ei
    e = np.exp(xr)
    return xr, xi, e * np.cos(xi), e * np.sin(xi)


@njit(cache=True)
def hear_directions(synth, bank, layout, ev, src, n):
    """Make each sounding (object, air microphone) voice's direction factors follow the
    direction from the object's pose (``synth.pos``, ``synth.R``) to the microphone
    (``synth.mics``) for the block of ``n`` samples about to be rendered with the events
    ``ev`` and forcing rows ``src`` (:class:`.records.EventRows`, :class:`.records.SourceRows`);
    module docstring. When the direction turned, each ringing mode gets its target ``tr, ti``,
    per-sample log ratio ``lr, li`` and factor ``rho`` (and its bank ``ramp``: applied and
    committed by :func:`.kernels.render_all`); a silent mode of a voice with rows in the block
    takes its target at once; the other silent modes are left unmade (``ar`` NaN), made at the
    voice's direction in the first block that has rows for the voice. Only modes that sound
    are evaluated."""
    dr = bank.direction
    if dr.n_objects[0] == 0 or n <= 0:
        return
    # (the records' arrays as locals: a record passed on or read in a loop is reference-counted
    # member by member on every use)
    prm = dr.params[0]
    cos_step, floor = prm.cos_step, prm.floor
    floor2 = floor * floor
    order, msh_off, cr, ci, U = dr.order, dr.msh_off, dr.coef_r, dr.coef_i, dr.u
    ar, ai, tr, ti, lr, li, rr, ri, ramp = dr.ar, dr.ai, dr.tr, dr.ti, dr.lr, dr.li, dr.rho_r, dr.rho_i, dr.ramp
    Y, tab = dr.sh, dr.sh_tab
    act, peak2, bstart = bank.active, bank.peak2, bank.start
    vbase, v_rel, v_len = layout.vbase, layout.v_rel, layout.v_len
    ev_ptr, ev_re, ev_im = ev.ptr, ev.re, ev.im
    src_ptr, src_gr, src_gi = src.ptr, src.gr, src.gi
    owner = synth.channels["owner"]
    mics, P, Rs, mode_off = synth.mics, synth.pos, synth.R, synth.objects.mode_off
    M = owner.shape[0]
    # the columns of each air bank with an event or a forcing row in this block
    hit = np.zeros((M, max(layout.width, ev_re.shape[1], src_gr.shape[1])), np.bool_)
    for m in range(M):
        if owner[m] == AIR:
            _row_columns(ev_ptr, ev_re, ev_im, m, hit[m])
            _row_columns(src_ptr, src_gr, src_gi, m, hit[m])
    # per voice of the object being made (slot t < nsel): its microphone, whether its direction
    # turned, whether it has rows in the block, whether its Y[t] is made, whether it ramps
    vm = np.empty((5, M), np.int64)
    for o in range(order.shape[0]):
        L = order[o]
        if L < 0 or o >= vbase.shape[0] or vbase[o] < 0:
            continue
        g0 = mode_off[o]
        nm = 0
        nsel = 0
        for m in range(M):
            if owner[m] != AIR:
                continue
            v = vbase[o] + m
            c0 = v_rel[v]
            nm = v_len[v]
            s0 = bstart[m] + c0
            ringing = False
            for i in range(s0, s0 + nm):
                if act[i]:
                    ringing = True
                    break
            rows = False
            for j in range(c0, c0 + nm):
                if hit[m, j]:
                    rows = True
                    break
            if not (ringing or rows):
                continue
            dx = mics[m, 0] - P[o, 0]
            dy = mics[m, 1] - P[o, 1]
            dz = mics[m, 2] - P[o, 2]
            r = np.sqrt(dx * dx + dy * dy + dz * dz)
            turned = False
            if r > 0.0:  # (a microphone at the object's origin: no direction to follow)
                ux = (Rs[o, 0, 0] * dx + Rs[o, 1, 0] * dy + Rs[o, 2, 0] * dz) / r  # u = R^T (mic - pos) / r
                uy = (Rs[o, 0, 1] * dx + Rs[o, 1, 1] * dy + Rs[o, 2, 1] * dz) / r
                uz = (Rs[o, 0, 2] * dx + Rs[o, 1, 2] * dy + Rs[o, 2, 2] * dz) / r
                if not ux * U[v, 0] + uy * U[v, 1] + uz * U[v, 2] >= cos_step:  # (NaN: never made)
                    U[v, 0] = ux
                    U[v, 1] = uy
                    U[v, 2] = uz
                    turned = True
            if not np.isfinite(U[v, 0]) or not (turned or rows):  # (nothing to make)
                continue
            vm[0, nsel] = m
            vm[1, nsel] = turned
            vm[2, nsel] = rows
            vm[3, nsel] = False
            vm[4, nsel] = False
            nsel += 1
        # mode by mode, each for every voice made (a microphone and its images): the mode's
        # coefficients are read once from memory for all of them
        for j in range(nm if nsel > 0 else 0):
            k0 = msh_off[g0 + j]
            k1 = msh_off[g0 + j + 1]
            crj = cr[k0:k1]
            cij = ci[k0:k1]
            for t in range(nsel):
                m = vm[0, t]
                turned = vm[1, t] != 0
                rows = vm[2, t] != 0
                i = bstart[m] + v_rel[vbase[o] + m] + j
                stale = not np.isfinite(ar[i])
                ring = act[i] and not stale
                if ring and not turned:
                    continue
                if not ring and not rows:  # (silent, nothing for it in this block: made when it has)
                    if turned:
                        ar[i] = np.nan
                    continue
                if not ring and not (turned or stale):
                    continue
                if vm[3, t] == 0:
                    v = vbase[o] + m
                    real_sh(L, U[v, 0], U[v, 1], U[v, 2], Y[t], tab)
                    vm[3, t] = True
                fr, fi = _factor(Y[t, :k1 - k0], crj, cij)
                a2 = fr * fr + fi * fi
                if not a2 >= floor2:  # (a null, or a NaN pattern: the floor, with the phase if any)
                    if a2 > 0.0:
                        c = floor / np.sqrt(a2)
                        fr *= c
                        fi *= c
                    else:
                        fr = floor
                        fi = 0.0
                tr[i] = fr
                ti[i] = fi
                if ring:  # ramped across the block
                    den = ar[i] * ar[i] + ai[i] * ai[i]  # (|A| >= floor > 0)
                    qr, qi = _cmul(fr, fi, ar[i] / den, -ai[i] / den)  # T / A
                    lr[i], li[i], rr[i], ri[i] = _root(qr, qi, n)
                    peak2[i] *= qr * qr + qi * qi
                    vm[4, t] = True
                else:  # silent: at once
                    ar[i] = fr
                    ai[i] = fi
        for t in range(nsel):
            if vm[4, t] != 0:
                ramp[vm[0, t]] = True


# ---------------------------------------------------------------- applied by the render (.kernels)
class ModeGains(NamedTuple):
    """One bank's direction factors for this block (views into :class:`.records.DirectionState`;
    :mod:`.directivity`): mode i carries ``D_i(s) = (ar_i + j ai_i) e^{s (lr_i + j li_i)}`` at
    sample ``s`` of the block. ``on``: the bank has a directional mode (``dmode``); ``ramp``:
    some ``lr, li`` is not zero."""

    on: bool
    ramp: bool
    dmode: np.ndarray
    ar: np.ndarray
    ai: np.ndarray
    lr: np.ndarray
    li: np.ndarray
    rho_r: np.ndarray
    rho_i: np.ndarray


@njit_inner(cache=True, inline="always")
def gain_at(gains, i, s):
    """``D_i(s)`` of :class:`ModeGains` (complex)."""
    d = complex(gains.ar[i], gains.ai[i])
    if gains.lr[i] != 0.0 or gains.li[i] != 0.0:
        d = d * np.exp(s * complex(gains.lr[i], gains.li[i]))
    return d


@njit_inner(cache=True)
def ramp_poles(wpr, wpi, idx, na, gains):
    """The gathered poles of the ramping modes times ``rho = e^{lr + j li}`` (the gain's
    per-sample factor: the block's exponential ramp at no cost per sample)."""
    for k in range(na):
        i = idx[k]
        if gains.lr[i] != 0.0 or gains.li[i] != 0.0:
            a = np.float64(wpr[k])
            b = np.float64(wpi[k])
            wpr[k] = a * gains.rho_r[i] - b * gains.rho_i[i]
            wpi[k] = a * gains.rho_i[i] + b * gains.rho_r[i]


@njit_inner(cache=True)
def scale_sources(gr, gi, gains, s):
    """Forcing rows' gains ``gr + j gi`` (q, m) of the directional modes times ``D(s)`` (only
    the non-zero ones: a silent mode's factor may be unmade, NaN)."""
    for i in range(gr.shape[1]):
        if gains.dmode[i]:
            d = complex(np.nan, np.nan)
            for q in range(gr.shape[0]):
                if gr[q, i] == 0.0 and gi[q, i] == 0.0:
                    continue
                if d != d:
                    d = gain_at(gains, i, s)
                g = complex(np.float64(gr[q, i]), np.float64(gi[q, i])) * d
                gr[q, i] = g.real
                gi[q, i] = g.imag


@njit_inner(cache=True)
def commit_ramp(dr, o, m):
    """The ramped modes ``o .. o + m`` of :class:`.records.DirectionState` reached their target."""
    for i in range(o, o + m):
        if dr.lr[i] != 0.0 or dr.li[i] != 0.0:
            dr.ar[i] = dr.tr[i]
            dr.ai[i] = dr.ti[i]
            dr.lr[i] = 0.0
            dr.li[i] = 0.0
            dr.rho_r[i] = 1.0
            dr.rho_i[i] = 0.0
