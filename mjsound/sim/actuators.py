"""Actuator noise: motors and gears of the joints' drives shake the links they connect.

For each MuJoCo actuator on a hinge or slide joint that names a preset (:data:`PRESETS`;
off unless one is named, in MJCF custom text ``<text name="mjsound-actuator:NAME"
data="servo"/>`` (``NAME`` an actuator's name or ``*`` for all) or in Python,
``AudioSimulator(..., actuators={"NAME": "servo"})`` or ``actuators="servo"`` for all):

- rotor speed ``w_m = N qdot`` [rad/s] (hinge; ``N`` the preset's reduction, not MJCF's
  ``gear``, which scales the force), ``w_m = N 2 pi qdot / lead`` for a slide (``lead``
  [m] per rotor turn);
- transmitted torque ``tau = gear * actuator_force`` [N m] (a slide: force [N]);
- force scale ``a = |tau| / radius * gate`` [N], ``gate = min(1, |qdot| / GATE_RAD_S)``:
  **a joint holding still is silent** (a servo holding a load against gravity hums from
  its PWM in reality; that electrical noise is not modelled);
- the force signal (:func:`mjsound.synth.drive_tones.drive_tones`): tonal components at
  ``order`` times the rotor's rate with amplitude ``A`` relative to ``a``: gear mesh
  (teeth times each stage's shaft rate, harmonics ``1/h``), motor ripple (slots / poles
  multiples of the rotor rate), plus broadband noise. Every amplitude is linear in the
  torque: the level rises 6 dB per doubling of torque at a given speed.

The force acts at the joint's anchor (``data.xanchor``) on the joint's body and, equal and
opposite, on its parent, across the axis (a hinge: along ``axis x e``, ``e`` the world
axis least aligned with the joint's; a slide: along the axis). Each driven body with a
sounding geom gets one persistent stream of the synthesizer (the sliding contacts'
machinery) carrying the sum of the forces on it (a link between two joints: both drives),
at the anchor and along the direction of its strongest drive
(:func:`mjsound.synth.drive_tones.streams_write`): air microphones hear the links ring, a
contact microphone on a driven link hears it directly. Air microphones also hear the motor
housing directly (``ActuatorPreset.housing``, :mod:`mjsound.synth.drive_housing`): a
monopole at the anchor, the drive's force times ``housing / r`` delayed ``r / c``, each
preset's coefficient calibrated to an A-weighted level at 1 m (:data:`HOUSING_POINTS`).
See ``docs/actuators.md`` for the presets' numbers and where they come from.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from ..synth.constants import P_REF_PA
from ..synth.dispatch import EntryPoint, PackedEntry
from ..synth.drive_lines import (DONE, GROW_LINES, Actuators, BodyGains, DriveRead, LineWeights, drive_read, lines_scratch,
                                 lines_drive_packed, scene_view)
from ..synth.drive_tones import DRIVE, NOISE, TONE, drive_tones, streams_write

__all__ = ["ActuatorPreset", "PRESETS", "HOUSING_POINTS", "housing_coefficient", "housing_level_dba",
           "a_weighting_db", "ACTUATOR_TEXT_PREFIX", "GATE_RAD_S", "DRIVE_BLOCK_S", "RENDERINGS",
           "ActuatorSound", "actuator_config", "channel_responses"]

#: MJCF custom text prefix naming an actuator's preset.
ACTUATOR_TEXT_PREFIX = "mjsound-actuator:"
#: Joint speed [rad/s or m/s] at and above which the drive sounds at full level (below: in
#: proportion; 0: silent).
GATE_RAD_S = 0.05
#: The drives are read at most this often [s] (and before every render): the rotor speed and
#: force scale are linear between two reads.
DRIVE_BLOCK_S = 0.05
#: How the drives are heard: ``"lines"`` (default) from the driven links' transfer functions
#: (:mod:`mjsound.synth.drive_lines`: steady state, no mode run per sample), ``"modal"`` the
#: exact response of the links' modes (:mod:`mjsound.synth.drive_tones`, the reference).
RENDERINGS = ("lines", "modal")


@dataclass(frozen=True)
class ActuatorPreset:
    """A drive train's sound parameters.

    Parameters
    ----------
    reduction : float
        Rotor turns per joint turn ``N`` (hinge), or per lead (slide).
    radius : float
        Radius [m] at which the torque's fluctuation acts on the housing (the force is
        ``|tau| / radius``); a slide's force is used as is.
    tones : tuple of (order, amplitude)
        Multiples of the rotor's rate and their amplitudes relative to the force scale.
    broadband : float
        Broadband noise level relative to the force scale.
    lead : float
        A slide's travel per rotor turn before the reduction [m].
    housing : float
        The motor housing's direct airborne part [Pa m / N]: each line's force ``f`` [N]
        (and the broadband force) heard at an air microphone at distance ``r`` [m] from the
        joint's anchor as the pressure ``housing f(t - r / c) / r`` [Pa]
        (:mod:`mjsound.synth.drive_housing`; :func:`housing_coefficient` makes one from a
        level at 1 m). 0: none (only the links' rings are heard in air).
    """

    reduction: float
    radius: float
    tones: tuple = field(default_factory=tuple)
    broadband: float = 0.0
    lead: float = 0.01
    housing: float = 0.0

    def __post_init__(self):
        if not (math.isfinite(self.housing) and self.housing >= 0.0):
            raise ValueError(f"ActuatorPreset housing={self.housing!r}: give a finite coefficient >= 0 [Pa m / N] "
                             "(0: no airborne part)")


def _mesh(teeth_and_ratios, frac, harmonics=3):
    """Gear mesh tones: stage ``s`` (pinion ``teeth``, stage ratio ``ratio``) meshes at ``teeth``
    times its shaft's rate, the rotor's rate over the product of the earlier stages' ratios;
    harmonics ``h`` at ``frac / h``."""
    out = []
    div = 1.0
    for teeth, ratio in teeth_and_ratios:
        for h in range(1, harmonics + 1):
            out.append((h * teeth / div, frac / h))
        div *= ratio
    return tuple(out)


def a_weighting_db(f):
    """The A-weighting [dB] at frequencies ``f`` [Hz] (IEC 61672-1: ``20 log10 R_A(f) + 2.00``,
    ``R_A = 12194^2 f^4 / ((f^2 + 20.6^2) sqrt((f^2 + 107.7^2)(f^2 + 737.9^2)) (f^2 + 12194^2))``;
    0.0 dB at 1 kHz within 0.01).

    >>> round(float(a_weighting_db(1000.0)), 2), round(float(a_weighting_db(100.0)), 1)
    (0.0, -19.1)
    """
    f2 = np.asarray(f, dtype=float) ** 2
    ra = 12194.0 ** 2 * f2 ** 2 / ((f2 + 20.6 ** 2) * np.sqrt((f2 + 107.7 ** 2) * (f2 + 737.9 ** 2)) * (f2 + 12194.0 ** 2))
    with np.errstate(divide="ignore"):
        return 20.0 * np.log10(ra) + 2.0


def housing_level_dba(preset: ActuatorPreset, torque: float, joint_speed: float, distance: float = 1.0) -> float:
    """The A-weighted level [dB(A) re 20 uPa] of a preset's housing tones (its direct airborne
    part, no links) at ``distance`` [m] from the anchor, its hinge at ``joint_speed`` [rad/s]
    (at or above the speed gate) under ``torque`` [N m]: the lines' forces ``a A_c``, ``a =
    torque / radius``, at ``f_c = order_c N joint_speed / (2 pi)`` as the pressures ``housing
    a A_c / distance`` (amplitudes; those of one order add, being in phase), summed in power: ``10 log10(sum_c (p_c 10^(A(f_c) / 20))^2
    / 2 / P_REF_PA^2)`` (:func:`a_weighting_db`). The broadband part is left out."""
    a = abs(torque) / preset.radius * min(1.0, abs(joint_speed) / GATE_RAD_S)
    amp: dict = {}
    for o, A in preset.tones:  # (components of one order turn in phase from the start: amplitudes add)
        amp[o] = amp.get(o, 0.0) + A
    f = np.array(list(amp)) * preset.reduction * abs(joint_speed) / (2.0 * math.pi)
    p = preset.housing * a * np.array(list(amp.values())) / distance * 10.0 ** (a_weighting_db(f) / 20.0)
    return float(10.0 * np.log10(np.sum(p ** 2) / 2.0 / P_REF_PA ** 2))


def housing_coefficient(preset: ActuatorPreset, torque: float, joint_speed: float, level_dba: float) -> float:
    """The housing coefficient [Pa m / N] that makes :func:`housing_level_dba` at 1 m equal to
    ``level_dba`` [dB(A)] at the operating point ``torque`` [N m], ``joint_speed`` [rad/s] (the
    level is linear in the coefficient: one division).

    >>> p = PRESETS["servo"]
    >>> round(housing_level_dba(p, *HOUSING_POINTS["servo"][:2]), 6) == HOUSING_POINTS["servo"][2]
    True
    """
    unit = housing_level_dba(replace(preset, housing=1.0), torque, joint_speed)
    return float(10.0 ** ((level_dba - unit) / 20.0))


#: Each preset's housing calibration (:func:`housing_coefficient`): (output torque [N m], joint
#: speed [rad/s], A-weighted level of its tones at 1 m [dB(A)]); see ``docs/actuators.md``,
#: "Airborne part", for where each level comes from (``servo`` and ``harmonic``: assumptions;
#: ``qdd``: a planetary gearbox maker's running noise).
HOUSING_POINTS = {
    "servo": (0.1, 5.0, 45.0),  # (hobby servo under load; rotor 1500 rad/s)
    "harmonic": (20.0, 2.0, 50.0),  # (arm joint; wave generator at 200 rad/s, 1900 rpm)
    "qdd": (10.0, 20.0, 58.0),  # (leg joint; rotor 120 rad/s, 1150 rpm)
}

_DRIVES = {
    "servo": ActuatorPreset(300.0, 0.01, _mesh(((10, 5.0), (10, 6.0), (10, 10.0)), 0.05) + ((6.0, 0.05),), 0.02),
    "harmonic": ActuatorPreset(100.0, 0.04, ((2.0, 0.03), (4.0, 0.015), (200.0, 0.02), (400.0, 0.01), (24.0, 0.02)),
                               0.01),
    "qdd": ActuatorPreset(6.0, 0.05, _mesh(((10, 6.0),), 0.03) + ((126.0, 0.02), (252.0, 0.01)), 0.01),
}

#: Named presets (``none``: silent). The numbers are assumptions of typical designs (see
#: ``docs/actuators.md``): ``servo`` a small brushed DC servo (3-slot motor: commutation
#: ripple at 6x the rotor rate; 10-tooth pinions, stages 5 x 6 x 10 = 300:1);
#: ``harmonic`` a BLDC motor (12 slots, 8 poles: ripple / cogging at lcm = 24x) into a
#: 100:1 harmonic drive (two-lobe wave generator at 2x, flexspline 200 teeth);
#: ``qdd`` a quasi-direct-drive leg motor (36 slots, 42 poles: 126x ripple, cogging 252x)
#: with one 6:1 planetary stage (12-tooth sun: mesh at 12 (1 - 1/6) = 10x). Each has a
#: housing (direct airborne part) calibrated at :data:`HOUSING_POINTS`.
PRESETS = {"none": None}
for _name, _p in _DRIVES.items():
    PRESETS[_name] = replace(_p, housing=housing_coefficient(_p, *HOUSING_POINTS[_name]))
del _name, _p


def _preset(value, where):
    if isinstance(value, ActuatorPreset) or value is None:
        return value
    if isinstance(value, str) and value.strip().lower() in PRESETS:
        return PRESETS[value.strip().lower()]
    raise ValueError(f"{where}: unknown actuator preset {value!r}; give one of {sorted(PRESETS)} or an "
                     "ActuatorPreset")


def _actuator_name(model, i: int) -> str:
    """Actuator ``i``'s MJCF name, or ``#i`` for an unnamed one."""
    import mujoco

    return mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, i) or f"#{i}"


def _not_a_motor(model, i: int) -> str:
    """Why actuator ``i`` has no drive-train sound of its own ('' where it has one): it does not
    drive a hinge or slide joint (a tendon, site, body, ball or free joint), or it is a muscle
    (MuJoCo's muscle dynamics, gain or bias)."""
    import mujoco

    # (a joint "in parent" is the joint itself for a hinge or slide: it differs for ball joints alone)
    if int(model.actuator_trntype[i]) not in (int(mujoco.mjtTrn.mjTRN_JOINT), int(mujoco.mjtTrn.mjTRN_JOINTINPARENT)) or int(
            model.jnt_type[model.actuator_trnid[i, 0]]) not in (int(mujoco.mjtJoint.mjJNT_HINGE),
                                                                int(mujoco.mjtJoint.mjJNT_SLIDE)):
        return "does not drive a hinge or slide joint"
    if (int(model.actuator_dyntype[i]) == int(mujoco.mjtDyn.mjDYN_MUSCLE)
            or int(model.actuator_gaintype[i]) == int(mujoco.mjtGain.mjGAIN_MUSCLE)
            or int(model.actuator_biastype[i]) == int(mujoco.mjtBias.mjBIAS_MUSCLE)):
        return "is a muscle"
    return ""


def actuator_config(model, actuators=None) -> dict:
    """``{actuator id: ActuatorPreset}`` of the actuators that sound: MJCF custom texts
    ``mjsound-actuator:NAME`` (``*``: every motor) first, then ``actuators`` (a preset for
    every motor, or ``{name: preset}``, ``"*"`` for every motor) over them.

    "Every motor" (``*``, or one preset for all) is every actuator on a hinge or slide joint
    that is not a muscle: the others (tendons, sites, bodies, ball and free joints; muscles)
    are left silent, and a warning says so where that leaves nothing to hear. An actuator
    *named* with a preset sounds as asked: a muscle on a hinge or slide joint too; one that
    does not drive a hinge or slide joint raises ``ValueError`` (it has no rotor speed to
    hear). Unknown names and presets raise ``ValueError``.

    Examples
    --------
    >>> actuator_config(model, "servo")  # doctest: +SKIP  (a model of 3 motors and a tendon actuator)
    {0: ActuatorPreset(...), 1: ActuatorPreset(...), 2: ActuatorPreset(...)}
    """
    from .objects import custom_texts

    names = {_actuator_name(model, i): i for i in range(model.nu)}
    chosen: dict[int, ActuatorPreset | None] = {}
    every: list[str] = []  # (where a preset for every motor was given)

    def apply(mapping, where):
        if "*" in mapping:
            p = _preset(mapping["*"], f"{where} '*'")
            for i in range(model.nu):
                if not _not_a_motor(model, i):
                    chosen[i] = p
            if p is not None:
                every.append(where)
        for key, value in mapping.items():
            if key == "*":
                continue
            if key not in names:
                raise ValueError(f"{where}: no actuator named {key!r} in this model; actuators: {sorted(names)}")
            chosen[names[key]] = _preset(value, f"{where} {key!r}")

    apply(custom_texts(model, ACTUATOR_TEXT_PREFIX), "MJCF custom text 'mjsound-actuator:'")
    if actuators is not None:
        apply(actuators if isinstance(actuators, dict) else {"*": actuators}, "actuators")
    out = {}
    for i, p in chosen.items():
        if p is None:
            continue
        why = _not_a_motor(model, i)
        if why and why != "is a muscle":
            raise ValueError(f"actuator {_actuator_name(model, i)!r} {why}: only those have a drive-train sound; "
                             "set it to 'none'")
        out[i] = p
    if every and not out and model.nu:
        import warnings

        from ..user_frame import user_stacklevel

        warnings.warn(f"mjsound: {every[-1]} gives every motor a preset, but none of this model's {model.nu} "
                      f"actuators is a motor on a hinge or slide joint (e.g. {_actuator_name(model, 0)!r} "
                      f"{_not_a_motor(model, 0)}): nothing is heard; name an actuator on a hinge or slide "
                      "joint to hear it", RuntimeWarning, stacklevel=user_stacklevel())
    return out


def channel_responses(synth, M: int) -> np.ndarray:
    """``(M, 2, k)``: each of the synthesizer's first ``M`` channels' response
    (:meth:`mjsound.synth.synthesizer.Synthesizer.channel_response`: an image microphone's
    reflection), the logarithms of its frequencies [Hz] padded with ``inf`` and its gains; a
    channel without one has no points (all ``inf``): what
    :func:`mjsound.synth.drive_housing.reflection_at` reads."""
    rs = [synth.channel_response(m) for m in range(M)]
    k = max([len(r[0]) for r in rs if r is not None], default=0)
    out = np.zeros((M, 2, k))
    out[:, 0, :] = np.inf
    for m, r in enumerate(rs):
        if r is not None:
            out[m, 0, :len(r[0])], out[m, 1, :len(r[1])] = np.log(r[0]), r[1]
    return out


class ActuatorSound:
    """The sounding actuators of a simulator and their state (phases, noise, last speeds).

    Parameters
    ----------
    sim : AudioSimulator
        The simulator (its model, data, synthesizer, geoms' objects).
    config : dict
        ``{actuator id: ActuatorPreset}`` (:func:`actuator_config`).
    rendering : str
        One of :data:`RENDERINGS`. ``"lines"`` needs the simulator's pulse track (a scene with
        clicks or contact microphones); without one the modal rendering is used.
    """

    def __init__(self, sim, config: dict, rendering: str = "lines"):
        import mujoco

        if rendering not in RENDERINGS:
            raise ValueError(f"actuator rendering {rendering!r}: give one of {RENDERINGS}")

        m = sim.model
        self._sim = sim
        self.ids = np.array(sorted(config), np.int64)
        J = len(self.ids)
        self.joint = m.actuator_trnid[self.ids, 0].astype(np.int64)
        self.dof = m.jnt_dofadr[self.joint].astype(np.int64)
        self.gear = m.actuator_gear[self.ids, 0].astype(float)
        slide = m.jnt_type[self.joint] == int(mujoco.mjtJoint.mjJNT_SLIDE)
        presets = [config[i] for i in self.ids.tolist()]
        self.ratio = np.array([p.reduction * (2 * math.pi / p.lead if s else 1.0) for p, s in zip(presets, slide)])
        self.inv_radius = np.array([1.0 if s else 1.0 / p.radius for p, s in zip(presets, slide)])
        self.drives = np.zeros(J, DRIVE)
        self.drives["joint"], self.drives["slide"] = self.joint, slide
        self.comp_off = np.zeros(J + 1, np.int64)
        self.comp_off[1:] = np.cumsum([len(p.tones) for p in presets])
        self.tones = np.zeros(int(self.comp_off[-1]), TONE)
        self.tones["order"] = [o for p in presets for o, _ in p.tones]
        self.tones["amp"] = [a for p in presets for _, a in p.tones]
        self.noise = np.zeros(J, NOISE)
        self.noise["broadband"] = [p.broadband for p in presets]
        self.noise["rng"] = [0x5EED0000 + int(i) for i in self.ids]
        # the driven bodies (the joint's body, its parent) that have a sounding geom: one
        # stream each, on its first sounding geom, carrying the sum of the drives on it
        body = m.jnt_bodyid[self.joint]
        obj = sim.geom_objects
        sides = {}
        for j in range(J):
            for side, b in enumerate((int(body[j]), int(m.body_parentid[body[j]]))):
                g = np.flatnonzero((m.geom_bodyid == b) & (obj >= 0))
                if len(g):
                    sides.setdefault(b, (int(g[0]), []))[1].append(2 * j + side)
        heard = {r // 2 for _, rows in sides.values() for r in rows}
        if len(heard) < J:
            import warnings

            from ..user_frame import user_stacklevel

            silent = [_actuator_name(m, int(self.ids[j])) for j in range(J) if j not in heard]
            warnings.warn(f"mjsound: actuators {silent} drive no sounding geom (neither the joint's body nor its "
                          "parent has one with an audible mode): they are silent; give those bodies' geoms a "
                          "material (materials=..., MJCF 'mjsound:GEOM') or a higher sample_rate to hear them", RuntimeWarning, stacklevel=user_stacklevel())
        # the housing's airborne part (drive_housing), for the actuators heard through a body
        self.housing = np.array([p.housing if j in heard else 0.0 for j, p in enumerate(presets)], np.float64)
        self.bodies = np.array(sorted(sides), np.int64)
        self.body_geom = np.array([sides[b][0] for b in self.bodies.tolist()], np.int64)
        self.body_ptr = np.zeros(len(self.bodies) + 1, np.int64)
        self.body_ptr[1:] = np.cumsum([len(sides[b][1]) for b in self.bodies.tolist()])
        self.body_rows = np.array([r for b in self.bodies.tolist() for r in sides[b][1]], np.int64)
        self._sidx = np.full(len(self.bodies), -1, np.int64)
        self._force = np.empty((J, 0))  # (the force signals' buffer, kept while blocks keep their length)
        self._epoch = None
        self._last = None  # (rotor speed, force scale) at the end of the last block
        self._done = None  # (absolute sample the drives were rendered up to; its synth origin)
        self._origin = None
        self.cadence = max(1, int(round(DRIVE_BLOCK_S * sim.sample_rate)))
        self.rendering = rendering if sim.pulses.active else "modal"
        M = sim.synth.n_channels
        C = len(self.tones)
        self._weights_for(M)
        z = np.zeros
        self._act = Actuators(self.comp_off, self.tones, self.noise, self.drives, self.body_ptr, self.body_rows,
                              self._sidx, z(len(self.bodies)), z(J, np.bool_), z(J), z(J), z(J), z(J),
                              self.housing)
        self._rd = DriveRead(self.dof, self.ids, self.ratio, self.gear, self.inv_radius, np.array([float(GATE_RAD_S)]))
        self._bg = None  # (the bodies' gains: _body_gains)
        self._view, self._view_of = None, None  # (scene_view of the synthesizer's state and directions)
        # (numba kernels through their compiled entry points: the dispatcher types record arrays in Python;
        # the lines' one call per block takes its state packed, :mod:`mjsound.synth.packing`)
        self._calls = {"read": EntryPoint(drive_read), "lines": PackedEntry(lines_drive_packed)}
        self._io = np.zeros(5, np.int64)
        self._dv, self._dv_of = None, None  # (the data's arrays the drives read, and the data they view)
        self._regain, self._fs = sim.regain_samples, float(sim.sample_rate)
        self._origin_view, self._origin_of = None, None
        #: :func:`lines_drive`'s state and what it was made of (:meth:`_lines_state`)
        self._args, self._args_of = None, None
        self._due = None  # (the block marked due: first synth sample, samples, whether fresh)

    @property
    def lines_rendered(self) -> int:
        """Lines the last block rendered (the cost's count)."""
        return int(self._io[2])

    @property
    def modes_kept(self) -> int:
        """Modes running for the broadband parts at the last block."""
        return int(self._io[3])

    def reset(self) -> None:
        """Forget the last block's speeds and any block marked due (a reset, or the clock
        jumped: the next block starts from its own)."""
        self._last = None
        self._done = None

    def _streams(self, synth):
        if self._epoch != synth.streams_epoch:
            names = self._sim.object_names
            for i, (b, g) in enumerate(zip(self.bodies.tolist(), self.body_geom.tolist())):
                self._sidx[i] = synth.stream(("actuator", b), names[g])
            self._epoch = synth.streams_epoch
        return self._sidx

    def drive(self, n0: int, n1: int, final: bool = True, later: bool = False) -> bool:
        """The drives on the clock's samples up to ``n1`` (the steps ``[n0, n1)`` are about to
        be read), linear from the last read to the actuators' state at the block's end. Unless
        ``final`` (the samples are rendered next), a call less than :data:`DRIVE_BLOCK_S` after
        the last read waits for a later one. ``later``: the block is only marked due and
        returns True; the step kernel reads the steps and hands back, and :meth:`render_due`
        renders it from the state then (:data:`mjsound.sim.step.DRIVES`); else it is rendered
        now, from the state now (a render of samples already read)."""
        sim = self._sim
        rec = sim.driver.clock.rec
        if self._origin_of is not rec:  # (a plain int64 view of the clock's origin: fast to read)
            self._origin_view, self._origin_of = rec["origin"], rec
        origin = int(self._origin_view[0])
        done = self._done
        if done is None or done > n0 or origin != self._origin or done < origin:
            done = self._done = n0  # (the first call, or the clock went back or restarted)
            self._origin = origin
            self._last = None
        if n1 - done <= 0 or (not final and n1 - done < self.cadence):
            return False
        self._done = n1
        if not len(self.bodies):  # (no driven body has a sounding geom: nothing to hear)
            return False
        fresh = self._last is None
        self._last = True
        self._due = (done - origin, n1 - done, fresh)
        if later:
            return True
        self.render_due()
        return False

    def render_due(self) -> bool:
        """Render the block :meth:`drive` marked due, from the actuators' state now. Returns
        whether an array the step kernel holds may have been replaced (the pulse track grown,
        streams made or grown)."""
        k0, L, fresh = self._due
        sim = self._sim
        if self._force.shape[1] != L:
            self._force = np.empty((len(self.ids), L))  # (the broadband forces' buffer: kept while blocks keep their length)
        if self.rendering == "modal":
            if self._calls["read"]((self._rd, self._act), sim.data.qvel, sim.data.actuator_force, fresh):
                self._drive_modal(sim.synth, sim.data, k0, L)
            return True  # (else every joint is still: nothing to drive; the phases wait)
        args = self._args
        self._drive_lines(sim.synth, sim.data, k0, L, fresh)
        return self._args is not args

    def _weights_for(self, M: int) -> None:
        """:attr:`weights` for ``M`` channels (new ones when the synthesizer's count changed)."""
        C, J = len(self.tones), len(self.ids)
        z = np.zeros
        #: the lines' weights; ``exact``: whether each actuator's broadband part goes through
        #: the modes now (its resonant response matters: :mod:`mjsound.synth.drive_broadband`);
        #: ``power``: that resonant power and everything the actuator makes heard, per unit
        #: force scale (summed over the microphones), at the last block; the lines' working
        #: arrays (blocks of up to twice the cadence allocate none)
        self.weights = LineWeights(z((C, M), np.complex128), z((C, M), np.complex128), z((J, M)), z((J, M)),
                                   z(M, np.int64), z(J, np.bool_), z((J, 2)), lines_scratch(C, M, 2 * self.cadence, J),
                                   z(J, np.int64), channel_responses(self._sim.synth, M))
        self._last = None  # (the next block starts from its own state)

    def _body_gains(self, state) -> BodyGains:
        """The bodies' gains and what is made of them, shaped as the stream table's gains."""
        nb, (_, M, nmax) = len(self.bodies), state.gr.shape
        bg = self._bg
        if bg is None or bg.gr.shape != (nb, M, nmax):
            z = np.zeros
            R = len(self.body_rows)
            bg = self._bg = BodyGains(z((nb, M, nmax)), z((nb, M, nmax)), z((nb, nmax)), z((nb, M, nmax), np.complex128),
                                      z((nb, M), np.int64), np.full((nb, M), np.nan),
                                      z((nb, M, nmax), np.complex128), np.full((R, 3), np.nan), z(R, np.int64),
                                      z((nb, M, nmax)), z((nb, nmax)), z((nb, nmax), np.bool_),
                                      z((nb, nmax), np.complex128), z((nb, nmax)),
                                      np.full((nb, M, 3), np.nan), z((nb, M, nmax), np.complex128))
        return bg

    def _drive_modal(self, synth, d, k0, L) -> None:
        """The exact rendering: force signals into the bodies' streams, through their modes."""
        act, F = self._act, self._force  # (L columns: render_due)
        drive_tones(act.w0, act.w1, act.a0, act.a1, self.comp_off, self.tones, self.noise, self._fs, F)
        sidx = self._streams(synth)
        while True:
            state, consts = synth.stream_tables()
            need = streams_write(state, consts, sidx, self.body_ptr, self.body_rows, k0, F, act.a1,
                                 d.xanchor, d.xaxis, self.drives, self._regain)
            if need == 0:
                break
            synth.grow_stream_ring(need)

    def _lines_state(self, synth, d):
        """:func:`mjsound.synth.drive_lines.lines_drive`'s state now: the same tuple while
        nothing it holds was replaced (kernel state, directions, data, streams, pulse track)."""
        ks, dr = synth.kernel_state(), synth._bank.direction
        key, track = self._args_of, self._sim.pulses.track.state
        if (key is not None and key[0] is ks and key[1] is dr and key[2] is d and key[3] == synth.streams_epoch
                and self._args[6] is track):
            return self._args
        if self.weights.W1.shape[1] != synth.n_channels:  # (microphones added or removed)
            self._weights_for(synth.n_channels)
        else:  # (the images' reflections may have been set since: the same array where it fits)
            resp = channel_responses(synth, synth.n_channels)
            if resp.shape == self.weights.response.shape:
                self.weights.response[...] = resp
            else:
                self.weights = self.weights._replace(response=resp)
        self._streams(synth)
        ks, dr = synth.kernel_state(), synth._bank.direction  # (after the streams: they may replace the table)
        if self._dv_of is not d:
            self._dv, self._dv_of = (d.qvel, d.actuator_force, d.xanchor, d.xaxis), d
        view = self._view
        if view is None or self._view_of[0] is not ks or self._view_of[1] is not dr:
            view = self._view = scene_view(ks, dr)
            self._view_of = (ks, dr)
        bg = self._bg
        if bg is None or bg.gr.shape[1:] != ks.streams.gr.shape[1:]:
            bg = self._body_gains(ks.streams)
        self._args = (self._rd, self._act, self.weights, bg, view, ks, track, self._dv, self._io)
        self._args_of = (ks, dr, d, synth.streams_epoch)
        return self._args

    def _drive_lines(self, synth, d, k0, L, fresh) -> None:
        """The lines' rendering (:mod:`mjsound.synth.drive_lines`) into the pulse track; the
        broadband parts that ring the modes through the bodies' streams
        (:mod:`mjsound.synth.drive_broadband`): one kernel call per block, from Python."""
        if synth.on_regain is not None and not synth.poses_current:
            synth.on_regain()  # (the poses and microphones now)
        weights = self.weights
        args = self._lines_state(synth, d)
        fresh = fresh or self.weights is not weights  # (new weights for new microphones: nothing to ramp from)
        call, io, resume, F = self._calls["lines"], self._io, False, self._force
        while True:
            if call.state is args:  # (the arguments packed last: PackedEntry's call without its checks)
                call.entry(*call.packed, k0, L, self._fs, fresh, resume, self._regain, F)
            else:
                call(args, k0, L, self._fs, fresh, resume, self._regain, F)
            if io[0] == DONE:
                break
            if io[0] == GROW_LINES:  # (a block longer than the working arrays hold: larger ones, nothing read yet)
                self.weights = self.weights._replace(scratch=lines_scratch(len(self.tones), self.weights.W1.shape[1],
                                                                           int(io[1]), len(self.ids)))
                self._args_of = None
            else:
                resume = True
                self._sim.pulses.track._grow(0, int(io[1]) - 1)  # (GROW_TRACK: the ring holds the block and the delays)
            args = self._lines_state(synth, d)
