"""``warmup()`` compiles (or loads) every kernel a take uses, so that speed figures taken after
it (``sonify``'s real-time factor) time no compilation."""

import json
import os
import subprocess
import sys

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")

CHILD = r'''
import importlib, json, pkgutil, warnings
import mujoco, numpy as np
from numba.core.registry import CPUDispatcher
import mjsound.sim, mjsound.synth
from mjsound.sim.warmup import warmup

disp = {}
for pkg in (mjsound.sim, mjsound.synth):
    for m in pkgutil.iter_modules(pkg.__path__):
        mod = importlib.import_module(f"{pkg.__name__}.{m.name}")
        disp.update({f"{mod.__name__}.{k}": v for k, v in vars(mod).items() if isinstance(v, CPUDispatcher)})
warmup(verbose=False)
before = {k: len(d.signatures) for k, d in disp.items()}
assert warmup(verbose=False, once=True) == 0.0

from mjsound.sim import AudioSimulator
from mjsound.sim.scene import SoundScene
from mjsound.sim.stub import stub_model
XML = """<mujoco><option timestep="0.001"/>
<custom><text name="mjsound:plate" data="aluminium"/><text name="mjsound:ball" data="steel"/></custom>
<worldbody><geom name="floor" type="plane" size="2 2 .1"/><site name="mic0" pos="0.3 0 0.4"/>
  <body name="plate" pos="0 0 0.01"><freejoint/><geom name="plate" type="box" size="0.1 0.1 0.01"/>
    <site name="contact_mic_plate" pos="0 0 0.01"/></body>
  <body name="ball" pos="0.02 0 0.1"><freejoint/><geom name="ball" type="sphere" size="0.015"/></body>
</worldbody></mujoco>"""
model = mujoco.MjModel.from_xml_string(XML)
data = mujoco.MjData(model)
data.qvel[6] = 0.4  # the ball falls onto the plate and rolls off onto the floor
models = {"plate": stub_model("box:0.2,0.2,0.02", "aluminium", 6, 900.0),
          "ball": stub_model("sphere:0.015", "steel", 4, 4000.0)}
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    scene = SoundScene.from_model(model, models=models, progress=False)
sim = AudioSimulator(model, data, scene=scene, sample_rate=48000)
audio = [sim.run(0.3)]
for _ in range(30):
    sim.advance(5, render=False)
    audio.append(sim.flush())
impacts = sim.n_impacts
sim.follow(2, np.zeros((sim.n_air, 3)))
sim.reset()
audio.append(sim.run(0.05))
audio = np.concatenate(audio, axis=1)
after = {k: len(d.signatures) for k, d in disp.items()}
print(json.dumps({"new": sorted(k for k in disp if after[k] != before[k]), "impacts": impacts,
                  "streams": sim.synth.n_streams, "peak": float(np.abs(audio).max()),
                  "channels": int(sim.n_channels)}))
'''


def test_warmup_compiles_every_kernel_a_take_uses():
    """In a fresh process: after ``warmup()``, a scene with impacts, sliding and rolling,
    clicks, a contact microphone, fused substeps and a following listener needs no kernel
    signature that the warm-up did not make (numba compiles or loads nothing more)."""
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    out = subprocess.run([sys.executable, "-c", CHILD], env=env, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    res = json.loads(out.stdout.strip().splitlines()[-1])
    assert res["impacts"] > 0 and res["streams"] > 0 and res["peak"] > 0 and res["channels"] == 2
    assert res["new"] == []


def test_kernels_cached_follows_the_sources(monkeypatch):
    """``kernels_cached`` is true once the step kernel of these sources is in numba's cache,
    and false when the cache's stamp is another one (after an edit or a ``git pull``): the
    first-compile notice then says so instead of a silent half-minute."""
    from mjsound.sim.step import advance
    from mjsound.sim.warmup import kernel_cache_dir, kernels_cached, warmup

    warmup(verbose=False, once=True)
    assert kernels_cached()
    assert os.path.isdir(kernel_cache_dir())
    monkeypatch.setattr(advance._cache._cache_file, "_source_stamp", b"another version of the sources")
    assert not kernels_cached()


def test_cli_warmup_compiles_every_group(capsys):
    """``mjsound warmup`` runs the per-step, wrapper and modal kernels and says where the cache is."""
    from mjsound.cli import main
    from mjsound.sim.warmup import warmup

    warmup(verbose=False, once=True)  # (the cache is filled: the command says it loads)
    assert main(["warmup"]) == 0
    out, err = capsys.readouterr()
    assert "numba cache" in err and "(filled: loading)" in err
    parts = dict(p.split()[:2] for p in out.strip().removeprefix("mjsound warmup: ").split("; ")[0].split(", "))
    assert set(parts) == {"sim", "wrapper", "modal"} and all(float(v) >= 0 for v in parts.values())
