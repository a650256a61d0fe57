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

Far field (``p ~ F(d) e^{ikr} / r``), referred to a centre ``c``:

.. math:: F(d) = \frac{1}{4\pi} \int_\Gamma \big(-ik (d\cdot n) p - q\big) e^{-ik d\cdot(y - c)} dA .
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

__all__ = ["QUAD_BARY", "QUAD_WEIGHTS", "BemMesh", "assemble", "assemble_mesh", "solve_far_field", "far_field_matrix",
           "far_field_parts", "far_fields_per_mode"]

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

    def __len__(self):
        return len(self.faces)


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


@njit(cache=True)
def _remainders(kr, k):
    """4 pi times the bounded Helmholtz remainders at R (module docstring):
    g = G_r, a_b = A + k^2 / 8 pi R, a2_b R = (A'/R - k^2 / 8 pi R^3) R, and A itself."""
    R = kr / k
    ik = 1j * k
    if kr < 0.1:  # series: exp(ikR) expanded, no cancellation
        g = 0j
        ab = 0j
        a2bR = 0j
        term = 1.0 + 0j  # (ik)^m R^m / m!
        for m in range(1, 16):
            term = term * (ik * R) / m
            g += term / R
            if m >= 3:
                ab += (m - 1) * term / (R * R * R)
            if m >= 4:
                a2bR += (m - 1) * (m - 3) * term / (R * R * R * R)
        A = ab - k * k / (2.0 * R)
        return g, ab, a2bR, A
    # real arithmetic, no complex division: e^{ikR} = c + i s
    c, s = _cis(kr)
    iR = 1.0 / R
    iR3 = iR * iR * iR
    g = complex((c - 1.0) * iR, s * iR)
    Ar, Ai = (1.0 - c - kr * s) * iR3, (kr * c - s) * iR3
    half = 0.5 * k * k * iR
    ab = complex(Ar + half, Ai)
    a2bR = complex((-k * k * c * iR - 3.0 * Ar) * iR - half * iR, (-k * k * s * iR - 3.0 * Ai) * iR)
    return g, ab, a2bR, complex(Ar, Ai)


@njit(cache=True)
def _far_pair(x, nx, nT, quad3, area, k):
    """4 pi times (S, K, K', W) of a distant triangle by the 3-point rule on the whole kernel:
    ``G' = e^{ikR}(ikR - 1) / R^2``, ``G'' = e^{ikR}((ik)^2 R^2 - 2ikR + 2) / R^3`` (times 1/4 pi).

    In real arithmetic (``t = kR``, ``e^{it} = c + i s``): ``G' / R = e^{it}(it - 1) / R^3`` and
    ``G'' / R^2 - G' / R^3 = e^{it}(3 - t^2 - 3it) / R^5``."""
    Sr = Si = Kr = Ki = Kpr = Kpi = Wr = Wi = 0.0
    nn = nx[0] * nT[0] + nx[1] * nT[1] + nx[2] * nT[2]
    w = area / 3.0
    for q in range(3):
        y = quad3[q]
        dx, dy, dz = x[0] - y[0], x[1] - y[1], x[2] - y[2]
        R2 = dx * dx + dy * dy + dz * dz
        R = np.sqrt(R2)
        iR = 1.0 / R
        iR3 = iR / R2
        t = k * R
        c, s = _cis(t)
        # G' / R
        g1r, g1i = (-c - s * t) * iR3, (c * t - s) * iR3
        # G'' / R^2 - G' / R^3
        u = 3.0 - t * t
        g2r, g2i = (c * u + 3.0 * s * t) * iR3 / R2, (s * u - 3.0 * c * t) * iR3 / R2
        cy = dx * nT[0] + dy * nT[1] + dz * nT[2]
        cx = dx * nx[0] + dy * nx[1] + dz * nx[2]
        Sr += w * c * iR
        Si += w * s * iR
        Kr -= w * g1r * cy
        Ki -= w * g1i * cy
        Kpr += w * g1r * cx
        Kpi += w * g1i * cx
        Wr -= w * (nn * g1r + cx * cy * g2r)
        Wi -= w * (nn * g1i + cx * cy * g2i)
    return complex(Sr, Si), complex(Kr, Ki), complex(Kpr, Kpi), complex(Wr, Wi)


@njit(cache=True, parallel=True)
def assemble(tri, centroids, normals, quad, quad_w, k, alpha, quad3, areas, edge):
    """Burton-Miller matrices on a :class:`BemMesh`.

    Parameters
    ----------
    tri : (N, 3, 3); centroids, normals : (N, 3); quad : (N, Q, 3); quad_w : (N, Q);
    quad3 : (N, 3, 3); areas, edge : (N,)
        The mesh's arrays (:class:`BemMesh`); triangles farther than ``FAR`` edges from a
        collocation point take the 3-point rule on the whole kernel.
    k : float
        Wavenumber [1/m], > 0.
    alpha : complex
        Coupling of the hypersingular equation (``i / k``).

    Returns
    -------
    A : (N, N) complex128, ``1/2 I - K + alpha W``
    Bq : (N, N) complex128, ``-S + alpha (1/2 I + K')``: the right-hand side is ``Bq @ q``.
    """
    N = len(tri)
    Q = quad.shape[1]
    A = np.empty((N, N), np.complex128)
    Bq = np.empty((N, N), np.complex128)
    k2_8pi = k * k / 2.0  # (k^2 / 8 pi) in units of 1 / 4 pi
    for i in prange(N):
        x = centroids[i]
        nx = normals[i]
        for j in range(N):
            nT = normals[j]
            ddx = x[0] - centroids[j, 0]
            ddy = x[1] - centroids[j, 1]
            ddz = x[2] - centroids[j, 2]
            if ddx * ddx + ddy * ddy + ddz * ddz > (FAR * edge[j]) ** 2:
                S, K, Kp, W = _far_pair(x, nx, nT, quad3[j], areas[j], k)
                A[i, j] = (-K + alpha * W) / FOUR_PI
                Bq[i, j] = (-S + alpha * Kp) / FOUR_PI
                continue
            self_term = i == j
            i1, omega, V, B, h = _laplace_parts(x, nx, tri[j, 0], tri[j, 1], tri[j, 2], nT, self_term)
            nn = nx[0] * nT[0] + nx[1] * nT[1] + nx[2] * nT[2]
            nV = nx[0] * V[0] + nx[1] * V[1] + nx[2] * V[2]
            nB = nx[0] * B[0] + nx[1] * B[1] + nx[2] * B[2]
            # all of these are 4 pi times the integral
            S = i1 + 0j
            K = omega + 0j
            Kp = -nV + 0j
            W = -nB + k2_8pi * nn * i1 - k2_8pi * h * nV + 0j
            for q in range(Q):
                y = quad[j, q]
                dx, dy, dz = x[0] - y[0], x[1] - y[1], x[2] - y[2]
                R = np.sqrt(dx * dx + dy * dy + dz * dz)
                g, ab, a2bR, Am = _remainders(k * R, k)
                cy = dx * nT[0] + dy * nT[1] + dz * nT[2]
                cx = dx * nx[0] + dy * nx[1] + dz * nx[2]
                w = quad_w[j, q]
                S += w * g
                K += w * (-Am * cy)
                Kp += w * (Am * cx)
                W += w * (-nn * ab - cx * cy * a2bR / R)
            S /= FOUR_PI
            K /= FOUR_PI
            Kp /= FOUR_PI
            W /= FOUR_PI
            A[i, j] = -K + alpha * W
            Bq[i, j] = -S + alpha * Kp
        A[i, i] += 0.5
        Bq[i, i] += 0.5 * alpha
    return A, Bq


def assemble_mesh(mesh: BemMesh, k: float):
    """:func:`assemble` on a :class:`BemMesh` with ``alpha = i / k``."""
    return assemble(mesh.tri, mesh.centroids, mesh.normals, mesh.quad, mesh.quad_w, float(k), 1j / float(k),
                    mesh.quad3, mesh.areas, mesh.edge)


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
    local : (n_dirs, N) complex, ``l_n(d) / 4 pi`` [m^2]
    proj : (n_dirs, N) float, ``d . (x_n - c)`` [m]
    dn : (n_dirs, N) float, ``d . n_n``
    """
    d = np.ascontiguousarray(directions, dtype=np.float64)
    return _far_field_parts(d, mesh.quad, mesh.quad_w, mesh.centroids, mesh.normals,
                            np.asarray(centre, np.float64), float(k))


@njit(cache=True, parallel=True, fastmath=True)
def _far_field_parts(d, quad, quad_w, centroids, normals, centre, k):
    nd, N, Q = len(d), len(quad), quad.shape[1]
    local = np.empty((nd, N), np.complex128)
    proj = np.empty((nd, N))
    dn = np.empty((nd, N))
    for a in prange(nd):
        for n in range(N):
            re = 0.0
            im = 0.0
            for q in range(Q):
                s = (d[a, 0] * (quad[n, q, 0] - centroids[n, 0]) + d[a, 1] * (quad[n, q, 1] - centroids[n, 1])
                     + d[a, 2] * (quad[n, q, 2] - centroids[n, 2]))
                c, sn = _cis(-k * s)
                re += quad_w[n, q] * c
                im += quad_w[n, q] * sn
            local[a, n] = complex(re, im) / FOUR_PI
            proj[a, n] = (d[a, 0] * (centroids[n, 0] - centre[0]) + d[a, 1] * (centroids[n, 1] - centre[1])
                          + d[a, 2] * (centroids[n, 2] - centre[2]))
            dn[a, n] = d[a, 0] * normals[n, 0] + d[a, 1] * normals[n, 1] + d[a, 2] * normals[n, 2]
    return local, proj, dn


@njit(cache=True, parallel=True, fastmath=True)
def far_fields_per_mode(local, proj, dn, p, q, k):
    r"""Far fields of modes, each at its own wavenumber, from one solve's surface fields.

    ``F[d, i] = sum_n local[d, n] e^{-i k_i proj[d, n]} (-i k_i dn[d, n] p[i, n] - q[i, n])``:
    the module docstring's far-field integral with the parts of :func:`far_field_parts`
    (the phase by :func:`_cis`, which vectorises where ``np.exp`` does not).

    Parameters
    ----------
    local, proj, dn : (n_dirs, N), :func:`far_field_parts`
    p, q : (g, N) complex, surface pressure [Pa] and its normal derivative [Pa/m] per mode
    k : (g,) float, the modes' wavenumbers [1/m]

    Returns
    -------
    F : (n_dirs, g) complex far-field amplitudes [Pa m].
    """
    nd, N = proj.shape
    g = len(k)
    F = np.empty((nd, g), np.complex128)
    lr = np.empty((nd, N))
    li = np.empty((nd, N))
    for a in range(nd):
        for n in range(N):
            lr[a, n] = local[a, n].real
            li[a, n] = local[a, n].imag
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
