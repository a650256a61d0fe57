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

import itertools
import warnings
from collections import deque

import numpy as np

from .bodies import moving_tree_mass
from .contact_types import ContactEvent, ContactFrame, ImpactEvent, ImpactRecord
from .impulses import restitution_of
from .pairs import contact_quantities, rehash
from .records import (BODY, GEOM, HIT, IMPACT, LOG, MISSING, ONSET, PAIR, PAIR_ROW, READER_COUNTS, READER_PARAMS,
                      RECORD, ReaderState, StepBuffers, contact_quantities_of, pair_scratch)
from ..user_frame import user_stacklevel

__all__ = ["ContactReader", "ContactFrame", "ImpactEvent", "ContactEvent", "ImpactRecord"]


class ContactReader:
    """Reads every contact after each ``mj_step`` and turns them into sound events.

    The reader owns the per-pair state (:data:`.records.PAIR` slots), its counters and the
    step buffers; the work is done by the step kernel (:mod:`.step`), whose results
    :meth:`events` shows as objects (a view for diagnostics) and :meth:`events_fast` as
    structured rows. :attr:`impacts` keeps an :class:`ImpactRecord` per impact event.

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
        Contact forces above this are clamped [N] (impulses above ``max_force * 0.01`` N s).
    max_event_s : float
        Longest an impact event is tracked for its ``sum F dt`` [s].
    keep_records : int
        How many :class:`ImpactRecord` to keep (oldest dropped).
    refractory_s, min_apart_s, v_hard : float
        A pair makes at most one impact per ``refractory_s`` [s]; a re-contact after
        ``min_apart_s`` [s] apart, or faster than ``v_hard`` [m/s], is a new impact.
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
        self.geoms = np.zeros(ng, GEOM)
        self.geoms["body"] = model.geom_bodyid
        self.geoms["plane"] = np.asarray(model.geom_type) == mujoco.mjtGeom.mjGEOM_PLANE
        self.geoms["restitution"] = e
        self.geoms["audible"] = 1  # (every impact heard until set_audible says otherwise)
        # moving mass of each body's subtree and of its whole moving tree (inf: welded to the world)
        welded = np.asarray(model.body_weldid) == 0
        self.bodies = np.zeros(model.nbody, BODY)
        self.bodies["root"] = model.body_rootid
        self.bodies["dofnum"] = model.body_dofnum
        self.bodies["dofadr"] = model.body_dofadr
        self.bodies["parent"] = model.body_parentid
        self.bodies["tree_mass"] = np.where(welded, np.inf, np.asarray(model.body_subtreemass))
        self.bodies["root_mass"] = moving_tree_mass(model)
        self.dof_parent = np.asarray(model.dof_parentid, np.int64)
        self.params = np.zeros(1, READER_PARAMS)
        for k, v in (("v_impact", self.v_impact), ("v_hard", self.v_hard), ("min_apart_s", self.min_apart_s),
                     ("refractory_s", self.refractory_s), ("max_event_s", self.max_event_s), ("v_slide", self.v_slide),
                     ("v_roll", self.v_roll), ("max_force", self.max_force), ("max_impulse", self.max_force * 0.01),
                     ("pyramidal", int(model.opt.cone) == int(mujoco.mjtCone.mjCONE_PYRAMIDAL))):
            self.params[0][k] = v
        self._warned = set()
        self._own = None  # (the step driver of events() / events_fast(), nothing sounding: made on first use)
        self.reset()

    # ------------------------------------------------------------------ state
    def reset(self) -> None:
        """Forget all pairs (call after ``mj_resetData`` or a state jump). The arrays are kept
        (cleared in place): the kernel's compiled entry point stays valid."""
        if getattr(self, "_state", None) is None or getattr(self, "buffers", None) is None:
            self.counts = np.zeros(1, READER_COUNTS)
            # plain int64 views of the fields Python reads after every kernel call
            self._n_records, self._n_bad, self._n_huge, self._nslots, self._any_open, self._n_audible = (
                self.counts[k] for k in ("n_records", "n_bad", "n_huge", "nslots", "any_open", "audible"))
            self._pairs = np.zeros(0, PAIR)
            self._hkeys = np.full(0, -1, np.int64)
            self._hvals = np.zeros(0, np.int64)
            self._state = None
            self._alloc_slots(64)
            self.buffers = None
            self.grow(8, 64)
        else:
            self.counts[:] = 0
            self._pairs[:] = 0
            self._hkeys[:] = -1
            self._hvals[:] = 0
        # slot -> its ImpactRecord, open when last synced; records read their sum F dt, steps
        # and duration from the slot state only when read (:attr:`impacts`) or closed by the
        # slot's next onset (its values banked in prev_* by the state machine)
        self._open: dict[int, ImpactRecord] = {}
        self._records = deque(maxlen=self.keep_records)  # (the oldest drop out in O(1))
        # record rows not turned into ImpactRecord yet (most runs never read them: they are
        # made when read, :meth:`_materialize`), and the geoms of the newest impacts
        self._raw: list[tuple] = []
        self._geoms = deque(maxlen=self.keep_records)  # ((g1, g2) of each impact)
        self._n_taken = 0  # (record rows taken from the kernel's buffer since the reset)
        self.n_clamped = 0

    @property
    def n_slots(self) -> int:
        """Pair slots in use (geom pairs seen since the last reset)."""
        return int(self._nslots[0])

    @property
    def step_count(self) -> int:
        """Physics steps counted (read or quiet) since the last reset."""
        return int(self.counts[0]["step"])

    @property
    def sustained_steps(self) -> np.ndarray:
        """Sliding and rolling pair-steps since the last reset, (2,) int64."""
        c = self.counts[0]
        return np.array([c["slide_steps"], c["roll_steps"]], np.int64)

    @property
    def n_impacts(self) -> int:
        """Impact records (impact events) since the last reset, taken or still waiting in the
        kernel's rows."""
        return self._n_taken + int(self._n_records[0])

    @property
    def n_impacts_made(self) -> int:
        """Impacts made since the last reset: the impact events with a positive impulse
        (those the synthesizer is asked to sound), one per geom pair and substep however
        many contact points it has."""
        return int(self.counts[0]["impacts"])

    @property
    def n_audible(self) -> int:
        """Impact records since the last reset with a geom that is heard (:meth:`set_audible`;
        every geom until it is called): a plain int, read once per env step by the wrappers."""
        return int(self._n_audible[0])

    def set_audible(self, audible) -> None:
        """Which geoms' impacts :attr:`n_audible` counts: ``audible`` (ngeom,) bool."""
        a = np.asarray(audible, bool)
        if a.shape != (len(self.geoms),):
            raise ValueError(f"set_audible: {a.shape} flags for {len(self.geoms)} geoms; give one per geom")
        self.geoms["audible"] = a  # (in place: the kernel's state is unchanged)

    @property
    def any_open(self) -> bool:
        """Whether an impact record may be open (quiet steps must then be read)."""
        return bool(self._any_open[0])

    def state(self) -> ReaderState:
        """The reader's arrays for the step kernel (:class:`.records.ReaderState`; a new one
        after the reader grew)."""
        if self._state is None:
            self._state = ReaderState(self.params, self.counts, self.geoms, self.bodies, self.dof_parent, self._hkeys,
                                      self._hvals, self._pairs)
        return self._state

    def _alloc_slots(self, cap) -> None:
        """Room for ``cap`` pair slots (state kept; the table stays at most half full)."""
        n = len(self._pairs)
        pairs = np.zeros(cap, PAIR)
        pairs[:n] = self._pairs
        self._pairs = pairs
        size = 1 << max(7, int(2 * cap - 1).bit_length())
        self._hkeys, self._hvals = rehash(self._hkeys, self._hvals, size)
        self._state = None

    def grow(self, ncon: int, nefc: int = 0) -> None:
        """Room for a step of ``ncon`` contacts (``nefc`` constraint forces when Python copies
        them in): buffers, pair slots, record rows (buffers keep their contents)."""
        nslots = int(self.counts[0]["nslots"])
        if nslots + ncon > len(self._pairs):
            self._alloc_slots(2 * (nslots + ncon))
        b = self.buffers
        nv = len(self.dof_parent)
        cap = 0 if b is None else len(b.geom)
        rcap = 0 if b is None else len(b.records)
        if b is not None and int(self._n_records[0]) + ncon > rcap:
            self.take_records()  # (the rows wait until read or full: taken, they are free again)
        nrec = int(self._n_records[0])
        if b is not None and ncon <= cap and nefc <= len(b.efc) and nrec + ncon <= rcap:
            return
        cap = max(cap, 2 * ncon if ncon > cap else cap, 8)
        rcap = max(rcap, 256, 2 * (nrec + ncon))
        groups, steps = pair_scratch(cap)
        new = StepBuffers(
            geom=np.zeros((cap, 2), np.int32), pos=np.zeros((cap, 3)), frame=np.zeros((cap, 9)),
            efc_address=np.zeros(cap, np.int32), dim=np.zeros(cap, np.int32),
            efc=np.zeros(max(2 * nefc, 64 if b is None else len(b.efc))), rows=np.zeros(cap, PAIR_ROW),
            sustained=np.zeros(cap, PAIR_ROW), hits=np.zeros(cap, HIT), onsets=np.zeros(cap + 1, ONSET),
            impacts=np.zeros(cap, IMPACT), jn=np.zeros((cap, nv)), minv_jt=np.zeros((cap, nv)),
            records=np.zeros(rcap, RECORD), missing=np.zeros(2 * cap, MISSING),
            log=np.zeros(0, LOG) if b is None else b.log, quantities=contact_quantities_of(cap),
            groups=groups, steps=steps)
        if b is not None:
            for old, arr in zip(b, new):
                if arr is not old and isinstance(arr, np.ndarray):  # (the working tuples start afresh)
                    k = min(len(old), len(arr))
                    arr[:k] = old[:k]
        self.buffers = new

    def grow_log(self, n: int) -> None:
        """Room for ``n`` event log entries (the waiting ones kept)."""
        b = self.buffers
        if n > len(b.log):
            log = np.zeros(max(n, 2 * len(b.log), 256), LOG)
            log[: len(b.log)] = b.log
            self.buffers = b._replace(log=log)

    # ------------------------------------------------------------------ results of the kernel
    def take_records(self) -> None:
        """Take the record rows the kernel wrote (they wait in its buffer until read, or until
        the rows are full: :meth:`grow`; made :class:`ImpactRecord` when read, each closing its
        slot's previous record) and report clamped forces (once)."""
        n = int(self._n_records[0])
        if n:
            self.add_records(self.buffers.records[:n])
            self._n_records[0] = 0
            self.counts[0]["clamped"] = 0  # (add_records warned of them)
        if self._n_bad[0] or self._n_huge[0]:
            self._report_forces()

    def report_clamped(self) -> None:
        """Warn (once) of the clamped forces and impulses the kernel counted; the record rows
        wait unless one holds a clamped impulse."""
        if self.counts[0]["clamped"]:
            self.take_records()
        elif self._n_bad[0] or self._n_huge[0]:
            self._report_forces()

    def _report_forces(self) -> None:
        nbad, nhuge = int(self._n_bad[0]), int(self._n_huge[0])
        self._n_bad[0] = self._n_huge[0] = 0
        self.n_clamped += nbad + nhuge
        self._warn_once(
            "force",
            f"mjsound: {nbad} NaN/Inf and {nhuge} huge (> {self.max_force:g} N) contact forces or "
            "velocities clamped (exploding simulation?); reported once",
        )

    def add_records(self, rows: np.ndarray) -> None:
        """Take the impact events' :data:`.records.RECORD` rows (in order). Their
        :class:`ImpactRecord` are made when read (:attr:`impacts`, :meth:`newest_records`):
        each closes its slot's previous record with the sums banked at its onset."""
        if not len(rows):
            return
        self._any_open[0] = 1
        # (a few rows per step: plain tuples cost less than numpy operations on them)
        rows = rows.tolist()
        raw, geoms = self._raw, self._geoms
        for row in rows:
            raw.append(row)
            geoms.append((row[1], row[2]))
            if row[7]:  # clamped
                self.n_clamped += 1
                self._warn_once("impulse", f"mjsound: impact impulse above {self.max_force * 0.01:g} N s clamped; "
                                "reported once")
        self._n_taken += len(rows)
        if len(raw) > 2 * self.keep_records:  # (bounded memory when nobody reads them)
            self._materialize()

    def _materialize(self) -> None:
        """Make the :class:`ImpactRecord` of the rows taken since the last read (only the
        newest ``keep_records`` are kept: an older row only closes its slot's open record)."""
        if not self._raw:
            return
        rows, self._raw = self._raw, []
        records, opened = self._records, self._open
        keep_from = len(rows) - self.keep_records
        for i, (t0, g1, g2, vmax, total, eq, j, _, p_imp, p_steps, p_end) in enumerate(rows):
            old = opened.pop(j, None)
            if old is not None:
                old.impulse_sim, old.steps, old.duration, old.open = p_imp, p_steps, p_end - old.time, False
            if i < keep_from:
                continue  # (never kept: the deque would drop it)
            rec = ImpactRecord(
                time=t0, geom1=g1, geom2=g2, speed=vmax, impulse_pred=total, impulse_sim=0.0, restitution=eq,
                effective_mass=total / ((1.0 + eq) * vmax) if vmax > 0 else 0.0,
            )
            opened[j] = rec
            records.append(rec)

    def newest_geoms(self, n: int) -> list[tuple[int, int]] | None:
        """The geoms ``(g1, g2)`` of the ``n`` newest impacts, newest first; None when the
        reader keeps fewer than ``n`` (``keep_records``)."""
        self.take_records()
        geoms = self._geoms
        if n > len(geoms):
            return None
        return list(itertools.islice(reversed(geoms), int(n)))

    def _warn_once(self, key, msg):
        if key not in self._warned:
            self._warned.add(key)
            warnings.warn(msg, RuntimeWarning, stacklevel=user_stacklevel())

    @property
    def impacts(self) -> list[ImpactRecord]:
        """The last ``keep_records`` impact events' :class:`ImpactRecord`, oldest first (the
        open ones brought up to date)."""
        self.take_records()
        self._materialize()
        pairs = self._pairs
        for j, rec in list(self._open.items()):
            p = pairs[j]
            rec.impulse_sim = float(p["rec_impulse"])
            rec.steps = int(p["rec_steps"])
            rec.duration = float(p["rec_end"] - p["rec_time"])
            if not p["open"]:
                rec.open = False
                del self._open[j]
        return list(self._records)

    def newest_records(self, n: int) -> list[ImpactRecord] | None:
        """The ``n`` newest :class:`ImpactRecord`, newest first, as they were made (open ones
        not brought up to date: geoms, time and predicted impulse are final); None when the
        reader keeps fewer than ``n`` (``keep_records``)."""
        self.take_records()
        self._materialize()
        records = self._records
        if n > len(records):
            return None
        return list(itertools.islice(reversed(records), int(n)))

    # ------------------------------------------------------------------ reading
    def read(self, data) -> ContactFrame | None:
        """All contacts of the last step as a :class:`ContactFrame` (None when there are none)."""
        if data.ncon == 0:
            return None
        n, _ = self.copy_contacts(data)
        b = self.buffers
        con = data.contact
        views = self._driver(data).views
        q = contact_quantities_of(n)  # (the frame's own arrays)
        nbad, nhuge = contact_quantities(b, n, np.ascontiguousarray(data.efc_force), self.state(), views, q)
        fn, normal, vel_rel, vapp, v_slip, v_roll = q.fn, q.nrm, q.vrel, q.vapp, q.vslip, q.vroll
        if nbad or nhuge:
            self.counts[0]["n_bad"] += nbad
            self.counts[0]["n_huge"] += nhuge
            self.take_records()
        return ContactFrame(geom=b.geom[:n].astype(np.int64), pos=b.pos[:n].copy(), normal=normal,
                            dist=np.array(con.dist, dtype=np.float64), force_n=fn, force=fn[:, None] * normal,
                            vel_rel=vel_rel, v_approach=vapp, v_slip=v_slip, v_roll=v_roll)

    def copy_contacts(self, data) -> tuple[int, int]:
        """Copy the step's contacts and constraint forces from the bindings into the buffers
        (where the kernel cannot read the mjData struct itself); returns ``(ncon, nefc)``."""
        n, nefc = int(data.ncon), int(data.nefc)
        self.grow(n, nefc)
        b = self.buffers
        if n:
            con = data.contact
            b.geom[:n] = con.geom
            b.pos[:n] = con.pos
            b.frame[:n] = con.frame
            b.efc_address[:n] = con.efc_address
            b.dim[:n] = con.dim
            b.efc[:nefc] = data.efc_force
        return n, nefc

    @staticmethod
    def local_points(data, cf: ContactFrame) -> np.ndarray:
        """Contact points in each geom's frame, (n, 2, 3) [m]."""
        xpos = np.asarray(data.geom_xpos)[cf.geom]  # (n,2,3)
        xmat = np.asarray(data.geom_xmat)[cf.geom].reshape(-1, 2, 3, 3)
        d = cf.pos[:, None, :] - xpos
        return np.einsum("nkji,nkj->nki", xmat, d)

    def _driver(self, data):
        """The reader's own step driver on ``data`` (:class:`.driver.StepDriver`, nothing sounds)."""
        if self._own is None or self._own.data is not data:
            from .driver import StepDriver

            self._own = StepDriver(self.model, data, self, 1)
        return self._own

    def events_fast(self, data, t0: float | None = None, t1: float | None = None):
        """Read the last step's contacts with the step kernel, nothing sounding.

        Returns
        -------
        impacts : (k,) :data:`.records.IMPACT` array | None
            The step's impacts with a positive impulse (all at ``t0``).
        sustained : (pairs,) :data:`.records.PAIR_ROW` array | None
            The step's sliding and rolling pairs.
        Both are copies.
        """
        dt = float(self.model.opt.timestep)
        t1 = float(data.time) if t1 is None else float(t1)
        t0 = t1 - dt if t0 is None else float(t0)
        driver = self._driver(data)
        driver.substeps(1, False, False, True, (t0, t1, 0, 0))
        self.take_records()
        r = driver.run[0]
        b = self.buffers
        n_imp, ns = int(r["n_imp"]), int(r["n_sust"])
        return (b.impacts[:n_imp].copy() if n_imp else None), (b.sustained[:ns].copy() if ns else None)

    def events(self, data, t0: float | None = None, t1: float | None = None, frame: ContactFrame | None = None):
        """:meth:`events_fast` as objects (a view for diagnostics).

        Parameters
        ----------
        data : mujoco.MjData
            Right after ``mj_step`` (or ``mj_forward`` for replay).
        t0, t1 : float, optional
            The step's time interval [s]; default ``data.time - timestep`` and ``data.time``.
        frame : ContactFrame, optional
            Returned as the third value instead of a fresh :meth:`read` (the events are read
            from ``data`` either way).

        Returns
        -------
        (impacts, contacts, frame) : (list[ImpactEvent], list[ContactEvent], ContactFrame | None)
        """
        dt = float(self.model.opt.timestep)
        t1 = float(data.time) if t1 is None else float(t1)
        t0 = t1 - dt if t0 is None else float(t0)
        cf = frame if frame is not None else (self.read(data) if data.ncon else None)
        imp, sus = self.events_fast(data, t0, t1)
        impacts = []
        if imp is not None:
            for r in imp:
                g1, g2 = int(r["g1"]), int(r["g2"])
                e = float(restitution_of(self.geoms, g1, g2))
                vi = float(r["speed"])
                impacts.append(ImpactEvent(time=t0, geom1=g1, geom2=g2, point=r["point"].copy(),
                                           normal=r["normal"].copy(), impulse=float(r["impulse"]), speed=vi,
                                           effective_mass=float(r["impulse"]) / ((1.0 + e) * vi) if vi > 0 else 0.0))
        contacts = [] if sus is None else [
            ContactEvent("slide" if r["kind"] == 1 else "roll", t0, t1, int(r["g1"]), int(r["g2"]), r["point"].copy(),
                         r["normal"].copy(), float(r["force"]), float(r["speed"])) for r in sus]
        return impacts, contacts, cf
