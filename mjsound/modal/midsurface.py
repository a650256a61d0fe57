r"""The mid-surface of a thin-walled solid, for the flat-facet shell (:mod:`.facet_shell`).

A closed surface that bounds a thin wall (a bowl, a tube, a can made hollow with
``wall=``) has two sheets facing each other ``t`` apart. :func:`mid_surface` finds them
and returns one sheet moved halfway across, with the local thickness:

1. From each triangle's centroid a ray goes inward (along ``-n``); the nearest triangle
   it hits (Möller-Trumbore, among the triangles with points nearest to where the
   wall's far side should be) gives the local thickness ``t_f`` if it faces back
   (``n_hit . n < -WALL_FACING``). Triangles without such a partner (a bowl's rim, the
   end faces of a solid part) are not wall.
2. The wall triangles split into connected sheets; of each pair facing each other the
   larger one (the outside) is kept.
3. Each kept vertex moves inward by the offset that puts every adjacent face plane
   ``t_v / 2`` away (:func:`.surface.vertex_offsets`), ``t_v`` the mean ``t_f`` of its
   faces.

The triangles left out (rim, ends) are reported as the fraction of the surface area
they cover: where it is large the object is not a thin wall and the shell does not
apply.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

__all__ = ["MidSurface", "mid_surface", "ray_hits", "crease_cents"]

#: a wall's far side faces back: normals within ~45 degrees of opposite
WALL_FACING = 0.7
#: a fold sharper than this [degrees] is a crease (a can's rim between wall and cap)
CREASE_DEGREES = 30.0


@dataclass
class MidSurface:
    """A mid-surface: ``vertices`` (V, 3) [m], ``faces`` (F, 3), ``thickness`` (V,) [m],
    ``coverage``: the fraction of the solid's surface area that is wall (both sheets), and
    ``creases``: its edges where the surface folds by more than :data:`CREASE_DEGREES`."""

    vertices: np.ndarray
    faces: np.ndarray
    thickness: np.ndarray
    coverage: float
    creases: int = 0


def _proxies(tris: np.ndarray, spacing: float, max_level: int = 32):
    """Points spread over each triangle no farther than ~``spacing`` apart (barycentric
    grids of ``L = ceil(longest edge / spacing)`` steps, at most ``max_level``): (P, 3)
    points and (P,) their triangles. A long thin triangle gets points along its length,
    where its centroid alone would be far from most of it."""
    longest = np.max(np.linalg.norm(tris - np.roll(tris, 1, axis=1), axis=2), axis=1)
    level = np.clip(np.ceil(longest / spacing), 1, max_level).astype(int)
    pts, owner = [], []
    for L in np.unique(level):
        i, j = np.meshgrid(np.arange(L + 1), np.arange(L + 1), indexing="ij")
        keep = i + j <= L
        bary = np.c_[i[keep], j[keep], L - i[keep] - j[keep]] / L if L > 1 else np.full((1, 3), 1 / 3)
        sel = np.flatnonzero(level == L)
        pts.append(np.einsum("bk,fkd->fbd", bary, tris[sel]).reshape(-1, 3))
        owner.append(np.repeat(sel, len(bary)))
    return np.concatenate(pts), np.concatenate(owner)


def ray_hits(tris: np.ndarray, origins: np.ndarray, dirs: np.ndarray, guess: np.ndarray, k: int = 24,
             spacing: float | None = None):
    """Nearest hit of each ray among the triangles nearest to its ``guess`` point
    (Möller-Trumbore): the owners of the ``k`` nearest of points spread over every triangle
    ``spacing`` [m] apart (default: each triangle's centroid only).

    Parameters
    ----------
    tris : (F, 3, 3) array
        Triangles [m].
    origins, dirs, guess : (R, 3) arrays
        Ray origins [m], unit directions and the points near which hits are expected [m].

    Returns
    -------
    dist : (R,) array
        Distance [m] to the nearest hit in front of the origin (inf: none).
    face : (R,) int array
        Triangle hit (-1: none).
    """
    from scipy.spatial import cKDTree

    if spacing is None:
        pts, owner = tris.mean(axis=1), np.arange(len(tris))
    else:
        pts, owner = _proxies(tris, spacing)
    k = min(k, len(pts))
    _, near = cKDTree(pts).query(guess, k=k)
    cand = owner[near.reshape(len(origins), k)]
    dist = np.full(len(origins), np.inf)
    face = np.full(len(origins), -1)
    for s0 in range(0, len(origins), RAY_CHUNK):  # bounded memory: (chunk, k, 3) arrays
        sl = slice(s0, s0 + RAY_CHUNK)
        dist[sl], face[sl] = _moller_trumbore(tris, cand[sl], origins[sl], dirs[sl])
    return dist, face


#: rays tested at once in :func:`ray_hits`
RAY_CHUNK = 8192


def _moller_trumbore(tris, cand, origins, dirs):
    """Nearest hit (R,) distances and (R,) triangles (-1: none) of each ray among its
    candidate triangles ``cand`` (R, k)."""
    a, b, c = (tris[cand, i] for i in range(3))  # (R, k, 3)
    e1, e2 = b - a, c - a
    d = np.broadcast_to(dirs[:, None, :], e1.shape)
    p = np.cross(d, e2)
    det = np.einsum("rkj,rkj->rk", e1, p)
    ok = np.abs(det) > 1e-30
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = origins[:, None, :] - a
    u = np.einsum("rkj,rkj->rk", s, p) * inv
    q = np.cross(s, e1)
    v = np.einsum("rkj,rkj->rk", d, q) * inv
    dist = np.einsum("rkj,rkj->rk", e2, q) * inv
    eps = 1e-9
    hit = ok & (u >= -eps) & (v >= -eps) & (u + v <= 1 + eps) & (dist > 0)
    dist = np.where(hit, dist, np.inf)
    best = np.argmin(dist, axis=1)
    r = np.arange(len(origins))
    dmin = dist[r, best]
    return dmin, np.where(np.isfinite(dmin), cand[r, best], -1)


def mid_surface(mesh: trimesh.Trimesh) -> MidSurface:
    """The mid-surface of a closed thin-walled solid (module docstring).

    Parameters
    ----------
    mesh : trimesh.Trimesh
        Watertight, outward-oriented surface of a thin wall.

    Returns
    -------
    MidSurface
        Empty (no faces, coverage 0) when no part of the surface is a thin wall.
    """
    from .surface import face_components, vertex_offsets

    m = trimesh.Trimesh(np.asarray(mesh.vertices, float), np.asarray(mesh.faces, np.int64), process=False)
    if m.is_watertight and m.volume < 0:
        m.invert()
    tris = np.asarray(m.triangles)
    nf = np.asarray(m.face_normals)
    cent = tris.mean(axis=1)
    t_guess = 2.0 * abs(float(m.volume)) / float(m.area)
    size = float(np.min(m.extents))
    dist, hit = ray_hits(tris, cent - 1e-9 * size * nf, -nf, cent - t_guess * nf, spacing=max(2.0 * t_guess, np.sqrt(m.area / 2e5)))
    facing = np.zeros(len(tris), bool)
    found = hit >= 0
    facing[found] = np.einsum("ij,ij->i", nf[hit[found]], nf[found]) < -WALL_FACING
    wall = facing & (dist < 0.25 * size)
    empty = MidSurface(np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros(0), 0.0)
    if not wall.any():
        return empty
    # sheets: connected components of the wall faces (shared edges)
    idx = np.flatnonzero(wall)
    _, label = face_components(m, wall)
    area = np.asarray(m.area_faces)
    sheet_area = np.bincount(label[idx], weights=area[idx], minlength=label.max() + 1)
    # each sheet's partner: the sheet most of its rays hit (by area)
    keep = np.zeros(len(tris), bool)
    for s in np.unique(label[idx]):
        mine = idx[label[idx] == s]
        other = label[hit[mine]]
        partner = np.bincount(other, weights=area[mine]).argmax()
        if partner != s and (sheet_area[s], -s) > (sheet_area[partner], -partner):
            keep[mine] = True
    faces = np.asarray(m.faces)[keep]
    coverage = float(area[wall].sum() / area.sum())
    if len(faces) == 0:
        return empty
    used, inv = np.unique(faces, return_inverse=True)
    inv = inv.ravel()
    sub = trimesh.Trimesh(m.vertices[used], inv.reshape(-1, 3), process=False)
    t_face = dist[keep]
    t_vert = np.bincount(inv, weights=np.repeat(t_face, 3), minlength=len(used)) / np.bincount(inv, minlength=len(used))
    offset = vertex_offsets(sub, 1.0) * (0.5 * t_vert)[:, None]
    creases = int(np.sum(sub.face_adjacency_angles > np.radians(CREASE_DEGREES)))
    return MidSurface(np.asarray(sub.vertices) - offset, np.asarray(sub.faces), t_vert, coverage, creases)


def crease_cents(thickness: float, smallest_side: float) -> float:
    r"""How many cents flat a plain shell's modes next to a crease would be [cents, >= 0].

    Where two walls meet at a sharp fold (a can's rim) a shell's plates span to the other
    wall's mid-surface, half a wall farther than the solid's stiff ``t x t`` corner lets
    them bend, so a plate mode of span ``a`` (taken as half the smallest side) is flat by
    about ``(a / (a - t/2))^2``:

    .. math:: \Delta c \approx \frac{1200}{\ln 2}\,\frac{t}{a}

    (a 1 mm can of radius 40 mm: 43 c; measured -38 and -36 c on its end-cap modes, -13
    and -4 c on its wall's, against extrapolated quadratic tets).
    :func:`.facet_shell.rigid_corner_factor` corrects most of it (-8, -7, -9, -2 c); the
    error estimate keeps :data:`CREASE_RESIDUAL` of it.
    """
    a = 0.5 * smallest_side
    return float(1200.0 / np.log(2.0) * thickness / a) if a > 0 else 0.0


def crease_thickness(thickness: np.ndarray) -> float:
    """The wall thickness [m] :func:`crease_cents` is evaluated at: the median over the
    mid-surface's vertices (one rule for ``auto``'s choice and for the error estimate; a
    few thick vertices where the walls meet do not move it)."""
    return float(np.median(np.asarray(thickness, float)))


#: the share of :func:`crease_cents` left after the corner correction (the can: 8 of 43 c)
CREASE_RESIDUAL = 0.2
