"""The synthesizer's objects: one object's modal data prepared for rendering
(:func:`prepare_object`), the world poses of all objects (:class:`PoseTable`) and the flat
layout of every object's modes in one bank per microphone (:func:`build_layout`).

Discretisation (see :mod:`.kernels`): mode i rings as ``z_i[n+1] = p_i z_i[n]`` with the
pole ``p_i = e^{lambda_i / fs}``, ``lambda_i = -d_i + j w_i``, rounded to the bank's dtype
with ``|p_i| < 1``; the rounding's systematic error is cancelled on a fixed grid of ``GRID``
samples by ``corr_i = (p_exact / p_rounded)^GRID``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .constants import D_MIN_PER_S, GRID, RHO_AIR
from .directivity import DIRECTION_FLOOR, DIRECTION_STEP_DEG, DirectionFit, fit_directions, sh_count, sh_tables
from .records import DIRECTIONS, Bank, BankLayout, DirectionState, ObjectTable

__all__ = ["finite_array", "VoiceState", "PoseTable", "SynthObject", "ObjectModes", "prepare_object", "Layout", "build_layout"]


def finite_array(x, what, fix):
    """``x`` as a float64 array; a ``ValueError`` naming ``what`` and the ``fix`` when it is not
    numeric or not finite."""
    try:
        a = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be numeric; {fix}") from None
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{what} contains NaN or Inf; {fix}")
    return a


class VoiceState:
    """State of one (object, microphone) pair: views into the synthesizer's flat state (the
    modes' state, and the direction factor ``dr + j di`` it carries, made for the direction
    ``u``: :mod:`.directivity`)."""

    __slots__ = ("zr", "zi", "peak2", "active", "dr", "di", "u")

    def __init__(self, n):
        self.zr = np.zeros(n)
        self.zi = np.zeros(n)
        self.peak2 = np.zeros(n)
        self.active = np.zeros(n, dtype=np.bool_)
        self.dr = np.ones(n)
        self.di = np.zeros(n)
        self.u = np.full(3, np.nan)


class PoseTable:
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


class SynthObject:
    """One object's modal data; its pose (``pos`` (3,) [m], ``R`` (3, 3) body-to-world) is
    row ``index`` of the synthesizer's :class:`PoseTable` (views: they change with it)."""

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


class ObjectModes(NamedTuple):
    """The modes the synthesizer renders for one object, as it holds them (read-only copies;
    for references and reports, :meth:`.Synthesizer.object_modes`). ``n`` kept modes, ``p``
    surface samples, ``m`` microphones."""

    position: np.ndarray  #: (3,) [m], object to world
    rotation: np.ndarray  #: (3, 3), object to world
    model: object  #: the :class:`~mjsound.modal.model.ModalModel` added
    keep: np.ndarray  #: (n,) int, indices of the kept modes in ``model`` (audible, underdamped)
    shapes: np.ndarray  #: (p, 3, n) mass-normalised mode shapes at the surface samples
    decay: np.ndarray  #: (n,) decay rate d [1/s]
    damped_omega: np.ndarray  #: (n,) damped angular frequency sqrt(w0^2 - d^2) [rad/s]
    weights: np.ndarray  #: (n,) radiation weight [Pa m]: a modal displacement q gives weights * q / r at r
    mic_distances: np.ndarray  #: (m,) distance to each microphone [m] (floored at R_MIN_M)
    directions: DirectionFit  #: the direction factors' fit (order -1: the same in every direction)


def prepare_object(name, model, index, poses, pos, R, sample_rate, dtype, radiation, f_max, n_mics,
                   directivity=True) -> SynthObject:
    """Object ``name`` of ``model`` ready to render, at row ``index`` of ``poses`` (placed at
    world ``pos``, rotation ``R``), with ``n_mics`` silent voices.

    Modes at or above ``0.45 fs`` (or ``f_max``), overdamped ones (``d >= omega``) and
    non-positive frequencies are dropped; a zero or negative decay becomes ``D_MIN_PER_S``.
    ``w_d = sqrt(w0^2 - d^2)``; radiation weights from the model (``radiation``, as
    :func:`mjsound.analyze` made it: capped at radiation efficiency 1 with the decay that goes
    with that, :mod:`mjsound.modal.radiation_bound`) or the
    modal-acceleration proxy ``-w0^2 rho_air / (4 pi) size^2 rms(phi . n)``; poles rounded to
    ``dtype`` and the grid correction (module docstring); with ``radiation`` and ``directivity``
    the direction factors of the model's ``radiation_pattern`` (:func:`.directivity.fit_directions`;
    the proxy is heard the same in every direction)."""
    rad, decay = np.asarray(model.radiation, np.float64), np.asarray(model.decay_per_s, np.float64)
    fs = sample_rate
    f = model.frequencies_hz
    d = np.where(decay > 0, decay, D_MIN_PER_S)
    w0 = 2 * np.pi * f
    limit = 0.45 * fs if f_max is None else min(0.45 * fs, f_max)
    keep = np.flatnonzero((f < limit) & (d < w0) & (f > 0))
    ob = SynthObject()
    ob.name = name
    ob.model = model
    ob.keep = keep
    ob.index = index
    ob.poses = poses
    poses.ensure(index + 1)
    ob.pos, ob.R = pos, R
    d = d[keep]
    wd = np.sqrt(w0[keep] ** 2 - d**2)
    ob.d, ob.wd = d, wd
    ob.lam = -d + 1j * wd
    if radiation:
        ob.weights = rad[keep]
    else:
        sh = model.shapes[:, :, keep].astype(np.float64)
        if len(model.points):
            nrm = np.einsum("pcn,pc->pn", sh, model.normals.astype(np.float64))
            rms = np.sqrt(np.mean(nrm**2, axis=0))
        else:
            rms = np.zeros(len(keep))
        size = model.size_m if model.size_m > 0 else 0.1
        ob.weights = -(w0[keep] ** 2) * RHO_AIR / (4 * np.pi) * size**2 * rms
    if radiation and directivity:
        ob.directions = fit_directions(model, keep, rad[keep], name)
    else:
        ob.directions = DirectionFit.none(len(keep))
    # rounded poles with |p| < 1, and the exact-pole correction
    p = np.exp(ob.lam / fs)
    dt = dtype
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
    ob.voices = [VoiceState(len(keep)) for _ in range(n_mics)]
    ob.mass = float(model.mass_kg) if np.isfinite(model.mass_kg) and model.mass_kg > 0 else np.inf
    # hot-path caches: kept shapes (p, 3, n) float64, surface points for the nearest lookup
    ob.shk = np.ascontiguousarray(model.shapes[:, :, keep], dtype=np.float64)
    ob.pts = np.ascontiguousarray(model.points, dtype=np.float64)
    return ob


def _direction_state(by_index, nidx, AR, AI, U, DM, mic_off) -> DirectionState:
    """The banks' :class:`.records.DirectionState` for objects ``by_index`` (index -> object),
    the applied factors ``AR + j AI`` and directions ``U`` the voices carry, and which modes
    are directional ``DM``."""
    order = np.full(nidx, -1, np.int64)
    counts, parts = [], []  # (every kept mode in object-index order, as ObjectTable.mode_off counts them)
    for i in range(nidx):
        ob = by_index.get(i)
        if ob is None:
            continue
        fit = ob.directions
        order[i] = fit.order
        for j in range(len(ob.keep)):
            k = sh_count(fit.orders[j]) if fit.order >= 0 else 0
            counts.append(k)
            parts.append(fit.coef[j, :k])
    msh_off = np.concatenate([[0], np.cumsum(counts, dtype=np.int64)]).astype(np.int64)
    coef = np.concatenate(parts) if parts else np.zeros(0, np.complex128)
    top = max(int(order.max(initial=-1)), 0)
    params = np.zeros(1, DIRECTIONS)
    params[0]["cos_step"] = np.cos(np.radians(DIRECTION_STEP_DEG))
    params[0]["floor"] = DIRECTION_FLOOR
    on = np.array([DM[mic_off[m]: mic_off[m + 1]].any() for m in range(len(mic_off) - 1)], np.bool_)
    total = len(AR)
    return DirectionState(order, msh_off, np.ascontiguousarray(coef.real), np.ascontiguousarray(coef.imag), U, AR, AI,
                          AR.copy(), AI.copy(), np.zeros(total), np.zeros(total), np.ones(total), np.zeros(total),
                          np.zeros(len(on), np.bool_), on, DM, np.array([int((order >= 0).sum())], np.int64), params,
                          np.zeros((len(mic_off) - 1, sh_count(top))), sh_tables(top))


class Layout(NamedTuple):
    """:func:`build_layout`'s result."""

    bank: Bank
    layout: BankLayout
    table: ObjectTable
    vbase: dict  # object index -> its first voice id
    by_index: dict  # object index -> SynthObject
    mic_ptr: np.ndarray  # (mics + 1,) 0 .. mics
    nmax: int  # modes of the widest object


def build_layout(obs, M, next_index, dtype, air=None) -> Layout:
    """Lay the voices of the objects ``obs`` at ``M`` microphones out in flat arrays (one numba
    call renders them all); each object's per-voice arrays become views of them, so ringing
    state survives a rebuild. ``next_index``: the next object index to be given out; ``air``
    (M,) bool: which channels are air microphones (default all), whose voices follow the
    direction (:mod:`.directivity`)."""
    air = np.ones(M, np.bool_) if air is None else np.asarray(air, np.bool_)
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
    dt = dtype
    Zr, Zi, P2 = np.zeros(total), np.zeros(total), np.zeros(total)
    ACT = np.zeros(total, np.bool_)
    PR, PI = np.zeros(total, dt), np.zeros(total, dt)
    CR, CI = np.zeros(total), np.zeros(total)
    AR, AI, DM = np.ones(total), np.zeros(total), np.zeros(total, np.bool_)
    U = np.full((nv, 3), np.nan)
    j = 0
    for ob in obs:
        for m in range(M):
            o, n = v_off[j], v_len[j]
            sl = slice(o, o + n)
            v = ob.voices[m]
            Zr[sl], Zi[sl], P2[sl], ACT[sl] = v.zr, v.zi, v.peak2, v.active
            v.zr, v.zi, v.peak2, v.active = Zr[sl], Zi[sl], P2[sl], ACT[sl]
            AR[sl], AI[sl], U[j] = v.dr, v.di, v.u
            v.dr, v.di, v.u = AR[sl], AI[sl], U[j]
            DM[sl] = air[m] and ob.directions.order >= 0
            PR[sl], PI[sl], CR[sl], CI[sl] = ob.pr, ob.pi, ob.corr_r, ob.corr_i
            j += 1
    mic_len = np.diff(mic_off)
    mic_ptr = np.arange(M + 1)
    live = np.zeros(M, np.bool_)
    for m in range(M):
        live[m] = ACT[mic_off[m]: mic_off[m + 1]].any()
    vbase = {ob.index: ob.vbase for ob in obs}
    by_index = {ob.index: ob for ob in obs}
    # one bank per microphone (render_all renders banks)
    bank = Bank(Zr, Zi, P2, ACT, PR, PI, CR, CI, mic_off[:-1].copy(), mic_len, np.arange(M, dtype=np.int64),
                live, _direction_state(by_index, next_index + 1, AR, AI, U, DM, mic_off))
    # every object's gain inputs in flat arrays indexed by object index (streams_gains)
    nidx = next_index + 1
    offs = {k: np.zeros(nidx + 1, np.int64) for k in ("pts_off", "shk_off", "mode_off")}
    for i in range(nidx):
        ob = by_index.get(i)
        offs["pts_off"][i + 1] = offs["pts_off"][i] + (len(ob.pts) if ob is not None else 0)
        offs["shk_off"][i + 1] = offs["shk_off"][i] + (ob.shk.size if ob is not None else 0)
        offs["mode_off"][i + 1] = offs["mode_off"][i] + (len(ob.keep) if ob is not None else 0)

    def cat(f, shape):
        parts = [f(by_index[i]) for i in range(nidx) if i in by_index]
        return np.ascontiguousarray(np.concatenate(parts) if parts else np.zeros(shape))

    # surface points sorted along each object's longest coordinate axis (nearest_sorted)
    axis = np.zeros(nidx, np.int64)
    order = {}
    for i, ob in by_index.items():
        p = ob.pts.reshape(-1, 3)
        axis[i] = int(np.argmax(np.ptp(p, axis=0))) if len(p) else 0
        order[i] = np.argsort(p[:, axis[i]], kind="stable")
    table = ObjectTable(
        pts=cat(lambda ob: ob.pts.reshape(-1, 3)[order[ob.index]], (0, 3)), pts_off=offs["pts_off"],
        pts_index=cat(lambda ob: order[ob.index].astype(np.int64), (0,)).astype(np.int64), pts_axis=axis,
        shk=cat(lambda ob: ob.shk.ravel(), (0,)), shk_off=offs["shk_off"], mode_off=offs["mode_off"],
        wd=cat(lambda ob: ob.wd, (0,)), w=cat(lambda ob: np.asarray(ob.weights, np.float64), (0,)),
        lam=cat(lambda ob: ob.lam, (0,)).astype(np.complex128),
        leps=cat(lambda ob: ob.logeps, (0,)).astype(np.complex128))
    vb_arr = np.full(next_index + 1, -1, np.int64)  # -1: removed (its queued events are dropped)
    for ob in obs:
        vb_arr[ob.index] = ob.vbase
    # voice ids are object-major; v_rel: offset of each voice inside its microphone's bank
    layout = BankLayout(vb_arr, v_off - mic_off[v_mic], v_len, v_mic, int(mic_len.max()) if M else 0)
    return Layout(bank, layout, table, vbase, by_index, mic_ptr, max([len(ob.keep) for ob in obs], default=0))
