"""`ModalModel`: what the synthesizer needs to play one object, and nothing of how it was made.

A model with ``n`` modes sampled at ``p`` surface points holds

* ``frequencies_hz`` (n,)        undamped natural frequencies f_i = omega_i / 2 pi, ascending
* ``decay_per_s`` (n,)           Rayleigh decay d_i = (alpha + beta omega_i^2) / 2
* ``damped_frequencies_hz`` (n,) sqrt(omega_i^2 - d_i^2) / 2 pi
* ``points`` (p, 3)              surface sample points in the object frame [m]
* ``normals`` (p, 3)             outward unit normals there
* ``shapes`` (p, 3, n)           mass-normalised mode shapes phi_i(x) at the points [1/sqrt(kg)]
                                 (phi^T M phi = 1): the *sound map*
* ``radiation`` (n,)             far-field pressure at 1 m per unit modal coordinate
                                 [Pa m / (m sqrt(kg))]: the RMS over directions of the pattern
* ``radiation_sh`` (n, (L+1)^2)  the far-field pattern of each mode as complex coefficients on
                                 real orthonormal spherical harmonics (:mod:`.sph`) about
* ``radiation_centre`` (3,)      [m] in the object frame; read it with :meth:`ModalModel.radiation_pattern`
                                 (None: no pattern, every direction gets ``radiation``)
* ``material``, ``method``, ``dofs``, ``seconds``, ``error_estimate_cents``, ``mass_kg``,
  ``info`` (discretization details).

An impulse J [N s] at point x excites mode i with modal velocity ``phi_i(x) . J``; the modal
coordinate then rings as ``q_i(t) = (phi_i(x).J / omega_d) e^{-d t} sin(omega_d t)``
[m sqrt(kg)], the surface moves by ``phi_i q_i`` and radiates ``radiation_i * q_i / r`` Pa.

Models are saved as ``.npz`` without pickle: arrays plus one JSON string of metadata.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field, replace

import numpy as np

from ..io import commit_temp, temp_beside
from ..materials import Material
from .sph import degree_of, real_sph_harm

__all__ = ["ModalModel", "FORMAT_VERSION"]

FORMAT_VERSION = 1


#: Up to this many (query, sample) pairs the nearest sample is found by comparing them all.
BRUTE_FORCE_PAIRS = 1 << 20


@dataclass
class ModalModel:
    """Modal parameters of one sounding object (see the module docstring for units)."""

    frequencies_hz: np.ndarray
    decay_per_s: np.ndarray
    points: np.ndarray
    normals: np.ndarray
    shapes: np.ndarray
    radiation: np.ndarray
    material: Material
    method: str = "unknown"
    dofs: int = 0
    seconds: float = 0.0
    error_estimate_cents: float = float("nan")
    mass_kg: float = float("nan")
    info: dict = field(default_factory=dict)
    radiation_sh: np.ndarray | None = None
    radiation_centre: np.ndarray | None = None

    def __post_init__(self):
        self.frequencies_hz = np.asarray(self.frequencies_hz, dtype=np.float64).reshape(-1)
        self.decay_per_s = np.asarray(self.decay_per_s, dtype=np.float64).reshape(-1)
        self.points = np.asarray(self.points, dtype=np.float32).reshape(-1, 3)
        self.normals = np.asarray(self.normals, dtype=np.float32).reshape(-1, 3)
        n = len(self.frequencies_hz)
        self.shapes = np.asarray(self.shapes, dtype=np.float32).reshape(len(self.points), 3, n)
        self.radiation = np.asarray(self.radiation, dtype=np.float64).reshape(-1)
        if len(self.decay_per_s) != n or len(self.radiation) != n:
            raise ValueError("ModalModel: frequencies, decay and radiation must have the same length")
        if self.radiation_sh is not None:
            self.radiation_sh = np.asarray(self.radiation_sh, dtype=np.complex64)
            if self.radiation_sh.ndim != 2 or len(self.radiation_sh) != n:
                raise ValueError("ModalModel: radiation_sh must be (n_modes, (L+1)^2)")
            degree_of(self.radiation_sh.shape[1])
            c = np.zeros(3) if self.radiation_centre is None else self.radiation_centre
            self.radiation_centre = np.asarray(c, dtype=np.float64).reshape(3)
        if len(self.normals) != len(self.points):
            raise ValueError("ModalModel: points and normals must have the same length")
        if n and (not np.all(np.isfinite(self.frequencies_hz)) or np.any(self.frequencies_hz <= 0)):
            raise ValueError("ModalModel: frequencies must be finite and positive")
        if not (np.all(np.isfinite(self.decay_per_s)) and np.all(np.isfinite(self.shapes))):
            raise ValueError("ModalModel: decay rates and shapes must be finite")
        self._tree = None

    # ------------------------------------------------------------------ derived
    @property
    def n_modes(self) -> int:
        return len(self.frequencies_hz)

    @property
    def omega(self) -> np.ndarray:
        """Undamped angular frequencies [rad/s]."""
        return 2.0 * np.pi * self.frequencies_hz

    @property
    def damped_frequencies_hz(self) -> np.ndarray:
        """sqrt(omega^2 - d^2) / 2 pi [Hz]; 0 for overdamped modes."""
        w2 = self.omega**2 - self.decay_per_s**2
        return np.sqrt(np.maximum(w2, 0.0)) / (2.0 * np.pi)

    @property
    def size_m(self) -> float:
        """Longest side of the sampled surface's bounding box [m]."""
        if len(self.points) < 2:
            return float(self.info.get("size_m", 0.0))
        return float(np.ptp(self.points, axis=0).max())

    # ------------------------------------------------------------------ radiation
    def radiation_pattern(self, directions) -> np.ndarray:
        r"""Far-field pressure of each mode per unit modal coordinate in given directions.

        The pressure a mode vibrating as ``q(t) = Re(Q e^{-i omega t})`` makes at distance
        ``r`` (far field) in direction ``d`` is ``Re(F(d) Q e^{i(k r - omega t)}) / r``;
        this returns ``F(d)`` [Pa m per m sqrt(kg)], complex: its magnitude is the amplitude at
        1 m, its phase is referred to :attr:`radiation_centre` (a listener at ``x`` hears
        the mode delayed by ``|x - centre| / c`` plus ``arg F / omega``). The RMS of
        ``|F|`` over all directions is :attr:`radiation`.

        Parameters
        ----------
        directions : (k, 3) array
            Directions in the model's frame (normalised here; zero vectors are refused).

        Returns
        -------
        (k, n_modes) complex128 array. A model without a stored pattern (``radiation_sh``
        None: fitted or stub models) radiates ``radiation`` in every direction.

        Examples
        --------
        >>> F = model.radiation_pattern([[0, 0, 1], [1, 0, 0]])  # doctest: +SKIP
        >>> np.abs(F)  # Pa at 1 m per unit modal coordinate, up and sideways  # doctest: +SKIP
        """
        d = np.asarray(directions, dtype=np.float64)
        if d.ndim == 1:
            d = d.reshape(1, -1)
        if d.ndim != 2 or d.shape[1] != 3:
            raise ValueError(f"radiation_pattern: directions must be (k, 3) vectors, got shape {np.shape(directions)}")
        norm = np.linalg.norm(d, axis=1)
        if not np.all(np.isfinite(norm)) or np.any(norm <= 0):
            raise ValueError("radiation_pattern: directions must be finite, non-zero vectors")
        d = d / norm[:, None]
        if self.radiation_sh is None:
            return np.broadcast_to(self.radiation.astype(np.complex128), (len(d), self.n_modes)).copy()
        Y = real_sph_harm(degree_of(self.radiation_sh.shape[1]), d)
        return Y @ self.radiation_sh.astype(np.complex128).T

    # ------------------------------------------------------------------ sound map
    def nearest_points(self, points: np.ndarray) -> np.ndarray:
        """Indices of the surface samples nearest to ``points`` (k, 3) in the object frame.

        A few query points (a contact, a microphone) are compared with every sample directly:
        building a k-d tree would first import scipy.spatial (0.1-0.2 s at start-up)."""
        q = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        if len(q) * len(self.points) <= BRUTE_FORCE_PAIRS:
            d2 = ((q[:, None, :] - self.points[None, :, :]) ** 2).sum(axis=2)
            return np.argmin(d2, axis=1).astype(np.int64)
        from scipy.spatial import cKDTree

        if self._tree is None:
            self._tree = cKDTree(self.points)
        _, idx = self._tree.query(q)
        return np.asarray(idx, dtype=np.int64)

    def gains(self, points: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """Modal participation ``phi_i(x) . d`` for points and direction vectors.

        Parameters
        ----------
        points : (k, 3) array
            Points in the object frame [m] (snapped to the nearest surface sample).
        directions : (k, 3) array
            Vectors in the object frame (an impulse in N s gives modal velocity in
            m sqrt(kg)/s).

        Returns
        -------
        (k, n) float64 array.
        """
        idx = self.nearest_points(points)
        d = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
        return np.einsum("kcn,kc->kn", self.shapes[idx].astype(np.float64), d)

    # ------------------------------------------------------------------ editing
    def select(self, keep) -> "ModalModel":
        """A copy with only the modes ``keep`` (boolean mask or indices)."""
        keep = np.asarray(keep)
        return replace(
            self,
            frequencies_hz=self.frequencies_hz[keep],
            decay_per_s=self.decay_per_s[keep],
            shapes=self.shapes[:, :, keep],
            radiation=self.radiation[keep],
            radiation_sh=None if self.radiation_sh is None else self.radiation_sh[keep],
            info=_select_info(self.info, keep, self.n_modes),
        )

    def truncated(self, f_max: float | None = None, n_modes: int | None = None) -> "ModalModel":
        """Modes below ``f_max`` [Hz] and/or the ``n_modes`` lowest."""
        keep = np.ones(self.n_modes, bool)
        if f_max is not None:
            keep &= self.frequencies_hz <= f_max
        idx = np.flatnonzero(keep)
        if n_modes is not None:
            idx = idx[: max(int(n_modes), 0)]
        return self.select(idx)

    # ------------------------------------------------------------------ I/O
    def metadata(self) -> dict:
        return {
            "format_version": FORMAT_VERSION,
            "material": self.material.to_dict(),
            "method": self.method,
            "dofs": int(self.dofs),
            "seconds": float(self.seconds),
            "error_estimate_cents": float(self.error_estimate_cents),
            "mass_kg": float(self.mass_kg),
            "info": self.info,
        }

    def summary(self) -> dict:
        """JSON-able summary (the ``mjsound analyze --json`` contract)."""
        return {
            "frequencies_hz": self.frequencies_hz.tolist(),
            "damped_frequencies_hz": self.damped_frequencies_hz.tolist(),
            "decay_per_s": self.decay_per_s.tolist(),
            "n_modes": self.n_modes,
            "method": self.method,
            "dofs": int(self.dofs),
            "seconds": float(self.seconds),
            "error_estimate_cents": None
            if not np.isfinite(self.error_estimate_cents)
            else float(self.error_estimate_cents),
            "mass_kg": float(self.mass_kg),
            "material": self.material.to_dict(),
            "n_points": int(len(self.points)),
            "info": self.info,
        }

    def save(self, path) -> None:
        """Write to ``path`` (.npz) atomically (temp file + rename)."""
        fd, tmp = temp_beside(path, ".npz")
        try:
            with os.fdopen(fd, "wb") as fh:
                np.savez_compressed(
                    fh,
                    frequencies_hz=self.frequencies_hz,
                    decay_per_s=self.decay_per_s,
                    points=self.points,
                    normals=self.normals,
                    shapes=self.shapes,
                    radiation=self.radiation,
                    **({} if self.radiation_sh is None else
                       dict(radiation_sh=self.radiation_sh, radiation_centre=self.radiation_centre)),
                    meta=np.array(json.dumps(self.metadata(), default=_json_default)),
                )
            commit_temp(tmp, path)
        except BaseException:
            if os.path.exists(tmp):
                os.unlink(tmp)
            raise

    @classmethod
    def load(cls, path) -> "ModalModel":
        """Read a model written by :meth:`save` (``allow_pickle=False``).

        Raises ``ValueError`` for a file that is not a valid model (truncated, wrong version).
        """
        try:
            with np.load(os.fspath(path), allow_pickle=False) as z:
                meta = json.loads(str(z["meta"]))
                if meta.get("format_version") != FORMAT_VERSION:
                    raise ValueError(f"format version {meta.get('format_version')} != {FORMAT_VERSION}")
                arrays = {k: z[k] for k in ("frequencies_hz", "decay_per_s", "points", "normals", "shapes", "radiation")}
                for k in ("radiation_sh", "radiation_centre"):  # absent: a model without a pattern
                    if k in z.files:
                        arrays[k] = z[k]
        except ValueError as exc:
            raise ValueError(f"{path}: not a valid mjsound model ({exc})") from exc
        except Exception as exc:  # zipfile.BadZipFile, KeyError, OSError, EOFError ...
            raise ValueError(f"{path}: not a valid mjsound model ({type(exc).__name__}: {exc})") from exc
        try:
            return cls(
                **arrays,
                material=Material(**meta["material"]),
                method=meta["method"],
                dofs=meta["dofs"],
                seconds=meta["seconds"],
                error_estimate_cents=meta["error_estimate_cents"],
                mass_kg=meta["mass_kg"],
                info=meta["info"],
            )
        except (KeyError, TypeError, ValueError) as exc:  # a metadata field missing or malformed
            raise ValueError(f"{path}: not a valid mjsound model (metadata {type(exc).__name__}: {exc})") from exc


#: per-mode lists in ``info['radiation']`` that :meth:`ModalModel.select` keeps aligned
PER_MODE_RADIATION_INFO = ("error_db", "capped_db", "shift_db")


def _select_info(info: dict, keep, n_modes: int) -> dict:
    """A copy of ``info`` whose per-mode radiation lists hold the modes ``keep`` only."""
    out = dict(info)
    rad = out.get("radiation")
    if isinstance(rad, dict):
        idx = np.arange(n_modes)[np.asarray(keep)]
        rad = dict(rad)
        for key in PER_MODE_RADIATION_INFO:
            if isinstance(rad.get(key), list) and len(rad[key]) == n_modes:
                rad[key] = [rad[key][i] for i in idx]
        out["radiation"] = rad
    return out


def _json_default(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"not JSON serialisable: {type(o)}")
