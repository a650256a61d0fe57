"""The step kernel: one numba implementation of a physics substep's sound.

:func:`advance` runs, for each of ``run.nstep`` substeps (``docs/design.md`` draws the data
flow):

1. ``mj_step`` (when it steps itself: :meth:`AudioSimulator.substeps`; :meth:`.step` and
   replay call it after MuJoCo stepped),
2. read: the clock's step times and samples (or the explicit ones of a replay), the
   contacts from the mjData struct (or as Python copied them in), per-pair quantities and the
   pair state machine (:func:`.pairs.read_pairs`),
3. impulses of the impact events (:mod:`.impulses`, ``mj_solveM`` through its C address) and
   their records,
4. queue: poses and microphones synced, the impacts into the synthesizer's event queue
   (:func:`.drive.queue_impacts`), the event log,
5. drive: the sliding / rolling streams (:func:`.drive.drive_sustained`),

and after the last substep renders the impacts' pulses into the pulse track
(:func:`.click_kernels.render_waiting`), syncs the poses and microphones once more (for the
render's stream gains), hands back for the actuators' block when one is due (rendered from
their state after the substeps: :data:`DRIVES`) and, when ``run.render`` asks, renders the pending block
(:func:`mjsound.synth.kernels.render_streams`, as ``Synthesizer.render`` would right after
the call) and mixes the track into it, so that an env step costs one numba call. It stops
and hands back to Python only for what numba cannot do, with a named reason in
``run.reason`` (:data:`DONE`, :data:`CLOCK_JUMP`, :data:`ROOM`, :data:`PULSES`,
:data:`SOLVE`, :data:`STREAMS`, :data:`RING`, :data:`AMPLITUDE`, :data:`DRIVES`); ``run.stage``
says where the substep resumes when Python calls again, and nothing of a stage is changed
before it can finish, so the resumed substep is the same as one that never stopped.

The state is a tuple of named records and :class:`typing.NamedTuple` s of them
(:mod:`.records`, :mod:`mjsound.synth.records`), packed into one table for the call
(:mod:`mjsound.synth.packing`: numba unboxes three arguments instead of about a hundred
arrays) and rebuilt by name in the kernel. The kernel returns nothing (outputs are in
the records), so that an interrupt (Ctrl-C) during the call reaches the caller as
``KeyboardInterrupt``: numba's boxing of a returned array runs Python code that would swallow
a pending signal into ``SystemError``.
"""

from __future__ import annotations

import numpy as np

from ..jit import njit, njit_inner
from ..synth.bandlimited import take_into_block
from ..synth.kernels import RENDERED, render_streams
from ..synth.packing import unpack
from .click_kernels import pulse_room, queue_pulses, render_waiting
from .drive import drive_sustained, missing_streams, queue_impacts, sync_poses
from .fused import data_efc_force, data_ncon, data_time, gather_contacts, mj_solve_now, mj_step_now
from .impulses import event_impulses, normal_jacobians, write_records
from .pairs import read_pairs
from .records import NOT_RENDERED

__all__ = ["advance", "DONE", "CLOCK_JUMP", "ROOM", "SOLVE", "STREAMS", "RING", "AMPLITUDE", "PULSES", "DRIVES",
           "DRIVES_NONE", "DRIVES_DUE", "DRIVES_HANDED", "STAGE_STEP",
           "STAGE_READ", "STAGE_IMPULSES", "STAGE_QUEUE", "STAGE_LOG", "STAGE_DRIVE", "REASONS"]

#: ``run.reason``: every substep done; ``data.time`` is not where the clock expects it (a
#: jump or an external reset: Python re-anchors or resets, then resumes); a buffer must grow
#: for ``run.need`` contacts; ``M^-1 Jn^T`` must come from Python (no C ``mj_solveM``: fill
#: ``buf.minv_jt`` from ``buf.jn`` and set ``run.solved``); ``run.n_missing`` streams
#: (``buf.missing``: row, side) must be made; the stream rings must hold ``run.need`` samples; an impact's amplitude is out
#: of range (Python raises; ``run.need`` impacts in ``buf.impacts``); the actuators' block is due
#: (``run.drives_due``: Python renders it into the pulse track from the state after the
#: substeps, then the call resumes and renders).
DONE, CLOCK_JUMP, ROOM, SOLVE, STREAMS, RING, AMPLITUDE, PULSES, DRIVES = range(9)
REASONS = ("done", "clock jump", "room", "solve", "streams", "ring", "amplitude", "pulses", "drives")
#: ``run.drives_due``: no actuators' block this call; one is due (set by Python before the
#: call); handed back for it (the call resumes at the render).
DRIVES_NONE, DRIVES_DUE, DRIVES_HANDED = range(3)
#: ``run.stage``: where the current substep resumes.
STAGE_STEP, STAGE_READ, STAGE_IMPULSES, STAGE_QUEUE, STAGE_LOG, STAGE_DRIVE = range(6)

LOG_IMPACT, LOG_SLIDE, LOG_ROLL = 0, 1, 2


@njit_inner(cache=True)
def _substep_times(clock, rn, mj):
    """Set ``rn``'s times and samples of the next step from the clock; False when
    ``data.time`` (read from the struct) does not match it within a quarter step."""
    ck = clock[0]
    k = ck.k + 1
    if rn.from_struct:
        if abs(data_time(mj) - (ck.t_start + k * ck.timestep)) > 0.25 * ck.timestep:
            return False
    num0 = ck.a0 + (k - 1) * ck.b
    num1 = num0 + ck.b
    rn.n0 = -((-num0 * ck.fs) // ck.den)
    rn.n1 = -((-num1 * ck.fs) // ck.den)
    rn.t0 = num0 / ck.den
    rn.t1 = num1 / ck.den
    return True


@njit_inner(cache=True)
def _has_room(counts, pairs, geom, records, efc, log, rn, consts, queue, ncon):
    """Whether every buffer holds a substep of ``ncon`` contacts (impacts on two sides at every
    microphone; log entries while the log is not full): the reader's ``counts`` and ``pairs``,
    the step buffers' ``geom``, ``records``, ``efc`` and ``log``, the synthesizer's ``consts``
    and event ``queue``. (The arrays it reads, not their owners' records: a call reference-counts
    every array it is handed, about 150 ``NRT_incref`` / ``NRT_decref`` calls per substep for
    the whole records.)"""
    cnt = counts[0]
    if ncon > geom.shape[0] or cnt.nslots + ncon > pairs.shape[0]:
        return False
    if cnt.n_records + ncon > records.shape[0]:
        return False
    if not rn.from_struct and rn.nefc > efc.shape[0]:
        return False
    if rn.n_log < rn.log_limit and rn.n_log + 2 * ncon > log.shape[0]:
        return False
    cst = consts[0]
    rows = 2 * cst.n_mics * ncon
    if queue.counts[0].count + rows > queue.events.shape[0] or queue.counts[0].pool_used + rows * cst.nmax > queue.re.shape[0]:
        return False
    return True


@njit_inner(cache=True)
def _log(log, rn, t, kind, g1, g2, value):
    """An event log entry into ``log`` (the step buffers' LOG rows) while it has room."""
    if rn.n_log < rn.log_limit:
        e = log[rn.n_log]
        e.time = t
        e.kind = kind
        e.g1 = g1
        e.g2 = g2
        e.value = value
        rn.n_log += 1


@njit_inner(cache=True)
def _impact_pairs(impacts, n):
    """Impacts of a substep counted per geom pair: ``impacts[:n]`` holds each pair's contact
    points next to each other (``event_impulses``), so a box landing flat on its four corners
    is one impact."""
    pairs = 0
    for i in range(n):
        if i == 0 or impacts[i].g1 != impacts[i - 1].g1 or impacts[i].g2 != impacts[i - 1].g2:
            pairs += 1
    return pairs


@njit_inner(cache=True, inline="always")
def _render_block(synth, target, rn, ck, out):
    """Render the pending block ``out`` (mics, n) (``run.render``): the synthesizer's samples
    ``[rendered, rendered + n)``, which must end where the last substep ends (else nothing is
    rendered: ``render_code`` :data:`NOT_RENDERED`). When the stream rings must grow first it
    sets ``run.reason`` :data:`RING` and leaves ``run.render`` set (the next call renders).
    Inlined into :func:`advance` (numba IR): compiled on its own, its library took another copy
    of the whole render tree, 1.1-1.7 s of a cold cache's compilation."""
    cst = synth.consts[0]
    start = cst.rendered
    n = out.shape[1]
    if rn.explicit or rn.nstep < 1 or start + n != rn.n1 - ck.origin:
        rn.render_code = NOT_RENDERED
        return
    # (may_regain not a literal True: the compiled render_streams is the one Synthesizer.render uses)
    code = render_streams(synth, target.bank, target.layout, start, n, np.bool_(True), out, target.zero[0])
    if code > 0:  # the ring must hold the block plus the delays (the gains are computed)
        rn.reason = RING
        rn.need = code
        return
    cst.rendered = start + n
    rn.render_code = code
    rn.render = 0


@njit(cache=True)
def advance(table, layout, out):
    """Run the substeps of ``run`` (see the module docstring) on the state packed in
    ``table`` (:func:`mjsound.synth.packing.pack`; called through
    :class:`mjsound.synth.dispatch.PackedEntry`): ``mj`` (1,) MJ, ``views`` DataViews of the
    mjData, ``reader`` ReaderState, ``buf`` StepBuffers, ``clock`` (1,) CLOCK, ``drive``
    DriveState, ``synth`` SynthState, ``run`` (1,) RUN (inputs and outputs), ``target``
    RenderTarget; then, when ``run.render`` is set, renders the pending block into ``out``
    (mics, n) (the bank dtype, zeroed)."""
    mj, views, reader, buf, clock, drive, synth, run, target = unpack(table, layout)
    rn = run[0]
    cnt = reader.counts[0]
    ck = clock[0]
    nv = reader.dof_parent.shape[0]
    rn.reason = DONE
    while rn.done < rn.nstep:
        if rn.stage == STAGE_STEP:
            if rn.call_step:
                mj_step_now(mj)
            rn.stage = STAGE_READ
        if rn.stage == STAGE_READ:
            if not rn.explicit and not _substep_times(clock, rn, mj):
                rn.reason = CLOCK_JUMP
                return
            ncon = data_ncon(mj) if rn.from_struct else rn.ncon
            rn.n_sust = 0
            rn.n_onset = 0
            rn.n_imp = 0
            if ncon == 0:  # nothing touches: an open impact record closes
                cnt.step += 1
                if cnt.any_open:
                    for j in range(cnt.nslots):
                        reader.pairs[j].open = 0
                    cnt.any_open = 0
                rn.stage = STAGE_DRIVE
            else:
                if not _has_room(reader.counts, reader.pairs, buf.geom, buf.records, buf.efc, buf.log, rn, synth.consts,
                                 synth.queue, ncon):
                    rn.reason = ROOM
                    rn.need = ncon
                    return
                if rn.from_struct:
                    gather_contacts(mj, buf, ncon)
                    efc = data_efc_force(mj)
                else:
                    efc = buf.efc[: rn.nefc]
                cnt.step += 1
                _, ns, nh, n_onset = read_pairs(reader, buf, views, ncon, efc, rn.t0, rn.t1)
                rn.n_sust = ns
                rn.n_hits = nh
                rn.n_onset = n_onset
                rn.stage = STAGE_IMPULSES if n_onset else STAGE_LOG
        if rn.stage == STAGE_IMPULSES:
            k = rn.n_hits
            jn = buf.jn[:k]
            minv = buf.minv_jt[:k]
            normal_jacobians(reader, buf.hits, k, views.cdof, views.subtree_com, jn)
            if nv > 0 and k > 0:
                if mj[0].solve_fn:
                    mj_solve_now(mj, minv, jn, k)
                elif not rn.solved:
                    rn.reason = SOLVE
                    rn.need = k
                    return
            rn.solved = 0
            n_imp, stats = event_impulses(reader, buf, rn.n_onset, jn, minv)
            write_records(reader, buf, rn.n_onset, stats, rn.t0)
            rn.n_imp = n_imp
            rn.stage = STAGE_QUEUE
        if rn.stage == STAGE_QUEUE:
            pulses = rn.n_imp > 0 and drive.prm[0].pulses != 0
            if pulses and not pulse_room(drive.pulses, rn.n_imp):
                rn.reason = PULSES  # Python moves the waiting pulses to its track (and grows the rows)
                return
            sync_poses(drive, views, synth)
            t_ev = max(rn.t0 - ck.origin / ck.fs, (rn.n0 - ck.origin) / ck.fs)
            if queue_impacts(drive, synth, buf, rn.n_imp, t_ev):
                rn.reason = AMPLITUDE
                rn.need = rn.n_imp
                return
            cnt.impacts += _impact_pairs(buf.impacts, rn.n_imp)
            if pulses:  # their clicks and contact-microphone pulses, rendered into the track after the substeps
                queue_pulses(drive.pulses, buf.impacts, rn.n_imp, t_ev, views, synth.mics)
            rn.stage = STAGE_LOG
        if rn.stage == STAGE_LOG:
            if rn.n_log < rn.log_limit:  # (no log, as in the wrappers, or a full one: no call per row)
                log = buf.log
                i = 0
                while i < rn.n_imp:  # one entry per geom pair: its contact points' impulses summed
                    im = buf.impacts[i]
                    total = im.impulse
                    j = i + 1
                    while j < rn.n_imp and buf.impacts[j].g1 == im.g1 and buf.impacts[j].g2 == im.g2:
                        total += buf.impacts[j].impulse
                        j += 1
                    _log(log, rn, rn.t0, np.int64(LOG_IMPACT), im.g1, im.g2, total)  # (one _log for both kinds)
                    i = j
                for i in range(rn.n_sust):
                    row = buf.sustained[i]
                    _log(log, rn, rn.t0, row.kind, row.g1, row.g2, row.speed)
            rn.stage = STAGE_DRIVE
        if rn.stage == STAGE_DRIVE:
            k0 = rn.n0 - ck.origin
            k1 = rn.n1 - ck.origin
            ns = rn.n_sust
            if drive.prm[0].sustained and ns and k1 > k0:
                nm, need = missing_streams(drive, synth, buf, ns, k1)
                if nm:
                    rn.reason = STREAMS
                    rn.n_missing = nm
                    return
                if need:
                    rn.reason = RING
                    rn.need = need
                    return
                drive_sustained(drive, synth, buf, ns, k0, k1)
            if not rn.explicit:
                ck.k += 1
            rn.done += 1
            rn.stage = STAGE_STEP
    ps = drive.pulses
    if rn.drives_due != DRIVES_HANDED:  # (resumed after the actuators' block: all this is done)
        if drive.prm[0].pulses and not render_waiting(ps):
            rn.reason = PULSES  # the pulse track must grow: Python renders the waiting pulses
            return
        sync_poses(drive, views, synth)
        rn.poses_current = 1
        if rn.drives_due == DRIVES_DUE:  # the actuators' block, read now that the substeps are done
            rn.drives_due = DRIVES_HANDED
            rn.reason = DRIVES
            return
    rn.drives_due = DRIVES_NONE
    if rn.render:
        _render_block(synth, target, rn, ck, out)
        if rn.render_code == RENDERED and drive.prm[0].mix_pulses:
            take_into_block(ps.track, out)
            rn.pulses_mixed = 1
    # (one flag for Python to read after the call instead of four counts; the impact records
    # wait in their rows until they are read or the rows are full)
    rn.collect = rn.n_log > 0 or cnt.n_bad > 0 or cnt.n_huge > 0 or cnt.clamped > 0
