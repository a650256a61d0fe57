"""RerunLogger: write a recording, read it back with rerun's own reader (rerun.chunk.RrdReader),
check the entities, the sim_time timeline, the waveform samples, the audio asset and the
blueprint's audio view. Stub modal models keep it fast (no analysis)."""

from __future__ import annotations

import io
import sys

import mujoco
import numpy as np
import pytest

rr = pytest.importorskip("rerun")

from mjsound.sim import AudioSimulator, SoundScene  # noqa: E402
from mjsound.sim.stub import stub_model  # noqa: E402

FS = 16000
XML = """
<mujoco>
  <option timestep="0.001"/>
  <custom><text name="mjsound:ball" data="steel"/><text name="mjsound:plate" data="aluminium"/></custom>
  <worldbody>
    <geom name="floor" type="plane" size="1 1 .1" solref="-1e5 -120"/>
    <site name="mic0" pos="0.3 -0.5 0.3"/>
    <site name="mic1" pos="-0.3 -0.5 0.3"/>
    <body name="plate" pos="0 0 0.006"><geom name="plate" type="box" size="0.1 0.1 0.005" solref="-1e5 -120"/></body>
    <body name="ball" pos="0 0 0.08">
      <freejoint/>
      <geom name="ball" type="sphere" size="0.015" solref="-1e5 -120"/>
    </body>
  </worldbody>
</mujoco>"""


def _chunks(path, store=None):
    from rerun.chunk import RrdReader

    out = {}
    for ch in RrdReader(str(path)).stream(store=store):
        rb = ch.to_record_batch()
        out.setdefault(ch.entity_path, []).append((ch, rb))
    return out


def _col(entries, name):
    vals = []
    for _, rb in entries:
        if name in rb.schema.names:
            vals.extend(rb.column(name).to_pylist())
    return vals


def test_recording_round_trip(tmp_path):
    import soundfile as sf

    from mjsound.rerun_log import RerunLogger
    from mjsound.synth.output import normalize_peak

    model = mujoco.MjModel.from_xml_string(XML)
    data = mujoco.MjData(model)
    models = {"plate": stub_model("box:0.2,0.2,0.01", "aluminium", 6, 900.0)}
    scene = SoundScene.from_model(model, models=models, sample_rate=FS, progress=False)
    sim = AudioSimulator(model, data, scene=scene, sample_rate=FS, progress=False)
    path = tmp_path / "take.rrd"
    assert "rerun" in sys.modules  # (imported by this test; mjsound itself does not need it)
    with RerunLogger(path, model, sim=sim, n_fft=256, hop=64) as log:
        blocks = []
        for _ in range(250):
            mujoco.mj_step(model, data)
            b = sim.step()
            blocks.append(b)
            log.log_step(data, b)
    audio = np.concatenate(blocks, axis=1)
    assert sim.events["impact"] >= 1 and np.abs(audio).max() > 0
    assert audio.shape == (2, 250 * FS // 1000)

    ents = _chunks(path)
    for p in ("/world/ball", "/world/ball/ball", "/world/plate/plate", "/world/floor", "/world/contacts/points",
              "/world/contacts/forces", "/events", "/audio/mic0/waveform", "/audio/mic1/waveform",
              "/audio/mic0/spectrogram", "/audio/take"):
        assert p in ents, (p, sorted(ents))
    assert _col(ents["/world/ball/ball"], "Mesh3D:vertex_positions")
    assert any("Arrows3D:vectors" in rb.schema.names for _, rb in ents["/world/contacts/forces"])
    texts = _col(ents["/events"], "TextLog:text")
    assert len(texts) == sim.events["impact"] and "ball" in texts[0][0]
    # the ball's poses are on the sim_time timeline
    assert all("sim_time" in ch.timeline_names for ch, _ in ents["/world/ball"] if not ch.is_static)
    # every sample of each microphone, at t = n / fs
    for c, mic in enumerate(("mic0", "mic1")):
        e = ents[f"/audio/{mic}/waveform"]
        vals = np.array([v[0] for v in _col(e, "Scalars:scalars")])
        times = []
        for ch, rb in e:
            if "Scalars:scalars" in rb.schema.names:
                times.extend(rb.column("sim_time").cast("int64").to_pylist())
        order = np.argsort(times)
        np.testing.assert_array_equal(vals[order], audio[c].astype(np.float64))
        np.testing.assert_array_equal(np.array(times)[order], np.round(np.arange(audio.shape[1]) / FS * 1e9))
    # the audio asset: a WAV of both channels, peak-normalised, 16-bit
    blob = _col(ents["/audio/take"], "AssetAudio:blob")[0]
    raw = bytes(np.asarray(blob[0] if isinstance(blob[0], list) else blob, dtype=np.uint8))
    wav, sr = sf.read(io.BytesIO(raw), dtype="float64")
    assert sr == FS and wav.shape == (audio.shape[1], 2)
    np.testing.assert_allclose(wav.T, normalize_peak(audio), atol=1.5 / 32768)
    # the blueprint has an audio view on the asset
    from rerun.chunk import RrdReader

    bp = RrdReader(str(path)).blueprints()
    assert bp
    kinds = [v for e in _chunks(path, store=bp[0]).values() for v in _col(e, "ViewBlueprint:class_identifier")]
    assert ["Audio"] in kinds and ["3D"] in kinds and ["TimeSeries"] in kinds


def test_log_sonify(tmp_path, monkeypatch):
    """sonify + a recording: same audio as the summary, on the same sample grid."""
    from mjsound.rerun_log import log_sonify
    import mjsound.sim.scene as sc

    real = sc.SoundScene.from_model.__func__

    def with_stub(cls, model, *a, **kw):
        import mujoco

        # only this test's scene (sonify's kernel warm-up builds a scene of its own)
        if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "plate") >= 0:
            kw["models"] = {"plate": stub_model("box:0.2,0.2,0.01", "aluminium", 6, 900.0)}
        return real(cls, model, *a, **kw)

    monkeypatch.setattr(sc.SoundScene, "from_model", classmethod(with_stub))
    xml = tmp_path / "scene.xml"
    xml.write_text(XML)
    rrd = tmp_path / "s.rrd"
    s = log_sonify(rrd, xml, duration=0.2, sample_rate=FS, progress=False)
    assert s["rrd"] == str(rrd) and s["events"]["impact"] >= 1
    ents = _chunks(rrd)
    vals = np.array([v[0] for v in _col(ents["/audio/mic0/waveform"], "Scalars:scalars")])
    assert len(vals) == s["samples"] == 0.2 * FS
    np.testing.assert_array_equal(np.sort(vals), np.sort(s["audio"][0].astype(np.float64)))


def test_rerun_not_imported_by_mjsound():
    import subprocess

    code = ("import sys, mjsound, mjsound.wrappers, mjsound.sim.rollout, mjsound.rerun_log; "
            "assert 'rerun' not in sys.modules, 'rerun imported'")
    subprocess.run([sys.executable, "-c", code], check=True)
