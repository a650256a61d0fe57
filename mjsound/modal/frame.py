r"""The frame an object is analysed in: its principal axes', where they fit it better.

The voxel grid (:mod:`.hex`) is aligned with the coordinate axes. A bar, plate or pin whose
mesh lies at an angle to them crosses its cells obliquely: a round rod at 30 degrees has
its 20 mm section cut by one or two cells and rang +14 .. +17 cents sharp, and its
bounding box (92 mm at the smallest) made ``auto`` take it for a thin wall. Frequencies do
not depend on the frame, so the analysis runs in the frame ``x = Q y + c`` of the box
around the mesh along its principal axes (``Q`` a rotation, columns the axes of the
surface's area-weighted second moment; ``c`` the box's centre) whenever that box holds at
most :data:`ALIGN_VOLUME_RATIO` of the axis-aligned box's volume, and the model's points,
normals and mode shapes are turned back:

.. math:: x_p = Q y_p + c, \qquad n_p = Q n_p^{(y)}, \qquad \phi_i(x_p) = Q \phi_i^{(y)}(y_p).

A mesh already along the axes (or one without a clear orientation: a sphere) is analysed
as given.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import trimesh

__all__ = ["ALIGN_VOLUME_RATIO", "principal_frame", "into_frame", "model_out_of_frame"]

#: analysed along its principal axes when the box along them holds at most this fraction of
#: the axis-aligned box's volume (a square bar turned 45 degrees about its axis: 0.5; the rod
#: at 30 degrees: 0.01)
ALIGN_VOLUME_RATIO = 0.6


def principal_frame(mesh: trimesh.Trimesh):
    """``(Q (3, 3), c (3,))`` of the box around the mesh along its principal axes (the
    eigenvectors of its surface's area-weighted second moment) when that box holds at most
    :data:`ALIGN_VOLUME_RATIO` of the axis-aligned box's volume (module docstring), else
    None. A flat or thin extent counts as 1e-3 of the largest, so that plates compare too."""
    if len(mesh.faces) == 0:
        return None
    w = np.asarray(mesh.area_faces, float)
    if not w.sum() > 0:
        return None
    x = np.asarray(mesh.triangles_center, float)
    x = x - np.average(x, axis=0, weights=w)
    _, Q = np.linalg.eigh((x * w[:, None]).T @ x)
    if np.linalg.det(Q) < 0:  # a reflection would turn the surface inside out
        Q[:, 2] *= -1.0
    y = np.asarray(mesh.vertices, float) @ Q
    lo, hi = y.min(axis=0), y.max(axis=0)
    ext_a = np.asarray(mesh.extents, float)
    eps = 1e-3 * float(ext_a.max())
    if not np.prod(hi - lo + eps) <= ALIGN_VOLUME_RATIO * np.prod(ext_a + eps):
        return None
    return Q, Q @ (0.5 * (lo + hi))


def into_frame(mesh: trimesh.Trimesh, frame) -> trimesh.Trimesh:
    """A copy of ``mesh`` in the frame ``(Q, c)``: ``y = Q^T (x - c)``."""
    Q, c = frame
    out = mesh.copy()
    out.vertices = (np.asarray(mesh.vertices, float) - c) @ Q
    return out


def model_out_of_frame(model, frame):
    """The model with points, normals and shapes turned back from the frame ``(Q, c)``
    (module docstring) and the frame recorded in ``info["analysis_frame"]``."""
    Q, c = frame
    info = dict(model.info)
    info["analysis_frame"] = {"axes": Q.T.tolist(), "centre": c.tolist()}
    shapes = np.einsum("ij,pjn->pin", Q, np.asarray(model.shapes, float))
    extra = {}
    if model.radiation_sh is not None:  # F_model(d) = F_frame(Q^T d): resampled and refitted
        from .sph import degree_of, fit_coefficients, sphere_quadrature

        L = degree_of(model.radiation_sh.shape[1])
        dirs, _ = sphere_quadrature(L)
        extra = dict(radiation_sh=fit_coefficients(L, model.radiation_pattern(dirs @ Q)),
                     radiation_centre=Q @ model.radiation_centre + c)
    return dataclasses.replace(model, points=np.asarray(model.points, float) @ Q.T + c,
                               normals=np.asarray(model.normals, float) @ Q.T, shapes=shapes, info=info, **extra)
