"""Offline rendering of a timed list of events (``mjsound render-events EVENTS.json``).

See :data:`EVENTS_HELP` for the file format (it is also the command's ``--help``).
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import replace

import numpy as np

from ..limits import check_array_bytes, check_duration, check_sample_rate

__all__ = ["EVENTS_HELP", "load_events", "validate_events", "render_events"]

EVENTS_HELP = """\
Render a list of timed excitation events on modal objects to an audio file, without a
simulator. EVENTS.json is one JSON object; all coordinates are world coordinates in metres,
all quantities SI (s, N, N s, m/s, kg, Pa). Relative paths are relative to the JSON file.

Top level
  sample_rate   int, Hz (default 48000; 1000..768000)
  duration      float, seconds of audio to render (required, > 0, at most one day)
  microphones   list of [x, y, z] positions, one output channel each
                (default [[0, 0, 1]]: one listener 1 m above the origin)
  objects       list of objects (required, at least one), see below
  events        list of events, see below (may be empty)
  full_scale_pa float, pressure mapped to digital full scale (default 20 Pa = 120 dB SPL);
                ignored when normalize is true
  normalize     bool, peak-normalise the file to -1 dBFS (default false; level is lost)
  dtype         "float32" (default) or "float64" oscillator state
  radiation     bool, far-field radiation estimate (default true) or modal acceleration
  seed          int, seed of the sliding/rolling noise (default 0)
  speed_of_sound float, m/s (default 343)
  cull_db       float or null, culling threshold below each mode's peak (default -100)

Object
  name          str, unique (required)
  model         path to a saved ModalModel (.npz, from `mjsound analyze -o`), or
  mesh          mesh file path or built-in shape ("box:0.1,0.02,0.01", "bowl:0.1,0.004",
                "cylinder:R,L", "sphere:R", "capsule:R,L"); modal analysis runs (cached)
  material      material name ("steel", "glass", ...) or inline "E=70e9,nu=0.33,rho=2700";
                required with mesh; with model it overrides the contact material
  method        discretisation for mesh: "hex" (default), "tet", "shell"
  quality       analysis quality for mesh (default "default")
  position      [x, y, z] of the object's origin (default [0, 0, 0])
  rotation      3x3 object-to-world rotation matrix (rows), default identity

Event (common fields: "type", "object" = an object's name)
  impact:  time [s]; point [x,y,z]; impulse [Jx,Jy,Jz] in N s (on this object).
           optional: pulse_s (contact time, overrides Hertz), speed (normal approach
           speed m/s), radius_m (this object's curvature radius at the contact),
           other_material (name/inline; default rigid), other_mass_kg, other_radius_m
           (default infinite = immovable / flat)
  slide:   start [s], end [s]; point; normal [nx,ny,nz]; normal_force [N]; speed [m/s]
           optional: roughness (force fluctuation per N per m/s, default 0.05)
  roll:    same fields as slide (the roughness noise is low-passed: a duller rumble)
  excite:  time [s]; point; direction; signal: list of force samples [N] at sample_rate

Example
  {"sample_rate": 48000, "duration": 2.0,
   "objects": [{"name": "bell", "mesh": "bowl:0.1,0.004", "material": "brass",
                "position": [0, 0, 0]}],
   "microphones": [[0.5, 0, 0.3]],
   "events": [{"type": "impact", "object": "bell", "time": 0.1,
               "point": [0.1, 0, 0], "impulse": [-0.05, 0, 0]}]}
"""

_TOP = {"sample_rate", "duration", "microphones", "objects", "events", "full_scale_pa", "normalize", "dtype",
        "radiation", "seed", "speed_of_sound", "cull_db", "f_max"}
_OBJ = {"name", "model", "mesh", "material", "method", "quality", "position", "rotation"}
_EV = {
    "impact": ({"time", "point", "impulse"},
               {"pulse_s", "speed", "radius_m", "other_material", "other_mass_kg", "other_radius_m"}),
    "slide": ({"start", "end", "point", "normal", "normal_force", "speed"}, {"roughness"}),
    "roll": ({"start", "end", "point", "normal", "normal_force", "speed"}, {"roughness"}),
    "excite": ({"time", "point", "direction", "signal"}, set()),
}


def _err(where, msg):
    return ValueError(f"events file: {where}: {msg}")


def _num(x, where, positive=False, nonneg=False):
    if isinstance(x, bool) or not isinstance(x, (int, float)):
        raise _err(where, f"expected a number, got {x!r}")
    x = float(x)
    if not math.isfinite(x):
        raise _err(where, f"{x!r} is not finite")
    if positive and x <= 0:
        raise _err(where, f"{x!r} must be > 0")
    if nonneg and x < 0:
        raise _err(where, f"{x!r} must be >= 0")
    return x


def _vec(x, where, n=3):
    if not isinstance(x, (list, tuple)) or len(x) != n:
        raise _err(where, f"expected a list of {n} numbers, got {x!r}")
    return [_num(v, f"{where}[{i}]") for i, v in enumerate(x)]


def validate_events(spec: dict) -> dict:
    """Check an events spec (see :data:`EVENTS_HELP`) and return a normalised copy.

    Raises ``ValueError`` naming the offending field (e.g. ``events[2].time``).
    """
    if not isinstance(spec, dict):
        raise _err("top level", "must be a JSON object")
    unknown = set(spec) - _TOP
    if unknown:
        raise _err("top level", f"unknown field(s) {sorted(unknown)}; known: {sorted(_TOP)}")
    out = dict(spec)
    try:
        out["sample_rate"] = check_sample_rate(_num(spec.get("sample_rate", 48000), "sample_rate"), "sample_rate")
        if "duration" not in spec:
            raise _err("duration", "missing: give the length of the audio in seconds")
        out["duration"] = check_duration(_num(spec["duration"], "duration"), "duration")
    except ValueError as exc:
        msg = str(exc)
        raise (exc if msg.startswith("events file") else _err("top level", msg)) from None
    mics = spec.get("microphones", [[0.0, 0.0, 1.0]])
    if not isinstance(mics, list) or not mics:
        raise _err("microphones", "expected a non-empty list of [x, y, z]")
    out["microphones"] = [_vec(m, f"microphones[{i}]") for i, m in enumerate(mics)]
    objs = spec.get("objects")
    if not isinstance(objs, list) or not objs:
        raise _err("objects", "expected a non-empty list of objects")
    names = set()
    nobjs = []
    for i, o in enumerate(objs):
        w = f"objects[{i}]"
        if not isinstance(o, dict):
            raise _err(w, "expected an object")
        unk = set(o) - _OBJ
        if unk:
            raise _err(w, f"unknown field(s) {sorted(unk)}; known: {sorted(_OBJ)}")
        name = o.get("name")
        if not isinstance(name, str) or not name:
            raise _err(f"{w}.name", "missing or not a string")
        if name in names:
            raise _err(f"{w}.name", f"duplicate name {name!r}")
        names.add(name)
        if ("model" in o) == ("mesh" in o):
            raise _err(w, "give exactly one of 'model' (saved .npz) or 'mesh' (+ 'material')")
        if "mesh" in o and "material" not in o:
            raise _err(f"{w}.material", "required with 'mesh' (a name like 'steel' or 'E=..,nu=..,rho=..')")
        no = dict(o)
        no["position"] = _vec(o.get("position", [0, 0, 0]), f"{w}.position")
        rot = o.get("rotation", [[1, 0, 0], [0, 1, 0], [0, 0, 1]])
        if not isinstance(rot, list) or len(rot) != 3:
            raise _err(f"{w}.rotation", "expected a 3x3 matrix (list of 3 rows)")
        no["rotation"] = [_vec(r, f"{w}.rotation[{j}]") for j, r in enumerate(rot)]
        nobjs.append(no)
    out["objects"] = nobjs
    evs = spec.get("events", [])
    if not isinstance(evs, list):
        raise _err("events", "expected a list")
    nevs = []
    for i, e in enumerate(evs):
        w = f"events[{i}]"
        if not isinstance(e, dict):
            raise _err(w, "expected an object")
        typ = e.get("type")
        if typ not in _EV:
            raise _err(f"{w}.type", f"{typ!r} is not one of {sorted(_EV)}")
        if e.get("object") not in names:
            raise _err(f"{w}.object", f"{e.get('object')!r} is not an object name ({sorted(names)})")
        req, opt = _EV[typ]
        missing = req - set(e)
        if missing:
            raise _err(w, f"{typ} event lacks {sorted(missing)}")
        unk = set(e) - req - opt - {"type", "object"}
        if unk:
            raise _err(w, f"unknown field(s) {sorted(unk)} for a {typ} event")
        ne = dict(e)
        for k in ("point", "impulse", "normal", "direction"):
            if k in e:
                ne[k] = _vec(e[k], f"{w}.{k}")
        for k in ("time", "start", "end"):
            if k in e:
                ne[k] = _num(e[k], f"{w}.{k}", nonneg=True)
        for k in ("time", "start"):
            if k in ne and ne[k] > out["duration"]:
                raise _err(f"{w}.{k}", f"{ne[k]!r} s is after the end of the audio (duration {out['duration']:g} s): "
                                       "give times in seconds from the start, or lengthen duration")
        if typ in ("slide", "roll") and not any(ne["normal"]):
            raise _err(f"{w}.normal", "is [0, 0, 0]: give the contact normal, a nonzero vector pointing out of "
                                      "the object's surface (e.g. [0, 0, 1])")
        for k in ("normal_force", "speed", "pulse_s", "roughness"):
            if k in e and e[k] is not None:
                ne[k] = _num(e[k], f"{w}.{k}", nonneg=True)
        for k in ("radius_m", "other_mass_kg", "other_radius_m"):
            if k in e and e[k] is not None:
                ne[k] = _num(e[k], f"{w}.{k}", positive=True)
        if typ in ("slide", "roll") and ne["end"] < ne["start"]:
            raise _err(f"{w}.end", "must not be before start")
        if typ == "excite":
            if not isinstance(e["signal"], list):
                raise _err(f"{w}.signal", "expected a list of force samples in N")
            ne["signal"] = [_num(v, f"{w}.signal[{j}]") for j, v in enumerate(e["signal"])]
        nevs.append(ne)
    out["events"] = nevs
    return out


def load_events(path) -> dict:
    """Read and validate an EVENTS.json file; relative paths are resolved against its folder."""
    path = os.fspath(path)
    try:
        with open(path, encoding="utf-8") as fh:
            spec = json.load(fh)
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path}: not a text (UTF-8) JSON file ({exc.reason} at byte {exc.start}); give an "
                         "EVENTS.json file (format: mjsound render-events --help)") from None
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not valid JSON ({exc})") from None
    except RecursionError:
        raise ValueError(f"{path}: JSON nested too deeply to be an events file (format: mjsound render-events "
                         "--help)") from None
    spec = validate_events(spec)
    spec["_base_dir"] = os.path.dirname(os.path.abspath(path))
    return spec


def _resolve(p, base):
    p = str(p)
    if base and not os.path.isabs(p) and os.path.exists(os.path.join(base, p)):
        return os.path.join(base, p)
    return p


def _load_model(o, base, fs):
    from ..materials import parse_material
    from ..modal.model import ModalModel

    if "model" in o:
        model = ModalModel.load(_resolve(o["model"], base))
        if "material" in o:
            model = replace(model, material=parse_material(o["material"]))
        return model
    from ..modal.analyze import analyze  # lazy: only when a mesh must be analysed

    mesh = o["mesh"]
    if ":" not in str(mesh) or os.path.exists(_resolve(mesh, base)):
        mesh = _resolve(mesh, base)
    return analyze(mesh, parse_material(o["material"]), method=o.get("method", "hex"),
                   quality=o.get("quality", "default"), sample_rate=fs)


def render_events(spec: dict, base_dir=None):
    """Render an events spec (dict as in :data:`EVENTS_HELP`).

    Returns
    -------
    audio : (channels, n) float32 sound pressure [Pa], n = round(duration * sample_rate)
    sample_rate : int
    """
    from ..materials import parse_material
    from .synthesizer import Synthesizer

    base = base_dir if base_dir is not None else spec.get("_base_dir")
    spec = validate_events({k: v for k, v in spec.items() if k != "_base_dir"})
    fs = spec["sample_rate"]
    n = int(round(spec["duration"] * fs))
    check_array_bytes(8.0 * n * len(spec["microphones"]), f"{spec['duration']:g} s of audio at {fs} Hz",
                      "shorten duration or render in pieces")
    syn = Synthesizer(fs, microphones=spec["microphones"], dtype=spec.get("dtype", "float32"),
                      cull_db=spec.get("cull_db", -100.0), radiation=spec.get("radiation", True),
                      speed_of_sound=spec.get("speed_of_sound", 343.0), seed=spec.get("seed", 0),
                      f_max=spec.get("f_max"))
    for o in spec["objects"]:
        syn.add_object(o["name"], _load_model(o, base, fs), o["position"], np.array(o["rotation"]))
    for i, e in enumerate(sorted(spec["events"], key=lambda e: e.get("time", e.get("start", 0.0)))):
        try:
            t = e["type"]
            if t == "impact":
                om = e.get("other_material")
                syn.impact(e["object"], e["point"], e["impulse"], e["time"], pulse_s=e.get("pulse_s"),
                           other_material=None if om is None else parse_material(om),
                           other_mass_kg=e.get("other_mass_kg") or np.inf,
                           other_radius_m=e.get("other_radius_m") or np.inf,
                           speed=e.get("speed"), radius_m=e.get("radius_m"))
            elif t in ("slide", "roll"):
                kw = {"roughness": e["roughness"]} if "roughness" in e else {}
                getattr(syn, t)(e["object"], e["point"], e["normal"], e["normal_force"], e["speed"],
                                e["start"], e["end"], **kw)
            else:
                syn.excite(e["object"], e["point"], e["direction"], e["signal"], e["time"])
        except ValueError as exc:
            raise ValueError(f"events file: {t} event on {e['object']!r}: {exc}") from None
    return syn.render(n), fs
