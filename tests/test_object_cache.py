"""The scene's object cache: a process whose objects were all analysed before loads their
models by what they are made of (geoms, meshes, material, options), without meshing,
planning or importing the analysis stack (issue 18, quick first start)."""

from __future__ import annotations

import os
import subprocess
import sys
import warnings

import mujoco
import numpy as np
import pytest

import mjsound.sim.scene_analysis as sa
from mjsound.sim.scene import SoundScene
from tests.scenes import TABLE_XML, table_model

OPTS = dict(materials={"table": "oak", "floor": "concrete"}, sample_rate=16000, quality="draft", method="hex",
            progress=False)


def build(model=None, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # (the floor is a plane: nothing to analyse; masses differ)
        return SoundScene.from_model(model or table_model(), **{**OPTS, **kw})


def entries():
    d = os.path.join(os.environ["MJSOUND_CACHE_DIR"], "objects")
    return sorted(os.listdir(d)) if os.path.isdir(d) else []


def test_a_second_scene_loads_every_object_without_analysing(monkeypatch):
    first = build()
    (table,) = first.sounding
    assert table.mesh.startswith("union of 2 geoms (") and len(entries()) == 1

    def refuse(*a, **k):
        raise AssertionError("analysed although cached")

    monkeypatch.setattr(sa, "_analyze_with_fallback", refuse)
    again = build()
    (t2,) = again.sounding
    assert t2.mesh == table.mesh and t2.notes == table.notes and t2.method == table.method
    np.testing.assert_array_equal(t2.model.frequencies_hz, table.model.frequencies_hz)
    np.testing.assert_array_equal(t2.model.shapes, table.model.shapes)
    assert "object_cache" not in t2.model.info

    # anything the surface or the analysis depends on is a new entry
    for change in [dict(quality="default"), dict(sample_rate=22050), dict(materials={"table": "steel"}),
                   dict(model=mujoco.MjModel.from_xml_string(_moved_leg_xml()))]:
        with pytest.raises(AssertionError, match="analysed although cached"):
            build(**change)


def _moved_leg_xml():
    return TABLE_XML.format(custom="", density=1000).replace('pos="0.15 0.05 -0.15"', 'pos="0.14 0.05 -0.15"')


def test_corrupt_entry_is_analysed_again_and_rewritten():
    first = build()
    (name,) = entries()
    path = os.path.join(os.environ["MJSOUND_CACHE_DIR"], "objects", name)
    with open(path, "wb") as fh:
        fh.write(b"not a model")
    again = build()
    np.testing.assert_array_equal(again.sounding[0].model.frequencies_hz, first.sounding[0].model.frequencies_hz)
    assert sa.load_object_model(name[:-4]) is not None


def test_no_entries_without_cache_or_with_a_replaced_analysis(fake_analyze):
    build()
    assert fake_analyze and entries() == []  # (a fake analysis never lands in the object cache)


def test_a_cached_scene_starts_without_the_analysis_stack():
    build(cache=True)
    code = ("import sys, warnings; warnings.simplefilter('ignore')\n"
            "from tests.test_object_cache import OPTS; from tests.scenes import table_model\n"
            "from mjsound.sim.scene import SoundScene\n"
            "s = SoundScene.from_model(table_model(), **OPTS)\n"
            "print(len(s.sounding), sorted(m for m in ('trimesh', 'scipy.sparse', 'scipy.special') if m in sys.modules))")
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    out = subprocess.run([sys.executable, "-c", code], cwd=root, capture_output=True, text=True, check=True,
                         env=dict(os.environ, PYTHONPATH=root))
    assert out.stdout.split("\n")[0] == "1 []", out.stdout + out.stderr


def test_processes_starting_together_analyse_each_object_once(monkeypatch):
    """Two scenes built at once (threads here; the lock is the same between processes: each
    holds its own open file) analyse the table once: the second waits for the first's entry and
    loads it, with the same modes."""
    import threading
    import time

    real, calls = sa._analyze_with_fallback, []

    def slow(*a, **k):  # (long enough that the second scene misses the cache before the entry exists)
        calls.append(a[0])
        time.sleep(0.5)
        return real(*a, **k)

    monkeypatch.setattr(sa, "_analyze_with_fallback", slow)
    sa._MODEL_MEMO.clear()
    scenes = [None, None]

    def build_into(i):
        scenes[i] = build()

    threads = [threading.Thread(target=build_into, args=(i,)) for i in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=300)
    assert calls == ["table"] and len(entries()) == 1
    np.testing.assert_array_equal(scenes[0].sounding[0].model.frequencies_hz, scenes[1].sounding[0].model.frequencies_hz)


def test_analysis_lock_lives_in_the_cache():
    """The object lock is a file in the cache's ``locks/`` (not among the entries); without a
    key (no cache) nothing is locked. Waiting and its limit: ``tests/test_jit.py``."""
    import contextlib

    with sa.analysis_lock("k" * 40):
        assert os.path.exists(os.path.join(os.environ["MJSOUND_CACHE_DIR"], "locks", "k" * 40 + ".lock"))
    assert isinstance(sa.analysis_lock(None), contextlib.nullcontext)
    assert entries() == []
