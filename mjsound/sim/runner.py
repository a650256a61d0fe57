"""`StepKernel`: calls the step kernel (:func:`.step.advance`) and does for it what numba
cannot (growing buffers, ``mj_solveM`` through the bindings when its C address is unknown).

Hand-backs that need the synthesizer or the clock (Hertz coefficients, streams, ring length,
clock jumps, out-of-range amplitudes) go to the caller's ``on_stop(reason)``
(:class:`mjsound.sim.simulator.AudioSimulator`); a reader on its own
(:meth:`ContactReader.events`) uses a silent drive, where none of them can happen.
"""

from __future__ import annotations

import numpy as np

from ..synth.dispatch import PackedEntry
from ..synth.objects import build_layout
from ..synth.records import CHANNEL, SYNTH_CONSTS, ObjectTable, RenderTarget, SynthState
from ..synth.queue import EventQueue
from ..synth.stream_table import StreamTable
from .clicks import silent_pulse_state
from .fused import mj_link
from .records import DRIVE_PARAMS, NOT_RENDERED, RUN, SOUND, DataViews, DriveState
from .step import DONE, REASONS, ROOM, SOLVE, STAGE_READ, STAGE_STEP, advance

__all__ = ["StepKernel", "silent_drive", "silent_synth_state", "silent_render_target"]


def silent_drive(ngeom: int) -> DriveState:
    """A :class:`.records.DriveState` in which no geom sounds."""
    sound = np.zeros(ngeom, SOUND)
    sound["obj"] = -1
    return DriveState(np.zeros(1, DRIVE_PARAMS), sound, np.full((0, 2), -1, np.int64),
                      np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, 3, 4)), np.zeros(0, np.int64),
                      np.zeros(0, np.int64),
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


class StepKernel:
    """The step kernel of one (reader, MjData): the :data:`.records.MJ` link, the data's
    views, the :data:`.records.RUN` record and the clock record it counts in.

    Parameters
    ----------
    model, data : mujoco.MjModel, mujoco.MjData
    reader : ContactReader
    clock : (1,) CLOCK, optional
        The sample clock's record (default: a private one; replay-style calls with explicit
        times do not use it).
    use_c : bool
        Reach MuJoCo through its C functions and struct (False: through the bindings only).
    """

    def __init__(self, model, data, reader, clock=None, use_c: bool = True):
        import mujoco

        from .records import CLOCK

        self._mj = mujoco
        self.model, self.data, self.reader = model, data, reader
        self.mj = mj_link(model, data, use_c)
        self.from_struct = bool(self.mj[0]["layout_ok"])
        self.views = DataViews(data.cvel, data.subtree_com, data.geom_xpos, data.geom_xmat, data.cdof, data.xpos,
                               data.site_xpos, data.xmat)
        self.run = np.zeros(1, RUN)
        #: the fields of :attr:`run` as one-element arrays (fast to use in Python)
        self.f = {name: self.run[name] for name in RUN.names}
        self.f["from_struct"][0] = self.from_struct
        self._reason = self.f["reason"]
        self._run_bytes = self.run.view(np.uint8)
        self._fresh = {}  # (nstep, call_step, render) -> a fresh call's RUN record, as bytes
        if clock is None:  # (calls with explicit times only; fs 1 keeps the event time finite)
            clock = np.zeros(1, CLOCK)
            clock[0]["fs"] = clock[0]["den"] = 1
        self.clock = clock
        self._advance_call = PackedEntry(advance)
        self._silent = None  # (silent_render_target, made on first use)

    def _fresh_run(self, nstep: int, call_step: bool, render: bool) -> np.ndarray:
        """The :data:`.records.RUN` record a call starts from, as bytes: the inputs a caller
        keeps from call to call set (steps, whether the kernel steps, whether it renders), where
        a substep starts, and every other field zero (``render_code``: :data:`NOT_RENDERED`;
        the log room and explicit times are written after the copy). The kernel sets each
        working field before it reads it, so a call needs nothing of the last one."""
        r = np.zeros(1, RUN)
        r0 = r[0]
        r0["nstep"], r0["call_step"], r0["from_struct"] = nstep, call_step, self.from_struct
        r0["stage"] = STAGE_STEP if call_step else STAGE_READ
        r0["render"], r0["render_code"] = render, NOT_RENDERED
        if len(self._fresh) >= 64:  # (a caller varying the number of steps every call: keep a few)
            self._fresh.clear()
        fresh = self._fresh[(nstep, call_step, render)] = r.view(np.uint8)
        return fresh

    @property
    def can_step(self) -> bool:
        """Whether the kernel can call ``mj_step`` itself (C function and struct layout known)."""
        m = self.mj[0]
        return bool(m["layout_ok"] and m["step_fn"] and m["solve_fn"])

    def _copy_contacts(self) -> None:
        """Python copies the step's contacts into the buffers (no usable struct layout)."""
        run = self.run[0]
        run["ncon"], run["nefc"] = self.reader.copy_contacts(self.data)

    def _silent_target(self) -> RenderTarget:
        if self._silent is None:
            self._silent = silent_render_target()
        return self._silent

    def call(self, drive, synth_state, nstep: int = 1, call_step: bool = False, explicit=None, log_limit: int = 0,
             on_stop=None, synth=None, target=None, block=None) -> None:
        """Run ``nstep`` substeps (``call_step``: the kernel calls ``mj_step``; else the step
        was taken and its contacts are read). ``explicit``: ``(t0, t1, n0, n1)`` of a single
        step instead of the clock's. ``drive``: a DriveState or a callable returning the
        current one, ``synth_state()``: the current SynthState and ``target()`` the current
        RenderTarget (None: :func:`silent_render_target`; all asked again after every
        hand-back); ``synth``: the Synthesizer whose queue grows on :data:`.step.ROOM`;
        ``on_stop(reason)`` handles the other reasons, then the call resumes. ``block``: a
        zeroed (mics, n) array of the bank dtype into which the kernel renders the pending
        samples after the last substep (``run.render_code`` says whether it did; None: no
        render)."""
        self._start(nstep, call_step, block is not None, log_limit)
        if explicit is not None:
            f = self.f
            f["explicit"][0] = 1
            f["t0"][0], f["t1"][0], f["n0"][0], f["n1"][0] = explicit
        if not self.from_struct:
            if call_step or nstep != 1:
                raise ValueError("StepKernel.call: stepping needs MuJoCo's C functions and struct layout")
            self._copy_contacts()
        reader = self.reader
        if target is None:
            target = self._silent_target

        def state():
            return (self.mj, self.views, reader.state(), reader.buffers, self.clock,
                    drive() if callable(drive) else drive, synth_state(), self.run, target())

        self._loop(state, block, on_stop, synth)

    def substeps_call(self):
        """``call(state, nstep, block, log_limit) -> bool``: the first call of :meth:`call` for
        :meth:`AudioSimulator.substeps`, ``nstep`` substeps that call ``mj_step``
        (:attr:`can_step`) on the clock's times, on the kernel's ``state`` tuple (``mj``,
        ``views``, the reader's state and buffers, ``clock``, the drive, the synthesizer's
        state, ``run``, the render target), rendering into ``block`` (None: no render), with
        ``log_limit`` log entries of room. It returns True when the kernel is done; False when
        it handed back (``run.reason``): :meth:`resume` then handles that and finishes.

        A closure over this kernel's run record and entry point: it runs once per env step,
        where looking up an attribute costs more than the lines around it (see
        :func:`mjsound.sim.substeps.make_substeps`)."""
        fresh_runs, fresh_run, run_bytes, advance_call = self._fresh, self._fresh_run, self._run_bytes, self._advance_call
        reason_f, log_limit_f = self._reason, self.f["log_limit"]

        def call(state: tuple, nstep: int, block, log_limit: int) -> bool:
            render = block is not None
            fresh = fresh_runs.get((nstep, True, render))
            if fresh is None:
                fresh = fresh_run(nstep, True, render)
            run_bytes[:] = fresh  # (as _start)
            if log_limit:
                log_limit_f[0] = log_limit
            advance_call(state, block if render else state[-1].empty)
            return reason_f[0] == DONE

        return call

    def resume(self, state, block, on_stop, synth) -> None:
        """Finish a call that handed back (the function of :meth:`substeps_call` returned
        False): ``state()`` returns the current state tuple, the rest as for :meth:`call`."""
        self._loop(state, block, on_stop, synth, call_first=False)

    def _start(self, nstep: int, call_step: bool, render: bool, log_limit: int) -> None:
        """Reset :attr:`run` for a call (:meth:`_fresh_run`) with ``log_limit`` log entries of room."""
        fresh = self._fresh.get((nstep, call_step, render))
        if fresh is None:
            fresh = self._fresh_run(nstep, call_step, render)
        self._run_bytes[:] = fresh  # (one copy of the whole record, its fields named in _fresh_run)
        if log_limit:  # (the log room shrinks as a simulator with an event log logs)
            self.f["log_limit"][0] = log_limit

    def _loop(self, state, block, on_stop, synth, call_first: bool = True) -> None:
        """Call the kernel on ``state()`` until it is done; what it hands back is handled here
        (buffers grow, ``mj_solveM`` through the bindings) or by ``on_stop(reason)``. ``block``
        None: the render target's empty block (no render). ``call_first`` False: the kernel
        was just called; handle its reason first."""
        reason_f = self._reason
        while True:
            if call_first:
                s = state()
                self._advance_call(s, s[-1].empty if block is None else block)
            call_first = True
            reason = reason_f[0]
            if reason == DONE:
                return
            reason = int(reason)
            run = self.run[0]
            reader = self.reader
            if reason == ROOM:
                n = int(run["need"])
                reader.grow(n, int(run["nefc"]))
                if run["n_log"] < run["log_limit"]:
                    reader.grow_log(int(run["n_log"]) + 2 * n)
                if synth is not None:
                    synth.reserve_impacts(2 * n)
                if not self.from_struct:
                    self._copy_contacts()
            elif reason == SOLVE:
                k = int(run["need"])
                b = reader.buffers
                self._mj.mj_solveM(self.model, self.data, b.minv_jt[:k], b.jn[:k])
                run["solved"] = 1
            elif on_stop is not None:
                on_stop(reason)
            else:
                raise RuntimeError(f"mjsound: the step kernel stopped ({REASONS[reason]}) with nobody to handle it")
