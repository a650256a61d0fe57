"""numba's disk cache stamped by the whole kernel group (mjsound/jit.py): an edit to any module
a kernel can reach recompiles it, where numba alone would load stale code of the unchanged file."""

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
                        ("mjsound.synth.bandlimited", "sim"), ("mjsound.wrappers", "sim"),
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
        if member.endswith(".py"):
            (root / member).parent.mkdir(parents=True, exist_ok=True)
            (root / member).write_text("X = 1\n")
        else:
            (root / member).mkdir(parents=True, exist_ok=True)
            (root / member / "a.py").write_text("Y = 2\n")
    r = str(root)
    before = {g: jit.sources_digest(g, r) for g in jit.KERNEL_GROUPS}
    (root / "synth" / "a.py").write_text("Y = 3\n")  # a callee's module changes ...
    jit.sources_digest.cache_clear()
    after = {g: jit.sources_digest(g, r) for g in jit.KERNEL_GROUPS}
    assert after["sim"] != before["sim"] and after["modal"] == before["modal"]
    (root / "sim" / "notes.txt").write_text("not a source")
    jit.sources_digest.cache_clear()
    assert jit.sources_digest("sim", r) == after["sim"]
    assert jit.kernel_group(str(root / "modal" / "a.py"), r) == "modal"
    assert jit.kernel_group(str(root / "synth" / "a.py"), r) == "sim"
    jit.sources_digest.cache_clear()
