"""Offline rendering of a timed list of events (``mjsound render-events EVENTS.json``).

See :data:`EVENTS_HELP` for the file format (it is also the command's ``--help``).
"""

from __future__ import annotations

import argparse
import json
import math
import os
from dataclasses import replace

import numpy as np

__all__ = ["EVENTS_HELP", "load_events", "validate_events", "render_events", "register_cli", "main"]

EVENTS_HELP = """\
Render a list of timed excitation events on modal objects to an audio file, without a
simulator. EVENTS.json is one JSON object; all coordinates are world coordinates in metres,
all quantities SI (s, N, N s, m/s, kg, Pa). Relative paths are relative to the JSON file.

Top level
  sample_rate   int, Hz (default 48000; 1000..768000)
  duration      float, seconds of audio to render (required, > 0)
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
    out["sample_rate"] = int(_num(spec.get("sample_rate", 48000), "sample_rate", positive=True))
    if "duration" not in spec:
        raise _err("duration", "missing: give the length of the audio in seconds")
    out["duration"] = _num(spec["duration"], "duration", positive=True)
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
        with open(path) as fh:
            spec = json.load(fh)
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not valid JSON ({exc})") from None
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
    syn = Synthesizer(fs, microphones=spec["microphones"], dtype=spec.get("dtype", "float32"),
                      cull_db=spec.get("cull_db", -100.0), radiation=spec.get("radiation", True),
                      speed_of_sound=spec.get("speed_of_sound", 343.0), seed=spec.get("seed", 0),
                      f_max=spec.get("f_max"))
    for o in spec["objects"]:
        syn.add_object(o["name"], _load_model(o, base, fs), o["position"], np.array(o["rotation"]))
    n = int(round(spec["duration"] * fs))
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


def _handler(args) -> int:
    from .output import DEFAULT_FULL_SCALE_PA, write_audio

    spec = load_events(args.events)
    if args.sample_rate is not None:
        spec["sample_rate"] = args.sample_rate
    audio, fs = render_events(spec)
    out = args.output or os.path.splitext(args.events)[0] + ".wav"
    fsp = args.full_scale_pa if args.full_scale_pa is not None else spec.get("full_scale_pa", DEFAULT_FULL_SCALE_PA)
    normalize = args.normalize or bool(spec.get("normalize", False))
    n_clipped = write_audio(out, audio, fs, full_scale_pa=fsp, normalize=normalize)
    peak = float(np.abs(audio).max()) if audio.size else 0.0
    msg = f"wrote {out}: {audio.shape[0]} channel(s), {audio.shape[1]} samples at {fs} Hz, peak {peak:.3g} Pa"
    if not normalize:
        msg += f", full scale {fsp:g} Pa, {n_clipped} clipped sample(s)"
    print(msg)
    return 0


def register_cli(subparsers) -> argparse.ArgumentParser:
    """Add the ``render-events`` subcommand to an argparse ``subparsers`` object.

    The handler is stored as ``func`` (``args.func(args)`` returns the exit code).
    """
    p = subparsers.add_parser(
        "render-events",
        help="render a JSON list of timed impacts/slides/rolls to a WAV/FLAC file",
        description=EVENTS_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("events", help="EVENTS.json (format above)")
    p.add_argument("-o", "--output", help="output .wav or .flac (default: EVENTS.wav next to the JSON)")
    p.add_argument("--full-scale-pa", type=float, default=None,
                   help="pressure [Pa] mapped to full scale (default: the file's full_scale_pa or 20)")
    p.add_argument("--normalize", action="store_true", help="peak-normalise to -1 dBFS (loses the level)")
    p.add_argument("--sample-rate", type=int, default=None, help="override the file's sample_rate [Hz]")
    p.set_defaults(func=_handler)
    return p


def main(argv=None) -> int:
    """Stand-alone entry point: ``python -m mjsound.synth.events EVENTS.json -o out.wav``."""
    ap = argparse.ArgumentParser(prog="mjsound")
    sub = ap.add_subparsers(dest="command", required=True)
    register_cli(sub)
    args = ap.parse_args(["render-events", *(argv if argv is not None else __import__("sys").argv[1:])])
    return args.func(args)


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
