"""numba's disk cache stamped by the whole kernel group (mjsound/jit.py): an edit to any module
a kernel can reach recompiles it, where numba alone would load stale code of the unchanged file;
an edit to a module no kernel reaches recompiles nothing."""

from __future__ import annotations

import importlib
import os

from numba.core.registry import CPUDispatcher

from mjsound import jit


def cached_dispatchers(module_name):
    mod = importlib.import_module(module_name)
    return [v for v in vars(mod).values() if isinstance(v, CPUDispatcher) and v._cache is not None
            and hasattr(v._cache, "_impl")]


def test_every_kernel_is_stamped_by_its_group():
    seen = 0
    for name, group in [("mjsound.sim.step", "sim"), ("mjsound.sim.pairs", "sim"), ("mjsound.synth.kernels", "sim"),
                        ("mjsound.synth.bandlimited", "sim"), ("mjsound.audio_window", "sim"),
                        ("mjsound.modal.voxelize", "modal"), ("mjsound.modal.hex", "modal")]:
        for d in cached_dispatchers(name):
            loc = d._cache._impl.locator
            assert isinstance(loc, (jit.GroupUserProvidedCacheLocator, jit.GroupInTreeCacheLocator,
                                    jit.GroupUserWideCacheLocator)), (name, d.py_func.__name__, type(loc))
            assert loc.get_source_stamp() == jit.sources_digest(group)
            seen += 1
    assert seen > 20
    assert jit.kernel_group(os.__file__) is None  # (other packages keep numba's own locators)


def test_digest_follows_every_source_of_the_group_and_only_it(tmp_path):
    root = tmp_path / "pkg"
    for member in jit.KERNEL_GROUPS["sim"] + jit.KERNEL_GROUPS["modal"]:
        (root / member).parent.mkdir(parents=True, exist_ok=True)
        (root / member).write_text("X = 1\n")
    r = str(root)
    before = {g: jit.sources_digest(g, r) for g in jit.KERNEL_GROUPS}
    (root / "synth" / "kernels.py").write_text("X = 3\n")  # a callee's module changes ...
    jit.sources_digest.cache_clear()
    after = {g: jit.sources_digest(g, r) for g in jit.KERNEL_GROUPS}
    assert after["sim"] != before["sim"] and after["modal"] == before["modal"]
    (root / "sim" / "scene.py").write_text("Y = 2\n")  # ... a module no kernel imports does not count
    (root / "sim" / "notes.txt").write_text("not a source")
    jit.sources_digest.cache_clear()
    assert jit.sources_digest("sim", r) == after["sim"]
    assert jit.kernel_group(str(root / "modal" / "a.py"), r) == "modal"
    assert jit.kernel_group(str(root / "synth" / "a.py"), r) == "sim"
    jit.sources_digest.cache_clear()


def test_file_lock_makes_a_second_holder_wait_then_go_on(tmp_path):
    """``io.file_lock``: a second holder (another open file, as in another process) waits
    while the first holds the lock, takes it as soon as it is free, and goes on without it
    after ``wait_s`` (a stuck process never hangs the others)."""
    import threading
    import time

    from mjsound.io import file_lock

    path = str(tmp_path / "sub" / "k.lock")
    order = []
    first_holds = threading.Event()

    def first():
        with file_lock(path, 10.0):
            first_holds.set()
            time.sleep(0.4)
            order.append("first done")

    t = threading.Thread(target=first)
    t.start()
    first_holds.wait(5.0)
    with file_lock(path, 10.0):
        order.append("second in")
    t.join()
    assert order == ["first done", "second in"]

    with file_lock(path, 10.0):
        t0 = time.monotonic()
        with file_lock(path, 0.3):
            waited = time.monotonic() - t0
    assert 0.3 <= waited < 5.0


def test_an_entry_points_first_call_compiles_under_the_kernels_lock(monkeypatch):
    """The first call of a kernel through ``EntryPoint`` holds ``jit.compile_lock`` (beside the
    kernel's cache index), so that processes starting together compile it once; later calls do
    not take it."""
    import contextlib

    import numpy as np

    import mjsound.synth.dispatch as dispatch
    from mjsound.jit import compile_lock
    from mjsound.sim.step import advance

    with compile_lock(advance):
        pass
    assert os.path.exists(os.path.join(advance._cache._cache_path, "advance.compile.lock"))
    assert isinstance(compile_lock(jit.njit(lambda x: x)), contextlib.nullcontext)  # (no disk cache: no lock)
    taken = []

    @contextlib.contextmanager
    def recording(fn):
        taken.append(fn)
        yield

    monkeypatch.setattr(dispatch, "compile_lock", recording)
    kernel = jit.njit(lambda a, b: a[0] + b)  # (a fresh dispatcher: nothing compiled yet)
    call = dispatch.EntryPoint(kernel)
    assert call((np.ones(2),), 1.0) == 2.0
    assert call((np.ones(2),), 2.0) == 3.0
    assert taken == [kernel]


def test_an_inner_kernel_refuses_python_and_runs_through_call_inner():
    """A kernel compiled without numba's Python entry (jit.njit_inner) raises a TypeError that
    names the way in, instead of running the missing entry; jit.call_inner runs it."""
    import numpy as np
    import pytest

    from mjsound.sim.impulses import pinv_psd

    with pytest.raises(TypeError, match="call_inner"):
        pinv_psd(np.eye(2), 1e-4)
    np.testing.assert_allclose(jit.call_inner(pinv_psd, 2.0 * np.eye(2), 1e-4), 0.5 * np.eye(2))
    assert isinstance(pinv_psd, CPUDispatcher) and pinv_psd.targetoptions["no_cpython_wrapper"]
