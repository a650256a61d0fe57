"""Raghuvanshi and Lin's spring-mass surface model ("shell" method).

Raghuvanshi & Lin (2006; thesis ch. 3, seed 000) turn a surface mesh into point masses
at the vertices and springs along the edges::

    k   = E t            spring constant of every edge [N/m]
    m_i = rho t a_i      mass of vertex i [kg], a_i = 1/3 of the adjacent triangle areas

and linearise about the rest shape. A spring between vertices a and b with unit
direction ``e = (x_b - x_a) / |x_b - x_a|`` resists only stretching along itself, so its
3x3 blocks are::

    K[a, a] += k e e^T    K[b, b] += k e e^T    K[a, b] = K[b, a] -= k e e^T

and ``M = diag(m_i) (x) I3``. Dofs are ``3 * vertex + component`` (x, y, z).

What the model is and is not
----------------------------
*Cheap and approximate.* It has no bending stiffness at all: a spring only resists
stretching, so a flat plate has zero out-of-plane stiffness (every transverse motion of a
flat triangulated plate is a zero-energy mechanism to first order). It works on curved
shells (bowls, bells, cans) because curvature couples bending to in-plane stretching;
there it gives plausible, not accurate, frequencies.

* **Spring constant.** ``k = E t`` is the paper's choice and does not depend on the edge
  length. For a uniform equilateral mesh the network's in-plane (membrane) stiffness is
  that of an isotropic sheet with ``E_2D = 2 k / sqrt(3) = 1.155 E t`` and Poisson's
  ratio 1/3, independent of the mesh size (a real membrane has ``E t / (1 - nu^2)``);
  irregular meshes are anisotropic. The material's ``nu`` is not used.
* **Scaling laws (exact in this model).** ``omega^2 ~ k / m = E / (rho a)``: the
  thickness cancels, so frequencies **do not depend on t**; they scale as
  ``sqrt(E / rho)`` and as ``1 / s`` when the geometry is scaled by s (with or without
  scaling t). This is the scaling of membrane (stretching) modes. Real bending modes of a
  thin shell scale as ``t / s^2``, which the model cannot reproduce.
* **Rigid modes.** A closed, strictly convex triangulated surface (icosphere, a box with
  no vertices inside flat faces) is infinitesimally rigid (Dehn's theorem): exactly 6 zero
  modes. Open surfaces, flat regions with interior vertices (a refined flat face) and
  hinges have extra zero-energy mechanisms; ``n_rigid`` is still reported as 6 and the
  extra near-zero modes fall below any audible band anyway.
"""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp
import trimesh

from .discretization import Discretization

__all__ = ["discretize_shell"]


def _clean(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """Copy with duplicate vertices merged, degenerate faces and unused vertices removed.

    Unmerged duplicates would split the network into loose pieces and unused vertices
    would get zero mass (a singular M).
    """
    m = trimesh.Trimesh(np.asarray(mesh.vertices, dtype=np.float64),
                        np.asarray(mesh.faces, dtype=np.int64), process=False)
    m.merge_vertices()
    m.update_faces(m.nondegenerate_faces())
    m.remove_unreferenced_vertices()
    return m


def _closest_point(V, F, pts, k=8, around_vertices=True):
    """Closest point on the surface: (p, 3) points, (p,) distances, (p,) triangle ids.

    Candidates are the k triangles with the nearest centroids and, with
    ``around_vertices``, the triangles around the k nearest vertices (no rtree needed);
    the closest of them wins.
    """
    from scipy.spatial import cKDTree

    kf = min(k, len(F))
    _, nf = cKDTree(V[F].mean(axis=1)).query(pts, k=kf)
    nf = nf.reshape(len(pts), kf)
    if not around_vertices:
        return _closest_of(V, F, pts, nf)
    kv = min(k, len(V))
    _, nv = cKDTree(V).query(pts, k=kv)
    nv = nv.reshape(len(pts), kv)
    # vertex -> incident faces, padded (CSR of the face list by vertex)
    vf = np.repeat(np.arange(len(F)), 3)
    order = np.argsort(F.reshape(-1), kind="stable")
    counts = np.bincount(F.reshape(-1), minlength=len(V))
    start = np.concatenate([[0], np.cumsum(counts)])
    width = int(counts.max())
    slot = start[:-1, None] + np.arange(width)
    pad = np.where(slot < start[1:, None], vf[order][np.minimum(slot, len(vf) - 1)], -1)
    cand = np.concatenate([pad[nv].reshape(len(pts), -1), nf], axis=1)  # (p, c)
    cand = np.where(cand < 0, nf[:, :1], cand)
    return _closest_of(V, F, pts, cand)


def _closest_of(V, F, pts, cand):
    """The closest point to each of ``pts`` (p, 3) on its candidate triangles ``cand`` (p, c)."""
    c = cand.shape[1]
    q = trimesh.triangles.closest_point(V[F[cand.reshape(-1)]], np.repeat(pts, c, axis=0))
    dist = np.linalg.norm(q - np.repeat(pts, c, axis=0), axis=1).reshape(len(pts), c)
    best = np.argmin(dist, axis=1)
    r = np.arange(len(pts))
    return q.reshape(len(pts), c, 3)[r, best], dist[r, best], cand[r, best]


def discretize_shell(mesh: trimesh.Trimesh, material, points: np.ndarray,
                     thickness: float) -> Discretization:
    """Spring-mass discretization of a thin surface (Raghuvanshi and Lin).

    Parameters
    ----------
    mesh : trimesh.Trimesh
        Triangle surface in metres; may be open or non-manifold. Duplicate vertices are
        merged and degenerate faces dropped first.
    material : mjsound.Material
        Uses E [Pa] and rho [kg/m^3] (not nu).
    points : (p, 3) array
        Sample points [m]; each is projected onto the nearest triangle and its
        displacement interpolated barycentrically from the three vertices.
    thickness : float
        Wall thickness t [m] (> 0). Sets the masses and spring constants; the
        frequencies do not depend on it (see the module notes).

    Returns
    -------
    Discretization
        ``K`` (3V, 3V) csr [N/m] from the edge springs, ``M`` (3V, 3V) diagonal csr [kg],
        ``interp`` (3p, 3V) csr, ``n_rigid = 6``, ``info`` with ``element`` ("spring"),
        ``n_vertices``, ``n_springs``, ``thickness`` [m], ``spring_k`` [N/m],
        ``mass`` [kg], ``mean_edge`` [m] and ``seconds``.

    Raises
    ------
    ValueError
        Non-positive or non-finite thickness, an empty mesh, or non-finite vertices.
    """
    t0 = time.perf_counter()
    t = float(thickness)
    if not (np.isfinite(t) and t > 0):
        raise ValueError(
            f"shell method: thickness={thickness!r} must be a positive length in metres"
        )
    if len(mesh.faces) == 0 or not np.all(np.isfinite(mesh.vertices)):
        raise ValueError("shell method: the mesh is empty or has non-finite vertices")
    m = _clean(mesh)
    if len(m.faces) == 0:
        raise ValueError("shell method: the mesh has no triangle of non-zero area")
    V, F = m.vertices, m.faces
    nv = len(V)

    # masses: m_i = rho t a_i, a_i = sum over adjacent faces of area / 3
    area = np.bincount(F.reshape(-1), weights=np.repeat(m.area_faces / 3.0, 3), minlength=nv)
    mass = material.rho * t * area
    M = sp.diags(np.repeat(mass, 3)).tocsr()

    # springs: k e e^T blocks along every unique edge
    E = m.edges_unique  # (ne, 2)
    d = V[E[:, 1]] - V[E[:, 0]]
    length = np.linalg.norm(d, axis=1)
    keep = length > 0
    E, d, length = E[keep], d[keep], length[keep]
    e = d / length[:, None]
    k = material.E * t
    blk = k * e[:, :, None] * e[:, None, :]  # (ne, 3, 3)
    a, b = E[:, 0], E[:, 1]
    c3 = np.arange(3)
    ri = lambda n: (3 * n[:, None, None] + c3[None, :, None]).repeat(3, axis=2)  # noqa: E731
    ci = lambda n: (3 * n[:, None, None] + c3[None, None, :]).repeat(3, axis=1)  # noqa: E731
    rows = np.concatenate([ri(a), ri(b), ri(a), ri(b)]).reshape(-1)
    cols = np.concatenate([ci(a), ci(b), ci(b), ci(a)]).reshape(-1)
    vals = np.concatenate([blk, blk, -blk, -blk]).reshape(-1)
    K = sp.csr_matrix((vals, (rows, cols)), shape=(3 * nv, 3 * nv))
    K = ((K + K.T) * 0.5).tocsr()  # exact symmetry (summation order differs by entry)

    # interp: barycentric on the closest triangle
    P, max_dist = surface_interpolation(V, F, points)

    info = {
        "method": "shell",
        "element": "spring",
        "n_vertices": int(nv),
        "n_springs": int(len(E)),
        "thickness": t,
        "spring_k": float(k),
        "mass": float(mass.sum()),
        "mean_edge": float(length.mean()) if len(length) else 0.0,
        "max_point_distance": max_dist,
        "seconds": time.perf_counter() - t0,
    }
    return Discretization(K=K, M=M, interp=P, n_rigid=6, info=info)


def surface_interpolation(V, F, points, dofs_per_node: int = 3, k: int = 8, around_vertices: bool = True):
    """Displacement at ``points`` (p, 3) [m] from the nodes ``V`` (n, 3) of triangles ``F``:
    barycentric on each point's closest triangle (:func:`_closest_point` with ``k`` and
    ``around_vertices``), as ``(P (3p, dofs_per_node n) csr, largest point distance [m])``.
    Node ``i``'s translations are its dofs ``dofs_per_node i + (0, 1, 2)``."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    p, nv = len(pts), len(V)
    if not p:
        return sp.csr_matrix((0, dofs_per_node * nv)), 0.0
    closest, dist, tri = _closest_point(V, F, pts, k, around_vertices)
    bary = trimesh.triangles.points_to_barycentric(V[F[tri]], closest)
    bary = np.clip(np.nan_to_num(bary, nan=1.0 / 3.0), 0.0, None)
    bary /= bary.sum(axis=1, keepdims=True)
    c3 = np.arange(3)
    rows = np.broadcast_to((3 * np.arange(p)[:, None, None] + c3), (p, 3, 3))
    cols = dofs_per_node * F[tri][:, :, None] + c3
    vals = np.broadcast_to(bary[:, :, None], (p, 3, 3))
    P = sp.csr_matrix((vals.reshape(-1), (rows.reshape(-1), cols.reshape(-1))),
                      shape=(3 * p, dofs_per_node * nv))
    return P, float(dist.max())
