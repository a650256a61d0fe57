"""Rollout sonification (resim / replay), the sonify/demo CLI and the demo assets."""

from __future__ import annotations

import os

import mujoco
import numpy as np
import pytest

from scenes import PLATE_BALL_XML

XML = PLATE_BALL_XML


def record(path, with_ctrl, every=1):
    model = mujoco.MjModel.from_xml_string(XML)
    data = mujoco.MjData(model)
    t, q, v = [], [], []
    for k in range(600):
        if k % every == 0:
            t.append(data.time)
            q.append(data.qpos.copy())
            v.append(data.qvel.copy())
        mujoco.mj_step(model, data)
    arrs = dict(time=np.array(t), qpos=np.array(q), qvel=np.array(v))
    if with_ctrl:
        arrs["ctrl"] = np.zeros((len(t), 0))
    np.savez(path, **arrs)


@pytest.mark.parametrize("mode", ["resim", "replay"])
def test_sonify_rollout(tmp_path, fake_analyze, mode):
    from mjsound.sim.rollout import sonify

    xml = tmp_path / "scene.xml"
    xml.write_text(XML)
    roll = tmp_path / "roll.npz"
    record(roll, with_ctrl=(mode == "resim"))
    out = tmp_path / "out.wav"
    s = sonify(xml, rollout=roll, out=out, progress=False)
    assert s["mode"] == mode
    assert s["samples"] == round(0.599 * 48000)  # frames 0..599 span 0.599 s
    assert s["events"]["impact"] >= 1 and s["peak_pa"] > 0
    assert np.isfinite(s["audio"]).all()
    if mode == "resim":
        assert s["max_qpos_error"] < 1e-9
    assert os.path.exists(out)
    import soundfile as sf

    a, fs = sf.read(out)
    assert fs == 48000 and len(a) == s["samples"]


def test_cli_has_sonify_and_demo(tmp_path, fake_analyze, capsys):
    from mjsound.cli import build_parser, main

    p = build_parser()
    args = p.parse_args(["sonify", "x.xml", "--duration", "1", "-o", "y.wav"])
    assert args.duration == 1.0 and args.output == "y.wav"
    xml = tmp_path / "scene.xml"
    xml.write_text(XML)
    rc = main(["sonify", str(xml), "--duration", "0.3", "-o", str(tmp_path / "o.wav")])
    assert rc == 0
    text = capsys.readouterr().out
    assert "plate" in text and "impacts" in text and "real time" in text


def test_demo_assets_are_deterministic_and_load(tmp_path):
    from mjsound.sim.demo import write_demo_assets

    p1 = write_demo_assets(tmp_path / "a")
    p2 = write_demo_assets(tmp_path / "b")
    for name in ("demo_scene.xml", "bowl.obj"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()
    model = mujoco.MjModel.from_xml_path(str(p1))
    names = {mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SITE, i) for i in range(model.nsite)}
    assert {"mic_left", "mic_right"} <= names
    assert model.nkey == 1
    repo = os.path.join(os.path.dirname(__file__), "..", "assets", "demo_scene.xml")
    if os.path.exists(repo):
        assert open(repo, "rb").read() == open(p2, "rb").read()
