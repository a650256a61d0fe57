"""The kernels shipped with mjsound (:mod:`mjsound.kernel_bundle`): current with the sources,
loaded by a fresh process instead of compiled, merged into numba's cache without losing what
is there, and declined (with the reason) where they do not fit."""

import json
import os
import shutil
import subprocess
import sys

import pytest

from mjsound import jit, kernel_bundle

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")


def _child(code: str, **env) -> dict:
    e = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    for k in ("NUMBA_CPU_NAME", "NUMBA_CPU_FEATURES", kernel_bundle.ENV_SWITCH):
        e.pop(k, None)
    e.update(env)
    out = subprocess.run([sys.executable, "-c", code], env=e, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


#: This process's verdict on the bundle: None where it fits this machine and these sources.
VERDICT = kernel_bundle.fits(kernel_bundle.read_manifest(), jit.kernel_digests())


def test_the_bundle_is_built_from_these_sources():
    """The shipped bundle carries the digests of the kernel sources as they are (rebuild it
    with ``scripts/build_kernel_bundle.py`` after an edit); under another numba or Python
    than it was built with it is declined for that reason."""
    manifest = kernel_bundle.read_manifest()
    assert manifest is not None, "no mjsound/kernel_bundle/manifest.json: run scripts/build_kernel_bundle.py"
    here = kernel_bundle.host_platform()
    if all(manifest[k] == here[k] for k in here):
        assert manifest["digests"] == jit.kernel_digests(), "the kernel sources changed: run scripts/build_kernel_bundle.py"
        assert manifest["cpu_name"] == "x86-64-v3" and manifest["cpu_features"] == ""
    else:
        assert VERDICT.startswith("built for ")


CHILD = """
import json
from numba.core import event
compiled = []
class Count(event.Listener):
    def on_start(self, e):
        f = getattr(e.data.get("dispatcher"), "py_func", None)
        if f is not None and f.__module__.startswith("mjsound"):
            compiled.append(f.__qualname__)
    def on_end(self, e):
        pass
event.register("numba:compile", Count())
import numba, mjsound
from mjsound.jit import SHIPPED
if SHIPPED.used:
    from mjsound.sim.warmup import warmup
    warmup(verbose=False)
print(json.dumps({"used": SHIPPED.used, "reason": SHIPPED.reason, "added": SHIPPED.added,
                  "cpu": numba.config.CPU_NAME, "compiled": compiled}))
"""


def test_a_fresh_process_loads_the_kernels_instead_of_compiling(tmp_path):
    """With an empty numba cache, a process that imports mjsound copies the bundle into the
    cache and runs every per-step and render path (``warmup``) without compiling one
    function of mjsound's; a second process copies nothing more. Where the bundle does not
    fit, the process says why and keeps numba's own CPU target."""
    res = _child(CHILD, NUMBA_CACHE_DIR=str(tmp_path))
    if VERDICT is None:
        assert res["used"] and res["cpu"] == "x86-64-v3"
        assert res["added"] > 50 and res["compiled"] == []
        again = _child("import json, mjsound.jit as j; print(json.dumps({'used': j.SHIPPED.used, 'added': j.SHIPPED.added}))",
                       NUMBA_CACHE_DIR=str(tmp_path))
        assert again == {"used": True, "added": 0}
    else:
        assert not res["used"] and res["reason"] == VERDICT and res["cpu"] is None


STATUS = "import json, numba, mjsound.jit as j; print(json.dumps([j.SHIPPED.used, j.SHIPPED.reason, numba.config.CPU_NAME]))"


def test_declined_when_switched_off_or_the_target_is_chosen_otherwise():
    """``MJSOUND_SHIPPED_KERNELS=0`` opts out; a CPU target set by ``NUMBA_CPU_NAME``, or fixed
    by numba code compiled before ``import mjsound``, is kept, and the bundle declined with
    that reason (loading it would need the target it was built for)."""
    assert _child(STATUS, MJSOUND_SHIPPED_KERNELS="0") == [False, "MJSOUND_SHIPPED_KERNELS=0", None]
    named = _child(STATUS, NUMBA_CPU_NAME="generic")
    taken = _child("import numba; numba.njit(lambda x: x + 1)(1)\n" + STATUS)
    assert named[0] is False and named[2] == "generic"
    assert taken[0] is False and taken[2] is None
    if VERDICT is None:
        assert "NUMBA_CPU_NAME" in named[1] and "compiled before mjsound" in taken[1]
    else:
        assert VERDICT in (named[1], taken[1])


def test_seeding_keeps_what_the_cache_holds(tmp_path):
    """Copying the bundle into a cache folder adds its entries beside the ones an index
    already has (a data file's name that is taken is not overwritten), replaces an index of
    older sources, and is done once per folder (a marker)."""
    manifest = kernel_bundle.read_manifest()
    from numba.core.caching import IndexDataCacheFile

    def locate(folder):
        path = tmp_path / folder.replace(".", "root")
        path.mkdir(exist_ok=True)
        return str(path)

    added = kernel_bundle.seed(manifest, locate, jit.folder_stamp)
    assert added > 50
    assert kernel_bundle.seed(manifest, locate, jit.folder_stamp) == 0  # (the markers)
    sim = tmp_path / "sim"
    base = next(n for n in sorted(os.listdir(sim)) if n.startswith("step.advance-") and n.endswith(".nbi"))[:-4]
    index = IndexDataCacheFile(str(sim), base, jit.folder_stamp("sim"))
    shipped = index._load_index()
    assert len(shipped) == 1
    (key, name), = shipped.items()
    code = (sim / name).read_bytes()

    # an index of these sources that holds another entry, under the name the bundle uses
    (sim / name).write_bytes(b"another entry")
    index._save_index({("another signature",): name})
    for m in sim.glob("mjsound-bundle-*.seeded"):
        m.unlink()
    assert kernel_bundle.seed(manifest, locate, jit.folder_stamp) == 1
    merged = index._load_index()
    assert merged[("another signature",)] == name and (sim / name).read_bytes() == b"another entry"
    assert merged[key] != name and (sim / merged[key]).read_bytes() == code

    # an index of older sources is replaced
    IndexDataCacheFile(str(sim), base, b"older sources")._save_index({("old",): name})
    for m in sim.glob("mjsound-bundle-*.seeded"):
        m.unlink()
    assert kernel_bundle.seed(manifest, locate, jit.folder_stamp) == 1
    assert list(index._load_index()) == [key]


def test_a_torn_bundle_is_reported_not_raised(tmp_path, monkeypatch):
    """A bundle whose archive cannot be read leaves the process compiling, with the reason."""
    torn = tmp_path / "bundle"
    torn.mkdir()
    shutil.copy(os.path.join(kernel_bundle.BUNDLE_DIR, "manifest.json"), torn / "manifest.json")
    (torn / "kernels.tar.xz").write_bytes(b"not an archive")
    monkeypatch.setattr(kernel_bundle, "STATUS", kernel_bundle.Status(used=True, reason="chosen"))
    st = kernel_bundle.seed_cache(lambda folder: str(tmp_path), lambda folder: b"", bundle_dir=str(torn))
    assert st.used is False and "could not be copied" in st.reason
    with pytest.raises(Exception):
        kernel_bundle.seed(kernel_bundle.read_manifest(str(torn)), lambda folder: str(tmp_path), lambda folder: b"",
                           bundle_dir=str(torn))
