"""Numba kernels of the contact reader: contacts -> per-pair quantities -> pair state machine.

The rules (impact onset, refractory time, sliding / rolling) are documented in
:mod:`mjsound.sim.contacts`; the state they keep is :data:`.records.PAIR` (one slot per geom
pair, found through an open-addressing table) and the reader's counters
:data:`.records.READER_COUNTS`. :func:`read_pairs` is stage 1 of the step kernel
(:mod:`.step`): it fills the substep's rows, hits and onsets in :class:`.records.StepBuffers`.
"""

from __future__ import annotations

import numpy as np

from ..jit import njit, njit_inner
from ..synth.sorting import stable_argsort_into

__all__ = ["contact_quantities", "group_pairs", "slot_of", "rehash", "update_pairs", "read_pairs"]


@njit(cache=True)
def contact_quantities(buf, ncon, efc, reader, views, out):
    """Per contact ``i < ncon`` of ``buf`` (world frame), into the rows ``< ncon`` of ``out``
    (:class:`.records.ContactQuantities`): normal force [N] (summed pyramid facets;
    non-finite forces are 0, huge ones clamped to ``max_force``), unit normal, relative
    velocity of geom2's material point minus geom1's [m/s] (from ``cvel`` about each body's
    subtree com), approach speed ``-(v_rel . n)``, slip speed ``|v_rel,t|`` and rolling speed
    ``|omega_rel,t| r`` (r: distance to the nearer non-plane geom centre). Contacts with
    non-finite data are silenced (force 0, normal +z) and non-finite points set to 0.
    Returns ``(nbad, nhuge)``: contacts silenced, forces clamped."""
    geom, pos, frame, adr, dim = buf.geom, buf.pos, buf.frame, buf.efc_address, buf.dim
    prm = reader.prm[0]
    pyramidal, fmax = prm.pyramidal, prm.max_force
    geoms, bodies = reader.geoms, reader.bodies
    cvel, scom, gxpos = views.cvel, views.subtree_com, views.geom_xpos
    n = ncon
    fn, nrm, vrel, vapp, vslip, vroll = out.fn, out.nrm, out.vrel, out.vapp, out.vslip, out.vroll
    nbad = 0
    nhuge = 0
    # per contact side: point velocity v and angular velocity w, and their difference wr
    v, w, wr = out.sides[0:2], out.sides[2:4], out.sides[4]
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
            b = geoms[geom[i, s]].body
            rb = bodies[b].root
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
            if not geoms[g].plane:
                dx = pos[i, 0] - gxpos[g, 0]
                dy = pos[i, 1] - gxpos[g, 1]
                dz = pos[i, 2] - gxpos[g, 2]
                r = np.sqrt(dx * dx + dy * dy + dz * dz)
                if r < rad:
                    rad = r
        if not np.isfinite(rad):
            rad = 0.0
        vroll[i] = np.sqrt(wt) * rad
    return nbad, nhuge


@njit_inner(cache=True)
def group_pairs(geom, ngeom, fn, vapp, vslip, vroll, pos, nrm, out):
    """Group the contacts (``fn`` and the other per-contact arrays: their first n rows) by geom
    pair, in ``out`` (:class:`.records.PairGroups`): per pair its contacts, largest approach
    speed, total normal force and the force-weighted slip speed, rolling speed, point and
    normal. Returns ``(order, starts, key, vmax, ftot, slip, roll, point, normal)`` (views of
    ``out``): pair ``p``'s contacts are ``order[starts[p]:starts[p + 1]]``."""
    n = fn.shape[0]
    keys = out.keys[:n]
    for i in range(n):
        a, b = geom[i, 0], geom[i, 1]
        keys[i] = min(a, b) * ngeom + max(a, b)
    order = stable_argsort_into(keys, out.order, out.order_b)
    starts = out.starts
    P = 0
    for j in range(n):
        if j == 0 or keys[order[j]] != keys[order[j - 1]]:
            starts[P] = j
            P += 1
    starts[P] = n
    pkey, vmax = out.pkey[:P], out.vmax[:P]
    ftot, slip, roll, point, normal = out.ftot[:P], out.slip[:P], out.roll[:P], out.point[:P], out.normal[:P]
    ftot[:] = 0.0
    slip[:] = 0.0
    roll[:] = 0.0
    point[:] = 0.0
    normal[:] = 0.0
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


@njit(cache=True)
def slot_of(hkeys, hvals, key, nslots):
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


@njit(cache=True)
def rehash(keys, vals, size):
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


@njit_inner(cache=True)
def update_pairs(reader, pkey, vmax, ftot, slip, roll, t0, t1, out):
    """The per-pair state machine for one step ``[t0, t1)`` (the rules are in
    :mod:`mjsound.sim.contacts`): finds or makes each pair's slot, decides impact onsets,
    accumulates the open records' ``sum F dt`` and classifies sustained contact. Returns per
    pair its slot, onset (an impact starts), kind (0 none, 1 slide, 2 roll) and speed (views
    of ``out``, :class:`.records.PairSteps`). Pairs seen before but not in this step close
    their open impact record."""
    prm = reader.prm[0]
    cnt = reader.counts[0]
    S = reader.pairs
    v_impact, v_hard, min_apart, refractory = prm.v_impact, prm.v_hard, prm.min_apart_s, prm.refractory_s
    max_event, v_slide, v_roll = prm.max_event_s, prm.v_slide, prm.v_roll
    step = cnt.step
    nslots = cnt.nslots
    dt = t1 - t0
    P = pkey.shape[0]
    slot, onset_out, kind, speed = out.slot[:P], out.onset[:P], out.kind[:P], out.speed[:P]
    onset_out[:] = False
    kind[:] = 0
    speed[:] = 0.0
    for p in range(P):
        j, new = slot_of(reader.hkeys, reader.hvals, pkey[p], nslots)
        s = S[j]
        if new:
            nslots += 1
            s.vprev = 0.0
            s.last = -10
            s.touch = -np.inf
            s.hit = -np.inf
            s.calm = 0
            s.open = 0
        slot[p] = j
        vm = vmax[p]
        if vm > v_impact:
            vp = max(s.vprev, 0.0)
            if s.last != step - 1:
                onset = vm >= v_hard or t0 - s.touch >= min_apart
            else:
                onset = vm > 2.0 * vp and vm - vp > 2.0 * v_impact
            if onset and t0 - s.hit >= refractory - 1e-12:
                onset_out[p] = True
                s.prev_impulse = s.rec_impulse
                s.prev_end = s.rec_end
                s.prev_steps = s.rec_steps
                s.open = 1
                s.rec_time = t0
                s.rec_speed = vm
                s.rec_impulse = 0.0
                s.rec_steps = 0
                s.calm = 0
                s.hit = t0
        if s.open:
            s.rec_impulse += ftot[p] * dt
            s.rec_steps += 1
            s.rec_end = t1
            tol = max(0.02 * s.rec_speed, 1e-3)
            s.calm = s.calm + 1 if abs(vm) < tol else 0
            if s.calm >= 2 or t1 - s.rec_time >= max_event:
                s.open = 0
        s.vprev = vm
        s.last = step
        s.touch = t0
        if ftot[p] > 0.0:
            if slip[p] > v_slide and slip[p] > 0.3 * roll[p]:
                kind[p] = 1
                speed[p] = slip[p]
            elif roll[p] > v_roll:
                kind[p] = 2
                speed[p] = roll[p]
    for j in range(nslots):
        if S[j].open and S[j].last != step:
            S[j].open = 0
    cnt.nslots = nslots
    return slot, onset_out, kind, speed


@njit_inner(cache=True, inline="always")  # (numba IR: no call that reference-counts every array of its records)
def read_pairs(reader, buf, views, ncon, efc, t0, t1):
    """Stage 1 of a substep: the ``ncon`` contacts in ``buf`` (their constraint forces in
    ``efc``) -> :func:`contact_quantities` -> :func:`group_pairs` -> :func:`update_pairs`, and
    the results into ``buf``: ``rows`` (every touching pair), ``sustained`` (those that slide or
    roll; the reader's slide / roll counters count them), ``hits`` (the contacts of onset
    pairs approaching faster than ``v_impact``, grouped by pair) and ``onsets`` (each onset
    pair's slot and first hit; one more row holds the number of hits). The reader's step
    counter must already count this step. Returns ``(pairs, n_sustained, n_hits, n_onset)``."""
    prm = reader.prm[0]
    cnt = reader.counts[0]
    q = buf.quantities
    nbad, nhuge = contact_quantities(buf, ncon, efc, reader, views, q)
    cnt.n_bad += nbad
    cnt.n_huge += nhuge
    geom, pos = buf.geom, buf.pos
    fn, nrm, vapp = q.fn[:ncon], q.nrm[:ncon], q.vapp[:ncon]
    order, starts, pkey, vmax, ftot, slip, roll, point, normal = group_pairs(
        geom, reader.geoms.shape[0], fn, vapp, q.vslip[:ncon], q.vroll[:ncon], pos, nrm, buf.groups)
    slot, onset, kind, speed = update_pairs(reader, pkey, vmax, ftot, slip, roll, t0, t1, buf.steps)
    rows = buf.rows
    P = pkey.shape[0]
    n_onset = 0
    n_sust = 0
    for p in range(P):
        i0 = order[starts[p]]
        r = rows[p]
        r.g1 = geom[i0, 0]
        r.g2 = geom[i0, 1]
        r.kind = kind[p]
        r.force = ftot[p]
        r.speed = speed[p]
        for c in range(3):
            r.point[c] = point[p, c]
            r.normal[c] = normal[p, c]
        r.onset = 1 if onset[p] else 0
        r.slot = slot[p]
        if onset[p]:
            n_onset += 1
        if kind[p] > 0:
            buf.sustained[n_sust] = rows[p]
            n_sust += 1
            if kind[p] == 1:
                cnt.slide_steps += 1
            else:
                cnt.roll_steps += 1
    nh = 0
    q = 0
    if n_onset:
        for p in range(P):
            if onset[p]:
                buf.onsets[q].slot = slot[p]
                buf.onsets[q].first = nh
                q += 1
                for j in range(starts[p], starts[p + 1]):
                    i = order[j]
                    if vapp[i] > prm.v_impact:
                        h = buf.hits[nh]
                        h.pair = p
                        h.g1 = geom[i, 0]
                        h.g2 = geom[i, 1]
                        for c in range(3):
                            h.point[c] = pos[i, c]
                            h.normal[c] = nrm[i, c]
                        h.speed = vapp[i]
                        nh += 1
    buf.onsets[q].first = nh
    return P, n_sust, nh, n_onset
