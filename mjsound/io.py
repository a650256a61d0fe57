"""Small file helpers shared by every writer: atomic replacement with normal permissions,
temporary files that never outlive their run, and output-path checks; the content digest
of a set of source files (cache keys that follow the code); and a lock file between processes
that would otherwise do the same long work at once (:func:`file_lock`).

Temporary files are named ``.mjsound-tmp-<host>-<pid>-<random><suffix>`` in the directory of
the final file. A run that is killed (SIGKILL, OOM) cannot remove its own; the next run that
writes into the same directory removes every such file of this host whose process is gone
(:func:`remove_stale_temps`).
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import socket
import tempfile
import time

__all__ = ["temp_beside", "commit_temp", "discard_temp", "remove_stale_temps", "check_output_file", "atomic_path",
           "atomic_open", "TEMP_PREFIX", "sources_digest", "file_lock"]

#: Prefix of every temporary file mjsound writes.
TEMP_PREFIX = ".mjsound-tmp-"
_swept: set = set()


def _host() -> str:
    return "".join(c if c.isalnum() else "_" for c in socket.gethostname())[:40] or "host"


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # exists, another user's
        return True
    return True


def remove_stale_temps(directory) -> list:
    """Delete this host's mjsound temporary files in ``directory`` whose process has ended.

    Returns the removed paths. Files of other hosts (a shared file system) and of running
    processes are left alone.
    """
    d = os.fspath(directory)
    head = f"{TEMP_PREFIX}{_host()}-"
    removed = []
    try:
        names = os.listdir(d)
    except OSError:
        return removed
    for name in names:
        if not name.startswith(head):
            continue
        pid_text = name[len(head):].split("-", 1)[0]
        if not pid_text.isdigit() or int(pid_text) == os.getpid() or _alive(int(pid_text)):
            continue
        path = os.path.join(d, name)
        try:
            os.unlink(path)
            removed.append(path)
        except OSError:
            pass
    return removed


def temp_beside(path, suffix: str = "") -> tuple[int, str]:
    """A temporary file in the directory of ``path`` (created if needed): ``(fd, tmp_path)``.

    Writing there and then :func:`commit_temp` makes the final file appear whole or not
    at all (``os.replace`` is atomic within one file system). The first call per directory
    and process removes stale temporary files left by killed runs.
    """
    d = os.path.dirname(os.path.abspath(os.fspath(path))) or "."
    os.makedirs(d, exist_ok=True)
    if d not in _swept:
        _swept.add(d)
        remove_stale_temps(d)
    return tempfile.mkstemp(dir=d, prefix=f"{TEMP_PREFIX}{_host()}-{os.getpid()}-", suffix=suffix)


def commit_temp(tmp: str, path) -> None:
    """Give ``tmp`` the permissions a new file would get (mkstemp makes 0600) and move it
    onto ``path`` atomically."""
    mask = os.umask(0)
    os.umask(mask)
    os.chmod(tmp, 0o666 & ~mask)
    os.replace(tmp, os.fspath(path))


def discard_temp(tmp) -> None:
    """Remove a temporary file if it is still there (never raises)."""
    try:
        os.unlink(tmp)
    except OSError:
        pass


def check_output_file(path, suffixes, option: str = "output") -> str:
    """Check an output path before any work: not a directory, a known suffix, a parent that
    is (or can become) a directory. Returns the path; raises ``ValueError`` naming ``option``.

    Parameters
    ----------
    suffixes : tuple of str
        Accepted suffixes, lower case with the dot (``(".wav", ".flac")``).
    """
    p = os.fspath(path)
    if not p:
        raise ValueError(f"{option}: empty file name")
    if os.path.isdir(p):
        raise ValueError(f"{option} {p!r} is a directory: give a file name, e.g. {os.path.join(p, 'out' + suffixes[0])}")
    ext = os.path.splitext(p)[1].lower()
    if ext not in suffixes:
        raise ValueError(f"{option} {p!r}: the file type {ext or '(none)'!r} is not supported; "
                         f"use {' or '.join(suffixes)}")
    parent = os.path.dirname(os.path.abspath(p))
    while parent and not os.path.exists(parent):
        parent = os.path.dirname(parent)
    if parent and not os.path.isdir(parent):
        raise ValueError(f"{option} {p!r}: {parent!r} is a file, not a directory")
    return p


@contextlib.contextmanager
def atomic_path(path, suffix: str = ""):
    """Yield a temporary path beside ``path`` to write (e.g. ``fig.savefig(tmp)``); on success it
    is moved onto ``path`` atomically, on any exception (Ctrl-C included) it is removed."""
    fd, tmp = temp_beside(path, suffix)
    os.close(fd)
    try:
        yield tmp
        commit_temp(tmp, path)
    except BaseException:
        discard_temp(tmp)
        raise


@contextlib.contextmanager
def atomic_open(path, mode: str = "w", **kwargs):
    """``open`` for writing, atomically: the file appears whole at ``path`` when the block ends
    without an exception, and not at all otherwise."""
    with atomic_path(path, os.path.splitext(os.fspath(path))[1]) as tmp:
        with open(tmp, mode, **kwargs) as fh:
            yield fh


def sources_digest(root: str, members) -> bytes:
    """sha256 over the names (relative to ``root``) and contents of the ``.py`` files of
    ``members``, each a folder (its ``.py`` files, sorted) or a file relative to ``root``."""
    h = hashlib.sha256()
    for member in members:
        path = os.path.join(root, member)
        files = sorted(os.path.join(path, n) for n in os.listdir(path) if n.endswith(".py")) \
            if os.path.isdir(path) else [path]
        for f in files:
            h.update(os.path.relpath(f, root).encode() + b"\0")
            with open(f, "rb") as fh:
                h.update(fh.read())
    return h.digest()


@contextlib.contextmanager
def file_lock(path, wait_s: float):
    """Hold an exclusive ``flock`` on the file ``path`` (made if missing) for the ``with`` body.

    For work that processes started together would otherwise all do at once (analysing the
    same object, compiling the same kernel): one does it, the others wait and then find its
    result. The kernel releases the lock of a process that dies. Without ``fcntl`` (Windows) or
    when the file cannot be made, nothing is locked; after ``wait_s`` seconds of waiting the
    caller goes on without the lock (a stuck process never hangs the others)."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover (Windows: no flock)
        fcntl = None
    fd = None
    if fcntl is not None:
        try:
            os.makedirs(os.path.dirname(os.fspath(path)) or ".", exist_ok=True)
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
        except OSError:
            fd = None
    try:
        if fd is not None:
            deadline = time.monotonic() + wait_s
            while True:
                try:
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                    break
                except BlockingIOError:
                    if time.monotonic() >= deadline:
                        break
                    time.sleep(0.05)
        yield
    finally:
        if fd is not None:
            os.close(fd)  # (releases the lock)
