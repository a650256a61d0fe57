"""Boundary-element meshes of an object's outer surface, one per element size.

A level's mesh has every edge at most ``h`` long: the surface is first coarsened where its
own triangles are much smaller than ``h`` (:func:`coarsen`: vertices merged per cell of a
grid, separately for each of the six directions a vertex normal mostly points to, so the two
sheets of a thin wall never merge), then each triangle too long is split evenly until
no edge is longer than about ``h`` (:func:`refine_to`). The split leaves hanging vertices, which a
collocation scheme with constant elements does not mind: the triangles still tile the surface
exactly, without gaps or overlaps.
"""

from __future__ import annotations

import numpy as np

__all__ = ["coarsen", "refine_to", "level_mesh"]
#: the grid cells :func:`level_mesh` tries for :func:`coarsen`, in units of the level's
#: element edge ``h``, until one keeps the surface's area: a cell of ``h`` gives triangles of
#: about ``h``; a cell of ``h / 2`` alone (before, and still the ``high`` radiation setting's
#: choice) gave the 10 cm bowl 712 elements at ``h = 4.7 cm``, where equilateral triangles of
#: that edge would be 128 (now 253), and each solve several times the cost (the level
#: objects' errors: reports/accuracy.md)
COARSEN_CELLS = (1.0, 0.5)


def coarsen(vertices, faces, vertex_normals, cell: float):
    """Vertex clustering: vertices in the same grid cell of side ``cell`` [m] whose normals
    point mostly along the same signed axis merge into their mean; collapsed triangles,
    duplicates and folded pairs (the same three vertices both ways round) go.

    Returns
    -------
    vertices : (v', 3), faces : (f', 3)
    """
    v = np.asarray(vertices, float)
    f = np.asarray(faces, np.int64)
    nrm = np.asarray(vertex_normals, float)
    axis = np.argmax(np.abs(nrm), axis=1)
    bucket = 2 * axis + (nrm[np.arange(len(v)), axis] < 0)
    cellidx = np.floor((v - v.min(axis=0)) / cell).astype(np.int64)
    key = np.c_[cellidx, bucket]
    _, cluster, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    cluster = cluster.reshape(-1)
    nv = np.zeros((len(counts), 3))
    np.add.at(nv, cluster, v)
    nv /= counts[:, None]
    nf = cluster[f]
    ok = (nf[:, 0] != nf[:, 1]) & (nf[:, 1] != nf[:, 2]) & (nf[:, 0] != nf[:, 2])
    nf = nf[ok]
    srt = np.sort(nf, axis=1)
    # orientation: +1 for an even permutation of the sorted triple, -1 for an odd one
    inversions = (nf[:, 0] > nf[:, 1]).astype(int) + (nf[:, 0] > nf[:, 2]) + (nf[:, 1] > nf[:, 2])
    sign = np.where(inversions % 2 == 0, 1, -1)
    uniq, inv = np.unique(srt, axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    net = np.zeros(len(uniq), np.int64)
    np.add.at(net, inv, sign)
    keep = np.zeros(len(nf), bool)
    first = np.full(len(uniq), -1)
    for i in range(len(nf)):  # one face per distinct triple whose orientations do not cancel
        u = inv[i]
        if net[u] != 0 and first[u] < 0 and np.sign(net[u]) == sign[i]:
            first[u] = i
            keep[i] = True
    used, fr = np.unique(nf[keep], return_inverse=True)
    return nv[used], fr.reshape(-1, 3)


def refine_to(vertices, faces, h: float):
    """Split triangles until every edge is at most about ``h`` [m].

    A triangle whose longest edge ``L`` exceeds ``1.3 h`` is cut into ``m = ceil(L / h)``:
    into ``m^2`` triangles like itself when it is well shaped (shortest edge over half the
    longest), else (a sliver, such as a thin plate's rim, or a bar's long face) into ``2 m - 1``
    strips across its two long edges, so that a 2 mm rim under 2 cm elements becomes ``L / h``
    pieces, not ``(L / h)^2``; strips still too wide are cut again.

    Returns
    -------
    vertices : (v', 3), faces : (f', 3); children keep their parent's orientation.
    """
    tri = np.asarray(vertices, float)[np.asarray(faces, np.int64)]
    for _ in range(8):
        tri, more = _refine_once(tri, h)
        if not more:
            break
    return tri.reshape(-1, 3), np.arange(3 * len(tri)).reshape(-1, 3)


def _refine_once(tri, h):
    out = []
    more = False
    for t in tri:
        le = np.linalg.norm(t[[1, 2, 0]] - t, axis=1)  # edge a: corner a -> a+1
        if le.max() <= 1.3 * h:
            out.append(t[None])
            continue
        more = True
        m = int(np.ceil(le.max() / h - 1e-9))
        if le.min() > 0.5 * le.max():
            # m^2 similar children on the barycentric grid
            idx = [(i, j) for i in range(m + 1) for j in range(m + 1 - i)]
            pos = {ij: (t[0] * (m - ij[0] - ij[1]) + t[1] * ij[0] + t[2] * ij[1]) / m for ij in idx}
            kids = []
            for i in range(m):
                for j in range(m - i):
                    kids.append([pos[(i, j)], pos[(i + 1, j)], pos[(i, j + 1)]])
                    if i + j < m - 1:
                        kids.append([pos[(i + 1, j)], pos[(i + 1, j + 1)], pos[(i, j + 1)]])
            out.append(np.array(kids))
            continue
        # sliver: the short edge is a -> a+1; the apex c = a+2 joins the two long edges
        a = int(np.argmin(le))
        p, q, c = t[a], t[(a + 1) % 3], t[(a + 2) % 3]
        s = np.linspace(0.0, 1.0, m + 1)[:, None]
        P = c + s * (p - c)  # along c -> p
        Q = c + s * (q - c)  # along c -> q
        kids = [[c, P[1], Q[1]]]  # orientation of (p, q, c) kept: (c, p, q) is the same cycle
        for i in range(1, m):
            kids.append([P[i], P[i + 1], Q[i + 1]])
            kids.append([P[i], Q[i + 1], Q[i]])
        out.append(np.array(kids))
    return np.concatenate(out), more


def level_mesh(tm, h: float, cells=COARSEN_CELLS):
    """The outer surface ``tm`` (trimesh, closed) as boundary elements of edge at most ``h``:
    coarsened first where most of its triangles are narrower than ``h / 3`` (their shortest
    edge), on the first grid of ``cells`` (units of ``h``, :data:`COARSEN_CELLS`) that keeps
    its area. Returns ``(vertices, faces)``."""
    v, f = np.asarray(tm.vertices, float), np.asarray(tm.faces, np.int64)
    shortest = np.linalg.norm(v[f[:, [1, 2, 0]]] - v[f], axis=2).min(axis=1)
    if np.median(shortest) < h / 3:
        for cell in cells:  # the coarsest grid that keeps the area, else the surface as given
            cv, cf = coarsen(v, f, tm.vertex_normals, cell * h)
            area = 0.5 * np.linalg.norm(np.cross(cv[cf[:, 1]] - cv[cf[:, 0]], cv[cf[:, 2]] - cv[cf[:, 0]]),
                                        axis=1).sum()
            if len(cf) >= 8 and abs(area / tm.area - 1) < 0.1:
                v, f = cv, cf
                break
    return refine_to(v, f, h)


def sealed(tm, tol: float = 1e-3) -> bool:
    """Whether the surface bounds a volume for the exterior problem: closed, or open only
    along seams (every boundary vertex within ``tol`` of the object's size of a boundary edge
    it is not on, as where a lid's ring meets a body's with vertices that do not coincide),
    with consistent winding and the normals outwards."""
    if not tm.is_winding_consistent or not tm.volume > 0:
        return False
    if tm.is_watertight:
        return True
    e = np.asarray(tm.edges_sorted)
    u, c = np.unique(e, axis=0, return_counts=True)
    b = u[c == 1]
    if len(b) == 0 or (c > 2).any():
        return False
    v = np.asarray(tm.vertices, float)
    a, d = v[b[:, 0]], v[b[:, 1]] - v[b[:, 0]]
    pts = np.unique(b.reshape(-1))
    x = v[pts]
    # distance of each boundary vertex to each boundary segment, excluding the segments it ends
    s = np.clip(np.einsum("pec,ec->pe", x[:, None, :] - a[None], d) / np.einsum("ec,ec->e", d, d), 0.0, 1.0)
    dist = np.linalg.norm(x[:, None, :] - (a[None] + s[..., None] * d[None]), axis=2)
    dist[(b[None, :, 0] == pts[:, None]) | (b[None, :, 1] == pts[:, None])] = np.inf
    return bool(dist.min(axis=1).max() <= tol * float(np.max(tm.extents)))
