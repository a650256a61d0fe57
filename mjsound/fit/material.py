"""Example-guided materials (:func:`fit_material`) and sound design with force signals
(:func:`render_excitation`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..materials import Material, parse_material
from ..modal.model import ModalModel
from ..modal.radiation import radiation_damping
from .recording import fit_recording
from .result import FitResult, _num, rayleigh_fit

__all__ = ["MaterialFit", "fit_material", "render_excitation"]


# ====================================================================== material fitting
@dataclass
class MaterialFit:
    """Result of :func:`fit_material`.

    Attributes
    ----------
    material : Material
        The base material with ``E`` scaled by ``stiffness_scale`` and the fitted Rayleigh
        ``alpha``, ``beta``; named "fitted". Reusable on other meshes.
    frequency_scale : float
        s: recorded / analysed frequencies (frequencies scale as sqrt(E / rho)).
    stiffness_scale : float
        s^2 (E is scaled, rho kept: only E / rho is observable from frequencies).
    alpha, beta : float
        Rayleigh damping [1/s], [s] with d = (alpha + beta w^2) / 2.
    matches : list of dict
        One per matched mode: fitted_hz, analysed_hz (at the reference material),
        predicted_hz (= s * analysed_hz), cents, fitted_decay, predicted_decay, amplitude.
    unmatched_hz : list of float
        Fitted modes with no analysed mode within ``tolerance_cents``.
    rms_cents : float
        RMS frequency error of the matched modes after scaling.
    decay_rms_rel : float
        RMS relative error of the matched decays against the Rayleigh fit.
    reference_model : ModalModel
        The model analysed at the reference material (frequencies before scaling).
    fit : FitResult
    """

    material: Material
    frequency_scale: float
    stiffness_scale: float
    alpha: float
    beta: float
    matches: list
    unmatched_hz: list
    rms_cents: float
    decay_rms_rel: float
    reference_model: ModalModel
    fit: FitResult

    def summary(self) -> dict:
        return {
            "material": self.material.to_dict(),
            "frequency_scale": self.frequency_scale,
            "stiffness_scale": self.stiffness_scale,
            "alpha": self.alpha,
            "beta": self.beta,
            "n_matched": len(self.matches),
            "matches": self.matches,
            "unmatched_hz": self.unmatched_hz,
            "rms_cents": _num(self.rms_cents),
            "decay_rms_rel": _num(self.decay_rms_rel),
        }


def _match_cost(dlog, g, tau2):
    """Truncated quadratic cost of the fitted modes against the analysed ones shifted by log
    scale g: dlog (n_fit, n_an) = log f_fit - log f_an; g (G,) -> (G,)."""
    r = dlog[None, :, :] - g[:, None, None]
    return np.minimum(np.min(r**2, axis=2), tau2).sum(axis=1)


def _match_scale(ff, fa, energies, lo, hi, tolerance_cents):
    """The log frequency scale ``g`` that maps the analysed frequencies ``fa`` onto the
    fitted ``ff`` [Hz], and the matched pairs ``[(fitted index, analysed index)]``: a grid
    search over ``[log lo, log hi]`` of a truncated-quadratic distance (:func:`_match_cost`),
    polished, then a one-to-one assignment (Hungarian) within ``tolerance_cents`` and a
    least-squares ``g`` over the pairs weighted by each fitted mode's amplitude
    (``sqrt(energies)``), iterated up to four times. No pair: ``pairs`` is empty."""
    from scipy.optimize import linear_sum_assignment

    dlog = np.log(ff)[:, None] - np.log(fa)[None, :]
    tau = tolerance_cents / 1200.0 * math.log(2.0)
    step = tau / 8
    grid = np.arange(math.log(lo), math.log(hi) + step, step)
    cost = np.concatenate([_match_cost(dlog, grid[i: i + 256], tau**2) for i in range(0, len(grid), 256)])
    g = float(grid[int(np.argmin(cost))])
    fine = g + np.linspace(-step, step, 41)
    g = float(fine[int(np.argmin(_match_cost(dlog, fine, tau**2)))])
    pairs = []
    for _ in range(4):
        r = np.abs(dlog - g)
        big = 1e6
        cm = np.where(r <= tau, r, big)
        rows, cols = linear_sum_assignment(cm)
        pairs = [(i, j) for i, j in zip(rows, cols) if cm[i, j] < big]
        if not pairs:
            break
        ii = np.array([p[0] for p in pairs])
        jj = np.array([p[1] for p in pairs])
        w = np.sqrt(energies[ii])  # louder modes are measured better
        g_new = float(np.sum(w * dlog[ii, jj]) / np.sum(w))
        if abs(g_new - g) < 1e-12:
            break
        g = g_new
    return g, pairs


def fit_material(mesh, recording, base_material=None, *, sample_rate: int | None = None,
                 model: ModalModel | None = None, scale_range=(0.5, 2.0), tolerance_cents: float = 35.0,
                 n_modes: int | None = None, method: str = "hex", quality: str = "default",
                 f_max: float | None = None, cache: bool = True, **fit_kwargs) -> MaterialFit:
    """Example-guided material fitting (Ren, Yeh and Lin 2013): stiffness scale and Rayleigh
    damping so that the analysed model of ``mesh`` matches a recording of the object.

    The mesh is analysed **once**, at the reference material (``base_material``, or the
    material of a given ``model``): frequencies scale exactly as sqrt(E / rho), so the scale
    s is found by matching log-frequencies (a grid search over ``scale_range`` of a
    truncated-quadratic distance from every fitted mode to its nearest analysed mode, then a
    one-to-one assignment (Hungarian) within ``tolerance_cents`` and a least-squares s in log
    frequency, iterated). The decays of the matched modes, less each mode's radiation damping
    (what the model radiates away: :func:`mjsound.modal.radiation.radiation_damping`), then
    give alpha, beta by a non-negative least-squares fit of d = (alpha + beta w^2) / 2 in the
    relative sense.

    Parameters
    ----------
    mesh : anything :func:`mjsound.analyze` accepts (ignored when ``model`` is given).
    recording : FitResult, array or path
        A :class:`FitResult`, or a recording (then fitted with :func:`fit_recording`).
    base_material : Material or spec
        Reference material (nu, rho, restitution are kept; E is scaled). Default: the
        ``model``'s material.
    sample_rate : int, for an array recording.
    model : ModalModel, optional
        The mesh already analysed at the reference material (skips the analysis).
    scale_range : (lo, hi)
        Range of the frequency scale s searched (E scale s^2).
    tolerance_cents : float
        Largest mismatch of a matched mode after scaling [cents].
    n_modes : int, optional
        Passed to :func:`fit_recording`.
    method, quality, f_max, cache :
        Analysis settings (``f_max`` default: the highest fitted frequency / ``scale_range[0]``).

    Returns
    -------
    MaterialFit
    """
    fit = recording if isinstance(recording, FitResult) else fit_recording(
        recording, sample_rate, n_modes, **fit_kwargs)
    if fit.n_modes == 0:
        raise ValueError("the recording gave no modes to match; check the recording (see its warnings)")
    lo, hi = (float(v) for v in scale_range)
    if not 0 < lo < hi:
        raise ValueError(f"scale_range={scale_range!r} must be (lo, hi) with 0 < lo < hi")
    if model is None:
        if base_material is None:
            raise ValueError("give base_material (the reference material the mesh is analysed with) or model=")
        ref = parse_material(base_material)
        from ..modal.analyze import analyze

        fm = f_max if f_max is not None else min(20000.0, 1.05 * float(fit.frequencies_hz.max()) / lo)
        model = analyze(mesh, ref, method=method, quality=quality, f_max=fm, cache=cache, error_estimate=False)
    else:
        ref = model.material if base_material is None else parse_material(base_material)
    # frequencies at the reference material (the model may have been analysed at another E / rho)
    fa = np.asarray(model.frequencies_hz, float) * math.sqrt(
        (ref.E / ref.rho) / (model.material.E / model.material.rho))
    if len(fa) == 0:
        raise ValueError("the analysed model has no modes; raise f_max or check the mesh")
    ff = fit.frequencies_hz
    g, pairs = _match_scale(ff, fa, fit.energies(), lo, hi, tolerance_cents)
    if not pairs:
        raise ValueError(
            f"no analysed mode matches the recording within {tolerance_cents} cents for a frequency scale in "
            f"{scale_range}; widen scale_range, raise f_max, or check that the mesh is the recorded object"
        )
    s = math.exp(g)
    ii = np.array([p[0] for p in pairs])
    jj = np.array([p[1] for p in pairs])
    order = np.argsort(ff[ii])
    ii, jj = ii[order], jj[order]
    # a recorded decay is the material's plus what the mode radiates away (the model's own
    # radiation damping, radiation_damping): the material keeps only its part
    d_rad = radiation_damping(np.asarray(model.radiation, float)[jj], 2 * np.pi * np.asarray(model.frequencies_hz)[jj])
    alpha, beta = rayleigh_fit(ff[ii], np.maximum(fit.decay_per_s[ii] - d_rad, 0.05 * fit.decay_per_s[ii]))
    w = 2 * np.pi * ff[ii]
    dpred = (alpha + beta * w**2) / 2 + d_rad
    matches = [
        {
            "fitted_hz": float(ff[i]),
            "analysed_hz": float(fa[j]),
            "predicted_hz": float(s * fa[j]),
            "cents": float(1200 * math.log2(ff[i] / (s * fa[j]))),
            "fitted_decay": float(fit.decay_per_s[i]),
            "predicted_decay": float(dp),
            "amplitude": float(fit.amplitudes[i]),
        }
        for i, j, dp in zip(ii, jj, dpred)
    ]
    cents = np.array([m["cents"] for m in matches])
    rel = fit.decay_per_s[ii] / dpred - 1
    unmatched = sorted(float(ff[i]) for i in set(range(len(ff))) - set(ii.tolist()))
    mat = replace(ref, E=ref.E * s * s, alpha=alpha, beta=beta, name="fitted")
    return MaterialFit(
        material=mat,
        frequency_scale=s,
        stiffness_scale=s * s,
        alpha=alpha,
        beta=beta,
        matches=matches,
        unmatched_hz=unmatched,
        rms_cents=float(np.sqrt(np.mean(cents**2))),
        decay_rms_rel=float(np.sqrt(np.mean(rel**2))),
        reference_model=model,
        fit=fit,
    )


# ====================================================================== sound design
def render_excitation(model: ModalModel, signal, sample_rate: int, point=None, direction=None, *,
                      tail_s: float | None = None, distance_m: float = 1.0, dtype: str = "float64",
                      radiation: bool = True) -> np.ndarray:
    """Audio of ``model`` driven by a user force signal (sound design: a recorded scrape, a
    mallet, a bow), through :meth:`Synthesizer.excite`.

    Parameters
    ----------
    model : ModalModel
        Analysed or fitted (:meth:`FitResult.to_model`).
    signal : (k,) array_like
        Force [N] at ``sample_rate``; sample j acts at time j / fs (an impulse of
        ``signal[j] / fs`` N s). ``signal = [fs, 0, 0, ...]`` is a 1 N s impulse.
    sample_rate : int
    point : (3,) array_like, optional
        Point in the object frame [m]; default: the single point of a fitted model, else the
        surface sample whose normal response is loudest.
    direction : (3,) array_like, optional
        Force direction in the object frame; default the normal at ``point`` (for a fitted
        model, the direction that replays the recording).
    tail_s : float, optional
        Render this long after the signal ends [s]; default until the slowest mode has decayed
        by 60 dB (at most 5 s).
    distance_m : float
        Microphone distance from the object's origin [m] (1/r; the propagation delay is
        removed so output sample j lines up with force sample j).
    dtype : "float64" (default, exact linear system) or "float32" (faster).
    radiation : bool
        Synthesizer radiation model (see :class:`Synthesizer`).

    Returns
    -------
    (len(signal) + tail,) float64 array of pressure [Pa] at the microphone.
    The output is linear in ``signal`` and equals ``np.convolve(signal / fs, h)`` with ``h`` the
    response to a 1 N s impulse.
    """
    from ..synth.synthesizer import Synthesizer

    if not isinstance(model, ModalModel):
        raise ValueError(f"model must be a mjsound.ModalModel, got {type(model).__name__}")
    f = np.asarray(signal, dtype=np.float64).reshape(-1)
    if not np.all(np.isfinite(f)):
        raise ValueError("signal contains NaN or Inf; give a finite force signal in N")
    fs = int(sample_rate)
    if point is None:
        if len(model.points) == 1:
            k = 0
        else:
            nrm = np.einsum("pcn,pc->pn", model.shapes.astype(np.float64), model.normals.astype(np.float64))
            wd = np.maximum(2 * np.pi * model.damped_frequencies_hz, 1e-9)
            k = int(np.argmax(np.sum((nrm * model.radiation[None, :] / wd[None, :]) ** 2, axis=1)))
        point = model.points[k]
        if direction is None:
            direction = model.normals[k]
    elif direction is None:
        direction = model.normals[int(model.nearest_points(np.reshape(point, (1, 3)))[0])]
    d = model.decay_per_s[(model.frequencies_hz < 0.45 * fs) & (model.decay_per_s > 0)]
    if tail_s is None:
        tail_s = min(6.91 / float(d.min()), 5.0) if len(d) else 0.0
    n = len(f) + int(round(float(tail_s) * fs))
    syn = Synthesizer(fs, microphones=[[0.0, 0.0, float(distance_m)]], dtype=dtype, cull_db=None,
                      radiation=radiation, speed_of_sound=1e12)
    syn.add_object("object", model)
    syn.excite("object", np.asarray(point, float), np.asarray(direction, float), f, 0.0)
    return syn.render(n)[0].astype(np.float64)
