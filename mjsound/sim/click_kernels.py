"""The per-impact part of :class:`.clicks.ImpactPulses` in numba: a substep's impacts ->
band-limited pulse rows (:data:`mjsound.synth.bandlimited.PULSE_DTYPE`), one call per substep.

For each touching pair of the substep (its impact rows with a finite, positive impulse,
grouped by ``(geom1, geom2)`` in order of first appearance) the pulse acts at the
impulse-weighted centre of its points with the summed impulse ``J`` (on geom2; geom1 gets
``-J``), the fastest approach speed ``v`` and the contact time ``tau``: Hertz's
``coef v^(-1/5)`` (:func:`mjsound.synth.pulse.contact_time`, :func:`hertz_coefficient`), or,
when longer, the thin shells' ``pi sqrt(m* (s1 + s2))``, at most ``pi R / v``
(:func:`pair_contact_time`). Each dynamic body
``b`` of the pair (centre of mass ``o``, principal frame ``Ri``) changes its velocity by
``dv = J / m_b`` and its angular velocity by ``dw = Ri (Ri^T ((p - o) x J) / I_b)``, each of
``|dv|`` and ``|dw x arm|`` capped at ``(1 + e) v`` (``e`` the pair's acoustic restitution,
:func:`mjsound.sim.impulses.restitution_of`: no impact with approach speed ``v`` changes a
velocity by more, whatever ``J`` says). Its click at air microphone ``m`` (distance
``r`` from ``o``, direction ``x^``, equivalent radius ``a``, dipole masses ``M``) is the pulse
``b0 = k / r^2``, ``b1 = k / (r c)``, ``d1 = a / c``, ``d2 = a^2 / (2 c^2)`` arriving at
``t + (r - a) / c``, ``k = x^ . Ri (M * (Ri^T dv^)) / (4 pi)``, scaled by ``|dv|``
(:func:`mjsound.synth.accel_noise.click_pulses`); a contact microphone on the body gets a unit
pulse at ``t`` scaled by ``(dv + dw x (x_site - o)) . n`` (:mod:`mjsound.synth.contact_mic`).
The arithmetic follows the numpy reference in ``tests/test_clicks.py`` to float rounding.
"""

from __future__ import annotations

import math

import numpy as np

from ..jit import njit, njit_inner
from ..synth.bandlimited import add_pulses
from ..synth.pulse import contact_time, effective, hertz_coef, shell_contact_time
from .impulses import restitution_of

__all__ = ["impact_pulses", "queue_pulses", "pulse_room", "render_waiting", "hertz_coefficient", "pair_contact_time",
           "pulse_rows_needed"]


def pulse_rows_needed(n_impacts: int, n_air: int, n_sites: int) -> int:
    """Most pulse rows :func:`impact_pulses` writes for ``n_impacts`` impact rows: both sides
    of each, a click per air microphone and a pulse per contact microphone."""
    return 2 * int(n_impacts) * (int(n_air) + int(n_sites))


@njit(cache=True)
def hertz_coefficient(cm, g1, g2):
    """``coef`` [s (m/s)^(1/5)] of ``tau = coef v^(-1/5)`` for an impact between geoms ``g1``
    and ``g2``: their bodies' Hertz masses and their contact radii combined harmonically,
    ``E* = 1 / (c1 + c2)`` from the materials' compliances (both
    ``prm.unknown_compliance`` when neither geom has a material), ``2.87 (m^2 / (R E*^2))^(1/5)``,
    0 for an immovable or flat pair or rigid materials (:func:`mjsound.synth.pulse.hertz_coef`)."""
    ga = cm.geoms[g1]
    gb = cm.geoms[g2]
    if ga.has_material or gb.has_material:
        c = ga.compliance + gb.compliance
    else:
        c = cm.prm[0].unknown_compliance + cm.prm[0].unknown_compliance
    return hertz_coef(effective(cm.bodies[ga.body].hertz_mass, cm.bodies[gb.body].hertz_mass),
                      effective(ga.radius, gb.radius), c)


@njit_inner(cache=True)
def _crush_time(ga, gb, speed):
    """``pi R / v`` [s], the longest a shell's contact can last at approach ``speed`` [m/s]:
    a mass on the wall's linear spring sinks ``v tau / pi`` into it, and the wall cannot give
    more than the radius ``R`` of its geom (the smaller of the shells' radii; inf at speed 0)."""
    r = math.inf
    if ga.shell_compliance > 0 and ga.radius < r:
        r = ga.radius
    if gb.shell_compliance > 0 and gb.radius < r:
        r = gb.radius
    if not speed > 0 or math.isinf(r):
        return math.inf
    return math.pi * r / speed


@njit(cache=True)
def pair_contact_time(cm, g1, g2, speed):
    """Contact time [s] of an impact between geoms ``g1`` and ``g2`` at approach ``speed``
    [m/s]: Hertz's ``contact_time(hertz_coefficient(cm, g1, g2), speed)``, or the thin shells'
    ``pi sqrt(m* (s1 + s2))`` when longer (:func:`mjsound.synth.pulse.shell_contact_time`;
    ``m*`` the bodies' Hertz masses combined, ``s`` each geom's ``shell_compliance`` [m/N]),
    at most ``pi R / v`` (:func:`_crush_time`: a wall sinks no deeper than its radius, which a
    light shell carrying a heavy subtree would otherwise do for seconds). Exactly Hertz's when
    neither geom is a shell."""
    tau = contact_time(hertz_coefficient(cm, g1, g2), speed)
    ga = cm.geoms[g1]
    gb = cm.geoms[g2]
    if ga.shell_compliance > 0 or gb.shell_compliance > 0:
        m = effective(cm.bodies[ga.body].hertz_mass, cm.bodies[gb.body].hertz_mass)
        shell = min(shell_contact_time(m, ga.shell_compliance, gb.shell_compliance), _crush_time(ga, gb, speed))
        if shell > tau:
            tau = shell
    return tau


@njit_inner(cache=True)
def _norm3(x0, x1, x2):
    return math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)


@njit_inner(cache=True)
def _capped(x, y, z, cap):
    """``(x, y, z)`` scaled to length ``cap`` when longer (and ``cap > 0``), and its length."""
    norm = _norm3(x, y, z)
    if norm > cap and cap > 0:
        f = cap / norm
        return x * f, y * f, z * f, cap
    return x, y, z, norm


@njit_inner(cache=True)
def _body_pulses(cm, b, J, point, cap, tau, time_s, pose, mics, rows, dv, n):
    """Append body ``b``'s pulses (its clicks, its contact microphones') from row ``n`` on, for
    the impulse ``J`` (3,) [N s] on it at ``point`` (3,) [m], the largest velocity change
    ``cap`` [m/s] the impact allows (``(1 + e) v``), pulse length ``tau`` [s] at ``time_s`` [s];
    ``pose`` is ``(xpos, xmat)``, the bodies' poses (see :func:`impact_pulses`). Returns the
    next free row."""
    xpos, xmat = pose
    bd = cm.bodies[b]
    prm = cm.prm[0]
    R = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            R[i, j] = xmat[b, 3 * i + j]
    com = np.empty(3)
    for i in range(3):
        com[i] = xpos[b, i] + (R[i, 0] * bd.ipos[0] + R[i, 1] * bd.ipos[1] + R[i, 2] * bd.ipos[2])
    Ri = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            Ri[i, j] = R[i, 0] * bd.iframe[0, j] + R[i, 1] * bd.iframe[1, j] + R[i, 2] * bd.iframe[2, j]
    dvx, dvy, dvz, dv_norm = _capped(J[0] / bd.mass, J[1] / bd.mass, J[2] / bd.mass, cap)
    n_air = prm.n_air
    if prm.clicks and n_air and dv_norm > 0:
        ux = dvx / dv_norm
        uy = dvy / dv_norm
        uz = dvz / dv_norm
        # dipole = Ri (M * (Ri^T u)) [kg per m/s of dv]
        loc = np.empty(3)
        for j in range(3):
            loc[j] = bd.masses[j] * (Ri[0, j] * ux + Ri[1, j] * uy + Ri[2, j] * uz)
        dip = np.empty(3)
        for i in range(3):
            dip[i] = Ri[i, 0] * loc[0] + Ri[i, 1] * loc[1] + Ri[i, 2] * loc[2]
        a = bd.a_eq
        c = prm.c
        air = cm.air
        for q in range(n_air):  # (each microphone, then its images: .records.CLICK_AIR)
            m = air[q].mic
            rx = mics[m, 0] - com[0]
            ry = mics[m, 1] - com[1]
            rz = mics[m, 2] - com[2]
            dist = _norm3(rx, ry, rz)
            h = dist if dist > 0 else 1.0  # a microphone at the centre hears nothing
            r = dist if dist > a else a
            k = ((rx / h) * dip[0] + (ry / h) * dip[1] + (rz / h) * dip[2]) / (4.0 * math.pi)
            gain = air[q].gain
            if gain != 1.0:  # (an image: the floor's reflection of the click)
                k *= gain
            row = rows[n]
            row.time_s = time_s + (r - a) / c
            row.tau_s = tau
            row.b0 = k / (r * r)
            row.b1 = k / (r * c)
            row.d1 = a / c
            row.d2 = a * a / (2.0 * c * c)
            row.channel = air[q].channel
            row.joins = air[q].joins
            dv[n] = dv_norm
            n += 1
    sites = cm.sites
    first = True
    dwx = 0.0
    dwy = 0.0
    dwz = 0.0
    for s in range(sites.shape[0]):
        st = sites[s]
        if st.body != b:
            continue
        if first:  # dw = Ri (Ri^T ((p - o) x J) / I), 0 about a principal axis without inertia
            first = False
            ax = point[0] - com[0]
            ay = point[1] - com[1]
            az = point[2] - com[2]
            tx = ay * J[2] - az * J[1]
            ty = az * J[0] - ax * J[2]
            tz = ax * J[1] - ay * J[0]
            wl = np.empty(3)
            for j in range(3):
                inertia = bd.inertia[j]
                wl[j] = (Ri[0, j] * tx + Ri[1, j] * ty + Ri[2, j] * tz) / inertia if inertia > 0 else 0.0
            dwx = Ri[0, 0] * wl[0] + Ri[0, 1] * wl[1] + Ri[0, 2] * wl[2]
            dwy = Ri[1, 0] * wl[0] + Ri[1, 1] * wl[1] + Ri[1, 2] * wl[2]
            dwz = Ri[2, 0] * wl[0] + Ri[2, 1] * wl[1] + Ri[2, 2] * wl[2]
        sx = xpos[b, 0] + (R[0, 0] * st.pos[0] + R[0, 1] * st.pos[1] + R[0, 2] * st.pos[2]) - com[0]
        sy = xpos[b, 1] + (R[1, 0] * st.pos[0] + R[1, 1] * st.pos[1] + R[1, 2] * st.pos[2]) - com[1]
        sz = xpos[b, 2] + (R[2, 0] * st.pos[0] + R[2, 1] * st.pos[1] + R[2, 2] * st.pos[2]) - com[2]
        nx = R[0, 0] * st.axis[0] + R[0, 1] * st.axis[1] + R[0, 2] * st.axis[2]
        ny = R[1, 0] * st.axis[0] + R[1, 1] * st.axis[1] + R[1, 2] * st.axis[2]
        nz = R[2, 0] * st.axis[0] + R[2, 1] * st.axis[1] + R[2, 2] * st.axis[2]
        spx, spy, spz, _ = _capped(dwy * sz - dwz * sy, dwz * sx - dwx * sz, dwx * sy - dwy * sx, cap)
        dv_site = (dvx + spx) * nx + (dvy + spy) * ny + (dvz + spz) * nz
        if dv_site != 0.0:
            row = rows[n]
            row.time_s = time_s
            row.tau_s = tau
            row.b0 = 1.0
            row.b1 = 0.0
            row.d1 = 0.0
            row.d2 = 0.0
            row.channel = n_air + s
            row.joins = 0
            dv[n] = dv_site
            n += 1
    return n


@njit(cache=True)
def impact_pulses(cm, impacts, k, time_s, xpos, xmat, mics, rows, dv, n):
    """The pulses of one substep's impacts ``impacts[:k]`` (``IMPACT`` rows: ``g1, g2, point,
    normal, impulse`` [N s] on geom2, ``speed`` [m/s]) at time ``time_s`` [s] on the output
    clock (see the module docstring), written from row ``n`` on.

    Parameters
    ----------
    cm : ClickModel
        The bodies, geoms, contact microphones and constants (:class:`.records.ClickModel`).
    xpos, xmat : (nbody, 3), (nbody, 9)
        Body poses of the impacts' step (MjData ``xpos``, ``xmat``).
    mics : (>= n_air, 3)
        Air microphone positions [m] (the first ``n_air`` rows).
    rows, dv : (>= n + :func:`pulse_rows_needed`,) PULSE_DTYPE and float64
        Receive the pulses and the velocity change [m/s] each is scaled by.

    Returns
    -------
    int : the next free row.
    """
    ok = np.zeros(k, np.bool_)
    for i in range(k):
        im = impacts[i]
        good = np.isfinite(im.impulse) and im.impulse > 0 and np.isfinite(im.speed)
        for c in range(3):
            good = good and np.isfinite(im.normal[c]) and np.isfinite(im.point[c])
        ok[i] = good
    done = np.zeros(k, np.bool_)
    J = np.empty(3)
    point = np.empty(3)
    Jm = np.empty(3)
    for i in range(k):
        if not ok[i] or done[i]:
            continue
        g1 = impacts[i].g1
        g2 = impacts[i].g2
        for c in range(3):
            J[c] = 0.0
            point[c] = 0.0
        wsum = 0.0
        speed = -np.inf
        for j in range(i, k):  # the pair's rows, in order
            if not ok[j] or done[j] or impacts[j].g1 != g1 or impacts[j].g2 != g2:
                continue
            done[j] = True
            w = impacts[j].impulse
            for c in range(3):
                J[c] += w * impacts[j].normal[c]
                point[c] += w * impacts[j].point[c]
            wsum += w
            if impacts[j].speed > speed:
                speed = impacts[j].speed
        for c in range(3):
            point[c] = point[c] / wsum
            Jm[c] = -J[c]
        tau = pair_contact_time(cm, g1, g2, speed)
        cap = (1.0 + restitution_of(cm.geoms, g1, g2)) * speed
        b = cm.geoms[g2].body
        if cm.bodies[b].dynamic:
            n = _body_pulses(cm, b, J, point, cap, tau, time_s, (xpos, xmat), mics, rows, dv, n)
        b = cm.geoms[g1].body
        if cm.bodies[b].dynamic:
            n = _body_pulses(cm, b, Jm, point, cap, tau, time_s, (xpos, xmat), mics, rows, dv, n)
    return n


@njit_inner(cache=True)
def pulse_room(ps, k):
    """Whether the rows of :class:`.records.PulseState` ``ps`` hold the pulses of ``k`` more
    impact rows."""
    prm = ps.model.prm[0]
    need = 2 * k * (prm.n_air + ps.model.sites.shape[0])
    return ps.counts[0].n + need <= ps.rows.shape[0]


@njit_inner(cache=True)
def queue_pulses(ps, impacts, k, time_s, views, mics):
    """The pulses of the substep's impacts ``impacts[:k]`` at ``time_s`` [s] appended to the
    waiting rows of ``ps`` (:func:`pulse_room` said they fit), from the body poses ``views.xpos``,
    ``views.xmat`` and the air microphones ``mics[:n_air]``."""
    c = ps.counts[0]
    c.n = impact_pulses(ps.model, impacts, k, time_s, views.xpos, views.xmat, mics, ps.rows, ps.dv, c.n)


@njit_inner(cache=True)
def render_waiting(ps):
    """Render the waiting rows of :class:`.records.PulseState` ``ps`` into its track
    (:func:`mjsound.synth.bandlimited.add_pulses`, in the order they were made) and empty
    them; False, with nothing changed, when the track must grow first (Python renders them,
    :meth:`.clicks.ImpactPulses.flush`)."""
    c = ps.counts[0]
    if c.n == 0:
        return True
    if not add_pulses(ps.track, ps.rows, ps.dv, c.n):
        return False
    c.n = 0
    return True
