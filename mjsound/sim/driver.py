"""`StepDriver`: the one way into the step kernel (:func:`.step.advance`) and the per-step
state around it.

Every step of sound goes through :meth:`StepDriver.substeps`: the env's ``mj_step`` then
``AudioSimulator.step()`` (``stepped=True``: the kernel reads the step just taken), mjsound
stepping the physics itself (``AudioSimulator.advance`` / ``run``, the gymnasium and
dm_control hooks: the kernel calls ``mj_step`` before each substep), a replayed frame
(``times``: the step's times and samples given) and the contact reader on its own
(:meth:`ContactReader.events_fast`, a driver without a synthesizer). One call:

1. the kernel's state, one named record (:class:`.records.KernelState`) built in
   :meth:`StepDriver.state`, packed into one table when one of its parts was replaced
   (:func:`mjsound.synth.packing.pack`) and handed to the kernel's compiled entry point;
2. what the kernel hands back (``run.reason``, :mod:`.step`) handled here (buffers grow,
   ``mj_solveM`` through the bindings, pulses to their track, a clock jump) or by the
   simulator's hooks (streams to make, an amplitude error), then the kernel called again;
3. the steps' samples counted as pending; the block the kernel rendered (``run.render``)
   returned, or kept for :meth:`StepDriver.flush`, or the pending samples rendered.

:meth:`StepDriver.substeps` is written flat, entering the kernel itself: an env step's
Python runs between MuJoCo's work and numba's, with cold caches, where each function
entered costs more than the arithmetic between (the README's profile of a wrapped env step
measures it), so what is rare (a hand-back, a clock jump, rendering in Python) is in other
methods. ``docs/design.md`` draws the data flow.

Time alignment (:mod:`.clock`): the step from ``t_k`` to ``t_{k+1}`` owns the samples
``ceil(t_k fs) <= n < ceil(t_{k+1} fs)``. ``data.time`` is checked at every step read (in the
kernel when it reads the mjData struct): a step more than one timestep after the last one
read, or no step at all since, raises (:meth:`StepDriver.time_error`); time going backwards is
a reset the simulator was not told about (the ringing is cleared, the samples counted so far
come out with the next block); a new timestep re-anchors the clock.
"""

from __future__ import annotations

import time as _time
from operator import is_

import numpy as np

from ..synth.dispatch import PackedEntry
from ..synth.kernels import RENDERED
from ..synth.objects import build_layout
from ..synth.queue import EventQueue
from ..synth.records import CHANNEL, SYNTH_CONSTS, ObjectTable, RenderTarget, SynthState
from ..synth.stream_table import StreamTable
from .clicks import silent_pulse_state
from .clock import SampleClock
from .fused import mj_link
from .images import fold
from .records import DRIVE_PARAMS, NOT_RENDERED, RUN, SOUND, DataViews, DriveState, KernelState
from .step import (AMPLITUDE, CLOCK_JUMP, DONE, DRIVES, DRIVES_DUE, DRIVES_NONE, PULSES, REASONS, RING, ROOM, SOLVE,
                   STAGE_READ, STAGE_STEP, STREAMS, advance)

__all__ = ["StepDriver", "silent_drive", "silent_synth_state", "silent_render_target"]

_new_state = tuple.__new__  # (a KernelState without its Python __new__: once per env step)


def silent_drive(ngeom: int) -> DriveState:
    """A :class:`.records.DriveState` in which no geom sounds."""
    sound = np.zeros(ngeom, SOUND)
    sound["obj"] = -1
    return DriveState(np.zeros(1, DRIVE_PARAMS), sound, np.full((0, 2), -1, np.int64), np.zeros(0, np.int64),
                      np.zeros((0, 3)), np.zeros((0, 3, 4)), np.zeros(0, np.int64), np.zeros(0, np.int64),
                      silent_pulse_state())


def silent_synth_state(dtype="float32") -> SynthState:
    """A :class:`mjsound.synth.records.SynthState` without objects or microphones (the same
    types as a synthesizer's, so the kernel compiled for one serves both)."""
    z = np.zeros
    objects = ObjectTable(z((0, 3)), z(1, np.int64), z(0, np.int64), z(1, np.int64), z(0), z(1, np.int64),
                          z(1, np.int64), z(0), z(0), z(0, np.complex128), z(0, np.complex128))
    return SynthState(objects, z((0, 3)), z((0, 3, 3)), z((0, 3)), z(1, SYNTH_CONSTS), EventQueue(1).state,
                      StreamTable(0, dtype).empty, z(0, CHANNEL), z(0, np.complex128))


def silent_render_target(dtype="float32") -> RenderTarget:
    """A :class:`mjsound.synth.records.RenderTarget` without banks (laid out by the
    synthesizer's own :func:`mjsound.synth.objects.build_layout` for no object and no
    microphone: the same types, for :func:`silent_synth_state`)."""
    lay = build_layout([], 0, 0, dtype)
    return RenderTarget(lay.bank, lay.layout, np.zeros(1, dtype), np.zeros((0, 0), dtype))


class StepDriver:
    """The step kernel of one MjData and the per-step state around it: the sample clock, the
    kernel's run record, the samples stepped but not rendered, the event log.

    Parameters
    ----------
    model, data : mujoco.MjModel, mujoco.MjData
    reader : ContactReader
    sample_rate : int
        The output's sample rate [Hz] (1 for a reader on its own: no samples).
    synth : Synthesizer, optional
        What sounds (None: nothing; the kernel runs on a silent drive and synthesizer).
    pulses : ImpactPulses, optional
        The impacts' clicks and contact-microphone pulses (with ``synth``).
    drive_state : callable, optional
        ``drive_state(reader_state) -> DriveState``: the drive's current arrays (None: a
        silent drive).
    make_streams : callable, optional
        ``make_streams(missing, rows)``: a stream for each ``(row, side)`` of ``missing``
        (:data:`.step.STREAMS`).
    amplitude_error : callable, optional
        ``amplitude_error(impacts) -> Exception`` for impacts whose amplitude is out of range.
    reset_sound : callable, optional
        ``reset_sound(clear_reader)``: silence the synthesizer and the pulses, forget the
        contact state when asked (:meth:`reset` calls it).
    n_channels : int
        Channels of a block when nothing sounds.
    images : ImageSet, optional
        Image microphones (:mod:`.images`): the synthesizer's image rows are folded into their
        microphones' channels in every block (None or empty: none).
    tail : LateTail, optional
        A room's late reverberant tail (:mod:`.room_tail`): added into the air rows of every
        block, from its image rows, before they are folded.
    keep_events : int
        :attr:`event_log` keeps the first this many events.
    use_c : bool
        Reach MuJoCo through its C functions and struct (False: through the bindings only).

    Attributes
    ----------
    clock : SampleClock
    fused : bool
        Whether the kernel calls ``mj_step`` itself (MuJoCo's C functions and struct layout
        checked); else :meth:`substeps` steps through the bindings.
    steps, samples : int
        Physics steps and samples counted since the last reset.
    on_block : callable | None
        Observer ``on_block(owner, block, n0)`` of every rendered block (first absolute
        sample ``n0``; e.g. :class:`mjsound.rerun_log.RerunLogger`).
    f : dict
        The fields of the run record as one-element arrays (what the last call did).
    """

    def __init__(self, model, data, reader, sample_rate: int, *, synth=None, pulses=None, drive_state=None,
                 make_streams=None, amplitude_error=None, reset_sound=None, n_channels: int = 0,
                 images=None, n_air: int = 0, tail=None, keep_events: int = 0, use_c: bool = True, owner=None):
        import mujoco

        self._mj = mujoco
        self.reader, self.synth, self.pulses = reader, synth, pulses
        self.clock = SampleClock(sample_rate, float(model.opt.timestep), float(data.time))
        if drive_state is None:
            silent = silent_drive(model.ngeom)
            drive_state = lambda rs: silent  # noqa: E731
        self._drive_state, self._make_streams, self._amplitude_error = drive_state, make_streams, amplitude_error
        self._reset_sound = reset_sound
        self._owner = self if owner is None else owner  # (what on_block is handed)
        self.n_channels = int(n_channels)
        self._images = images if images is not None and len(images) else None
        self._n_air = int(n_air)
        self._tail = tail
        self.keep_events = int(keep_events)
        self._use_c = use_c
        self.run = np.zeros(1, RUN)
        #: the fields of :attr:`run` as one-element arrays (fast to use in Python)
        self.f = {name: self.run[name] for name in RUN.names}
        self._run_bytes = self.run.view(np.uint8)
        self._fresh = {}  # (nstep, stepped, render) -> a fresh call's RUN record, as bytes
        self.kernel = PackedEntry(advance)  # (its state packed, and its compiled entry point)
        self._silent_synth = None if synth is not None else silent_synth_state()
        self._silent_target = None if synth is not None else silent_render_target()
        self.on_block = None
        #: optional actuators (:class:`.actuators.ActuatorSound`): ``drives.drive(n0, n1, final,
        #: later)`` called with the samples of the steps about to be read (not on a replay;
        #: ``final``: the call renders them; ``later``: a block due is rendered when the kernel
        #: hands back :data:`.step.DRIVES` after the substeps, by ``drives.render_due()``; it
        #: returns whether one is due), and ``(n, n, True, False)`` before a render of the
        #: samples up to ``n``; ``drives.reset()`` when the clock jumps
        self.drives = None
        self._held = []  # blocks rendered before an automatic reset, returned by the next render
        self.bind(model, data)
        self.clock.rec[0]["origin"] = self.clock.n
        self._clear_counts()

    # ------------------------------------------------------------------ the data stepped
    def bind(self, model, data) -> None:
        """Step (or read) ``model`` / ``data`` from now on: their C link and views; the clock
        anchored at ``data.time`` with the sample count continuing (:meth:`rebind`)."""
        self.model, self.data, self._opt = model, data, model.opt
        self.mj = mj_link(model, data, self._use_c)
        self.from_struct = bool(self.mj[0]["layout_ok"])
        self.fused = bool(self.from_struct and self.mj[0]["step_fn"] and self.mj[0]["solve_fn"])
        self.views = DataViews(data.cvel, data.subtree_com, data.geom_xpos, data.geom_xmat, data.cdof, data.xpos,
                               data.site_xpos, data.xmat)
        self._fresh.clear()
        self.f["from_struct"][0] = self.from_struct
        self._reanchor(float(model.opt.timestep), float(data.time))

    def state(self) -> KernelState:
        """The step kernel's state now (:class:`.records.KernelState`): asked again after every
        hand-back, since an owner may have replaced a record."""
        rs = self.reader.state()
        synth = self.synth
        if synth is None:
            return _new_state(KernelState, (self.mj, self.views, rs, self.reader.buffers, self.clock.rec,
                                            self._drive_state(rs), self._silent_synth, self.run, self._silent_target))
        return _new_state(KernelState, (self.mj, self.views, rs, self.reader.buffers, self.clock.rec,
                                        self._drive_state(rs), synth.kernel_state(), self.run, synth.render_target()))

    def _fresh_run(self, nstep: int, stepped: bool, render: bool) -> np.ndarray:
        """The :data:`.records.RUN` record a call starts from, as bytes: the inputs a caller
        keeps from call to call set (steps, whether the kernel steps, whether it renders), where
        a substep starts, and every other field zero (``render_code``: :data:`NOT_RENDERED`;
        the log room and explicit times are written after the copy). The kernel sets each
        working field before it reads it, so a call needs nothing of the last one."""
        r = np.zeros(1, RUN)
        r0 = r[0]
        r0["nstep"], r0["call_step"], r0["from_struct"] = nstep, not stepped, self.from_struct
        r0["stage"] = STAGE_READ if stepped else STAGE_STEP
        r0["render"], r0["render_code"] = render, NOT_RENDERED
        if len(self._fresh) >= 64:  # (a caller varying the number of steps every call: keep a few)
            self._fresh.clear()
        fresh = self._fresh[(nstep, stepped, render)] = r.view(np.uint8)
        return fresh

    # ------------------------------------------------------------------ stepping
    def substeps(self, nstep: int, render: bool = True, keep: bool = False, stepped: bool = False, times=None):
        """Read ``nstep`` physics steps through the step kernel and queue their sound.

        Parameters
        ----------
        nstep : int
            Physics steps (``stepped``: 1).
        render : bool
            Return the samples pending after the steps (those of earlier unrendered steps
            first), rendered in the kernel's call where it can; False: return None (the
            samples stay pending: :meth:`flush`).
        keep : bool
            Render in the kernel's call but keep the block for the next :meth:`flush` (a hook
            inside an env's step, whose audio the wrapper takes after the step); returns None.
        stepped : bool
            The caller has taken the step (``mj_step``) already: read it. False: the kernel
            calls ``mj_step`` before each substep.
        times : tuple, optional
            ``(t0, t1, n0, n1)``: a replayed step's times [s] and samples (the clock unused).

        Returns
        -------
        (channels, n) float32 array | None
        """
        if not stepped and not self.fused:
            return self._python_steps(nstep, render, keep)
        clock = self.clock
        synth = self.synth
        if times is None:
            if not self.from_struct:  # (the kernel checks data.time itself where it reads the struct)
                self._check_time()
            k0, n0, n1 = clock.span(nstep)
            if k0 + nstep > clock.k_max_int64:
                return self._python_steps(nstep, render, keep, stepped)
            due = self.drives is not None and self.drives.drive(n0, n1, render or keep, True)
        else:
            k0, n0, n1 = clock.k, times[2], times[3]
            due = False
        pending = self._pending
        block = None
        if (render or keep) and times is None and synth is not None and self._ready is None and not self._held \
                and synth.renders_in_kernel:
            block = synth.new_block(pending + n1 - n0)
        fresh = self._fresh.get((nstep, stepped, block is not None))
        if fresh is None:
            fresh = self._fresh_run(nstep, stepped, block is not None)
        self._run_bytes[:] = fresh
        f = self.f
        if due:
            f["drives_due"][0] = DRIVES_DUE
        if self.keep_events:
            f["log_limit"][0] = max(0, self.keep_events - self._n_logged)
        if times is not None:
            f["explicit"][0] = 1
            f["t0"][0], f["t1"][0], f["n0"][0], f["n1"][0] = times
        if not self.from_struct:
            self._copy_contacts()
        if synth is not None:
            synth.poses_current = False
        seg = self._seg = (k0, n0)
        reason = f["reason"]
        kernel = self.kernel
        tc = _time.perf_counter() if stepped else 0.0
        while True:  # (PackedEntry.__call__ written out: one Python frame less between the env and the kernel)
            state = self.state()
            out = block if block is not None else state.target.empty
            packed_for = kernel.state
            if packed_for is None or not all(map(is_, state, packed_for)):
                kernel.bind(state, out)
            kernel.entry(*kernel.packed, out)
            # (the actuators' block, handed back after the substeps: the call resumes with the
            # same state unless rendering it replaced a record)
            while reason[0] == DRIVES and not self._render_drives():
                kernel.entry(*kernel.packed, out)
            if reason[0] == DONE:
                break
            if reason[0] != DRIVES:
                self._hand_back(int(reason[0]))
        if f["collect"][0]:
            self._collect()
        if times is not None:
            self._count(n0, n1)
        elif self._seg is seg:  # (no clock jump counted a segment during the call: all in one go)
            if not pending:
                self._pending_n0 = n0
            self._pending = pending + n1 - n0
            self.steps += nstep
            self.samples += n1 - n0
        else:
            self._count_segment()
        if stepped:
            self.seconds_contacts += _time.perf_counter() - tc
        if synth is not None:
            synth.poses_current = bool(f["poses_current"][0])
        if block is not None and f["render_code"][0] != NOT_RENDERED:
            return self._take_block(block, keep)
        if render and not keep:
            return self.flush()
        return None

    def replay(self, n0: int, n1: int, t0: float, t1: float, origin: int | None = None, render: bool = True):
        """Read a recorded step (``data`` set to its frame and ``mj_forward``-ed): samples
        ``[n0, n1)`` and times ``[t0, t1)`` [s] given, the clock unused; ``origin``: absolute
        sample of the synthesizer's sample 0 (None: unchanged). Returns what pends when
        ``render`` (as :meth:`substeps`)."""
        if origin is not None:
            self.clock.rec[0]["origin"] = int(origin)
        return self.substeps(1, render, False, True, (float(t0), float(t1), int(n0), int(n1)))

    def _take_block(self, block: np.ndarray, keep: bool):
        """The block the kernel rendered (every pending sample) as :meth:`flush` returns it:
        float32, never NaN, the pulse track mixed in; kept for :meth:`flush` when ``keep``."""
        synth, f = self.synth, self.f
        self._pending = 0
        code = f["render_code"][0]
        if code != RENDERED or block.dtype != np.float32:
            block = synth.kernel_block(block, code == RENDERED)
        if not f["pulses_mixed"][0]:  # (the kernel mixes the pulse track into a float32 block itself)
            block = self.pulses.mix(block)
        if self._tail is not None:  # (a room's late tail, fed by the image rows: before the fold)
            self._tail.apply(block)
        if self._images is not None:  # (image microphones' rows into their channels, .images)
            block = fold(block, self._n_air, self._images)
        if not keep:
            return self._deliver(block, self._pending_n0)
        self._ready = block if self.on_block is None else self._deliver(block, self._pending_n0)
        return None

    def _python_steps(self, nstep: int, render: bool, keep: bool, stepped: bool = False):
        """:meth:`substeps` one step per kernel call, MuJoCo stepped through the bindings (no C
        functions or struct layout checked; a clock about to leave 64-bit integers re-anchored
        first)."""
        c = self.clock
        if c.k + nstep > c.k_max_int64:
            self._reanchor(c.timestep, c.time_at(c.k))
        for _ in range(nstep):
            if not stepped:
                self._mj.mj_step(self.model, self.data)
            self.substeps(1, False, False, True)
        return self.flush() if render and not keep else None

    def _check_time(self) -> None:
        """``data.time`` one step after the last one read, else a clock jump (:meth:`_clock_jump`;
        the kernel checks this itself when it reads the mjData struct)."""
        c = self.clock
        dt = c.timestep
        if self._opt.timestep != dt or abs(self.data.time - c.time_at(c.k + 1)) > 0.25 * dt:
            self._clock_jump()

    def _reanchor(self, timestep: float, t_start: float) -> None:
        """Restart the clock's count at ``t_start`` with ``timestep``, the output's absolute
        sample count going on (the synthesizer's sample 0 moves with it)."""
        c = self.clock
        n_prev = c.n
        c.anchor(timestep, t_start)
        c.rec[0]["origin"] += c.n - n_prev

    def _copy_contacts(self) -> None:
        """Python copies the step's contacts into the buffers (no usable struct layout)."""
        run = self.run[0]
        run["ncon"], run["nefc"] = self.reader.copy_contacts(self.data)

    def _render_drives(self) -> bool:
        """The actuators' block the kernel handed back for (:data:`.step.DRIVES`), from their
        state after the substeps; returns whether a record of the kernel's state was replaced."""
        self.synth.poses_current = True  # (the kernel synced them before handing back)
        return self.drives.render_due()

    def _hand_back(self, reason: int) -> None:
        """Do what the kernel handed back (``run.reason``, :mod:`.step`); it is called again."""
        run = self.run[0]
        reader = self.reader
        buf = reader.buffers
        if reason == ROOM:
            n = int(run["need"])
            reader.grow(n, int(run["nefc"]))
            if run["n_log"] < run["log_limit"]:
                reader.grow_log(int(run["n_log"]) + 2 * n)
            if self.synth is not None:
                self.synth.reserve_impacts(2 * n)
            if not self.from_struct:
                self._copy_contacts()
        elif reason == SOLVE:
            k = int(run["need"])
            self._mj.mj_solveM(self.model, self.data, buf.minv_jt[:k], buf.jn[:k])
            run["solved"] = 1
        elif reason == STREAMS:
            self._make_streams(buf.missing[: int(run["n_missing"])].tolist(), buf.sustained)
        elif reason == RING:
            self.synth.grow_stream_ring(int(run["need"]))
        elif reason == CLOCK_JUMP:
            run["render"] = 0  # (the pending samples change: flush renders them)
            if self.drives is not None:
                run["drives_due"] = DRIVES_NONE
                self.drives.reset()  # (its block was for the clock before the jump)
            self._collect()
            self.pulses.flush()  # (the substeps' pulses so far, before the clock moves)
            self._count_segment()
            self._clock_jump()
            self._seg = (self.clock.k, self.clock.n)
        elif reason == PULSES:  # the pulse rows are full: to the track, and room for this substep's
            self.pulses.flush()
            self.pulses.reserve(int(run["n_imp"]))
        elif reason == AMPLITUDE:
            self._collect()
            self.pulses.flush()
            raise self._amplitude_error(buf.impacts[: int(run["need"])])
        else:
            raise RuntimeError(f"mjsound: the step kernel stopped ({REASONS[reason]}) with nobody to handle it")

    def _count_segment(self) -> None:
        """Count the substeps the kernel finished since ``_seg`` (clock step and sample)."""
        k0, n0 = self._seg
        c = self.clock
        k = c.k
        n = c.sample_at(k)
        if k > k0:
            self._count(n0, n, k - k0)
        self._seg = (k, n)

    def _count(self, n0: int, n1: int, steps: int = 1) -> None:
        """Count ``steps`` physics steps of samples ``[n0, n1)``, not rendered yet."""
        if self._pending == 0:
            self._pending_n0 = n0
        self._pending += n1 - n0
        self.steps += steps
        self.samples += n1 - n0

    def _collect(self) -> None:
        """Take the kernel's event log entries and clamped-force counts (the reader warns); the
        impact records wait in the reader's rows until read."""
        f = self.f
        self.reader.report_clamped()
        n_log = int(f["n_log"][0])
        if n_log:
            self._log_pending.append(self.reader.buffers.log[:n_log].copy())
            self._n_logged += n_log
            f["n_log"][0] = 0
            f["log_limit"][0] = max(0, self.keep_events - self._n_logged)

    # ------------------------------------------------------------------ time
    def _clock_jump(self) -> None:
        """``data.time`` or the timestep no longer match the count. A new timestep: restart
        counting at this step (the step just taken ends at ``data.time``). Backwards in time is
        a reset the simulator was not told about (``mj_resetData`` between episodes): the
        ringing is cleared and counting restarts (the samples counted so far are rendered first
        and come out with the next block). Time that did not advance, or advanced by more than
        one step, raises (:meth:`time_error`)."""
        c = self.clock
        dt = float(self._opt.timestep)
        t_new = float(self.data.time) - dt
        if self.data.time < c.time_at(c.k) - 0.25 * c.timestep:  # backwards
            if self._ready is not None:
                self._held.append(self._ready)
                self._ready = None
            if self._pending:
                self._held.append(self._render_pending())
            self._reset_at(t_new, keep_observer=True)
            return
        if dt == c.timestep:
            raise self.time_error()
        self._reanchor(dt, t_new)

    def time_error(self) -> RuntimeError:
        """The error for a step whose ``data.time`` is not one timestep after the last one read."""
        c = self.clock
        t, t_last, dt = float(self.data.time), c.time_at(c.k), c.timestep
        if abs(t - t_last) <= 0.25 * dt:
            return RuntimeError(
                f"mjsound: data.time ({t:.9g} s) has not advanced since the last step read: this simulator's MjData "
                "is not the one being stepped (an env that rebuilt its MjModel/MjData on reset, e.g. robosuite's hard "
                "reset or a dm_control composer env: call sim.rebind(model, data) with the new ones), or step() "
                "was called without an mj_step before it")
        return RuntimeError(
            f"mjsound: data.time advanced by {t - t_last:.6g} s ({(t - t_last) / dt:.4g} timesteps of {dt:g} s) since "
            "the last step read: the contacts of the skipped steps were never read. Call sim.step() after every "
            "mj_step (in an env's own substep loop: sim.step(render=False) after each mj_step, then sim.flush() "
            "once per env step), or let sim.advance(n) step the physics; after setting data.time yourself (or a "
            "loop interrupted between mj_step and step()), call sim.reset()")

    def reset(self, clear_reader: bool = True) -> None:
        """Silence everything, forget contact state (``clear_reader``) and re-anchor the clock
        at ``data.time``."""
        self._reset_at(float(self.data.time), clear_reader)
        self._held = []

    def _reset_at(self, t_start: float, clear_reader: bool = True, keep_observer: bool = False) -> None:
        if self._reset_sound is not None:
            self._reset_sound(clear_reader)
        elif clear_reader:
            self.reader.reset()
        self.clock.anchor(float(self.model.opt.timestep), t_start)
        self.clock.rec[0]["origin"] = self.clock.n  # synth sample 0 is absolute sample n = origin
        self._clear_counts(keep_observer)

    def _clear_counts(self, keep_observer: bool = False) -> None:
        """Counts, event log and samples pending from the clock's anchor on."""
        self.impacts_base = self.reader.n_impacts_made
        self.sustained_base = self.reader.sustained_steps
        self._log = []  # event log: entries and LOG arrays, expanded when read (event_log)
        self._log_pending = []
        self._n_logged = 0
        self.samples = 0
        self.steps = 0
        if not keep_observer:
            self.on_block = None
        self.seconds_contacts = 0.0
        self.seconds_synth = 0.0
        self._pending = 0  # samples stepped but not rendered yet
        self._pending_n0 = self.clock.n
        self._ready = None  # a block substeps(keep=True) rendered, returned by the next flush

    # ------------------------------------------------------------------ rendering
    @property
    def pending(self) -> int:
        """Samples stepped and not returned yet (rendered or not)."""
        return self._pending + sum(b.shape[1] for b in self._held) + (0 if self._ready is None else self._ready.shape[1])

    def flush(self) -> np.ndarray:
        """Every sample stepped and not returned yet, ``(channels, n)`` float32 pressure [Pa]."""
        ready = self._ready
        if ready is None:
            return self._render_pending()
        self._ready = None
        if not self._pending and not self._held:
            return ready
        return np.concatenate([ready, self._render_pending()], axis=1)

    def _render_pending(self) -> np.ndarray:
        n = self._pending
        n0 = self._pending_n0 if n else self.clock.n  # (_count sets _pending_n0 when samples start pending)
        self._pending = 0
        if self.synth is None:
            block = np.zeros((self.n_channels, n), dtype=np.float32)
        else:
            if self.drives is not None:
                self.drives.drive(n0 + n, n0 + n, True, False)
            tc = _time.perf_counter()
            block = self.pulses.mix(self.synth.render(n))  # (never NaN) plus the clicks and contact pulses
            if self._tail is not None:
                self._tail.apply(block)
            if self._images is not None:
                block = fold(block, self._n_air, self._images)  # (image rows into their microphones' channels)
            self.seconds_synth += _time.perf_counter() - tc
        return self._deliver(block, n0)

    def _deliver(self, block: np.ndarray, n0: int) -> np.ndarray:
        """A rendered block (first absolute sample ``n0``) to the observer, after the blocks
        held back by an automatic reset."""
        if self.on_block is not None:
            self.on_block(self._owner, block, n0)
        if self._held:
            block = np.concatenate([*self._held, block], axis=1)
            self._held = []
        return block

    # ------------------------------------------------------------------ reports
    @property
    def event_log(self) -> list:
        """The first ``keep_events`` events since the last reset, in order:
        ``(time [s], kind, geom1, geom2, value)``, kind ``"impact"`` (value: impulse [N s]) or
        ``"slide"`` / ``"roll"`` (one per pair and physics step; value: speed [m/s])."""
        if self._log_pending:
            log = self._log
            for entries in self._log_pending:
                log.extend((t, _LOG_KINDS[k], g1, g2, v) for t, k, g1, g2, v in entries.tolist())
            del log[self.keep_events:]
            self._log_pending = []
        return self._log


_LOG_KINDS = ("impact", "slide", "roll")
