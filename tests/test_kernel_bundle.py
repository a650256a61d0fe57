"""The kernels shipped with mjsound (:mod:`mjsound.kernel_bundle`): built for the numba the
package pins, stamped by the kernels' code (a docstring edit leaves them usable), loaded by a
fresh process instead of compiled, merged into numba's cache without losing what is there,
and declined (with the reason) where they do not fit."""

import ast
import json
import os
import re
import shutil
import subprocess
import sys
import warnings

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


def _code(group):
    return jit.code_digest(group).hex()


#: This process's verdict on the bundle: None where it fits this machine and these kernels.
VERDICT = kernel_bundle.fits(kernel_bundle.read_manifest(), jit.kernel_digests(), _code)
#: The kernel groups whose code changed since the bundle was built (they compile).
STALE = kernel_bundle.stale_groups(kernel_bundle.read_manifest() or {}, jit.kernel_digests(), _code)


def test_the_bundle_is_built_for_the_pinned_numba():
    """The shipped bundle is numba's cache of the numba ``pyproject.toml`` pins, for
    ``x86-64-v3``; under another numba or Python it is declined for that reason, with the fix.
    A bundle older than the kernels' code is a warning, not a failure: it is rebuilt once per
    release (docs/kernels.md), and until then the changed group compiles."""
    manifest = kernel_bundle.read_manifest()
    assert manifest is not None, "no mjsound/kernel_bundle/manifest.json: run scripts/build_kernel_bundle.py"
    with open(os.path.join(ROOT, "pyproject.toml")) as f:
        pin = re.search(r'"numba==([0-9][0-9a-z.]*)"', f.read())
    assert pin is not None and pin.group(1) == manifest["numba"], "pyproject.toml must pin the bundle's numba"
    assert manifest["cpu_name"] == "x86-64-v3" and manifest["cpu_features"] == ""
    here = kernel_bundle.host_platform()
    if manifest["numba"] != here["numba"]:
        assert VERDICT == f"built for numba {manifest['numba']}, this is {here['numba']} " \
                          f"(pip install numba=={manifest['numba']} loads them)"
    elif any(manifest[k] != here[k] for k in here):
        assert VERDICT.startswith("built for ")
    if STALE:
        warnings.warn(f"the shipped kernels are older than the {', '.join(STALE)} kernels' code (those compile "
                      "once per machine): rebuild with scripts/build_kernel_bundle.py at the release", UserWarning)


def _tree_with(tmp_path, group, edit):
    """A copy of the group's sources under ``tmp_path`` with ``edit(text) -> text`` applied
    to ``synth/kernels.py`` (sim) or ``modal/hex.py`` (modal)."""
    target = {"sim": "synth/kernels.py", "modal": "modal/hex.py"}[group]
    root = tmp_path / f"pkg{len(os.listdir(tmp_path))}"
    for member in jit.KERNEL_GROUPS[group]:
        (root / member).parent.mkdir(parents=True, exist_ok=True)
        text = open(os.path.join(ROOT, "mjsound", member)).read()
        (root / member).write_text(edit(text) if member == target else text)
    return str(root)


def test_the_code_stamp_ignores_docstrings_comments_and_layout(tmp_path):
    """A group's code digest (what the bundle must match) stays the same when a docstring, a
    comment or blank lines change, and changes with the code; the byte digest (numba's stamp
    of the local cache) changes with any of them."""
    def digests(root):
        jit.sources_digest.cache_clear()
        jit.code_digest.cache_clear()
        out = (jit.sources_digest("sim", root), jit.code_digest("sim", root))
        jit.sources_digest.cache_clear()
        jit.code_digest.cache_clear()
        return out

    plain = digests(_tree_with(tmp_path, "sim", lambda t: t))
    first_def = re.compile(r'(\ndef \w+\([^)]*\)[^:]*:\n    """)')
    doc = digests(_tree_with(tmp_path, "sim", lambda t: first_def.sub(r"\1An edited docstring. ", t, count=1)))
    comment = digests(_tree_with(tmp_path, "sim", lambda t: t.replace("\n\n\n", "\n\n\n# a comment\n\n", 1)))
    code = digests(_tree_with(tmp_path, "sim", lambda t: t + "\nNEW_CONSTANT = 1\n"))
    assert doc[0] != plain[0] and comment[0] != plain[0] and code[0] != plain[0]
    assert doc[1] == plain[1] and comment[1] == plain[1]
    assert code[1] != plain[1]
    # the bundle's verdict follows the code: usable after the docstring edit, stale after the code edit
    manifest = {"digests": {"sim": plain[0].hex()}, "code_digests": {"sim": plain[1].hex()}}
    assert kernel_bundle.stale_groups(manifest, {"sim": doc[0].hex()}, lambda g: doc[1].hex()) == []
    assert kernel_bundle.stale_groups(manifest, {"sim": code[0].hex()}, lambda g: code[1].hex()) == ["sim"]


def _imports(path: str, name: str) -> set[str]:
    """The package modules (file paths relative to the package) that ``path`` imports at load
    time (module level, outside functions and ``TYPE_CHECKING`` blocks)."""
    pkg = os.path.join(ROOT, "mjsound")
    parts = name.split(".")
    found = set()

    def module_file(dotted):
        rel = os.path.join(*dotted.split(".")[1:]) if "." in dotted else ""
        for cand in (rel + ".py", os.path.join(rel, "__init__.py")):
            if rel and os.path.isfile(os.path.join(pkg, cand)):
                return cand.replace(os.sep, "/")
        return None

    def visit(nodes):
        for node in nodes:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
                continue
            if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
                continue
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    base = ".".join(parts[: len(parts) - node.level] + ([node.module] if node.module else []))
                subs = [f"{base}.{a.name}" for a in node.names]
                targets = subs if any(module_file(t) for t in subs) else [base]
            else:
                targets = []
            found.update(f for f in map(module_file, targets) if f)
            visit(ast.iter_child_nodes(node))

    visit(ast.parse(open(path).read()).body)
    return found


def test_each_group_lists_its_kernels_import_closure():
    """``jit.KERNEL_GROUPS`` holds, per group, every module that defines one of its kernels
    and every package module those import at load time, transitively: an edit to any module
    whose names or constants a kernel can read changes the group's stamps."""
    pkg = os.path.join(ROOT, "mjsound")
    kernel_modules = {"modal": set(), "sim": set()}
    for folder, dirs, files in os.walk(pkg):
        dirs[:] = [d for d in dirs if d != "__pycache__"]
        for f in files:
            path = os.path.join(folder, f)
            if f.endswith(".py") and re.search(r"@njit|njit\(|njit_inner|numba\.njit", open(path).read()):
                rel = os.path.relpath(path, pkg).replace(os.sep, "/")
                kernel_modules["modal" if rel.startswith("modal/") else "sim"].add(rel)
    assert len(kernel_modules["sim"]) > 10 and len(kernel_modules["modal"]) > 5
    for group, start in kernel_modules.items():
        seen, todo = set(), sorted(start)
        while todo:
            rel = todo.pop()
            if rel in seen:
                continue
            seen.add(rel)
            name = "mjsound." + rel[:-3].replace("/", ".").removesuffix(".__init__")
            todo.extend(_imports(os.path.join(pkg, rel), name))
        missing = sorted(seen - set(jit.KERNEL_GROUPS[group]))
        assert missing == [], f"add {missing} to jit.KERNEL_GROUPS[{group!r}]"


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
if SHIPPED.used and not SHIPPED.stale:  # (a stale group would compile for minutes)
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
    if VERDICT is None and not STALE:
        assert res["used"] and res["cpu"] == "x86-64-v3"
        assert res["added"] > 50 and res["compiled"] == []
        again = _child("import json, mjsound.jit as j; print(json.dumps({'used': j.SHIPPED.used, 'added': j.SHIPPED.added}))",
                       NUMBA_CACHE_DIR=str(tmp_path))
        assert again == {"used": True, "added": 0}
    elif VERDICT is None:  # (a group's code changed since the build: it compiles, the other loads)
        assert res["used"] and res["cpu"] == "x86-64-v3" and res["added"] > 10
        assert all(stale in res["reason"] for stale in STALE)
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
    stamp = jit.folder_stamp("sim")
    base = next(n[:-4] for n in sorted(os.listdir(sim))
                if n.endswith(".nbi") and len(IndexDataCacheFile(str(sim), n[:-4], stamp)._load_index()) == 1)
    index = IndexDataCacheFile(str(sim), base, stamp)
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
