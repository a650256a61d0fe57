"""The result of a fit (:class:`FitResult`), its warning class and the Rayleigh damping fit."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..materials import Material, parse_material
from ..modal.model import ModalModel

__all__ = ["FitResult", "FitWarning", "rayleigh_fit"]


class FitWarning(UserWarning):
    """A recording could be fitted, but something about it needs attention."""


# ====================================================================== result
@dataclass
class FitResult:
    """Modal parameters fitted to an impact recording.

    Attributes
    ----------
    frequencies_hz : (n,) undamped natural frequencies ``sqrt(w^2 + d^2) / 2 pi`` [Hz],
        ascending (the :class:`ModalModel` convention; :attr:`damped_frequencies_hz` is what
        is heard and measured; they differ by d^2/(2 w^2), a few ppm).
    decay_per_s : (n,) decay rates d [1/s] (amplitude ~ e^{-d t}; T60 = 6.91 / d).
    amplitudes : (n,) |b_i| in the recording's units at ``onset_s``.
    phases_rad : (n,) arg b_i (0 or pi for an ideal impulse at ``onset_s``).
    sample_rate : int
    onset_s : float, time of the (equivalent ideal) impulse in the recording [s].
    residual_db : float, 10 log10(residual energy / signal energy) over the analysed span.
    snr_db : float, loudest 2.5 ms frame over the noise floor [dB].
    noise_rms : float, noise floor estimate (recording units).
    analysis_start_s, analysis_end_s : float, analysed span of the recording [s].
    channels : str, how channels were combined ("mono", "mix of 2", "channel 1 of 2").
    impulse_like : bool, whether the phases are those of an impulse at ``onset_s``.
    warnings : list of str, problems found (also issued as :class:`FitWarning`).
    modes_supported : int, modes the recording supports (above ``min_snr_db``) before the
        ``n_modes`` limit; the fit never returns more.
    seconds : float, fitting wall time.
    """

    frequencies_hz: np.ndarray
    decay_per_s: np.ndarray
    amplitudes: np.ndarray
    phases_rad: np.ndarray
    sample_rate: int
    onset_s: float = 0.0
    residual_db: float = float("nan")
    snr_db: float = float("nan")
    noise_rms: float = float("nan")
    analysis_start_s: float = 0.0
    analysis_end_s: float = 0.0
    channels: str = "mono"
    impulse_like: bool = True
    warnings: list = field(default_factory=list)
    modes_supported: int = -1
    seconds: float = 0.0
    source: str = "array"

    @property
    def n_modes(self) -> int:
        return len(self.frequencies_hz)

    @property
    def damped_frequencies_hz(self) -> np.ndarray:
        w2 = (2 * np.pi * self.frequencies_hz) ** 2 - self.decay_per_s**2
        return np.sqrt(np.maximum(w2, 0.0)) / (2 * np.pi)

    @property
    def gains(self) -> np.ndarray:
        """Signed amplitudes ``A_i sign(cos phi_i)``: the impulse-response amplitudes (of
        ``sin``) that :meth:`to_model` plays."""
        return self.amplitudes * np.where(np.cos(self.phases_rad) >= 0, 1.0, -1.0)

    @property
    def complex_amplitudes(self) -> np.ndarray:
        return self.amplitudes * np.exp(1j * self.phases_rad)

    def energies(self) -> np.ndarray:
        """Energy of each mode's decay, sum over t >= onset of y_i(t)^2 [units^2 s]
        (A^2 / (4 d) for d << w)."""
        return self.amplitudes**2 / (4.0 * np.maximum(self.decay_per_s, 1e-9))

    def synthesize(self, n_samples: int, sample_rate: int | None = None, onset_s: float | None = None,
                   impulse_like: bool = False) -> np.ndarray:
        """The fitted model as a signal: samples ``n / fs`` for n < ``n_samples``, zero before
        the onset. ``impulse_like=True`` uses the signed :attr:`gains` (what the
        synthesizer plays) instead of the fitted phases."""
        fs = self.sample_rate if sample_rate is None else int(sample_rate)
        t0 = self.onset_s if onset_s is None else float(onset_s)
        tau = np.arange(int(n_samples)) / fs - t0
        y = np.zeros(int(n_samples))
        on = tau >= 0
        b = self.gains.astype(complex) if impulse_like else self.complex_amplitudes
        lam = -self.decay_per_s + 2j * np.pi * self.damped_frequencies_hz
        for bi, li in zip(b, lam):
            y[on] += (bi * np.exp(li * tau[on])).imag
        return y

    def to_model(self, material=None, mass_kg: float | None = None, size_m: float | None = None,
                 impulse_ns: float = 1.0, distance_m: float = 1.0) -> ModalModel:
        """A one-point :class:`ModalModel` (no sound map) that replays the recording.

        The model has one surface point at the origin with normal +z and mode shapes
        ``phi_i = (0, 0, 1)``; ``radiation_i = gain_i w_i distance_m / impulse_ns``. With the
        synthesizer's ``c_i = (phi_i . J) / w_i S_i`` and ``p = radiation_i q_i / r``, an
        impulse of ``impulse_ns`` N s along +z, a short pulse (``S ~ 1``, e.g. ``pulse_s=0``)
        and a microphone ``distance_m`` from the object give back
        ``sum_i gain_i e^{-d_i t} sin(w_i t)``: the recording's amplitudes (same units,
        read as pascals). Other impulses scale it linearly; only the impulse's z component
        (object frame) excites it.

        Parameters
        ----------
        material : Material or spec, optional
            Stored with the model (used for Hertz contact times); default an aluminium-like
            placeholder named "fitted" carrying the Rayleigh alpha, beta fitted to the decays.
        mass_kg, size_m : float, optional
            The object's mass [kg] and size [m] (Hertz contact time in scenes; unknown: NaN /
            0, which gives ideal impulses against immovable bodies).
        impulse_ns, distance_m : float
            Reference impulse [N s] and microphone distance [m] the amplitudes stand for.

        Using it in a scene
        -------------------
        ``SoundScene.from_model(xml, models={"cup": fit.to_model(mass_kg=0.2)})`` uses it for
        geom ``cup`` in place of an analysed model (orient the geom so that its z axis is
        the struck direction); ``Synthesizer.add_object("cup", model)`` plays it directly.
        """
        if not (impulse_ns > 0 and distance_m > 0):
            raise ValueError("impulse_ns and distance_m must be positive")
        wd = 2 * np.pi * self.damped_frequencies_hz
        order = np.argsort(self.frequencies_hz, kind="stable")
        n = self.n_modes
        shapes = np.zeros((1, 3, n))
        shapes[0, 2, :] = 1.0
        if material is None:
            a, b = rayleigh_fit(self.frequencies_hz, self.decay_per_s)
            material = Material(E=70e9, nu=0.33, rho=2700, alpha=a, beta=b, name="fitted")
        else:
            material = parse_material(material)
        info = {
            "fitted": True,
            "source": self.source,
            "sample_rate": int(self.sample_rate),
            "onset_s": float(self.onset_s),
            "residual_db": float(self.residual_db),
            "snr_db": float(self.snr_db),
            "reference_impulse_ns": float(impulse_ns),
            "reference_distance_m": float(distance_m),
            "amplitudes": self.amplitudes[order].tolist(),
            "phases_rad": self.phases_rad[order].tolist(),
            "impulse_like": bool(self.impulse_like),
            "channels": self.channels,
            "size_m": float(size_m) if size_m else 0.0,
            "f_max": float(self.frequencies_hz.max()) if n else 0.0,
            "n_rigid": 0,
            "n_overdamped": 0,
        }
        return ModalModel(
            frequencies_hz=self.frequencies_hz[order],
            decay_per_s=self.decay_per_s[order],
            points=np.zeros((1, 3)),
            normals=np.array([[0.0, 0.0, 1.0]]),
            shapes=shapes,
            radiation=(self.gains * wd * distance_m / impulse_ns)[order],
            material=material,
            method="fitted",
            mass_kg=float("nan") if mass_kg is None else float(mass_kg),
            info=info,
        )

    def summary(self) -> dict:
        """JSON-able dict (the ``mjsound fit --json`` contract)."""
        return {
            "frequencies_hz": self.frequencies_hz.tolist(),
            "damped_frequencies_hz": self.damped_frequencies_hz.tolist(),
            "decay_per_s": self.decay_per_s.tolist(),
            "amplitudes": self.amplitudes.tolist(),
            "phases_rad": self.phases_rad.tolist(),
            "gains": self.gains.tolist(),
            "n_modes": self.n_modes,
            "modes_supported": int(self.modes_supported),
            "residual_db": _num(self.residual_db),
            "snr_db": _num(self.snr_db),
            "noise_rms": _num(self.noise_rms),
            "onset_s": float(self.onset_s),
            "analysis_start_s": float(self.analysis_start_s),
            "analysis_end_s": float(self.analysis_end_s),
            "sample_rate": int(self.sample_rate),
            "channels": self.channels,
            "impulse_like": bool(self.impulse_like),
            "warnings": list(self.warnings),
            "seconds": float(self.seconds),
            "source": self.source,
        }


def _num(x):
    x = float(x)
    return x if math.isfinite(x) else None


def rayleigh_fit(frequencies_hz, decay_per_s, weights=None):
    """Non-negative Rayleigh ``(alpha, beta)`` with ``d = (alpha + beta w^2) / 2`` fitted to
    decays in the relative sense (each mode's relative error counts equally)."""
    from scipy.optimize import nnls

    f = np.asarray(frequencies_hz, float)
    d = np.asarray(decay_per_s, float)
    ok = np.isfinite(f) & np.isfinite(d) & (d > 0) & (f > 0)
    f, d = f[ok], d[ok]
    if len(f) == 0:
        return 0.0, 0.0
    w2 = (2 * np.pi * f) ** 2
    if len(f) == 1:
        return 2.0 * float(d[0]), 0.0
    wt = 1.0 / d if weights is None else np.asarray(weights, float)[ok] / d
    scale = np.array([1.0, 1.0 / w2.max()])  # column scaling for conditioning
    A = np.stack([0.5 * np.ones_like(w2), 0.5 * w2], axis=1) * scale * wt[:, None]
    coef, _ = nnls(A, d * wt)
    coef = coef * scale
    return float(coef[0]), float(coef[1])
