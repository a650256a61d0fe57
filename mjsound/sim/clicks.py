"""`ImpactPulses`: the rigid-body side of every impact, for air and contact microphones.

Every impact the contact reader finds (a record with fields ``g1``, ``g2``, ``point``,
``normal``, ``impulse``: ``J`` on geom2 along the normal [N s], ``speed``: approach speed
[m/s]) accelerates the bodies of both geoms within the Hertz contact time ``tau``:

* **acceleration noise** (:mod:`mjsound.synth.accel_noise`): each dynamic body of the pair,
  sounding or not, radiates a click to every air microphone, from its centre of mass, as the
  equivalent ellipsoid of its mass and inertia whose velocity changes by ``dv``;
* **contact microphones** (:mod:`mjsound.synth.contact_mic`): a sensor on either body reads
  that body's rigid-body acceleration at its site along its axis; a sensor on any other body
  reads nothing of this impact.

``dv`` of body b: ``J / m_b`` with ``m_b`` its own mass (exact for a free body), and
``dw = I_b^-1 ((p - o_b) x J)``; for a body in an articulated chain, which the rest of the
chain holds back, this over-estimates the change, so ``|dv|`` and ``|dw x arm|`` are each
capped at ``(1 + e) v`` (``v`` the approach speed, ``e`` the pair's restitution: an impact
against an immovable body). The cap is what the impact allows, whatever pushes: a mocap weld or
an actuator pressing on through the contact adds force over the contact's whole duration, not
to the impact's velocity change (``docs/clicks.md``).
Bodies welded to the world and mocap bodies do not move and make no click.

``tau`` is Hertz's, as for the modal excitation: both geoms' acoustic materials (a missing
material counts as rigid), the bodies' subtree masses ``m*`` combined (infinite when welded)
and the geoms' contact radii; when neither geom has a material, both count as
:data:`UNKNOWN_MATERIAL` (ABS: most robot shells and household plastics), so that every click
has a finite duration. A body too light to be solid in its geom's material is a hollow shell,
which bends under the contact (:func:`mjsound.synth.pulse.shell_contact_time`)::

    tau = max(tau_hertz, min(pi sqrt(m* (s1 + s2)), pi R / v))

(``s = 1/k`` per geom [m/N], 0 when solid; ``R`` the smaller shell radius: a wall sinks no
deeper than its radius, ``v tau / pi <= R``.)

:func:`shell_compliances` estimates ``s`` at construction. A body's wall is its mass spread
over its surface, ``t = m_b / (rho A_b)`` (``rho`` the geom's material's density, ``A_b`` and
``V_b`` the summed surface and volume of the body's colliding geoms: a MuJoCo body's mass is
its geoms' volume times their density, so the geoms, not the equivalent ellipsoid, tell its
volume and surface; the ellipsoid of two spheres on a rod is one long ellipsoid far larger
than they are). Where that wall is at most :data:`SHELL_MAX_WALL_RATIO` of both the geom's
radius of curvature ``R`` and the body's thickness ``3 V_b / A_b`` (so at most 30 % of the
body's volume is material), the geom is a thin shell with Reissner's point-load stiffness
``k = 4 E t^2 / (R sqrt(3 (1 - nu^2)))``. Gymnasium's Ant (``density="5"``) in aluminium has
foil walls (70 um ankles, 150 um torso): 8 to 23 ms of contact where solid Hertz gives 72 to
163 us at 3.6 m/s, and its clicks are correspondingly quiet and low. A body of its material's
density (a wall a third of a sphere's radius) stays solid, and its ``tau`` is Hertz's bit for
bit. The modal excitation keeps Hertz's ``tau`` everywhere: the shell time is the clicks' and
the contact microphones' rigid-body pulses' only.

Only impacts call into this module: a step without impacts costs nothing here, and a render
with nothing pending adds nothing (:class:`mjsound.synth.bandlimited.PulseTrack`).
"""

from __future__ import annotations

import math

import numpy as np

from ..materials import get_material
from ..synth import accel_noise
from ..synth.bandlimited import PULSE_DTYPE, PulseTrack, pulse_extent
from ..synth.contact_mic import site_pulse
from ..synth.dispatch import EntryPoint
from ..synth.pulse import compliance, contact_time, shell_compliance
from ..synth.records import TRACK, TrackState
from .bodies import geom_shape_axes, geom_volume_area, quat_mat
from .click_kernels import impact_pulses, pulse_rows_needed
from .records import CLICK_AIR, CLICK_BODY, CLICK_GEOM, CLICK_PARAMS, CLICK_SITE, IMPACT, PULSE_COUNTS, ClickModel, PulseState

__all__ = ["ImpactPulses", "UNKNOWN_MATERIAL", "SHELL_MAX_WALL_RATIO", "shell_compliances",
           "geom_volume_area", "bounded_axes"]

#: Material both sides of an impact count as for the click's duration when neither has one.
UNKNOWN_MATERIAL = "abs"

#: Largest wall-to-radius ratio ``t / R`` [-] of a body treated as a thin shell. Reissner's
#: point-load stiffness is thin-shell theory, which neglects terms of order ``t / R``: ``R / t
#: >= 10`` is its usual bound. Thicker walls keep Hertz's solid contact time; at the bound the
#: two are alike (a wall of a tenth of the radius, aluminium, radii 3 to 25 cm: the shell's
#: time within a factor 1.6 of Hertz's for the same mass at 0.3 to 3.6 m/s), so the switch
#: makes no large jump. A uniform solid sphere has ``t / R = 1/3`` by this measure (its mass
#: over its surface), a long solid capsule ``1/2``; MuJoCo's default density (1000) in
#: aluminium (2700) about 0.12 to 0.19: solid. The same ratio bounds the wall against the
#: body's thickness ``3 V / A`` (a sphere's radius; a thin disc's three half-heights): a solid
#: disc, thin beside its curvature, is no shell.
SHELL_MAX_WALL_RATIO = 0.1

#: Geom types whose contact radius is also the radius of curvature of their wall (sphere,
#: capsule, ellipsoid, cylinder); boxes and meshes use ``3 V / A`` of the geom instead (a
#: sphere's radius from its volume and area: a cube's is its half side).
_CURVED = (2, 3, 4, 5)


def shell_compliances(model, geom_material, geom_radius, dynamic) -> np.ndarray:
    """Point-load compliance [m/N] of each geom's wall where its body is a thin hollow shell,
    0 elsewhere (solid, no material, a body that does not move).

    Parameters
    ----------
    model : mujoco.MjModel
    geom_material : list of Material | None
        Acoustic material per geom (None: none, no shell).
    geom_radius : (ngeom,) array
        Contact radius per geom [m] (the click's: a box's half its largest extent; inf: flat).
    dynamic : (nbody,) bool
        Bodies that move (a shell elsewhere changes nothing: immovable bodies count as rigid).

    Returns
    -------
    (ngeom,) float64 : ``R sqrt(3 (1 - nu^2)) / (4 E t^2)``
    (:func:`mjsound.synth.pulse.shell_compliance`) where the body's wall
    ``t = m_b / (rho A_b)`` is at most :data:`SHELL_MAX_WALL_RATIO` of ``R``, the geom's
    radius of curvature, and of ``3 V_b / A_b``, the body's own thickness
    (a sphere's radius; then ``t <= 0.1 (3 V_b / A_b)`` says ``m_b <= 0.3 rho V_b``: the body
    is mostly hollow, which a solid disc or plate, thin beside its radius of curvature, is
    not). ``V_b`` and ``A_b`` sum the volumes and surfaces of the body's colliding geoms (all
    its geoms when none collides; overlaps count twice). A body with a geom of unknown volume
    (plane, height field) is solid here.
    """
    m = model
    out = np.zeros(m.ngeom)
    if m.ngeom == 0:
        return out
    body = np.asarray(m.geom_bodyid, dtype=np.int64)
    collide = (np.asarray(m.geom_contype) != 0) | (np.asarray(m.geom_conaffinity) != 0)
    shapes = [geom_volume_area(m, g) for g in range(m.ngeom)]
    volume, area = {}, {}
    for b in np.unique(body).tolist():
        mine = np.flatnonzero(body == b)
        counted = mine[collide[mine]] if collide[mine].any() else mine
        if all(shapes[g] is not None for g in counted):
            volume[b] = sum(shapes[g][0] for g in counted)
            area[b] = sum(shapes[g][1] for g in counted)
    for g in range(m.ngeom):
        mat, b = geom_material[g], int(body[g])
        if mat is None or not dynamic[b] or b not in area or shapes[g] is None:
            continue
        mass = float(m.body_mass[b])
        if not (math.isfinite(mass) and mass > 0 and area[b] > 0 and volume[b] > 0):
            continue
        vol, surf = shapes[g]
        if int(m.geom_type[g]) in _CURVED:
            R = float(geom_radius[g])
        else:
            R = 3.0 * vol / surf if surf > 0 else math.inf
        wall = mass / (float(mat.rho) * area[b])
        thin = min(R, 3.0 * volume[b] / area[b]) * SHELL_MAX_WALL_RATIO
        if math.isfinite(R) and R > 0 and wall <= thin:
            out[g] = shell_compliance(mat, wall, R)
    return out


_LOADED = [False]


def _load_kernels() -> None:
    """Compile or load the pulse kernels once per process, when a simulator that will need them
    is made, not at its first impact (a first load from numba's cache, numba's own start included, would
    stall the step of that impact)."""
    if not _LOADED[0]:
        _LOADED[0] = True
        track = PulseTrack(1, 16000)
        pulse = site_pulse(0.001, 1e-4, 0)
        track.add_trusted(pulse, np.ones(1))
        pulse_extent(pulse, np.ones(1), 1, 16000.0)  # (the track's growth)
        track.take_into(np.zeros((1, 64), np.float32))
        track.take(64)
        contact_time(1e-4, 1.0)


def bounded_axes(axes, shape_axes) -> np.ndarray:
    """Semi-axes [m] of a body's equivalent ellipsoid, each at most the same axis of the
    ellipsoid of the body's geoms' own shape (:func:`.bodies.geom_shape_axes`; None or a zero
    axis: no bound there).

    The ellipsoid of a mass and inertia (:func:`mjsound.synth.accel_noise.ellipsoid_from_inertia`)
    is the body's own shape only when the inertia is: MJCF files often give small links a
    rounded-up inertia (MyoSuite's 2-10 g phalanges 1e-4 kg m^2, 0.16-0.35 m ellipsoids around
    capsules of 5-9 mm; robosuite's 10 g finger pads 0.01 kg m^2, 1.58 m), and the click's
    dipole grows with the ellipsoid's volume. The air is pushed by the body's surface, not by
    where its mass sits: no axis reaches beyond the shape's (a hollow body's inertia, its mass
    on the walls, gives a larger ellipsoid than its shape: the shape's is kept too). A uniform
    solid body's inertia is its shape's, and nothing changes."""
    axes = np.asarray(axes, dtype=np.float64).copy()
    if shape_axes is None:
        return axes
    bound = np.asarray(shape_axes, dtype=np.float64)
    ok = np.isfinite(bound) & (bound > 0)
    axes[ok] = np.minimum(axes[ok], bound[ok])
    return axes


def silent_pulse_state() -> PulseState:
    """A :class:`.records.PulseState` of a model without bodies (the same types as an
    :class:`ImpactPulses`' state, for a drive in which nothing makes pulses)."""
    z = np.zeros
    track = TrackState(z(1, TRACK), z((0, 1)), z(0, np.complex128), z(0), z(0, np.complex128))
    return PulseState(ClickModel(z(1, CLICK_PARAMS), z(0, CLICK_BODY), z(0, CLICK_GEOM), z(0, CLICK_SITE),
                                 z(0, CLICK_AIR)),
                      z(0, PULSE_DTYPE), z(0), z(1, PULSE_COUNTS), track)


def click_rows(n_air: int, images=None) -> np.ndarray:
    """The :data:`.records.CLICK_AIR` rows of ``n_air`` air rows whose last ``len(images)`` are
    the image microphones ``images`` (:class:`.images.ImageSet`, None: none): each microphone
    followed by its images, which go to its channel with their click reflection factor and
    join its pulse's window.

    Examples
    --------
    >>> from mjsound.sim.images import ImageSet
    >>> im = ImageSet(np.array([0]), np.zeros((1, 3, 4)), np.ones((1, 6)), np.array([0.5]), ["floor"])
    >>> click_rows(2, im)[["mic", "channel", "gain", "joins"]].tolist()
    [(0, 0, 1.0, 0), (1, 0, 0.5, 1)]
    """
    k = 0 if images is None else len(images)
    a = int(n_air) - k
    if a < 0:
        raise ValueError(f"click_rows: {k} image microphones but only {n_air} air rows")
    out = np.zeros(int(n_air), CLICK_AIR)
    r = 0
    for m in range(a):
        out[r] = (m, m, 1.0, 0)
        r += 1
        for i in range(k):
            if int(images.parent[i]) == m:
                out[r] = (a + i, m, float(images.click[i]), 1)
                r += 1
    if r != n_air:
        raise ValueError("click_rows: an image microphone's parent is not one of the air microphones")
    return out


class ImpactPulses:
    """Clicks at the air microphones and rigid-body pulses at the contact microphones.

    Parameters
    ----------
    model : mujoco.MjModel
    geom_material : list of Material | None
        Acoustic material per geom (None: unknown).
    geom_radius : (ngeom,) array
        Contact radius of curvature per geom [m] (inf: flat).
    n_air : int
        Air microphones (channels ``0 .. n_air - 1``).
    contact_sites : list of int
        Contact microphone sites (channels ``n_air ..``).
    sample_rate : int
        [Hz].
    clicks : bool
        Render acceleration noise at the air microphones.
    speed_of_sound : float
        [m/s].
    active : bool
        False: a stand-in that never has anything pending (a scene whose impacts make no pulses).
    images : mjsound.sim.images.ImageSet, optional
        The last ``len(images)`` air rows are image microphones (:mod:`.images`): a click's
        pulse there goes straight into the parent's channel, times the click's reflection
        factor, rendered in the window of the parent's pulse (one inverse FFT for a click and
        its images, :func:`mjsound.synth.bandlimited.pulse_group`); their own channels get none.
    """

    def __init__(self, model, geom_material, geom_radius, n_air, contact_sites, sample_rate, *, clicks=True,
                 speed_of_sound=accel_noise.SPEED_OF_SOUND, active=True, images=None):
        m = model
        self.model = m
        self.active = bool(active)
        self.n_air = int(n_air)
        self.contact_sites = [int(s) for s in contact_sites]
        self.clicks = bool(clicks)
        self.c = float(speed_of_sound)
        self.track = PulseTrack(self.n_air + len(self.contact_sites), sample_rate)
        self._mat = list(geom_material)
        # a flat-faced geom (box) touches with its edges: half its largest extent, as a sounding
        # object's default radius of curvature (Synthesizer.impacts); planes stay flat
        radius = np.array(geom_radius, dtype=np.float64)
        plane = np.asarray(m.geom_type) == 0  # mjGEOM_PLANE
        half = np.asarray(m.geom_aabb, dtype=np.float64).reshape(-1, 6)[:, 3:].max(axis=1)
        self._radius = np.where(np.isinf(radius) & ~plane & (half > 0), half, radius)
        nb = m.nbody
        self._mass = np.array(m.body_mass, dtype=np.float64)
        self._dynamic = np.array([b > 0 and m.body_weldid[b] != 0 and m.body_mocapid[b] < 0 and self._mass[b] > 0
                                  for b in range(nb)])
        self._hertz_mass = np.array([m.body_subtreemass[b] if m.body_weldid[b] != 0 else np.inf for b in range(nb)])
        self._axes = np.zeros((nb, 3))
        self._masses = np.zeros((nb, 3))  # displaced + added air mass along each axis [kg]
        self._a_eq = np.zeros(nb)
        self._iframe = np.tile(np.eye(3), (nb, 1, 1))  # principal axes in the body frame
        for b in np.flatnonzero(self._dynamic):
            inertia = np.asarray(m.body_inertia[b], dtype=np.float64)
            if inertia.any():
                self._axes[b] = accel_noise.ellipsoid_from_inertia(self._mass[b], inertia)
            else:  # a point mass: a sphere of the density of water
                self._axes[b] = (3 * self._mass[b] / (4 * math.pi * 1000.0)) ** (1 / 3)
            self._axes[b] = bounded_axes(self._axes[b], geom_shape_axes(m, b))
            self._iframe[b] = quat_mat(m.body_iquat[b])
            self._masses[b] = accel_noise.dipole_masses(self._axes[b])
            self._a_eq[b] = accel_noise.equivalent_radius(self._axes[b])
        self._site_body = np.array([m.site_bodyid[s] for s in self.contact_sites], np.int64)
        # each contact microphone's site frame in its body's frame (its axis: the frame's z)
        self._site_frame = np.array([quat_mat(m.site_quat[s]) for s in self.contact_sites]).reshape(-1, 3, 3)
        # the same, as the records the impact kernel reads (click_kernels.impact_pulses)
        bodies = np.zeros(nb, CLICK_BODY)
        bodies["dynamic"] = self._dynamic
        bodies["mass"] = self._mass
        bodies["ipos"] = np.asarray(m.body_ipos, dtype=np.float64).reshape(-1, 3)
        bodies["iframe"] = self._iframe
        bodies["masses"] = self._masses
        bodies["a_eq"] = self._a_eq
        bodies["inertia"] = np.asarray(m.body_inertia, dtype=np.float64).reshape(-1, 3)
        bodies["hertz_mass"] = self._hertz_mass
        geoms = np.zeros(m.ngeom, CLICK_GEOM)
        geoms["body"] = np.asarray(m.geom_bodyid, dtype=np.int64)
        geoms["has_material"] = [mat is not None for mat in self._mat]
        geoms["compliance"] = [compliance(mat) for mat in self._mat]
        geoms["radius"] = self._radius
        geoms["shell_compliance"] = shell_compliances(m, self._mat, self._radius, self._dynamic)
        geoms["restitution"] = [mat.restitution if mat is not None else np.nan for mat in self._mat]
        sites = np.zeros(len(self.contact_sites), CLICK_SITE)
        sites["body"] = self._site_body
        sites["pos"] = np.asarray(m.site_pos, dtype=np.float64).reshape(-1, 3)[self.contact_sites]
        sites["axis"] = self._site_frame[:, :, 2]
        prm = np.zeros(1, CLICK_PARAMS)
        prm[0]["clicks"], prm[0]["n_air"], prm[0]["c"] = int(self.clicks), self.n_air, self.c
        prm[0]["unknown_compliance"] = compliance(get_material(UNKNOWN_MATERIAL))
        self._model = ClickModel(prm, bodies, geoms, sites, click_rows(self.n_air, images))
        self._state = PulseState(self._model, np.zeros(0, PULSE_DTYPE), np.zeros(0), np.zeros(1, PULSE_COUNTS),
                                 self.track.state)
        self._waiting = self._state.counts["n"]  # (a plain int64 view: read after every kernel call)
        self.reserve(8)
        self._impact_pulses = EntryPoint(impact_pulses)
        if self.active:
            _load_kernels()

    def audible_bodies(self) -> np.ndarray:
        """(nbody,) bool: bodies whose impacts this makes heard: each dynamic body (not welded
        to the world, not mocap, with mass) when it clicks at air microphones, and each body
        carrying a contact microphone (a stand-in, ``active=False``: none)."""
        audible = np.zeros(self.model.nbody, bool)
        if self.active and self.clicks and self.n_air:
            audible |= self._dynamic
        audible[self._site_body] = True
        return audible

    @property
    def state(self) -> PulseState:
        """The pulses the step kernel makes (:func:`.click_kernels.queue_pulses`) and the track
        it renders them into (a new tuple after either grew: ask again after any call here)."""
        st = self._state
        if st.track is not self.track.state:
            st = self._state = st._replace(track=self.track.state)
        return st

    @property
    def n_channels(self) -> int:
        return self.track.n_channels

    def reset(self, start: int = 0) -> None:
        """Forget pending pulses; the next sample :meth:`take` returns is ``start``."""
        self._waiting[0] = 0
        self.track.reset(start)

    def reserve(self, k: int) -> None:
        """Room in :attr:`state` for the pulses of ``k`` more impact rows (a new state when the
        rows grow: ask for it again)."""
        need = int(self._waiting[0]) + pulse_rows_needed(k, self.n_air, len(self.contact_sites))
        st = self.state
        if need > len(st.rows):
            cap = max(need, 2 * len(st.rows))
            rows, dv = np.zeros(cap, PULSE_DTYPE), np.zeros(cap)
            n = int(self._waiting[0])
            rows[:n], dv[:n] = st.rows[:n], st.dv[:n]
            self._state = st._replace(rows=rows, dv=dv)

    @property
    def waiting(self) -> int:
        """Pulse rows the step kernel made that :meth:`flush` has not moved to the track yet."""
        return int(self._waiting[0])

    def flush(self) -> None:
        """Render the waiting pulse rows of :attr:`state` into the track (in the order they were
        made: the same sum as rendering each step's pulses as they come). The step kernel does
        this itself after its substeps (:func:`.click_kernels.render_waiting`); Python when the
        rows are full or the track must grow first (reason ``PULSES``)."""
        n = int(self._waiting[0])
        if n:
            self._waiting[0] = 0
            self.track.add_trusted(self.state.rows[:n], self.state.dv[:n])

    def take(self, n: int) -> np.ndarray | None:
        """``(n_air + n_contact, n)`` samples to add to the next ``n`` rendered samples (Pa at
        the air channels, m/s^2 at the contact ones), or None when nothing is pending."""
        return self.track.take(n)

    def mix(self, block: np.ndarray) -> np.ndarray:
        """Add the pending pulses of the next ``block.shape[1]`` samples into ``block``
        (channels, n) in place (nothing to do when none is pending); returns it."""
        if not self.active:
            return block  # (a stand-in: nothing is ever pending)
        if block.dtype == np.float32:
            self.track.take_into(block)  # (one numba call; never NaN audio)
            return block
        extra = self.track.take(block.shape[1])
        if extra is not None:
            if not np.isfinite(extra).all():  # (never NaN audio; checking costs less than nan_to_num on every block)
                extra = np.nan_to_num(extra, nan=0.0, posinf=0.0, neginf=0.0)
            block += extra.astype(block.dtype)
        return block

    def add(self, impacts: np.ndarray, time_s: float, data, mic_positions) -> None:
        """Pulses of a step's impacts.

        Parameters
        ----------
        impacts : (k,) structured array
            The step's impacts: fields ``g1``, ``g2``, ``point`` (3,) [m], ``normal`` (3,)
            (from geom1 to geom2), ``impulse`` on geom2 along the normal [N s] (geom1 gets the
            opposite) and ``speed`` [m/s].
        time_s : float
            Their time on the output's clock [s] (sample n at n / fs).
        data : mujoco.MjData
            Poses of the bodies at the impact (``xpos``, ``xmat``: right after the ``mj_step``
            that found the contacts they are those of the step's start, as the contacts).
        mic_positions : (n_air, 3) array
            Air microphones (world) [m].
        """
        if not (self.active and len(impacts)) or not (self.clicks and self.n_air or self.contact_sites):
            return
        imp = np.ascontiguousarray(impacts, dtype=IMPACT)
        mics = np.ascontiguousarray(mic_positions, dtype=np.float64).reshape(-1, 3)
        self.flush()
        self.reserve(len(imp))
        st = self.state
        self._waiting[0] = self._impact_pulses((self._model,), imp, len(imp), float(time_s), np.asarray(data.xpos),
                                               np.asarray(data.xmat), mics, st.rows, st.dv, 0)
        self.flush()  # (every pulse of the step, rendered in one call)
