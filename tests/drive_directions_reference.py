"""The float64 direction factors the drives used before their float32 ones
(:func:`mjsound.synth.drive_directions.direction_factors`): the reference the tests compare
them with (the fits' sums at each microphone's direction, :mod:`mjsound.synth.directivity`)."""

from numba import njit

from mjsound.synth.directivity import _factor, real_sh
from mjsound.synth.drive_directions import _floored, apply_factors, turned_directions


@njit(cache=True, fastmath=True)
def _factor_pair(Y0, Y1, cr, ci):
    """``sum_k Y0[k] (cr + j ci)[k]`` and the same with ``Y1`` (one mode's factor at two
    directions: its coefficients read once; over the views' length, vectorised as
    :func:`.directivity._factor`)."""
    r0 = 0.0
    i0 = 0.0
    r1 = 0.0
    i1 = 0.0
    for k in range(cr.shape[0]):
        r0 += Y0[k] * cr[k]
        i0 += Y0[k] * ci[k]
        r1 += Y1[k] * cr[k]
        i1 += Y1[k] * ci[k]
    return r0, i0, r1, i1


@njit(cache=True)
def direction_factors_f64(xr, xi, n, o, m0, view, U, Fd, heard):
    """The float64 reference of :func:`.drive_directions.direction_factors` (the weights use
    that one, on the fits' float32 copy; its tests compare with this one):
    ``xr + j xi`` (M, :n) (object ``o``'s modes, the first at ``m0`` of the flat order) times
    each mode's direction factor towards air microphone ``m`` now (:func:`.directivity.hear_directions`'
    target: the fit at ``u = R^T (mic - pos) / r``, its magnitude floored), made again only
    when ``u`` turned by more than the synthesizer's step since the factors ``Fd[m]`` were
    made for ``U[m]`` (a body's own cache; NaN: never made); ``view``: a :class:`SceneView`;
    ``heard`` (>= M,) scratch (0: no factor, 1: the kept one, 2: made again now). The
    microphones whose direction turned are made two at a time, each mode's coefficients read
    once for both (:func:`_factor_pair`), each microphone's harmonics in its own row of the
    synthesizer's scratch."""
    msh_off, cfr, cfi, Y, tab = view.msh_off, view.coef_r, view.coef_i, view.sh, view.sh_tab
    floor = view.params[0].floor
    L = view.order[o]
    M = min(xr.shape[0], view.mics.shape[0], Y.shape[0])
    turned_directions(view, o, M, U, heard)
    for m in range(M):
        if heard[m] == 2.0:
            real_sh(L, U[m, 0], U[m, 1], U[m, 2], Y[m], tab)
    m = 0
    while m < M:
        while m < M and heard[m] != 2.0:
            m += 1
        m1 = m + 1
        while m1 < M and heard[m1] != 2.0:
            m1 += 1
        if m >= M:
            break
        Y0 = Y[m]
        if m1 < M:
            Y1 = Y[m1]
            for k in range(n):
                k0 = msh_off[m0 + k]
                k1 = msh_off[m0 + k + 1]
                if k1 > k0:
                    r0, i0, r1, i1 = _factor_pair(Y0[:k1 - k0], Y1[:k1 - k0], cfr[k0:k1], cfi[k0:k1])
                    Fd[m, k] = _floored(r0, i0, floor)
                    Fd[m1, k] = _floored(r1, i1, floor)
                else:
                    Fd[m, k] = 1.0
                    Fd[m1, k] = 1.0
        else:
            for k in range(n):
                k0 = msh_off[m0 + k]
                k1 = msh_off[m0 + k + 1]
                if k1 > k0:
                    r0, i0 = _factor(Y0[:k1 - k0], cfr[k0:k1], cfi[k0:k1])
                    Fd[m, k] = _floored(r0, i0, floor)
                else:
                    Fd[m, k] = 1.0
        m = m1 + 1
    apply_factors(xr, xi, n, M, Fd, heard)
