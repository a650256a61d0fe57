"""Surface meshes: load, build the built-in shapes, check and clean.

Everything is in metres, in the object's own frame. :func:`load_mesh` accepts

* a path to an OBJ/STL/PLY/OFF/GLB file (read with trimesh),
* a built-in shape spec: ``box:LX,LY,LZ``, ``cylinder:RADIUS,LENGTH`` (axis z),
  ``sphere:RADIUS``, ``bowl:RADIUS,THICKNESS`` (open hemispherical bowl, rim up),
  ``capsule:RADIUS,LENGTH``,
* a ``(vertices, faces)`` pair or a ``trimesh.Trimesh``.

and returns a cleaned :class:`trimesh.Trimesh` or raises a ``ValueError`` that names the problem.

Cleaning keeps a surface what it is:

* vertices are welded by position only: texture seams and split normals (an OBJ's ``vt`` /
  ``vn``, which make a textured cube 24 vertices and 12 separate quads) do not cut a closed
  surface into open pieces;
* duplicate faces go; zero-area faces go only when that does not open a closed surface (a
  sliver face on a T-junction is part of what closes it, and a closed surface that turned
  open would be analysed as a hollow shell).

:func:`surface_report` says whether a mesh is closed (and so analysed as a solid) or open
(analysed as a wall of a given thickness).
"""

from __future__ import annotations

import hashlib
import os
import warnings

import numpy as np
import trimesh

from .user_frame import user_stacklevel

__all__ = ["load_mesh", "builtin_mesh", "mesh_digest", "surface_report", "BUILTIN_SHAPES"]

BUILTIN_SHAPES = {
    "box": "box:LX,LY,LZ (full side lengths, m)",
    "cylinder": "cylinder:RADIUS,LENGTH (axis z, m)",
    "sphere": "sphere:RADIUS (m)",
    "capsule": "capsule:RADIUS,LENGTH (cylinder part length, axis z, m)",
    "bowl": "bowl:RADIUS,THICKNESS (hemispherical bowl, opening up, m)",
}

#: Objects larger than this (longest side, m) are probably in millimetres.
IMPLAUSIBLE_SIZE_M = 20.0


def _bowl(radius: float, thickness: float, sections: int = 48) -> trimesh.Trimesh:
    """A closed hemispherical bowl: outer radius ``radius``, wall ``thickness``, rim at z=0."""
    if not 0 < thickness < radius:
        raise ValueError(f"bowl: need 0 < THICKNESS < RADIUS, got {radius}, {thickness}")
    # Profile in (r, z): outer arc from the rim down to the pole, inner arc back up.
    n = sections // 2
    th = np.linspace(0.5 * np.pi, np.pi, n + 1)  # polar angle from +z
    ri = radius - thickness
    outer = np.c_[radius * np.sin(th), radius * np.cos(th)]
    inner = np.c_[ri * np.sin(th[::-1]), ri * np.cos(th[::-1])]
    profile = np.vstack([outer, inner])
    profile[np.abs(profile[:, 0]) < 1e-12, 0] = 0.0
    # Close the profile: from the inner rim to the outer rim (the rim annulus).
    profile = np.vstack([profile, profile[:1]])
    mesh = trimesh.creation.revolve(profile, sections=sections)
    mesh.merge_vertices()
    mesh.update_faces(mesh.nondegenerate_faces())
    mesh.fix_normals()
    return mesh


def builtin_mesh(spec: str) -> trimesh.Trimesh:
    """Build a built-in shape from ``"kind:a,b,..."`` (see :data:`BUILTIN_SHAPES`)."""
    kind, _, args = spec.partition(":")
    kind = kind.strip().lower()
    if kind not in BUILTIN_SHAPES:
        raise ValueError(f"unknown built-in shape {kind!r}; known: {', '.join(BUILTIN_SHAPES.values())}")
    try:
        vals = [float(a) for a in args.split(",") if a.strip()]
    except ValueError:
        raise ValueError(f"built-in shape {spec!r}: arguments must be numbers; {BUILTIN_SHAPES[kind]}") from None
    need = {"box": 3, "cylinder": 2, "sphere": 1, "capsule": 2, "bowl": 2}[kind]
    if len(vals) != need or not all(np.isfinite(vals)) or min(vals) <= 0:
        raise ValueError(f"built-in shape {spec!r}: expected {BUILTIN_SHAPES[kind]}, all positive")
    if kind == "box":
        return trimesh.creation.box(extents=vals)
    if kind == "cylinder":
        sections = int(np.clip(2 * np.pi * vals[0] / (vals[0] * 0.1), 32, 96))
        return trimesh.creation.cylinder(radius=vals[0], height=vals[1], sections=sections)
    if kind == "sphere":
        return trimesh.creation.icosphere(subdivisions=3, radius=vals[0])
    if kind == "capsule":
        return trimesh.creation.capsule(radius=vals[0], height=vals[1], count=[32, 16])
    return _bowl(vals[0], vals[1])


def load_mesh(mesh, *, check_size: bool = True) -> trimesh.Trimesh:
    """Load and clean a surface mesh.

    Parameters
    ----------
    mesh : str | os.PathLike | tuple(vertices (V,3), faces (F,3)) | trimesh.Trimesh
        File path, built-in spec (``box:0.1,0.1,0.1``) or arrays in metres.
    check_size : bool
        Warn when the mesh is implausibly large (probably millimetres).

    Returns
    -------
    trimesh.Trimesh
        Vertices welded by position, no duplicate faces, no zero-area faces unless they
        close the surface (module docstring). No texture or normals are kept.

    Raises
    ------
    ValueError
        Empty mesh, NaN/Inf vertices, out-of-range face indices, nothing left after cleaning.
    """
    if isinstance(mesh, trimesh.Trimesh):
        tm = mesh.copy()
        label = "mesh"
    elif isinstance(mesh, (tuple, list)) and len(mesh) == 2:
        v = np.asarray(mesh[0], dtype=np.float64)
        f = np.asarray(mesh[1])
        label = "vertices/faces"
        if v.ndim != 2 or v.shape[1] != 3 or len(v) == 0:
            raise ValueError(f"{label}: vertices must be a non-empty (V, 3) array, got shape {v.shape}")
        if f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
            raise ValueError(f"{label}: faces must be a non-empty (F, 3) integer array, got shape {f.shape}")
        if not np.isfinite(v).all():
            raise ValueError(f"{label}: {int((~np.isfinite(v)).any(1).sum())} vertices are NaN or Inf; fix the mesh")
        if f.min() < 0 or f.max() >= len(v):
            raise ValueError(f"{label}: face indices must lie in [0, {len(v) - 1}]")
        tm = trimesh.Trimesh(vertices=v, faces=f.astype(np.int64), process=False)
    else:
        spec = os.fspath(mesh)
        label = spec
        if ":" in spec and spec.split(":", 1)[0].lower() in BUILTIN_SHAPES and not os.path.exists(spec):
            tm = builtin_mesh(spec)
        else:
            if not os.path.exists(spec):
                raise ValueError(
                    f"mesh {spec!r}: no such file, and not a built-in shape ({', '.join(BUILTIN_SHAPES.values())})"
                )
            try:
                loaded = trimesh.load(spec, force="mesh", process=False)
            except Exception as exc:  # trimesh raises many types
                raise ValueError(f"mesh {spec!r}: could not be read ({exc})") from exc
            if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
                raise ValueError(f"mesh {spec!r}: contains no triangles")
            tm = loaded
    if len(tm.vertices) == 0 or len(tm.faces) == 0:
        raise ValueError(f"{label}: empty mesh (no vertices or faces)")
    if not np.isfinite(tm.vertices).all():
        raise ValueError(f"{label}: vertices contain NaN or Inf; fix the mesh")
    tm = _welded(tm)
    unique = tm.unique_faces()
    keep = tm.nondegenerate_faces(height=1e-12 * max(tm.scale, 1e-300)) & unique
    if not keep.all():
        closed = tm.is_watertight
        cleaned = tm.copy()
        cleaned.update_faces(keep)
        if closed and not cleaned.is_watertight:
            cleaned = tm.copy()  # zero-area faces close this surface: keep them
            cleaned.update_faces(unique)
        tm = cleaned
    tm.remove_unreferenced_vertices()
    if len(tm.faces) == 0:
        raise ValueError(f"{label}: every face has zero area; nothing to analyse")
    ext = float(np.max(tm.extents))
    if ext <= 0:
        raise ValueError(f"{label}: zero-size mesh")
    if check_size and ext > IMPLAUSIBLE_SIZE_M:
        warnings.warn(
            f"{label}: longest side is {ext:.3g} m; a mesh in millimetres is 1000x too large "
            "(scale it by 0.001). Analysing it as given.",
            stacklevel=user_stacklevel(),
        )
    return tm


def _welded(tm: trimesh.Trimesh) -> trimesh.Trimesh:
    """The geometry of ``tm`` alone (no texture, normals or colours), vertices welded by position
    (trimesh's merge tolerance, 1e-8 m)."""
    out = trimesh.Trimesh(vertices=np.asarray(tm.vertices, np.float64), faces=np.asarray(tm.faces, np.int64),
                          process=False)
    out.merge_vertices(merge_tex=True, merge_norm=True)
    return out


def surface_report(tm: trimesh.Trimesh) -> dict:
    """Whether a cleaned mesh is closed, and how many boundary edges it has.

    Returns
    -------
    dict
        ``closed`` (bool: every edge has exactly two faces, the mesh bounds a volume and is
        analysed as a solid), ``boundary_edges`` (int: edges with one face; an open mesh is
        analysed as a wall, see :func:`mjsound.modal.analyze.analyze`'s ``thickness``),
        ``volume_m3`` (float, NaN when open), ``area_m2``.
    """
    edges = np.sort(np.asarray(tm.edges), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    closed = bool(tm.is_watertight)
    return {
        "closed": closed,
        "boundary_edges": int(np.sum(counts == 1)),
        "volume_m3": float(abs(tm.volume)) if closed else float("nan"),
        "area_m2": float(tm.area),
    }


def mesh_digest(tm: trimesh.Trimesh) -> str:
    """Content hash of a mesh (vertex and face bytes), for cache keys."""
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(tm.vertices, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(tm.faces, dtype=np.int64).tobytes())
    return h.hexdigest()[:32]
