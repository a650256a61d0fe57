"""Property-based fuzzing of the public entry points (issue 17): meshes, material specs,
events files, rollouts, CLI options and wrapper options. Whatever the input, the outcome is
a result or a ``ValueError`` / ``KeyError`` naming the input; never another exception, a
hang or NaN. Bounded to a few dozen examples each (well under a minute in all)."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from mjsound.sim.stub import stub_model

#: Deterministic (derandomize: the same examples on every run and machine), no example database.
COMMON = dict(deadline=None, derandomize=True, database=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
FAST = settings(max_examples=40, **COMMON)

numbers = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10**12, 10**12),
                    st.sampled_from([0, 1, -1, 1e-300, 1e300, 0.5, 48000, 16000]))
scalars = st.one_of(numbers, st.text(max_size=8), st.booleans(), st.none())
json_values = st.recursive(scalars, lambda c: st.one_of(st.lists(c, max_size=4),
                                                         st.dictionaries(st.text(max_size=8), c, max_size=4)),
                           max_leaves=20)


@pytest.fixture
def fake_analyze(monkeypatch):
    import mjsound.modal.analyze as an

    monkeypatch.setattr(an, "analyze", lambda mesh, material, **kw: stub_model(mesh, material, 6, 430.0))


@FAST
@given(st.lists(st.one_of(st.sampled_from(["steel", "glass", "oak", "unobtainium", "E", "nu", "rho", "alpha",
                                            "name", "=", ",", " "]), st.text(max_size=4),
                          numbers.map(str)), max_size=8).map("".join))
def test_material_specs(text):
    from mjsound import parse_material

    try:
        m = parse_material(text)
    except (ValueError, KeyError) as exc:
        assert str(exc)
        return
    assert math.isfinite(m.E) and m.E > 0 and math.isfinite(m.rho) and m.rho > 0 and -1 < m.nu < 0.5


@FAST
@given(st.sampled_from(["box", "sphere", "cylinder", "capsule", "bowl", "torus", ""]),
       st.lists(numbers, max_size=4))
def test_builtin_mesh_specs(kind, values):
    from mjsound.geometry import load_mesh

    spec = kind + ":" + ",".join(str(v) for v in values)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            tm = load_mesh(spec)
    except ValueError as exc:
        assert str(exc)
        return
    assert np.isfinite(tm.vertices).all() and len(tm.faces) > 0


@FAST
@given(st.integers(1, 6), st.integers(1, 6), st.lists(numbers, min_size=0, max_size=18),
       st.lists(st.integers(-3, 8), min_size=0, max_size=12))
def test_mesh_arrays(nv, nf, coords, idx):
    from mjsound.geometry import load_mesh

    v = (np.resize(np.asarray(coords or [0.0], dtype=np.float64), nv * 3)).reshape(nv, 3)
    f = np.resize(np.asarray(idx or [0], dtype=np.int64), nf * 3).reshape(nf, 3)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            tm = load_mesh((v, f))
    except ValueError as exc:
        assert str(exc)
        return
    assert np.isfinite(tm.vertices).all()


@FAST
@given(json_values)
def test_events_files_any_json(spec):
    from mjsound.synth.events import validate_events

    try:
        validate_events(spec)
    except ValueError as exc:
        assert str(exc).startswith("events file")


@FAST
@given(st.dictionaries(st.sampled_from(["sample_rate", "duration", "microphones", "seed", "cull_db"]), json_values,
                       max_size=3),
       st.lists(st.fixed_dictionaries({"type": st.sampled_from(["impact", "slide", "roll", "excite", "x"]),
                                       "object": st.sampled_from(["a", "b"]),
                                       "time": numbers, "start": numbers, "end": numbers,
                                       "point": st.lists(numbers, min_size=3, max_size=3),
                                       "impulse": st.lists(numbers, min_size=3, max_size=3),
                                       "normal": st.lists(numbers, min_size=3, max_size=3),
                                       "normal_force": numbers, "speed": numbers}), max_size=3))
def test_events_files_near_valid(top, events):
    from mjsound.synth.events import validate_events

    spec = {"sample_rate": 16000, "duration": 0.1, "objects": [{"name": "a", "mesh": "box:0.1,0.1,0.1",
                                                                "material": "steel"}], **top}
    spec["events"] = [{k: v for k, v in e.items() if k in _FIELDS.get(e["type"], e.keys())} for e in events]
    try:
        out = validate_events(spec)
    except ValueError as exc:
        assert str(exc).startswith("events file")
        return
    assert 1000 <= out["sample_rate"] <= 768000 and 0 < out["duration"] <= 86400
    for e in out["events"]:
        for k in ("time", "start"):
            if k in e:
                assert 0 <= e[k] <= out["duration"]


_FIELDS = {"impact": {"type", "object", "time", "point", "impulse"},
           "slide": {"type", "object", "start", "end", "point", "normal", "normal_force", "speed"},
           "roll": {"type", "object", "start", "end", "point", "normal", "normal_force", "speed"}}

XML = """<mujoco><option timestep="0.002"/>
  <custom><text name="mjsound:plate" data="steel"/></custom>
  <worldbody><geom name="plate" type="box" size="0.1 0.1 0.005"/>
    <body name="ball" pos="0 0 0.05"><freejoint/><geom name="ball" type="sphere" size="0.01"/></body>
  </worldbody></mujoco>"""


@FAST
@given(st.dictionaries(st.sampled_from(["time", "qpos", "qvel", "ctrl", "act", "mocap_pos", "junk"]),
                       st.tuples(st.lists(st.integers(0, 5), min_size=0, max_size=3),
                                 st.sampled_from(["f8", "f4", "i4", "u1", "c16", "U3", "?"]), numbers),
                       max_size=5))
def test_rollout_files(tmp_path_factory, arrays):
    import mujoco

    from mjsound.sim.rollout import load_rollout

    d = tmp_path_factory.mktemp("roll")
    np.savez(d / "r.npz", **{k: np.full(tuple(shape), fill if dt[0] not in "U?" else 1).astype(dt)
                             if dt[0] not in "U" else np.full(tuple(shape), "x", dtype=dt)
                             for k, (shape, dt, fill) in arrays.items()})
    model = mujoco.MjModel.from_xml_string(XML)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r = load_rollout(d / "r.npz", model)
    except ValueError as exc:
        assert "rollout" in str(exc)
        event("refused")
        return
    event("loaded")
    assert r["qpos"].shape[1] == model.nq and np.isfinite(r["time"]).all()


@settings(max_examples=25, **COMMON)
@given(st.one_of(st.none(), st.sampled_from(["0.02", "0", "-5", "inf", "nan", "1e7", "abc", "1e-9"])),
       st.sampled_from(["48000", "8000", "1", "100", "10000000", "0", "-48000"]),
       st.one_of(st.none(), st.sampled_from(["0.002", "1e-12", "0", "inf", "nan", "2", "-1"])),
       st.sampled_from(["out.wav", "out.flac", "out.mp3", "out", "."]))
def test_sonify_cli_options(tmp_path_factory, fake_analyze, duration, rate, timestep, out):
    import contextlib
    import io
    import os

    from mjsound.cli import main

    d = tmp_path_factory.mktemp("cli")
    (d / "scene.xml").write_text(XML)
    argv = ["sonify", str(d / "scene.xml"), "--sample-rate", rate, "-o", str(d / out), "--json"]
    if duration is not None:
        argv += ["--duration", duration]
    if timestep is not None:
        argv += ["--timestep", timestep]
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            code = main(argv)
        except SystemExit as exc:  # argparse: a value that is not a number
            code = exc.code
    assert code in (0, 2), err.getvalue()
    event(f"exit {code}")
    if code == 2:
        assert "error" in err.getvalue() and "Traceback" not in err.getvalue()
    else:
        assert os.path.getsize(d / out) > 0
    assert not [n for n in os.listdir(d) if n.startswith(".mjsound-tmp")]


@settings(max_examples=20, **COMMON)
@given(st.sampled_from([16000, 8000, 0, 1, 100, 10**7, 16000.5, float("nan")]),
       st.one_of(st.none(), st.sampled_from([0.05, 0.0, -1.0, float("nan"), float("inf"), 1e9, 1e-6])),
       st.sampled_from(["waveform", "spectrogram", "mel"]),
       st.sampled_from([256, 0, 1, 2, -5, 64]))
def test_wrapper_options(fake_analyze, rate, window_s, mode, n_fft):
    import gymnasium as gym

    from mjsound.wrappers import AudioObservation

    try:
        env = AudioObservation(gym.make("Ant-v5"), sample_rate=rate, window_s=window_s, mode=mode, n_fft=n_fft,
                               progress=False)
    except ValueError as exc:
        assert str(exc)
        event("refused")
        return
    event("built")
    obs, _ = env.reset(seed=0)
    obs, *_ = env.step(env.action_space.sample())
    assert np.isfinite(obs["audio"]).all() and env.observation_space["audio"].contains(obs["audio"])
    env.close()


@FAST
@given(st.one_of(st.lists(numbers, min_size=0, max_size=5),
                 st.lists(st.floats(0, 100), min_size=2, max_size=5, unique=True).map(sorted)),
       st.sampled_from([7, 6, 8]), st.sampled_from([6, 7]),
       st.sampled_from([0.0, 1.0, float("nan"), 1e300]))
def test_rollout_near_valid(tmp_path_factory, times, nq, nv, fill):
    import mujoco

    from mjsound.sim.rollout import load_rollout

    d = tmp_path_factory.mktemp("roll")
    T = len(times)
    q = np.full((T, nq), fill)
    if nq == 7 and T:
        q[:, 3] = 1.0
    np.savez(d / "r.npz", time=np.asarray(times, dtype=np.float64), qpos=q, qvel=np.zeros((T, nv)))
    model = mujoco.MjModel.from_xml_string(XML)
    try:
        r = load_rollout(d / "r.npz", model)
    except ValueError as exc:
        assert "rollout" in str(exc)
        event("refused")
        return
    event("loaded")
    assert T >= 2 and np.all(np.diff(r["time"]) > 0) and r["time"][-1] - r["time"][0] <= 86400
    assert np.isfinite(r["qpos"]).all()
