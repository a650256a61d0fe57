"""Named state records of the per-step path (contacts -> events -> synthesizer queue).

Every piece of state that crosses into numba is defined here once, as a numpy structured
dtype (read and written by field name, ``pairs[j].last``) or a :class:`typing.NamedTuple` of
arrays (one owner's arrays together). The owner of each record is the only one that
allocates or replaces it; the step kernel (:mod:`.step`) writes the fields that the table in
``docs/design.md`` lists. A scalar record is a one-element array (``counts[0].nslots``), so
numba updates it in place and Python reads it after the call.

Units: SI (s, m, N, N s, m/s); samples are absolute sample indices of the synthesizer's
clock unless a field says otherwise.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..synth.records import RenderTarget, SynthState, TrackState

__all__ = ["CLOCK", "MJ", "READER_PARAMS", "READER_COUNTS", "PAIR", "GEOM", "BODY", "PAIR_ROW", "HIT", "ONSET",
           "IMPACT", "RECORD", "LOG", "MISSING", "SOUND", "DRIVE_PARAMS", "RUN", "NOT_RENDERED", "CLICK_PARAMS",
           "CLICK_BODY", "CLICK_SITE", "CLICK_AIR", "CLICK_GEOM", "PULSE_COUNTS", "ReaderState", "StepBuffers", "DataViews", "DriveState", "KernelState",
           "ClickModel", "PulseState", "record", "ContactQuantities", "PairGroups", "PairSteps", "contact_quantities_of",
           "pair_scratch"]

i8, f8 = np.int64, np.float64

#: The sample clock (owner: :class:`mjsound.sim.clock.SampleClock`). Step ``k`` starts at
#: ``(a0 + k b) / den`` seconds; its first sample is ``ceil((a0 + k b) fs / den)``; ``k`` steps
#: are counted; the synthesizer's sample 0 is absolute sample ``origin``.
CLOCK = np.dtype([("a0", i8), ("b", i8), ("den", i8), ("fs", i8), ("k", i8), ("origin", i8),
                  ("t_start", f8), ("timestep", f8)])

#: MuJoCo as the fused loop reaches it (owner: :func:`mjsound.sim.fused.mj_link`): addresses
#: of ``mj_step`` / ``mj_solveM`` (0: not available) and of the mjModel / mjData, then byte
#: offsets of the mjData fields read (``ncon`` ...) and of the mjContact fields; ``layout_ok``
#: is 0 when the struct description disagrees with the bindings (contacts are then copied in
#: by Python).
MJ = np.dtype([("step_fn", i8), ("solve_fn", i8), ("model", i8), ("data", i8), ("layout_ok", i8),
               ("ncon", i8), ("nefc", i8), ("time", i8), ("contact", i8), ("efc_force", i8),
               ("contact_size", i8), ("c_pos", i8), ("c_frame", i8), ("c_geom", i8), ("c_dim", i8),
               ("c_efc_address", i8)])

#: The reader's thresholds (owner: :class:`mjsound.sim.contacts.ContactReader`; see its
#: docstring): speeds [m/s], times [s], largest force [N] and impulse [N s]; whether the
#: friction cone is pyramidal (its normal force is the sum of the facets' forces).
READER_PARAMS = np.dtype([("v_impact", f8), ("v_hard", f8), ("min_apart_s", f8), ("refractory_s", f8),
                          ("max_event_s", f8), ("v_slide", f8), ("v_roll", f8), ("max_force", f8),
                          ("max_impulse", f8), ("pyramidal", i8)])

#: The reader's counters (owner: ContactReader; written by the step kernel): pair slots in
#: use, whether an impact record may be open, steps read, record rows waiting in
#: ``StepBuffers.records`` (Python takes them when they are read or the rows are full),
#: clamped forces (non-finite / huge; Python warns and zeroes them), sliding and rolling
#: pair-steps; since the reset: impacts made (the impact rows with a positive impulse: what
#: ``AudioSimulator.n_impacts`` counts) and impact records with an audible geom
#: (``GEOM.audible``); waiting record rows whose impulse was clamped (Python warns).
READER_COUNTS = np.dtype([("nslots", i8), ("any_open", i8), ("step", i8), ("n_records", i8), ("n_bad", i8),
                          ("n_huge", i8), ("slide_steps", i8), ("roll_steps", i8), ("impacts", i8),
                          ("audible", i8), ("clamped", i8)])

#: One geom pair's state (owner: ContactReader, a table of slots; written by the state
#: machine :func:`mjsound.sim.pairs.update_pairs`): approach speed of its last step [m/s],
#: when it last touched and last made an impact [s]; its open impact record (start time,
#: speed, sum F dt [N s], end time, steps) and the previous record's sums banked at an onset
#: (which close that record in Python); the last step it touched, steps it has been calm,
#: whether a record is open.
PAIR = np.dtype([("vprev", f8), ("touch", f8), ("hit", f8), ("rec_time", f8), ("rec_speed", f8),
                 ("rec_impulse", f8), ("rec_end", f8), ("prev_impulse", f8), ("prev_end", f8),
                 ("last", i8), ("calm", i8), ("open", i8), ("rec_steps", i8), ("prev_steps", i8)])

#: Per geom (owner: ContactReader): its body, whether it is a plane (no rolling radius), its
#: acoustic restitution (NaN: unknown) and whether an impact on it is heard
#: (``ContactReader.set_audible``; counted in ``READER_COUNTS.audible``).
GEOM = np.dtype([("body", i8), ("plane", i8), ("restitution", f8), ("audible", i8)])

#: Per body (owner: ContactReader): root body, dofs (``mj_jac``'s walk), moving mass of its
#: subtree and of its whole tree [kg] (inf: welded to the world).
BODY = np.dtype([("root", i8), ("dofnum", i8), ("dofadr", i8), ("parent", i8), ("tree_mass", f8),
                 ("root_mass", f8)])

#: A touching geom pair of one step (written by the step kernel into ``StepBuffers.rows``):
#: geoms, kind (0 silent, 1 slide, 2 roll), state slot, whether an impact starts, total
#: normal force [N], slip or rolling speed [m/s], force-weighted point [m] and unit normal.
PAIR_ROW = np.dtype([("g1", i8), ("g2", i8), ("kind", i8), ("slot", i8), ("onset", i8), ("force", f8),
                     ("speed", f8), ("point", f8, (3,)), ("normal", f8, (3,))])

#: An impacting contact of an onset pair: its pair row, geoms, point [m], normal, approach
#: speed [m/s].
HIT = np.dtype([("pair", i8), ("g1", i8), ("g2", i8), ("point", f8, (3,)), ("normal", f8, (3,)), ("speed", f8)])

#: An impact event (one onset pair): its slot and its first hit (hits run to the next
#: event's ``first``; one more row holds the number of hits).
ONSET = np.dtype([("slot", i8), ("first", i8)])

#: An impact at one contact point: impulse [N s] on geom2 along the normal (geom1 gets the
#: opposite), approach speed [m/s], the pair's restitution (the impulse's ``e``; it bounds the
#: modes' energy, :func:`mjsound.sim.drive.impact_sides`).
IMPACT = np.dtype([("g1", i8), ("g2", i8), ("point", f8, (3,)), ("normal", f8, (3,)), ("impulse", f8),
                   ("speed", f8), ("restitution", f8)])

#: An impact event's record (made into :class:`mjsound.sim.contacts.ImpactRecord` by
#: ``ContactReader.add_records``): onset time [s], geoms, largest approach speed, predicted
#: impulse, restitution, slot, clamped, then the slot's previous record's sum F dt, steps and
#: end time (which close it).
RECORD = np.dtype([("time", f8), ("g1", i8), ("g2", i8), ("speed", f8), ("impulse_pred", f8),
                   ("restitution", f8), ("slot", i8), ("clamped", i8), ("prev_impulse", f8),
                   ("prev_steps", i8), ("prev_end", f8)])

#: An event log entry (``AudioSimulator.event_log``): time [s], kind (0 impact, 1 slide,
#: 2 roll), geoms, value (impulse [N s] or speed [m/s]).
LOG = np.dtype([("time", f8), ("kind", i8), ("g1", i8), ("g2", i8), ("value", f8)])

#: What Python must supply before the kernel can go on: (row, side) without a stream.
MISSING = np.dtype([("a", i8), ("b", i8)])

#: Per geom, how it sounds (owner: AudioSimulator): synthesizer object index (-1: silent);
#: what Hertz's contact time of its impacts (:func:`mjsound.synth.pulse.hertz_coef`) takes of
#: it when it is struck (a sounding geom: its object's mass [kg], its radius of curvature [m],
#: its material's compliance ``(1 - nu^2) / E`` [1/Pa]) and when it strikes a sounding geom
#: (its body's moving subtree mass, inf: welded to the world; its contact radius, inf: flat;
#: its material's compliance, 0: rigid or none); and, where its body is a thin hollow shell
#: (:func:`mjsound.sim.clicks.shell_compliances`), its wall's point-load compliance [m/N] when it
#: is struck (only an object analysed hollow: its modes are the wall's) and when it strikes (0:
#: solid).
SOUND = np.dtype([("obj", i8), ("mass", f8), ("radius", f8), ("compliance", f8), ("other_mass", f8),
                  ("other_radius", f8), ("other_compliance", f8), ("shell", f8),
                  ("other_shell", f8)])

#: The drive's constants (owner: AudioSimulator): slide / roll roughness [1/(m/s)] and
#: low-pass length [m], samples between a stream's gain updates, whether sustained contacts
#: sound, how microphones move (0 fixed, 1 ``mics[m] = source[rows[m]] + offsets[m]``) and
#: from which positions (0 body ``xpos``, 1 ``site_xpos``), whether a substep's impacts make
#: pulses (their clicks and contact-microphone pulses: :mod:`.clicks`), and whether the kernel
#: mixes the pulse track into the block it renders (float32 blocks only: a float64 block is
#: mixed by Python after its conversion to float32, as :meth:`ImpactPulses.mix` does).
DRIVE_PARAMS = np.dtype([("rough_slide", f8), ("rough_roll", f8), ("len_slide", f8), ("len_roll", f8),
                         ("regain", i8), ("sustained", i8), ("mic_mode", i8), ("mic_source", i8), ("pulses", i8),
                         ("mix_pulses", i8)])

#: One call of the step kernel (owner: AudioSimulator, which sets the inputs and reads the
#: outputs). Inputs: substeps asked (``nstep``) and done, whether the kernel calls
#: ``mj_step`` itself, whether the contacts come from the mjData struct or Python copied them
#: into the buffers (then ``ncon``, ``nefc``), whether the step's times ``t0, t1`` [s] and
#: samples ``[n0, n1)`` are given (replay) instead of coming from the clock, the log's limit,
#: ``solved`` (Python supplied ``M^-1 Jn^T``). State of the current substep: ``stage``, its
#: times and samples, sustained rows, hits, onset pairs and impacts. Outputs: why it stopped
#: (``reason``, ``need``, ``n_missing``), log entries written (counting up over calls until
#: Python takes them), whether poses and microphones are current.
#: ``render`` (input): after the last substep, render the pending block into the call's block
#: argument (it must end where the last substep ends); ``render_code`` (output): the render's
#: code (``mjsound.synth.kernels.RENDERED`` or ``RENDERED_NONFINITE``), :data:`NOT_RENDERED`
#: when no block was rendered; ``pulses_mixed`` (output): the pulse track is mixed into that
#: block already (``DRIVE_PARAMS.mix_pulses`` and every sample finite); ``collect`` (output):
#: there is something for Python to take after the call (log entries, clamped forces or
#: impulses to warn of: ``AudioSimulator._collect``; the reader's impact records wait).
RUN = np.dtype([("nstep", i8), ("done", i8), ("call_step", i8), ("from_struct", i8), ("ncon", i8), ("nefc", i8),
                ("explicit", i8), ("log_limit", i8), ("solved", i8), ("stage", i8), ("t0", f8), ("t1", f8),
                ("n0", i8), ("n1", i8), ("n_sust", i8), ("n_hits", i8), ("n_onset", i8), ("n_imp", i8),
                ("reason", i8), ("need", i8), ("n_missing", i8), ("n_log", i8),
                ("poses_current", i8), ("render", i8), ("render_code", i8), ("pulses_mixed", i8),
                ("collect", i8), ("drives_due", i8)])
#: ``RUN.render_code`` of a call that rendered no block.
NOT_RENDERED = 1


#: Impact pulses' constants (owner: :class:`mjsound.sim.clicks.ImpactPulses`): whether air
#: microphones hear clicks, how many air microphones (channels ``0 .. n_air - 1``; contact
#: microphones follow), speed of sound [m/s], the compliance both geoms of an impact count
#: with when neither has a material [1/Pa].
CLICK_PARAMS = np.dtype([("clicks", i8), ("n_air", i8), ("c", f8), ("unknown_compliance", f8)])

#: Per body, what its impact pulses need (owner: ImpactPulses): whether it moves (not welded
#: to the world, not mocap, with mass), mass [kg], centre of mass in the body frame [m],
#: principal axes in the body frame (columns), displaced plus added air mass along each
#: principal axis [kg], equivalent sphere radius [m], principal inertia [kg m^2], the mass
#: it strikes with in the Hertz contact time (its subtree's; inf: welded to the world) [kg].
CLICK_BODY = np.dtype([("dynamic", i8), ("mass", f8), ("ipos", f8, (3,)), ("iframe", f8, (3, 3)),
                       ("masses", f8, (3,)), ("a_eq", f8), ("inertia", f8, (3,)), ("hertz_mass", f8)])

#: Per geom, its impact pulses' contact (owner: ImpactPulses): its body, whether it has an
#: acoustic material, the material's compliance ``(1 - nu^2) / E`` [1/Pa] (0: none, rigid),
#: its contact radius [m] (inf: flat) and, where its body is a thin hollow shell, the wall's
#: point-load compliance ``1 / k`` [m/N] (0: solid; :func:`mjsound.sim.clicks.shell_compliances`).
CLICK_GEOM = np.dtype([("body", i8), ("has_material", i8), ("compliance", f8), ("radius", f8),
                       ("shell_compliance", f8), ("restitution", f8)])

#: Pulse rows waiting in :class:`PulseState` for the pulse track.
PULSE_COUNTS = np.dtype([("n", i8)])

#: A contact microphone (owner: ImpactPulses): its body, site position and sensing axis in the
#: body frame.
CLICK_SITE = np.dtype([("body", i8), ("pos", f8, (3,)), ("axis", f8, (3,))])

#: The air rows a click is heard at, in the order its pulses are made (owner: ImpactPulses):
#: the row's position among the microphones the kernel is given, the output channel the pulse
#: goes to and its gain (an image microphone's: its parent's channel and the click's
#: reflection factor, :mod:`mjsound.sim.images`; else its own and 1), and whether it joins the
#: window of the pulse made before it (:data:`mjsound.synth.bandlimited.PULSE_DTYPE`).
CLICK_AIR = np.dtype([("mic", i8), ("channel", i8), ("gain", f8), ("joins", i8)])


def record(dtype: np.dtype, **values) -> np.ndarray:
    """A one-element array of ``dtype`` (a scalar record numba updates in place), zeroed and
    then set from ``values``."""
    r = np.zeros(1, dtype)
    for k, v in values.items():
        r[k] = v
    return r


class ReaderState(NamedTuple):
    """The contact reader's state (owner: ContactReader)."""

    prm: np.ndarray  # (1,) READER_PARAMS
    counts: np.ndarray  # (1,) READER_COUNTS
    geoms: np.ndarray  # (ngeom,) GEOM
    bodies: np.ndarray  # (nbody,) BODY
    dof_parent: np.ndarray  # (nv,) int64: parent dof (mj_jac's walk)
    hkeys: np.ndarray  # (table,) int64: open-addressing table pair key -> slot (-1: empty)
    hvals: np.ndarray  # (table,) int64
    pairs: np.ndarray  # (slots,) PAIR


class ContactQuantities(NamedTuple):
    """Per contact of a substep (:func:`mjsound.sim.pairs.contact_quantities`; rows ``< ncon``)."""

    fn: np.ndarray  # (cap,) normal force [N]
    nrm: np.ndarray  # (cap, 3) unit normal
    vrel: np.ndarray  # (cap, 3) relative velocity [m/s]
    vapp: np.ndarray  # (cap,) approach speed [m/s]
    vslip: np.ndarray  # (cap,) slip speed [m/s]
    vroll: np.ndarray  # (cap,) rolling speed [m/s]
    sides: np.ndarray  # (5, 3) scratch: each side's point and angular velocity, their difference


class PairGroups(NamedTuple):
    """The substep's contacts grouped by geom pair (:func:`mjsound.sim.pairs.group_pairs`;
    pair ``p``'s contacts are ``order[starts[p]:starts[p + 1]]``)."""

    keys: np.ndarray  # (cap,) int64 pair key of each contact
    order: np.ndarray  # (cap,) int64 contacts sorted by key
    order_b: np.ndarray  # (cap,) int64 the sort's second buffer
    starts: np.ndarray  # (cap + 1,) int64
    pkey: np.ndarray  # (cap,) int64 pair key of each pair
    vmax: np.ndarray  # (cap,) largest approach speed [m/s]
    ftot: np.ndarray  # (cap,) total normal force [N]
    slip: np.ndarray  # (cap,) force-weighted slip speed [m/s]
    roll: np.ndarray  # (cap,) force-weighted rolling speed [m/s]
    point: np.ndarray  # (cap, 3) force-weighted point [m]
    normal: np.ndarray  # (cap, 3) force-weighted unit normal


class PairSteps(NamedTuple):
    """What the pair state machine decided per pair (:func:`mjsound.sim.pairs.update_pairs`)."""

    slot: np.ndarray  # (cap,) int64 pair slot
    onset: np.ndarray  # (cap,) bool: an impact starts
    kind: np.ndarray  # (cap,) int64: 0 none, 1 slide, 2 roll
    speed: np.ndarray  # (cap,) its sliding or rolling speed [m/s]


def contact_quantities_of(cap: int) -> ContactQuantities:
    """Room for the quantities of ``cap`` contacts."""
    return ContactQuantities(np.zeros(cap), np.zeros((cap, 3)), np.zeros((cap, 3)), np.zeros(cap), np.zeros(cap),
                             np.zeros(cap), np.zeros((5, 3)))


def pair_scratch(cap: int) -> tuple[PairGroups, PairSteps]:
    """Room for the groups and state-machine results of ``cap`` contacts."""
    z, zi = np.zeros, (lambda n: np.zeros(n, np.int64))
    groups = PairGroups(zi(cap), zi(cap), zi(cap), zi(cap + 1), zi(cap), z(cap), z(cap), z(cap), z(cap), z((cap, 3)),
                        z((cap, 3)))
    return groups, PairSteps(zi(cap), np.zeros(cap, np.bool_), zi(cap), z(cap))


class StepBuffers(NamedTuple):
    """Buffers of one substep (owner: ContactReader; grown in Python when the kernel asks).
    ``quantities``, ``groups`` and ``steps`` are the contact reading's working arrays (no
    allocation per substep); their contents do not outlive a substep."""

    geom: np.ndarray  # (cap, 2) int32: the contacts, copied from the mjData struct
    pos: np.ndarray  # (cap, 3)
    frame: np.ndarray  # (cap, 9)
    efc_address: np.ndarray  # (cap,) int32
    dim: np.ndarray  # (cap,) int32
    efc: np.ndarray  # (nefc_cap,) constraint forces (when Python copies the contacts)
    rows: np.ndarray  # (cap,) PAIR_ROW: the touching pairs
    sustained: np.ndarray  # (cap,) PAIR_ROW: the pairs that slide or roll
    hits: np.ndarray  # (cap,) HIT
    onsets: np.ndarray  # (cap + 1,) ONSET
    impacts: np.ndarray  # (cap,) IMPACT: the substep's impacts with a positive impulse
    jn: np.ndarray  # (cap, nv) normal Jacobians of the hits
    minv_jt: np.ndarray  # (cap, nv) M^-1 Jn^T
    records: np.ndarray  # (rcap,) RECORD: impact records not yet taken by Python
    missing: np.ndarray  # (2 cap,) MISSING
    log: np.ndarray  # (lcap,) LOG: event log entries not yet taken by Python
    quantities: ContactQuantities
    groups: PairGroups
    steps: PairSteps


class DataViews(NamedTuple):
    """Fixed-size arrays of one MjData (numpy views: valid as long as the MjData lives)."""

    cvel: np.ndarray  # (nbody, 6) (angular, linear) com-based velocity
    subtree_com: np.ndarray  # (nbody, 3)
    geom_xpos: np.ndarray  # (ngeom, 3)
    geom_xmat: np.ndarray  # (ngeom, 9)
    cdof: np.ndarray  # (nv, 6)
    xpos: np.ndarray  # (nbody, 3)
    site_xpos: np.ndarray  # (nsite, 3)
    xmat: np.ndarray  # (nbody, 9) body orientations


class DriveState(NamedTuple):
    """How the simulator feeds the synthesizer (owner: AudioSimulator)."""

    prm: np.ndarray  # (1,) DRIVE_PARAMS
    sound: np.ndarray  # (ngeom,) SOUND
    sidx: np.ndarray  # (slots, 2) int64: stream of (pair slot, side), -1: none yet
    mic_rows: np.ndarray  # (mics,) int64: rows of the microphones' source positions
    mic_offsets: np.ndarray  # (mics, 3) [m]
    mic_affine: np.ndarray  # (mics, 3, 4): then x -> A x + b (an image microphone's mirrors; identity otherwise)
    dyn_geoms: np.ndarray  # (moving objects,) int64: geom of each moving sounding object
    dyn_obj: np.ndarray  # (moving objects,) int64: its synthesizer object index
    pulses: PulseState  # impacts' clicks and contact-microphone pulses (ImpactPulses)


class KernelState(NamedTuple):
    """The step kernel's state (:func:`mjsound.sim.step.advance`), built in one place:
    :meth:`mjsound.sim.driver.StepDriver.state`."""

    mj: np.ndarray  # (1,) MJ: MuJoCo's C functions and the mjData struct's layout
    views: "DataViews"  # the mjData's arrays the kernel reads
    reader: ReaderState  # the contact reader's state
    buf: "StepBuffers"  # the reader's per-substep buffers
    clock: np.ndarray  # (1,) CLOCK
    drive: "DriveState"  # how the substep's events feed the synthesizer
    synth: SynthState  # the synthesizer's arrays (mjsound.synth.records)
    run: np.ndarray  # (1,) RUN: the call's inputs and outputs
    target: RenderTarget  # what the kernel renders a block with


class ClickModel(NamedTuple):
    """What :func:`mjsound.sim.click_kernels.impact_pulses` reads of the model (owner:
    ImpactPulses; made once)."""

    prm: np.ndarray  # (1,) CLICK_PARAMS
    bodies: np.ndarray  # (nbody,) CLICK_BODY
    geoms: np.ndarray  # (ngeom,) CLICK_GEOM
    sites: np.ndarray  # (contact microphones,) CLICK_SITE
    air: np.ndarray  # (n_air,) CLICK_AIR


class PulseState(NamedTuple):
    """Impact pulses made in the step kernel and the track they are rendered into (owner:
    ImpactPulses, which grows ``rows`` and ``dv`` when the kernel asks; the kernel renders the
    waiting rows into ``track`` after its substeps, Python when the track must grow first)."""

    model: ClickModel
    rows: np.ndarray  # (cap,) PULSE_DTYPE
    dv: np.ndarray  # (cap,) velocity change each row is scaled by [m/s]
    counts: np.ndarray  # (1,) PULSE_COUNTS
    track: TrackState  # the pulse track (mjsound.synth.bandlimited.PulseTrack.state)
