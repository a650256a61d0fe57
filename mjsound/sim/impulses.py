"""Numba kernels of an impact's impulse: ``lambda = A^+ (1 + e) v`` from MuJoCo's dynamics.

For the impacting contacts of one event (a geom pair's onset, :mod:`.pairs`), with approach
speeds ``v`` along their normals, the contact-space inverse inertia is
``A = Jn M^-1 Jn^T`` (``Jn``: the normal rows of the point Jacobians, :func:`normal_jacobians`;
``M^-1 Jn^T`` from one ``mj_solveM`` for all of a substep's hits). The impulses
``lambda = A^+ (1 + e) v`` (clipped at 0) stop the approach with restitution ``e``; when
``A`` is degenerate the bodies' masses give ``m* (1 + e) v / k`` instead. The total never
exceeds ``(1 + e) max(v)`` times the lighter moving tree's mass, and each impulse is capped
at ``max_impulse``.
"""

from __future__ import annotations

import numpy as np

from ..jit import njit, njit_inner

__all__ = ["normal_jacobians", "restitution_of", "pinv_psd", "impulse_kernel", "event_impulses", "write_records"]


@njit_inner(cache=True)
def normal_jacobians(reader, hits, k, cdof, scom, jn):
    """``jn[r] = n_r . (J_geom2(p_r) - J_geom1(p_r))`` (k, nv) for the hits ``r < k`` (world
    point ``p_r`` and normal ``n_r``; the world body adds nothing).

    The point Jacobian of body ``b`` is MuJoCo's ``mj_jac`` (its C code, here in numba so
    that no Python call per contact side is needed): from the first body with dofs up the
    tree, each dof ``i`` on the ancestor chain (``dof_parent``) contributes the column
    ``J[:, i] = cdof_lin_i + cdof_ang_i x (p - subtree_com[root(b)])`` (``cdof`` rows are
    (angular, linear) motion axes)."""
    bodies = reader.bodies
    dof_parent = reader.dof_parent
    jn[:] = 0.0
    for r in range(k):
        h = hits[r]
        nx, ny, nz = h.normal[0], h.normal[1], h.normal[2]
        for side in range(2):
            b0 = reader.geoms[h.g1 if side == 0 else h.g2].body
            b = b0
            while b > 0 and bodies[b].dofnum == 0:
                b = bodies[b].parent
            if b == 0:
                continue
            root = bodies[b0].root
            ox = h.point[0] - scom[root, 0]
            oy = h.point[1] - scom[root, 1]
            oz = h.point[2] - scom[root, 2]
            sign = 1.0 if side == 1 else -1.0
            i = bodies[b].dofadr + bodies[b].dofnum - 1
            while i >= 0:
                jx = cdof[i, 3] + (cdof[i, 1] * oz - cdof[i, 2] * oy)
                jy = cdof[i, 4] + (cdof[i, 2] * ox - cdof[i, 0] * oz)
                jz = cdof[i, 5] + (cdof[i, 0] * oy - cdof[i, 1] * ox)
                jn[r, i] += sign * (nx * jx + ny * jy + nz * jz)
                i = dof_parent[i]


@njit(cache=True)
def restitution_of(geoms, g1, g2):
    """Acoustic restitution of a geom pair: ``sqrt(e1 e2)``, the one known (NaN: unknown), or 0.5."""
    e1, e2 = geoms[g1].restitution, geoms[g2].restitution
    if e1 == e1 and e2 == e2:
        return np.sqrt(e1 * e2)
    if e1 == e1:
        return e1
    if e2 == e2:
        return e2
    return 0.5


@njit_inner(cache=True)
def pinv_psd(S, rcond):
    """Pseudo-inverse of a symmetric ``(k, k)`` matrix ``S``, as ``numpy.linalg.pinv(S, rcond)``.

    ``S = V diag(lambda) V^T`` by cyclic Jacobi rotations (Numerical Recipes 11.1: each
    rotation zeroes one off-diagonal entry, ``theta = (s_qq - s_pp) / (2 s_pq)``,
    ``t = sgn(theta) / (|theta| + sqrt(theta^2 + 1))``, ``c = 1 / sqrt(t^2 + 1)``, ``s = t c``;
    sweeps until the off-diagonal part is below rounding), then
    ``S^+ = sum_{|lambda_i| > rcond max|lambda|} v_i v_i^T / lambda_i`` (a symmetric matrix's
    singular values are its ``|lambda|``). ``k`` is the number of contacts of one impact, a
    few: this keeps LAPACK (and its threads) out of the step kernel."""
    k = S.shape[0]
    A = S.copy()
    V = np.eye(k)
    scale = 0.0
    for i in range(k):
        for j in range(k):
            scale += A[i, j] * A[i, j]
    for _ in range(100):
        off = 0.0
        for p in range(k):
            for q in range(p + 1, k):
                off += A[p, q] * A[p, q]
        if off <= 1e-32 * scale:
            break
        for p in range(k - 1):
            for q in range(p + 1, k):
                apq = A[p, q]
                if apq == 0.0:
                    continue
                theta = (A[q, q] - A[p, p]) / (2.0 * apq)
                t = 1.0 / (abs(theta) + np.sqrt(theta * theta + 1.0))
                if theta < 0.0:
                    t = -t
                c = 1.0 / np.sqrt(t * t + 1.0)
                s = t * c
                for r in range(k):  # columns p, q
                    arp = A[r, p]
                    arq = A[r, q]
                    A[r, p] = c * arp - s * arq
                    A[r, q] = s * arp + c * arq
                for r in range(k):  # rows p, q
                    apr = A[p, r]
                    aqr = A[q, r]
                    A[p, r] = c * apr - s * aqr
                    A[q, r] = s * apr + c * aqr
                A[p, q] = 0.0
                A[q, p] = 0.0
                for r in range(k):
                    vrp = V[r, p]
                    vrq = V[r, q]
                    V[r, p] = c * vrp - s * vrq
                    V[r, q] = s * vrp + c * vrq
    lmax = 0.0
    for i in range(k):
        lmax = max(lmax, abs(A[i, i]))
    P = np.zeros((k, k))
    for i in range(k):
        lam = A[i, i]
        if abs(lam) > rcond * lmax:
            for a in range(k):
                for b in range(k):
                    P[a, b] += V[a, i] * V[b, i] / lam
    return P


@njit_inner(cache=True)
def impulse_kernel(Jn, MinvJt, v, e, m1, m2, cap_mass, jmax):
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
                Ap = pinv_psd(S, 1e-4)
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


@njit_inner(cache=True)
def event_impulses(reader, buf, n_onset, jn, minv_jt):
    """:func:`impulse_kernel` for every impact event of a substep: hits
    ``onsets[q].first : onsets[q + 1].first`` are event ``q`` (one geom pair). Writes the
    impacts with ``lambda > 0`` into ``buf.impacts`` and returns their number and, per event,
    its restitution, largest approach speed, total impulse and whether an impulse was clamped
    (``stats`` (events, 4))."""
    prm = reader.prm[0]
    geoms, bodies, hits, ons = reader.geoms, reader.bodies, buf.hits, buf.onsets
    k = ons[n_onset].first
    lam = np.zeros(k)
    e_hit = np.zeros(k)  # (each hit's restitution: its event's)
    stats = np.zeros((n_onset, 4))
    for q in range(n_onset):
        a, b = ons[q].first, ons[q + 1].first
        g1, g2 = hits[a].g1, hits[a].g2
        b1, b2 = geoms[g1].body, geoms[g2].body
        e = restitution_of(geoms, g1, g2)
        v = np.empty(b - a)
        for r in range(a, b):
            v[r - a] = hits[r].speed
        lq, cl = impulse_kernel(jn[a:b], minv_jt[a:b], v, e, bodies[b1].tree_mass, bodies[b2].tree_mass,
                                min(bodies[b1].root_mass, bodies[b2].root_mass), prm.max_impulse)
        for r in range(a, b):
            lam[r] = lq[r - a]
            e_hit[r] = e
        stats[q, 0] = e
        stats[q, 1] = v.max()
        stats[q, 2] = lq.sum()
        stats[q, 3] = 1.0 if cl else 0.0
    n = 0
    for r in range(k):
        if lam[r] > 0:
            h = hits[r]
            im = buf.impacts[n]
            im.g1 = h.g1
            im.g2 = h.g2
            for c in range(3):
                im.point[c] = h.point[c]
                im.normal[c] = h.normal[c]
            im.impulse = lam[r]
            im.speed = h.speed
            im.restitution = e_hit[r]
            n += 1
    return n, stats


@njit_inner(cache=True)
def write_records(reader, buf, n_onset, stats, t0):
    """An impact record row per event into ``buf.records`` (after the ``n_records`` waiting):
    time, geoms, largest approach speed, predicted impulse, restitution, slot, clamped, then
    what the state machine banked at this onset for the slot's previous record (sum F dt,
    steps, end time), which closes it (``ContactReader.add_records``). Marks an impact open;
    counts the records with an audible geom (``GEOM.audible``) and the clamped ones."""
    cnt = reader.counts[0]
    ons, hits, pairs, geoms = buf.onsets, buf.hits, reader.pairs, reader.geoms
    for q in range(n_onset):
        a, j = ons[q].first, ons[q].slot
        r = buf.records[cnt.n_records]
        g1, g2 = hits[a].g1, hits[a].g2
        r.time = t0
        r.g1 = g1
        r.g2 = g2
        r.speed = stats[q, 1]
        r.impulse_pred = stats[q, 2]
        r.restitution = stats[q, 0]
        r.slot = j
        r.clamped = 0
        if stats[q, 3]:
            r.clamped = 1
            cnt.clamped += 1
        if geoms[g1].audible or geoms[g2].audible:
            cnt.audible += 1
        r.prev_impulse = pairs[j].prev_impulse
        r.prev_steps = pairs[j].prev_steps
        r.prev_end = pairs[j].prev_end
        cnt.n_records += 1
    cnt.any_open = 1
