"""The per-env-step path of :meth:`AudioSimulator.substeps`, written flat.

:func:`make_substeps` makes the simulator's ``substeps(nstep, render=True)`` once, as a
closure over the objects that live as long as the simulator. An env step's Python runs
between MuJoCo's work and numba's, with cold caches: there each function entered and each
attribute looked up costs more than the arithmetic between (the README's profile of a wrapped
env step measures it), so this path enters as few functions as it can; what is rare (a
hand-back, impacts to collect, a clock jump) stays in the simulator's methods.
"""

from __future__ import annotations

import numpy as np

from ..synth.kernels import RENDERED
from .images import fold
from .records import NOT_RENDERED

__all__ = ["make_substeps"]


def make_substeps(sim):
    """``substeps(nstep: int, render: bool = True)``: the body of
    :meth:`AudioSimulator.substeps` for ``sim``, with the simulator's kernel, reader,
    synthesizer, clock and the fields of the run record it reads bound once."""
    kern, reader, synth, clock, opt = sim._kernel, sim.reader, sim.synth, sim.clock, sim._opt
    run, mj, views, clock_rec = kern.run, kern.mj, kern.views, kern.clock
    f = kern.f
    collect_f, poses_f, code_f, mixed_f = f["collect"], f["poses_current"], f["render_code"], f["pulses_mixed"]
    span = clock.span
    kernel_call = kern.substeps_call()
    fused = sim._fused and synth is not None
    f32 = synth is not None and synth.dtype == np.float32  # (kernel_block returns such a block as is)
    drive_state, kernel_state, on_stop = sim._drive_state, sim._kernel_state, sim._on_stop
    mj_step, model, data, pulses = sim._mj.mj_step, sim.model, sim.data, sim.pulses
    images, n_air = (sim.images if len(sim.images) else None), sim.n_air

    def substeps(nstep: int, render: bool = True) -> None:
        k0, n0, n1 = span(nstep)
        if not fused or k0 + nstep > clock.k_max_int64 or opt.timestep != clock.timestep:
            for _ in range(nstep):
                mj_step(model, data)
                sim.step(render=False)
            return
        synth.poses_current = False
        seg = sim._seg = (k0, n0)
        pending = sim._pending
        block = None
        if render and nstep > 0 and sim._ready is None and not sim._held and synth.renders_in_kernel:
            block = synth.new_block(pending + n1 - n0)
        rs = reader.state()  # (the state as _kernel_state makes it)
        state = (mj, views, rs, reader.buffers, clock_rec, drive_state(rs), synth.kernel_state(), run,
                 synth.render_target())
        if not kernel_call(state, nstep, block, sim._log_room() if sim.keep_events else 0):
            kern.resume(kernel_state, block, on_stop, synth)
        if collect_f[0]:
            sim._collect()
        if sim._seg is seg:  # (no clock jump counted a segment during the call: all in one go; as _count)
            if not pending:
                sim._pending_n0 = n0
            sim._pending = pending + n1 - n0
            sim.steps += nstep
            sim.samples += n1 - n0
        else:
            sim._count_segment()
        synth.poses_current = bool(poses_f[0])
        if block is not None:
            code = code_f[0]
            if code != NOT_RENDERED:  # (the pending samples are rendered: flush returns them)
                sim._pending = 0
                if code != RENDERED or not f32:
                    block = synth.kernel_block(block, code == RENDERED)
                if not mixed_f[0]:  # (the kernel mixes the pulse track into a float32 block itself)
                    block = pulses.mix(block)
                if images is not None:  # (image microphones' rows into their channels, .images)
                    block = fold(block, n_air, images)
                if sim.on_block is None and not sim._held:  # (as _deliver)
                    sim._ready = block
                else:
                    sim._ready = sim._deliver(block, sim._pending_n0)

    return substeps
