"""Sustained contact -> synthesizer streams, one numba call per physics step.

:meth:`ContactReader.events_fast` returns the step's sliding / rolling pairs as rows (columns
``R_*`` of :mod:`.contacts`); each pair and side that sounds owns a persistent noise stream of
the synthesizer (:meth:`mjsound.synth.Synthesizer._stream_index`). Whether the pair slides or
rolls this step only sets the drive (roughness and low-pass), so a contact that switches
between them keeps one continuous noise and one set of gains. The table ``sidx[slot, side]``
maps the reader's pair slot to that stream (-1: none yet), so a step's drives cost no Python
per contact: :func:`drive_rows` computes each drive's force amplitude and low-pass from the
row and generates its noise (``kernels.stream_drive``).
Side 0 is ``geom2`` (pushed along the normal), side 1 ``geom1`` (pushed against it).
:func:`read_and_drive` is the reader's kernel followed by :func:`drive_rows`: the whole
per-step contact work in one numba call (:class:`mjsound.sim.AudioSimulator` uses it once
every stream it needs exists).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..synth import kernels
from ..synth.pulse import contact_time
from .contacts import (I_G1, I_G2, I_IMPULSE, I_NORMAL, I_POINT, I_SPEED, R_FORCE, R_G1, R_G2, R_KIND, R_NORMAL,
                       R_POINT, R_SLOT, R_SPEED, _fused_kernel)

__all__ = ["drive_rows", "read_and_drive", "impact_sides", "impacts_to_synth", "pose_rows", "follow_rows"]


@njit(cache=True)
def drive_rows(rows, sidx, geom_obj, rough, length, fs, k0, k1, regain, rendered, slack, SF, SI, D, ring, missing):
    """Drive the streams of every sounding side of every row on synth samples ``[k0, k1)``.

    Parameters
    ----------
    rows : (pairs, R_COLS) float
        Sustained rows of the step (kind 1 slide, 2 roll).
    sidx : (slots, 2) int64
        Stream of (pair slot, side); -1 where none exists yet.
    geom_obj : (ngeom,) int64
        Synth object index of each geom (-1: silent or no modes).
    rough, length : (2,) float
        Roughness [1/(m/s)] and low-pass length [m] of slide and roll.
    fs : float
        Sample rate [Hz].
    k0, k1, regain, rendered, slack : int
        Block samples, gain refresh interval, samples rendered so far, ring slack.
    SF, SI, D, ring
        The synthesizer's stream arrays.
    missing : (>= 2 pairs, 2) int64
        Buffer: its first ``n_missing`` rows are set to the (row, side) pairs that need a
        stream first (nothing was driven for them).

    Returns
    -------
    n_missing : int
    need : int
        0, or the ring length needed before anything can be driven (nothing driven at all).
    """
    P = rows.shape[0]
    nm = 0
    cap = ring.shape[1]
    # the ring must hold the pending samples plus every stream's delay: check before any drive
    for r in range(P):
        kind = int(rows[r, R_KIND])
        slot = int(rows[r, R_SLOT])
        if kind == 0 or slot >= sidx.shape[0]:
            continue
        for side in range(2):
            s = sidx[slot, side]
            if s >= 0:
                for m in range(D.shape[1]):
                    need = D[s, m] + (k1 - rendered) + slack
                    if need > cap:
                        return 0, need
    p = np.empty(3)
    nrm = np.empty(3)
    for r in range(P):
        kind = int(rows[r, R_KIND])
        if kind == 0:
            continue
        fn = rows[r, R_FORCE]
        spd = rows[r, R_SPEED]
        if not (np.isfinite(fn) and np.isfinite(spd)):
            continue  # (points and normals are sanitised by the reader)
        slot = int(rows[r, R_SLOT])
        amp = rough[kind - 1] * abs(fn) * abs(spd)
        fc = min(abs(spd) / length[kind - 1], 0.45 * fs)
        alpha = 1.0 - np.exp(-2.0 * np.pi * fc / fs)
        for side in range(2):
            g = int(rows[r, R_G2]) if side == 0 else int(rows[r, R_G1])
            if geom_obj[g] < 0:
                continue
            s = sidx[slot, side] if slot < sidx.shape[0] else -1
            if s < 0:
                missing[nm, 0] = r
                missing[nm, 1] = side
                nm += 1
                continue
            sign = 1.0 if side == 0 else -1.0
            for c in range(3):
                p[c] = rows[r, R_POINT + c]
                nrm[c] = sign * rows[r, R_NORMAL + c]
            kernels.stream_drive(s, k0, k1, amp, alpha, p, nrm, regain, rendered, slack, SF, SI, D, ring)
    return nm, 0


@njit(cache=True)
def read_and_drive(geom, pos, frame, adr, dim, efc, pyramidal, cvel, scom, gxpos, gbody, broot, plane, ngeom,
                   hkeys, hvals, CF, CI, nslots, t0, t1, step, prm, counts, rows, srows, hits, onsets,
                   sidx, geom_obj, rough, length, fs, k0, k1, regain, rendered, slack, SF, SI, D, ring, missing):
    """The reader's per-step kernel (``contacts._fused_kernel``) followed by
    :func:`drive_rows` on its sustained rows: one numba call per physics step for reading
    every contact and driving every sliding / rolling stream. Returns the reader's outputs
    then ``(n_missing, need)`` of :func:`drive_rows` (see :meth:`ContactReader.events_fast`)."""
    P, ns, nh, nbad, nhuge, n_onset, nslots = _fused_kernel(
        geom, pos, frame, adr, dim, efc, pyramidal, cvel, scom, gxpos, gbody, broot, plane, ngeom,
        hkeys, hvals, CF, CI, nslots, t0, t1, step, prm, counts, rows, srows, hits, onsets)
    nm, need = 0, 0
    if ns and k1 > k0:
        nm, need = drive_rows(srows[:ns], sidx, geom_obj, rough, length, fs, k0, k1, regain, rendered, slack,
                              SF, SI, D, ring, missing)
    return P, ns, nh, nbad, nhuge, n_onset, nslots, nm, need


@njit(cache=True)
def pose_rows(gxpos, gxmat, geoms, idx, pos_out, R_out):
    """Object ``idx[q]``'s pose from geom ``geoms[q]``: ``pos_out[idx[q]] = gxpos[g]``,
    ``R_out[idx[q]] = gxmat[g]`` as 3x3 (rows with a non-finite pose are left as they were:
    an exploding simulation keeps the last good pose)."""
    for q in range(geoms.shape[0]):
        g = geoms[q]
        s = 0.0
        for c in range(3):
            s += gxpos[g, c]
        for c in range(9):
            s += gxmat[g, c]
        if not np.isfinite(s):
            continue
        o = idx[q]
        for c in range(3):
            pos_out[o, c] = gxpos[g, c]
        for a in range(3):
            for b in range(3):
                R_out[o, a, b] = gxmat[g, 3 * a + b]


@njit(cache=True)
def impact_sides(imp, geom_obj, coef_row, coef):
    """Every sounding side of a step's impacts (rows of ``ContactReader.events_fast``, columns
    ``I_*``; side 0 is geom2, pushed along the normal, side 1 geom1, pushed against it).

    Returns ``(obj, P, J, tau, missing)``: per side the synth object index, the world point
    [m], the impulse on that side [N s] and the Hertz pulse length [s] from the struck/other
    coefficient ``coef[coef_row[g], other]`` (``pulse.contact_time``); ``missing`` (m, 2) the
    (struck, other) geom pairs whose coefficient is not known yet (NaN: their sides are left
    out; the caller computes them and calls again).
    """
    K = imp.shape[0]
    obj = np.empty(2 * K, np.int64)
    P = np.empty((2 * K, 3))
    J = np.empty((2 * K, 3))
    tau = np.empty(2 * K)
    missing = np.empty((2 * K, 2), np.int64)
    n = 0
    nm = 0
    for r in range(K):
        g1 = int(imp[r, I_G1])
        g2 = int(imp[r, I_G2])
        for side in range(2):
            g = g2 if side == 0 else g1
            other = g1 if side == 0 else g2
            if geom_obj[g] < 0:
                continue
            c = coef[coef_row[g], other]
            if not (c == c):
                missing[nm, 0] = g
                missing[nm, 1] = other
                nm += 1
                continue
            a = (1.0 if side == 0 else -1.0) * imp[r, I_IMPULSE]
            obj[n] = geom_obj[g]
            for k in range(3):
                P[n, k] = imp[r, I_POINT + k]
                J[n, k] = a * imp[r, I_NORMAL + k]
            tau[n] = contact_time(c, imp[r, I_SPEED])
            n += 1
    return obj[:n], P[:n], J[:n], tau[:n], missing[:nm]


@njit(cache=True)
def impacts_to_synth(imp, geom_obj, coef_row, coef, t_ev, pts_all, pts_off, shk_all, shk_off, mode_off, wd_all,
                     w_all, lam_all, leps_all, pos_all, R_all, mics, c, fs, rmin, tol, rendered, grid,
                     QI, qkind, qre, qim, count, used):
    """:func:`impact_sides` then ``synth.kernels.impacts_to_queue`` at synth time ``t_ev``: a
    step's impacts into the synthesizer's event queue in one call. Returns ``(count, used,
    next sample, max |a|, missing)`` (nothing is queued while coefficients are missing)."""
    obj, P, J, tau, missing = impact_sides(imp, geom_obj, coef_row, coef)
    if missing.shape[0]:
        return count, used, np.int64(2**62), 0.0, missing
    t = np.full(obj.shape[0], t_ev)
    count, used, nxt, amax = kernels.impacts_to_queue(obj, P, J, t, tau, pts_all, pts_off, shk_all, shk_off,
                                                      mode_off, wd_all, w_all, lam_all, leps_all, pos_all, R_all,
                                                      mics, c, fs, rmin, tol, rendered, grid, QI, qkind, qre, qim,
                                                      count, used)
    return count, used, nxt, amax, missing


@njit(cache=True)
def follow_rows(pos, rows, offsets, out):
    """``out[m] = pos[rows[m]] + offsets[m]`` (microphones at a body or at their sites; a
    single row repeated for a following listener), unless a position is not finite (then
    ``out`` keeps the last good ones). Returns whether ``out`` was updated."""
    M = out.shape[0]
    s = 0.0
    for m in range(M):
        for c in range(3):
            s += pos[rows[m], c] + offsets[m, c]
    if not np.isfinite(s):
        return False
    for m in range(M):
        for c in range(3):
            out[m, c] = pos[rows[m], c] + offsets[m, c]
    return True
