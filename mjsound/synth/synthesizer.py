"""`Synthesizer`: modal sound from impacts, sliding, rolling and force signals.

Physics (see ``docs/design.md``, "Exciting a mode")
-----------------------------------------------
Mode i of an object has decay ``d_i`` [1/s], damped angular frequency ``w_i`` [rad/s],
``lambda_i = -d_i + j w_i`` and mass-normalised shape ``phi_i(x)`` [1/sqrt(kg)]. An impulse
``J`` [N s] at surface point x at time ``t_e`` adds the complex modal amplitude::

    c_i = (phi_i(x) . J) / w_i * S_i          [m sqrt(kg)]

with ``S_i = S(w_i; tau)`` the half-sine contact pulse spectrum (:mod:`.pulse`, ``tau`` from
Hertz theory), and the modal coordinate rings as ``q_i(t) = Im(c_i e^{lambda_i (t - t_e)})``.

Radiation and microphones (``docs/design.md``, "Radiation, microphones, output")
------------------------------------------------------------------------
Each object reaches microphone m, at distance ``r`` from the object's origin, as::

    p_m(t) = sum_i  w_i q_i(t - r/c) / r        [Pa]

where ``w_i`` is ``model.radiation[i]`` [Pa m per unit modal coordinate] (``radiation=True``)
or, with ``radiation=False``, a plain modal-acceleration proxy
``w_i = -w_i^2 * rho_air / (4 pi) * size^2 * rms_x(phi_i(x) . n(x))`` (a compact source whose
volume acceleration is the mode's rms normal acceleration times ``size^2``; same units, Pa m,
but only a rough level). ``r`` is clamped to at least ``R_MIN_M`` and is computed when the event
is added (moving objects and microphones take effect for later events; ringing already
excited keeps the distance of its event).

Discretisation
--------------
Each (object, microphone) pair is one *voice*: a bank of complex oscillators
``z_i[n+1] = p_i z_i[n]``, ``p_i = e^{lambda_i / fs}``, whose output at sample n is
``sum_i Im z_i[n]``. Sample n is simulation time ``n / fs``. An event arriving at time
``t_a = t_e + r/c`` enters at sample ``n_a = ceil(t_a fs)`` with the exact phase
``c_i w_i / r * e^{lambda_i (n_a / fs - t_a)}``, so timing and delay are exact to far below
a sample. Amplitudes are computed in float64; the bank state is float32 (default) or
float64. Modes with ``f >= 0.45 fs`` (or above ``f_max``) or overdamped (``d >= omega``) are
dropped when the object is added; a mode with ``d <= 0`` gets ``D_MIN_PER_S`` so no pole can
reach the unit circle. The rounded pole's systematic error is cancelled on a fixed grid of
``GRID`` samples (see :mod:`.kernels`), which keeps hours of ringing on the closed form.

Determinism: the same calls with the same ``seed`` give bit-identical audio, however
:meth:`Synthesizer.render` is split into blocks.
"""

from __future__ import annotations

import math

import numpy as np

from ..modal.model import ModalModel
from . import kernels
from .pulse import contact_time, effective, hertz_coefficient
from .interrupt import interruptible
from .dispatch import EntryPoint
from .queue import EventQueue
from .records import AIR, CHANNEL, DEAF, SYNTH_CONSTS, Bank, BankLayout, EventRows, ObjectTable, SourceRows, SynthState
from .stream_table import RING_SLACK, StreamTable
from .streams import any_due, stream_drive, streams_bank_rows, streams_gains

__all__ = ["Synthesizer", "GRID", "D_MIN_PER_S", "R_MIN_M", "TIME_TOLERANCE_S"]

#: Samples between exact-pole corrections / culling checks (absolute grid).
GRID = 256
#: Decay rate [1/s] given to modes whose damping is zero or negative (e-folding in 1000 s).
D_MIN_PER_S = 1e-3
#: Smallest source-microphone distance [m] used for 1/r.
R_MIN_M = 0.01
#: Events up to this much before the rendered time are accepted (and start now) [s].
TIME_TOLERANCE_S = 1e-6
#: Air density [kg/m^3] (``radiation=False`` proxy).
RHO_AIR = 1.2
#: Absolute amplitude floor [Pa at the microphone]: modes below it are culled.
FLOOR_PA = 1e-30
#: Largest accepted modal amplitude at a microphone [Pa]; above it the input is rejected.
MAX_AMPLITUDE = 1e30
#: Sliding: force fluctuation per newton of normal force and per m/s of speed [1/(m/s)].
SLIDE_ROUGHNESS = 0.05
#: Sliding: roughness grain [m]; the noise is low-passed at speed / grain.
SLIDE_GRAIN_M = 20e-6
#: Rolling: force fluctuation per newton of normal force and per m/s of speed [1/(m/s)].
ROLL_ROUGHNESS = 0.05
#: Rolling: contact-patch length [m]; the noise is low-passed at speed / length
#: (van den Doel et al. 2001: rolling filters the roughness through the contact patch).
ROLL_PATCH_M = 2e-3

_SAMPLE_TOL = 1e-6  # in samples: ceil(x - tol) so on-sample times are not pushed one late


def _finite_array(x, _unused, what, fix):
    try:
        a = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be numeric; {fix}") from None
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{what} contains NaN or Inf; {fix}")
    return a


class _Voice:
    """State of one (object, microphone) pair: views into the synthesizer's flat state."""

    __slots__ = ("zr", "zi", "peak2", "active")

    def __init__(self, n):
        self.zr = np.zeros(n)
        self.zi = np.zeros(n)
        self.peak2 = np.zeros(n)
        self.active = np.zeros(n, dtype=np.bool_)


class _PoseTable:
    """World poses of all objects, row = object index: ``pos`` (n, 3) [m], ``R`` (n, 3, 3)
    body-to-world. A driver sets every moving object's pose in one call
    (:func:`mjsound.sim.drive.pose_rows`) and the numba kernels read them from here."""

    def __init__(self, cap: int = 8):
        self.pos = np.zeros((cap, 3))
        self.R = np.tile(np.eye(3), (cap, 1, 1))

    def ensure(self, n: int) -> None:
        cap = len(self.pos)
        if n > cap:
            k = max(n, 2 * cap)
            pos, R = np.zeros((k, 3)), np.tile(np.eye(3), (k, 1, 1))
            pos[:cap], R[:cap] = self.pos, self.R
            self.pos, self.R = pos, R


class _Object:
    """One object's modal data; its pose (``pos`` (3,) [m], ``R`` (3, 3) body-to-world) is
    row ``index`` of the synthesizer's :class:`_PoseTable` (views: they change with it)."""

    @property
    def pos(self) -> np.ndarray:
        return self.poses.pos[self.index]

    @pos.setter
    def pos(self, p) -> None:
        self.poses.pos[self.index] = p

    @property
    def R(self) -> np.ndarray:
        return self.poses.R[self.index]

    @R.setter
    def R(self, R) -> None:
        self.poses.R[self.index] = R


def _finite(block: np.ndarray, finite: bool | None = None) -> np.ndarray:
    """``block`` with NaN and infinities set to 0 (an exploding simulation must not hand out
    NaN audio); ``finite=True`` when that is known already."""
    if finite is None:
        finite = bool(np.isfinite(block).all())
    return block if finite else np.nan_to_num(block, copy=False, nan=0.0, posinf=0.0, neginf=0.0)


class Synthesizer:
    """Real-time modal synthesizer for any number of objects and microphones.

    Parameters
    ----------
    sample_rate : int
        Output sample rate [Hz], 1000..768000.
    microphones : (m, 3) array_like or None
        World positions of the microphones [m], one output channel each. ``None`` gives one
        default listener at (0, 0, 1) m.
    dtype : {"float32", "float64"}
        Oscillator state precision (float32 is about twice as fast; its error against float64
        is below -80 dB of peak).
    cull_db : float or None
        A mode whose amplitude fell this far below its peak since it was last excited stops
        costing anything until re-excited (default -100 dB). ``None`` disables culling (an
        absolute floor of 1e-30 Pa still applies).
    radiation : bool
        Use the models' far-field radiation estimate (``True``) or the modal-acceleration proxy.
    speed_of_sound : float
        c [m/s] for the propagation delay r / c.
    seed : int
        Seed of the sliding / rolling noise; same calls and seed give bit-identical audio.
    f_max : float or None
        Drop modes above this frequency [Hz] (always also above 0.45 * sample_rate).

    Attributes
    ----------
    sample_rate : int
    n_channels : int
        Number of microphones.
    samples_rendered : int
        Samples produced by :meth:`render` since construction / :meth:`reset`.
    time : float
        ``samples_rendered / sample_rate`` [s]: the earliest time a new event may have.

    Examples
    --------
    >>> import numpy as np
    >>> from mjsound import ModalModel, get_material
    >>> m = ModalModel([440.0], [3.0], [[0, 0, 0]], [[0, 0, 1]], np.ones((1, 3, 1)), [1.0],
    ...                get_material("steel"), mass_kg=0.1)
    >>> syn = Synthesizer(48000, microphones=[[0, 0, 1]])
    >>> syn.add_object("bell", m)
    >>> syn.impact("bell", [0, 0, 0], [0, 0, 0.01], time=0.0)
    >>> syn.render(4800).shape
    (1, 4800)
    """

    def __init__(self, sample_rate=48000, microphones=None, dtype="float32", cull_db=-100.0,
                 radiation=True, speed_of_sound=343.0, seed=0, f_max=None):
        try:
            fs = float(sample_rate)
        except (TypeError, ValueError):
            fs = float("nan")
        if not math.isfinite(fs) or fs < 1000 or fs > 768000 or fs != int(fs):
            raise ValueError(
                f"sample_rate={sample_rate!r} is invalid: give an integer number of samples per "
                "second between 1000 and 768000, e.g. 48000"
            )
        dt = np.dtype(dtype)
        if dt not in (np.dtype(np.float32), np.dtype(np.float64)):
            raise ValueError(f"dtype={dtype!r} is invalid: use 'float32' (default) or 'float64'")
        if cull_db is not None:
            cull_db = float(cull_db)
            if math.isnan(cull_db) or cull_db > 0:
                raise ValueError(f"cull_db={cull_db!r} must be <= 0 dB (e.g. -100) or None")
        c = float(speed_of_sound)
        if not math.isfinite(c) or c <= 0:
            raise ValueError(f"speed_of_sound={speed_of_sound!r} must be a positive finite speed in m/s")
        if f_max is not None:
            f_max = float(f_max)
            if not f_max > 0:
                raise ValueError(f"f_max={f_max!r} must be a positive frequency in Hz or None")
        self.sample_rate = int(fs)
        self.dtype = dt
        self.cull_db = cull_db
        self._cull2 = 0.0 if cull_db is None else 10.0 ** (cull_db / 10.0)
        self.radiation = bool(radiation)
        self.speed_of_sound = c
        self.seed = int(seed)
        self.f_max = f_max
        self._objects: dict[str, _Object] = {}
        self._next_index = 0
        self._poses = _PoseTable()
        # pending events (.queue); forcing sources: (object index, mic, a, b, g (n,), f (b - a,))
        self._ev = EventQueue()
        self._src = []
        self._dirty = True  # voice layout must be rebuilt before rendering
        self._mics = self._check_mics(np.array([[0.0, 0.0, 1.0]]) if microphones is None else microphones)
        # output channels: air microphones, then contact microphones (add_contact_microphone)
        self._channels = np.zeros(len(self._mics), CHANNEL)
        self._channels["owner"] = AIR
        self._contacts = {}  # channel -> (object name or None, point, axis) in the object frame
        self._chan_w = np.zeros(0, np.complex128)
        self._consts = np.zeros(1, SYNTH_CONSTS)
        for k, v in (("c", c), ("fs", float(self.sample_rate)), ("rmin", R_MIN_M), ("tol", _SAMPLE_TOL),
                     ("grid", GRID), ("slack", RING_SLACK), ("cull2", self._cull2), ("floor2", FLOOR_PA**2)):
            self._consts[0][k] = v
        self.samples_rendered = 0
        self._streams_clear()

    # ------------------------------------------------------------------ properties
    @property
    def n_channels(self) -> int:
        return len(self._mics)

    @property
    def time(self) -> float:
        return self.samples_rendered / self.sample_rate

    @property
    def samples_rendered(self) -> int:
        """Samples produced by :meth:`render` since construction / :meth:`reset`."""
        return int(self._consts[0]["rendered"])

    @samples_rendered.setter
    def samples_rendered(self, n: int) -> None:
        self._consts[0]["rendered"] = n

    @property
    def microphones(self) -> np.ndarray:
        """(m, 3) world positions of the microphones [m] (a copy)."""
        return self._mics.copy()

    @property
    def objects(self) -> list[str]:
        return list(self._objects)

    def n_modes(self, name) -> int:
        """Modes of object ``name`` that are run (after dropping those above the band)."""
        return len(self._get(name).keep)

    def active_modes(self, name) -> int:
        """Modes of ``name`` currently running (summed over microphones)."""
        return int(sum(v.active.sum() for v in self._get(name).voices))

    # ------------------------------------------------------------------ setup
    @staticmethod
    def _check_mics(positions):
        p = _finite_array(positions, None, "microphones", "give (m, 3) world positions in metres")
        p = p.reshape(-1, 3) if p.size % 3 == 0 and p.size > 0 else None
        if p is None:
            raise ValueError("microphones must be (m, 3) world positions in metres with m >= 1")
        return p.copy()

    def set_microphones(self, positions) -> None:
        """Move the microphones ((m, 3) world positions [m]).

        Applies to events added afterwards. If the number changes, channels that remain keep
        their ringing state, new channels start silent and dropped channels are discarded.
        """
        p = self._check_mics(positions)
        if self._contacts and len(p) != len(self._mics):
            raise ValueError(f"set_microphones: this synthesizer has contact microphones; give all "
                             f"{len(self._mics)} channels' positions (a contact channel's position is not used)")
        self._set_channels(p)

    def _set_channels(self, p) -> None:
        """Channel positions ``p`` (m, 3); a new count keeps the channels that remain."""
        old = len(self._mics)
        self._mics = p
        if len(p) == old:
            return  # same channels: only later events see the new positions
        for ob in self._objects.values():
            n = len(ob.keep)
            ob.voices = ob.voices[: len(p)] + [_Voice(n) for _ in range(max(0, len(p) - old))]
        self._channels = np.resize(self._channels, len(p))
        self._channels["owner"][old:] = AIR
        if len(p) != old:
            nch = len(p)
            self._ev.drop_mics(nch)
            self._src = [s for s in self._src if s[1] < nch]
            self._streams_clear()
            self._dirty = True

    def add_contact_microphone(self, name, point, axis) -> int:
        """Add a contact microphone on object ``name``: a new output channel reading the
        object's surface acceleration along ``axis`` at ``point`` [m/s^2] (both in the object
        frame; the mode shapes at the surface sample nearest ``point``), from every excitation
        of that object and of no other, with no propagation delay
        (:mod:`mjsound.synth.contact_mic`). ``name=None`` adds a channel that hears no modes
        (a sensor on a body without a modal model). Returns the channel index."""
        if name is not None:
            ob = self._get(name)
        p = _finite_array(point, None, "point", "give the contact microphone's point in the object frame [m]")
        a = _finite_array(axis, None, "axis", "give the sensing axis as a 3-vector in the object frame")
        na = float(np.linalg.norm(a)) if a.shape == (3,) else 0.0
        if p.shape != (3,) or not na > 0:
            raise ValueError("a contact microphone needs a 3-vector point [m] and a non-zero 3-vector axis")
        pos = np.zeros(3) if name is None else ob.pos + ob.R @ p
        old = self.n_channels
        self._set_channels(np.vstack([self._mics, pos[None]]))
        self._contacts[old] = (None if name is None else str(name), p.copy(), a / na)
        self._channels[old]["owner"] = DEAF if name is None else ob.index
        self._dirty = True
        return old

    def object_pose(self, name) -> tuple[np.ndarray, np.ndarray]:
        """``(position (3,), rotation (3, 3))`` of object ``name`` (object to world), copies."""
        ob = self._get(name)
        return ob.pos.copy(), ob.R.copy()

    def object_points_world(self, name) -> np.ndarray:
        """The surface samples of ``name``'s model in world coordinates, (p, 3) [m]."""
        ob = self._get(name)
        return ob.pos[None, :] + ob.pts @ ob.R.T

    @staticmethod
    def _check_pose(position, rotation, name):
        pos = _finite_array(position, None, f"position of {name!r}", "give 3 finite coordinates in metres")
        if pos.shape != (3,):
            raise ValueError(f"position of {name!r} must have 3 coordinates, got shape {pos.shape}")
        R = _finite_array(rotation, None, f"rotation of {name!r}", "give a 3x3 rotation matrix")
        if R.shape != (3, 3) or not np.allclose(R.T @ R, np.eye(3), atol=1e-4):
            raise ValueError(f"rotation of {name!r} must be a 3x3 orthonormal matrix (object -> world)")
        return pos.copy(), R.copy()

    def add_object(self, name: str, model: ModalModel, position=(0.0, 0.0, 0.0), rotation=np.eye(3)) -> None:
        """Add a sounding object.

        Parameters
        ----------
        name : str
            Unique name used by the excitation methods.
        model : ModalModel
            Its modes. Modes at or above ``0.45 * sample_rate`` (or ``f_max``) and overdamped
            modes are dropped; zero or negative decay becomes ``D_MIN_PER_S``.
        position : (3,) array_like
            World position of the object frame's origin [m].
        rotation : (3, 3) array_like
            Object-to-world rotation matrix.
        """
        name = str(name)
        if name in self._objects:
            raise ValueError(f"object {name!r} already exists; use another name or set_pose() to move it")
        if not isinstance(model, ModalModel):
            raise ValueError(f"model for {name!r} must be a mjsound.ModalModel, got {type(model).__name__}")
        pos, R = self._check_pose(position, rotation, name)
        rad = np.asarray(model.radiation, dtype=np.float64)
        if self.radiation and not np.all(np.isfinite(rad)):
            raise ValueError(f"model of {name!r} has non-finite radiation values; recompute it or use radiation=False")
        fs = self.sample_rate
        f = model.frequencies_hz
        d = np.where(model.decay_per_s > 0, model.decay_per_s, D_MIN_PER_S)
        w0 = 2 * np.pi * f
        limit = 0.45 * fs if self.f_max is None else min(0.45 * fs, self.f_max)
        keep = np.flatnonzero((f < limit) & (d < w0) & (f > 0))
        ob = _Object()
        ob.name = name
        ob.model = model
        ob.keep = keep
        ob.index = self._next_index
        self._next_index += 1
        ob.poses = self._poses
        self._poses.ensure(self._next_index)
        ob.pos, ob.R = pos, R
        d = d[keep]
        wd = np.sqrt(w0[keep] ** 2 - d**2)
        ob.d, ob.wd = d, wd
        ob.lam = -d + 1j * wd
        if self.radiation:
            ob.weights = rad[keep]  # capped at full radiation efficiency by the analysis
        else:
            sh = model.shapes[:, :, keep].astype(np.float64)
            if len(model.points):
                nrm = np.einsum("pcn,pc->pn", sh, model.normals.astype(np.float64))
                rms = np.sqrt(np.mean(nrm**2, axis=0))
            else:
                rms = np.zeros(len(keep))
            size = model.size_m if model.size_m > 0 else 0.1
            ob.weights = -(w0[keep] ** 2) * RHO_AIR / (4 * np.pi) * size**2 * rms
        # rounded poles with |p| < 1, and the exact-pole correction
        p = np.exp(ob.lam / fs)
        dt = self.dtype
        pr = p.real.astype(dt)
        pi = p.imag.astype(dt)
        one_minus = dt.type(1) - np.finfo(dt).eps
        for _ in range(8):
            mag2 = pr.astype(np.float64) ** 2 + pi.astype(np.float64) ** 2
            bad = mag2 >= 1.0
            if not bad.any():
                break
            pr[bad] = pr[bad] * one_minus
            pi[bad] = pi[bad] * one_minus
        ob.pr, ob.pi = np.ascontiguousarray(pr), np.ascontiguousarray(pi)
        prd = pr.astype(np.float64) + 1j * pi.astype(np.float64)
        # eps = p_exact / p_rounded = exp(logeps); the correction after GRID samples is eps^GRID
        with np.errstate(divide="ignore", invalid="ignore"):
            logeps = ob.lam / fs - np.log(prd)
        logeps = np.where(np.isfinite(logeps), logeps, 0.0)
        # keep the imaginary part in (-pi, pi] (principal branch already)
        ob.logeps = logeps
        corr = np.exp(GRID * logeps)
        ob.corr_r = np.ascontiguousarray(corr.real)
        ob.corr_i = np.ascontiguousarray(corr.imag)
        ob.rng = None  # noise generator, created on first use from (seed, index)
        ob.filter_state = {}  # kind -> (next source sample, last output)
        ob.voices = [_Voice(len(keep)) for _ in range(self.n_channels)]
        ob.mass = float(model.mass_kg) if np.isfinite(model.mass_kg) and model.mass_kg > 0 else np.inf
        # hot-path caches: kept shapes (p, 3, n) float64, surface points for the nearest lookup
        ob.shk = np.ascontiguousarray(model.shapes[:, :, keep], dtype=np.float64)
        ob.pts = np.ascontiguousarray(model.points, dtype=np.float64)
        self._objects[name] = ob
        self._dirty = True

    def remove_object(self, name) -> None:
        """Remove an object (its ringing stops at once)."""
        ob = self._get(name)
        del self._objects[name]
        self._ev.drop_object(ob.index)
        self._src = [c for c in self._src if c[0] != ob.index]
        self._streams.retire_object(ob.index)
        self._dirty = True

    def set_pose(self, name, position, rotation) -> None:
        """Set the world pose of ``name`` (applies to events added afterwards)."""
        ob = self._get(name)
        ob.pos, ob.R = self._check_pose(position, rotation, name)

    def _get(self, name) -> _Object:
        try:
            return self._objects[str(name)]
        except KeyError:
            raise ValueError(
                f"unknown object {name!r}; add it with add_object() first (known: {', '.join(self._objects) or 'none'})"
            ) from None

    def _check_time(self, t, what="time"):
        t = np.asarray(t, dtype=np.float64)
        if not np.all(np.isfinite(t)):
            raise ValueError(f"{what} contains NaN or Inf; give simulation time in seconds")
        if t.size and t.min() < self.time - TIME_TOLERANCE_S:
            raise ValueError(
                f"{what}={float(t.min())!r} s is before the audio already rendered (up to {self.time!r} s); "
                "add events before rendering the block that contains them"
            )
        return np.maximum(t, self.time)

    # ------------------------------------------------------------------ geometry helpers
    def _distances(self, ob):
        r = np.linalg.norm(self._mics - ob.pos[None, :], axis=1)
        return np.maximum(r, R_MIN_M)

    # ------------------------------------------------------------------ excitation
    def impact(self, name, point, impulse, time, *, pulse_s=None, other_material=None, other_mass_kg=np.inf,
               other_radius_m=np.inf, speed=None, radius_m=None) -> None:
        """One impact: impulse ``J`` [N s] (world vector) at world ``point`` [m] at ``time`` [s].

        Parameters
        ----------
        name : str
            Object struck.
        point : (3,) array_like
            Contact point in world coordinates [m] (snapped to the nearest surface sample).
        impulse : (3,) array_like
            Impulse vector on this object in world coordinates [N s].
        time : float
            Simulation time of the impact [s], not before :attr:`time` (minus 1 us tolerance).
        pulse_s : float, optional
            Contact time [s]; overrides Hertz (0 = ideal impulse).
        other_material : Material, optional
            Material of the other body; ``None`` means a rigid partner (infinite E).
        other_mass_kg, other_radius_m : float
            Other body's mass [kg] and radius of curvature at the contact [m] (inf: immovable / flat).
        speed : float, optional
            Normal approach speed [m/s]; default ``|J| / (m* (1 + e))`` with m* the effective
            mass and e the restitution (the smaller of the two materials').
        radius_m : float, optional
            This object's radius of curvature at the contact [m]; default half its size.

        Notes
        -----
        ``tau = 2.87 (m*^2 / (R* E*^2 v))^(1/5)`` (see :mod:`.pulse`); an object whose model
        has no mass, struck by an immovable body, gets an ideal impulse. Raises ``ValueError``
        (with the state unchanged) for an unknown object or NaN / Inf / out-of-range input.
        """
        self.impacts(name, np.reshape(np.asarray(point, dtype=np.float64), (1, -1)) if np.size(point) == 3 else point,
                     np.reshape(np.asarray(impulse, dtype=np.float64), (1, -1)) if np.size(impulse) == 3 else impulse,
                     np.atleast_1d(np.asarray(time, dtype=np.float64)) if np.size(time) == 1 else time,
                     pulse_s=pulse_s, other_material=other_material, other_mass_kg=other_mass_kg,
                     other_radius_m=other_radius_m, speed=speed, radius_m=radius_m)

    def impacts(self, name, points, impulses, times, *, pulse_s=None, other_material=None,
                other_mass_kg=np.inf, other_radius_m=np.inf, speed=None, radius_m=None) -> None:
        """Many impacts on one object at once (vectorised :meth:`impact`).

        ``points`` (k, 3) [m], ``impulses`` (k, 3) [N s], ``times`` (k,) [s]; ``pulse_s`` and
        ``speed`` may be scalars or (k,) arrays. Much faster than k calls of :meth:`impact`.
        """
        ob = self._get(name)
        P = _finite_array(points, None, "point", "give world coordinates in metres")
        J = _finite_array(impulses, None, "impulse", "give a finite impulse vector in N s")
        if P.ndim != 2 or P.shape[1] != 3:
            raise ValueError(f"point must be (3,) or (k, 3) world coordinates, got shape {P.shape}")
        if J.shape != P.shape:
            raise ValueError(f"impulse must be a 3-vector per point (shape {P.shape}), got shape {J.shape}")
        k = len(P)
        if np.size(times) not in (1, k):
            raise ValueError(f"times must have one value per impact ({k}), got {np.size(times)}")
        t = _finite_array(times, None, "time", "give simulation time in seconds").reshape(-1)
        t = self._check_time(np.broadcast_to(t, (k,)), "time")
        # ---- pulse length
        if pulse_s is not None:
            tau = _finite_array(pulse_s, None, "pulse_s", "give the contact time in seconds (>= 0)")
            if np.any(tau < 0):
                raise ValueError("pulse_s must be >= 0 seconds")
            tau = np.broadcast_to(tau, (k,)).astype(np.float64)
        else:
            m2 = float(other_mass_kg)
            R2 = float(other_radius_m)
            if math.isnan(m2) or m2 <= 0 or math.isnan(R2) or R2 <= 0:
                raise ValueError("other_mass_kg and other_radius_m must be positive (np.inf for immovable / flat)")
            if radius_m is not None:
                R1 = float(radius_m)
                if math.isnan(R1) or R1 <= 0:
                    raise ValueError(f"radius_m={radius_m!r} must be a positive radius in metres")
            v = None
            if speed is not None:
                v = np.abs(_finite_array(speed, None, "speed", "give the normal approach speed in m/s"))
                v = np.broadcast_to(v, (k,)).astype(np.float64)
            tau = self._hertz_tau(ob, J, other_material, m2, R2, v, radius_m)
        if len(ob.keep) == 0 or k == 0:
            return
        self._impacts_trusted(ob, P, J, t, tau)

    def _hertz_coef(self, ob, other_material, m2, R2, radius_m):
        """``(coef, e)``: :func:`.pulse.hertz_coefficient` of ``ob`` against the other body
        (mass ``m2``, radius ``R2``; ``radius_m`` None: half the object's size) and the
        restitution of the pair."""
        mat1 = ob.model.material
        if radius_m is None:
            R1 = ob.model.size_m / 2 if ob.model.size_m > 0 else np.inf
        else:
            R1 = float(radius_m)
        e = mat1.restitution if other_material is None else min(mat1.restitution, other_material.restitution)
        return hertz_coefficient(effective(ob.mass, m2), effective(R1, R2), mat1, other_material), e

    def _hertz_tau(self, ob, J, other_material, m2, R2, v, radius_m):
        """Hertz contact time per impact (see :mod:`.pulse`); ``v`` None: from |J| / (m*(1+e))."""
        coef, e = self._hertz_coef(ob, other_material, m2, R2, radius_m)
        if v is None:
            mstar = effective(ob.mass, m2)
            v = np.sqrt(np.einsum("kc,kc->k", J, J)) / (mstar * (1 + e)) if not math.isinf(mstar) else np.zeros(len(J))
        return np.array([contact_time(coef, vi) for vi in np.asarray(v, np.float64).reshape(-1).tolist()])

    def _impacts_trusted(self, ob, P, J, t, tau):
        """Internal fast path of :meth:`impacts`: finite (k, 3) world ``P``, ``J``, (k,) times
        already >= :attr:`time` and pulse lengths ``tau``. State is unchanged on error."""
        self._impact_rows(np.full(len(P), ob.index, np.int64), P, J, t, tau)

    def _impact_rows(self, obj, P, J, t, tau) -> None:
        """Impacts on several objects in one numba call (the per-step driver's path): impact
        ``i`` strikes object index ``obj[i]`` at world ``P[i]`` with impulse ``J[i]`` [N s] at
        synth time ``t[i]`` >= :attr:`time` [s], pulse length ``tau[i]`` [s] (rows with
        non-finite values are skipped). State is unchanged on error."""
        self.reserve_impacts(len(obj))
        f64 = np.float64
        count, used, nxt, amax = kernels.impacts_to_queue(
            self.kernel_state(), obj, np.ascontiguousarray(P, f64), np.ascontiguousarray(J, f64),
            np.ascontiguousarray(t, f64), np.ascontiguousarray(tau, f64))
        if not (amax <= MAX_AMPLITUDE):  # also catches NaN
            raise self.amplitude_error(obj)
        kernels.commit_queued(self._ev.state, count, used, nxt)

    # ------------------------------------------------------------------ for drivers (numba)
    def kernel_state(self) -> SynthState:
        """The arrays the per-step kernels read and write (:class:`.records.SynthState`): every
        object's modal data, poses, microphones, constants, the event queue and the streams.
        Valid until the synthesizer next grows a buffer or changes its objects or
        microphones: ask again after any call into the synthesizer."""
        if self._dirty:
            self._rebuild()
        st = self._streams.state
        parts = (self._object_table, self._poses.pos, self._poses.R, self._mics, self._consts, self._ev.state,
                 self._streams.empty if st is None else st, self._channels, self._chan_w)
        # the same tuple while its arrays are the same: the step kernel's runner calls the
        # compiled entry point directly only while its arguments are the objects it was looked
        # up for (a new tuple each call typed every argument in Python: 4x the step time)
        ks = getattr(self, "_kernel_state", None)
        if ks is None or any(a is not b for a, b in zip(ks, parts)):
            ks = self._kernel_state = SynthState(*parts)
        return ks

    def reserve_impacts(self, k: int) -> None:
        """Room in the event queue for ``k`` more impacts (each at every microphone)."""
        if self._dirty:
            self._rebuild()
        M = self.n_channels
        self._ev.reserve(M * k, M * k * self._nmax)

    def has_room_for_impacts(self, k: int) -> bool:
        """Whether ``k`` more impacts fit in the event queue without growing it."""
        M = self.n_channels
        return not self._dirty and self._ev.room(M * k, M * k * self._nmax)

    def amplitude_error(self, struck) -> ValueError:
        """The error for impacts on object indices ``struck`` whose modal amplitude is out of
        range (nothing of them was queued)."""
        names = sorted({self._by_index[int(o)].name for o in np.asarray(struck).tolist() if int(o) in self._by_index})
        return ValueError(
            f"impulse on {', '.join(map(repr, names))} gives a modal amplitude above {MAX_AMPLITUDE:g} Pa; "
            "check the impulse units (N s) and magnitude"
        )

    def object_index(self, name) -> int:
        """Index of object ``name`` in :meth:`kernel_state`'s tables (stable while it exists)."""
        return self._get(name).index

    def hertz_coefficient(self, name, other_material, other_mass_kg, other_radius_m, radius_m=None) -> float:
        """``coef`` [s (m/s)^(1/5)] of ``tau = coef v^(-1/5)`` for ``name`` struck by a body of
        ``other_material`` (None: rigid), mass and radius of curvature at the contact (inf:
        immovable / flat); ``radius_m`` None: half the object's size (:mod:`.pulse`)."""
        return self._hertz_coef(self._get(name), other_material, float(other_mass_kg), float(other_radius_m),
                                radius_m)[0]

    def stream(self, key, name) -> int:
        """Index of the persistent sustained-contact stream ``key`` (any hashable, e.g.
        ``(geom1, geom2, struck geom)``) on object ``name``, created on first use (a driver
        then drives it in numba: :func:`.streams.stream_drive`)."""
        ob = self._get(name)
        nmax = max([len(o.keep) for o in self._objects.values()], default=0)
        return self._streams.index(key, ob.index, nmax, self.seed, self.samples_rendered)

    def grow_stream_ring(self, need: int) -> None:
        """Stream rings of at least ``need`` samples."""
        self._streams.grow_ring(need)

    @property
    def streams_epoch(self) -> int:
        """Changes whenever the synthesizer forgets its streams (stream indices held elsewhere
        are stale then)."""
        return self._st_epoch

    @property
    def n_streams(self) -> int:
        """Persistent streams in use."""
        return self._streams.n

    @staticmethod
    def _nearest(ob, pl):
        if len(pl) * len(ob.pts) > 4_000_000:
            return ob.model.nearest_points(pl)
        return kernels.nearest(ob.pts, np.ascontiguousarray(pl, dtype=np.float64))

    def slide(self, name, point, normal, normal_force, speed, t0, t1, *, roughness=SLIDE_ROUGHNESS) -> None:
        """Sliding contact on ``[t0, t1)`` [s]: surface-roughness noise drives the modes.

        The force along ``normal`` is ``roughness * |normal_force| * speed * w[k]`` [N], ``w``
        unit-variance Gaussian noise (seeded, per object) low-passed at ``speed / SLIDE_GRAIN_M``
        (faster sliding is brighter; van den Doel et al. 2001). ``speed == 0`` is silence.

        Parameters
        ----------
        point : (3,) world contact point [m];  normal : (3,) world contact normal;
        normal_force : float [N];  speed : float, relative sliding speed [m/s];
        t0, t1 : float, interval [s] (samples with t0 <= n/fs < t1 are driven);
        roughness : float, force fluctuation per N and per m/s.
        """
        self._sustained("slide", name, point, normal, normal_force, speed, t0, t1, roughness, SLIDE_GRAIN_M)

    def roll(self, name, point, normal, normal_force, speed, t0, t1, *, roughness=ROLL_ROUGHNESS) -> None:
        """Rolling contact on ``[t0, t1)`` [s]: like :meth:`slide` but the roughness noise is
        low-passed at ``speed / ROLL_PATCH_M`` (the contact patch averages the roughness; van
        den Doel et al. 2001), so rolling is a duller rumble. ``speed == 0`` is silence."""
        self._sustained("roll", name, point, normal, normal_force, speed, t0, t1, roughness, ROLL_PATCH_M)

    def _sustained(self, kind, name, point, normal, normal_force, speed, t0, t1, roughness, length):
        ob = self._get(name)
        p = _finite_array(point, None, "point", "give world coordinates in metres").reshape(-1)
        nv = _finite_array(normal, None, "normal", "give a finite direction vector").reshape(-1)
        if p.shape != (3,) or nv.shape != (3,):
            raise ValueError("point and normal must be 3-vectors")
        fn = float(_finite_array(normal_force, None, "normal_force", "give the normal force in N"))
        v = float(_finite_array(speed, None, "speed", "give the sliding/rolling speed in m/s"))
        rough = float(_finite_array(roughness, None, "roughness", "give a non-negative number"))
        t0 = float(self._check_time(t0, "t0"))
        t1 = float(_finite_array(t1, None, "t1", "give the end time in seconds"))
        if t1 < t0:
            raise ValueError(f"t1={t1!r} is before t0={t0!r}; give an interval t0 <= t1 in seconds")
        self._sustained_trusted(kind, ob, p, nv, fn, v, t0, t1, rough, length)

    def _sustained_trusted(self, kind, ob, p, nv, fn, v, t0, t1, rough, length):
        """Internal fast path of :meth:`slide` / :meth:`roll` (inputs already checked)."""
        fs = self.sample_rate
        k0 = int(math.ceil(t0 * fs - _SAMPLE_TOL))
        k1 = int(math.ceil(t1 * fs - _SAMPLE_TOL))
        L = k1 - k0
        nn = math.sqrt(nv[0] * nv[0] + nv[1] * nv[1] + nv[2] * nv[2])
        if L <= 0 or v == 0.0 or fn == 0.0 or rough == 0.0 or nn == 0.0 or len(ob.keep) == 0:
            return
        if ob.rng is None:
            ob.rng = np.random.default_rng([self.seed, ob.index])
        x = ob.rng.standard_normal(L)
        fc = min(abs(v) / length, 0.45 * fs)
        a = 1.0 - math.exp(-2 * math.pi * fc / fs)
        nxt, y = ob.filter_state.get(kind, (None, 0.0))
        if nxt != k0:
            y = 0.0
        f = kernels.one_pole(x, a, y)
        ob.filter_state[kind] = (k1, float(f[-1]))
        f *= rough * abs(fn) * abs(v)
        self._add_source(ob, p, nv / nn, k0 / fs, f)

    def excite(self, name, point, direction, signal, time) -> None:
        """Drive ``name`` with a force signal: ``signal[k]`` [N] along ``direction`` (world,
        normalised) at world ``point``, sample k at time ``time + k / fs`` [s]."""
        ob = self._get(name)
        p = _finite_array(point, None, "point", "give world coordinates in metres").reshape(-1)
        dv = _finite_array(direction, None, "direction", "give a finite direction vector").reshape(-1)
        if p.shape != (3,) or dv.shape != (3,):
            raise ValueError("point and direction must be 3-vectors")
        f = _finite_array(signal, None, "signal", "give a 1-D force signal in N at the sample rate").reshape(-1)
        t = float(self._check_time(time, "time"))
        nn = np.linalg.norm(dv)
        if nn == 0 or len(f) == 0 or len(ob.keep) == 0:
            return
        self._add_source(ob, p, dv / nn, t, f.copy())

    def _add_source(self, ob, p, dirw, t_start, f):
        fs = self.sample_rate
        pl = (p - ob.pos) @ ob.R
        dl = dirw @ ob.R
        idx = int(self._nearest(ob, pl[None])[0])
        G = dl @ ob.shk[idx]  # (n,)
        base = G / (fs * ob.wd)
        r = self._distances(ob)
        owner = self._channels["owner"]
        r[owner != AIR] = 1.0
        ta = t_start + np.where(owner == AIR, r / self.speed_of_sound, 0.0)
        na = np.maximum(np.ceil(ta * fs - _SAMPLE_TOL).astype(np.int64), self.samples_rendered)
        dts = na / fs - ta
        w = np.zeros((len(r), len(ob.keep)), np.complex128)  # contact channels of other bodies: 0
        w[owner == AIR] = ob.weights[None, :] / r[owner == AIR, None]
        if self._dirty:
            self._rebuild()
        for m in np.flatnonzero(owner == ob.index).tolist():
            off = int(self._channels["w_off"][m])
            w[m] = self._chan_w[off:off + len(ob.keep)]
        g = base[None, :] * w * np.exp(ob.lam[None, :] * dts[:, None])  # (M, n)
        fmax = np.abs(f).max()
        gm = np.abs(g).max() if g.size else 0.0
        if not (gm <= MAX_AMPLITUDE) or not (gm * fmax <= MAX_AMPLITUDE):
            raise ValueError(f"force on {ob.name!r} is too large; check units (N)")
        L = len(f)
        M = len(r)
        for m in range(M):
            a = int(na[m])
            self._src.append((ob.index, m, a, a + L, g[m], f))
        self._ev.push(ob.index, np.arange(M, dtype=np.int64), na, np.ones(M, np.int8),
                      (g != 0).astype(np.complex128))

    # ------------------------------------------------------------------ persistent streams
    def _streams_clear(self) -> None:
        """Forget all sustained-contact streams (their ringing modes keep ringing)."""
        st = getattr(self, "_streams", None)
        if st is not None and st.n_mics == self.n_channels:
            st.clear()  # (in place: the kernels' compiled entry points stay valid)
        else:
            self._streams = StreamTable(self.n_channels, self.dtype)
        if not hasattr(self, "_render_all_call"):
            # numba kernels called through their compiled entry points (no per-call typing)
            self._render_all_call = EntryPoint(kernels.render_all)
            self._render_streams_call = EntryPoint(kernels.render_streams)
        self._st_epoch = getattr(self, "_st_epoch", 0) + 1  # stream indices held elsewhere are stale
        #: optional ``on_regain()`` called once before the gains of due streams are computed
        #: (a driver updates the poses and the microphones there), unless ``poses_current``
        #: says the driver has just done so
        self.on_regain = getattr(self, "on_regain", None)
        self.poses_current = False
        #: render blocks with streams and no forcing sources in one numba call (same sound to
        #: float32 rounding: 1.5e-6 of the peak on Ant-v5; False: one call per stage)
        self.fused_streams = True

    def _stream_drive(self, j, p, nv, fn, v, k0, k1, rough, length, regain) -> None:
        """Drive stream ``j`` (:meth:`stream`) on synth samples ``[k0, k1)`` with
        sliding/rolling noise of force ``fn`` [N] and speed ``v`` [m/s] at world ``p`` along
        world unit ``nv`` (see :meth:`slide`); the noise is generated now, so several drives may
        come before one :meth:`render`. The gains follow the point every ``regain`` samples
        (computed at the next render from the last point). (Drivers drive many streams per
        step in numba: :func:`.streams.stream_drive`.)"""
        fs = self.sample_rate
        amp = rough * abs(fn) * abs(v)
        fc = min(abs(v) / length, 0.45 * fs)
        alpha = 1.0 - math.exp(-2 * math.pi * fc / fs)
        args = (int(j), int(k0), int(k1), amp, alpha, np.asarray(p, np.float64), np.asarray(nv, np.float64),
                int(regain))
        need = stream_drive(self._streams.state, self._consts, *args)
        if need:
            self._streams.grow_ring(need)
            stream_drive(self._streams.state, self._consts, *args)

    def _streams_regain(self, n) -> None:
        """Gains of the streams marked due (from their last point and normal, the objects'
        poses and the microphones after ``on_regain``), then make sure the ring holds a block
        plus the delays."""
        st = self._streams.state
        if any_due(st):
            if self.on_regain is not None and not self.poses_current:
                self.on_regain()
            dmax = streams_gains(self.kernel_state())
            need = int(dmax) + n + 1
            if need > st.ring.shape[1]:
                self._streams.grow_ring(need)

    def _render_streams(self, ev, start, n, out) -> bool:
        """Render a block with streams and no forcing sources in one numba call
        (:func:`.kernels.render_streams`: due gains, stream rows, :func:`.kernels.render_all`);
        the same samples as :meth:`_streams_bank_rows` then ``render_all``. Returns whether
        every sample is finite."""
        may_regain = self.on_regain is None or self.poses_current
        while True:
            code = self._render_streams_call((self.kernel_state(), self._bank, self._layout), ev, start, n, may_regain,
                                          out, self.dtype.type(0))
            if code == kernels.RENDERED or code == kernels.RENDERED_NONFINITE:
                return code == kernels.RENDERED
            if code == kernels.REGAIN_FIRST:
                self.on_regain()
                may_regain = True
            else:  # the ring must hold the block plus the delays
                self._streams.grow_ring(code)

    def _streams_bank_rows(self, start, end) -> SourceRows:
        self._streams_regain(end - start)
        return SourceRows(*streams_bank_rows(self._streams.state, self._layout, start, end, self.dtype.type(0)))

    def _source_rows(self, srcs, start, end):
        """Forcing sources ``srcs`` (entries of ``_src`` overlapping ``[start, end)``) as
        :func:`.kernels.render_all` rows: ``(ptr, a, b, gr, gi, F)``, gains placed in the
        microphone banks, grouped by microphone (by voice, then in order, within one)."""
        vb = self._vbase
        dt = self.dtype
        n = end - start
        sv = np.array([vb[s[0]] + s[1] for s in srcs], np.int64)
        order = np.argsort(sv, kind="stable")
        q = len(srcs)
        src_a = np.empty(q, np.int64)
        src_b = np.empty(q, np.int64)
        gr = np.zeros((q, self._nmax), dt)
        gi = np.zeros((q, self._nmax), dt)
        F = np.zeros((q, n), dt)
        for j, i in enumerate(order.tolist()):
            _, _, a, b, g, f = srcs[i]
            src_a[j] = a
            src_b[j] = b
            gr[j, : len(g)] = g.real
            gi[j, : len(g)] = g.imag
            lo, hi = max(a, start), min(b, end)
            F[j, lo - start: hi - start] = f[lo - a: hi - a]
        lay = self._layout
        sm, gr, gi = kernels.place_rows(sv[order], gr, gi, lay.v_rel, lay.v_len, lay.v_mic, lay.width)
        if self.n_channels > 1:  # rows by microphone (one microphone: already in order)
            order = np.argsort(sm, kind="stable")
            src_a, src_b, gr, gi, F, sm = src_a[order], src_b[order], gr[order], gi[order], F[order], sm[order]
        return SourceRows(np.searchsorted(sm, self._mic_ptr), src_a, src_b, gr, gi, F)

    # ------------------------------------------------------------------ rendering
    def _rebuild(self) -> None:
        """Lay all voices out in flat arrays (one numba call renders them all); the per-voice
        arrays become views, so ringing state survives the rebuild."""
        obs = list(self._objects.values())
        M = self.n_channels
        nv = len(obs) * M
        v_off = np.zeros(nv, np.int64)
        v_len = np.zeros(nv, np.int64)
        v_mic = np.zeros(nv, np.int64)
        # voice ids are object-major (vbase + mic) but the state is laid out microphone-major:
        # all voices of one microphone form one contiguous bank, rendered in one pass
        # (a loop over many modes per sample vectorises; a few modes per voice does not)
        j = 0
        for ob in obs:
            ob.vbase = j
            for m in range(M):
                v_len[j] = len(ob.keep)
                v_mic[j] = m
                j += 1
        mic_off = np.zeros(M + 1, np.int64)
        total = 0
        for m in range(M):
            mic_off[m] = total
            for ob in obs:
                v_off[ob.vbase + m] = total
                total += len(ob.keep)
        mic_off[M] = total
        dt = self.dtype
        Zr, Zi, P2 = np.zeros(total), np.zeros(total), np.zeros(total)
        ACT = np.zeros(total, np.bool_)
        PR, PI = np.zeros(total, dt), np.zeros(total, dt)
        CR, CI = np.zeros(total), np.zeros(total)
        j = 0
        for ob in obs:
            for m in range(M):
                o, n = v_off[j], v_len[j]
                sl = slice(o, o + n)
                v = ob.voices[m]
                Zr[sl], Zi[sl], P2[sl], ACT[sl] = v.zr, v.zi, v.peak2, v.active
                v.zr, v.zi, v.peak2, v.active = Zr[sl], Zi[sl], P2[sl], ACT[sl]
                PR[sl], PI[sl], CR[sl], CI[sl] = ob.pr, ob.pi, ob.corr_r, ob.corr_i
                j += 1
        mic_len = np.diff(mic_off)
        self._mic_ptr = np.arange(M + 1)
        live = np.zeros(M, np.bool_)
        for m in range(M):
            live[m] = ACT[mic_off[m]: mic_off[m + 1]].any()
        # one bank per microphone (render_all renders banks)
        self._bank = Bank(Zr, Zi, P2, ACT, PR, PI, CR, CI, mic_off[:-1].copy(), mic_len, np.arange(M, dtype=np.int64),
                          live)
        self._vbase = {ob.index: ob.vbase for ob in obs}
        self._by_index = {ob.index: ob for ob in obs}
        # every object's gain inputs in flat arrays indexed by object index (streams_gains)
        nidx = self._next_index + 1
        offs = {k: np.zeros(nidx + 1, np.int64) for k in ("pts_off", "shk_off", "mode_off")}
        for i in range(nidx):
            ob = self._by_index.get(i)
            offs["pts_off"][i + 1] = offs["pts_off"][i] + (len(ob.pts) if ob is not None else 0)
            offs["shk_off"][i + 1] = offs["shk_off"][i] + (ob.shk.size if ob is not None else 0)
            offs["mode_off"][i + 1] = offs["mode_off"][i] + (len(ob.keep) if ob is not None else 0)

        def cat(f, shape):
            parts = [f(self._by_index[i]) for i in range(nidx) if i in self._by_index]
            return np.ascontiguousarray(np.concatenate(parts) if parts else np.zeros(shape))

        self._object_table = ObjectTable(
            pts=cat(lambda ob: ob.pts.reshape(-1, 3), (0, 3)), pts_off=offs["pts_off"],
            shk=cat(lambda ob: ob.shk.ravel(), (0,)), shk_off=offs["shk_off"], mode_off=offs["mode_off"],
            wd=cat(lambda ob: ob.wd, (0,)), w=cat(lambda ob: np.asarray(ob.weights, np.float64), (0,)),
            lam=cat(lambda ob: ob.lam, (0,)).astype(np.complex128),
            leps=cat(lambda ob: ob.logeps, (0,)).astype(np.complex128))
        vb_arr = np.full(self._next_index + 1, -1, np.int64)  # -1: removed (its queued events are dropped)
        for ob in obs:
            vb_arr[ob.index] = ob.vbase
        # voice ids are object-major; v_rel: offset of each voice inside its microphone's bank
        self._layout = BankLayout(vb_arr, v_off - mic_off[v_mic], v_len, v_mic, int(mic_len.max()) if M else 0)
        self._ev_ptr0 = np.zeros(M + 1, np.int64)
        self._nmax = max([len(ob.keep) for ob in obs], default=0)
        self._consts[0]["nmax"] = self._nmax
        self._consts[0]["n_mics"] = M
        # contact channels: their owner's complex weights (phi(x) . n) lambda^2 per kept mode
        parts, off = [], 0
        for m, (name, p, a) in sorted(self._contacts.items()):
            ob = self._objects.get(name) if name is not None else None
            if ob is None:
                self._channels[m]["owner"] = DEAF
                continue
            g = ob.model.gains(p[None], a[None])[0][ob.keep]
            parts.append(np.ascontiguousarray(g * ob.lam**2, np.complex128))
            self._channels[m]["owner"] = ob.index
            self._channels[m]["w_off"] = off
            off += len(parts[-1])
        self._chan_w = np.concatenate(parts) if parts else np.zeros(0, np.complex128)
        self._empty_ev = EventRows(self._ev_ptr0, np.zeros(0, np.int64), np.zeros(0, np.int8),
                                   np.zeros((0, self._nmax)), np.zeros((0, self._nmax)))
        self._empty_src = (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, self._nmax), dt),
                           np.zeros((0, self._nmax), dt))
        self._dirty = False

    @interruptible
    def render(self, n_samples) -> np.ndarray:
        """Render the next ``n_samples`` samples.

        Returns
        -------
        (n_channels, n_samples) float32 array of sound pressure [Pa] at the microphones,
        for times ``time .. time + (n_samples - 1) / fs`` (never NaN: non-finite samples, from
        an exploding simulation, are set to 0).
        """
        try:
            n = int(n_samples)
        except (TypeError, ValueError):
            raise ValueError(f"n_samples={n_samples!r} must be a non-negative integer") from None
        if n < 0 or n != n_samples:
            raise ValueError(f"n_samples={n_samples!r} must be a non-negative integer")
        dt = self.dtype
        out = np.zeros((self.n_channels, n), dtype=dt)
        if n == 0:
            return out.astype(np.float32)
        if self._dirty:
            self._rebuild()
        start = self.samples_rendered
        end = start + n
        streams = self._streams.n > 0
        if self._ev.count or self._src or streams or self._bank.live.any():
            # ---- events due in this block: rows placed in the microphone banks, sorted by
            # (microphone, sample), ties in order
            if self._ev.count and self._ev.next_sample < end:
                lay = self._layout
                ev = self._ev.take(end, lay.vbase, lay.v_rel, lay.v_len, self.n_channels, lay.width)
            else:
                ev = self._empty_ev
            # ---- forcing sources overlapping the block, as rows placed in the microphone banks
            # and grouped by microphone (src.ptr)
            srcs = [s for s in self._src if s[2] < end and s[3] > start] if self._src else ()
            if streams and not srcs and self.fused_streams:  # (the common case while something slides or rolls)
                finite = self._render_streams(ev, start, n, out)
                self.samples_rendered = end
                return _finite(out.astype(np.float32, copy=False), finite)
            if srcs:
                src = self._source_rows(srcs, start, end)
                self._src = [s for s in self._src if s[3] > end]
            if streams:
                # persistent sliding / rolling streams: noise generated in numba, rows placed there
                rows = self._streams_bank_rows(start, end)
                if srcs:  # both: merged by microphone, the forcing sources' rows first
                    M = self.n_channels
                    mic = np.concatenate([np.repeat(np.arange(M), np.diff(src.ptr)),
                                          np.repeat(np.arange(M), np.diff(rows.ptr))])
                    order = np.argsort(mic, kind="stable")
                    src = SourceRows(np.searchsorted(mic[order], self._mic_ptr),
                                     *(np.concatenate([x, y])[order] for x, y in zip(src[1:], rows[1:])))
                else:
                    src = rows
            elif not srcs:
                src = SourceRows(self._ev_ptr0, *self._empty_src, np.zeros((0, n), dt))
            self._render_all_call((self._bank, self._consts), ev, src, start, n, out, dt.type(0))
        self.samples_rendered = end
        return _finite(out.astype(np.float32, copy=False))

    def reset(self) -> None:
        """Silence everything and restart time at 0 (objects, poses and microphones stay;
        the noise generators restart from the seed)."""
        self.samples_rendered = 0
        self._ev.clear()
        self._src = []
        if not self._dirty:
            b = self._bank
            b.zr[:] = 0.0
            b.zi[:] = 0.0
            b.peak2[:] = 0.0
            b.active[:] = False
            b.live[:] = False
        else:
            for ob in self._objects.values():
                ob.voices = [_Voice(len(ob.keep)) for _ in range(self.n_channels)]
        for ob in self._objects.values():
            ob.rng = None
            ob.filter_state = {}
        self._streams_clear()
