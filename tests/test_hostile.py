"""Hostile and mistaken inputs: each is refused before anything is allocated, with an error
naming the input and the fix (issue 17). Fast: no modal analysis (stub models)."""

from __future__ import annotations

import io
import json
import os
import zipfile

import numpy as np
import pytest

from mjsound.cli import main
from mjsound.sim.stub import stub_model
from scenes import PLATE_BALL_XML

XML = PLATE_BALL_XML


@pytest.fixture
def scene(tmp_path, monkeypatch):
    import mjsound.modal.analyze as an

    monkeypatch.setattr(an, "analyze", lambda mesh, material, **kw: stub_model(mesh, material, 8, 430.0))
    p = tmp_path / "scene.xml"
    p.write_text(XML)
    return str(p)


def cli_error(capsys, argv) -> str:
    """Run the CLI, expect exit status 2 with one error line; return that line."""
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2, err
    assert "error:" in err and "Traceback" not in err
    return err


# ---------------------------------------------------------------------- rates, durations, steps
@pytest.mark.parametrize("rate,shown", [("1", "1"), ("100", "100"), ("10000000", "1e+07")])
def test_sonify_refuses_implausible_sample_rates(scene, tmp_path, capsys, rate, shown):
    err = cli_error(capsys, ["sonify", scene, "--sample-rate", rate, "-o", str(tmp_path / "a.wav")])
    assert f"sample_rate={shown} Hz" in err and "1000..768000" in err
    assert not (tmp_path / "a.wav").exists()


@pytest.mark.parametrize("value,why", [("inf", "finite"), ("nan", "finite"), ("-5", "> 0"), ("1e7", "one day")])
def test_sonify_refuses_bad_durations(scene, tmp_path, capsys, value, why):
    err = cli_error(capsys, ["sonify", scene, "--duration", value, "-o", str(tmp_path / "a.wav")])
    assert "duration=" in err and why in err


def test_sonify_refuses_absurd_timestep(scene, tmp_path, capsys):
    err = cli_error(capsys, ["sonify", scene, "--timestep", "1e-12", "-o", str(tmp_path / "a.wav")])
    assert "timestep=1e-12" in err and "1e-06..1 s" in err


def _rollout(path, time, nq=7, nv=6, ctrl=False):
    T = len(time)
    arrs = dict(time=np.asarray(time, float), qpos=np.zeros((T, nq)), qvel=np.zeros((T, nv)))
    arrs["qpos"][:, 2] = 0.25
    arrs["qpos"][:, 3] = 1.0
    if ctrl:
        arrs["ctrl"] = np.zeros((T, 0))
    np.savez(path, **arrs)
    return str(path)


def test_rollout_time_span_in_nanoseconds_is_refused(scene, tmp_path):
    from mjsound.sim.rollout import sonify

    r = _rollout(tmp_path / "ns.npz", [0.0, 1e9])
    with pytest.raises(ValueError, match=r"time span.*1e\+09.*milliseconds or nanoseconds"):
        sonify(scene, rollout=r, progress=False)


def test_resim_step_count_is_checked_first(scene, tmp_path):
    from mjsound.sim.rollout import sonify

    r = _rollout(tmp_path / "long.npz", [0.0, 80000.0], ctrl=True)
    with pytest.raises(ValueError, match=r"8e\+10 physics steps"):
        sonify(scene, rollout=r, timestep=1e-6, progress=False, keep_audio=False)


def test_keeping_a_long_take_in_memory_is_checked(scene, monkeypatch):
    from mjsound.sim.rollout import sonify

    monkeypatch.setenv("MJSOUND_MAX_MEMORY_GB", "0.001")  # 1 MB
    with pytest.raises(ValueError, match=r"keeping 60 s of audio in memory.*keep_audio=False"):
        sonify(scene, duration=60.0, progress=False)


def _npz_with_header(path, arrays):
    """An .npz whose members claim the given shapes (header only: the data is not there)."""
    with zipfile.ZipFile(path, "w") as zf:
        for name, (shape, dtype) in arrays.items():
            buf = io.BytesIO()
            np.lib.format.write_array_header_1_0(buf, {"descr": np.dtype(dtype).str, "fortran_order": False,
                                                        "shape": shape})
            zf.writestr(name + ".npy", buf.getvalue() + b"\0" * 64)
    return str(path)


def test_rollout_that_would_inflate_is_refused_from_its_headers(scene, tmp_path):
    from mjsound.sim.rollout import load_rollout

    T = 10**8
    bomb = _npz_with_header(tmp_path / "bomb.npz", {"time": ((T,), "<f8"), "qpos": ((T, 7), "<f8"),
                                                    "qvel": ((T, 6), "<f8")})
    with pytest.raises(ValueError, match=r"rollout .*bomb.npz \(100000000 frames\) would take 11.2 GB"):
        load_rollout(bomb)


def test_rollout_with_a_third_axis_names_the_shape(scene, tmp_path):
    import mujoco

    from mjsound.sim.rollout import load_rollout

    p = tmp_path / "r.npz"
    np.savez(p, time=np.arange(3.0), qpos=np.zeros((3, 7, 1)), qvel=np.zeros((3, 6)))
    with pytest.raises(ValueError, match=r"'qpos' has shape \(3, 7, 1\); give \(3, model.nq\)"):
        load_rollout(p, mujoco.MjModel.from_xml_path(scene))


# ---------------------------------------------------------------------- output paths
def test_output_checks_happen_before_the_run(scene, tmp_path, capsys):
    err = cli_error(capsys, ["sonify", scene, "-o", str(tmp_path / "x.mp3")])
    assert "x.mp3" in err and "'.mp3' is not supported" in err and ".wav or .flac" in err
    err = cli_error(capsys, ["sonify", scene, "-o", str(tmp_path)])
    assert "is a directory" in err
    f = tmp_path / "a_file"
    f.write_text("x")
    err = cli_error(capsys, ["sonify-batch", str(tmp_path), "--scene", scene, "-o", str(f)])
    assert "is a file: give a directory" in err
    assert not [n for n in os.listdir(tmp_path) if n.startswith(".mjsound-tmp")]


def test_audio_writer_refuses_unknown_suffix(tmp_path):
    from mjsound.synth.output import AudioWriter

    with pytest.raises(ValueError, match=r"cannot write '.mp3' audio"):
        AudioWriter(tmp_path / "x.mp3", 48000, 1)


# ---------------------------------------------------------------------- materials, JSON
def test_materials_must_be_a_json_object(scene, tmp_path, capsys):
    err = cli_error(capsys, ["sonify", scene, "--materials", '["steel"]', "-o", str(tmp_path / "a.wav")])
    assert "--materials" in err and "JSON list" in err and '{"bowl": "porcelain"}' in err


def test_deeply_nested_json_is_named(scene, tmp_path, capsys):
    deep = tmp_path / "deep.json"
    deep.write_text("[" * 100000 + "]" * 100000)
    err = cli_error(capsys, ["render-events", str(deep), "-o", str(tmp_path / "a.wav")])
    assert "deep.json" in err and "nested too deeply" in err
    err = cli_error(capsys, ["sonify", scene, "--materials", str(deep), "-o", str(tmp_path / "a.wav")])
    assert "--materials" in err and "nested too deeply" in err


def test_junk_bytes_as_events_file_names_the_file(tmp_path, capsys):
    junk = tmp_path / "junk.json"
    junk.write_bytes(bytes(range(128, 256)) * 10)
    err = cli_error(capsys, ["render-events", str(junk)])
    assert "junk.json" in err and "not a text (UTF-8) JSON file" in err


# ---------------------------------------------------------------------- events
def _events(tmp_path, **over):
    m = stub_model("box:0.1,0.1,0.1", "steel", 4, 500.0)
    m.save(tmp_path / "m.npz")
    spec = {"sample_rate": 16000, "duration": 0.2, "objects": [{"name": "a", "model": str(tmp_path / "m.npz")}],
            "events": [{"type": "impact", "object": "a", "time": 0.01, "point": [0, 0, 0.05],
                        "impulse": [0, 0, -0.01]}]}
    spec.update(over)
    return spec


def test_events_duration_and_times_are_checked(tmp_path, monkeypatch):
    from mjsound.synth.events import render_events, validate_events

    with pytest.raises(ValueError, match=r"duration=1e\+09 s .*one day"):
        validate_events(_events(tmp_path, duration=1e9))
    late = _events(tmp_path)
    late["events"][0]["time"] = 1e300
    with pytest.raises(ValueError, match=r"events\[0\]\.time: 1e\+300 s is after the end of the audio"):
        validate_events(late)
    monkeypatch.setenv("MJSOUND_MAX_MEMORY_GB", "0.001")
    with pytest.raises(ValueError, match=r"100 s of audio at 16000 Hz would take .* GB"):
        render_events(_events(tmp_path, duration=100.0))


def test_slide_with_zero_normal_is_refused(tmp_path):
    from mjsound.synth.events import validate_events

    spec = _events(tmp_path)
    spec["events"] = [{"type": "slide", "object": "a", "start": 0.0, "end": 0.1, "point": [0, 0, 0.05],
                       "normal": [0, 0, 0], "normal_force": 1.0, "speed": 0.2}]
    with pytest.raises(ValueError, match=r"events\[0\]\.normal: is \[0, 0, 0\]"):
        validate_events(spec)


def test_events_sample_rate_range(tmp_path):
    from mjsound.synth.events import validate_events

    for fs in (1, 100, 1e7):
        with pytest.raises(ValueError, match=r"1000\.\.768000 Hz"):
            validate_events(_events(tmp_path, sample_rate=fs))


# ---------------------------------------------------------------------- cache
def test_cache_entry_without_metadata_field_is_recomputed(tmp_path):
    import mjsound.modal.analyze as an
    from mjsound.modal.model import ModalModel

    kw = dict(resolution=2, f_max=20000.0, error_estimate=False)
    first = an.analyze("box:0.05,0.04,0.03", "aluminium", **kw)
    (entry,) = [os.path.join(an.cache_dir(), n) for n in os.listdir(an.cache_dir()) if n.endswith(".npz")]
    with np.load(entry) as z:
        arrays = {k: z[k] for k in z.files}
    meta = json.loads(str(arrays["meta"]))
    del meta["material"]["rho"], meta["method"]
    arrays["meta"] = np.array(json.dumps(meta))
    with open(entry, "wb") as fh:
        np.savez(fh, **arrays)
    with pytest.raises(ValueError, match="not a valid mjsound model"):
        ModalModel.load(entry)
    with pytest.warns(UserWarning, match="corrupt"):
        again = an.analyze("box:0.05,0.04,0.03", "aluminium", **kw)
    np.testing.assert_allclose(again.frequencies_hz, first.frequencies_hz)
    assert ModalModel.load(entry).method == first.method  # rewritten whole


# ---------------------------------------------------------------------- gymnasium wrapper
@pytest.mark.parametrize("kw,match", [
    (dict(sample_rate=0), r"sample_rate=0 Hz is not a plausible audio rate"),
    (dict(sample_rate=100), r"1000\.\.768000"),
    (dict(sample_rate=1e7), r"1000\.\.768000"),
    (dict(window_s=float("nan")), r"window_s=nan must be a finite number"),
    (dict(window_s=1e9), r"window_s=1e\+09 s is longer than"),
    (dict(mode="spectrogram", n_fft=0), r"n_fft=0 must be an integer >= 2"),
])
def test_wrapper_options_are_named(kw, match):
    import gymnasium as gym

    from mjsound.wrappers import AudioObservation

    with pytest.raises(ValueError, match=match):
        AudioObservation(gym.make("Ant-v5"), **kw)


def test_wrapper_step_after_close_raises(scene):
    import gymnasium as gym

    from mjsound.wrappers import AudioObservation

    env = AudioObservation(gym.make("Ant-v5"), sample_rate=8000)
    env.reset(seed=0)
    env.step(env.action_space.sample())
    env.close()
    with pytest.raises(RuntimeError, match=r"step\(\) after close\(\)"):
        env.step(env.action_space.sample())


def test_atomic_open_and_stale_temp_sweep(tmp_path):
    import subprocess
    import sys

    import mjsound.io as mio

    target = tmp_path / "report.md"
    target.write_text("old")
    with pytest.raises(KeyboardInterrupt):
        with mio.atomic_open(target) as fh:
            fh.write("half")
            raise KeyboardInterrupt
    assert target.read_text() == "old" and os.listdir(tmp_path) == ["report.md"]
    with mio.atomic_open(target) as fh:
        fh.write("new")
    assert target.read_text() == "new" and os.listdir(tmp_path) == ["report.md"]
    # temp files of a finished process of this host go; a live process's (ours) and other hosts' stay
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    host = mio._host()
    names = [f"{mio.TEMP_PREFIX}{host}-{dead.stdout.strip()}-abc.wav", f"{mio.TEMP_PREFIX}{host}-{os.getpid()}-x.wav",
             f"{mio.TEMP_PREFIX}otherhost-{dead.stdout.strip()}-y.wav"]
    for n in names:
        (tmp_path / n).write_bytes(b"x")
    removed = mio.remove_stale_temps(tmp_path)
    assert [os.path.basename(p) for p in removed] == names[:1]
    assert sorted(os.listdir(tmp_path)) == sorted(["report.md", *names[1:]])


@pytest.mark.parametrize("normalize", [False, True])
def test_streamed_file_equals_the_whole_take(scene, tmp_path, normalize):
    """The take written block by block is the file the whole array would give (also with the
    second, normalising pass), and the warm-up block is timed apart."""
    import soundfile as sf

    from mjsound.sim.rollout import sonify
    from mjsound.synth.output import normalize_peak, to_full_scale

    s = sonify(scene, duration=2.5, out=tmp_path / "a.wav", normalize=normalize, progress=False)
    got, fs = sf.read(tmp_path / "a.wav", dtype="float32", always_2d=True)
    want = normalize_peak(s["audio"]) if normalize else to_full_scale(s["audio"], 20.0)[0]
    assert fs == 48000 and got.shape == (120000, 1)
    np.testing.assert_array_equal(got.T, want)
    assert 0 < s["warmup_seconds"] < s["wall_seconds"] and np.isfinite(s["realtime_factor"])
    assert s["timed_wall_seconds"] + s["warmup_seconds"] <= s["wall_seconds"] + 1e-9
    assert s["realtime_factor"] == pytest.approx(s["timed_sim_seconds"] / s["timed_wall_seconds"])
    assert not [n for n in os.listdir(tmp_path) if n.startswith(".mjsound-tmp")]


def test_analyze_checks_its_options_first(tmp_path, capsys):
    err = cli_error(capsys, ["analyze", "box:0.1,0.1,0.1", "--sample-rate", "100"])
    assert "--sample-rate=100 Hz" in err and "1000..768000" in err
    err = cli_error(capsys, ["analyze", "box:0.1,0.1,0.1", "-o", str(tmp_path / "m.txt")])
    assert "'.txt' is not supported; use .npz" in err


def test_analyze_memory_cap_option_reaches_the_analysis(capsys):
    err = cli_error(capsys, ["analyze", "box:10,1,1", "--quality", "draft", "--max-memory-gb", "0.01",
                             "--over-budget", "refuse", "--no-cache"])
    assert "over the cap of 0.01 GB" in err


def test_sonify_memory_cap_option_reaches_the_arrays(scene, tmp_path, capsys):
    r = _rollout(tmp_path / "r.npz", np.arange(600) * 0.001)  # 600 frames x 14 numbers: 67 kB as float64
    before = os.environ.get("MJSOUND_MAX_MEMORY_GB")
    err = cli_error(capsys, ["sonify", scene, "--rollout", r, "--max-memory-gb", "1e-5", "-o", str(tmp_path / "a.wav")])
    assert "(600 frames) would take 6.72e-05 GB of memory, over the 1e-05 GB cap" in err
    assert os.environ.get("MJSOUND_MAX_MEMORY_GB") == before  # restored after the run
