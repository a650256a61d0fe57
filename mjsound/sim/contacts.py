"""`ContactReader`: MuJoCo contacts of one step -> sound events (impact, slide, roll).

What a step's data means
------------------------
``mj_step`` runs ``mj_forward`` at the state ``(q_k, v_k)`` of time ``t_k`` (collision
detection, body velocities ``cvel``, constraint forces) and then integrates to ``t_{k+1}``.
So right after ``mj_step`` the contacts, ``geom_xpos``, ``cvel`` and the contact forces all
belong to ``t_k`` and the forces act over ``[t_k, t_{k+1})``, while ``qpos``/``qvel`` are
already those of ``t_{k+1}``. The reader uses the ``t_k`` quantities only, so the
velocity at a new contact is the *pre-contact* approach velocity.

Impacts (design)
----------------
MuJoCo's soft contacts spread one impact over several physics steps; feeding the per-step
``F dt`` to the modes would be a comb filter at the physics rate. The reader therefore emits
**one** impact per event, at contact onset, timed at ``t_k`` (the first state that has the
contact: the audio for ``[t_k, t_{k+1})`` is not rendered yet, so the timing is exact to the
physics' own resolution and nothing has to be delayed). Its impulse is predicted from the
pre-contact velocities:

* the approach speeds ``v_c = -(v_rel . n)`` at the new contact points,
* the contact-space inverse inertia ``A = J M^-1 J^T`` of those points along their normals
  (the point Jacobians as ``mj_jac`` computes them, in numba, and one ``mj_solveM`` for all
  of a step's impacts: the true effective mass including rotation and articulation; for a
  ball on the ground ``A = 1/m``),
* the restitution ``e`` of the two acoustic materials (``sqrt(e1 e2)``, or the one known),

``lambda = A^+ (1 + e) v`` (clipped to >= 0), one impulse per new contact point of the pair.
While the event lasts (until the pair separates, comes to rest, or 0.1 s) MuJoCo's normal
impulse ``sum F_n dt`` is accumulated (in the per-pair state, read into the records when
:attr:`ContactReader.impacts` is read) and stored next to the prediction in an
:class:`ImpactRecord` per event, which is the check the tests use. A new impact starts at a pair's onset with an approach speed above ``v_impact``
(default 0.05 m/s: a 0.13 mm fall; slower touches, solver jitter and a resting or sliding
body's contact flicker are silent) or, while a pair stays in contact, when its approach speed
jumps by more than ``2 v_impact`` to more than twice that of the step before (a box slapping
down on its other edge). A pair makes at most one impact per ``refractory_s`` (default
10 ms): re-contacts within it (a rocking bar's micro-bounces, contacts flickering at the
margin) merge into the impact already emitted. The audible impulse follows the acoustic
material's restitution, not MuJoCo's (which is set by ``solref``/``solimp``; the defaults are
nearly plastic); give the contacts a matching ``solref`` when the two must agree.

Sustained contact
-----------------
While a pair stays in contact with a positive normal force, per step and per pair:
*slide* when the tangential slip speed ``|v_t|`` exceeds ``v_slide`` and 0.3 x the rolling
speed, *roll* when the rolling speed ``|omega_rel,t| r`` exceeds ``v_roll``, otherwise silence
(resting contact). Forces are summed over the pair's contacts, the point is their force-
weighted centroid. Both bodies sound, each driven at the (shared) contact point, with
opposite impulses. (The driver keeps one noise stream per pair and side across slide and
roll steps: :mod:`.drive`.)

Bad input
---------
NaN/Inf or huge (> ``max_force`` N) contact forces and NaN velocities are clamped (to 0 or
``max_force``) and reported once with :func:`warnings.warn`.
"""

from __future__ import annotations

import warnings
from collections import deque
from dataclasses import dataclass

import numpy as np

__all__ = ["ContactReader", "ContactFrame", "ImpactEvent", "ContactEvent", "ImpactRecord"]

try:  # numba keeps the per-step contact work in the microseconds
    from numba import njit as _njit
except ImportError:  # pragma: no cover
    def _njit(*a, **k):
        return (lambda f: f) if not a or not callable(a[0]) else a[0]


@_njit(cache=True, nogil=True)
def _contact_kernel(geom, pos, frame, adr, dim, efc, pyramidal, cvel, scom, gxpos, gbody, broot, plane, fmax):
    """Per-contact normal force, relative velocity, approach / slip / rolling speed (world)."""
    n = geom.shape[0]
    fn = np.zeros(n)
    nrm = np.empty((n, 3))
    vrel = np.empty((n, 3))
    vapp = np.empty(n)
    vslip = np.empty(n)
    vroll = np.empty(n)
    nbad = 0
    nhuge = 0
    v = np.zeros((2, 3))  # per contact side: point velocity and angular velocity (reused)
    w = np.zeros((2, 3))
    wr = np.empty(3)
    for i in range(n):
        a = adr[i]
        f = 0.0
        if a >= 0:
            if pyramidal and dim[i] > 1:
                for j in range(2 * (dim[i] - 1)):
                    f += efc[a + j]
            else:
                f = efc[a]
        if not np.isfinite(f):
            f = 0.0
            nbad += 1
        elif f > fmax:
            f = fmax
            nhuge += 1
        elif f < -fmax:
            f = -fmax
            nhuge += 1
        ok = True
        for c in range(3):
            nrm[i, c] = frame[i, c]
            if not (np.isfinite(frame[i, c]) and np.isfinite(pos[i, c])):
                ok = False
        for s in range(2):
            b = gbody[geom[i, s]]
            rb = broot[b]
            rx = pos[i, 0] - scom[rb, 0]
            ry = pos[i, 1] - scom[rb, 1]
            rz = pos[i, 2] - scom[rb, 2]
            wx, wy, wz = cvel[b, 0], cvel[b, 1], cvel[b, 2]
            w[s, 0], w[s, 1], w[s, 2] = wx, wy, wz
            v[s, 0] = cvel[b, 3] + wy * rz - wz * ry
            v[s, 1] = cvel[b, 4] + wz * rx - wx * rz
            v[s, 2] = cvel[b, 5] + wx * ry - wy * rx
        for c in range(3):
            vrel[i, c] = v[1, c] - v[0, c]
            if not np.isfinite(vrel[i, c]) or not np.isfinite(w[1, c] - w[0, c]):
                ok = False
        if not ok:
            nbad += 1
            f = 0.0
            for c in range(3):
                vrel[i, c] = 0.0
                w[0, c] = 0.0
                w[1, c] = 0.0
            nrm[i, 0], nrm[i, 1], nrm[i, 2] = 0.0, 0.0, 1.0
            for c in range(3):
                if not np.isfinite(pos[i, c]):
                    pos[i, c] = 0.0
        fn[i] = f
        vn = vrel[i, 0] * nrm[i, 0] + vrel[i, 1] * nrm[i, 1] + vrel[i, 2] * nrm[i, 2]
        vapp[i] = -vn
        st = 0.0
        for c in range(3):
            t = vrel[i, c] - vn * nrm[i, c]
            st += t * t
        vslip[i] = np.sqrt(st)
        for c in range(3):
            wr[c] = w[1, c] - w[0, c]
        wn = wr[0] * nrm[i, 0] + wr[1] * nrm[i, 1] + wr[2] * nrm[i, 2]
        wt = 0.0
        for c in range(3):
            t = wr[c] - wn * nrm[i, c]
            wt += t * t
        rad = np.inf
        for s in range(2):
            g = geom[i, s]
            if not plane[g]:
                dx = pos[i, 0] - gxpos[g, 0]
                dy = pos[i, 1] - gxpos[g, 1]
                dz = pos[i, 2] - gxpos[g, 2]
                r = np.sqrt(dx * dx + dy * dy + dz * dz)
                if r < rad:
                    rad = r
        if not np.isfinite(rad):
            rad = 0.0
        vroll[i] = np.sqrt(wt) * rad
    return fn, nrm, vrel, vapp, vslip, vroll, nbad, nhuge


@_njit(cache=True, nogil=True)
def _pair_kernel(geom, ngeom, fn, vapp, vslip, vroll, pos, nrm):
    """Group contacts by geom pair: per pair its contacts, largest approach speed, total normal
    force and the force-weighted slip speed, rolling speed, point and normal."""
    n = geom.shape[0]
    keys = np.empty(n, np.int64)
    for i in range(n):
        a, b = geom[i, 0], geom[i, 1]
        keys[i] = min(a, b) * ngeom + max(a, b)
    order = np.argsort(keys, kind="mergesort")
    starts = np.empty(n + 1, np.int64)
    P = 0
    for j in range(n):
        if j == 0 or keys[order[j]] != keys[order[j - 1]]:
            starts[P] = j
            P += 1
    starts[P] = n
    pkey = np.empty(P, np.int64)
    vmax = np.empty(P)
    ftot = np.zeros(P)
    slip = np.zeros(P)
    roll = np.zeros(P)
    point = np.zeros((P, 3))
    normal = np.zeros((P, 3))
    for p in range(P):
        i0 = order[starts[p]]
        pkey[p] = keys[i0]
        vm = -np.inf
        fp = 0.0
        for j in range(starts[p], starts[p + 1]):
            i = order[j]
            if vapp[i] > vm:
                vm = vapp[i]
            f = fn[i]
            if f > 0:
                fp += f
                slip[p] += f * vslip[i]
                roll[p] += f * vroll[i]
                for c in range(3):
                    point[p, c] += f * pos[i, c]
                    normal[p, c] += f * nrm[i, c]
        vmax[p] = vm
        ftot[p] = fp
        if fp > 0:
            slip[p] /= fp
            roll[p] /= fp
            nn = 0.0
            for c in range(3):
                point[p, c] /= fp
                nn += normal[p, c] ** 2
            nn = np.sqrt(nn)
            for c in range(3):
                normal[p, c] = normal[p, c] / nn if nn > 0 else nrm[i0, c]
    return order, starts[: P + 1], pkey, vmax, ftot, slip, roll, point, normal


@_njit(cache=True, nogil=True)
def _slot_of(hkeys, hvals, key, nslots):
    """Slot of pair ``key`` in the open-addressing table ``hkeys``/``hvals`` (power-of-two size,
    -1 = empty; the caller keeps it at most half full), inserted as slot ``nslots`` when new.
    Returns ``(slot, is_new)``. (A plain array table: numba's typed Dict costs seconds of
    compilation per process and microseconds per call to pass in.)"""
    mask = hkeys.shape[0] - 1
    h = (key * 2654435761) & mask
    while True:
        k = hkeys[h]
        if k == key:
            return hvals[h], False
        if k < 0:
            hkeys[h] = key
            hvals[h] = nslots
            return nslots, True
        h = (h + 1) & mask


@_njit(cache=True, nogil=True)
def _rehash(keys, vals, size):
    """A new table of ``size`` entries holding the (key, slot) pairs of ``keys``/``vals``."""
    hk = np.full(size, -1, np.int64)
    hv = np.zeros(size, np.int64)
    mask = size - 1
    for i in range(keys.shape[0]):
        key = keys[i]
        if key < 0:
            continue
        h = (key * 2654435761) & mask
        while hk[h] >= 0:
            h = (h + 1) & mask
        hk[h] = key
        hv[h] = vals[i]
    return hk, hv


#: Rows of the packed per-slot state: float rows ``SF`` and integer rows ``SI``.
SF_VPREV, SF_TOUCH, SF_HIT, SF_RTIME, SF_RSPEED, SF_RIMP, SF_REND, SF_PRIMP, SF_PREND = range(9)
SI_LAST, SI_CALM, SI_OPEN, SI_RSTEPS, SI_PRSTEPS = range(5)
SF_ROWS, SI_ROWS = 9, 5
# (R: the open impact record's sum F dt, end time and steps; P..: the same of the slot's
# previous record, banked at an onset so that Python can close that record afterwards)
#: Thresholds passed to the kernels as one array (``ContactReader._params``).
P_V_IMPACT, P_V_HARD, P_MIN_APART, P_REFRACTORY, P_MAX_EVENT, P_V_SLIDE, P_V_ROLL, P_FMAX = range(8)


@_njit(cache=True, nogil=True)
def _state_kernel(pkey, vmax, ftot, slip, roll, hkeys, hvals, SF, SI, nslots, t0, t1, dt, step, prm):
    """Per-pair state machine of :meth:`ContactReader.events` (the rules are in the module
    docstring). ``SF`` (6, cap) / ``SI`` (4, cap) hold each slot's state (rows ``SF_*``,
    ``SI_*``), ``prm`` the thresholds (``P_*``). Returns per pair: slot, onset (an impact
    starts: Python computes its impulse), sustained kind (0 none, 1 slide, 2 roll) and speed,
    and the new number of slots. Pairs seen before but not in this step close their open
    impact record."""
    v_impact, v_hard, min_apart, refractory = prm[P_V_IMPACT], prm[P_V_HARD], prm[P_MIN_APART], prm[P_REFRACTORY]
    max_event, v_slide, v_roll = prm[P_MAX_EVENT], prm[P_V_SLIDE], prm[P_V_ROLL]
    P = pkey.shape[0]
    slot = np.empty(P, np.int64)
    onset_out = np.zeros(P, np.bool_)
    kind = np.zeros(P, np.int64)
    speed = np.zeros(P)
    for p in range(P):
        j, new = _slot_of(hkeys, hvals, pkey[p], nslots)
        if new:
            nslots += 1
            SF[SF_VPREV, j] = 0.0
            SI[SI_LAST, j] = -10
            SF[SF_TOUCH, j] = -np.inf
            SF[SF_HIT, j] = -np.inf
            SI[SI_CALM, j] = 0
            SI[SI_OPEN, j] = 0
        slot[p] = j
        vm = vmax[p]
        if vm > v_impact:
            vp = max(SF[SF_VPREV, j], 0.0)
            if SI[SI_LAST, j] != step - 1:
                onset = vm >= v_hard or t0 - SF[SF_TOUCH, j] >= min_apart
            else:
                onset = vm > 2.0 * vp and vm - vp > 2.0 * v_impact
            if onset and t0 - SF[SF_HIT, j] >= refractory - 1e-12:
                onset_out[p] = True
                SF[SF_PRIMP, j] = SF[SF_RIMP, j]
                SF[SF_PREND, j] = SF[SF_REND, j]
                SI[SI_PRSTEPS, j] = SI[SI_RSTEPS, j]
                SI[SI_OPEN, j] = 1
                SF[SF_RTIME, j] = t0
                SF[SF_RSPEED, j] = vm
                SF[SF_RIMP, j] = 0.0
                SI[SI_RSTEPS, j] = 0
                SI[SI_CALM, j] = 0
                SF[SF_HIT, j] = t0
        if SI[SI_OPEN, j]:
            SF[SF_RIMP, j] += ftot[p] * dt
            SI[SI_RSTEPS, j] += 1
            SF[SF_REND, j] = t1
            tol = max(0.02 * SF[SF_RSPEED, j], 1e-3)
            SI[SI_CALM, j] = SI[SI_CALM, j] + 1 if abs(vm) < tol else 0
            if SI[SI_CALM, j] >= 2 or t1 - SF[SF_RTIME, j] >= max_event:
                SI[SI_OPEN, j] = 0
        SF[SF_VPREV, j] = vm
        SI[SI_LAST, j] = step
        SF[SF_TOUCH, j] = t0
        if ftot[p] > 0.0:
            if slip[p] > v_slide and slip[p] > 0.3 * roll[p]:
                kind[p] = 1
                speed[p] = slip[p]
            elif roll[p] > v_roll:
                kind[p] = 2
                speed[p] = roll[p]
    for j in range(nslots):
        if SI[SI_OPEN, j] and SI[SI_LAST, j] != step:
            SI[SI_OPEN, j] = 0
    return slot, onset_out, kind, speed, nslots


#: Columns of the rows :func:`_fused_kernel` returns, one row per touching geom pair.
R_G1, R_G2, R_KIND, R_FORCE, R_SPEED, R_POINT, R_NORMAL, R_ONSET, R_SLOT = 0, 1, 2, 3, 4, 5, 8, 11, 12
R_COLS = 13
#: Columns of the impact contacts :func:`_fused_kernel` returns (``hits``).
H_ROW, H_G1, H_G2, H_POINT, H_NORMAL, H_SPEED = 0, 1, 2, 3, 6, 9
H_COLS = 10


@_njit(cache=True, nogil=True)
def _fused_kernel(geom, pos, frame, adr, dim, efc, pyramidal, cvel, scom, gxpos, gbody, broot, plane, ngeom,
                  hkeys, hvals, SF, SI, nslots, t0, t1, step, prm, counts, rows, sustained, hits, onsets):
    """:func:`_contact_kernel`, :func:`_pair_kernel` and :func:`_state_kernel` in one call (the
    per-step hot path); ``counts`` (2,) adds the step's sliding and rolling pairs.

    Writes into the caller's buffers (at least as many rows as contacts; reused every step, so
    that no array is allocated for Python): ``rows`` (pairs, ``R_COLS``) and ``sustained`` (the
    rows of kind > 0): geom1, geom2, kind (0 none, 1 slide, 2 roll), total normal force, speed,
    point (3), normal (3), onset (1: an impact starts), slot (the pair's state slot); ``hits``
    (``H_COLS``) the impacting contacts of onset pairs, grouped by row; ``onsets`` (int64,
    rows + 1 by 2) each onset pair's slot and first hit (its hits run to the next one's first;
    row ``n_onset`` holds ``n_hits``). Returns
    ``(pairs, n_sustained, n_hits, nbad, nhuge, n_onset, nslots)``. ``pos`` is not modified."""
    pos = pos.copy()  # (the contact kernel sanitises non-finite points in place)
    fn, nrm, vrel, vapp, vslip, vroll, nbad, nhuge = _contact_kernel(
        geom, pos, frame, adr, dim, efc, pyramidal, cvel, scom, gxpos, gbody, broot, plane, prm[P_FMAX])
    order, starts, pkey, vmax, ftot, slip, roll, point, normal = _pair_kernel(
        geom, ngeom, fn, vapp, vslip, vroll, pos, nrm)
    slot, onset, kind, speed, nslots = _state_kernel(
        pkey, vmax, ftot, slip, roll, hkeys, hvals, SF, SI, nslots, t0, t1, t1 - t0, step, prm)
    P = pkey.shape[0]
    for p in range(P):
        i0 = order[starts[p]]
        rows[p, R_G1] = geom[i0, 0]
        rows[p, R_G2] = geom[i0, 1]
        rows[p, R_KIND] = kind[p]
        rows[p, R_FORCE] = ftot[p]
        rows[p, R_SPEED] = speed[p]
        for c in range(3):
            rows[p, R_POINT + c] = point[p, c]
            rows[p, R_NORMAL + c] = normal[p, c]
        rows[p, R_ONSET] = 1.0 if onset[p] else 0.0
        rows[p, R_SLOT] = slot[p]
    n_onset = 0
    n_sust = 0
    for p in range(P):
        if onset[p]:
            n_onset += 1
        if kind[p] > 0:
            n_sust += 1
            counts[kind[p] - 1] += 1
    q = 0
    for p in range(P):
        if kind[p] > 0:
            sustained[q] = rows[p]
            q += 1
    # the contacts of onset pairs that approach faster than v_impact: (row, geom1, geom2,
    # point (3), normal (3), approach speed), grouped by row
    nh = 0
    if n_onset:
        for p in range(P):
            if onset[p]:
                for j in range(starts[p], starts[p + 1]):
                    if vapp[order[j]] > prm[P_V_IMPACT]:
                        nh += 1
    h = 0
    q = 0
    if nh:
        for p in range(P):
            if onset[p]:
                onsets[q, 0] = slot[p]
                onsets[q, 1] = h
                q += 1
                for j in range(starts[p], starts[p + 1]):
                    i = order[j]
                    if vapp[i] > prm[P_V_IMPACT]:
                        hits[h, H_ROW] = p
                        hits[h, H_G1] = geom[i, 0]
                        hits[h, H_G2] = geom[i, 1]
                        for c in range(3):
                            hits[h, H_POINT + c] = pos[i, c]
                            hits[h, H_NORMAL + c] = nrm[i, c]
                        hits[h, H_SPEED] = vapp[i]
                        h += 1
    onsets[q, 1] = h
    return P, n_sust, nh, nbad, nhuge, n_onset, nslots


#: Columns of the impact array :meth:`ContactReader.events_fast` returns, one row per
#: impacting contact: geom1, geom2, point (3), normal (3), impulse on geom2 along the normal
#: [N s], approach speed [m/s].
I_G1, I_G2, I_POINT, I_NORMAL, I_IMPULSE, I_SPEED = 0, 1, 2, 5, 8, 9
I_COLS = 10


@_njit(cache=True, nogil=True)
def _normal_jacobians(hits, cdof, scom, gbody, body_dofnum, body_dofadr, body_parentid, body_rootid,
                      dof_parentid, nv):
    """``Jn[r] = n_r . (J_geom2(p_r) - J_geom1(p_r))`` (k, nv) for the impacting contacts
    ``hits`` (columns ``H_*``: geoms, world point ``p_r`` and normal ``n_r``; the world body
    adds nothing).

    The point Jacobian of body ``b`` is MuJoCo's ``mj_jac`` (its C code, here in numba so
    that no Python call per contact side is needed): from the first body with dofs up the
    tree, each dof ``i`` on the ancestor chain (``dof_parentid``) contributes the column
    ``J[:, i] = cdof_lin_i + cdof_ang_i x (p - subtree_com[root(b)])`` (``cdof`` rows are
    (angular, linear) motion axes).
    """
    k = hits.shape[0]
    Jn = np.zeros((k, nv))
    for r in range(k):
        nx, ny, nz = hits[r, H_NORMAL], hits[r, H_NORMAL + 1], hits[r, H_NORMAL + 2]
        for side in range(2):
            b0 = gbody[int(hits[r, H_G1 + side])]
            b = b0
            while b > 0 and body_dofnum[b] == 0:
                b = body_parentid[b]
            if b == 0:
                continue
            root = body_rootid[b0]
            ox = hits[r, H_POINT] - scom[root, 0]
            oy = hits[r, H_POINT + 1] - scom[root, 1]
            oz = hits[r, H_POINT + 2] - scom[root, 2]
            sign = 1.0 if side == 1 else -1.0
            i = body_dofadr[b] + body_dofnum[b] - 1
            while i >= 0:
                jx = cdof[i, 3] + (cdof[i, 1] * oz - cdof[i, 2] * oy)
                jy = cdof[i, 4] + (cdof[i, 2] * ox - cdof[i, 0] * oz)
                jz = cdof[i, 5] + (cdof[i, 0] * oy - cdof[i, 1] * ox)
                Jn[r, i] += sign * (nx * jx + ny * jy + nz * jz)
                i = dof_parentid[i]
    return Jn


@_njit(cache=True, nogil=True)
def _restitution_of(e_geom, g1, g2):
    """Acoustic restitution of a geom pair: ``sqrt(e1 e2)``, the one known (NaN: unknown), or 0.5."""
    e1, e2 = e_geom[g1], e_geom[g2]
    if e1 == e1 and e2 == e2:
        return np.sqrt(e1 * e2)
    if e1 == e1:
        return e1
    if e2 == e2:
        return e2
    return 0.5


#: columns of an impact event's record row (:func:`_record_rows`)
REC_COLS = 11


@_njit(cache=True, nogil=True)
def _record_rows(hits, starts, slots, stats, t0, SF, SI, out):
    """Record rows of a step's impact events (``stats`` of :func:`_impulses_grouped`, event
    ``q`` on pair slot ``slots[q]``) into ``out`` (events, ``REC_COLS``): time, geom1, geom2,
    largest approach speed, predicted impulse, restitution, slot, clamped (0/1), then what the
    state kernel banked at this onset for the slot's previous record (sum F dt, steps, end
    time), which closes it (:meth:`ContactReader.add_records`)."""
    for q in range(stats.shape[0]):
        a, j = starts[q], slots[q]
        out[q, 0] = t0
        out[q, 1] = hits[a, H_G1]
        out[q, 2] = hits[a, H_G2]
        out[q, 3] = stats[q, 1]
        out[q, 4] = stats[q, 2]
        out[q, 5] = stats[q, 0]
        out[q, 6] = j
        out[q, 7] = stats[q, 3]
        out[q, 8] = SF[SF_PRIMP, j]
        out[q, 9] = SI[SI_PRSTEPS, j]
        out[q, 10] = SF[SF_PREND, j]


@_njit(cache=True, nogil=True)
def _impulses_grouped(hits, Jn, MinvJt, starts, e_geom, tree_mass, root_mass, gbody, jmax):
    """:func:`_impulse_kernel` for every impact event of a step at once: contacts (rows of
    ``hits``) ``starts[q] : starts[q + 1]`` are event ``q`` (one geom pair).

    Returns ``lambda (k,)``, per event its restitution, largest approach speed, total impulse
    and whether an impulse was clamped (``stats`` (events, 4)), and the impacts with
    ``lambda > 0`` as rows of columns ``I_*``.
    """
    Q = starts.shape[0] - 1
    k = hits.shape[0]
    lam = np.zeros(k)
    stats = np.zeros((Q, 4))
    for q in range(Q):
        a, b = starts[q], starts[q + 1]
        g1, g2 = int(hits[a, H_G1]), int(hits[a, H_G2])
        b1, b2 = gbody[g1], gbody[g2]
        e = _restitution_of(e_geom, g1, g2)
        v = hits[a:b, H_SPEED].copy()
        lq, cl = _impulse_kernel(Jn[a:b], MinvJt[a:b], v, e, tree_mass[b1], tree_mass[b2],
                                 min(root_mass[b1], root_mass[b2]), jmax)
        lam[a:b] = lq
        stats[q, 0] = e
        stats[q, 1] = v.max()
        stats[q, 2] = lq.sum()
        stats[q, 3] = 1.0 if cl else 0.0
    n = 0
    for r in range(k):
        if lam[r] > 0:
            n += 1
    imp = np.empty((n, I_COLS))
    n = 0
    for r in range(k):
        if lam[r] > 0:
            imp[n, I_G1] = hits[r, H_G1]
            imp[n, I_G2] = hits[r, H_G2]
            for c in range(3):
                imp[n, I_POINT + c] = hits[r, H_POINT + c]
                imp[n, I_NORMAL + c] = hits[r, H_NORMAL + c]
            imp[n, I_IMPULSE] = lam[r]
            imp[n, I_SPEED] = hits[r, H_SPEED]
            n += 1
    return lam, stats, imp


@_njit(cache=True, nogil=True)
def _impulse_kernel(Jn, MinvJt, v, e, m1, m2, cap_mass, jmax):
    """Per-contact normal impulses ``lambda = A^+ (1 + e) v`` with ``A = Jn M^-1 Jn^T``
    (contact-space inverse inertia), or the body-mass fallback when ``A`` is degenerate; the
    total is capped at ``(1 + e) max(v) cap_mass`` and each at ``jmax``. Returns
    ``(lambda, clamped)``."""
    k = v.shape[0]
    nv = Jn.shape[1]
    lam = np.zeros(k)
    ok = False
    if nv > 0:
        A = np.zeros((k, k))
        finite = True
        amax = 0.0
        for a in range(k):
            for b in range(k):
                acc = 0.0
                for j in range(nv):
                    acc += Jn[a, j] * MinvJt[b, j]
                A[a, b] = acc
        for a in range(k):
            for b in range(k):
                x = 0.5 * (A[a, b] + A[b, a])
                if not np.isfinite(x):
                    finite = False
                elif abs(x) > amax:
                    amax = abs(x)
        if finite and amax > 0:
            if k == 1:
                if A[0, 0] > 0:
                    lam[0] = (1.0 + e) * v[0] / A[0, 0]
                    ok = True
            else:
                S = 0.5 * (A + A.T)
                # rcond: near-duplicate contacts make A nearly singular; do not amplify noise
                Ap = np.linalg.pinv(S, 1e-4)
                for a in range(k):
                    acc = 0.0
                    for b in range(k):
                        acc += Ap[a, b] * (1.0 + e) * v[b]
                    lam[a] = acc if acc > 0.0 else 0.0
                ok = True
        for a in range(k):
            if not np.isfinite(lam[a]):
                ok = False
    if not ok:
        # no dofs (both static) or a degenerate system: unit-free fallback with body masses
        inv = 0.0
        if np.isfinite(m1) and m1 > 0:
            inv += 1.0 / m1
        if np.isfinite(m2) and m2 > 0:
            inv += 1.0 / m2
        mstar = 1.0 / inv if inv > 0 else 0.0
        for a in range(k):
            lam[a] = (1.0 + e) * v[a] * mstar / k
    # the effective mass never exceeds the lighter moving tree: cap the total impulse
    vmax = 0.0
    tot = 0.0
    for a in range(k):
        vmax = max(vmax, v[a])
        tot += lam[a]
    if np.isfinite(cap_mass):
        cap = (1.0 + e) * vmax * cap_mass
        if tot > cap > 0:
            for a in range(k):
                lam[a] *= cap / tot
    clamped = False
    for a in range(k):
        if lam[a] > jmax:
            lam[a] = jmax
            clamped = True
    return lam, clamped


@dataclass
class ContactFrame:
    """All contacts of one step, as arrays over the ``n`` contacts (world frame, SI).

    Attributes
    ----------
    geom : (n, 2) int
        ``geom[:, 0]``, ``geom[:, 1]``; the normal points from the first to the second.
    pos : (n, 3) contact point [m].
    normal : (n, 3) unit normal.
    dist : (n,) signed distance [m] (negative: penetration).
    force_n : (n,) normal force on geom 1 along ``normal`` [N] (clamped, finite).
    force : (n, 3) world force on geom 1 [N] (geom 0 gets the opposite).
    vel_rel : (n, 3) velocity of geom 1's material point minus geom 0's at ``pos`` [m/s].
    v_approach : (n,) ``-(vel_rel . normal)``; positive when closing [m/s].
    v_slip : (n,) tangential slip speed [m/s].
    v_roll : (n,) rolling speed ``|omega_rel,t| r`` [m/s].
    local : (n, 2, 3) contact point in each geom's frame [m] (computed on demand).
    """

    geom: np.ndarray
    pos: np.ndarray
    normal: np.ndarray
    dist: np.ndarray
    force_n: np.ndarray
    force: np.ndarray
    vel_rel: np.ndarray
    v_approach: np.ndarray
    v_slip: np.ndarray
    v_roll: np.ndarray
    local: np.ndarray | None = None

    @property
    def n(self) -> int:
        return len(self.geom)


@dataclass
class ImpactEvent:
    """One impact at one contact point.

    ``impulse`` [N s] acts on ``geom2`` along ``normal`` (``geom1`` gets ``-impulse``).
    """

    time: float
    geom1: int
    geom2: int
    point: np.ndarray
    normal: np.ndarray
    impulse: float
    speed: float
    effective_mass: float


@dataclass
class ContactEvent:
    """Sustained contact of a pair over ``[t0, t1)``: ``kind`` is ``"slide"`` or ``"roll"``."""

    kind: str
    t0: float
    t1: float
    geom1: int
    geom2: int
    point: np.ndarray
    normal: np.ndarray
    force_n: float
    speed: float


@dataclass
class ImpactRecord:
    """Predicted and simulated impulse of one impact event (diagnostics).

    Attributes
    ----------
    time : onset time [s].
    geom1, geom2 : geom ids.
    speed : largest pre-contact approach speed [m/s].
    impulse_pred : emitted ``sum lambda = sum A^+ (1+e) v`` [N s].
    impulse_sim : MuJoCo's ``sum F_n dt`` over the event [N s].
    restitution : ``e`` used.
    effective_mass : ``impulse_pred / ((1+e) speed)`` [kg].
    duration : event length [s]; ``steps`` physics steps.
    """

    time: float
    geom1: int
    geom2: int
    speed: float
    impulse_pred: float
    impulse_sim: float
    restitution: float
    effective_mass: float
    duration: float = 0.0
    steps: int = 0
    open: bool = True


class ContactReader:
    """Reads every contact after each ``mj_step`` and turns them into sound events.

    Parameters
    ----------
    model : mujoco.MjModel
    restitution : sequence of float | None, optional
        Per-geom acoustic restitution (NaN or None entries: unknown); default 0.5 where
        neither geom knows.
    v_impact : float
        Smallest approach speed that makes an impact [m/s].
    v_slide, v_roll : float
        Smallest slip / rolling speed that makes sliding / rolling sound [m/s].
    max_force : float
        Contact forces above this are clamped [N].
    max_event_s : float
        Longest an impact event is tracked for its ``sum F dt`` [s].
    keep_records : int
        How many :class:`ImpactRecord` to keep (oldest dropped).
    """

    def __init__(
        self,
        model,
        restitution=None,
        v_impact: float = 0.05,
        v_slide: float = 0.01,
        v_roll: float = 0.01,
        max_force: float = 1e6,
        max_event_s: float = 0.1,
        keep_records: int = 10000,
        refractory_s: float = 0.01,
        min_apart_s: float = 0.005,
        v_hard: float = 0.3,
    ):
        import mujoco

        self._mj = mujoco
        self.model = model
        self.v_impact = float(v_impact)
        self.v_slide = float(v_slide)
        self.v_roll = float(v_roll)
        self.max_force = float(max_force)
        self.max_event_s = float(max_event_s)
        self.keep_records = int(keep_records)
        self.refractory_s = float(refractory_s)
        self.min_apart_s = float(min_apart_s)
        self.v_hard = float(v_hard)
        ng = model.ngeom
        e = np.full(ng, np.nan)
        if restitution is not None:
            for g, r in enumerate(restitution):
                if r is not None and np.isfinite(r):
                    e[g] = float(r)
        self.restitution = e
        self._e_list = e.tolist()
        # moving mass of each body's subtree and of its whole tree (inf: welded to the world)
        welded = np.asarray(model.body_weldid) == 0
        self._tree_mass = np.where(welded, np.inf, np.asarray(model.body_subtreemass))
        self._root_mass = np.where(welded, np.inf, np.asarray(model.body_subtreemass)[np.asarray(model.body_rootid)])
        self.geom_body = np.asarray(model.geom_bodyid, dtype=np.int64)
        self.body_root = np.asarray(model.body_rootid, dtype=np.int64)
        T = mujoco.mjtGeom
        self._plane = np.asarray(model.geom_type) == T.mjGEOM_PLANE
        self._pyramidal = int(model.opt.cone) == int(mujoco.mjtCone.mjCONE_PYRAMIDAL)
        #: record rows of impacts made in numba (:mod:`.fused`), taken by :meth:`add_records`
        self.record_buffer = np.zeros((64, REC_COLS))
        self._kin = tuple(np.asarray(a, np.int64) for a in (model.body_dofnum, model.body_dofadr, model.body_parentid,
                                                            model.body_rootid, model.dof_parentid))  # for _normal_jacobians
        self._views_of = None  # MjData whose fixed-size views (cvel, subtree_com, geom_xpos) are cached
        self._warned = set()
        self._records: deque[ImpactRecord] = deque(maxlen=self.keep_records)
        self.reset()

    # ------------------------------------------------------------------ state
    def reset(self) -> None:
        """Forget all pairs (call after ``mj_resetData`` or a state jump)."""
        # per contact pair (slot): its state in two packed arrays for the numba state machine,
        # and an open-addressing table pair key -> slot
        self._nslots = 0
        self._SF = np.zeros((SF_ROWS, 0))
        self._SI = np.zeros((SI_ROWS, 0), np.int64)
        self._hkeys = np.full(0, -1, np.int64)
        self._hvals = np.zeros(0, np.int64)
        self._alloc_slots(64)
        # slot -> its ImpactRecord, open when last synced; records read their sum F dt, steps
        # and duration from the slot state only when read (:attr:`impacts`) or closed by the
        # slot's next onset (its values banked in SF_P* / SI_P* by the state kernel)
        self._open: dict[int, ImpactRecord] = {}
        self._any_open = False  # an impact may be open: quiet steps must close it
        self._step = 0
        self._records = deque(maxlen=self.keep_records)  # (the oldest drop out in O(1))
        self.n_impacts = 0
        self.n_clamped = 0
        self._prev_cvel = None
        self.drive_result = None
        #: sliding and rolling pair-steps seen by :meth:`events_fast` (counted in numba)
        self.sustained_steps = np.zeros(2, np.int64)
        # output buffers of the per-step kernel (grown to the largest contact count seen)
        self._buffers(8)
        self._params = np.array([self.v_impact, self.v_hard, self.min_apart_s, self.refractory_s,
                                 self.max_event_s, self.v_slide, self.v_roll, self.max_force])

    def _buffers(self, n: int) -> None:
        """Output buffers of the per-step kernel for up to ``n`` contacts."""
        self._rows_buf = np.empty((n, R_COLS))
        self._srows_buf = np.empty((n, R_COLS))
        self._hits_buf = np.empty((n, H_COLS))
        self._missing_buf = np.empty((2 * n, 2), np.int64)
        self._onset_buf = np.empty((n + 1, 2), np.int64)

    def _alloc_slots(self, cap):
        """Room for ``cap`` pair slots (state kept; the table stays at most half full)."""
        n = self._SF.shape[1]
        SF = np.zeros((SF_ROWS, cap))
        SI = np.zeros((SI_ROWS, cap), np.int64)
        SF[:, :n] = self._SF
        SI[:, :n] = self._SI
        self._SF, self._SI = SF, SI
        size = 1 << max(7, int(2 * cap - 1).bit_length())
        self._hkeys, self._hvals = _rehash(self._hkeys, self._hvals, size)

    def _room(self, n_new):
        if self._nslots + n_new > self._SF.shape[1]:
            self._alloc_slots(2 * (self._nslots + n_new))

    def _report_clamped(self, nbad, nhuge) -> None:
        self.n_clamped += int(nbad + nhuge)
        self._warn_once(
            "force",
            f"mjsound: {nbad} NaN/Inf and {nhuge} huge (> {self.max_force:g} N) contact forces or "
            "velocities clamped (exploding simulation?); reported once",
        )

    def _warn_once(self, key, msg):
        if key not in self._warned:
            self._warned.add(key)
            warnings.warn(msg, RuntimeWarning, stacklevel=4)

    # ------------------------------------------------------------------ reading
    def read(self, data) -> ContactFrame | None:
        """All contacts of the last step as a :class:`ContactFrame` (None when there are none)."""
        n = int(data.ncon)
        if n == 0:
            return None
        con = data.contact
        geom = np.array(con.geom, dtype=np.int64)
        pos = np.array(con.pos, dtype=np.float64)
        frame = con.frame
        dist = np.array(con.dist, dtype=np.float64)
        fn, normal, vel_rel, vapp, v_slip, v_roll, nbad, nhuge = _contact_kernel(
            geom, pos, np.ascontiguousarray(frame, dtype=np.float64), np.asarray(con.efc_address, dtype=np.int64),
            np.asarray(con.dim, dtype=np.int64), data.efc_force, self._pyramidal, data.cvel, data.subtree_com,
            data.geom_xpos, self.geom_body, self.body_root, self._plane, self.max_force,
        )
        if nbad or nhuge:
            self._report_clamped(nbad, nhuge)
        return ContactFrame(
            geom=geom,
            pos=pos,
            normal=normal,
            dist=dist,
            force_n=fn,
            force=fn[:, None] * normal,
            vel_rel=vel_rel,
            v_approach=vapp,
            v_slip=v_slip,
            v_roll=v_roll,
        )

    @staticmethod
    def local_points(data, cf: ContactFrame) -> np.ndarray:
        """Contact points in each geom's frame, (n, 2, 3) [m]."""
        xpos = np.asarray(data.geom_xpos)[cf.geom]  # (n,2,3)
        xmat = np.asarray(data.geom_xmat)[cf.geom].reshape(-1, 2, 3, 3)
        d = cf.pos[:, None, :] - xpos
        return np.einsum("nkji,nkj->nki", xmat, d)

    # ------------------------------------------------------------------ events
    def events(self, data, t0: float | None = None, t1: float | None = None, frame: ContactFrame | None = None):
        """Read the last step's contacts and return its sound events.

        Parameters
        ----------
        data : mujoco.MjData
            Right after ``mj_step`` (or ``mj_forward`` for replay).
        t0, t1 : float, optional
            The step's time interval [s]; default ``data.time - timestep`` and ``data.time``.
        frame : ContactFrame, optional
            A frame already read with :meth:`read`.

        Returns
        -------
        (impacts, contacts, frame) : (list[ImpactEvent], list[ContactEvent], ContactFrame | None)
        """
        dt = float(self.model.opt.timestep)
        if t1 is None:
            t1 = float(data.time)
        if t0 is None:
            t0 = t1 - dt
        step_dt = t1 - t0
        self._step += 1
        step = self._step
        cf = self.read(data) if frame is None else frame
        impacts: list[ImpactEvent] = []
        contacts: list[ContactEvent] = []
        if cf is not None:
            order, starts, pkey, vmax, ftot, slip, roll, point, normal = _pair_kernel(
                cf.geom, self.model.ngeom, cf.force_n, cf.v_approach, cf.v_slip, cf.v_roll, cf.pos, cf.normal
            )
            self._room(len(pkey))
            slot, onset, kind, speed, self._nslots = _state_kernel(
                pkey, vmax, ftot, slip, roll, self._hkeys, self._hvals, self._SF, self._SI, self._nslots,
                t0, t1, step_dt, step, self._params,
            )
            if onset.any():
                pairs = np.flatnonzero(onset)
                hits = [order[starts[p]: starts[p + 1]] for p in pairs.tolist()]
                hits = [idx[cf.v_approach[idx] > self.v_impact] for idx in hits]
                hit_starts = np.concatenate([[0], np.cumsum([len(h) for h in hits])]).astype(np.int64)
                hit = np.concatenate(hits)
                H = np.zeros((len(hit), H_COLS))
                H[:, H_G1:H_G2 + 1] = cf.geom[hit]
                H[:, H_POINT:H_POINT + 3] = cf.pos[hit]
                H[:, H_NORMAL:H_NORMAL + 3] = cf.normal[hit]
                H[:, H_SPEED] = cf.v_approach[hit]
                lam, e_pair, _ = self._impacts(data, H, hit_starts, slot[pairs], t0)
                for q in range(len(pairs)):
                    e = float(e_pair[q])
                    for r in range(hit_starts[q], hit_starts[q + 1]):
                        i = int(hit[r])
                        if lam[r] > 0:
                            vi = cf.v_approach[i]
                            impacts.append(ImpactEvent(
                                time=t0, geom1=int(cf.geom[i, 0]), geom2=int(cf.geom[i, 1]), point=cf.pos[i].copy(),
                                normal=cf.normal[i].copy(), impulse=float(lam[r]), speed=float(vi),
                                effective_mass=float(lam[r] / ((1.0 + e) * vi)) if vi > 0 else 0.0))
            if kind.any():
                geom = cf.geom
                for p in np.flatnonzero(kind).tolist():
                    i0 = int(order[starts[p]])
                    contacts.append(ContactEvent(
                        "slide" if kind[p] == 1 else "roll", t0, t1, int(geom[i0, 0]), int(geom[i0, 1]),
                        point[p], normal[p], float(ftot[p]), float(speed[p])))
        elif self._any_open:
            self._close_all()
        return impacts, contacts, cf

    def step_if_quiet(self, data) -> bool:
        """Count the step and return True when nothing touches and no impact is open (what
        :meth:`events_fast` would do, without its call); False: call it."""
        if data.ncon or self._any_open:
            return False
        self._step += 1
        return True

    def events_fast(self, data, t0: float, t1: float, drive=None):
        """:meth:`events` for the per-step driver: the same events and state in one numba call
        per step (plus one more on a step where impacts start), returned as arrays instead of
        event objects; no :class:`ContactFrame` is built.

        Returns
        -------
        impacts : (k, I_COLS) float array | None
            The step's impacting contacts (columns ``I_*``; all at ``t0``); None when none.
        rows : (pairs, R_COLS) float array | None
            The step's sounding pairs (kind slide or roll), columns ``R_*``; None when none.
            A view of a buffer that the next call overwrites: copy it to keep it.

        ``drive``: optional ``(kernel, args)``: ``kernel(*reader_args, *args, missing)``
        replaces the reader's kernel and returns its outputs plus ``(n_missing, need)``;
        :attr:`drive_result` is then ``(missing[:n_missing], need)``
        (:func:`mjsound.sim.drive.read_and_drive`: the sustained rows drive the synthesizer's
        streams in the same call).
        """
        self._step += 1
        step = self._step
        self.drive_result = None
        n = data.ncon
        if n:
            self._room(n)
            con = data.contact
            cvel, scom, gxpos, _ = self._data_views(data)
            if n > len(self._rows_buf):
                self._buffers(2 * n)
            args = (con.geom, con.pos, con.frame, con.efc_address, con.dim, data.efc_force, self._pyramidal,
                    cvel, scom, gxpos, self.geom_body, self.body_root, self._plane,
                    self.model.ngeom, self._hkeys, self._hvals, self._SF, self._SI, self._nslots, t0, t1, step,
                    self._params, self.sustained_steps, self._rows_buf, self._srows_buf, self._hits_buf,
                    self._onset_buf)
            if drive is None:
                out = _fused_kernel(*args)
            else:
                out = drive[0](*args, *drive[1], self._missing_buf)
            return self.kernel_outputs(out, data, t0)
        if self._any_open:
            self._close_all()
        return None, None

    def kernel_outputs(self, out, data, t0: float):
        """:meth:`events_fast`'s results from its kernel's outputs ``out`` (of
        ``_fused_kernel``, or of :func:`.drive.read_and_drive` when 9 long: then
        :attr:`drive_result` is set): the step's impact events are made here."""
        impacts = sustained = None
        n_pairs, n_sust, n_hits, nbad, nhuge, n_onset, self._nslots = out[:7]
        if len(out) > 7:
            self.drive_result = (self._missing_buf[: out[7]], out[8])
        if nbad or nhuge:
            self._report_clamped(nbad, nhuge)
        if n_onset:
            ons = self._onset_buf[: n_onset + 1]
            _, _, impacts = self._impacts(data, self._hits_buf[:n_hits], ons[:, 1], ons[:-1, 0], t0)
        if n_sust:
            sustained = self._srows_buf[:n_sust]
        return impacts, sustained

    def impact_args(self, data) -> tuple:
        """The arguments of :func:`.fused.run_substeps` for impacts (as in :meth:`_impacts`):
        kinematic tree, dofs, ``cdof``, restitution, masses, largest impulse and the record
        rows buffer (:attr:`record_buffer`)."""
        return (self._kin, self.model.nv, self._data_views(data)[3], self.restitution, self._tree_mass,
                self._root_mass, self.max_force * 0.01, self.record_buffer)

    def state_args(self, data) -> tuple:
        """The arguments of ``_fused_kernel`` after the contacts and ``efc_force`` except
        ``nslots, t0, t1, step`` (:func:`.fused.run_substeps` keeps those itself), then the
        drive's ``missing`` buffer."""
        cvel, scom, gxpos, _ = self._data_views(data)
        return (self._pyramidal, cvel, scom, gxpos, self.geom_body, self.body_root, self._plane, self.model.ngeom,
                self._hkeys, self._hvals, self._SF, self._SI, self._params, self.sustained_steps, self._rows_buf,
                self._srows_buf, self._hits_buf, self._onset_buf), self._missing_buf

    def _close_all(self) -> None:
        """Nothing touches: every open impact record closes."""
        self._SI[SI_OPEN, : self._nslots] = 0
        self._any_open = False

    def _data_views(self, data):
        """``(cvel, subtree_com, geom_xpos, cdof)`` of ``data``: fixed-size MjData arrays, whose
        numpy views stay valid (only contacts and constraints change size), made once."""
        if data is not self._views_of:
            self._views = (data.cvel, data.subtree_com, data.geom_xpos, data.cdof)
            self._views_of = data
        return self._views

    @property
    def impacts(self) -> list[ImpactRecord]:
        """The last ``keep_records`` impact events' :class:`ImpactRecord`, oldest first (the
        open ones brought up to date)."""
        SF, SI = self._SF, self._SI
        for j, rec in list(self._open.items()):
            rec.impulse_sim = float(SF[SF_RIMP, j])
            rec.steps = int(SI[SI_RSTEPS, j])
            rec.duration = float(SF[SF_REND, j] - SF[SF_RTIME, j])
            if not SI[SI_OPEN, j]:
                rec.open = False
                del self._open[j]
        return list(self._records)

    def _impacts(self, data, hits, starts, slots, t0):
        """Impact events of several pairs at once: contacts ``starts[q] : starts[q + 1]`` of
        ``hits`` (k, ``H_COLS``) are the event of pair slot ``slots[q]``. Each gets its
        :class:`ImpactRecord` (listed open under its slot). Returns the impulses (k,), each
        event's restitution (events,) and the impacts with a positive impulse (columns ``I_*``).

        ``lambda = A^+ (1 + e) v`` with the contact-space inverse inertia ``A = Jn M^-1 Jn^T``
        of each event: all normal Jacobians by :func:`_normal_jacobians`, one ``mj_solveM`` for
        all of them, the impulses by :func:`_impulses_grouped`.
        """
        m = self.model
        nv = m.nv
        k = len(hits)
        if nv > 0:
            _, scom, _, cdof = self._data_views(data)
            Jn = _normal_jacobians(hits, cdof, scom, self.geom_body, *self._kin, nv)
            MinvJt = np.empty((k, nv))
            self._mj.mj_solveM(m, data, MinvJt, Jn)
        else:
            Jn = MinvJt = np.zeros((k, 0))
        lam, stats, imp = _impulses_grouped(hits, Jn, MinvJt, starts, self.restitution, self._tree_mass,
                                            self._root_mass, self.geom_body, self.max_force * 0.01)
        rows = np.empty((len(stats), REC_COLS))
        _record_rows(hits, starts, slots, stats, t0, self._SF, self._SI, rows)
        self.add_records(rows)
        return lam, stats[:, 0], imp

    def add_records(self, rows: np.ndarray) -> None:
        """An :class:`ImpactRecord` for each impact event (rows of :func:`_record_rows`, in
        order); each closes its slot's previous record with the sums banked at its onset."""
        records = self._records
        self._any_open = self._any_open or len(rows) > 0
        for t0, g1, g2, vmax, total, eq, j, clamped, p_imp, p_steps, p_end in rows.tolist():
            old = self._open.pop(int(j), None)
            if old is not None:
                old.impulse_sim, old.steps, old.duration, old.open = p_imp, int(p_steps), p_end - old.time, False
            rec = ImpactRecord(
                time=t0, geom1=int(g1), geom2=int(g2), speed=vmax, impulse_pred=total, impulse_sim=0.0, restitution=eq,
                effective_mass=total / ((1.0 + eq) * vmax) if vmax > 0 else 0.0,
            )
            self._open[int(j)] = rec
            records.append(rec)
            if clamped:
                self.n_clamped += 1
                self._warn_once("impulse", f"mjsound: impact impulse above {self.max_force * 0.01:g} N s clamped; "
                                "reported once")
        self.n_impacts += len(rows)
