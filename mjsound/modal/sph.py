r"""Real spherical harmonics and a sphere quadrature that integrates them exactly.

A far-field radiation pattern ``F(d)`` (a function of the unit direction ``d``) band-limited
to degree ``L`` is stored as its coefficients on the real orthonormal harmonics

.. math:: F(d) = \sum_{l=0}^{L}\sum_{m=-l}^{l} c_{lm} Y_{lm}(d), \qquad
          \int_{S^2} Y_{lm} Y_{l'm'} \, d\Omega = \delta_{ll'}\delta_{mm'},

with ``Y_{l0} = \bar P_l^0(\cos\theta)``, ``Y_{lm} = \sqrt 2 \bar P_l^m(\cos\theta)\cos m\phi`` and
``Y_{l,-m} = \sqrt 2 \bar P_l^m(\cos\theta)\sin m\phi`` (``m > 0``), where ``\bar P_l^m`` are the
associated Legendre functions normalised to ``\int \bar P^2 d\Omega / (2\pi) = 1`` for m = 0
(the usual 4-pi normalisation, computed by the stable three-term recurrences below).
Coefficient ``(l, m)`` sits at index ``l^2 + l + m``. Parseval: the mean square of ``F`` over
the sphere is ``sum |c|^2 / 4 pi``.

:func:`sphere_quadrature` gives Gauss-Legendre nodes in ``cos theta`` times equispaced
``phi``: exact for products of harmonics up to total degree ``2 L + 1``, so projecting samples
of a degree-``L`` pattern gives its coefficients exactly.
"""

from __future__ import annotations

import numpy as np

__all__ = ["n_coefficients", "degree_of", "real_sph_harm", "sphere_quadrature", "fit_coefficients"]


def n_coefficients(degree: int) -> int:
    """Number of real harmonics up to ``degree``: ``(L + 1)^2``."""
    return (int(degree) + 1) ** 2


def degree_of(n_coef: int) -> int:
    """The degree ``L`` of an expansion with ``(L + 1)^2 = n_coef`` coefficients."""
    L = int(round(np.sqrt(n_coef))) - 1
    if (L + 1) ** 2 != n_coef:
        raise ValueError(f"{n_coef} spherical-harmonic coefficients is not (L + 1)^2 for any degree L")
    return L


def real_sph_harm(degree: int, directions) -> np.ndarray:
    """Real orthonormal spherical harmonics up to ``degree`` at unit ``directions``.

    Parameters
    ----------
    degree : int
        Highest degree ``L >= 0``.
    directions : (n, 3) array
        Unit vectors (not re-normalised here).

    Returns
    -------
    (n, (L + 1)^2) float64 array, column ``l^2 + l + m`` holding ``Y_lm``.

    Examples
    --------
    >>> Y = real_sph_harm(1, np.array([[0.0, 0.0, 1.0]]))
    >>> np.allclose(Y[0], [0.5 / np.sqrt(np.pi), 0.0, np.sqrt(3 / (4 * np.pi)), 0.0])
    True
    """
    L = int(degree)
    d = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
    n = len(d)
    ct = np.clip(d[:, 2], -1.0, 1.0)
    st = np.sqrt(np.maximum(0.0, 1.0 - ct * ct))
    phi = np.arctan2(d[:, 1], d[:, 0])
    out = np.empty((n, (L + 1) ** 2))
    pmm = np.full(n, np.sqrt(1.0 / (4.0 * np.pi)))
    for m in range(L + 1):
        if m > 0:  # P_m^m from P_{m-1}^{m-1}
            pmm = -np.sqrt((2.0 * m + 1.0) / (2.0 * m)) * st * pmm
        cm, sm = (np.sqrt(2.0) * np.cos(m * phi), np.sqrt(2.0) * np.sin(m * phi)) if m > 0 else (None, None)
        p_lm2, p_lm1 = None, pmm
        for l in range(m, L + 1):
            if l == m:
                p = pmm
            elif l == m + 1:
                p = np.sqrt(2.0 * m + 3.0) * ct * pmm
            else:
                a = np.sqrt((4.0 * l * l - 1.0) / (l * l - m * m))
                b = np.sqrt(((l - 1.0) ** 2 - m * m) / (4.0 * (l - 1.0) ** 2 - 1.0))
                p = a * (ct * p_lm1 - b * p_lm2)
            if l > m:
                p_lm2, p_lm1 = p_lm1, p
            base = l * l + l
            if m == 0:
                out[:, base] = p
            else:
                out[:, base + m] = p * cm
                out[:, base - m] = p * sm
    return out


def sphere_quadrature(degree: int):
    """Directions and weights integrating harmonics up to total degree ``2 degree + 1`` exactly.

    Returns
    -------
    directions : (n, 3) float64 array of unit vectors, ``n = (L + 1) (2 L + 2)``
    weights : (n,) float64 array summing to ``4 pi``
    """
    L = int(degree)
    x, w = np.polynomial.legendre.leggauss(L + 1)
    n_phi = 2 * L + 2
    phi = (np.arange(n_phi) + 0.5) * (2.0 * np.pi / n_phi)
    st = np.sqrt(1.0 - x * x)
    dirs = np.stack([np.outer(st, np.cos(phi)), np.outer(st, np.sin(phi)), np.outer(x, np.ones(n_phi))], axis=-1)
    weights = np.outer(w, np.full(n_phi, 2.0 * np.pi / n_phi))
    return dirs.reshape(-1, 3), weights.reshape(-1)


def fit_coefficients(degree: int, values) -> np.ndarray:
    """Coefficients of patterns sampled on :func:`sphere_quadrature`'s directions.

    Parameters
    ----------
    degree : int
        ``L`` of the quadrature the samples were taken on.
    values : (n_dirs, k) array (real or complex)

    Returns
    -------
    (k, (L + 1)^2) array: ``c_lm = sum_q w_q F(d_q) Y_lm(d_q)``.
    """
    dirs, w = sphere_quadrature(degree)
    Y = real_sph_harm(degree, dirs)
    return ((Y * w[:, None]).T @ np.asarray(values)).T
