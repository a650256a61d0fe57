"""Which acoustic material each geom of a MuJoCo model has, and which geoms can sound.

:func:`assign_materials` applies the precedence of :mod:`mjsound.sim.scene` (the Python
mapping, an MJCF custom text ``mjsound:GEOM``, the geom's MJCF material named like an
acoustic one, the ``"*"`` default) and says why each silent geom is silent (cannot collide,
no material, a plane or height field). :func:`warn_unknown_texts` flags MJCF custom texts
that name nothing in the model.
"""

from __future__ import annotations

import warnings
from typing import NamedTuple

import numpy as np

from ..materials import Material, get_material, parse_material
from .objects import close_names, geom_name
from ..user_frame import user_stacklevel

__all__ = ["GeomMaterials", "assign_materials", "warn_unknown_texts", "SILENT_WORDS", "CANNOT_COLLIDE", "NO_MATERIAL"]

#: A material value that makes a geom silent (case-insensitive).
SILENT_WORDS = {"none", "silent", "off", ""}
#: why a geom is silent: it never touches anything (a visual geom) / it was given no material
CANNOT_COLLIDE = "cannot collide (contype = conaffinity = 0)"
NO_MATERIAL = "no acoustic material"


class GeomMaterials(NamedTuple):
    """What :func:`assign_materials` found for every geom of a model."""

    materials: list
    """(ngeom,) the acoustic :class:`~mjsound.materials.Material` of each geom, or None."""
    sources: list
    """(ngeom,) where each came from: ``mapping``, ``custom``, ``mjcf-material``, ``default`` or None."""
    silent: dict
    """Geom name -> why it cannot sound."""
    sounding: list
    """Ids of the geoms that can sound (collide, have a material, are not planes), in order."""
    named: set
    """Ids of the sounding geoms whose material the user named (mapping or custom text)."""


def assign_materials(model, materials: dict, custom: dict, star=None) -> GeomMaterials:
    """The acoustic material of every geom of ``model`` and which geoms can sound.

    Parameters
    ----------
    model : mujoco.MjModel
    materials : dict
        The checked mapping (:func:`.objects.checked_mapping`) without its ``"*"`` key: geom
        name, fallback name, id or body name -> material.
    custom : dict
        MJCF custom texts ``mjsound:GEOM`` (:func:`.objects.custom_materials`).
    star : optional
        The ``"*"`` default for every geom that has no material otherwise.

    Returns
    -------
    GeomMaterials
    """
    import mujoco

    pair_geoms = set(np.asarray(model.pair_geom1).tolist()) | set(np.asarray(model.pair_geom2).tolist())
    geom_material, sources, silent, todo = [], [], {}, []
    named = set()  # geoms whose material the user named (mapping or custom text)
    for g in range(model.ngeom):
        gname = geom_name(model, g)
        bname = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, int(model.geom_bodyid[g])) or ""
        mat, source = None, None
        raw_name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g)
        for key in (raw_name, gname, g, bname):
            if key not in ("", None) and key in materials:
                mat, source = materials[key], "mapping"
                break
        if source is None and raw_name and raw_name in custom:
            mat, source = custom[raw_name], "custom"
        if source is None and model.geom_matid[g] >= 0:
            mname = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_MATERIAL, int(model.geom_matid[g])) or ""
            try:
                mat, source = get_material(mname), "mjcf-material"
            except KeyError:
                mat, source = None, None
        if source is None and star is not None:
            mat, source = star, "default"
        if mat is not None and not isinstance(mat, Material):
            if isinstance(mat, str) and mat.strip().lower() in SILENT_WORDS:
                mat = None
            else:
                try:
                    mat = parse_material(mat)
                except (KeyError, ValueError) as exc:
                    raise ValueError(f"geom {gname!r}: bad acoustic material ({source}): {exc}") from exc
        geom_material.append(mat)
        sources.append(source)
        collides = bool(model.geom_contype[g] or model.geom_conaffinity[g] or g in pair_geoms)
        gtype = int(model.geom_type[g])
        if not collides:
            silent[gname] = CANNOT_COLLIDE
        elif mat is None:
            silent[gname] = NO_MATERIAL
        elif gtype == mujoco.mjtGeom.mjGEOM_PLANE:
            silent[gname] = f"plane (never analysed; material {mat.name} used for contacts)"
        elif gtype in (mujoco.mjtGeom.mjGEOM_HFIELD, getattr(mujoco.mjtGeom, "mjGEOM_SDF", -99)):
            silent[gname] = "height field / SDF (not analysed)"
        else:
            todo.append(g)
            if source in ("mapping", "custom"):
                named.add(g)
    return GeomMaterials(geom_material, sources, silent, todo, named)


def warn_unknown_texts(model, texts: dict, prefix: str, *kinds) -> None:
    """Warn about MJCF custom texts ``PREFIX + NAME`` whose NAME is no object of ``kinds`` (a typo
    would do nothing; a text for a geom that a templated scene left out is harmless, so a warning,
    not an error)."""
    import mujoco

    for key in texts:
        if all(mujoco.mj_name2id(model, kind, key) < 0 for kind in kinds):
            names = [mujoco.mj_id2name(model, kind, i) for kind in kinds
                     for i in range({mujoco.mjtObj.mjOBJ_GEOM: model.ngeom, mujoco.mjtObj.mjOBJ_BODY: model.nbody}[kind])]
            warnings.warn(f"mjsound: MJCF custom text '{prefix}{key}' names nothing in this model (it is ignored)"
                          f"{close_names(key, [n for n in names if n])}", UserWarning, stacklevel=user_stacklevel())
