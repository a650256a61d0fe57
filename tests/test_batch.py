"""Batch sonification (mjsound.batch): local process pool and Ray, identical to serial `sonify`.

The driver's modal analysis is replaced by a fast stub (monkeypatched in this process only):
workers that recomputed models would run the real analysis and produce different audio, so
"identical to serial" also proves that the models were shared, not recomputed per task.
"""

from __future__ import annotations

import json
import os

import mujoco
import numpy as np
import pytest
import soundfile as sf


XML = """
<mujoco>
  <option timestep="0.001"/>
  <custom>
    <text name="mjsound:floor" data="oak"/>
    <text name="mjsound:plate" data="steel"/>
    <text name="mjsound:block" data="aluminium"/>
  </custom>
  <worldbody>
    <geom name="floor" type="plane" size="1 1 .1"/>
    <body name="plate" pos="0 0 0.05"><freejoint/>
      <geom name="plate" type="box" size="0.08 0.05 0.004" solref="-1e5 -120"/></body>
    <body name="block" pos="0.1 0 0.08"><freejoint/>
      <geom name="block" type="box" size="0.02 0.02 0.02" solref="-1e5 -120"/></body>
  </worldbody>
</mujoco>"""

N_ROLLOUTS = 8
STEPS = 300  # 0.3 s each


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    """SCENE.xml and 8 rollouts (with ctrl: re-simulated) of two boxes dropping onto a floor."""
    d = tmp_path_factory.mktemp("rollouts")
    scene = d / "scene.xml"
    scene.write_text(XML)
    model = mujoco.MjModel.from_xml_string(XML)
    paths = []
    for k in range(N_ROLLOUTS):
        data = mujoco.MjData(model)
        data.qpos[2] = 0.03 + 0.01 * k
        data.qvel[3:6] = [0.5 * k, -0.3, 0.2]
        data.qvel[6 + 2] = -0.2 * k
        t, q, v = [], [], []
        for _ in range(STEPS):
            t.append(data.time)
            q.append(data.qpos.copy())
            v.append(data.qvel.copy())
            mujoco.mj_step(model, data)
        p = d / f"roll{k:02d}.npz"
        np.savez(p, time=np.array(t), qpos=np.array(q), qvel=np.array(v), ctrl=np.zeros((STEPS, 0)))
        paths.append(str(p))
    return str(scene), paths


def serial(scene, paths):
    """Reference: one direct `sonify` call per rollout (what `mjsound sonify` writes)."""
    from mjsound.sim.rollout import sonify

    return {os.path.splitext(os.path.basename(p))[0]: sonify(scene, rollout=p, progress=False)["audio"] for p in paths}


def assert_same_as(ref, outdir):
    from mjsound.synth.output import DEFAULT_FULL_SCALE_PA, to_full_scale

    for stem, audio in ref.items():
        got, fs = sf.read(os.path.join(outdir, stem + ".wav"), dtype="float32", always_2d=True)
        want, _ = to_full_scale(audio, DEFAULT_FULL_SCALE_PA)
        assert fs == 48000
        assert np.abs(want).max() > 0, stem
        # Same samples to float32 rounding: a fresh environment showed 1-ulp differences
        # between a pool worker and the parent (vectorised float32 sums); a worker that
        # re-analysed a model would differ by orders of magnitude more.
        assert np.max(np.abs(got.T - want)) <= 1e-5 * np.abs(want).max(), stem  # -100 dB


def no_temp_files(outdir):
    return [f for f in os.listdir(outdir) if f.startswith(".tmp")] == []


# ---------------------------------------------------------------------- local pool
def test_local_pool_identical_despite_crash_and_bad_rollout(dataset, tmp_path, fake_analyze, monkeypatch):
    from mjsound.batch import sonify_batch

    scene, paths = dataset
    bad = tmp_path / "broken.npz"
    bad.write_text("not a rollout")
    marker = tmp_path / "crashed"
    monkeypatch.setenv("MJSOUND_BATCH_TEST_CRASH_ONCE", str(marker))
    out = tmp_path / "out"
    s = sonify_batch(paths + [str(bad)], scene, out, workers=2, progress=False)
    assert marker.exists()  # a worker did die mid-run ...
    assert s["pool_restarts"] >= 1  # ... and the pool was rebuilt
    assert s["backend"] == "local" and s["workers"] == 2
    assert sorted(s["done"]) == [f"roll{k:02d}" for k in range(N_ROLLOUTS)]
    assert [f["stem"] for f in s["failed"]] == ["broken"]
    assert "cannot read" in s["failed"][0]["error"]
    assert not (out / "broken.wav").exists() and not (out / "broken.json").exists()
    assert no_temp_files(out)
    assert fake_analyze  # the driver analysed (once per sounding geom) ...
    assert len(fake_analyze) == 2
    assert_same_as(serial(scene, paths), out)  # ... and the workers used exactly those models
    assert s["audio_seconds"] == pytest.approx(N_ROLLOUTS * (STEPS - 1) * 1e-3, rel=1e-3)
    assert s["throughput"] > 0


def test_missing_ray_is_a_clear_error(dataset, tmp_path, fake_analyze, monkeypatch):
    import sys

    from mjsound.batch import sonify_batch

    monkeypatch.setitem(sys.modules, "ray", None)
    scene, paths = dataset
    with pytest.raises(ImportError, match=r"mjsound\[batch\]"):
        sonify_batch(paths[:1], scene, tmp_path / "o", address="auto", progress=False)


def test_duplicate_stems_rejected(dataset, tmp_path):
    from mjsound.batch import sonify_batch

    scene, paths = dataset
    other = tmp_path / "x"
    other.mkdir()
    dup = other / os.path.basename(paths[0])
    dup.write_bytes(open(paths[0], "rb").read())
    with pytest.raises(ValueError, match="two rollouts"):
        sonify_batch([paths[0], str(dup)], scene, tmp_path / "o", progress=False)


# ---------------------------------------------------------------------- Ray
@pytest.fixture(scope="module")
def ray_local():
    ray = pytest.importorskip("ray")
    import logging

    ray.init(num_cpus=2, include_dashboard=False, logging_level=logging.WARNING, log_to_driver=False)
    yield ray
    ray.shutdown()


def test_ray_identical_to_serial_and_resumable(dataset, tmp_path, fake_analyze, ray_local):
    from mjsound.batch import sonify_batch

    scene, paths = dataset
    out = tmp_path / "out"
    s = sonify_batch(paths, scene, out, workers=2, address="auto", progress=False)
    assert s["backend"] == "ray" and not s["failed"] and len(s["done"]) == N_ROLLOUTS
    assert len({r["pid"] for r in s["results"]}) >= 1
    ref = serial(scene, paths)
    assert_same_as(ref, out)

    # a rerun skips everything (no analysis, no task)
    n_analyses = len(fake_analyze)
    s2 = sonify_batch(paths, scene, out, workers=2, address="auto", progress=False)
    assert s2["skipped"] == s["done"] and s2["done"] == [] and len(fake_analyze) == n_analyses

    # damaged outputs are redone: a truncated WAV, a missing sidecar, a WAV with other samples,
    # a sidecar of other parameters
    wav = out / "roll01.wav"
    wav.write_bytes(wav.read_bytes()[:-1000])
    (out / "roll02.json").unlink()
    a, fs = sf.read(out / "roll03.wav", dtype="float32")
    sf.write(out / "roll03.wav", a * 0.5, fs, subtype="FLOAT")
    meta = json.loads((out / "roll04.json").read_text())
    meta["params"]["sample_rate"] = 44100
    (out / "roll04.json").write_text(json.dumps(meta))
    s3 = sonify_batch(paths, scene, out, workers=2, address="auto", progress=False)
    assert s3["done"] == ["roll01", "roll02", "roll03", "roll04"]
    assert len(s3["skipped"]) == N_ROLLOUTS - 4 and not s3["failed"]
    assert_same_as(ref, out)
    assert no_temp_files(out)


def test_ray_worker_killed_mid_run_still_completes(dataset, tmp_path, fake_analyze, ray_local, monkeypatch):
    from mjsound.batch import sonify_batch

    scene, paths = dataset
    marker = tmp_path / "crashed"
    monkeypatch.setenv("MJSOUND_BATCH_TEST_CRASH_ONCE", str(marker))
    out = tmp_path / "out"
    s = sonify_batch(paths, scene, out, workers=2, address="auto", max_retries=2, progress=False)
    assert marker.exists()  # one task's worker process died (os._exit) and Ray retried it
    assert not s["failed"] and len(s["done"]) == N_ROLLOUTS
    assert_same_as(serial(scene, paths), out)
    assert no_temp_files(out)


def test_ray_cli_failing_rollout_reported(dataset, tmp_path, fake_analyze, ray_local, capsys):
    from mjsound.cli import main

    scene, paths = dataset
    bad = tmp_path / "bad.npz"
    np.savez(bad, time=np.array([0.0, 0.001]), qpos=np.zeros((2, 3)), qvel=np.zeros((2, 12)))  # wrong width
    out = tmp_path / "out"
    rc = main(["sonify-batch", *paths[:3], str(bad), "--scene", scene, "-o", str(out), "--address", "auto",
               "--workers", "2", "--json"])
    assert rc == 1  # non-zero: a rollout failed
    s = json.loads(capsys.readouterr().out)
    assert sorted(s["done"]) == ["roll00", "roll01", "roll02"]
    assert len(s["failed"]) == 1 and s["failed"][0]["stem"] == "bad" and "qpos" in s["failed"][0]["error"]
    assert (out / "roll00.wav").exists() and not (out / "bad.wav").exists()
