"""`SoundScene`: which objects of a MuJoCo model sound, with which material and modal model.

A geom *sounds* when it can collide (``contype`` or ``conaffinity`` non-zero, or it is named
in an explicit ``<pair>``), is not a plane/height field, and has an acoustic material. The
material comes from, in this order of precedence:

1. the Python mapping ``materials={key: material}``, key a geom name, MuJoCo's fallback name
   ``geom<ID>`` of an unnamed geom, its id, or its body's name (a geom key wins over its
   body's; a value of ``None``/``"none"``/``"silent"`` makes the geom silent),
2. an MJCF custom text ``<custom><text name="mjsound:GEOMNAME" data="steel"/></custom>``,
3. the geom's MJCF ``material`` name when it names a known acoustic material
   (case-insensitive, see :func:`mjsound.materials.get_material`),
4. ``materials["*"]``, the default for every other geom.

An unknown key in ``materials`` is an error listing the closest names: a typo never passes
silently.

Sounding geoms form **objects** (:mod:`mjsound.sim.objects`): by default the collision geoms
of one body with one material ring as one (one modal model of their union, in the frame of
an anchor geom), ``objects="geom"`` keeps one per geom. An object of one geom is named like
the geom; an object of several geoms like their body. Geoms with no acoustic material are
silent but still excite what they hit; a plane (e.g. the floor) may carry a material, which
is then used for the contact (Hertz) pulse of the objects hitting it, but it never gets a
modal model.

Modal models come from :func:`mjsound.modal.analyze.analyze` (disk-cached, and memoised in the
process) with a progress bar on stderr once the analysis takes over a second. What the scene
decided is in :meth:`SoundScene.report`: each object's modes, error estimate (flagged above
50 cents), mass against MuJoCo's, open surfaces and every mode budget.

Budgets: a large solid (a table, a floor slab) whose Weyl estimate of modes below f_max is
above :data:`AUTO_MAX_MODES` keeps its lowest ``AUTO_MAX_MODES`` (``max_modes_per_object``).
A scene budget ``budget_modes`` (total modes) is shared by importance: every object keeps at
least a few modes (never silently dropped), the rest go greedily to the loudest next-lowest
mode of any object (loudness per unit impulse at 1 m: ``|radiation_i| * rms(phi_i) /
omega_i``). Every truncation is listed in :meth:`SoundScene.report`.
"""

from __future__ import annotations

import dataclasses
import os
import time
from dataclasses import dataclass, field

import numpy as np

from ..materials import Material
from ..modal.band import default_f_max
from ..modal.model import ModalModel
from .objects import (checked_mapping, checked_names, close_names, custom_materials, custom_texts,  # noqa: F401
                      geom_mesh_spec, geom_name, group_objects, plan_object, unique_names)  # (geom_mesh_spec re-exported)
from .scene_analysis import (AUTO_MAX_MODES, MASS_TOLERANCE, AnalysisOptions, _analyze_with_fallback,  # noqa: F401
                             _finite_or_none, _mode_cap, _sphere_inaudible, _surface_notes, check_masses,
                             object_model, warn_unheard)  # (re-exported)
from .scene_budget import share_budget
from .scene_levels import loudest_modes
from .scene_materials import CANNOT_COLLIDE, NO_MATERIAL, assign_materials, warn_unknown_texts
from .scene_masses import decide, decide_masses, masses_option
from .scene_mics import place_microphones

__all__ = ["SoundScene", "SoundingGeom", "SoundingObject", "geom_mesh_spec", "geom_contact_radius"]

#: Estimated frequency errors above this are flagged in the report [cents].
ERROR_FLAG_CENTS = 50.0


def _mujoco():
    import mujoco

    return mujoco


@dataclass
class SoundingGeom:
    """One sounding object: one geom, or the collision geoms of one body that share a material.

    Attributes
    ----------
    geom_id : int
        The anchor geom: the model lives in its frame and follows its pose.
    body_id : int
        MuJoCo body id.
    name : str
        Synthesizer object name: the geom's name (``geom<ID>`` for unnamed geoms) for one geom,
        the body's name (``body<ID>``) for several.
    material : Material
    model : ModalModel
        The (possibly budget-truncated) model the synthesizer plays.
    n_modes_analysed : int
        Modes the analysis produced before the budget.
    source : str
        Where the material came from: ``mapping``, ``custom``, ``mjcf-material``.
    mesh : str
        Built-in spec or ``mesh:NAME`` that was analysed.
    dynamic : bool
        Whether the geom moves (its body is not welded to the world).
    method : str
    geom_ids : tuple[int, ...]
        Every geom whose contacts excite this object (the anchor first).
    notes : list[str]
        What the scene noticed or decided (mode budget, open surface, mass against MuJoCo's).
    mass_rule : str
        How the object got MuJoCo's mass (:mod:`.scene_masses`): ``"solid"`` (its material's
        already), ``"hollow"`` (a wall from the mass), ``"scaled"`` (density and stiffness
        scaled together), ``"kept"`` (``masses="material"``), ``"none"`` (no MuJoCo mass to follow).
    """

    geom_id: int
    body_id: int
    name: str
    material: Material
    model: ModalModel
    n_modes_analysed: int
    source: str
    mesh: str
    dynamic: bool = True
    method: str = "hex"
    geom_ids: tuple = ()
    notes: list = field(default_factory=list)
    mass_rule: str = "kept"

    def __post_init__(self):
        if not self.geom_ids:
            self.geom_ids = (int(self.geom_id),)


#: The same class under the name of what it is since objects are bodies.
SoundingObject = SoundingGeom


@dataclass
class SoundScene:
    """Sounding geoms, their materials and modal models, and the microphones of a model.

    Build it with :meth:`from_model`. Attributes are read-only by convention.

    Attributes
    ----------
    model : mujoco.MjModel
    sounding : list[SoundingGeom]
        In geom-id order.
    geom_material : list[Material | None]
        Acoustic material of every geom (silent geoms and planes may have one too).
    silent : dict[str, str]
        Geom name -> why it does not sound.
    mic_site_ids : list[int]
        Microphone sites (follow their bodies); empty when ``mic_positions`` is fixed.
    mic_positions : (m, 3) array
        Microphone positions at the initial state [m].
    mic_names : list[str]
    budget_modes : int | None
    budget_notes : list[str]
        One line per geom whose model the budget truncated.
    sample_rate : int
        Sample rate the models were analysed for [Hz].
    quality : str
        The analysis quality asked for (``"draft"``, ``"default"``, ``"high"``).
    """

    model: object
    sounding: list = field(default_factory=list)
    geom_material: list = field(default_factory=list)
    silent: dict = field(default_factory=dict)
    mic_site_ids: list = field(default_factory=list)
    mic_positions: np.ndarray = field(default_factory=lambda: np.zeros((1, 3)))
    mic_names: list = field(default_factory=list)
    budget_modes: int | None = None
    budget_notes: list = field(default_factory=list)
    sample_rate: int = 48000
    analysis_seconds: float = 0.0
    quality: str = "default"

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_model(
        cls,
        model,
        materials: dict | None = None,
        microphones=None,
        budget_modes: int | None = None,
        sample_rate: int = 48000,
        quality: str = "default",
        progress: bool = True,
        *,
        method: str = "auto",
        models: dict | None = None,
        cache: bool = True,
        objects: str = "body",
        sound_meshes: dict | None = None,
        max_modes_per_object="auto",
        error_estimate: bool = True,
        masses: str | None = None,
    ) -> "SoundScene":
        """Build the scene of a model.

        Parameters
        ----------
        model : mujoco.MjModel | str | os.PathLike
            A compiled model or a path to an MJCF file.
        materials : dict, optional
            ``{key: material}``; a key is a geom name, MuJoCo's fallback name of an unnamed
            geom (``"geom22"``, as the report prints it) or its id (``22``), a body name, or
            ``"*"`` (every geom that has no material otherwise: not in the mapping, no custom
            text, no MJCF material named like an acoustic one). Values are anything
            :func:`mjsound.materials.parse_material` accepts, or ``None``/``"silent"``. An
            unknown key is an error that lists the closest names.
        microphones : list[str] | (m, 3) array, optional
            Site names (they follow their bodies) or fixed world positions [m]. Default: the
            sites whose name starts with ``mic`` in model order, else one listener 1 m from the
            centre of the scene.
        budget_modes : int, optional
            Total modes over all sounding objects (None: no limit).
        sample_rate : int
            Audio sample rate [Hz]; modes above ``0.45 * sample_rate`` are not computed.
        quality : str
            Passed to ``analyze`` (``"draft"``, ``"default"``, ``"high"``).
        progress : bool
            Progress bar (stderr) over the analyses; it appears once they take over a second.
        method : str
            Discretization (``"auto"`` default: per object, shell triangles for thin curved
            walls, voxel hexahedra otherwise; see :func:`mjsound.analyze`); on failure falls
            back to ``hex``, then silence.
        models : dict, optional
            Precomputed ``{object_name: ModalModel}``; those objects skip analysis. A model
            analysed under this scene's mass rule (another scene's of the same MJCF, a batch
            driver's) keeps the rule; any other keeps its own material (rule ``"kept"``).
        cache : bool
            Use the on-disk model cache.
        objects : {"body", "geom"}
            ``"body"`` (default): the collision geoms of one body with one material ring as one
            object (:mod:`mjsound.sim.objects`); ``"geom"``: every geom rings on its own.
        sound_meshes : dict, optional
            ``{body_or_geom_name: surface}``: analyse this surface instead of the collision
            geoms (a geom such as the body's visual mesh, a mesh asset, a file, a built-in
            spec or ``(V, F)`` in the body frame; see :mod:`mjsound.sim.objects`). MJCF:
            ``<text name="mjsound-mesh:BODY" data="GEOM_OR_MESH"/>``.
        max_modes_per_object : "auto" | int | None
            Mode budget of one object. ``"auto"``: a solid whose Weyl estimate of modes
            below f_max exceeds :data:`AUTO_MAX_MODES` (a table or a floor slab in aluminium:
            hundreds of modes, a minute of analysis, little of the sound) keeps its lowest
            ``AUTO_MAX_MODES``, analysed on a mesh sized for those modes (up to 1.25 times the
            estimated frequency of the last, ``scene_analysis._mode_cap``); the report says
            so. An int: every object keeps at most that many. ``None``: no limit.
        error_estimate : bool
            Let ``analyze`` estimate each model's frequency error (a second, coarser solve);
            the report shows it and flags objects above 50 cents.
        masses : {"mujoco", "material"}, optional
            ``"mujoco"`` (default): every object weighs what MuJoCo says, as a hollow wall
            when it is lighter than a solid of its material and thin enough, else with its
            density and stiffness scaled together (:mod:`.scene_masses`; the report says which
            per object). ``"material"``: every material keeps its own density. Default: the
            MJCF custom text ``<text name="mjsound-masses" data="..."/>``, else ``"mujoco"``.

        Returns
        -------
        SoundScene
        """
        mujoco = _mujoco()
        if not isinstance(model, mujoco.MjModel):
            model = mujoco.MjModel.from_xml_path(os.fspath(model))
        scene = cls(model=model, budget_modes=budget_modes, sample_rate=int(sample_rate), quality=str(quality))
        materials = checked_mapping(model, materials, "materials", allow_star=True)
        mesh_texts = custom_texts(model, "mjsound-mesh:")
        warn_unknown_texts(model, mesh_texts, "mjsound-mesh:", mujoco.mjtObj.mjOBJ_BODY, mujoco.mjtObj.mjOBJ_GEOM)
        mesh_texts = {k: v for k, v in mesh_texts.items() if k in checked_names(model)}
        sound_meshes = {**mesh_texts, **checked_mapping(model, sound_meshes, "sound_meshes", allow_star=False)}
        models = dict(models or {})
        custom = custom_materials(model)
        warn_unknown_texts(model, custom, "mjsound:", mujoco.mjtObj.mjOBJ_GEOM)
        star = materials.pop("*", None)

        assigned = assign_materials(model, materials, custom, star)
        scene.geom_material, scene.silent = assigned.materials, assigned.silent
        plans = _plan_objects(model, assigned, objects, sound_meshes, models)
        decide_masses(model, plans, masses_option(model, masses))
        t0 = time.perf_counter()
        f_max = default_f_max(sample_rate)
        options = AnalysisOptions(method, quality, int(sample_rate), max_modes_per_object, bool(error_estimate),
                                  bool(cache))
        analysed = _analyse_objects(model, plans, models, options, scene.silent, progress)
        for plan in plans:
            plan["named"] = any(g in assigned.named for g in plan["members"])
        scene.analysis_seconds = time.perf_counter() - t0
        scene.sounding = analysed
        warn_unheard(scene, [p for p in plans if p["named"] and p["name"] in scene.silent], f_max)
        check_masses(scene)
        scene.budget_notes = share_budget(scene.sounding, budget_modes)
        scene.mic_site_ids, scene.mic_positions, scene.mic_names = place_microphones(model, scene.sounding,
                                                                                     microphones)
        return scene

    # ------------------------------------------------------------------ microphones
    @property
    def mics_move(self) -> bool:
        """Whether any microphone site sits on a moving body."""
        m = self.model
        return any(m.body_weldid[m.site_bodyid[s]] != 0 for s in self.mic_site_ids)

    # ------------------------------------------------------------------ reporting
    @property
    def n_modes(self) -> int:
        """Total modes the synthesizer plays."""
        return int(sum(s.model.n_modes for s in self.sounding))

    def by_geom(self) -> dict:
        """``{geom_id: SoundingGeom}`` for every geom that excites an object (an object of
        several geoms appears once per geom; its anchor comes last)."""
        out = {}
        for s in self.sounding:
            for g in s.geom_ids[1:]:
                out[g] = s
        for s in self.sounding:
            out[s.geom_id] = s
        return out

    def summary(self) -> dict:
        """JSON-able description of the scene."""
        return {
            "sounding": [
                {
                    "geom": s.name,
                    "material": s.material.name,
                    "material_source": s.source,
                    "mesh": s.mesh,
                    "method": s.method,
                    "n_modes": s.model.n_modes,
                    "n_modes_analysed": s.n_modes_analysed,
                    "f_min_hz": float(s.model.frequencies_hz[0]) if s.model.n_modes else None,
                    "f_max_hz": float(s.model.frequencies_hz[-1]) if s.model.n_modes else None,
                    "dofs": int(s.model.dofs),
                    "seconds": float(s.model.seconds),
                    "geoms": [geom_name(self.model, g) for g in s.geom_ids],
                    "mass_kg": float(s.model.mass_kg),
                    "error_estimate_cents": _finite_or_none(s.model.error_estimate_cents),
                    "notes": list(s.notes),
                    "loudest_mode": levels,
                }
                for s, levels in zip(self.sounding, loudest_modes(self))
            ],
            "silent": dict(self.silent),
            "n_modes": self.n_modes,
            "budget_modes": self.budget_modes,
            "budget_notes": list(self.budget_notes),
            "microphones": list(self.mic_names),
            "sample_rate": self.sample_rate,
            "analysis_seconds": self.analysis_seconds,
        }

    def report(self, details: bool = False) -> str:
        """Human-readable summary: what sounds (modes, range, error estimate, flagged ``(!)``
        above 50 cents), what each object is made of, its loudest mode at each microphone for
        a reference tap (a 10 g steel ball at 1 m/s, :func:`.scene_levels.loudest_modes`: free
        field, the initial pose), every
        budget and note, what is silent.

        Geoms that are silent for a reason of no interest (they cannot collide: visual
        geoms; they have no acoustic material) are counted in one line per reason, with the
        first names, when there are more than :data:`LISTED_SILENT`; ``details=True`` lists
        every one.
        """
        lines = [f"{len(self.sounding)} sounding object(s), {self.n_modes} modes, mics: {', '.join(self.mic_names)}"]
        flagged = 0
        loudest = loudest_modes(self)
        for s, levels in zip(self.sounding, loudest):
            f = s.model.frequencies_hz
            rng = f"{f[0]:.0f}-{f[-1]:.0f} Hz" if len(f) else "-"
            cut = f" (of {s.n_modes_analysed})" if s.model.n_modes != s.n_modes_analysed else ""
            err = float(s.model.error_estimate_cents)
            if np.isfinite(err):
                bad = err > ERROR_FLAG_CENTS
                flagged += bad
                est = f"+-{err:.0f} c{' (!)' if bad else ''}"
            else:
                est = "err n/a"
            geoms = f" {len(s.geom_ids)} geoms," if len(s.geom_ids) > 1 and not s.mesh.startswith("union") else ""
            lines.append(f"  {s.name:<20s} {s.material.name:<14s} {s.model.n_modes:4d} modes{cut}  {rng}  {est}  "
                         f"{s.model.mass_kg:.3g} kg  [{geoms} {s.mesh}]".replace("[ ", "["))
            if levels and all(lv["spl_db"] is not None for lv in levels):
                at = ", ".join(f"{lv['frequency_hz']:.0f} Hz {lv['spl_db']:.0f} dB at {lv['mic']} ({lv['distance_m']:.2g} m)"
                               for lv in levels)
                lines.append(f"      loudest mode, a 10 g steel ball's tap at 1 m/s: {at}")
            for note in s.notes:
                lines.append(f"      {note}")
        if flagged:
            lines.append(f"  (!) {flagged} object(s) with an estimated frequency error above {ERROR_FLAG_CENTS:.0f} cents: "
                         f"{_finer_quality_hint(self.quality)}")
        for note in self.budget_notes:
            lines.append(f"  budget: {note}")
        grouped: dict = {}
        for name, why in self.silent.items():
            grouped.setdefault(why if why in UNINTERESTING_SILENCE else name, []).append((name, why))
        for entries in grouped.values():
            if details or len(entries) <= LISTED_SILENT:
                lines += [f"  silent {name}: {why}" for name, why in entries]
            else:
                names = ", ".join(name for name, _ in entries[:LISTED_SILENT])
                lines.append(f"  silent: {len(entries)} geoms {entries[0][1]} ({names}, ...; report(details=True) "
                             "lists them)")
        return "\n".join(lines)


#: silent reasons counted in one line by :meth:`SoundScene.report` (visual geoms, geoms left
#: without a material): per-geom lines of them drown the objects that matter
UNINTERESTING_SILENCE = frozenset({CANNOT_COLLIDE, NO_MATERIAL})
#: how many such geoms the report names before it counts them
LISTED_SILENT = 3


def _finer_quality_hint(quality: str) -> str:
    """What to do about flagged frequency errors at analysis ``quality``: the qualities above
    it, or, at the highest, that the estimate is what it resolves."""
    from ..modal.plan import QUALITY_ORDER

    finer = QUALITY_ORDER[:QUALITY_ORDER.index(quality)][::-1] if quality in QUALITY_ORDER else ()
    if finer:
        return f"a higher quality ({', '.join(repr(q) for q in finer)}; now {quality!r}) makes them more accurate"
    return f"quality {quality!r} is the finest preset: these estimates are what it resolves"


# ---------------------------------------------------------------------- helpers
def _plan_objects(model, assigned, objects: str, sound_meshes: dict, models: dict) -> list:
    """The scene's objects (:func:`.objects.group_objects`, :func:`.objects.plan_object`) from
    the geoms that can sound (``assigned``: :func:`.scene_materials.assign_materials`), uniquely
    named; a key of ``sound_meshes`` or ``models`` that names no object is an error listing the
    closest names."""
    groups = group_objects(model, assigned.sounding, assigned.materials, objects)
    per_body = np.bincount([int(model.geom_bodyid[m[0]]) for m in groups], minlength=model.nbody)
    plans = [plan_object(model, members, sound_meshes, assigned.materials[members[0]], assigned.sources[members[0]],
                         alone=per_body[int(model.geom_bodyid[members[0]])] == 1)
             for members in groups]
    unique_names(plans)
    unused = set(sound_meshes) - {p["sound_key"] for p in plans}
    if unused:
        k = sorted(unused, key=str)[0]
        raise ValueError(f"sound mesh for {k!r}: no sounding object is named so (the geom or body has no acoustic "
                         f"material or cannot collide; see the keys of materials=){close_names(str(k), [p['name'] for p in plans])}")
    unknown = set(models) - {p["name"] for p in plans}
    if unknown:
        names = [p["name"] for p in plans]
        k = sorted(unknown)[0]
        raise ValueError(f"models: no sounding object named {k!r}{close_names(k, names)}; "
                         f"the objects are {', '.join(map(repr, names)) or 'none'}")
    return plans


def _analyse_objects(model, plans: list, models: dict, options: AnalysisOptions, silent: dict,
                     progress: bool) -> list:
    """The :class:`SoundingGeom` of every planned object that rings: its model from ``models``
    or analysed (:func:`.scene_analysis.object_model`, a progress bar once that takes over a
    second); an object that cannot ring goes into ``silent`` with the reason."""
    analysed = []
    bar = None
    try:
        for done, plan in enumerate(plans):
            name, members, mat = plan["name"], plan["members"], plan["material"]
            if bar is not None:
                bar.set_postfix_str(name, refresh=False)
            mm, notes = models.get(name), []
            if mm is not None:
                _adopt_given_model(model, plan, mm)
                mat = plan["material"]
            inaudible = _sphere_inaudible(model, members[0], mat, options.sample_rate) if len(members) == 1 and \
                plan["sound_mesh"] is None else None
            if mm is None and inaudible:
                silent[name] = inaudible
            elif mm is None:
                def start_bar():  # (at the first object to analyse)
                    nonlocal bar
                    if progress and bar is None:
                        bar = _progress_bar(len(plans), done, name)

                mm, notes = _object_model(model, plan, options, start_bar)
                mat = plan["material"]
                if mm is None:
                    silent[name] = "analysis failed (see warning)"
            if bar is not None:
                bar.update(1)
            if mm is None:
                continue
            if mm.n_modes == 0:
                top = mm.info.get("f_max", default_f_max(options.sample_rate))
                silent[name] = f"no audible modes (none between 20 Hz and f_max {top / 1000:.1f} kHz)"
                continue
            notes.extend(_surface_notes(mm))
            if plan.get("mass_note"):
                notes.insert(0, plan["mass_note"])
            body = int(model.geom_bodyid[members[0]])
            analysed.append(
                SoundingGeom(
                    geom_id=members[0], body_id=body, name=name, material=mat, model=mm,
                    n_modes_analysed=mm.n_modes, source=plan["source"], mesh=plan["label"],
                    dynamic=bool(model.body_weldid[body] != 0), method=str(mm.method),
                    geom_ids=tuple(members), notes=notes, mass_rule=plan.get("mass_rule", "kept"),
                )
            )
    finally:
        if bar is not None:
            bar.close()
    return analysed


def _adopt_given_model(model, plan: dict, mm) -> None:
    """Set ``plan``'s material and mass rule for a model given to :meth:`SoundScene.from_model`.

    A model analysed under this scene's mass decision (its material is the one
    :func:`.scene_masses.decide_masses` chose, or the scaled fallback of a hollow wall the
    analysis could not resolve: a batch driver's models, another scene's of the same MJCF) keeps
    that decision, so a batch worker's scene is the driver's and its audio that of ``sonify``;
    any other model weighs what it weighs (its named material, rule ``"kept"``).
    """
    if mm.material == plan["material"]:
        return
    if plan.get("mass_rule") == "hollow":
        fallback = dict(plan)
        _hollow_fallback(model, fallback)
        if mm.material == fallback["material"]:
            plan.update(fallback)
            return
    plan["material"] = plan.get("material_named", plan["material"])
    plan["mass_rule"], plan["mass_note"] = "kept", None


def _hollow_fallback(model, plan: dict) -> None:
    """Replace a hollow plan's wall by :func:`.scene_masses.decide`'s solid rule (scaled
    density and stiffness), with a note saying why."""
    wall = plan["material"].wall
    solid = dataclasses.replace(plan["material"], wall=None)
    material, rule, note = decide(model, plan["members"], solid, hollow=False)
    plan["material"], plan["mass_rule"] = material, rule
    plan["mass_note"] = f"{note}; as a hollow wall of {wall * 1e3:.3g} mm it could not be analysed"


def _object_model(model, plan: dict, options: AnalysisOptions, on_analyse):
    """:func:`.scene_analysis.object_model`; a hollow object the analysis cannot resolve (the
    wall too thin for its size at this sample rate) is analysed again with its density and
    stiffness scaled instead (:mod:`.scene_masses`), and its note says so."""
    if plan.get("mass_rule") != "hollow":
        return object_model(plan, options, on_analyse)
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        mm, notes = object_model(plan, options, on_analyse)
    if mm is not None:
        return mm, notes
    _hollow_fallback(model, plan)
    return object_model(plan, options, on_analyse)


def geom_contact_radius(model, g: int) -> float:
    """Radius of curvature for Hertz contact [m] (inf for planes and flat boxes)."""
    mujoco = _mujoco()
    T = mujoco.mjtGeom
    t = int(model.geom_type[g])
    s = model.geom_size[g]
    if t in (T.mjGEOM_SPHERE, T.mjGEOM_CAPSULE, T.mjGEOM_CYLINDER):
        return float(s[0])
    if t == T.mjGEOM_ELLIPSOID:
        return float(np.min(s))
    if t == T.mjGEOM_MESH:
        # A mesh touches with its edges and corners; a tenth of its bounding radius.
        return float(0.1 * model.geom_rbound[g]) if model.geom_rbound[g] > 0 else np.inf
    return np.inf


def _progress_bar(total: int, done: int, name: str):
    """A tqdm bar over the scene's objects (``done`` already loaded; shown after 1 s), or None."""
    try:
        from tqdm.auto import tqdm
    except ImportError:  # pragma: no cover
        return None
    bar = tqdm(total=total, initial=done, desc="mjsound: modal analysis", unit="object", delay=1.0)
    bar.set_postfix_str(name, refresh=False)
    return bar
