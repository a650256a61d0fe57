r"""Exterior acoustic boundary elements: Burton-Miller collocation on flat triangles.

The pressure ``p`` outside a closed surface ``Gamma`` (outward normal ``n``, into the air) with
prescribed normal derivative ``q = dp/dn`` solves ``Delta p + k^2 p = 0`` and radiates
(time factor ``e^{-i omega t}``, Green's function ``G = e^{ikR} / 4 pi R``). On ``Gamma``
Green's representation and its normal derivative give

.. math:: (\tfrac12 I - K) p = -S q, \qquad W p = (\tfrac12 I + K') q,

with ``S q = int G q``, ``K p = int dG/dn_y p``, ``K' q = int dG/dn_x q`` and the hypersingular
``W p = d/dn_x int dG/dn_y p``. Either equation alone fails at the interior resonances of the
body; their combination with ``alpha = i / k`` (Burton and Miller 1971) does not:

.. math:: (\tfrac12 I - K + \alpha W)\, p = \big(-S + \alpha(\tfrac12 I + K')\big)\, q .

Discretisation: ``p`` and ``q`` constant on each triangle, the equation collocated at the
centroids. Every integral splits into its Laplace (``k = 0``) part, integrated exactly, and a
bounded remainder integrated by a 6-point rule. The exact Laplace parts of a flat triangle
``T`` (normal ``n_T``, edges ``e`` with in-plane outward normals ``m_e``) seen from ``x``, with
``h = (x - y) . n_T``, the signed in-plane distances ``t_e`` of ``x`` to the edges, the edge
integrals ``L_e = int_e dl / R`` (logarithms) and the solid angle ``Omega = int_T h / R^3``
(van Oosterom and Strackee 1983):

.. math:: \int_T \frac{dA}{R} = \sum_e t_e L_e - h\,\Omega, \qquad
          \int_T \frac{x - y}{R^3} dA = \sum_e m_e L_e + \Omega\, n_T,

and ``grad Omega`` is the Biot-Savart field of the triangle's edge loop (each straight edge in
closed form), which is also the finite part of the hypersingular self term. The Helmholtz
remainder of the hypersingular kernel is not bounded: with ``G_r = G - G_0``,
``A(R) = G_r'(R) / R = -k^2 / 8 pi R + O(1)``,

.. math:: \frac{\partial^2 G_r}{\partial n_x \partial n_y}
          = -(n_x\cdot n_y) A - c_x c_y \frac{A'}{R}, \qquad c_x = (x-y)\cdot n_x,\; c_y = h,

whose ``1/R`` parts ``(n_x . n_y) k^2 / 8 pi R - k^2 c_x h / 8 pi R^3`` are integrated with the
two exact integrals above; what is left is bounded. Nearly touching elements (the two faces
of a 2 mm plate under 2 cm elements) are therefore integrated as accurately as distant ones.

Cost: the Laplace parts of the near pairs (a triangle within ``FAR`` of its edges from the
collocation point) do not depend on ``k`` and are computed once per mesh
(:meth:`BemMesh.near_parts`), however many wavenumbers it is solved at; the rest is written
to vectorise (:func:`far_row`, :func:`near_rows`: structure-of-arrays input, quadrature points
unrolled, real arithmetic without branches): 0.35 -> 0.07 s of CPU for a 1356-element
assembly (2 mm plate; ``python scripts/bench_radiation.py``, docs/radiation.md "Cost").

Far field (``p ~ F(d) e^{ikr} / r``), referred to a centre ``c``:

.. math:: F(d) = \frac{1}{4\pi} \int_\Gamma \big(-ik (d\cdot n) p - q\big) e^{-ik d\cdot(y - c)} dA .
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

__all__ = ["QUAD_BARY", "QUAD_WEIGHTS", "BemMesh", "near_laplace_parts", "assemble", "assemble_mesh", "solve_far_field",
           "far_field_matrix", "far_field_parts", "far_fields_per_mode", "far_row", "near_rows", "gather_near"]

FOUR_PI = 4.0 * np.pi

#: Dunavant's 6-point rule (degree 4) on the reference triangle: barycentric points and
#: weights summing to 1 (no point at the centroid, where the collocation point lies).
_A1, _B1 = 0.445948490915965, 0.091576213509771
QUAD_BARY = np.array([[_A1, _A1, 1 - 2 * _A1], [_A1, 1 - 2 * _A1, _A1], [1 - 2 * _A1, _A1, _A1],
                      [_B1, _B1, 1 - 2 * _B1], [_B1, 1 - 2 * _B1, _B1], [1 - 2 * _B1, _B1, _B1]])
QUAD_WEIGHTS = np.array([0.223381589678011] * 3 + [0.109951743655322] * 3)
#: Strang and Fix's 3-point rule (degree 2), for well separated pairs.
QUAD3_BARY = np.array([[2 / 3, 1 / 6, 1 / 6], [1 / 6, 2 / 3, 1 / 6], [1 / 6, 1 / 6, 2 / 3]])
#: a triangle seen from farther than this many times its longest edge is integrated whole
#: (Laplace part included) by the 3-point rule
FAR = 4.0


class BemMesh:
    """A flat-triangle mesh prepared for :func:`assemble`.

    Parameters
    ----------
    vertices : (v, 3) array [m]
    faces : (N, 3) int array, counter-clockwise seen from outside (normals into the air).

    Attributes
    ----------
    tri : (N, 3, 3) corners; centroids, normals : (N, 3); areas : (N,) [m^2];
    quad : (N, 6, 3) quadrature points; quad_w : (N, 6) their weights [m^2].
    """

    def __init__(self, vertices, faces):
        v = np.asarray(vertices, dtype=np.float64)
        f = np.asarray(faces, dtype=np.int64)
        self.vertices, self.faces = v, f
        self.tri = np.ascontiguousarray(v[f])
        cross = np.cross(self.tri[:, 1] - self.tri[:, 0], self.tri[:, 2] - self.tri[:, 0])
        dbl = np.linalg.norm(cross, axis=1)
        if len(f) == 0 or not np.all(dbl > 0):
            raise ValueError("BemMesh: the surface has degenerate (zero-area) triangles or none")
        self.areas = 0.5 * dbl
        self.normals = cross / dbl[:, None]
        self.centroids = self.tri.mean(axis=1)
        self.quad = np.ascontiguousarray(np.einsum("qa,nac->nqc", QUAD_BARY, self.tri))
        self.quad_w = np.ascontiguousarray(self.areas[:, None] * QUAD_WEIGHTS[None, :])
        self.quad3 = np.ascontiguousarray(np.einsum("qa,nac->nqc", QUAD3_BARY, self.tri))
        self.edge = np.linalg.norm(self.tri[:, [1, 2, 0]] - self.tri, axis=2).max(axis=1)
        self.size = float(np.sqrt(self.areas.max() * 4 / np.sqrt(3)))  # edge of the largest, if equilateral
        self._near = None
        # far_row's input: the 3-point rule's points by coordinate, the normals, area / 3
        self.far_geo = np.ascontiguousarray(np.vstack([self.quad3.reshape(-1, 9).T, self.normals.T, self.areas / 3.0]))
        # far_field_parts' input: the 6-point rule's points about the centroid by coordinate,
        # their weights, the centroids, the normals
        self.far_field_geo = np.ascontiguousarray(np.vstack([
            (self.quad - self.centroids[:, None, :]).reshape(-1, 18).T, self.quad_w.T, self.centroids.T,
            self.normals.T]))
        # near_rows' input: the 6-point rule's points by coordinate, their weights, the normals
        self.near_geo = np.ascontiguousarray(np.hstack([self.quad.reshape(-1, 18), self.quad_w, self.normals]))

    def __len__(self):
        return len(self.faces)

    def near_parts(self):
        """:func:`near_laplace_parts` of this mesh, computed once and kept (about 45 bytes a
        near pair: 0.4 M pairs, 18 MB, at 1356 elements on a 2 mm plate)."""
        if getattr(self, "_near", None) is None:
            self._near = near_laplace_parts(self.tri, self.centroids, self.normals, self.edge)
        return self._near


@njit(cache=True, fastmath=False)
def _laplace_parts(x, nx, v0, v1, v2, nT, self_term):
    """Exact k = 0 integrals over triangle (v0, v1, v2) seen from x (module docstring).

    Returns (int 1/R, Omega, V = int (x-y)/R^3, B = -grad Omega (the edge loop's Biot-Savart sum), h)."""
    h = (x[0] - v0[0]) * nT[0] + (x[1] - v0[1]) * nT[1] + (x[2] - v0[2]) * nT[2]
    if self_term:
        h = 0.0
    verts = (v0, v1, v2)
    R = np.empty((3, 3))
    r = np.empty(3)
    for a in range(3):
        for c in range(3):
            R[a, c] = verts[a][c] - x[c]
        r[a] = np.sqrt(R[a, 0] ** 2 + R[a, 1] ** 2 + R[a, 2] ** 2)
    if self_term:
        omega = 0.0
    else:
        trip = (R[0, 0] * (R[1, 1] * R[2, 2] - R[1, 2] * R[2, 1]) - R[0, 1] * (R[1, 0] * R[2, 2] - R[1, 2] * R[2, 0])
                + R[0, 2] * (R[1, 0] * R[2, 1] - R[1, 1] * R[2, 0]))
        d01 = R[0, 0] * R[1, 0] + R[0, 1] * R[1, 1] + R[0, 2] * R[1, 2]
        d02 = R[0, 0] * R[2, 0] + R[0, 1] * R[2, 1] + R[0, 2] * R[2, 2]
        d12 = R[1, 0] * R[2, 0] + R[1, 1] * R[2, 1] + R[1, 2] * R[2, 2]
        den = r[0] * r[1] * r[2] + d01 * r[2] + d02 * r[1] + d12 * r[0]
        omega = -2.0 * np.arctan2(trip, den)
    i1 = 0.0
    V = np.zeros(3)
    B = np.zeros(3)
    for e in range(3):
        a, b = e, (e + 1) % 3
        ex, ey, ez = R[b, 0] - R[a, 0], R[b, 1] - R[a, 1], R[b, 2] - R[a, 2]
        le = np.sqrt(ex * ex + ey * ey + ez * ez)
        tx, ty, tz = ex / le, ey / le, ez / le
        # in-plane outward normal of the edge: t x n_T
        mx, my, mz = ty * nT[2] - tz * nT[1], tz * nT[0] - tx * nT[2], tx * nT[1] - ty * nT[0]
        sa = R[a, 0] * tx + R[a, 1] * ty + R[a, 2] * tz
        sb = R[b, 0] * tx + R[b, 1] * ty + R[b, 2] * tz
        if sa > 0.0:
            L = np.log((r[b] + sb) / (r[a] + sa))
        elif sb < 0.0:
            L = np.log((r[a] - sa) / (r[b] - sb))
        else:
            rho2 = r[a] * r[a] - sa * sa
            L = np.log((r[b] + sb) * (r[a] - sa) / max(rho2, 1e-300))
        te = R[a, 0] * mx + R[a, 1] * my + R[a, 2] * mz
        i1 += te * L
        V[0] += mx * L
        V[1] += my * L
        V[2] += mz * L
        # Biot-Savart of the edge a -> b at x: (t x (x - v_a)) / rho^2 * (s_b / r_b - s_a / r_a)
        wx, wy, wz = -R[a, 0], -R[a, 1], -R[a, 2]  # x - v_a
        cx, cy, cz = ty * wz - tz * wy, tz * wx - tx * wz, tx * wy - ty * wx
        rho2 = cx * cx + cy * cy + cz * cz
        if rho2 > 1e-24 * le * le:
            f = (sb / r[b] - sa / r[a]) / rho2
            B[0] += cx * f
            B[1] += cy * f
            B[2] += cz * f
    i1 -= h * omega
    V[0] += omega * nT[0]
    V[1] += omega * nT[1]
    V[2] += omega * nT[2]
    return i1, omega, V, B, h


@njit(cache=True, inline="always")
def _cis(theta):
    r"""``(cos theta, sin theta)`` in branch-free arithmetic that the compiler vectorises:
    ``theta`` reduced to ``r`` in ``[-pi, pi]``, the Taylor polynomials of ``cos`` and ``sin``
    at ``r / 4`` (``|r / 4| <= pi / 4``: remainder ``(pi/4)^14 / 14! < 1e-12``), then the
    double-angle formulas twice. Within ``1e-11`` of ``np.cos``, ``np.sin``."""
    r = theta - 6.283185307179586 * np.floor(theta * 0.15915494309189535 + 0.5)
    z = 0.25 * r
    z2 = z * z
    c = 1.0 + z2 * (-1.0 / 2 + z2 * (1.0 / 24 + z2 * (-1.0 / 720 + z2 * (1.0 / 40320 + z2 * (
        -1.0 / 3628800 + z2 * (1.0 / 479001600))))))
    s = z * (1.0 + z2 * (-1.0 / 6 + z2 * (1.0 / 120 + z2 * (-1.0 / 5040 + z2 * (1.0 / 362880 + z2 * (
        -1.0 / 39916800 + z2 * (1.0 / 6227020800)))))))
    c, s = c * c - s * s, 2.0 * c * s
    return c * c - s * s, 2.0 * c * s


@njit(cache=True, error_model="numpy", fastmath={"contract"}, inline="always")
def _near_point(x, n, y, t, nn, k):
    """One point ``y`` of a near triangle (normal ``t``, ``nn = n . t``) seen from ``x`` (normal
    ``n``; all three-tuples): 4 pi times the bounded Helmholtz remainders (module docstring)
    as they enter ``S``, ``K``, ``K'`` and ``W``, each (real, imaginary):
    ``G_r``, ``-A c_y``, ``A c_x``, ``-(n_x . n_y) a_b - c_x c_y a2_b``, with
    ``a_b = A + k^2 / 8 pi R`` and ``a2_b = A'/R - k^2 / 8 pi R^3``.

    In real arithmetic (``kR``, ``e^{ikR} = c + i s``), and without a series for small ``kR``:
    the closed forms lose their relative accuracy there (``1 - c - kR s + (kR)^2 / 2`` is
    ``(kR)^4 / 8``), but their absolute error stays at rounding of the Laplace kernel's own
    size (``eps / R^3``), which is what the sums need."""
    dx, dy, dz = x[0] - y[0], x[1] - y[1], x[2] - y[2]
    R = np.sqrt(dx * dx + dy * dy + dz * dz)
    kr = k * R
    c, s = _cis(kr)
    iR = 1.0 / R
    iR3 = iR * iR * iR
    gr, gi = (c - 1.0) * iR, s * iR
    Ar, Ai = (1.0 - c - kr * s) * iR3, (kr * c - s) * iR3
    half = 0.5 * k * k * iR
    abr, abi = Ar + half, Ai
    a2r = ((-k * k * c * iR - 3.0 * Ar) * iR - half * iR) * iR
    a2i = (-k * k * s * iR - 3.0 * Ai) * iR * iR
    cy = dx * t[0] + dy * t[1] + dz * t[2]
    cx = dx * n[0] + dy * n[1] + dz * n[2]
    cc = cx * cy
    return (gr, gi, -Ar * cy, -Ai * cy, Ar * cx, Ai * cx, -nn * abr - cc * a2r, -nn * abi - cc * a2i)


@njit(cache=True, inline="always")
def _accumulate(acc, w, r):
    """``acc + w r`` for tuples of 8."""
    return (acc[0] + w * r[0], acc[1] + w * r[1], acc[2] + w * r[2], acc[3] + w * r[3], acc[4] + w * r[4],
            acc[5] + w * r[5], acc[6] + w * r[6], acc[7] + w * r[7])


@njit(cache=True, error_model="numpy", fastmath={"contract"})
def _near_three(x, nx, pairs, k, a, first, sums):
    """``sums`` (4, n) written: points ``first .. first + 2`` of the 6-point rule, weighted and
    summed, as they enter ``4 pi (-K + alpha W)`` and ``4 pi (-S + alpha K')`` (real, imaginary),
    for every pair. Three points at a time into four rows: the compiler vectorises neither a
    loop over all six unrolled nor one that stores eight rows (or reads what it writes)."""
    xs = (x[0], x[1], x[2])
    ns = (nx[0], nx[1], nx[2])
    b0, b1, b2 = 3 * first, 3 * first + 3, 3 * first + 6
    w0, w1, w2 = 18 + first, 19 + first, 20 + first
    for p in range(pairs.shape[1]):
        t = (pairs[24, p], pairs[25, p], pairs[26, p])
        nn = ns[0] * t[0] + ns[1] * t[1] + ns[2] * t[2]
        r = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        y0 = (pairs[b0, p], pairs[b0 + 1, p], pairs[b0 + 2, p])
        y1 = (pairs[b1, p], pairs[b1 + 1, p], pairs[b1 + 2, p])
        y2 = (pairs[b2, p], pairs[b2 + 1, p], pairs[b2 + 2, p])
        r = _accumulate(r, pairs[w0, p], _near_point(xs, ns, y0, t, nn, k))
        r = _accumulate(r, pairs[w1, p], _near_point(xs, ns, y1, t, nn, k))
        r = _accumulate(r, pairs[w2, p], _near_point(xs, ns, y2, t, nn, k))
        sums[0, p], sums[1, p] = -r[2] - a * r[7], -r[3] + a * r[6]  # alpha W = i a W
        sums[2, p], sums[3, p] = -r[0] - a * r[5], -r[1] + a * r[4]


@njit(cache=True, error_model="numpy", fastmath={"contract"})
def near_rows(x, nx, pairs, k, a, out):
    """One row's near pairs: their Laplace integrals plus the 6-point rule on the remainders,
    written to vectorise over the pairs like :func:`far_row` (the pairs' data gathered first
    into contiguous rows, :func:`gather_near`).

    Parameters
    ----------
    x, nx : (3,) collocation point and its normal
    pairs : (32, n) per pair: the 6-point rule's points by coordinate, their weights [m^2],
        the triangle's normal (:attr:`BemMesh.near_geo`) and the Laplace integrals of
        :func:`near_laplace_parts`
    k : float, wavenumber [1/m]; a : float, ``alpha = i a``
    out : (4, n) written: ``-K + alpha W`` and ``-S + alpha K'`` as (real, imaginary) rows
    """
    n0, n1, n2 = nx[0], nx[1], nx[2]
    k2 = k * k / 2.0  # (k^2 / 8 pi) in units of 1 / 4 pi
    n = pairs.shape[1]
    s1 = np.empty((4, n))  # the remainders' points 0-2
    s2 = np.empty((4, n))  # and 3-5
    _near_three(x, nx, pairs, k, a, 0, s1)
    _near_three(x, nx, pairs, k, a, 3, s2)
    for p in range(n):  # plus the Laplace parts: 4 pi (S, K, K', W) = (i1, Omega, -n.V, -n.B + ...), real
        nn = n0 * pairs[24, p] + n1 * pairs[25, p] + n2 * pairs[26, p]
        i1, om, nV, nB, h = pairs[27, p], pairs[28, p], pairs[29, p], pairs[30, p], pairs[31, p]
        W = -nB + k2 * nn * i1 - k2 * h * nV
        out[0, p] = (-om + s1[0, p] + s2[0, p]) / FOUR_PI
        out[1, p] = (a * W + s1[1, p] + s2[1, p]) / FOUR_PI
        out[2, p] = (-i1 + s1[2, p] + s2[2, p]) / FOUR_PI
        out[3, p] = (-a * nV + s1[3, p] + s2[3, p]) / FOUR_PI


@njit(cache=True)
def gather_near(cols, parts, geo6, pairs):
    """:func:`near_rows`' input for near pairs ``cols`` (and their ``parts``): the triangles'
    rows of ``geo6`` ((N, 27), :attr:`BemMesh.near_geo`) and the parts, one column a pair."""
    for m in range(len(cols)):
        j = cols[m]
        for c in range(27):
            pairs[c, m] = geo6[j, c]
        for c in range(5):
            pairs[27 + c, m] = parts[m, c]


@njit(cache=True, error_model="numpy", fastmath={"contract"}, inline="always")
def _far_point(x, n, y, t, k):
    """One point ``y`` of :func:`far_row`'s rule on a triangle of normal ``t``, seen from ``x``
    (normal ``n``; all three-tuples): the kernels'
    pieces ``G``, ``G'/R (x-y).n_T``, ``G'/R (x-y).n_x``, ``G'/R``, ``(G''/R^2 - G'/R^3) c_x c_y``,
    each as (real, imaginary), times 4 pi.

    In real arithmetic (``e^{ikR} = c + i s``): ``G' / R = e^{ikR}(ikR - 1) / R^3`` and
    ``G'' / R^2 - G' / R^3 = e^{ikR}(3 - (kR)^2 - 3ikR) / R^5``."""
    dx, dy, dz = x[0] - y[0], x[1] - y[1], x[2] - y[2]
    R2 = dx * dx + dy * dy + dz * dz
    R = np.sqrt(R2)
    iR = 1.0 / R
    iR3 = iR / R2
    kr = k * R
    c, s = _cis(kr)
    g1r, g1i = (-c - s * kr) * iR3, (c * kr - s) * iR3  # G' / R
    u = 3.0 - kr * kr
    g2r, g2i = (c * u + 3.0 * s * kr) * iR3 / R2, (s * u - 3.0 * c * kr) * iR3 / R2  # G''/R^2 - G'/R^3
    cy = dx * t[0] + dy * t[1] + dz * t[2]
    cx = dx * n[0] + dy * n[1] + dz * n[2]
    return c * iR, s * iR, g1r * cy, g1i * cy, g1r * cx, g1i * cx, g1r, g1i, cx * cy * g2r, cx * cy * g2i


@njit(cache=True, error_model="numpy", fastmath={"contract"})
def far_row(x, nx, geo, k, a, out):
    """One row of the Burton-Miller matrices with every triangle taken as distant: the 3-point
    rule on the whole kernel, ``G'' = e^{ikR}((ik)^2 R^2 - 2ikR + 2) / R^3`` (times 1/4 pi).

    Written to vectorise (the triangles ``j`` in SIMD lanes: structure-of-arrays input, the
    rule's three points unrolled, no branch, no division check): 15 ns a pair against 115
    for the same sums pair by pair (2 mm plate, 1356 elements, AVX2).

    Parameters
    ----------
    x, nx : (3,) collocation point and its normal
    geo : (13, N) the rule's points ``(y_0, y_1, y_2)`` by coordinate, the normals, area / 3
        (:attr:`BemMesh.far_geo`)
    k : float, wavenumber [1/m]; a : float, ``alpha = i a`` (``a = 1 / k``)
    out : (4, N) written: ``-K + alpha W`` and ``-S + alpha K'`` as (real, imaginary) rows
    """
    N = geo.shape[1]
    xs = (x[0], x[1], x[2])
    ns = (nx[0], nx[1], nx[2])
    for j in range(N):
        t = (geo[9, j], geo[10, j], geo[11, j])
        nn = ns[0] * t[0] + ns[1] * t[1] + ns[2] * t[2]
        w = geo[12, j]
        a0 = _far_point(xs, ns, (geo[0, j], geo[1, j], geo[2, j]), t, k)
        a1 = _far_point(xs, ns, (geo[3, j], geo[4, j], geo[5, j]), t, k)
        a2 = _far_point(xs, ns, (geo[6, j], geo[7, j], geo[8, j]), t, k)
        Sr = w * (a0[0] + a1[0] + a2[0])
        Si = w * (a0[1] + a1[1] + a2[1])
        Kr = -w * (a0[2] + a1[2] + a2[2])
        Ki = -w * (a0[3] + a1[3] + a2[3])
        Kpr = w * (a0[4] + a1[4] + a2[4])
        Kpi = w * (a0[5] + a1[5] + a2[5])
        Wr = -w * (nn * (a0[6] + a1[6] + a2[6]) + a0[8] + a1[8] + a2[8])
        Wi = -w * (nn * (a0[7] + a1[7] + a2[7]) + a0[9] + a1[9] + a2[9])
        out[0, j] = (-Kr - a * Wi) / FOUR_PI  # alpha W = i a W
        out[1, j] = (-Ki + a * Wr) / FOUR_PI
        out[2, j] = (-Sr - a * Kpi) / FOUR_PI
        out[3, j] = (-Si + a * Kpr) / FOUR_PI


@njit(cache=True, parallel=True)
def near_laplace_parts(tri, centroids, normals, edge):
    """The wavenumber-independent part of every near pair's integrals, for :func:`assemble`.

    A triangle ``j`` is *near* collocation point ``i`` when ``|x_i - x_j| <= FAR edge_j``; its
    Laplace integrals (module docstring) do not depend on ``k``, so a mesh solved at several
    wavenumbers (a level's frequency clusters) computes them once.

    Parameters
    ----------
    tri : (N, 3, 3); centroids, normals : (N, 3); edge : (N,), as in :class:`BemMesh`

    Returns
    -------
    starts : (N + 1,) int64, row ``i``'s near pairs are ``starts[i]:starts[i + 1]``
    cols : (nnz,) int64, their triangles ``j``, ascending
    parts : (nnz, 5) float64, 4 pi times ``int 1/R``, ``Omega``, ``n_x . V``, ``n_x . B``
        (:func:`_laplace_parts`) and ``h``
    """
    N = len(tri)
    count = np.zeros(N, np.int64)
    for i in prange(N):
        x = centroids[i]
        c = 0
        for j in range(N):
            ddx, ddy, ddz = x[0] - centroids[j, 0], x[1] - centroids[j, 1], x[2] - centroids[j, 2]
            if ddx * ddx + ddy * ddy + ddz * ddz <= (FAR * edge[j]) ** 2:
                c += 1
        count[i] = c
    starts = np.zeros(N + 1, np.int64)
    for i in range(N):
        starts[i + 1] = starts[i] + count[i]
    cols = np.empty(starts[N], np.int64)
    parts = np.empty((starts[N], 5))
    for i in prange(N):
        x = centroids[i]
        nx = normals[i]
        p = starts[i]
        for j in range(N):
            ddx, ddy, ddz = x[0] - centroids[j, 0], x[1] - centroids[j, 1], x[2] - centroids[j, 2]
            if ddx * ddx + ddy * ddy + ddz * ddz > (FAR * edge[j]) ** 2:
                continue
            i1, omega, V, B, h = _laplace_parts(x, nx, tri[j, 0], tri[j, 1], tri[j, 2], normals[j], i == j)
            cols[p] = j
            parts[p, 0] = i1
            parts[p, 1] = omega
            parts[p, 2] = nx[0] * V[0] + nx[1] * V[1] + nx[2] * V[2]
            parts[p, 3] = nx[0] * B[0] + nx[1] * B[1] + nx[2] * B[2]
            parts[p, 4] = h
            p += 1
    return starts, cols, parts


@njit(cache=True, parallel=True)
def assemble(centroids, normals, k, geo, geo6, starts, cols, parts):
    """Burton-Miller matrices on a :class:`BemMesh` (``alpha = i / k``).

    Parameters
    ----------
    centroids, normals : (N, 3); geo : (13, N); geo6 : (N, 27)
        The mesh's arrays (:class:`BemMesh`: ``far_geo``, ``near_geo``).
    k : float
        Wavenumber [1/m], > 0.
    starts, cols, parts
        The near pairs and their Laplace integrals (:func:`near_laplace_parts`), completed by
        :func:`near_rows`; every other triangle takes the 3-point rule on the whole kernel
        (:func:`far_row`, computed for the whole row and then overwritten at the near pairs:
        cheaper, vectorised, than a branch per pair).

    Returns
    -------
    A : (N, N) complex128, ``1/2 I - K + alpha W``
    Bq : (N, N) complex128, ``-S + alpha (1/2 I + K')``: the right-hand side is ``Bq @ q``.
    """
    N = len(centroids)
    A = np.empty((N, N), np.complex128)
    Bq = np.empty((N, N), np.complex128)
    a = 1.0 / k
    for i in prange(N):
        x = centroids[i]
        nx = normals[i]
        row = np.empty((4, N))
        far_row(x, nx, geo, k, a, row)
        lo, hi = starts[i], starts[i + 1]
        pairs = np.empty((32, hi - lo))
        gather_near(cols[lo:hi], parts[lo:hi], geo6, pairs)
        near = np.empty((4, hi - lo))
        near_rows(x, nx, pairs, k, a, near)
        for m in range(hi - lo):
            j = cols[lo + m]
            for c in range(4):
                row[c, j] = near[c, m]
        for j in range(N):
            A[i, j] = complex(row[0, j], row[1, j])
            Bq[i, j] = complex(row[2, j], row[3, j])
        A[i, i] += 0.5
        Bq[i, i] += 0.5j * a
    return A, Bq


def assemble_mesh(mesh: BemMesh, k: float):
    """:func:`assemble` on a :class:`BemMesh` with ``alpha = i / k``; the near pairs' Laplace
    integrals are computed on the mesh's first assembly and kept with it."""
    return assemble(mesh.centroids, mesh.normals, float(k), mesh.far_geo, mesh.near_geo, *mesh.near_parts())


def far_field_matrix(mesh: BemMesh, k: float, directions, centre):
    """``(E_p, E_q)``, each (n_dirs, N): ``F = E_p @ p + E_q @ q`` (module docstring), the
    element integrals by the 6-point rule."""
    d = np.asarray(directions, dtype=np.float64)
    phase = np.exp(-1j * k * np.einsum("dc,nqc->dnq", d, mesh.quad - np.asarray(centre)[None, None, :]))
    ph = np.einsum("dnq,nq->dn", phase, mesh.quad_w) / FOUR_PI
    Ep = -1j * k * (d @ mesh.normals.T) * ph
    return Ep, -ph


def far_field_parts(mesh: BemMesh, k: float, directions, centre):
    r"""The far field's pieces at the solve's wavenumber ``k`` for :func:`far_fields_per_mode`.

    Each element's integral of ``e^{-ik d.(y - c)}`` splits into the phase of its centroid
    ``x_n`` and a local factor, ``int e^{-ik d.(y - c)} dA = e^{-ik d.(x_n - c)} l_n(d)`` with
    ``l_n(d) = int e^{-ik d.(y - x_n)} dA`` (6-point rule). ``l_n = A_n (1 + O((k h)^2))``:
    its first-order term vanishes about the centroid, so a mode a few per cent off ``k`` keeps
    the local factor at ``k`` and takes its own wavenumber in the centroid's phase.

    Returns
    -------
    local_re, local_im : (n_dirs, N) float, ``l_n(d) / 4 pi`` [m^2]
    proj : (n_dirs, N) float, ``d . (x_n - c)`` [m]
    dn : (n_dirs, N) float, ``d . n_n``
    """
    d = np.ascontiguousarray(directions, dtype=np.float64)
    out = np.empty((4, len(d), len(mesh)))
    _far_field_parts(d, mesh.far_field_geo, np.asarray(centre, np.float64), float(k), out)
    return out[0], out[1], out[2], out[3]


@njit(cache=True, error_model="numpy", fastmath=True)
def _far_field_row(d0, d1, d2, geo, c0, c1, c2, k, lr, li, proj, dn):
    """:func:`far_field_parts` for one direction, vectorised over the elements (their data by
    rows, :attr:`BemMesh.far_field_geo`; the six points unrolled)."""
    for n in range(geo.shape[1]):
        re = 0.0
        im = 0.0
        c, s = _cis(-k * (d0 * geo[0, n] + d1 * geo[1, n] + d2 * geo[2, n]))
        re += geo[18, n] * c
        im += geo[18, n] * s
        c, s = _cis(-k * (d0 * geo[3, n] + d1 * geo[4, n] + d2 * geo[5, n]))
        re += geo[19, n] * c
        im += geo[19, n] * s
        c, s = _cis(-k * (d0 * geo[6, n] + d1 * geo[7, n] + d2 * geo[8, n]))
        re += geo[20, n] * c
        im += geo[20, n] * s
        c, s = _cis(-k * (d0 * geo[9, n] + d1 * geo[10, n] + d2 * geo[11, n]))
        re += geo[21, n] * c
        im += geo[21, n] * s
        c, s = _cis(-k * (d0 * geo[12, n] + d1 * geo[13, n] + d2 * geo[14, n]))
        re += geo[22, n] * c
        im += geo[22, n] * s
        c, s = _cis(-k * (d0 * geo[15, n] + d1 * geo[16, n] + d2 * geo[17, n]))
        re += geo[23, n] * c
        im += geo[23, n] * s
        lr[n] = re / FOUR_PI
        li[n] = im / FOUR_PI
        proj[n] = d0 * (geo[24, n] - c0) + d1 * (geo[25, n] - c1) + d2 * (geo[26, n] - c2)
        dn[n] = d0 * geo[27, n] + d1 * geo[28, n] + d2 * geo[29, n]


@njit(cache=True, parallel=True)
def _far_field_parts(d, geo, centre, k, out):
    for a in prange(len(d)):
        _far_field_row(d[a, 0], d[a, 1], d[a, 2], geo, centre[0], centre[1], centre[2], k,
                       out[0, a], out[1, a], out[2, a], out[3, a])


@njit(cache=True, parallel=True, fastmath=True)
def far_fields_per_mode(lr, li, proj, dn, p, q, k):
    r"""Far fields of modes, each at its own wavenumber, from one solve's surface fields.

    ``F[d, i] = sum_n l[d, n] e^{-i k_i proj[d, n]} (-i k_i dn[d, n] p[i, n] - q[i, n])``:
    the module docstring's far-field integral with the parts of :func:`far_field_parts`
    (the phase by :func:`_cis`, which vectorises where ``np.exp`` does not).

    Parameters
    ----------
    lr, li, proj, dn : (n_dirs, N), :func:`far_field_parts` (the local factor's real and
        imaginary parts, the projections, the normals' components)
    p, q : (g, N) complex, surface pressure [Pa] and its normal derivative [Pa/m] per mode
    k : (g,) float, the modes' wavenumbers [1/m]

    Returns
    -------
    F : (n_dirs, g) complex far-field amplitudes [Pa m].
    """
    nd, N = proj.shape
    g = len(k)
    F = np.empty((nd, g), np.complex128)
    pr = np.ascontiguousarray(p.real)
    pi = np.ascontiguousarray(p.imag)
    qr = np.ascontiguousarray(q.real)
    qi = np.ascontiguousarray(q.imag)
    for a in prange(nd):
        for i in range(g):
            ki = k[i]
            re = 0.0
            im = 0.0
            for n in range(N):
                c, s = _cis(-ki * proj[a, n])
                er, ei = lr[a, n] * c - li[a, n] * s, lr[a, n] * s + li[a, n] * c  # local e^{i ph}
                # (-i k dn p - q)
                kd = ki * dn[a, n]
                vr = kd * pi[i, n] - qr[i, n]
                vi = -kd * pr[i, n] - qi[i, n]
                re += er * vr - ei * vi
                im += er * vi + ei * vr
            F[a, i] = re + 1j * im
    return F


def solve_far_field(mesh: BemMesh, k: float, q, directions, centre=(0.0, 0.0, 0.0)):
    """Far field of the exterior problem with normal derivative ``q`` on ``mesh``.

    Parameters
    ----------
    mesh : BemMesh
    k : float
        Wavenumber [1/m].
    q : (N,) or (N, m) array
        ``dp/dn`` per triangle (``rho omega^2 u_n`` for a normal displacement ``u_n``) [Pa/m].
    directions : (n_dirs, 3) unit vectors
    centre : (3,) point the phase is referred to [m]

    Returns
    -------
    F : (n_dirs, m) complex far-field amplitude [Pa m] (``p ~ F e^{ikr} / r``);
    p : (N, m) surface pressure [Pa].
    """
    import scipy.linalg as sla

    q = np.asarray(q, dtype=np.complex128)
    q2 = q.reshape(len(mesh), -1)
    A, Bq = assemble_mesh(mesh, float(k))
    p = sla.lu_solve(sla.lu_factor(A, overwrite_a=True, check_finite=False), Bq @ q2, check_finite=False)
    Ep, Eq = far_field_matrix(mesh, k, directions, centre)
    F = Ep @ p + Eq @ q2
    return (F, p) if q.ndim == 2 else (F[:, 0], p[:, 0])
