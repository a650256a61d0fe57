"""Precompiled kernels shipped with mjsound: numba's cache of mjsound's kernels, built for a
portable CPU target, so that a process on a new machine loads them instead of compiling.

A process whose numba cache is empty compiles the step kernel's call tree (about ninety
functions) before its first audio: half a minute and more on two cores. numba keeps what it
compiles in an on-disk cache, keyed by the function, its argument types and the *CPU target*;
with the target set to a named CPU model instead of "this host" (``NUMBA_CPU_NAME``, numba's
documented way to share a cache between machines) the cached machine code runs on any CPU
that has that model's instructions. mjsound ships such a cache, built for ``x86-64-v3``
(AVX2 and FMA: Intel's Core since Haswell, AMD's since Zen; not every low-end Atom,
Celeron or Pentium has them) by ``scripts/build_kernel_bundle.py``,
in ``mjsound/kernel_bundle/``: ``manifest.json`` (what it was built with) and
``kernels.tar.xz`` (numba's index and data files, by source folder).

:func:`activate` runs when ``mjsound`` is imported, before any kernel is declared (numba
fixes its CPU target when the first one is), and :func:`seed_cache` at the end of that
import. They use the bundle only where it fits:

- the same numba version, Python version and platform as the build (``pyproject.toml`` pins
  the numba the bundle is built with; numba rejects a cache of any other version);
- per kernel group (:data:`mjsound.jit.KERNEL_GROUPS`), the same kernel code: the sources'
  bytes (:func:`mjsound.jit.sources_digest`), or else their code without docstrings,
  comments and formatting (:func:`mjsound.jit.code_digest`). A group whose code changed
  compiles, as before; the other group still loads;
- a CPU with the target's instructions (``manifest["cpu_requires"]``);
- numba's CPU target not chosen otherwise: neither ``NUMBA_CPU_NAME``/``NUMBA_CPU_FEATURES``
  set to something else, nor numba code compiled in this process before ``import mjsound``;
- ``MJSOUND_SHIPPED_KERNELS`` not ``0`` (the way to opt out).

Then it sets numba's CPU target to the bundle's (numba has one per process: numba code of
the caller's own, compiled after ``import mjsound``, is compiled for it too; the kernels ran
as fast with it as with the host's own target, docs/benchmarks.md) and copies the bundle's
entries into numba's cache folders, next to whatever is there (an index that already holds
an entry keeps it), once per folder (a marker file) and under a lock (processes starting
together). :data:`STATUS` says whether it was used and, if not, why.
"""

from __future__ import annotations

import ast
import hashlib
import io
import json
import os
import pickle
import sys
import tarfile
from dataclasses import dataclass

__all__ = ["BUNDLE_DIR", "ENV_SWITCH", "Status", "STATUS", "activate", "seed_cache", "fits", "mismatches", "seed",
           "stale_groups", "code_digest", "first_lines", "index_name_now",
           "read_manifest", "host_platform", "write_bundle"]

_ROOT = os.path.dirname(os.path.abspath(__file__))

#: Where the shipped bundle lives (package data).
BUNDLE_DIR = os.path.join(_ROOT, "kernel_bundle")

#: Set to ``0`` to compile for this host instead of loading the shipped kernels.
ENV_SWITCH = "MJSOUND_SHIPPED_KERNELS"

#: Longest wait for another process that is copying the bundle into the same cache [s].
SEED_WAIT_S = 120.0


@dataclass
class Status:
    """Whether this process uses the shipped kernels (``used``), and why not (``reason``)."""

    used: bool = False
    reason: str = "not checked yet"
    added: int = 0  # cache entries this process copied in
    groups: tuple = ()  # the kernel groups loaded from the bundle
    stale: tuple = ()  # the kernel groups whose code differs from the bundle's (they compile)


#: What :func:`activate` decided in this process.
STATUS = Status()


def read_manifest(bundle_dir: str = BUNDLE_DIR) -> dict | None:
    """The bundle's ``manifest.json``, or None when there is no bundle."""
    try:
        with open(os.path.join(bundle_dir, "manifest.json")) as f:
            return json.load(f)
    except (OSError, ValueError):
        return None


def host_platform() -> dict:
    """What a bundle must match here: numba's version, the Python tag of numba's cache file
    names, and LLVM's process triple."""
    import llvmlite.binding as ll
    import numba

    return {"numba": numba.__version__, "python": f"py{sys.version_info[0]}{sys.version_info[1]}",
            "triple": ll.get_process_triple()}


def _code_of(source: bytes) -> str:
    """A module's code without what does not compile into it: parsed, the docstrings of the
    module, its classes and functions dropped, dumped without line and column numbers (so
    comments, blank lines and formatting are gone too)."""
    tree = ast.parse(source)
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) \
                    and isinstance(first.value.value, str):
                node.body = node.body[1:] or [ast.Pass()]
    return ast.dump(tree, annotate_fields=False)


def code_digest(root: str, members, memo_dir: str | None = None, memo_key: str | None = None) -> bytes:
    """sha256 of the code of the sources ``members`` (files relative to ``root``): each
    :func:`_code_of`, with its name. What the shipped kernels of a group must match: an edit
    to a docstring, a comment or the layout leaves it as it was. Parsing takes a tenth of a
    second or more, so with ``memo_dir`` the result is kept there under ``memo_key`` (the
    sources' byte digest: only an edit computes it again)."""
    memo = os.path.join(memo_dir, f"mjsound-code-{memo_key}") if memo_dir and memo_key else None
    if memo is not None:
        try:
            with open(memo) as f:
                return bytes.fromhex(f.read().strip())
        except (OSError, ValueError):
            pass
    h = hashlib.sha256()
    for member in sorted(members):
        with open(os.path.join(root, member), "rb") as f:
            h.update(member.encode() + b"\0" + _code_of(f.read()).encode() + b"\0")
    digest = h.digest()
    if memo is not None:
        tmp = f"{memo}.{os.getpid()}.tmp"
        try:
            os.makedirs(memo_dir, exist_ok=True)
            with open(tmp, "w") as f:
                f.write(digest.hex() + "\n")
            os.replace(tmp, memo)
        except OSError:  # (a read-only install: computed again next time)
            pass
    return digest


def first_lines(root: str, members, folder: str) -> dict:
    """``{"module.qualname": first line}`` of the functions of the sources ``members`` that lie
    in the package folder ``folder``, as numba names their cache files
    (``module.qualname-LINE.pyXY.nbi``, LINE the first decorator's): module-level functions
    and methods, from the sources as they are."""
    out = {}
    for member in sorted(members):
        if os.path.dirname(member) != ("" if folder == "." else folder):
            continue
        stem = os.path.basename(member)[:-3]
        with open(os.path.join(root, member), "rb") as f:
            tree = ast.parse(f.read())
        for node in tree.body:
            scopes = [(n, node.name + ".") for n in node.body] if isinstance(node, ast.ClassDef) else [(node, "")]
            for fn, prefix in scopes:
                if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
                    out[f"{stem}.{prefix}{fn.name}"] = min([fn.lineno] + [d.lineno for d in fn.decorator_list])
    return out


_LINES: dict = {}


def index_name_now(root: str, members, folder: str, name: str) -> str:
    """The name numba gives today to the bundle's cache file ``name``
    (``module.qualname-LINE.pyXY.nbi``) of the package folder ``folder``: the same with the
    function's current first line (a line added above a kernel, a comment or a docstring's,
    moves it; the code is the bundle's, :func:`fits` checked); ``name`` itself for a function
    not found (a closure)."""
    if (root, folder) not in _LINES:
        _LINES[root, folder] = first_lines(root, members, folder)
    head, sep, tail = name.rpartition("-")
    line = _LINES[root, folder].get(head)
    if not sep or line is None or "." not in tail:
        return name
    return f"{head}-{line}.{tail.split('.', 1)[1]}"


def _target_taken() -> bool:
    """Whether numba's CPU target is set up in this process already (a kernel was declared)."""
    from numba.core.registry import cpu_target

    return "_toplevel_target_context" in vars(cpu_target)


def stale_groups(manifest: dict, digests: dict, code_digest=None) -> list[str]:
    """The kernel groups whose code is not the bundle's, sorted: the sources' byte digest
    (``digests``: ``{group: hex digest}``) differs from the manifest's ``digests`` and, when
    ``code_digest(group)`` (hex) is given, the code digest from its ``code_digests`` too (an
    edit to a docstring or a comment leaves a group usable)."""
    out = []
    for g in sorted(digests):
        if manifest.get("digests", {}).get(g) == digests[g]:
            continue
        if code_digest is not None and manifest.get("code_digests", {}).get(g) == code_digest(g):
            continue
        out.append(g)
    return out


def mismatches(manifest: dict, digests: dict, here: dict | None = None, code_digest=None) -> list[str]:
    """What the bundle ``manifest`` was built with that differs here: the keys of
    :func:`host_platform` (``here``, default this process's), then the kernel groups whose
    code is not the bundle's (:func:`stale_groups`)."""
    here = host_platform() if here is None else here
    keys = [k for k in here if manifest.get(k) != here[k]]
    return keys + stale_groups(manifest, digests, code_digest)


def fits(manifest: dict | None, digests: dict, code_digest=None) -> str | None:
    """Why the bundle ``manifest`` cannot be used in this process, or None when it can (for
    at least one kernel group: :func:`stale_groups`). ``digests``: ``{group: hex digest}`` of
    the current kernel sources' bytes; ``code_digest(group)``: the hex digest of a group's
    code, asked only for a group whose bytes differ."""
    import llvmlite.binding as ll
    from numba.core import config

    if os.environ.get(ENV_SWITCH, "1") == "0":
        return f"{ENV_SWITCH}=0"
    if manifest is None:
        return "no bundle in this install"
    here = host_platform()
    for key in here:
        if manifest.get(key) != here[key]:
            fix = f" (pip install numba=={manifest.get(key)} loads them)" if key == "numba" else ""
            return f"built for {key} {manifest.get(key)}, this is {here[key]}{fix}"
    stale = stale_groups(manifest, digests, code_digest)
    if len(stale) == len(digests):
        return (f"the kernel code ({', '.join(stale)}) differs from the bundle's "
                "(rebuild it with scripts/build_kernel_bundle.py)")
    features = ll.get_host_cpu_features()
    missing = [f for f in manifest.get("cpu_requires", []) if not features.get(f, False)]
    if missing:
        return f"this CPU lacks {', '.join(missing)} ({manifest['cpu_name']} needs them)"
    wanted = (manifest["cpu_name"], manifest["cpu_features"])
    if (config.CPU_NAME, config.CPU_FEATURES) not in ((None, None), wanted):
        return f"numba's CPU target is set to {config.CPU_NAME!r} (NUMBA_CPU_NAME)"
    if _target_taken() and (config.CPU_NAME, config.CPU_FEATURES) != wanted:
        return "numba code was compiled before mjsound was imported (numba's CPU target is fixed)"
    return None


def _entries(tar: tarfile.TarFile) -> dict:
    """``{folder: {file name: bytes}}`` of a bundle's archive."""
    out: dict = {}
    for m in tar.getmembers():
        if m.isfile():
            folder, name = m.name.rsplit("/", 1)
            out.setdefault(folder, {})[name] = tar.extractfile(m).read()
    return out


def _read_index(raw: bytes):
    """(numba version, source stamp, {key: data file name}) of a numba index file's bytes."""
    f = io.BytesIO(raw)
    version = pickle.load(f)
    stamp, overloads = pickle.loads(f.read())
    return version, stamp, overloads


def _bundle_id(manifest: dict) -> str:
    return hashlib.sha256(json.dumps(manifest, sort_keys=True).encode()).hexdigest()[:16]


def seed(manifest: dict, locate, stamp_of, bundle_dir: str = BUNDLE_DIR, folders=None, name_of=None) -> int:
    """Copy the bundle's cache entries into numba's cache folders; returns how many were added.

    ``locate(folder)``: numba's cache folder for the kernels of the package folder ``folder``
    ("sim", "synth", "." ...), or None; ``stamp_of(folder)``: the source stamp numba's
    index there must carry (the sources as they are: the caller checked that their code is
    the bundle's); ``folders``: the package folders to seed (default all of the bundle's);
    ``name_of(folder, index name)``: the index's name today (numba's names carry the
    function's first line, which an edit above it moves; default: unchanged).
    For each index of the bundle the entries the folder's index lacks are added (data files
    under free names, then the index, each replaced atomically, stamped ``stamp_of(folder)``);
    an index with another stamp (older sources) is replaced. A marker file per folder and
    stamp makes later processes skip the work (an edit that changes the stamp seeds again); a
    lock keeps processes that start together from doing it twice."""
    from numba.core.caching import IndexDataCacheFile

    from .io import file_lock

    wanted = manifest["folders"] if folders is None else [f for f in manifest["folders"] if f in folders]
    paths = {f: locate(f) for f in wanted}
    markers = {f: f"mjsound-bundle-{_bundle_id(manifest)}-{stamp_of(f).hex()[:16]}.seeded" for f in paths}
    todo = {f: p for f, p in paths.items() if p and not os.path.exists(os.path.join(p, markers[f]))}
    if not todo:
        return 0
    with tarfile.open(os.path.join(bundle_dir, "kernels.tar.xz")) as tar:
        entries = _entries(tar)
    added = 0
    for folder, path in todo.items():
        marker = markers[folder]
        with file_lock(os.path.join(path, "mjsound-bundle.lock"), SEED_WAIT_S):
            if os.path.exists(os.path.join(path, marker)):
                continue
            files = entries.get(folder, {})
            stamp = stamp_of(folder)
            for name, raw in sorted(files.items()):
                if not name.endswith(".nbi"):
                    continue
                version, _, src = _read_index(raw)  # (its stamp: the build's sources, whose code fits() compared)
                index = IndexDataCacheFile(path, (name if name_of is None else name_of(folder, name))[:-4], stamp)
                if version != index._version:
                    continue  # (fits() compared numba's version: a bundle at odds with itself)
                have = index._load_index()
                used = set(have.values())
                new = {}
                for key, data_name in src.items():
                    if key in have:
                        continue
                    n = 1
                    while index._data_name(n) in used:
                        n += 1
                    mine = index._data_name(n)
                    used.add(mine)
                    with index._open_for_write(os.path.join(path, mine)) as out:
                        out.write(files[data_name])
                    new[key] = mine
                if new:
                    index._save_index({**have, **new})
                    added += len(new)
            with open(os.path.join(path, marker), "w") as f:
                f.write(json.dumps(manifest.get("built", {})) + "\n")
    return added


def activate(digests: dict, code_digest=None, bundle_dir: str = BUNDLE_DIR) -> Status:
    """Choose the shipped kernels for this process if they fit (:func:`fits`): set numba's
    CPU target to the bundle's, and note in :data:`STATUS` which kernel groups load from it
    (a group whose code changed compiles). Sets and returns :data:`STATUS`;
    :func:`seed_cache` then copies them into numba's cache (after ``mjsound`` is imported:
    reading numba's indexes imports the modules that define the kernels' argument types)."""
    from numba.core import config

    manifest = read_manifest(bundle_dir)
    why = fits(manifest, digests, code_digest)
    if why is not None:
        STATUS.used, STATUS.reason = False, why
        return STATUS
    stale = stale_groups(manifest, digests, code_digest)
    config.CPU_NAME, config.CPU_FEATURES = manifest["cpu_name"], manifest["cpu_features"]
    STATUS.used, STATUS.reason = True, f"shipped kernels for {manifest['cpu_name']}"
    STATUS.groups, STATUS.stale = tuple(g for g in sorted(digests) if g not in stale), tuple(stale)
    if stale:
        STATUS.reason += (f" ({', '.join(STATUS.groups)}; the {', '.join(stale)} kernels compile: their code "
                          "differs from the bundle's, rebuild it with scripts/build_kernel_bundle.py)")
    return STATUS


def seed_cache(locate, stamp_of, bundle_dir: str = BUNDLE_DIR, group_of=None, name_of=None) -> Status:
    """:func:`seed` the chosen bundle (:func:`activate`) into numba's cache: the package
    folders whose kernel group (``group_of(folder)``) loads from it. A bundle that cannot be
    read or copied is reported in :data:`STATUS`, never raised: the kernels are compiled then
    (for the bundle's CPU target, which is set already)."""
    if not STATUS.used:
        return STATUS
    try:
        manifest = read_manifest(bundle_dir)
        folders = None if group_of is None or not STATUS.stale else \
            [f for f in manifest["folders"] if group_of(f) in STATUS.groups]
        STATUS.added = seed(manifest, locate, stamp_of, bundle_dir, folders, name_of)
    except Exception as e:  # (a torn archive, a full disk, numba internals moved: compile instead)
        STATUS.used, STATUS.reason = False, f"the bundle could not be copied into numba's cache ({e!r})"
    return STATUS


def write_bundle(out_dir: str, folders: dict, manifest: dict) -> str:
    """Write a bundle: ``folders`` maps a package folder ("sim", ".") to the numba cache
    folder holding its kernels' index and data files; ``manifest`` is completed with the
    folder list and written beside ``kernels.tar.xz``. The archive is reproducible (sorted
    members, no times or owners), so the same cache gives the same bytes. Returns the
    archive's path."""
    from .io import atomic_open

    os.makedirs(out_dir, exist_ok=True)
    buf = io.BytesIO()
    with tarfile.open(fileobj=buf, mode="w:xz", preset=9) as tar:
        for folder in sorted(folders):
            src = folders[folder]
            for name in sorted(os.listdir(src)):
                if not name.endswith((".nbi", ".nbc")):
                    continue
                with open(os.path.join(src, name), "rb") as f:
                    raw = f.read()
                info = tarfile.TarInfo(f"{folder}/{name}")
                info.size, info.mode, info.mtime = len(raw), 0o644, 0
                tar.addfile(info, io.BytesIO(raw))
    archive = os.path.join(out_dir, "kernels.tar.xz")
    with atomic_open(archive, "wb") as f:
        f.write(buf.getvalue())
    manifest = dict(manifest, folders=sorted(folders))
    with atomic_open(os.path.join(out_dir, "manifest.json")) as f:
        json.dump(manifest, f, indent=1, sort_keys=True)
        f.write("\n")
    return archive
