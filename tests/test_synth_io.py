"""Output helpers (full scale, atomic streaming writer) and `mjsound render-events`."""

import argparse
import json
import os

import numpy as np
import pytest
import soundfile as sf

from mjsound import ModalModel, get_material
from mjsound.cli.events import register as register_cli
from mjsound.synth.events import EVENTS_HELP, render_events, validate_events
from mjsound.synth.output import AudioWriter, to_full_scale, write_audio


def test_to_full_scale_clips_and_counts():
    x = np.array([[0.0, 10.0, -30.0, 25.0, np.nan, np.inf]])
    y, n = to_full_scale(x, full_scale_pa=20.0)
    assert y.dtype == np.float32
    assert np.allclose(y, [[0, 0.5, -1, 1, 0, 0]])
    assert n == 4
    with pytest.raises(ValueError):
        to_full_scale(x, 0.0)


def test_audio_writer_streams_and_is_atomic(tmp_path):
    path = tmp_path / "a.wav"
    blocks = [np.random.default_rng(i).normal(size=(2, 1000)).astype(np.float32) * 0.1 for i in range(3)]
    with AudioWriter(path, 48000, 2) as w:
        for b in blocks:
            w.write(b)
        assert not path.exists()  # only the temp file exists while writing
    data, fs = sf.read(path, dtype="float32")
    assert fs == 48000 and np.array_equal(data.T, np.concatenate(blocks, axis=1))
    # an error inside the block leaves the previous file untouched and no temp file
    with pytest.raises(RuntimeError):
        with AudioWriter(path, 48000, 2) as w:
            w.write(blocks[0][:, :10])
            raise RuntimeError("boom")
    data2, _ = sf.read(path, dtype="float32")
    assert np.array_equal(data, data2)
    assert sorted(os.listdir(tmp_path)) == ["a.wav"]


def test_write_audio_flac_and_clipping(tmp_path):
    x = np.array([0.0, 5.0, 50.0, -50.0])
    n = write_audio(tmp_path / "b.flac", x, 16000, full_scale_pa=20.0)
    assert n == 2
    data, fs = sf.read(tmp_path / "b.flac")
    assert fs == 16000 and np.allclose(data, [0, 0.25, 1, -1], atol=1e-6)
    write_audio(tmp_path / "c.wav", x, 16000, normalize=True)
    assert abs(np.abs(sf.read(tmp_path / "c.wav")[0]).max() - 0.891) < 1e-6


def _model_file(tmp_path):
    m = ModalModel([300.0, 1200.0, 4000.0], [4.0, 8.0, 20.0], [[0, 0, 0], [0.05, 0, 0]], [[0, 0, 1], [1, 0, 0]],
                   np.random.default_rng(0).normal(size=(2, 3, 3)), [0.3, 1.0, 2.0], get_material("brass"),
                   mass_kg=0.2)
    m.save(tmp_path / "bell.npz")
    return "bell.npz"


def _spec(model_path):
    return {
        "sample_rate": 16000,
        "duration": 0.5,
        "objects": [{"name": "bell", "model": model_path, "position": [0, 0, 0]}],
        "microphones": [[0.5, 0, 0.3], [-0.5, 0, 0.3]],
        "events": [
            {"type": "impact", "object": "bell", "time": 0.1, "point": [0, 0, 0], "impulse": [0, 0, -0.05]},
            {"type": "impact", "object": "bell", "time": 0.2, "point": [0.05, 0, 0], "impulse": [-0.02, 0, 0],
             "other_material": "rubber", "other_mass_kg": 0.05},
            {"type": "slide", "object": "bell", "start": 0.3, "end": 0.4, "point": [0, 0, 0],
             "normal": [0, 0, 1], "normal_force": 2.0, "speed": 0.3},
            {"type": "roll", "object": "bell", "start": 0.35, "end": 0.45, "point": [0, 0, 0],
             "normal": [0, 0, 1], "normal_force": 2.0, "speed": 0.3},
        ],
    }


def test_render_events_cli(tmp_path, capsys):
    spec = _spec(_model_file(tmp_path))
    (tmp_path / "ev.json").write_text(json.dumps(spec))
    ap = argparse.ArgumentParser(prog="mjsound")
    sub = ap.add_subparsers(dest="command")
    p = register_cli(sub)
    assert "normal_force" in p.format_help() and "impulse" in EVENTS_HELP
    out = tmp_path / "out.wav"
    args = ap.parse_args(["render-events", str(tmp_path / "ev.json"), "-o", str(out)])
    assert args.func(args) == 0
    data, fs = sf.read(out)
    assert fs == 16000 and data.shape == (8000, 2)
    assert np.abs(data[: 1600 - 1]).max() == 0  # nothing before the first impact
    assert np.abs(data).max() > 0 and np.all(np.isfinite(data))
    assert "wrote" in capsys.readouterr().out
    # the same through the Python API, relative model path resolved with base_dir
    audio, fs2 = render_events(spec, base_dir=str(tmp_path))
    assert fs2 == 16000 and audio.shape == (2, 8000)


def test_events_validation_names_the_field(tmp_path):
    spec = _spec("bell.npz")
    bad = json.loads(json.dumps(spec))
    bad["events"][0]["time"] = "soon"
    with pytest.raises(ValueError, match=r"events\[0\]\.time"):
        validate_events(bad)
    bad = json.loads(json.dumps(spec))
    bad["events"][1]["object"] = "gong"
    with pytest.raises(ValueError, match=r"events\[1\]\.object"):
        validate_events(bad)
    bad = json.loads(json.dumps(spec))
    del bad["duration"]
    with pytest.raises(ValueError, match="duration"):
        validate_events(bad)
    bad = json.loads(json.dumps(spec))
    bad["objects"][0]["mesh"] = "box:0.1,0.1,0.1"
    with pytest.raises(ValueError, match="exactly one"):
        validate_events(bad)
