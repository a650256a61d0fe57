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
Each object reaches air microphone m, at distance ``r`` from the object's origin in the
direction ``u`` (object frame), as::

    p_m(t) = sum_i  D_i(u) w_i q_i(t - r/c) / r        [Pa]

where ``w_i`` is ``model.radiation[i]`` [Pa m per unit modal coordinate] (``radiation=True``)
and ``D_i(u) = P_i(u) / w_i`` the direction factor of the model's pattern
``model.radiation_pattern`` (:mod:`.directivity`: followed per render block as objects move
and turn, ramped across the block; 1 for a model heard the same in every direction, with
``directivity=False`` or with the proxy)
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
from .constants import (D_MIN_PER_S, FLOOR_PA, GRID, MAX_AMPLITUDE, R_MIN_M, ROLL_PATCH_M, ROLL_ROUGHNESS,
                        SAMPLE_TOL, SLIDE_GRAIN_M, SLIDE_ROUGHNESS, TIME_TOLERANCE_S)
from .impacts import ImpactMethods
from .interrupt import interruptible
from .objects import ObjectModes, PoseTable, SynthObject, VoiceState, build_layout, finite_array, prepare_object
from .queue import EventQueue
from .records import AIR, CHANNEL, DEAF, SYNTH_CONSTS, EventRows, RenderTarget, SourceRows, SynthState
from .sources import ForcingSources
from .stream_table import RING_SLACK, StreamMethods

__all__ = ["Synthesizer", "GRID", "D_MIN_PER_S", "R_MIN_M", "TIME_TOLERANCE_S", "MAX_AMPLITUDE", "SLIDE_ROUGHNESS",
           "SLIDE_GRAIN_M", "ROLL_ROUGHNESS", "ROLL_PATCH_M"]


def _finite(block: np.ndarray, finite: bool | None = None) -> np.ndarray:
    """``block`` with NaN and infinities set to 0 (an exploding simulation must not hand out
    NaN audio); ``finite=True`` when that is known already."""
    if finite is None:
        finite = bool(np.isfinite(block).all())
    return block if finite else np.nan_to_num(block, copy=False, nan=0.0, posinf=0.0, neginf=0.0)


class Synthesizer(ImpactMethods, ForcingSources, StreamMethods):
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
    directivity : bool
        Hear each mode with the model's radiation pattern in the direction of each air
        microphone (:mod:`.directivity`; default), or with its RMS over directions (``False``).

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
                 radiation=True, speed_of_sound=343.0, seed=0, f_max=None, directivity=True):
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
        self.directivity = bool(directivity)
        self._objects: dict[str, SynthObject] = {}
        self._next_index = 0
        self._poses = PoseTable()
        # pending events (.queue); forcing sources: (object index, mic, a, b, g (n,), f (b - a,))
        self._ev = EventQueue()
        self._src = []
        self._dirty = True  # voice layout must be rebuilt before rendering
        self._mics = self._check_mics(np.array([[0.0, 0.0, 1.0]]) if microphones is None else microphones)
        # output channels: air microphones, then contact microphones (add_contact_microphone)
        self._channels = np.zeros(len(self._mics), CHANNEL)
        self._channels["owner"] = AIR
        self._channels["w_off"] = -1
        self._responses = {}  # air channel -> (frequencies [Hz], gains): an image microphone's reflection
        self._contacts = {}  # channel -> (object name or None, point, axis) in the object frame
        self._chan_w = np.zeros(0, np.complex128)
        self._consts = np.zeros(1, SYNTH_CONSTS)
        self._rendered = self._consts["rendered"]  # (a plain int64 view: read on every render)
        for k, v in (("c", c), ("fs", float(self.sample_rate)), ("rmin", R_MIN_M), ("tol", SAMPLE_TOL),
                     ("grid", GRID), ("slack", RING_SLACK), ("cull2", self._cull2), ("floor2", FLOOR_PA**2)):
            self._consts[0][k] = v
        self.samples_rendered = 0
        self._streams_clear()
        self._kernel_state = None  # (kernel_state(): made on first use, kept while its arrays are)
        self._render_target = None  # (render_target(): likewise)

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
        return int(self._rendered[0])

    @samples_rendered.setter
    def samples_rendered(self, n: int) -> None:
        self._rendered[0] = n

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
        p = finite_array(positions, "microphones", "give (m, 3) world positions in metres")
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
            ob.voices = ob.voices[: len(p)] + [VoiceState(n) for _ in range(max(0, len(p) - old))]
        self._channels = np.resize(self._channels, len(p))
        self._channels["owner"][old:] = AIR
        self._channels["w_off"][old:] = -1
        self._responses = {m: v for m, v in self._responses.items() if m < len(p)}
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
        p = finite_array(point, "point", "give the contact microphone's point in the object frame [m]")
        a = finite_array(axis, "axis", "give the sensing axis as a 3-vector in the object frame")
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

    def set_channel_response(self, channel: int, frequencies, gains) -> None:
        """Make air channel ``channel`` an image microphone: every mode it hears is multiplied
        by a real gain read off its frequency (the reflection of the surface the image is
        behind, :mod:`mjsound.sim.reflections`).

        Parameters
        ----------
        channel : int
            An air microphone's channel.
        frequencies : (k,) array_like
            Increasing frequencies [Hz] (> 0), e.g. octave band centres.
        gains : (k,) array_like
            The gain at each [-] (>= 0). Between two frequencies the gain is interpolated
            linearly in log frequency; below the first and above the last it is constant.
            ``frequencies=None`` makes the channel a plain microphone again.

        Examples
        --------
        >>> synth.set_channel_response(1, [125, 4000], [0.99, 0.6])  # doctest: +SKIP
        """
        m = int(channel)
        if not (0 <= m < self.n_channels) or self._channels["owner"][m] != AIR:
            raise ValueError(f"set_channel_response: channel {channel!r} is not an air microphone of this synthesizer")
        if frequencies is None:
            self._responses.pop(m, None)
        else:
            f = finite_array(frequencies, "frequencies", "give increasing frequencies in Hz").reshape(-1)
            g = finite_array(gains, "gains", "give one finite gain >= 0 per frequency").reshape(-1)
            if len(f) == 0 or len(f) != len(g) or np.any(f <= 0) or np.any(np.diff(f) <= 0) or np.any(g < 0):
                raise ValueError("set_channel_response: give k > 0 increasing frequencies [Hz] > 0 and k gains >= 0")
            self._responses[m] = (f.copy(), g.copy())
        self._dirty = True

    def channel_response(self, channel: int):
        """``(frequencies [Hz], gains)`` of air channel ``channel``'s response
        (:meth:`set_channel_response`; copies), or None for a plain microphone."""
        r = self._responses.get(int(channel))
        return None if r is None else (r[0].copy(), r[1].copy())

    @staticmethod
    def response_at(frequencies, gains, f) -> np.ndarray:
        """The gain of a channel response (:meth:`set_channel_response`) at frequencies ``f``
        [Hz]: linear in log frequency between the points, constant outside."""
        return np.interp(np.log(np.maximum(np.asarray(f, np.float64), 1e-30)), np.log(frequencies), gains)

    def object_pose(self, name) -> tuple[np.ndarray, np.ndarray]:
        """``(position (3,), rotation (3, 3))`` of object ``name`` (object to world), copies."""
        ob = self._get(name)
        return ob.pos.copy(), ob.R.copy()

    def object_modes(self, name) -> ObjectModes:
        """The kept modes of object ``name`` as this synthesizer renders them (copies): pose,
        shapes, decay, damped frequency, radiation weights, microphone distances and the
        direction factors' fit. For references computed outside the renderer (closed forms,
        bounds)."""
        ob = self._get(name)
        return ObjectModes(ob.pos.copy(), ob.R.copy(), ob.model, ob.keep.copy(), ob.shk.copy(), ob.d.copy(),
                           ob.wd.copy(), np.array(ob.weights, np.float64), self._distances(ob), ob.directions)

    def direction_factors(self, name) -> np.ndarray:
        """(channels, n_modes) complex: the direction factor ``D`` (:mod:`.directivity`) each
        channel hears ``name``'s kept modes with now (after the last rendered block; 1 for
        contact microphones and objects heard the same in every direction; NaN for a silent
        mode whose factor is made only when something excites it)."""
        ob = self._get(name)
        return np.array([v.dr + 1j * v.di for v in ob.voices])

    def object_points_world(self, name) -> np.ndarray:
        """The surface samples of ``name``'s model in world coordinates, (p, 3) [m]."""
        ob = self._get(name)
        return ob.pos[None, :] + ob.pts @ ob.R.T

    @staticmethod
    def _check_pose(position, rotation, name):
        pos = finite_array(position, f"position of {name!r}", "give 3 finite coordinates in metres")
        if pos.shape != (3,):
            raise ValueError(f"position of {name!r} must have 3 coordinates, got shape {pos.shape}")
        R = finite_array(rotation, f"rotation of {name!r}", "give a 3x3 rotation matrix")
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
        ob = prepare_object(name, model, self._next_index, self._poses, pos, R, self.sample_rate, self.dtype,
                            self.radiation, self.f_max, self.n_channels, self.directivity)
        self._next_index += 1
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

    def _get(self, name) -> SynthObject:
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

    # ------------------------------------------------------------------ for drivers (numba)
    def kernel_state(self) -> SynthState:
        """The arrays the per-step kernels read and write (:class:`.records.SynthState`): every
        object's modal data, poses, microphones, constants, the event queue and the streams.
        Valid until the synthesizer next grows a buffer or changes its objects or
        microphones: ask again after any call into the synthesizer."""
        if self._dirty:
            self._rebuild()
        st = self._streams.state
        if st is None:
            st = self._streams.empty
        # the same tuple while its arrays are the same: the step driver calls the
        # compiled entry point directly only while its arguments are the objects it was looked
        # up for (a new tuple each call typed every argument in Python: 4x the step time)
        ks = self._kernel_state
        if (ks is None or ks.queue is not self._ev.state or ks.streams is not st or ks.objects is not self._object_table
                or ks.pos is not self._poses.pos or ks.R is not self._poses.R or ks.mics is not self._mics
                or ks.channels is not self._channels or ks.chan_w is not self._chan_w):
            ks = self._kernel_state = SynthState(self._object_table, self._poses.pos, self._poses.R, self._mics,
                                                 self._consts, self._ev.state, st, self._channels, self._chan_w)
        return ks

    def render_target(self) -> RenderTarget:
        """What the step kernel needs to render a block itself (:class:`.records.RenderTarget`:
        the banks and their layout), valid as long as :meth:`kernel_state` is."""
        if self._dirty:
            self._rebuild()
        rt = self._render_target
        if rt is None or rt.bank is not self._bank or rt.layout is not self._layout:
            dt = self.dtype
            rt = self._render_target = RenderTarget(self._bank, self._layout, np.zeros(1, dt),
                                                    np.zeros((len(self._mics), 0), dt))
        return rt

    @property
    def renders_in_kernel(self) -> bool:
        """Whether a block can be rendered by one numba call (:func:`.kernels.render_streams`,
        as :meth:`render` does; not with Python forcing sources pending)."""
        return not self._src and self.fused_streams

    def new_block(self, n: int) -> np.ndarray:
        """A zeroed ``(channels, n)`` block of the bank dtype for a kernel to render into."""
        return np.zeros((len(self._mics), n), self.dtype)

    def kernel_block(self, out: np.ndarray, finite: bool) -> np.ndarray:
        """The block a kernel rendered into ``out`` (:meth:`new_block`) as :meth:`render`
        returns it: float32, never NaN (``finite``: the kernel found every sample finite)."""
        return _finite(out.astype(np.float32, copy=False), finite)

    # ------------------------------------------------------------------ rendering
    def _rebuild(self) -> None:
        """Lay all voices out in flat arrays (one numba call renders them all); the per-voice
        arrays become views, so ringing state survives the rebuild."""
        air = np.array([m not in self._contacts for m in range(self.n_channels)], np.bool_)
        lay = build_layout(list(self._objects.values()), self.n_channels, self._next_index, self.dtype, air)
        self._bank, self._layout, self._object_table = lay.bank, lay.layout, lay.table
        self._vbase, self._by_index, self._mic_ptr = lay.vbase, lay.by_index, lay.mic_ptr
        M = self.n_channels
        dt = self.dtype
        self._ev_ptr0 = np.zeros(M + 1, np.int64)
        self._nmax = lay.nmax
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
        # image microphones: a real gain per mode of every object, in object-table order
        obs = [self._by_index[i] for i in sorted(self._by_index)]
        self._channels["w_off"][self._channels["owner"] == AIR] = -1
        for m, (f, g) in sorted(self._responses.items()):
            if self._channels[m]["owner"] != AIR:
                continue
            gm = [self.response_at(f, g, ob.wd / (2 * np.pi)) for ob in obs]
            parts.append(np.concatenate(gm).astype(np.complex128) if gm else np.zeros(0, np.complex128))
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
        n = n_samples
        if type(n) is not int or n < 0:  # (the per-step call passes a plain int: checked once)
            try:
                n = int(n_samples)
            except (TypeError, ValueError):
                raise ValueError(f"n_samples={n_samples!r} must be a non-negative integer") from None
            if n < 0 or n != n_samples:
                raise ValueError(f"n_samples={n_samples!r} must be a non-negative integer")
        if self._dirty:
            self._rebuild()
        dt = self.dtype
        out = np.zeros((len(self._mics), n), dtype=dt)
        if n == 0:
            return out.astype(np.float32)
        start = int(self._rendered[0])
        end = start + n
        if not self._src and self.fused_streams:
            # (the common case: no forcing sources) due events, streams and banks in one numba
            # call; nothing queued, streamed or ringing: silence without one
            finite = True
            if self._ev.count or self._streams.n or self._bank.live.any():
                finite = self._render_streams(start, n, out)
            self._rendered[0] = end
            return _finite(out.astype(np.float32, copy=False), finite)
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
            if self._bank.direction.n_objects[0]:
                self._hear_call((self.kernel_state(), self._bank, self._layout), ev, src, n)
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
                ob.voices = [VoiceState(len(ob.keep)) for _ in range(self.n_channels)]
        for ob in self._objects.values():
            ob.rng = None
            ob.filter_state = {}
        self._streams_clear()
