"""Named state records of the synthesizer that numba kernels read and write.

Defined once here (see ``docs/design.md`` for who writes which field); a scalar record is a
one-element array updated in place. The synthesizer owns all of them and replaces an array
only in its own methods (growing a buffer, rebuilding the voice layout), after which
:meth:`mjsound.synth.Synthesizer.kernel_state` hands out the new ones.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["STREAM", "STREAMS", "EVENT", "QUEUE", "SYNTH_CONSTS", "CHANNEL", "AIR", "DEAF", "ObjectTable", "QueueState", "StreamState",
           "SynthState", "EventRows", "SourceRows", "BankLayout", "Bank", "RenderTarget", "TRACK", "TrackState",
           "DIRECTIONS", "DirectionState"]

i8, f8 = np.int64, np.float64

#: One persistent sliding / rolling noise stream: live, synthesizer object index, last drive's
#: source samples ``[k0, k1)``, samples generated up to ``gen``, last sample with a non-zero
#: drive, sample of the last gain update and whether new gains are due, noise generator state
#: (splitmix64 as int64); drive amplitude [N], low-pass coefficient, low-pass output, point
#: [m] and unit force direction (world) of the last drive.
STREAM = np.dtype([("live", i8), ("obj", i8), ("k0", i8), ("k1", i8), ("gen", i8), ("last", i8), ("gupd", i8),
                   ("due", i8), ("rng", i8), ("amp", f8), ("alpha", f8), ("y", f8), ("p", f8, (3,)),
                   ("n", f8, (3,))])

#: The streams' counters: streams in use, largest integer delay of any stream [samples].
STREAMS = np.dtype([("n", i8), ("dmax", i8)])

#: A pending event of the queue: object index, microphone, absolute sample, offset and
#: width of its amplitudes in the pool, kind (0: add the amplitudes; 1: activate a forcing
#: source's modes).
EVENT = np.dtype([("obj", i8), ("mic", i8), ("sample", i8), ("offset", i8), ("width", i8), ("kind", i8)])

#: The queue's counters: events, pool entries used, earliest pending sample.
QUEUE = np.dtype([("count", i8), ("pool_used", i8), ("next_sample", i8)])

#: Constants and the render position: speed of sound [m/s], sample rate [Hz], smallest
#: distance [m], sample rounding tolerance [samples], correction grid [samples], samples
#: rendered, ring slack [samples], widest object [modes], microphones, culling thresholds
#: (squared amplitude relative to the peak, absolute [Pa^2]).
SYNTH_CONSTS = np.dtype([("c", f8), ("fs", f8), ("rmin", f8), ("tol", f8), ("grid", i8), ("rendered", i8),
                         ("slack", i8), ("nmax", i8), ("n_mics", i8), ("cull2", f8), ("floor2", f8)])

#: One output channel: ``owner`` is :data:`AIR` (-1) for an air microphone, the object index
#: of a contact microphone's body (which alone it hears, with no delay), or :data:`DEAF` (-2)
#: for a contact microphone on a body without modes; its complex weights per mode of the
#: owner (``(phi_i(x) . n) lambda_i^2``, :func:`mjsound.synth.contact_mic.modal_weights`)
#: start at ``w_off`` in ``SynthState.chan_w``. An air microphone has ``w_off = -1``, or, when
#: it is an image microphone (:meth:`mjsound.synth.synthesizer.Synthesizer.set_channel_response`),
#: the start of its real gain per mode of every object: mode ``i`` of the object table
#: (``ObjectTable.mode_off``) is multiplied by ``chan_w[w_off + i].real``.
CHANNEL = np.dtype([("owner", i8), ("w_off", i8)])
AIR, DEAF = -1, -2


class ObjectTable(NamedTuple):
    """Every object's modal data in flat arrays indexed by object index ``o``: surface points
    ``pts[pts_off[o]:pts_off[o+1]]`` (object frame) [m] sorted along the object's coordinate
    axis ``pts_axis[o]`` (for :func:`.streams.nearest_sorted`), ``pts_index`` the sample index
    of each of those rows in the model (the row of its shapes), shapes ``shk[shk_off[o]:...]``
    as (points, 3, modes) in sample order, per-mode values ``[mode_off[o]:mode_off[o+1]]`` of
    ``wd`` (damped angular frequency [rad/s]), ``w`` (radiation weight [Pa m]), ``lam``
    (complex pole [1/s]) and ``leps`` (log of the pole-rounding ratio)."""

    pts: np.ndarray
    pts_off: np.ndarray
    pts_index: np.ndarray
    pts_axis: np.ndarray
    shk: np.ndarray
    shk_off: np.ndarray
    mode_off: np.ndarray
    wd: np.ndarray
    w: np.ndarray
    lam: np.ndarray
    leps: np.ndarray


class QueueState(NamedTuple):
    """The event queue's arrays (owner: :class:`mjsound.synth.queue.EventQueue`)."""

    events: np.ndarray  # (cap,) EVENT
    re: np.ndarray  # (pool,) amplitudes, real part
    im: np.ndarray  # (pool,) imaginary part
    counts: np.ndarray  # (1,) QUEUE


class StreamState(NamedTuple):
    """The persistent streams (owner: Synthesizer). ``dts`` and ``dfac`` keep the
    transcendental factors of each stream's last gains (:func:`.streams.stream_gains`), reused
    while its sub-sample delay to a microphone stays the same (an object at rest)."""

    table: np.ndarray  # (cap,) STREAM
    D: np.ndarray  # (cap, mics) int64: integer delay to each microphone [samples]
    gr: np.ndarray  # (cap, mics, nmax) complex gain, real part (state dtype)
    gi: np.ndarray  # (cap, mics, nmax) imaginary part
    ring: np.ndarray  # (cap, L) force [N] of source sample k at ring[s, k & (L - 1)]
    counts: np.ndarray  # (1,) STREAMS
    dts: np.ndarray  # (cap, mics) float64 sub-sample delay [s] the delay factors were made for (NaN: none)
    dfac: np.ndarray  # (cap, mics, 3, nmax) float64 delay factors per mode: e^{Re lam dts}, cos, sin of Im lam dts


class SynthState(NamedTuple):
    """What the per-step kernels need of the synthesizer (:meth:`Synthesizer.kernel_state`)."""

    objects: ObjectTable
    pos: np.ndarray  # (objects, 3) world position of each object [m]
    R: np.ndarray  # (objects, 3, 3) object-to-world rotation
    mics: np.ndarray  # (mics, 3) world positions [m]
    consts: np.ndarray  # (1,) SYNTH_CONSTS
    queue: QueueState
    streams: StreamState
    channels: np.ndarray  # (mics,) CHANNEL: air or contact microphone
    chan_w: np.ndarray  # complex128 contact weights (CHANNEL.w_off)


class EventRows(NamedTuple):
    """A block's events placed in the microphone banks (:meth:`.queue.EventQueue.take`):
    bank ``m``'s rows are ``ptr[m] : ptr[m + 1]``, sorted by sample."""

    ptr: np.ndarray  # (banks + 1,) int64
    sample: np.ndarray  # (k,) int64 absolute sample
    kind: np.ndarray  # (k,) int8: 0 add the amplitudes, 1 activate the modes a source drives
    re: np.ndarray  # (k, width) amplitudes, real part (already carrying the sub-sample phase)
    im: np.ndarray  # (k, width) imaginary part


class SourceRows(NamedTuple):
    """A block's forcing sources placed in the microphone banks: bank ``m``'s rows are
    ``ptr[m] : ptr[m + 1]``."""

    ptr: np.ndarray  # (banks + 1,) int64
    a: np.ndarray  # (q,) int64 first absolute sample the source acts on
    b: np.ndarray  # (q,) int64 end (exclusive)
    gr: np.ndarray  # (q, width) complex per-mode gain, real part (state dtype)
    gi: np.ndarray  # (q, width) imaginary part
    F: np.ndarray  # (q, n) force samples on this block [N] (block-relative index)


class BankLayout(NamedTuple):
    """Where each voice (object ``o``, microphone ``m``: voice id ``vbase[o] + m``) sits in the
    microphone banks (one contiguous bank of modes per microphone)."""

    vbase: np.ndarray  # (objects,) int64 first voice id of each object index (-1: removed)
    v_rel: np.ndarray  # (voices,) int64 offset of the voice inside its microphone's bank
    v_len: np.ndarray  # (voices,) int64 modes of the voice
    v_mic: np.ndarray  # (voices,) int64 its microphone
    width: int  # widest bank [modes]


#: How the direction factors follow the microphones (:mod:`.directivity`): the cosine of the
#: smallest turn of the direction that makes them again, the smallest ``|D|`` heard.
DIRECTIONS = np.dtype([("cos_step", f8), ("floor", f8)])


class DirectionState(NamedTuple):
    """The direction factors ``D`` of the air microphones' voices (:mod:`.directivity`): per
    object index ``o`` the highest order ``order[o]`` of its modes' fits (-1: the same in every
    direction, never touched); per kept mode ``g`` (the flat order of
    :attr:`ObjectTable.mode_off`) its coefficients ``coef_r + j coef_i`` at ``msh_off[g] .. msh_off[g + 1]``
    (harmonic ``k`` at ``msh_off[g] + k``, up to the mode's own order); per voice (object-major ids, :class:`BankLayout`) the
    direction ``u`` its factors were made for; per mode of the banks (the flat order of
    :class:`Bank`) the factor applied to the state ``ar + j ai``, this block's target
    ``tr + j ti``, per-sample log ratio ``lr + j li`` (0: none) and per-sample factor
    ``rho_r + j rho_i = e^{lr + j li}``; per bank whether this block ramps and whether it holds a
    directional mode at all (``on``), per mode whether it is one (``dmode``)."""

    order: np.ndarray  # (objects,) int64
    msh_off: np.ndarray  # (kept modes + 1,) int64
    coef_r: np.ndarray  # (k,) float64
    coef_i: np.ndarray  # (k,) float64
    u: np.ndarray  # (voices, 3) float64 object frame (NaN: not made yet)
    ar: np.ndarray  # (modes,) float64
    ai: np.ndarray
    tr: np.ndarray
    ti: np.ndarray
    lr: np.ndarray
    li: np.ndarray
    rho_r: np.ndarray
    rho_i: np.ndarray
    ramp: np.ndarray  # (banks,) bool
    on: np.ndarray  # (banks,) bool
    dmode: np.ndarray  # (modes,) bool
    n_objects: np.ndarray  # (1,) int64 objects with a direction (0: nothing to do)
    params: np.ndarray  # (1,) DIRECTIONS
    sh: np.ndarray  # (microphones, (max order + 1)^2) float64 scratch: one object's harmonics per voice
    sh_tab: np.ndarray  # (3, (max order + 1)^2) float64 recurrence factors (:func:`.directivity.sh_tables`)


class Bank(NamedTuple):
    """The oscillator state of every mode of every voice, laid out bank after bank, and the
    banks (a bank renders into ``out[mic[b]]``)."""

    zr: np.ndarray  # (modes,) float64 state, real part
    zi: np.ndarray  # (modes,) float64 state, imaginary part
    peak2: np.ndarray  # (modes,) float64 largest |z|^2 since the mode was (re)started
    active: np.ndarray  # (modes,) bool which modes run
    pr: np.ndarray  # (modes,) rounded pole, real part (state dtype)
    pi: np.ndarray  # (modes,) imaginary part
    corr_r: np.ndarray  # (modes,) float64 grid correction (p_exact / p_rounded)^grid, real part
    corr_i: np.ndarray  # (modes,) imaginary part
    start: np.ndarray  # (banks,) int64 first mode of each bank
    length: np.ndarray  # (banks,) int64 modes of each bank
    mic: np.ndarray  # (banks,) int64 output channel of each bank
    live: np.ndarray  # (banks,) bool: has running modes (kept up to date by render_all)
    direction: DirectionState  # the air microphones' direction factors (:mod:`.directivity`)


class RenderTarget(NamedTuple):
    """What the step kernel needs to render the pending block itself, right after its
    substeps (:meth:`mjsound.synth.Synthesizer.render_target`; the block's array is passed
    on its own, so that this tuple stays the same object from call to call)."""

    bank: Bank
    layout: BankLayout
    zero: np.ndarray  # (1,) state dtype: 0 (fixes the render's accumulator type)
    empty: np.ndarray  # (mics, 0) state dtype: the block argument of a call that renders nothing


#: A pulse track's position (owner: :class:`mjsound.synth.bandlimited.PulseTrack`): sample
#: rate [Hz], first sample not handed out yet, the samples pending pulses reach
#: ``[pending_from, pending_until)`` (empty: nothing pending), pulses dropped (a window too
#: long, a non-finite field or velocity).
TRACK = np.dtype([("fs", f8), ("start", i8), ("pending_from", i8), ("pending_until", i8), ("dropped", i8)])


class TrackState(NamedTuple):
    """A pulse track's arrays (owner: :class:`mjsound.synth.bandlimited.PulseTrack`, which
    replaces the tuple when the ring or the scratch grows; the step kernel renders and mixes
    through it, :func:`mjsound.synth.bandlimited.add_pulses` and ``take_into_block``)."""

    rec: np.ndarray  # (1,) TRACK
    acc: np.ndarray  # (channels, capacity) float64 ring: absolute sample u at u & (capacity - 1)
    work: np.ndarray  # (n,) complex128 scratch of the longest window so far
    out: np.ndarray  # (n,) float64 scratch
    table: np.ndarray  # (n - 1,) complex128 inverse twiddle factors up to length n
