"""Small file helpers shared by every writer: atomic replacement with normal permissions."""

from __future__ import annotations

import os
import tempfile

__all__ = ["temp_beside", "commit_temp"]


def temp_beside(path, suffix: str = "") -> tuple[int, str]:
    """A temporary file in the directory of ``path`` (created if needed): ``(fd, tmp_path)``.

    Writing there and then :func:`commit_temp` makes the final file appear whole or not
    at all (``os.replace`` is atomic within one file system).
    """
    d = os.path.dirname(os.path.abspath(os.fspath(path))) or "."
    os.makedirs(d, exist_ok=True)
    return tempfile.mkstemp(dir=d, prefix=".tmp-", suffix=suffix)


def commit_temp(tmp: str, path) -> None:
    """Give ``tmp`` the permissions a new file would get (mkstemp makes 0600) and move it
    onto ``path`` atomically."""
    mask = os.umask(0)
    os.umask(mask)
    os.chmod(tmp, 0o666 & ~mask)
    os.replace(tmp, os.fspath(path))
