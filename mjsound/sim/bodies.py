"""What a MuJoCo body is made of, as the sound sees it: its geoms' volumes and surfaces, the
extent of its geoms about its centre of mass, and the mass that really moves with it.

* :func:`geom_volume_area`: a geom's volume and surface as MuJoCo weighs it (its density times
  this volume is its share of the body's mass).
* :func:`geom_shape_axes`: the ellipsoid of a body's geoms' own shape along its principal axes:
  a bound on the size of what radiates for the body (:mod:`.clicks` bounds the equivalent
  ellipsoid of the inertia with it: an inertia in an MJCF file is often a guess, ten to a
  thousand times a small link's own).
* :func:`moving_tree_mass`: per body, the mass of the part of its kinematic tree that moves
  (nothing welded to the world): the most an impact on the body can ever push against.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["geom_volume_area", "geom_shape_axes", "moving_tree_mass", "ellipsoid_area"]


def ellipsoid_area(a, b, c) -> float:
    """Surface of the ellipsoid of semi-axes ``a, b, c`` [m^2] (Thomsen's formula, within
    1.1 %)."""
    p = 1.6075
    ap, bp, cp = a**p, b**p, c**p
    return 4.0 * math.pi * ((ap * bp + ap * cp + bp * cp) / 3.0) ** (1.0 / p)


def geom_volume_area(model, g: int) -> tuple[float, float] | None:
    """Volume [m^3] and surface [m^2] of geom ``g`` as MuJoCo weighs it (``geom_size``:
    sphere, capsule, ellipsoid, cylinder, box; a mesh from its triangles, the divergence
    theorem's signed tetrahedra), or None for a plane, height field or other shape without a
    closed volume (and a mesh whose volume is not positive)."""
    t = int(model.geom_type[g])
    s = np.asarray(model.geom_size[g], dtype=np.float64)
    if t == 2:  # sphere
        r = s[0]
        return 4.0 / 3.0 * math.pi * r**3, 4.0 * math.pi * r * r
    if t == 3:  # capsule: radius, half-length of the cylinder
        r, h = s[0], s[1]
        return math.pi * r * r * (2.0 * h + 4.0 / 3.0 * r), 2.0 * math.pi * r * (2.0 * h + 2.0 * r)
    if t == 4:  # ellipsoid: semi-axes
        return 4.0 / 3.0 * math.pi * s[0] * s[1] * s[2], ellipsoid_area(s[0], s[1], s[2])
    if t == 5:  # cylinder: radius, half-height
        r, h = s[0], s[1]
        return 2.0 * math.pi * r * r * h, 2.0 * math.pi * r * (2.0 * h + r)
    if t == 6:  # box: half-sizes
        return 8.0 * s[0] * s[1] * s[2], 8.0 * (s[0] * s[1] + s[1] * s[2] + s[0] * s[2])
    if t == 7 and model.geom_dataid[g] >= 0:  # mesh
        k = int(model.geom_dataid[g])
        v0, nv = int(model.mesh_vertadr[k]), int(model.mesh_vertnum[k])
        f0, nf = int(model.mesh_faceadr[k]), int(model.mesh_facenum[k])
        vert = np.asarray(model.mesh_vert[v0:v0 + nv], dtype=np.float64)
        face = np.asarray(model.mesh_face[f0:f0 + nf], dtype=np.int64)
        if not (nv and nf) or face.min() < 0 or face.max() >= nv:
            return None
        a, b, c = vert[face[:, 0]], vert[face[:, 1]], vert[face[:, 2]]
        vol = abs(float(np.einsum("ij,ij->", a, np.cross(b, c)))) / 6.0
        area = 0.5 * float(np.linalg.norm(np.cross(b - a, c - a), axis=1).sum())
        return (vol, area) if vol > 0 and area > 0 else None
    return None


def quat_mat(q) -> np.ndarray:
    """Rotation matrix of the unit quaternion ``(w, x, y, z)``."""
    w, x, y, z = (float(v) for v in q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def geom_shape_axes(model, b: int) -> np.ndarray | None:
    """Semi-axes [m] along body ``b``'s principal axes of inertia of the uniform solid ellipsoid
    with the second moments of the body's geoms, (3,): the size of the body's own shape.

    Each geom counts as its bounding box (MuJoCo's ``geom_aabb`` in the geom's frame: centre
    ``c_g``, half sizes ``h_g``, rotation ``R_g`` into the body frame) filled uniformly, weighed
    by its volume ``V_g``; about their centroid ``C`` the boxes' covariance is

        S = sum_g V_g (R_g diag(h_g^2 / 3) R_g^T + (c_g - C)(c_g - C)^T) / sum_g V_g

    and a uniform solid ellipsoid's is ``diag(a_i^2 / 5)``, so ``a_i = sqrt(5 e_i^T S e_i)``
    along each principal axis ``e_i`` (``body_iquat``). A cube gets its own inertia's sphere
    (``sqrt(5/3)`` its half side), a capsule a little more than itself, two spheres on a rod
    the long ellipsoid of the pair. Every geom counts, visual ones included (the shape a body is
    drawn with is its size as well as the one it collides with); planes and height fields do
    not. None for a body without such a geom.
    """
    m = model
    geoms = [g for g in np.flatnonzero(np.asarray(m.geom_bodyid) == b).tolist()
             if int(m.geom_type[g]) not in (0, 1)]  # mjGEOM_PLANE, mjGEOM_HFIELD
    if not geoms:
        return None
    aabb = np.asarray(m.geom_aabb, dtype=np.float64).reshape(-1, 6)
    R_i = quat_mat(m.body_iquat[b])
    vols, centres, covs = [], [], []
    for g in geoms:
        Rg = quat_mat(m.geom_quat[g])
        h = np.abs(aabb[g, 3:])
        vols.append(max(8.0 * h[0] * h[1] * h[2], 1e-30))
        centres.append(Rg @ aabb[g, :3] + np.asarray(m.geom_pos[g], dtype=np.float64))
        covs.append(Rg @ np.diag(h * h / 3.0) @ Rg.T)
    w = np.array(vols) / sum(vols)
    centres = np.array(centres)
    C = w @ centres
    d = centres - C
    S = np.einsum("g,gij->ij", w, np.array(covs)) + np.einsum("g,gi,gj->ij", w, d, d)
    return np.sqrt(5.0 * np.maximum(np.einsum("ji,jk,ki->i", R_i, S, R_i), 0.0))


def moving_tree_mass(model) -> np.ndarray:
    """(nbody,) mass [kg] of the moving part of each body's kinematic tree; inf for a body
    welded to the world (``body_weldid == 0``, the world itself included) or to a mocap body
    (which the user moves, whatever pushes on it).

    A body's moving tree hangs from its highest ancestor that is not welded to the world (a
    fixed-base arm's first link: the base, its mount and the pedestal do not count, though
    MuJoCo's ``body_subtreemass`` of the world's child holds them); its mass is that ancestor's
    ``body_subtreemass``. No impact on the body can push against more: the impulse of an impact
    is at most ``(1 + e) v`` times it (:func:`.impulses.impulse_kernel`).
    """
    m = model
    weld = np.asarray(m.body_weldid)
    parent = np.asarray(m.body_parentid)
    subtree = np.asarray(m.body_subtreemass, dtype=np.float64)
    # immovable: welded to the world or to a mocap body (moved by the user, whatever pushes)
    still = (weld == 0) | (np.asarray(m.body_mocapid)[weld] >= 0)
    top = np.full(m.nbody, -1, np.int64)
    for b in range(1, m.nbody):  # (a parent's id is below its children's)
        if still[b]:
            continue
        top[b] = b if still[parent[b]] else top[parent[b]]
    return np.where(top >= 0, subtree[np.maximum(top, 0)], np.inf)
