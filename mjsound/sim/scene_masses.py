"""The sound's objects weigh what MuJoCo says (``masses="mujoco"``, the default).

MuJoCo stores body masses, not geom masses: a body's geoms share its mass by volume (its
colliding geoms, or all of them when none collides; :func:`.bodies.geom_volume_area`), so an
object made of geoms ``O`` of body ``b`` weighs ``m = m_b V_O / V_b``. Against a solid of its
material, ``r = m / (rho V_O)``:

* ``|r - 1| <= MASS_TOLERANCE``: the material as it is (``"solid"``);
* lighter, ``r < 1``, with a wall ``t = m / (rho A_O)`` thin enough to be a shell: at most
  :data:`.clicks.SHELL_MAX_WALL_RATIO` of the geoms' radius of curvature ``R`` and of the
  object's thickness ``3 V_O / A_O`` (the rule the clicks' contact time uses,
  :func:`.clicks.shell_compliances`): a hollow wall of thickness ``t`` (the material's ``wall``,
  ``"hollow"``; its contacts last as long as its wall's spring makes them, the clicks' shell
  time), unless that wall is under :data:`HOLLOW_MIN_WALL_RATIO` of ``R``: a foil (gymnasium's
  Ant, ``density="5"``: 65 um of aluminium on 8 cm capsules) has thousands of modes below
  f_max, which no modal analysis resolves, and its solid modes with MuJoCo's mass would ring
  hundreds of times too loud under the sliding and rolling contacts; it keeps the material's
  density (``"foil"``, said in the report; its clicks keep the foil's contact time);
* otherwise, lighter or heavier: density and Young's modulus both scaled by ``r``
  (:meth:`mjsound.materials.Material.scaled`): the wave speeds ``sqrt(E / rho)``, hence the
  frequencies, stay the material's and the modes carry MuJoCo's mass (``"scaled"``).

``masses="material"`` (or the MJCF custom text ``<text name="mjsound-masses" data="material"/>``)
keeps every material's own density (``"kept"``): the report then gives the mass against
MuJoCo's, and a material the user named (a mapping, a custom text or an MJCF material) that
still differs by more than :data:`MASS_TOLERANCE` is warned of. Objects with no MuJoCo mass to
follow (geoms of the world body, a sound mesh given instead of the geoms, a geom without a
volume: plane, height field) keep their material (``"none"``). The modal analysis gets a
material and, for a hollow object, a wall: it never sees MuJoCo.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .bodies import geom_volume_area
from .clicks import SHELL_MAX_WALL_RATIO
from .scene_analysis import MASS_TOLERANCE

__all__ = ["decide_masses", "masses_option", "MASS_TOLERANCE", "HOLLOW_MIN_WALL_RATIO", "MASSES"]

#: Thinnest wall [fraction of the radius of curvature] made a hollow shell; thinner walls (Ant's
#: 65 um aluminium foil on 8 cm capsules, R / t = 1200) keep the material's density.
HOLLOW_MIN_WALL_RATIO = 0.01
#: The values of ``masses=``.
MASSES = ("mujoco", "material")

#: Geom types whose size gives their wall's radius of curvature: sphere, capsule, ellipsoid, cylinder.
_CURVED = (2, 3, 4, 5)


def masses_option(model, masses) -> str:
    """The mass rule in force: ``masses`` when given, else the MJCF custom text
    ``mjsound-masses``, else ``"mujoco"``; an unknown value is an error naming both."""
    if masses is None:
        from .objects import custom_texts

        texts = custom_texts(model, "mjsound-masses")
        masses = texts.get("", "mujoco")
        where = "MJCF custom text 'mjsound-masses'"
    else:
        where = "masses"
    value = str(masses).strip().lower()
    if value not in MASSES:
        raise ValueError(f"{where}={masses!r}: give 'mujoco' (the sound's objects get MuJoCo's masses) or "
                         "'material' (every material keeps its own density)")
    return value


def _radius_of_curvature(model, g: int, vol: float, area: float) -> float:
    t = int(model.geom_type[g])
    s = np.asarray(model.geom_size[g], dtype=np.float64)
    if t in (2, 3, 5):
        return float(s[0])
    if t == 4:
        return float(s.min())
    return 3.0 * vol / area if area > 0 else math.inf


def decide(model, members, material, tolerance: float = MASS_TOLERANCE, hollow: bool = True):
    """``(material, rule, note)`` for the object of geoms ``members`` (one body) in
    ``material`` under the default rule (module docstring); ``rule`` one of ``"solid"``,
    ``"hollow"`` (never when ``hollow`` is False), ``"scaled"``, ``"foil"``, ``"none"``."""
    m = model
    b = int(m.geom_bodyid[members[0]])
    mass_b = float(m.body_mass[b])
    if b == 0 or not (math.isfinite(mass_b) and mass_b > 0):
        return material, "none", None
    body = np.flatnonzero(np.asarray(m.geom_bodyid) == b).tolist()
    colliding = [g for g in body if m.geom_contype[g] or m.geom_conaffinity[g]]
    counted = colliding or body
    shapes = {g: geom_volume_area(m, g) for g in set(counted) | set(members)}
    if any(shapes[g] is None for g in counted) or any(shapes[g] is None for g in members):
        return material, "none", "mass: a geom of its body has no volume (plane, height field): the material's density"
    V_b = sum(shapes[g][0] for g in counted)
    V = sum(shapes[g][0] for g in members)
    A = sum(shapes[g][1] for g in members)
    if not (V_b > 0 and V > 0 and A > 0):
        return material, "none", None
    mass = mass_b * min(V / V_b, 1.0)
    solid = material.rho * V
    r = mass / solid
    what = f"MuJoCo's {mass:.3g} kg against {solid:.3g} kg of solid {material.name}"
    if abs(r - 1.0) <= tolerance:
        return material, "solid", None
    if r < 1.0 and material.wall is None:
        wall = mass / (material.rho * A)
        R = min(_radius_of_curvature(m, g, *shapes[g]) for g in members)
        if wall <= SHELL_MAX_WALL_RATIO * min(R, 3.0 * V / A):
            if wall < HOLLOW_MIN_WALL_RATIO * R:
                return material, "foil", (f"mass: MuJoCo's {mass:.3g} kg would be a foil of {wall * 1e6:.3g} um, "
                                          f"under {100 * HOLLOW_MIN_WALL_RATIO:g} % of its radius, which no modal "
                                          f"analysis resolves: solid {material.name} ({solid:.3g} kg); its clicks "
                                          "are the foil's")
            if hollow:
                return (dataclasses.replace(material, wall=wall), "hollow",
                        f"mass: hollow, a wall of {wall * 1e3:.3g} mm ({what})")
    scaled = material.scaled(stiffness=r, density=r)
    return scaled, "scaled", (f"mass: density and stiffness x{r:.3g}, the wave speeds the material's ({what})")


def decide_masses(model, plans: list, masses: str) -> None:
    """Give each planned object (:func:`.objects.plan_object`: ``members``, ``material``,
    ``sound_mesh``) MuJoCo's mass: sets ``plan["material"]`` (the one analysed),
    ``plan["mass_rule"]`` and ``plan["mass_note"]`` (None or a line for the report), and keeps
    the material it had in ``plan["material_named"]``. Under ``masses="material"`` nothing
    changes (rule ``"kept"``)."""
    for plan in plans:
        plan["mass_rule"], plan["mass_note"] = "kept", None
        plan["material_named"] = plan["material"]
        if masses != "mujoco":
            continue
        if plan.get("sound_mesh") is not None:
            plan["mass_rule"] = "none"
            plan["mass_note"] = "mass: a sound mesh stands for the geoms: the material's density"
            continue
        plan["material"], plan["mass_rule"], plan["mass_note"] = decide(model, plan["members"], plan["material"])
