"""`AudioSimulator`: the per-step driver, MuJoCo contacts -> synthesizer -> audio blocks.

Time alignment
--------------
Sample ``n`` belongs to simulation time ``n / fs``. The step that advances the simulation
from ``t_k`` to ``t_{k+1}`` returns exactly the samples with ``t_k <= n/fs < t_{k+1}``, i.e.
``n`` from ``ceil(t_k fs)`` to ``ceil(t_{k+1} fs) - 1``. The boundaries are computed in
exact integer arithmetic: the timestep and the start time are turned into fractions
(``Fraction.limit_denominator(10**9)``, which recovers 1/1000, 7/10000, 1/3000 ... exactly)
and ``t_k = t_start + k * dt`` is never accumulated in floating point, so the total over a
run of ``T`` seconds is ``ceil(T fs)`` (``= round(T fs)`` whenever ``T fs`` is an integer,
e.g. any whole number of milliseconds at 48 kHz) with no drift over hours. If ``data.time``
jumps (the user reset it, or changed the timestep) the clock re-anchors at the new time.

Events found in the step ``[t_k, t_{k+1})`` are timed at ``t_k`` (see
:mod:`mjsound.sim.contacts`), which is never earlier than what was already rendered, so the
block is rendered right after they are queued and nothing is delayed.

Rendering can wait: ``step(render=False)`` queues a step's impacts and sustained-contact
noise (generated at once, :mod:`.drive`) and :meth:`AudioSimulator.flush` renders every
pending sample in one synthesizer call. Impacts sound exactly the same; a sliding contact's
gains (where it excites the object, how far the microphones are) follow its point once per
render instead of every ``sustained_block_s``.
"""

from __future__ import annotations

import math
import os
import time as _time
import warnings
from fractions import Fraction

import numpy as np

from .contacts import (I_G1, I_G2, I_IMPULSE, R_COLS, R_FORCE, R_G1, R_G2, R_KIND, R_NORMAL, R_POINT, R_SLOT, R_SPEED,
                       ContactReader)
from .drive import drive_rows, follow_rows, impacts_to_synth, pose_rows, read_and_drive
from .fused import DONE, PYTHON_AFTER, PYTHON_STEP, mj_function_address, mjdata_layout, run_substeps
from .scene import SoundScene, geom_contact_radius

__all__ = ["AudioSimulator", "SampleClock"]


class SampleClock:
    """Maps physics steps to sample ranges exactly (no floating-point drift).

    Parameters
    ----------
    sample_rate : int
        Samples per second (integer) [Hz].
    timestep : float
        Physics step [s].
    t_start : float
        Simulation time of the first step's start [s].
    """

    def __init__(self, sample_rate: int, timestep: float, t_start: float = 0.0):
        self.fs = int(sample_rate)
        if self.fs != sample_rate or self.fs <= 0:
            raise ValueError(f"sample_rate must be a positive integer, got {sample_rate}")
        self.anchor(timestep, t_start)

    def anchor(self, timestep: float, t_start: float) -> None:
        """Restart counting from ``t_start`` with step ``timestep``."""
        if not (np.isfinite(timestep) and timestep > 0):
            raise ValueError(f"timestep must be positive, got {timestep}")
        self.timestep = float(timestep)
        self.t_start = float(t_start)
        dt = Fraction(self.timestep).limit_denominator(10**9)
        t0 = Fraction(self.t_start).limit_denominator(10**9)
        den = dt.denominator * t0.denominator // _gcd(dt.denominator, t0.denominator)
        self._den = den
        self._a0 = t0.numerator * (den // t0.denominator)
        self._b = dt.numerator * (den // dt.denominator)
        self.k = 0
        self.n = self.sample_at(0)
        # last step whose start time and first sample fit int64 exactly (a0 + k b < 2^53 and
        # (a0 + k b) fs < 2^62): .fused counts steps in numba up to there
        self.k_max_int64 = (min(2**53, 2**62 // self.fs) - abs(self._a0)) // self._b - 1

    def sample_at(self, k: int) -> int:
        """First sample at or after ``t_start + k * timestep``: ``ceil(t fs)``."""
        num = (self._a0 + k * self._b) * self.fs
        return -((-num) // self._den)

    def time_at(self, k: int) -> float:
        """``t_start + k * timestep`` [s] (float, for reporting)."""
        return (self._a0 + k * self._b) / self._den  # int / int: correctly rounded, as float(Fraction)

    def advance(self, steps: int = 1) -> tuple[int, int]:
        """Count ``steps`` steps; returns ``(n0, n1)``, their samples ``n0 <= n < n1``."""
        n0 = self.n
        self.k += steps
        self.n = self.sample_at(self.k)
        return n0, self.n


def _gcd(a: int, b: int) -> int:
    import math

    return math.gcd(a, b)


def _same_args(a, b) -> bool:
    """Arrays the same objects, other values equal, through tuples and lists."""
    if isinstance(a, (tuple, list)):
        return isinstance(b, type(a)) and len(a) == len(b) and all(_same_args(x, y) for x, y in zip(a, b))
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return a is b
    return a == b


class AudioSimulator:
    """Sound for a running MuJoCo simulation, one audio block per physics step.

    Parameters
    ----------
    model : mujoco.MjModel | str
        The model (or an MJCF path).
    data : mujoco.MjData, optional
        Its data (created when omitted).
    scene : SoundScene, optional
        A prepared scene; built with :meth:`SoundScene.from_model` otherwise.
    sample_rate : int
        Audio sample rate [Hz].
    materials, microphones, budget_modes, quality, progress
        Passed to :meth:`SoundScene.from_model` when ``scene`` is None.
    synth_kwargs : dict, optional
        Extra keyword arguments for :class:`mjsound.synth.synthesizer.Synthesizer`.
    reader_kwargs : dict, optional
        Extra keyword arguments for :class:`ContactReader` (thresholds).
    sustained : bool
        Drive sliding and rolling sound (default True).
    keep_events : int
        :attr:`event_log` keeps the first this many events.
    sustained_block_s : float
        A sliding / rolling contact's gains follow its point at most this often [s].
    render_block_s : float
        :meth:`run` and :meth:`advance` render once per this much simulated time [s]
        (default 10 ms: one synthesizer call per 10 steps of 1 ms, which is most of the
        per-step cost saved; 0 renders every step). :meth:`step` renders every call unless
        told otherwise.

    Notes
    -----
    Call :meth:`step` right after every ``mj_step`` (or let :meth:`advance` / :meth:`run` do
    the stepping). Each call returns ``(channels, n)`` float32 pascals: exactly the samples
    of the step just taken. ``events`` counts what was emitted.

    Examples
    --------
    >>> sim = AudioSimulator(model, data)            # doctest: +SKIP
    >>> for _ in range(1000):                         # doctest: +SKIP
    ...     mujoco.mj_step(model, data)
    ...     block = sim.step()
    """

    def __init__(
        self,
        model,
        data=None,
        scene: SoundScene | None = None,
        sample_rate: int = 48000,
        materials: dict | None = None,
        microphones=None,
        budget_modes: int | None = None,
        quality: str = "default",
        progress: bool = True,
        synth_kwargs: dict | None = None,
        reader_kwargs: dict | None = None,
        sustained: bool = True,
        keep_events: int = 100_000,
        sustained_block_s: float = 0.004,
        render_block_s: float = 0.01,
        fused: bool = True,
    ):
        import mujoco

        self._mj = mujoco
        if not isinstance(model, mujoco.MjModel):
            if scene is not None:
                model = scene.model
            else:
                model = mujoco.MjModel.from_xml_path(os.fspath(model))
        self.model = model
        self.data = data if data is not None else mujoco.MjData(model)
        self._opt = model.opt  # (a view into the model: timestep changes show through it)
        # fixed-size MjData arrays read every step: their numpy views stay valid
        self._geom_xpos, self._geom_xmat = self.data.geom_xpos, self.data.geom_xmat
        self._xpos, self._site_xpos = self.data.xpos, self.data.site_xpos
        if scene is None:
            scene = SoundScene.from_model(
                model,
                materials=materials,
                microphones=microphones,
                budget_modes=budget_modes,
                sample_rate=sample_rate,
                quality=quality,
                progress=progress,
            )
        self.scene = scene
        self.sample_rate = int(sample_rate)
        self.sustained = bool(sustained)
        self.keep_events = int(keep_events)
        self.sustained_block_s = float(sustained_block_s)
        self.render_block_s = float(render_block_s)
        if not (math.isfinite(self.render_block_s) and self.render_block_s >= 0):
            raise ValueError(f"render_block_s={render_block_s!r} must be a duration >= 0 in seconds")
        restitution = [m.restitution if m is not None else None for m in scene.geom_material]
        self.reader = ContactReader(model, restitution=restitution, **(reader_kwargs or {}))
        self._sounding = scene.by_geom()
        self._names = {g: s.name for g, s in self._sounding.items()}
        self._radius = np.array([geom_contact_radius(model, g) for g in range(model.ngeom)])
        m = model
        self._other_mass = np.array(
            [m.body_subtreemass[m.geom_bodyid[g]] if m.body_weldid[m.geom_bodyid[g]] != 0 else np.inf for g in range(m.ngeom)]
        )
        self.n_channels = max(1, len(scene.mic_positions))
        self.synth = None
        if not np.any(np.asarray(self.data.geom_xmat)):
            mujoco.mj_kinematics(model, self.data)  # poses for add_object (state is unchanged)
        if scene.sounding:
            from ..synth import synthesizer as _sy
            from ..synth.synthesizer import Synthesizer

            self._rough = np.array([_sy.SLIDE_ROUGHNESS, _sy.ROLL_ROUGHNESS])
            self._length = np.array([_sy.SLIDE_GRAIN_M, _sy.ROLL_PATCH_M])

            kw = dict(synth_kwargs or {})
            self.synth = Synthesizer(sample_rate=self.sample_rate, microphones=np.asarray(scene.mic_positions), **kw)
            for s in scene.sounding:
                self.synth.add_object(
                    s.name,
                    s.model,
                    position=np.array(self.data.geom_xpos[s.geom_id]),
                    rotation=np.array(self.data.geom_xmat[s.geom_id]).reshape(3, 3),
                )
            self.synth.on_regain = self._sync_poses
        # synth object index of each geom (-1: silent, or no modes to drive), and the moving
        # objects with their geoms
        self._geom_obj = np.full(model.ngeom, -1, np.int64)
        moving = {}
        if self.synth is not None:
            for g, s in self._sounding.items():
                ob = self.synth._objects[s.name]
                if s.dynamic:
                    moving[ob.index] = g
                if len(ob.keep):
                    self._geom_obj[g] = ob.index
        self._dyn_idx = np.array(sorted(moving), np.int64)
        self._dyn_geoms = np.array([moving[i] for i in self._dyn_idx.tolist()], np.int64)
        self._follow = None
        self._mic_sites = np.asarray(scene.mic_site_ids, np.int64)
        self._no_mic_rows = np.zeros(0, np.int64)
        self._sites_move = bool(scene.mic_site_ids) and scene.mics_move
        self._zero_offsets = np.zeros((len(self._mic_sites), 3))
        # Hertz coefficient of (struck sounding geom, other geom), NaN until first needed
        self._coef_row = np.cumsum(self._geom_obj >= 0) - 1
        self._coef = np.full((int((self._geom_obj >= 0).sum()), model.ngeom), np.nan)
        # substeps in one numba call (.fused) where this MuJoCo build's struct layout and C
        # functions check out (else every substep runs through Python, as with fused=False)
        self._fused_layout = None
        if fused and os.environ.get("MJSOUND_FUSED", "1") != "0":
            try:
                self._fused_step, self._fused_solve = mj_function_address("mj_step"), mj_function_address("mj_solveM")
                self._fused_m, self._fused_d = self.model._address, self.data._address
                self._fused_layout = mjdata_layout()
            except (OSError, TypeError, KeyError, AttributeError) as e:
                warnings.warn(f"mjsound: substeps run through Python ({e})", RuntimeWarning, stacklevel=2)
        self._fused_anchor = None
        self._fused_key = None
        self._fused_check = os.environ.get("MJSOUND_FUSED_CHECK") == "1"
        self._fused_ints = np.zeros(17, np.int64)  # clock (6), reader state (6), queue (3), queue room (2)
        self._fused_floats = np.zeros(2)
        self._fused_views = tuple(self._fused_ints[a:b] for a, b in ((0, 6), (6, 12), (12, 15), (15, 17)))
        self._log_rows = np.zeros((256, R_COLS))  # sustained rows logged in numba, and their times
        self._log_t = np.zeros(256)
        self._no_streams = {"SF": np.zeros((0, 9)), "SI": np.zeros((0, 9), np.int64),
                            "D": np.zeros((0, self.n_channels), np.int64), "ring": np.zeros((0, 1))}
        self._fused_buf = None
        self.reset(clear_reader=True)

    # ------------------------------------------------------------------ state
    def reset(self, clear_reader: bool = True) -> None:
        """Silence all ringing, forget contact state and re-anchor the clock at ``data.time``
        (a following listener moves to its body's current position)."""
        if self.synth is not None:
            self.synth.reset()
            if self._follow is not None:
                self._update_mics()
        if clear_reader:
            self.reader.reset()
        self.clock = SampleClock(self.sample_rate, float(self.model.opt.timestep), float(self.data.time))
        self._origin = self.clock.n  # synth sample 0 is absolute sample n = origin
        self._n_impacts = 0
        self._sustained_base = self.reader.sustained_steps.copy()
        # event log: entries and per-step arrays of sustained rows, expanded when read (event_log)
        self._log = []
        self._log_pending = []
        self._n_logged = 0
        self.samples = 0
        self.steps = 0
        #: optional observer ``on_block(sim, block, n0)`` called with every step's audio block
        #: and its first absolute sample index (e.g. :class:`mjsound.rerun_log.RerunLogger`)
        self.on_block = None
        self.seconds_contacts = 0.0
        self.seconds_synth = 0.0
        self.seconds_fused = 0.0  # substeps run by .fused (mj_step included)
        self._pending = 0  # samples stepped but not rendered yet (step(render=False))
        self._pending_n0 = self.clock.n
        self._sidx = np.full((16, 2), -1, np.int64)
        self._sidx_epoch = None
        self._regain = max(1, int(round(self.sustained_block_s * self.sample_rate)))

    # ------------------------------------------------------------------ stepping
    def _reanchor_clock(self) -> None:
        """``data.time`` or the timestep no longer match the count (:meth:`step` checks):
        restart counting at this step. The synthesizer keeps counting where it stopped, so
        absolute samples are re-mapped onto it."""
        c = self.clock
        n_prev = c.n
        dt = float(self._opt.timestep)
        c.anchor(dt, float(self.data.time) - dt)
        self._origin += c.n - n_prev

    def follow(self, body: int, offsets) -> None:
        """Move the microphones with ``body`` (translation only): microphone m sits at
        ``data.xpos[body] + offsets[m]``, updated whenever an event needs the positions
        (an impact, or a sustained contact's gains). ``body=None`` stops following."""
        if body is None:
            self._follow = None
            return
        off = np.asarray(offsets, np.float64).reshape(-1, 3)
        if not 0 <= int(body) < self.model.nbody:
            raise ValueError(f"follow: body {body} does not exist (the model has {self.model.nbody} bodies)")
        if len(off) != self.n_channels or not np.isfinite(off).all():
            raise ValueError(f"follow: give {self.n_channels} finite (x, y, z) offsets [m], one per microphone; "
                             f"got {len(off)}")
        self._follow = (int(body), off)
        self._follow_rows = np.full(len(off), int(body))

    def step(self, render: bool = True) -> np.ndarray | None:
        """Process the step just taken by ``mj_step``; return its audio block.

        Parameters
        ----------
        render : bool
            False: read the step's contacts and queue its sound, but render later (in
            :meth:`flush`, one synthesizer call for many steps: e.g. once per env step of a
            gymnasium env with ``frame_skip``). The step returns None then. The audio is the
            same except that a sliding contact's gains follow its point once per render.

        Returns
        -------
        (channels, n) float32 array | None
            Sound pressure at each microphone [Pa] for the samples ``t_k <= n/fs < t_{k+1}``
            (with ``render=True``: the samples of earlier unrendered steps come first).
        """
        # (the per-physics-step path: kept flat, it runs ~10^4 times per simulated second)
        c = self.clock
        dt = c.timestep
        if self._opt.timestep != dt or abs(self.data.time - (c.t_start + (c.k + 1) * dt)) > 0.25 * dt:
            self._reanchor_clock()
        n0, n1 = c.advance()
        return self._process(n0, n1, render=render)

    def substeps(self, nstep: int) -> None:
        """``mj_step`` then :meth:`step` ``(render=False)``, ``nstep`` times (a gymnasium env's
        ``frame_skip``); the audio comes from :meth:`flush`.

        The substeps run in one numba call (:mod:`.fused`: ``mj_step`` called from numba,
        the reader's, the drive's and the impacts' kernels after each) whenever this
        simulator can (``fused=True``, the clock fits 64-bit integers); a substep that needs
        Python (a new sliding pair, a Hertz coefficient not known yet, ...) is finished here
        and the call goes on. The result is the same as the loop in Python, bit for bit."""
        done, nstep = 0, int(nstep)
        if self.synth is not None:
            self.synth.poses_current = False
        while done < nstep:
            args = self._fused_args(nstep - done)
            if args is None:
                for _ in range(nstep - done):
                    self._mj.mj_step(self.model, self.data)
                    self.step(render=False)
                return
            tc = _time.perf_counter()
            i, code, out, imp = run_substeps(*args)
            self.seconds_fused += _time.perf_counter() - tc
            self._count_fused(i)
            done += i + (code != DONE)
            self.synth.poses_current = code == DONE  # (run_substeps syncs them after its last substep)
            if code == PYTHON_STEP:
                self.step(render=False)
            elif code != DONE:
                self._finish_fused(code, out, imp)

    def _fused_args(self, nstep: int) -> list | None:
        """:func:`.fused.run_substeps`'s arguments for the next ``nstep`` substeps, or None
        when they must run in Python.

        The list is built again only when an array it holds was replaced (a buffer grew, the
        streams or the voice layout were rebuilt...: the ``key`` of their identities); else
        only its few changing values are set (building it cost 8 us per call, 18 us in the
        env loop where MuJoCo's step has just evicted these objects from the caches).
        ``MJSOUND_FUSED_CHECK=1`` compares every call with a fresh build (the tests do)."""
        synth, c = self.synth, self.clock
        if self._fused_layout is None or synth is None or not self.sustained:
            return None
        if c.k + nstep > c.k_max_int64 or self._opt.timestep != c.timestep:
            return None  # (numba counts steps in int64, exact as SampleClock)
        r = self.reader
        if self._sidx_epoch != synth._st_epoch:  # the synthesizer forgot its streams
            self._reset_sidx()
        # impacts: the voice layout up to date, room in the event queue for one substep's
        # impacting contacts (2 sides each, every microphone; Synthesizer._impact_queue)
        q = synth._impact_queue(len(r._rows_buf))
        key = (id(r._SF), id(r._rows_buf), id(r.sustained_steps), id(r._params), id(r.record_buffer), id(self._sidx),
               id(synth._st), id(synth._gain_data), id(synth._poses.pos), id(synth._mics), id(q.I), id(q.re),
               id(self._follow))
        if key != self._fused_key:
            self._fused_key, self._fused_list = key, self._fused_build()  # (the list keeps the ids unique)
        args = self._fused_list
        args[4], args[8] = nstep, self._n_logged < self.keep_events
        args[self._fused_at_rendered] = synth.samples_rendered
        consts = args[self._fused_at_consts]
        args[self._fused_at_consts] = consts[:4] + (synth.samples_rendered, consts[5])
        # clock, reader state, queue state and queue room: views of one int64 vector (the
        # clock's anchor and the room change rarely: set when they do)
        ints = self._fused_ints
        anchor = (c._a0, c._b, c._den, c.fs, self._origin, synth.n_channels, synth._nmax, c.t_start, c.timestep)
        if anchor != self._fused_anchor:
            a0, b, den, fs, origin, M, nmax, t_start, dt = self._fused_anchor = anchor
            ints[[0, 1, 2, 3, 5, 15, 16]] = (a0, b, den, fs, origin, 2 * M, 2 * M * nmax)
            self._fused_floats[:] = (t_start, dt)
        ints[4], ints[6], ints[7], ints[8], ints[9], ints[10], ints[11] = c.k, r._nslots, r._any_open, r._step, 0, 0, 0
        ints[12], ints[13], ints[14] = q.count, q.pool_used, q.next_sample
        if self._fused_check:
            fresh = self._fused_build()
            fresh[4], fresh[8] = args[4], args[8]
            if not _same_args(args, fresh):
                raise AssertionError("AudioSimulator._fused_args: the cached arguments are stale")
        return args

    def _fused_build(self) -> list:
        """The arguments of :func:`.fused.run_substeps` (``nstep`` and ``want_log`` are set by
        :meth:`_fused_args`)."""
        synth, r = self.synth, self.reader
        reader_args, missing = r.state_args(self.data)
        cap = len(reader_args[-4])
        if self._fused_buf is None or len(self._fused_buf[0]) != cap:
            self._fused_buf = (np.empty((cap, 2), np.int32), np.empty((cap, 3)), np.empty((cap, 9)),
                               np.empty(cap, np.int32), np.empty(cap, np.int32))
        q = synth._ev
        clk, st, qs, room = self._fused_views
        g = synth._impact_data()
        head = [self._fused_step, self._fused_m, self._fused_d, self._fused_layout, 0, clk, self._fused_floats, st,
                False, *reader_args]
        stream = self._stream_args()
        self._fused_at_rendered = len(head) + 6  # (synth.samples_rendered in _stream_args)
        body = [*stream, missing, *self._fused_buf, self._fused_solve, *r.impact_args(self.data),
                *self._mic_args(), self._geom_xmat, self._dyn_geoms, self._dyn_idx, synth._poses.pos, synth._poses.R,
                self._coef_row, self._coef, g[:9]]
        self._fused_at_consts = len(head) + len(body)  # (speed of sound ... samples rendered, grid)
        return head + body + [g[12:], q.I, q.kind, q.re, q.im, qs, room, self._log_rows, self._log_t]

    def _mic_args(self) -> tuple:
        """Where the microphones are synced from, ``(mode, source, rows, offsets, mics)``:
        ``mics[m] = source[rows[m]] + offsets[m]`` (:func:`.drive.follow_rows`, here and in
        numba) when ``mode`` is 1; mode 0: they stay."""
        mics = self.synth._mics
        if self._follow is not None:
            return int(len(mics) == len(self._follow_rows)), self._xpos, self._follow_rows, self._follow[1], mics
        if self._sites_move and len(mics) == len(self._mic_sites):
            return 1, self._site_xpos, self._mic_sites, self._zero_offsets, mics
        return 0, self._xpos, self._no_mic_rows, self._zero_offsets, mics

    def _count_fused(self, m: int) -> None:
        """Take over the state of :func:`.fused.run_substeps` after it finished ``m`` substeps
        (and made the impacts of the next one, if it did)."""
        r = self.reader
        nslots, any_open, r._step, n_rec, n_imp, n_log, q_count, q_used, q_next = self._fused_ints[6:15].tolist()
        r._nslots, r._any_open = nslots, bool(any_open)
        if n_rec:
            r.add_records(r.record_buffer[:n_rec])
            self._n_impacts += n_imp
        if n_log:  # one event log entry per substep, as _queue_outputs makes them
            rows, ts = self._log_rows[:n_log].copy(), self._log_t[:n_log]
            cuts = [0, *(np.flatnonzero(np.diff(ts)) + 1).tolist(), n_log]
            for a, b in zip(cuts[:-1], cuts[1:]):
                self._log_pending.append((float(ts[a]), "sustained", rows[a:b]))
            self._n_logged += n_log
        q = self.synth._ev
        q.count, q.pool_used, q.next_sample = q_count, q_used, q_next
        if m:
            self._count(*self.clock.advance(m), m)

    def _finish_fused(self, code, out, imp) -> None:
        """Finish the substep that :func:`.fused.run_substeps` read but left to Python (its
        kernel outputs ``out``): with ``PYTHON_AFTER`` make its impacts, with ``PYTHON_DRIVE``
        queue the impacts ``imp`` that numba could not; then drive what needs new streams."""
        c = self.clock
        n0, n1 = c.advance()
        self._count(n0, n1)
        t0 = c.time_at(c.k - 1)
        r = self.reader
        if code == PYTHON_AFTER:
            impacts, rows = r.kernel_outputs(out, self.data, t0)
        else:
            r.drive_result = (r._missing_buf[: out[7]], out[8])
            impacts = imp if len(imp) else None
            rows = r._srows_buf[: out[1]] if out[1] else None
        self._queue_outputs(impacts, rows, t0, n0, n1, True, logged=code != PYTHON_AFTER)

    def flush(self) -> np.ndarray:
        """Render the samples of the steps taken with ``step(render=False)`` (possibly none):
        ``(channels, n)`` float32 pressure [Pa]."""
        return self._render_pending()

    def _process(self, n0: int, n1: int, t0: float | None = None, t1: float | None = None,
                 render: bool = True) -> np.ndarray | None:
        """Count the step of samples ``[n0, n1)`` (times ``t0, t1``: default from the clock),
        queue its sound, and render what is pending if ``render``."""
        self._count(n0, n1)
        if self.synth is not None:
            self.synth.poses_current = False  # (a physics step was taken)
            if not self.reader.step_if_quiet(self.data):
                self._queue(n0, n1, t0, t1)
        return self._render_pending() if render else None

    def _count(self, n0: int, n1: int, steps: int = 1) -> None:
        """Count ``steps`` physics steps of samples ``[n0, n1)``, not rendered yet."""
        if self._pending == 0:
            self._pending_n0 = n0
        self._pending += n1 - n0
        self.steps += steps
        self.samples += n1 - n0

    def _render_pending(self) -> np.ndarray:
        n, n0 = self._pending, self._pending_n0
        self._pending = 0
        self._pending_n0 = self.clock.n
        if self.synth is None:
            block = np.zeros((self.n_channels, n), dtype=np.float32)
        else:
            tc = _time.perf_counter()
            block = self.synth.render(n)  # (never NaN: the synthesizer zeroes non-finite samples)
            self.seconds_synth += _time.perf_counter() - tc
        if self.on_block is not None:
            self.on_block(self, block, n0)
        return block

    def _update_mics(self) -> None:
        """Microphones to where their sites / the followed body are now (nothing when they
        cannot move)."""
        mode, source, rows, offsets, mics = self._mic_args()
        if mode:  # (mics updated in place; a non-finite position keeps the last)
            follow_rows(source, rows, offsets, mics)

    def _sync_poses(self) -> None:
        """Microphones and every moving sounding object to where they are now, before an
        event needs them (impacts; ``Synthesizer.on_regain`` for the streams' gains). An
        exploding simulation's non-finite poses are skipped: those keep the last good one."""
        self._update_mics()
        if len(self._dyn_idx):
            poses = self.synth._poses
            pose_rows(self._geom_xpos, self._geom_xmat, self._dyn_geoms, self._dyn_idx, poses.pos, poses.R)

    def _queue(self, n0: int, n1: int, t0: float | None = None, t1: float | None = None) -> None:
        """Read the step's contacts (something touches, or an impact is open) and queue its
        impacts and sustained drives (sounding scenes only)."""
        reader = self.reader
        if t0 is None:
            c = self.clock
            t0 = c.time_at(c.k - 1)
            t1 = c.time_at(c.k)
        tc = _time.perf_counter()
        drive = None
        if self.synth._st is not None and self.sustained and n1 > n0:
            # read the contacts and drive the existing streams in one numba call
            drive = (read_and_drive, self._drive_args(n0, n1))
        impacts, rows = reader.events_fast(self.data, t0, t1, drive)
        t_read = _time.perf_counter()
        self.seconds_contacts += t_read - tc
        self._queue_outputs(impacts, rows, t0, n0, n1, drive is not None)
        self.seconds_synth += _time.perf_counter() - t_read

    def _queue_outputs(self, impacts, rows, t0, n0, n1, driven: bool, logged: bool = False) -> None:
        """Queue what the reader found in a step (``driven``: its kernel drove the streams
        it could, :attr:`ContactReader.drive_result` says what is left; ``logged``: the rows
        are in the event log already)."""
        reader = self.reader
        nblock = n1 - n0
        if impacts is not None:
            self._queue_impacts(impacts, t0, n0)
        if rows is not None and not logged and self._n_logged < self.keep_events:
            self._log_pending.append((t0, "sustained", rows.copy()))  # (rows: the reader's buffer)
            self._n_logged += len(rows)
        if rows is not None and self.sustained and nblock:
            done = reader.drive_result if driven else None
            if done is None:
                self._drive(rows, n0, n1)
            elif done[1] or len(done[0]):  # a ring too short, or pairs without a stream yet
                self._drive(rows, n0, n1, done)

    def _queue_impacts(self, imp, t0, n0) -> None:
        """Queue the step's impacts (rows of :meth:`ContactReader.events_fast`, columns ``I_*``):
        every sounding side of every row in one synthesizer call, with its Hertz pulse length
        (coefficient cached per struck/other geom pair)."""
        synth = self.synth
        fs = self.sample_rate
        # synth time of the step start (never before what the synthesizer has rendered)
        t_ev = max(t0 - self._origin / fs, (n0 - self._origin) / fs)
        self._sync_poses()
        self._n_impacts += len(imp)
        if self._n_logged < self.keep_events:
            self._log_pending.append((t0, "impact", imp))
            self._n_logged += len(imp)
        q = synth._impact_queue(2 * len(imp))
        while True:
            *out, missing = impacts_to_synth(imp, self._geom_obj, self._coef_row, self._coef, t_ev,
                                             *synth._impact_data(), q.I, q.kind, q.re, q.im, q.count, q.pool_used)
            if not len(missing):
                break
            for g, other in missing.tolist():
                self._coef[self._coef_row[g], other] = self._hertz_coef(g, other)
        synth._commit_impacts(*out, struck=lambda: self._geom_obj[imp[:, I_G1:I_G2 + 1].astype(np.int64).ravel()])

    def _hertz_coef(self, g, other) -> float:
        """Hertz coefficient of sounding geom ``g`` struck by geom ``other``."""
        synth = self.synth
        ob = synth._objects[self._names[g]]
        return synth._hertz_coef(ob, self.scene.geom_material[other], float(self._other_mass[other]),
                                 float(self._radius[other]), float(self._radius[g]) if np.isfinite(self._radius[g]) else None)[0]

    def _reset_sidx(self) -> None:
        """The synthesizer forgot its streams (reset, microphones changed): forget their indices."""
        self._sidx = np.full((16, 2), -1, np.int64)
        self._sidx_epoch = self.synth._st_epoch

    def _drive_args(self, n0, n1) -> tuple:
        """The arguments of :func:`.drive.drive_rows` after the rows, for the step's samples
        ``[n0, n1)`` (the synthesizer's streams must exist)."""
        a = self._stream_args()
        return a[:5] + (n0 - self._origin, n1 - self._origin) + a[5:]

    def _stream_args(self) -> tuple:
        """:meth:`_drive_args` without the step's samples ``k0, k1`` (before the first stream
        exists: empty stream arrays, so that every sounding side is reported missing)."""
        synth = self.synth
        if self._sidx_epoch != synth._st_epoch:  # the synthesizer forgot its streams
            self._reset_sidx()
        st = synth._st
        if st is None:
            st = self._no_streams
        return (self._sidx, self._geom_obj, self._rough, self._length, float(self.sample_rate), self._regain,
                synth.samples_rendered, synth._RING_SLACK, st["SF"], st["SI"], st["D"], st["ring"])

    def _drive(self, rows, n0, n1, done=None) -> None:
        """One persistent noise stream per (pair, side), whether it slides or rolls: its force,
        speed and kind are updated every step (numba generates the noise), its gains follow the
        contact point every
        ``sustained_block_s`` (see :mod:`.drive`). ``done``: ``(missing, need)`` of a
        :func:`.drive.read_and_drive` call that already drove the rows that have streams."""
        synth = self.synth
        k0 = n0 - self._origin  # synth samples of this step
        k1 = n1 - self._origin
        slots = self.reader._nslots
        if slots > len(self._sidx):
            grown = np.full((max(2 * len(self._sidx), slots, 16), 2), -1, np.int64)
            grown[: len(self._sidx)] = self._sidx
            self._sidx = grown
        if done is not None and not done[1]:
            missing = done[0].tolist()  # the others were driven already
        elif synth._st is None:  # no stream yet: every sounding side needs one
            missing = [(r, sd) for r in range(len(rows)) for sd in (0, 1)
                       if self._geom_obj[int(rows[r, R_G2 if sd == 0 else R_G1])] >= 0]
        else:
            need = done[1] if done is not None else 0  # done[1]: the ring was too short, nothing driven
            while True:
                if need:
                    synth._streams_grow_ring(need)
                buf = np.empty((2 * len(rows), 2), np.int64)
                nm, need = drive_rows(rows, *self._drive_args(n0, n1), buf)
                if not need:
                    break
            if not nm:
                return
            missing = buf[:nm].tolist()
        for r, side in missing:
            row = rows[r]
            if not (math.isfinite(row[R_FORCE]) and math.isfinite(row[R_SPEED])):
                continue
            g1, g2, kind = int(row[R_G1]), int(row[R_G2]), int(row[R_KIND])
            g = g2 if side == 0 else g1
            ob = synth._objects[self._names[g]]
            key = (g1, g2, g)
            j = synth._stream_index(key, ob)
            self._sidx[int(row[R_SLOT]), side] = j
            sign = 1.0 if side == 0 else -1.0
            synth._stream_drive(j, row[R_POINT:R_POINT + 3], sign * row[R_NORMAL:R_NORMAL + 3], float(row[R_FORCE]),
                                float(row[R_SPEED]), k0, k1, self._rough[kind - 1], self._length[kind - 1],
                                self._regain)

    def _render_every(self) -> int:
        """Steps per render in :meth:`run` / :meth:`advance` (``render_block_s``)."""
        return max(1, int(round(self.render_block_s / float(self.model.opt.timestep))))

    def advance(self, nstep: int = 1) -> np.ndarray:
        """``mj_step`` then :meth:`step`, ``nstep`` times; the blocks concatenated."""
        return self.run(int(nstep) * float(self.model.opt.timestep), nsteps=int(nstep))

    def run(self, duration: float, callback=None, nsteps: int | None = None) -> np.ndarray:
        """Simulate ``duration`` seconds (``round(duration / timestep)`` steps) with sound.

        Parameters
        ----------
        duration : float
            Simulated time [s].
        callback : callable, optional
            ``callback(model, data)`` before every ``mj_step`` (e.g. to set controls).
        nsteps : int, optional
            Number of steps (overrides ``duration``).

        Returns
        -------
        (channels, n) float32 array [Pa], ``n = ceil(t_end fs) - ceil(t_start fs)``.
        """
        if nsteps is None:
            nsteps = int(round(float(duration) / float(self.model.opt.timestep)))
        every = self._render_every()
        blocks = []
        if self._pending:
            blocks.append(self.flush())
        for i in range(0, nsteps, every):  # render_block_s of steps at a time
            m = min(every, nsteps - i)
            if callback is None:
                self.substeps(m)  # (one numba call: .fused)
            else:
                for _ in range(m):
                    callback(self.model, self.data)
                    self._mj.mj_step(self.model, self.data)
                    self.step(render=False)
            blocks.append(self.flush())
        if not blocks:
            return np.zeros((self.n_channels, 0), np.float32)
        return blocks[0] if len(blocks) == 1 else np.concatenate(blocks, axis=1)

    # ------------------------------------------------------------------ reporting
    @property
    def event_log(self) -> list:
        """The first ``keep_events`` events since the last reset, in order:
        ``(time [s], kind, geom1, geom2, value)``, kind ``"impact"`` (value: impulse [N s]) or
        ``"slide"`` / ``"roll"`` (one per pair and physics step; value: speed [m/s])."""
        if self._log_pending:
            log = self._log
            for t0, what, rows in self._log_pending:
                if what == "impact":
                    log.extend((t0, "impact", int(r[I_G1]), int(r[I_G2]), r[I_IMPULSE]) for r in rows.tolist())
                else:
                    log.extend((t0, "slide" if r[R_KIND] == 1.0 else "roll", int(r[R_G1]), int(r[R_G2]), r[R_SPEED])
                               for r in rows.tolist())
            del log[self.keep_events:]
            self._log_pending = []
        return self._log

    @property
    def n_impacts(self) -> int:
        """Impact events since the last reset (``events["impact"]``, without building the dict)."""
        return self._n_impacts

    @property
    def events(self) -> dict:
        """Counts since the last reset: ``impact`` events, and ``slide`` / ``roll`` pair-steps
        (a pair sliding or rolling for one physics step counts once)."""
        s = self.reader.sustained_steps - self._sustained_base
        return {"impact": self._n_impacts, "slide": int(s[0]), "roll": int(s[1])}

    @property
    def impacts(self):
        """:class:`ImpactRecord` list (predicted vs MuJoCo impulse) of the reader."""
        return self.reader.impacts

    def stats(self) -> dict:
        """Counts and timings so far."""
        return {
            "steps": self.steps,
            "samples": self.samples,
            "events": dict(self.events),
            "contact_us_per_step": 1e6 * self.seconds_contacts / max(self.steps, 1),
            "synth_us_per_step": 1e6 * self.seconds_synth / max(self.steps, 1),
            # substeps run in numba (.fused): mj_step, reading, driving and impacts together
            "fused_us_per_step": 1e6 * self.seconds_fused / max(self.steps, 1),
            "clamped": self.reader.n_clamped,
        }
