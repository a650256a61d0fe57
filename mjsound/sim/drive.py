"""A substep's events -> the synthesizer: impacts into its queue, sliding / rolling into its
streams, poses and microphones to where they are (numba; stages of :mod:`.step`).

Impacts: each sounding side of an impact (side 0 is geom2, pushed along the normal; side 1
geom1, pushed against it) strikes its synthesizer object with the Hertz pulse length
``tau = coef v^(-1/5)`` of the (struck, other) geom pair (:func:`mjsound.synth.pulse.hertz_coef`
on the masses, radii and compliances of ``DriveState.sound``).

Sustained contact: each pair and side that sounds owns a persistent noise stream of the
synthesizer (:meth:`mjsound.synth.Synthesizer.stream`); whether the pair slides or rolls this
step only sets the drive (roughness and low-pass), so a contact that switches between them
keeps one continuous noise and one set of gains. ``DriveState.sidx[slot, side]`` maps the
reader's pair slot to that stream (-1: none yet, :data:`.step.STREAMS`).
"""

from __future__ import annotations

import math

import numpy as np

from ..jit import njit, njit_inner
from ..synth.constants import MAX_AMPLITUDE
from ..synth.impact_energy import collision_mass, lost_energy
from ..synth.kernels import commit_queued, impacts_to_queue
from ..synth.pulse import contact_time, effective, hertz_coef, shell_contact_time
from ..synth.streams import ring_need, stream_drive

__all__ = ["sync_poses", "impact_sides", "queue_impacts", "missing_streams", "drive_sustained", "pose_rows",
           "follow_rows"]


@njit_inner(cache=True)
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
def follow_rows(pos, rows, offsets, affine, out):
    """``out[m] = A_m (pos[rows[m]] + offsets[m]) + b_m`` with ``affine[m] = [A_m | b_m]``
    (microphones at a body or at their sites, a single row repeated for a following listener;
    an image microphone's mirrors, :mod:`.images`, the identity for the others: ``1 x + 0 y +
    0 z + 0`` is ``x`` exactly), unless a position is not finite (then ``out`` keeps the last
    good ones). Returns whether ``out`` was updated."""
    M = out.shape[0]
    s = 0.0
    for m in range(M):
        for c in range(3):
            s += pos[rows[m], c] + offsets[m, c]
    if not np.isfinite(s):
        return False
    for m in range(M):
        x0 = pos[rows[m], 0] + offsets[m, 0]
        x1 = pos[rows[m], 1] + offsets[m, 1]
        x2 = pos[rows[m], 2] + offsets[m, 2]
        for c in range(3):
            out[m, c] = affine[m, c, 0] * x0 + affine[m, c, 1] * x1 + affine[m, c, 2] * x2 + affine[m, c, 3]
    return True


@njit(cache=True, inline="always")  # (numba IR in the step kernel: no call that reference-counts its records)
def sync_poses(drive, views, synth):
    """Microphones (``DRIVE_PARAMS.mic_mode``) and every moving sounding object to where they
    are now, before an event needs them."""
    prm = drive.prm[0]
    if prm.mic_mode:
        src = views.site_xpos if prm.mic_source == 1 else views.xpos
        follow_rows(src, drive.mic_rows, drive.mic_offsets, drive.mic_affine, synth.mics)
    if drive.dyn_obj.shape[0]:
        pose_rows(views.geom_xpos, views.geom_xmat, drive.dyn_geoms, drive.dyn_obj, synth.pos, synth.R)


@njit_inner(cache=True)
def impact_sides(drive, impacts, k):
    """Every sounding side of the impacts ``impacts[:k]``: ``(obj, P, J, tau, budget, mass, n)``,
    per side the synthesizer object index, world point [m], impulse on that side [N s], Hertz
    pulse length [s] (struck geom ``g``, other geom ``o``: ``hertz_coef(effective(m_g, M_o),
    effective(R_g, R_o), c_g + C_o)``, the struck fields and the other's of ``drive.sound``),
    the most vibration energy the impact can give it, the energy the collision takes from the
    approach, ``|J| v (1 - e) / 2`` [J] (``v`` the approach speed, ``e`` the restitution of the
    impulse ``J = m* (1 + e) v``; ``inf`` without a speed), and the collision's effective mass
    ``m* = |J| / ((1 + e) v)`` [kg] that the modes are coupled to (0 without a speed; see
    :func:`mjsound.synth.kernels.impacts_to_queue`)."""
    sound = drive.sound
    obj = np.empty(2 * k, np.int64)
    P = np.empty((2 * k, 3))
    J = np.empty((2 * k, 3))
    tau = np.empty(2 * k)
    budget = np.empty(2 * k)
    mass = np.empty(2 * k)
    n = 0
    for r in range(k):
        im = impacts[r]
        g1, g2 = im.g1, im.g2
        for side in range(2):
            g = g2 if side == 0 else g1
            other = g1 if side == 0 else g2
            s = sound[g]
            if s.obj < 0:
                continue
            o = sound[other]
            c = hertz_coef(effective(s.mass, o.other_mass), effective(s.radius, o.other_radius),
                           s.compliance + o.other_compliance)
            a = (1.0 if side == 0 else -1.0) * im.impulse
            obj[n] = s.obj
            for q in range(3):
                P[n, q] = im.point[q]
                J[n, q] = a * im.normal[q]
            tau[n] = _with_shells(contact_time(c, im.speed), s, o, im.speed)
            budget[n] = lost_energy(im.impulse, im.speed, im.restitution)
            mass[n] = collision_mass(im.impulse, im.speed, im.restitution)
            n += 1
    return obj[:n], P[:n], J[:n], tau[:n], budget[:n], mass[:n], n


@njit_inner(cache=True)
def _with_shells(tau, s, o, speed):
    """The contact time ``tau`` [s] (Hertz's) of the struck side ``s`` and the other ``o``
    (``drive.sound`` rows), or, when either is a thin hollow shell (``s.shell``,
    ``o.other_shell`` > 0: its wall's point-load compliance [m/N],
    :func:`mjsound.sim.clicks.shell_compliances`; the struck side's only when its modes are a
    hollow wall's) and that is
    longer, the mass on the walls' springs, ``pi sqrt(m* (s1 + s2))``, at most ``pi R / v``
    (``R`` the smaller shell's radius): the clicks' contact time
    (:func:`.click_kernels.pair_contact_time`), so the modes and the click of one impact
    share one pulse. Exactly ``tau`` when neither is a shell."""
    if not (s.shell > 0 or o.other_shell > 0):
        return tau
    shell = shell_contact_time(effective(s.mass, o.other_mass), s.shell, o.other_shell)
    r = math.inf
    if s.shell > 0 and s.radius < r:
        r = s.radius
    if o.other_shell > 0 and o.other_radius < r:
        r = o.other_radius
    if speed > 0 and not math.isinf(r):
        shell = min(shell, math.pi * r / speed)
    return shell if shell > tau else tau


@njit_inner(cache=True, inline="always")  # (numba IR: no call that reference-counts every array of its records)
def queue_impacts(drive, synth, buf, k, t_ev):
    """The substep's impacts ``buf.impacts[:k]`` into the synthesizer's queue at synth time
    ``t_ev`` [s] (:func:`mjsound.synth.kernels.impacts_to_queue`). Returns 0, or 1 when an
    amplitude is out of range (nothing queued)."""
    obj, P, J, tau, budget, mass, n = impact_sides(drive, buf.impacts, k)
    t = np.full(n, t_ev)
    count, used, nxt, amax = impacts_to_queue(synth, obj, P, J, t, tau, budget, mass)
    if not amax <= MAX_AMPLITUDE:  # (also NaN)
        return 1
    commit_queued(synth.queue, count, used, nxt)
    return 0


@njit_inner(cache=True)
def missing_streams(drive, synth, buf, ns, k1):
    """Before driving the sustained rows ``buf.sustained[:ns]`` up to synth sample ``k1``: the
    (row, side) pairs that sound but have no stream yet go to ``buf.missing``; returns
    ``(n_missing, need)``, ``need`` the ring length a stream needs first (0: enough)."""
    rows, sidx, sound = buf.sustained, drive.sidx, drive.sound
    cap = synth.streams.ring.shape[1]
    nm = 0
    for r in range(ns):
        row = rows[r]
        if row.kind == 0 or not (np.isfinite(row.force) and np.isfinite(row.speed)):
            continue
        for side in range(2):
            g = row.g2 if side == 0 else row.g1
            if sound[g].obj < 0:
                continue
            s = sidx[row.slot, side] if row.slot < sidx.shape[0] else -1
            if s < 0:
                buf.missing[nm].a = r
                buf.missing[nm].b = side
                nm += 1
            elif nm == 0:
                need = ring_need(synth.streams, synth.consts, s, k1)
                if need > cap:
                    return 0, need
    return nm, 0


@njit_inner(cache=True, inline="always")  # (numba IR: no call that reference-counts every array of its records)
def drive_sustained(drive, synth, buf, ns, k0, k1):
    """Drive the stream of every sounding side of the sustained rows ``buf.sustained[:ns]`` on
    synth samples ``[k0, k1)`` (:func:`missing_streams` found none missing and the rings long
    enough): force amplitude ``roughness |F| |v|``, low-pass ``alpha = 1 - e^{-2 pi f_c / fs}``
    with ``f_c = min(|v| / length, 0.45 fs)``."""
    prm = drive.prm[0]
    rows, sidx, sound = buf.sustained, drive.sidx, drive.sound
    fs = synth.consts[0].fs
    p = np.empty(3)
    nrm = np.empty(3)
    for r in range(ns):
        row = rows[r]
        kind = row.kind
        if kind == 0:
            continue
        fn = row.force
        spd = row.speed
        if not (np.isfinite(fn) and np.isfinite(spd)):
            continue  # (points and normals are sanitised by the reader)
        rough = prm.rough_slide if kind == 1 else prm.rough_roll
        length = prm.len_slide if kind == 1 else prm.len_roll
        amp = rough * abs(fn) * abs(spd)
        fc = min(abs(spd) / length, 0.45 * fs)
        alpha = 1.0 - np.exp(-2.0 * np.pi * fc / fs)
        for side in range(2):
            g = row.g2 if side == 0 else row.g1
            if sound[g].obj < 0:
                continue
            sign = 1.0 if side == 0 else -1.0
            for c in range(3):
                p[c] = row.point[c]
                nrm[c] = sign * row.normal[c]
            stream_drive(synth.streams, synth.consts, sidx[row.slot, side], k0, k1, amp, alpha, p, nrm, prm.regain)
