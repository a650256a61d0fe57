"""Sounding objects of a MuJoCo model: which geoms vibrate together, and what surface each is.

A sounding *object* is, by default, the collision geoms of one rigid body that share a
material: real assets build one body from several geoms (convex decompositions, a table top
and its legs, a mug as 16 hulls), and the body rings as one piece. Its surface is the union
of those geoms' surfaces (the voxel method fills overlaps and unions by the winding rule),
expressed in the frame of one **anchor** geom of the body: all geoms of a body move
rigidly, so the synthesizer follows the anchor's pose and every geom of the object excites
it at the world contact point.

With ``objects="geom"`` every geom is its own object (the anchor is the geom itself). Geoms
of the world body (static scenery: floors, walls, bins built of boxes) are always separate
objects: they are not one piece of material.

A body's sound surface can be named instead of its collision geoms (collision geoms are often
hulls or primitives while the visual mesh has the real shape): ``sound_meshes={BODY: NAME}``
in Python, or ``<custom><text name="mjsound-mesh:BODY" data="NAME"/></custom>`` in MJCF, where
NAME is a geom of the model (typically the body's visual geom, ``contype="0"``), a mesh asset
used by a geom of that body, or (Python only) a mesh file / built-in spec / ``(V, F)`` in the
body frame [m].

Frames: ``model.geom_pos`` / ``geom_quat`` place a geom in its body; a point ``x_g`` of geom
``g`` is ``x_b = R_g x_g + p_g`` in the body frame and ``x_a = R_a^T (x_b - p_a)`` in the
anchor's frame.
"""

from __future__ import annotations

import difflib
import hashlib
import os
from functools import partial

import numpy as np

__all__ = ["group_objects", "object_surface", "object_recipe", "object_mesh", "geom_pose_in_body", "close_names", "solid_mode_count", "geom_name",
           "geom_mesh_spec", "plan_object", "checked_mapping", "checked_names", "custom_texts"]


def _mujoco():
    import mujoco

    return mujoco


def close_names(key: str, names, n: int = 3) -> str:
    """``"; closest: 'a', 'b'"`` (difflib), or ``""`` when nothing is close."""
    near = difflib.get_close_matches(str(key), [str(x) for x in names], n=n, cutoff=0.5)
    return f"; closest: {', '.join(repr(x) for x in near)}" if near else ""


def geom_pose_in_body(model, g: int) -> tuple[np.ndarray, np.ndarray]:
    """``(p, R)``: geom ``g``'s position (3,) [m] and rotation (3, 3) in its body's frame."""
    mujoco = _mujoco()
    R = np.empty(9)
    mujoco.mju_quat2Mat(R, np.asarray(model.geom_quat[g], np.float64))
    return np.array(model.geom_pos[g], np.float64), R.reshape(3, 3)


def group_objects(model, geoms, materials, objects: str = "body") -> list[list[int]]:
    """Sounding geoms grouped into objects (each list in geom order, its anchor first).

    Parameters
    ----------
    model : mujoco.MjModel
    geoms : list[int]
        Geoms that sound (collide, have a material, are not planes).
    materials : list[Material]
        Material of every geom of the model (indexed by geom id).
    objects : {"body", "geom"}
        ``"body"``: the geoms of one body with one material form one object (the world body's
        geoms stay separate); ``"geom"``: one object per geom.
    """
    if objects not in ("body", "geom"):
        raise ValueError(f"objects={objects!r}: choose 'body' (a body's collision geoms ring as one) or 'geom'")
    groups: dict = {}
    for g in geoms:
        b = int(model.geom_bodyid[g])
        key = (b, materials[g].key()) if objects == "body" and b != 0 else ("geom", g)
        groups.setdefault(key, []).append(int(g))
    return list(groups.values())


def _geom_surface(model, g: int):
    """``(V, F)`` of geom ``g`` in its own frame [m] (primitives triangulated)."""
    from ..geometry import load_mesh
    spec, _ = geom_mesh_spec(model, g)
    tm = load_mesh(spec, check_size=False)
    return np.asarray(tm.vertices, np.float64), np.asarray(tm.faces, np.int64)


#: Each part of a union is shrunk by this fraction of its size about its centre (see _in_anchor).
PART_GAP = 1e-6


def _in_anchor(model, anchor: int, parts) -> tuple[np.ndarray, np.ndarray]:
    """Concatenate ``[(V_body, F)]`` given in the body frame into the anchor geom's frame.

    Parts that touch (a table top on its legs, two boxes side by side) share vertices and
    faces; welded by position (:func:`mjsound.geometry.load_mesh`) they would become one
    non-manifold surface, which the voxelizer takes for an open shell (a 2-box union then
    weighs 58 % of the solid). So several parts are kept apart: each is shrunk about its
    centre by ``PART_GAP`` of its size (1e-7 m on a 10 cm part, far above the 1e-8 m weld
    tolerance and far below any voxel); each stays closed and the winding-rule fill takes
    their union, overlaps included.
    """
    pa, Ra = geom_pose_in_body(model, anchor)
    vs, fs, off = [], [], 0
    for V, F in parts:
        V = np.asarray(V, np.float64)
        if len(parts) > 1:
            c = 0.5 * (V.min(axis=0) + V.max(axis=0))
            V = c + (V - c) * (1.0 - PART_GAP)
        vs.append((V - pa) @ Ra)  # R_a^T (x_b - p_a), row vectors
        fs.append(np.asarray(F, np.int64) + off)
        off += len(V)
    return np.vstack(vs), np.vstack(fs)


def _named_surface(model, body: int, name, anchor: int):
    """A user-named sound surface of ``body`` (module docstring) in the body frame, and its label."""
    mujoco = _mujoco()
    from ..geometry import load_mesh

    if isinstance(name, (tuple, list)) and len(name) == 2:
        tm = load_mesh(name)
        return (np.asarray(tm.vertices), np.asarray(tm.faces)), "given mesh"
    text = os.fspath(name)
    g = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, text)
    if g < 0:
        mid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_MESH, text)
        if mid >= 0:
            users = [h for h in range(model.ngeom) if model.geom_dataid[h] == mid
                     and int(model.geom_type[h]) == mujoco.mjtGeom.mjGEOM_MESH and model.geom_bodyid[h] == body]
            if not users:
                bname = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, body)
                raise ValueError(f"sound mesh {text!r} of body {bname!r}: no geom of that body uses this mesh asset, "
                                 "so its pose is unknown; name a geom of the body instead, or give (V, F) in the "
                                 "body frame")
            g = users[0]
    if g >= 0:
        if int(model.geom_bodyid[g]) != body:
            bname = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, body)
            raise ValueError(f"sound mesh {text!r}: geom {text!r} is not on body {bname!r}; name one of its geoms")
        V, F = _geom_surface(model, g)
        p, R = geom_pose_in_body(model, g)
        return (V @ R.T + p, F), f"geom {text}"
    try:
        tm = load_mesh(text)
    except ValueError as exc:
        names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, h) for h in range(model.ngeom)]
        names += [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_MESH, m) for m in range(model.nmesh)]
        raise ValueError(f"sound mesh {text!r}: not a geom, mesh asset, file or built-in shape of this model "
                         f"({exc}){close_names(text, [x for x in names if x])}") from None
    return (np.asarray(tm.vertices), np.asarray(tm.faces)), text


def object_surface(model, members: list[int], sound_mesh=None):
    """What to analyse for an object: ``(mesh, label)`` for :func:`mjsound.modal.analyze.analyze`.

    One geom and no ``sound_mesh``: the geom's own spec (a built-in shape string or its mesh
    arrays, in the geom frame). Otherwise ``(V, F)`` in the anchor's (``members[0]``) frame: the
    union of the members' surfaces, or ``sound_mesh`` (module docstring).
    """
    anchor = members[0]
    body = int(model.geom_bodyid[anchor])
    if sound_mesh is not None:
        part, label = _named_surface(model, body, sound_mesh, anchor)
        return _in_anchor(model, anchor, [part]), f"sound mesh: {label}"
    if len(members) == 1:
        return geom_mesh_spec(model, anchor)
    parts = []
    for g in members:
        V, F = _geom_surface(model, g)
        p, R = geom_pose_in_body(model, g)
        parts.append((V @ R.T + p, F))
    V, F = _in_anchor(model, anchor, parts)
    return (V, F), f"union of {len(members)} geoms ({len(V)} vertices)"


def solid_mode_count(volume_m3: float, material, f_max: float) -> float:
    """Weyl's estimate of a solid's elastic modes below ``f_max`` [Hz]:
    ``N ~ (4 pi / 3) V f^3 (1 / c_L^3 + 2 / c_T^3)``, ``c_T = sqrt(G / rho)``,
    ``c_L = c_T sqrt(2 (1 - nu) / (1 - 2 nu))`` (a free surface adds about as many again at
    low counts; the caller allows for that)."""
    cT = np.sqrt(material.shear_modulus / material.rho)
    nu = material.nu
    cL = cT * np.sqrt(2 * (1 - nu) / (1 - 2 * nu))
    return float(4 * np.pi / 3 * volume_m3 * f_max**3 * (1 / cL**3 + 2 / cT**3))


def geom_name(model, g: int) -> str:
    """The geom's name, or ``geom<ID>`` when it has none."""
    mujoco = _mujoco()
    return mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, int(g)) or f"geom{int(g)}"


def custom_materials(model) -> dict:
    """``{geom_name: material text}`` from custom texts named ``mjsound:GEOMNAME``."""
    return custom_texts(model, "mjsound:")


def geom_mesh_spec(model, g: int):
    """What to analyse for geom ``g``: a built-in spec or ``(vertices, faces)`` in the geom frame.

    Returns
    -------
    (mesh, label) : (str | tuple[np.ndarray, np.ndarray], str)
        ``mesh`` for :func:`analyze`; ``label`` a short description.

    Raises
    ------
    ValueError
        For planes, height fields and SDFs.
    """
    mujoco = _mujoco()
    T = mujoco.mjtGeom
    t = int(model.geom_type[g])
    s = np.asarray(model.geom_size[g], dtype=np.float64)
    fmt = lambda *v: ",".join(f"{x:.6g}" for x in v)  # noqa: E731
    if t == T.mjGEOM_SPHERE:
        spec = f"sphere:{fmt(s[0])}"
        return spec, spec
    if t == T.mjGEOM_BOX:
        spec = f"box:{fmt(*(2 * s))}"
        return spec, spec
    if t == T.mjGEOM_CYLINDER:
        spec = f"cylinder:{fmt(s[0], 2 * s[1])}"
        return spec, spec
    if t == T.mjGEOM_CAPSULE:
        spec = f"capsule:{fmt(s[0], 2 * s[1])}"
        return spec, spec
    if t == T.mjGEOM_ELLIPSOID:
        import trimesh

        sph = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
        return (np.asarray(sph.vertices) * s[None, :], np.asarray(sph.faces)), f"ellipsoid:{fmt(*s)}"
    if t == T.mjGEOM_MESH:
        mid = int(model.geom_dataid[g])
        va, vn = int(model.mesh_vertadr[mid]), int(model.mesh_vertnum[mid])
        fa, fn = int(model.mesh_faceadr[mid]), int(model.mesh_facenum[mid])
        v = np.array(model.mesh_vert[va : va + vn], dtype=np.float64)
        f = np.array(model.mesh_face[fa : fa + fn], dtype=np.int64)
        mname = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_MESH, mid) or str(mid)
        return (v, f), f"mesh:{mname} ({vn} vertices)"
    raise ValueError(f"geom {geom_name(model, g)!r}: type {t} has no mesh to analyse")


def checked_names(model) -> set:
    """Names a mapping may use: geom names and fallback names ``geom<ID>``, body names."""
    mujoco = _mujoco()
    valid = {geom_name(model, g) for g in range(model.ngeom)}
    valid |= {mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) or "" for b in range(model.nbody)}
    valid.discard("")
    return valid


def checked_mapping(model, mapping, what: str, allow_star: bool) -> dict:
    """``mapping`` with every key checked against the model's geoms and bodies.

    Keys: geom names, fallback names ``geom<ID>``, geom ids (int), body names (and ``"*"``
    when ``allow_star``). An unknown key raises ``ValueError`` with the closest names."""
    mapping = dict(mapping or {})
    valid = checked_names(model)
    if allow_star:
        valid.add("*")
    for key in mapping:
        if isinstance(key, (int, np.integer)) and not isinstance(key, bool):
            if not 0 <= int(key) < model.ngeom:
                raise ValueError(f"{what}: geom id {key} out of range (the model has {model.ngeom} geoms)")
            continue
        if key not in valid:
            raise ValueError(
                f"{what}: no geom or body named {key!r}{close_names(str(key), sorted(valid))}. Keys are geom names "
                "(unnamed geoms: 'geom<ID>' as the report prints them, or the id), body names"
                + (", or '*' for every geom without a material" if allow_star else "")
            )
    return {(int(k) if isinstance(k, np.integer) else k): v for k, v in mapping.items()}


def custom_texts(model, prefix: str) -> dict:
    """``{NAME: text}`` of the MJCF custom texts named ``PREFIX + NAME``."""
    mujoco = _mujoco()
    out = {}
    for t in range(model.ntext):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_TEXT, t) or ""
        if not name.startswith(prefix):
            continue
        adr, size = int(model.text_adr[t]), int(model.text_size[t])
        raw = bytes(model.text_data[adr : adr + size - 1])
        out[name[len(prefix) :]] = raw.decode("utf-8", "replace").strip()
    return out


def plan_object(model, members, sound_meshes, material, source, alone: bool = False) -> dict:
    """Name, surface and label of one object (:mod:`mjsound.sim.objects`).

    The name: the body's for several geoms; for one geom, the geom's name, or, when the geom is
    unnamed and the only object of a named body (Fetch's table: an unnamed box in ``table0``),
    the body's; else MuJoCo's fallback ``geom<ID>``."""
    mujoco = _mujoco()
    anchor = members[0]
    body = int(model.geom_bodyid[anchor])
    bname = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, body) or f"body{body}"
    name = geom_name(model, anchor) if len(members) == 1 else bname
    named_body = body != 0 and mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, body)
    if len(members) == 1 and alone and named_body and not mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, anchor):
        name = bname
    override = key_used = None
    for key in (geom_name(model, anchor), anchor, bname):
        if key in sound_meshes:
            override, key_used = sound_meshes[key], key
            break
    if override is not None and body == 0:
        raise ValueError(f"sound mesh for {name!r}: the world body's geoms are separate objects; name the geom")
    if override is None and len(members) > 1:
        # (a union is built only when it is analysed: building it loads trimesh, a cached model does not need it)
        mesh, label = None, f"union of {len(members)} geoms"
    else:
        mesh, label = object_surface(model, members, override)
    return {"name": name, "members": list(members), "material": material, "source": source, "mesh": mesh,
            "label": label, "sound_mesh": override, "body": bname, "sound_key": key_used,
            "recipe": object_recipe(model, members, mesh if override is not None else None),
            "build": partial(object_surface, model, members, override)}


def object_mesh(plan: dict):
    """The surface to analyse of a :func:`plan_object` plan (built now if it was deferred; its
    label then gets the vertex count)."""
    if plan["mesh"] is None:
        plan["mesh"], plan["label"] = plan["build"]()
    return plan["mesh"]


def object_recipe(model, members: list[int], surface=None) -> str:
    """A digest of everything an object's surface is made from, without building it.

    ``surface`` (a named sound mesh, already built): its spec or vertex and face bytes. Otherwise
    every member's type, size and mesh data, and for a union (several members) each member's
    pose in the body, which places it in the anchor's frame. One geom's pose does not change its
    surface (given in its own frame), so identical geoms (four legs) share a recipe.
    """
    h = hashlib.sha256()
    if surface is not None:
        parts = [surface] if isinstance(surface, str) else list(surface)
        for x in parts:
            h.update(x.encode() if isinstance(x, str) else np.ascontiguousarray(x, np.float64).tobytes())
        return h.hexdigest()[:32]
    for g in members:
        h.update(np.array([model.geom_type[g]], np.int64).tobytes())
        h.update(np.asarray(model.geom_size[g], np.float64).tobytes())
        if len(members) > 1:
            h.update(np.asarray(model.geom_pos[g], np.float64).tobytes())
            h.update(np.asarray(model.geom_quat[g], np.float64).tobytes())
        mid = int(model.geom_dataid[g])
        if int(model.geom_type[g]) == _mujoco().mjtGeom.mjGEOM_MESH and mid >= 0:
            va, vn = int(model.mesh_vertadr[mid]), int(model.mesh_vertnum[mid])
            fa, fn = int(model.mesh_faceadr[mid]), int(model.mesh_facenum[mid])
            h.update(np.ascontiguousarray(model.mesh_vert[va:va + vn], np.float64).tobytes())
            h.update(np.ascontiguousarray(model.mesh_face[fa:fa + fn], np.int64).tobytes())
    return h.hexdigest()[:32]


def unique_names(plans) -> None:
    """Make object names unique (a body named like another object's geom gets ``#body``)."""
    seen: dict = {}
    for p in plans:
        n = p["name"]
        if n in seen:
            p["name"] = f"{n}#{p['body']}" if f"{n}#{p['body']}" not in seen else f"{n}#{p['members'][0]}"
        seen[p["name"]] = True
