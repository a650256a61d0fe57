"""Analysing a scene's objects: fallbacks, the process-wide memo, mode budgets of large solids,
and what the scene tells its user about them (objects that will not ring, open surfaces,
masses that disagree with MuJoCo's). Used by :meth:`mjsound.sim.SoundScene.from_model`."""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import hashlib
import os
import sys
import warnings
from typing import NamedTuple

import numpy as np

from ..io import file_lock, sources_digest
from ..limits import max_memory_gb
from ..modal.band import default_f_max, ringing_below
from ..modal.model import ModalModel
from ..user_frame import user_stacklevel
from .objects import object_mesh, solid_mode_count
from .scene_materials import NO_MATERIAL

#: A body's sounding mass and MuJoCo's may differ by this fraction before the scene warns.
MASS_TOLERANCE = 0.05
#: Mode budget of one large solid object under ``max_modes_per_object="auto"``.
AUTO_MAX_MODES = 64
#: Such an object is analysed up to this factor above the estimated frequency of its last kept mode.
BAND_MARGIN = 1.25


def _mujoco():
    import mujoco

    return mujoco


def _sphere_inaudible(model, g, mat, sample_rate) -> str | None:
    """Why a solid sphere is too small/stiff to ring below f_max, or None.

    The lowest mode of a free solid sphere (spheroidal n=0, l=2) is at
    ``omega R / c_s ~ 2.6`` (nu 0..0.45), ``c_s = sqrt(G / rho)``; of a thin hollow one (a
    material with a ``wall``) about 0.6 of the ring frequency ``sqrt(E / (rho (1 - nu^2))) /
    (2 pi R)``; a margin of two keeps it safe.
    """
    mujoco = _mujoco()
    if int(model.geom_type[g]) != mujoco.mjtGeom.mjGEOM_SPHERE:
        return None
    R = float(model.geom_size[g][0])
    if getattr(mat, "wall", None) is None:
        f1 = 2.6 * np.sqrt(mat.shear_modulus / mat.rho) / (2 * np.pi * R)
    else:  # a thin spherical shell: its lowest bending modes lie just under the membrane's
        # ring frequency sqrt(E / (rho (1 - nu^2))) / (2 pi R), from about 0.6 of it
        f1 = 0.6 * np.sqrt(mat.E / (mat.rho * (1 - mat.nu**2))) / (2 * np.pi * R)
    f_max = min(20000.0, 0.45 * float(sample_rate))
    if 0.5 * f1 > f_max:
        return f"no audible modes (lowest mode ~{f1 / 1000:.0f} kHz > f_max {f_max / 1000:.1f} kHz)"
    return None


#: The radiation setting a scene analyses its objects with, by analysis quality: the boundary-
#: element solve at the scene's own quality, but ``draft`` radiation for ``draft`` scenes (the
#: env wrappers' default, for training at scale). On the reference objects (reports/accuracy.md
#: "Levels") ``default`` gives each converged mode's radiated power within 0.6 dB and every
#: direction within 2.7 dB of the converged reference, at 0.4-0.8 times the modal analysis's own
#: cost at 20 kHz; ``draft`` 1.6 dB in power but up to 12 dB in some directions of weak modes,
#: at 0.04-0.16 times it (docs/radiation.md "Cost"). ``quality="high"`` scenes take ``default``
#: too (the converged setting; ``high`` refines further at several times the cost).
SCENE_RADIATION = {"draft": "draft", "default": "default", "high": "default"}

#: Process-wide memo of modal models by (surface, material, analysis options), so that several
#: copies of one env (SyncVectorEnv, repeated gym.make) analyse each object once.
_MODEL_MEMO: dict = {}


def _analyze_with_fallback(name, spec, material, method, quality, sample_rate, cache, max_modes=None,
                           error_estimate=True, f_max=None):
    """``analyze`` with ``method``, then ``hex``; ``None`` (and a warning) when both fail."""
    from ..modal.analyze import analyze

    if isinstance(spec, tuple):
        h = hashlib.sha1(np.ascontiguousarray(spec[0], np.float64).tobytes())
        h.update(np.ascontiguousarray(spec[1], np.int64).tobytes())
        label = h.hexdigest()
    else:
        label = str(spec)
    # (keyed by the analysis function too: one replaced by a fake never shares entries with the real one)
    key = (analyze, label, material.key(), int(sample_rate), quality, method, max_modes, bool(error_estimate),
           bool(cache), f_max)
    if key in _MODEL_MEMO:
        return _MODEL_MEMO[key]
    tried = []
    for m in dict.fromkeys([method, "hex"]):
        try:
            mm = analyze(spec, material, method=m, quality=quality, sample_rate=sample_rate, cache=cache,
                         progress=False, max_modes=max_modes, error_estimate=error_estimate, f_max=f_max,
                         radiation=SCENE_RADIATION.get(quality))
            _MODEL_MEMO[key] = mm
            return mm
        except (ValueError, RuntimeError, MemoryError) as exc:
            tried.append(f"{m}: {exc}")
    warnings.warn(f"{name!r} stays silent: modal analysis failed ({'; '.join(tried)})", stacklevel=user_stacklevel())
    return None


# ---------------------------------------------------------------------- object cache
#: Files whose code decides how an object's geoms become a modal model (with trimesh's version,
#: part of every object-cache key: an edit there is never answered from an older entry).
_ANALYSIS_SOURCES = ("modal", "geometry.py", "materials.py", "sim/objects.py", "sim/scene_analysis.py")


@functools.lru_cache(maxsize=1)
def analysis_source_digest() -> str:
    """sha256 of the analysis code (``_ANALYSIS_SOURCES``) and the installed trimesh version."""
    from importlib.metadata import PackageNotFoundError, version

    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    h = hashlib.sha256(sources_digest(root, _ANALYSIS_SOURCES))
    try:
        h.update(version("trimesh").encode())
    except PackageNotFoundError:  # pragma: no cover
        pass
    return h.hexdigest()


class AnalysisOptions(NamedTuple):
    """How a scene analyses its objects (:meth:`mjsound.sim.SoundScene.from_model`'s arguments)."""

    method: str
    quality: str
    sample_rate: int
    max_modes_per_object: object
    error_estimate: bool
    cache: bool


def object_model(plan: dict, options: AnalysisOptions, on_analyse=None):
    """``(model, notes)`` of one scene object: from the object cache, else analysed (mode cap
    for large solids, ``method`` then ``hex``; ``on_analyse()`` is called first) and kept
    there; ``(None, [])`` when the analysis failed (a warning says why). A process that finds
    another one analysing the same object waits for its entry (:func:`analysis_lock`)."""
    key = object_cache_key(plan, options)
    hit = load_object_model(key)
    if hit is None:
        with analysis_lock(key):  # (another process analysing this object: wait for its entry)
            hit = load_object_model(key)
            if hit is None:
                return _analyse_object(plan, options, key, on_analyse)
    mm, plan["label"], notes = hit
    return mm, notes


def _analyse_object(plan: dict, options: AnalysisOptions, key, on_analyse):
    if on_analyse is not None:
        on_analyse()
    o, notes = options, []
    mesh = object_mesh(plan)
    max_modes, f_band, cap_note = _mode_cap(mesh, plan["material"], default_f_max(o.sample_rate),
                                            o.max_modes_per_object)
    if cap_note:
        notes.append(cap_note)
    mm = _analyze_with_fallback(plan["name"], mesh, plan["material"], o.method, o.quality, o.sample_rate, o.cache,
                                f_max=f_band, max_modes=max_modes, error_estimate=o.error_estimate)
    if mm is None:
        return None, []
    save_object_model(key, mm, plan["label"], notes)
    return mm, notes


def object_cache_key(plan: dict, options: AnalysisOptions) -> str | None:
    """The object cache's key of one scene object: its recipe (:func:`.objects.object_recipe`),
    material, the analysis ``options``, the memory cap (it can coarsen a mesh), the analysis
    function in use and :func:`analysis_source_digest`. None without ``options.cache``, or when
    the analysis function was replaced by one that is not mjsound's (a test's fake never shares
    entries with the real one)."""
    if not options.cache:
        return None
    an = sys.modules.get("mjsound.modal.analyze")
    fn = getattr(an, "analyze", None) if an is not None else None
    if fn is not None and getattr(fn, "__module__", None) != "mjsound.modal.analyze":
        return None
    text = repr((plan["recipe"], plan["material"].key(), tuple(options), max_memory_gb(), analysis_source_digest()))
    return hashlib.sha256(text.encode()).hexdigest()[:40]


#: Longest wait for another process's analysis of the same object [s]; then this one analyses too.
LOCK_WAIT_S = 1800.0


def analysis_lock(key: str | None):
    """The object cache's lock of ``key`` (:func:`mjsound.io.file_lock` on a file in the
    cache's ``locks/``): processes that start together on a new machine (the workers of a
    vectorised env) need the same objects; with the lock one of them analyses each object and
    the others wait and load its entry, instead of every process analysing it at once (the time,
    and the memory, of N analyses). Nothing is locked without a key (no cache); after
    :data:`LOCK_WAIT_S` of waiting the caller goes on."""
    if key is None:
        return contextlib.nullcontext()
    from ..modal.cache import cache_dir

    return file_lock(os.path.join(cache_dir(), "locks", f"{key}.lock"), LOCK_WAIT_S)


def _object_path(key: str) -> str:
    from ..modal.cache import cache_dir

    return os.path.join(cache_dir(), "objects", f"{key}.npz")


def load_object_model(key: str | None):
    """``(model, label, notes)`` of a cached scene object, or None (no entry, or a corrupt one).

    This is the start-up fast path: an object found here is never meshed or planned, so a
    process whose objects are all cached loads neither trimesh nor the analysis code."""
    if key is None:
        return None
    path = _object_path(key)
    if not os.path.exists(path):
        return None
    try:
        mm = ModalModel.load(path)
        entry = mm.info.pop("object_cache")
        return mm, str(entry["label"]), [str(n) for n in entry["notes"]]
    except (ValueError, KeyError, TypeError):  # (corrupt or foreign: analyse again, the entry is rewritten)
        return None


def save_object_model(key: str | None, mm: ModalModel, label: str, notes: list) -> None:
    """Keep ``mm`` (and the object's label and notes) under ``key`` (atomic; a failure only warns)."""
    if key is None:
        return
    entry = dataclasses.replace(mm, info={**mm.info, "object_cache": {"label": label, "notes": list(notes)}})
    try:
        entry.save(_object_path(key))
    except OSError as exc:
        warnings.warn(f"could not write the object cache entry {_object_path(key)}: {exc}", stacklevel=user_stacklevel())


# ---------------------------------------------------------------------- construction helpers
def _finite_or_none(x):
    x = float(x)
    return x if np.isfinite(x) else None


def _mode_cap(mesh, material, f_max, max_modes_per_object):
    """``(max_modes, f_band, note)`` for one object's analysis (see ``SoundScene.from_model``).

    Under ``"auto"`` a closed solid whose Weyl estimate ``N(f) = 2 * solid_mode_count`` (the
    factor two for the free surface's modes) exceeds ``AUTO_MAX_MODES`` below ``f_top`` (f_max,
    or where its material stops ringing) keeps its lowest ``AUTO_MAX_MODES``, and is analysed
    only up to ``f_band = BAND_MARGIN * f_N``, ``f_N = f_top (AUTO_MAX_MODES / N(f_top))^(1/3)``
    the estimated frequency of its last kept mode: the mesh is sized for the modes kept
    (elements per wavelength at ``f_band``, not at ``f_max``). ``f_band`` None: the default.
    """
    if max_modes_per_object is None:
        return None, None, None
    if max_modes_per_object != "auto":
        n = int(max_modes_per_object)
        if n < 1:
            raise ValueError(f"max_modes_per_object={max_modes_per_object!r}: give 'auto', None or a count >= 1")
        return n, None, f"mode budget: lowest {n} modes (max_modes_per_object={n})"
    from ..geometry import load_mesh

    tm = load_mesh(mesh, check_size=False)
    if not tm.is_watertight or getattr(material, "wall", None) is not None:
        return None, None, None  # (only solids: an open surface or a hollow object is a wall)
    f_top = min(f_max, ringing_below(material))
    est = 2.0 * solid_mode_count(abs(float(tm.volume)), material, f_top)
    if est <= AUTO_MAX_MODES:
        return None, None, None
    f_band = min(f_top, BAND_MARGIN * f_top * (AUTO_MAX_MODES / est) ** (1 / 3))
    return AUTO_MAX_MODES, f_band, (
        f"large solid ({np.max(tm.extents):.2g} m, ~{est:.0f} modes expected below {f_top / 1000:.1f} kHz): its "
        f"lowest {AUTO_MAX_MODES}, analysed to {f_band / 1000:.1f} kHz (max_modes_per_object=None analyses all)")


def _surface_notes(mm: ModalModel) -> list:
    """A note when the analysed surface was open (analysed as a thin wall, not a solid)."""
    info = mm.info or {}
    if info.get("watertight", True):
        return []
    h = info.get("h")
    r = info.get("refine")
    t = info.get("wall_m") or info.get("thickness")
    if not t and h is not None and r:
        t = float(np.min(h)) / float(r)
    thick = f"a wall {1000 * t:.2g} mm thick" if t else "a thin wall"
    return [f"not a closed surface (open, or edges with more than two faces): its unclosed parts are analysed as "
            f"{thick}, not as a solid; close the mesh, or give the wall thickness (wall= in the material)"]


def warn_unheard(scene, plans, f_max) -> None:
    """A warning for every object the user gave a material that will not ring, and one when
    nothing in the scene rings (objects with materials too high-pitched, or no material at all)."""
    if not scene.sounding and any("no audible modes" in why for why in scene.silent.values()):
        quiet = [n for n, why in scene.silent.items() if "no audible modes" in why]
        warnings.warn(f"mjsound: nothing in this scene rings: {len(quiet)} object(s) with a material have no mode "
                      f"between 20 Hz and f_max {f_max / 1000:.1f} kHz ({', '.join(quiet[:4])}"
                      f"{' ...' if len(quiet) > 4 else ''}). A higher sample_rate (f_max = 0.45 x sample_rate) or "
                      "lower-pitched materials would make them ring (moving bodies still click on impact).", UserWarning,
                      stacklevel=user_stacklevel())
    elif not scene.sounding and any(why == NO_MATERIAL for why in scene.silent.values()):
        bare = sum(why == NO_MATERIAL for why in scene.silent.values())
        warnings.warn(f"mjsound: nothing in this scene rings: no colliding geom has an acoustic material ({bare} "
                      "without one). Give materials= (a geom, body or '*': a material name such as 'steel'), name "
                      "MJCF materials after mjsound's, or default_material= in the env wrappers (moving bodies still "
                      "click on impact).", UserWarning, stacklevel=user_stacklevel())
    for p in plans:
        why = scene.silent[p["name"]]
        fix = ("a lower-pitched object (larger, or a softer or denser material) or a higher sample_rate "
               f"(f_max = 0.45 x sample_rate, now {f_max / 1000:.1f} kHz) would make it ring"
               if "no audible modes" in why else "see the warning above")
        warnings.warn(f"mjsound: {p['name']!r} ({p['material'].name}, {p['label']}) will not ring: {why}. "
                      f"It still excites what it hits (and clicks when it moves); {fix}.", UserWarning, stacklevel=user_stacklevel())

def check_masses(scene) -> None:
    """Compare every body's sounding mass with MuJoCo's ``body_mass``; note > 5 % off, and warn
    of the objects whose material the user named and whose mass the scene did not make
    MuJoCo's (``masses="material"``, or no MuJoCo mass to follow: :mod:`.scene_masses`).

    Only bodies (not the world) whose colliding geoms all sound are compared: the modal
    models' masses (``rho V``, what the sound assumes) summed over the body's objects
    against what the physics uses (MJCF density, ``mass`` or ``<inertial>``). An object the
    mass rule made hollow or scaled is not warned of (its note says what it became; a
    voxelised volume may still differ from the geoms' by a few per cent).
    """
    m = scene.model
    by_body: dict = {}
    for s in scene.sounding:
        by_body.setdefault(s.body_id, []).append(s)
    sounding_geoms = {g for s in scene.sounding for g in s.geom_ids}
    off = []
    for b, objs in by_body.items():
        if b == 0 or not m.body_mass[b] > 0:
            continue
        geoms = np.flatnonzero(np.asarray(m.geom_bodyid) == b)
        colliding = [g for g in geoms.tolist() if m.geom_contype[g] or m.geom_conaffinity[g]]
        if not set(colliding) <= sounding_geoms:
            continue
        mass = sum(float(s.model.mass_kg) for s in objs)
        if not np.isfinite(mass) or mass <= 0:
            continue
        ref = float(m.body_mass[b])
        if abs(mass / ref - 1.0) > MASS_TOLERANCE:
            followed = all(getattr(s, "mass_rule", "kept") in ("solid", "hollow", "scaled", "foil") for s in objs)
            note = (f"mass {mass:.3g} kg ({', '.join(sorted({s.material.name for s in objs}))}) against MuJoCo's "
                    f"{ref:.3g} kg for its body ({100 * (mass / ref - 1):+.0f} %)")
            if not followed:
                note += (": set the body's density or mass in the MJCF, choose the material it is made of, or "
                         "masses='mujoco'")
            for s in objs:
                s.notes.append(note)
            named = any(s.source in ("mapping", "custom", "mjcf-material") for s in objs)
            if named and not followed:
                off.append(f"{objs[0].name} {mass:.3g} vs {ref:.3g} kg")
    if off:
        warnings.warn(f"mjsound: {len(off)} object(s) whose material you named differ in mass from MuJoCo's by "
                      f"more than {100 * MASS_TOLERANCE:.0f} % (the sound and the physics disagree; scene.report() "
                      f"says more): {'; '.join(off[:6])}{' ...' if len(off) > 6 else ''}", UserWarning, stacklevel=user_stacklevel())

