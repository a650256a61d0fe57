r"""Surface operations before meshing: edge refinement and hollow walls.

* :func:`refine_to_size` splits edges longer than a target size at their midpoints
  until none is left (conforming: a split edge is split in both its triangles), so a
  surface keeps its exact (faceted) shape while its triangles shrink to the element size.
  Each round splits only edges that are the longest of one of their triangles (Rivara's
  longest-edge bisection): a long thin triangle is cut across its long side, which makes
  it rounder, where a uniform 1-to-4 split would keep its shape.
* :func:`hollow` makes a wall of thickness ``t`` from a surface: a closed surface keeps
  its outside and gets an inner copy offset by ``t`` towards the inside (reversed, so
  the cavity is outside the solid); an open surface gets two copies at ``+- t/2`` joined
  along its rim.

Offsets
-------
Each vertex moves by the vector ``d`` whose distance to the plane of every adjacent
face is the wall: the least-squares solution of ``n_f . d = t`` over the faces around
it, weighted by their angle at the vertex,

.. math:: d = t \left(\sum_f w_f n_f n_f^T\right)^{+} \sum_f w_f n_f ,

with the pseudo-inverse dropping directions whose weight is below a tenth of the
largest (a flat or smooth neighbourhood gives ``d = t n``; the corner of a box moves by
``t`` along each of its three faces' normals, so its faces stay exactly ``t`` apart).

Features narrower than twice the wall (a can's rolled rim, a lip a quarter of a millimetre
wide on a 5 cm part) would turn the inner copy inside out there. The vertices of such faces
have their offsets halved, repeatedly (at most :data:`THINNING_ROUNDS` times), until no face
flips: the wall is locally thinner under those features. This is accepted only while the
thinned faces cover at most :data:`MAX_THINNED_AREA` of the surface (the acoustics of a few
tiny features are not the wall's); beyond it the wall is too thick for the mesh and
:func:`hollow` refuses. The returned mesh's ``metadata["thinned_area"]`` says how much was thinned.
"""

from __future__ import annotations

import numpy as np
import trimesh

#: Halvings of a vertex's offset at most, where the inner surface would turn inside out.
THINNING_ROUNDS = 12
#: Largest fraction of the surface area whose wall :func:`hollow` may thin that way.
MAX_THINNED_AREA = 0.01

__all__ = ["refine_to_size", "hollow", "vertex_offsets", "winding_number", "cavities", "face_components"]


#: two triangles are coplanar (an edge flip keeps the surface) when their normals agree to this
COPLANAR = 1e-9


def _face_edges(F: np.ndarray) -> np.ndarray:
    """Directed edges (3F, 2) of the faces (F, 3), as they run in each face: edge k
    ``(v_k, v_k+1)`` of face f at row ``k F + f``."""
    return np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])


def refine_to_size(vertices: np.ndarray, faces: np.ndarray, size: float, max_rounds: int = 64,
                   flat: float = COPLANAR):
    """Split edges longer than ``size`` [m] until none is left (conforming bisection).

    Parameters
    ----------
    vertices : (V, 3) float array [m]
    faces : (F, 3) int array, consistently oriented
    size : float
        Longest edge allowed [m].
    max_rounds : int
        Each round splits the longest edge of every triangle whose longest edge is too long.
    flat : float
        Tolerance ``1 - cos(angle)`` between two triangles' normals under which the edge
        between them may be flipped after each round (:func:`_delaunay_flips`).

    Returns
    -------
    vertices (V', 3), faces (F', 3): the same surface (every new vertex is the midpoint
    of an old edge), orientation kept.
    """
    V = np.asarray(vertices, dtype=np.float64)
    F = np.asarray(faces, dtype=np.int64)
    for _ in range(max_rounds):
        e = _face_edges(F)
        key = np.sort(e, axis=1)
        uniq, inv = np.unique(key, axis=0, return_inverse=True)
        length = np.linalg.norm(V[uniq[:, 0]] - V[uniq[:, 1]], axis=1)
        # only edges that are the longest of one of their triangles (Rivara): the rest wait
        # for a later round, so a long thin triangle is cut across, not along
        face_edges = inv.reshape(3, -1)
        longest = face_edges[np.argmax(length[face_edges], axis=0), np.arange(len(F))]
        split = np.zeros(len(uniq), bool)
        split[longest] = True
        split &= length > size
        if not split.any():
            break
        mid = np.full(len(uniq), -1, np.int64)
        mid[split] = len(V) + np.arange(int(split.sum()))
        V = np.vstack([V, 0.5 * (V[uniq[split, 0]] + V[uniq[split, 1]])])
        m = mid[inv.reshape(3, -1).T]  # (F, 3): midpoint of edge k (v_k, v_k+1) or -1
        F = _delaunay_flips(V, _split_faces(F, m), flat=flat)
    return V, F


def _delaunay_flips(V: np.ndarray, F: np.ndarray, max_passes: int = 100, flat: float = COPLANAR) -> np.ndarray:
    """Flip the shared edge of coplanar triangle pairs whose opposite angles sum over pi
    (Lawson's flips towards the Delaunay triangulation of each flat region): the surface
    is unchanged, thin triangles (a cap's fan, halves of a long triangle) get rounder.
    Each pass flips a set of edges that share no triangle."""
    F = F.copy()
    for _ in range(max_passes):
        e = _face_edges(F)
        nF = len(F)
        key = np.sort(e, axis=1)
        order = np.lexsort((key[:, 1], key[:, 0]))
        ks = key[order]
        same = np.all(ks[1:] == ks[:-1], axis=1)
        pair = np.flatnonzero(same)
        if len(pair) == 0:
            break
        # interior edges used exactly twice (not part of a triple)
        ok = np.ones(len(pair), bool)
        ok[1:] &= pair[1:] != pair[:-1] + 1
        ok[:-1] &= pair[:-1] + 1 != pair[1:]
        pair = pair[ok]
        i, j = order[pair], order[pair + 1]  # slots k nF + f of the two half-edges
        fi, ki, fj, kj = i % nF, i // nF, j % nF, j // nF
        a, b = F[fi, ki], F[fi, (ki + 1) % 3]
        c, d = F[fi, (ki + 2) % 3], F[fj, (kj + 2) % 3]  # opposite vertices
        n1 = np.cross(V[b] - V[a], V[c] - V[a])
        n2 = np.cross(V[a] - V[b], V[d] - V[b])
        l1, l2 = np.linalg.norm(n1, axis=1), np.linalg.norm(n2, axis=1)
        coplanar = np.einsum("ij,ij->i", n1, n2) >= (1 - flat) * l1 * l2
        angle = _angle(V[a] - V[c], V[b] - V[c]) + _angle(V[a] - V[d], V[b] - V[d])
        # the flipped pair must stay positively oriented (convex quadrilateral)
        m1 = np.cross(V[d] - V[a], V[c] - V[a])
        m2 = np.cross(V[b] - V[d], V[c] - V[d])
        convex = (np.einsum("ij,ij->i", m1, n1) > 0) & (np.einsum("ij,ij->i", m2, n1) > 0)
        want = np.flatnonzero(coplanar & convex & (angle > np.pi + 1e-9) & (c != d))
        if len(want) == 0:
            break
        # an independent set: each triangle in at most one flip (first come)
        used = np.zeros(nF, bool)
        take = []
        for w in want[np.argsort(-angle[want])]:
            if not (used[fi[w]] or used[fj[w]]):
                used[fi[w]] = used[fj[w]] = True
                take.append(w)
        take = np.asarray(take)
        F[fi[take]] = np.c_[a[take], d[take], c[take]]
        F[fj[take]] = np.c_[d[take], b[take], c[take]]
    return F


def _angle(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return np.arctan2(np.linalg.norm(np.cross(u, v), axis=1), np.einsum("ij,ij->i", u, v))


def _split_faces(F: np.ndarray, m: np.ndarray) -> np.ndarray:
    """Triangles of each face after splitting the edges with a midpoint (``m >= 0``)."""
    n_split = (m >= 0).sum(axis=1)
    out = [F[n_split == 0]]
    r = np.arange(len(F))
    for k in range(3):  # one split edge k: (v_k, m, o), (m, v_k+1, o)
        sel = (n_split == 1) & (m[:, k] >= 0)
        a, b, o, mk = F[sel, k], F[sel, (k + 1) % 3], F[sel, (k + 2) % 3], m[sel, k]
        out += [np.c_[a, mk, o], np.c_[mk, b, o]]
    for k in range(3):  # edge k whole, the other two split: p on (v_k+1, o), q on (o, v_k)
        sel = (n_split == 2) & (m[:, k] < 0)
        a, b, o = F[sel, k], F[sel, (k + 1) % 3], F[sel, (k + 2) % 3]
        p, q = m[sel, (k + 1) % 3], m[sel, (k + 2) % 3]
        out += [np.c_[a, b, p], np.c_[a, p, q], np.c_[q, p, o]]
    sel = r[n_split == 3]
    v0, v1, v2 = F[sel, 0], F[sel, 1], F[sel, 2]
    m0, m1, m2 = m[sel, 0], m[sel, 1], m[sel, 2]
    out += [np.c_[v0, m0, m2], np.c_[m0, v1, m1], np.c_[m2, m1, v2], np.c_[m0, m1, m2]]
    return np.concatenate(out).astype(np.int64)


def vertex_offsets(mesh: trimesh.Trimesh, t: float) -> np.ndarray:
    """Per-vertex offsets (V, 3) [m] that keep every adjacent face plane ``t`` away
    (module docstring); along the outward normals for ``t > 0``."""
    F = np.asarray(mesh.faces)
    nf = np.asarray(mesh.face_normals)
    w = np.asarray(mesh.face_angles)  # (F, 3) angle of each face at its corners
    nv = len(mesh.vertices)
    A = np.zeros((nv, 3, 3))
    b = np.zeros((nv, 3))
    outer = nf[:, :, None] * nf[:, None, :]
    for k in range(3):
        np.add.at(A, F[:, k], w[:, k, None, None] * outer)
        np.add.at(b, F[:, k], w[:, k, None] * nf)
    g, U = np.linalg.eigh(A)  # ascending
    keep = g > 0.1 * g[:, -1:]
    ginv = np.where(keep, 1.0 / np.where(keep, g, 1.0), 0.0)
    d = np.einsum("vij,vj,vkj,vk->vi", U, ginv, U, b)
    return t * d


def hollow(mesh: trimesh.Trimesh, wall: float) -> trimesh.Trimesh:
    """A solid wall of thickness ``wall`` [m] made from a surface (module docstring).

    Parameters
    ----------
    mesh : trimesh.Trimesh
        Closed (watertight) outer surface, or an open surface (the wall's mid-surface).
    wall : float
        Wall thickness [m], > 0.

    Returns
    -------
    trimesh.Trimesh
        Watertight, outward oriented; a closed input gives two shells (outer and the
        reversed inner one), an open one a single closed slab.

    Raises
    ------
    ValueError
        A non-manifold surface (edges shared by more than two faces), or a wall so thick
        for this mesh that the inner surface turns inside out (a face of it flips).
    """
    t = float(wall)
    if not (np.isfinite(t) and t > 0):
        raise ValueError(f"wall={wall!r} must be a positive length in metres")
    m = trimesh.Trimesh(np.asarray(mesh.vertices, float), np.asarray(mesh.faces, np.int64), process=False)
    m.merge_vertices()
    counts = np.bincount(m.edges_unique_inverse, minlength=len(m.edges_unique))
    if np.any(counts > 2):
        raise ValueError(
            f"wall={t:g} m: the surface has {int((counts > 2).sum())} non-manifold edges (shared by more than "
            "two faces); a hollow wall needs a manifold surface. Repair the mesh, or analyse it solid with "
            "method='hex' and thickness=... for open parts"
        )
    closed = m.is_watertight
    if closed:
        if m.volume < 0:
            m.invert()
        d = vertex_offsets(m, t)
        outer_v, inner_v = m.vertices, m.vertices - d
    else:
        m.fix_normals()
        d = vertex_offsets(m, 0.5 * t)
        outer_v, inner_v = m.vertices + d, m.vertices - d
    F = np.asarray(m.faces)
    nf = np.asarray(m.face_normals)
    thinned = np.zeros(len(F), bool)
    if closed:  # (module docstring: features narrower than twice the wall get a thinner wall)
        for _ in range(THINNING_ROUNDS):
            bad = _flipped_mask(inner_v, F, nf)
            if not bad.any():
                break
            thinned |= bad
            v = np.unique(F[bad])
            d[v] *= 0.5
            inner_v = m.vertices - d
    flipped = int(_flipped_mask(inner_v, F, nf).sum()) + (0 if closed else int(_flipped_mask(outer_v, F, nf).sum()))
    area = np.asarray(m.area_faces)
    thinned_area = float(area[thinned].sum() / area.sum())
    if closed and not flipped:  # the inner copy turned inside out as a whole (a point reflection)
        inner_volume = trimesh.Trimesh(inner_v, F, process=False).volume
        flipped = len(F) if not 0 < inner_volume < m.volume else 0
    if flipped or thinned_area > MAX_THINNED_AREA:
        n = flipped or int(thinned.sum())
        raise ValueError(
            f"wall={t:g} m is too thick for this mesh: {n} faces of the inner surface turn inside out "
            f"(features narrower than twice the wall, {100 * thinned_area:.1f} % of the surface where at most "
            f"{100 * MAX_THINNED_AREA:.0f} % may be thinned). Use a thinner wall, or model the cavity in the mesh"
        )
    nv = len(m.vertices)
    faces = [F, F[:, ::-1] + nv]
    if not closed:
        # rim: each boundary edge (a, b), as it runs in its face, joins its outer and inner copies
        e = _face_edges(F)
        key = np.sort(e, axis=1)
        _, inv, cnt = np.unique(key, axis=0, return_inverse=True, return_counts=True)
        rim = e[cnt[inv.ravel()] == 1]
        a, b = rim[:, 0], rim[:, 1]
        faces += [np.c_[b, a, a + nv], np.c_[b, a + nv, b + nv]]
    out = trimesh.Trimesh(np.vstack([outer_v, inner_v]), np.concatenate(faces), process=False)
    if not out.is_watertight:
        raise ValueError(f"wall={t:g} m: could not close the wall of this surface (its rim is not a simple loop)")
    if out.volume < 0:
        out.invert()
    out.metadata["thinned_area"] = thinned_area
    return out


def _flipped_mask(V: np.ndarray, F: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """(F,) bool: faces of the offset surface ``V[F]`` that point against (or collapse from) ``normals``."""
    cross = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    return np.einsum("fi,fi->f", cross, normals) <= 0.0


def face_components(mesh: trimesh.Trimesh, faces: np.ndarray | None = None) -> tuple[int, np.ndarray]:
    """Connected pieces of a surface: faces sharing an edge, ``(count, label (F,))``.

    ``faces``: a (F,) boolean mask; only edges between two of its faces join pieces (the
    others are then pieces of their own)."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    adj = mesh.face_adjacency
    if faces is not None:
        adj = adj[faces[adj[:, 0]] & faces[adj[:, 1]]]
    nf = len(mesh.faces)
    graph = sp.coo_matrix((np.ones(len(adj)), (adj[:, 0], adj[:, 1])), shape=(nf, nf))
    return connected_components(graph, directed=False)


def winding_number(tris: np.ndarray, p: np.ndarray) -> float:
    """Generalised winding number of point ``p`` (3,) for triangles (T, 3, 3): the sum of
    their solid angles (Van Oosterom-Strackee) over 4 pi; +1 inside an outward shell, -1
    inside an inward one, 0 outside."""
    a, b, c = (tris[:, k] - p for k in range(3))
    la, lb, lc = (np.linalg.norm(x, axis=1) for x in (a, b, c))
    num = np.einsum("ij,ij->i", a, np.cross(b, c))
    den = la * lb * lc + np.einsum("ij,ij->i", a, b) * lc + np.einsum("ij,ij->i", b, c) * la \
        + np.einsum("ij,ij->i", c, a) * lb
    return float(np.sum(2.0 * np.arctan2(num, den)) / (4.0 * np.pi))


def cavities(parts: list) -> list:
    """For each part (trimesh.Trimesh), whether it is a cavity: closed, facing inward
    (negative volume) and inside an outward closed part (the inner shell of a hollow
    object). An inward part elsewhere is a solid with flipped faces, not a cavity."""
    closed = [p.is_watertight and abs(p.volume) > 0 for p in parts]
    outward = [c and p.volume > 0 for p, c in zip(parts, closed)]
    if not any(outward):
        return [False] * len(parts)
    solid = np.concatenate([np.asarray(p.triangles) for p, o in zip(parts, outward) if o])
    out = []
    for p, c, o in zip(parts, closed, outward):
        inward = c and not o
        probe = np.asarray(p.vertices[p.faces[0, 0]], float)  # (a part may list unused vertices)
        out.append(bool(inward and winding_number(solid, probe) > 0.5))
    return out
