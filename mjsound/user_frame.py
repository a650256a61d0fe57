"""Warnings attributed to the user's call: :func:`warn` points a warning at the first stack frame
outside mjsound and the libraries it runs inside (gymnasium, dm_control, robosuite, ...), so that
``file:line`` in the message is the user's ``AudioObservation(...)``, ``env.step(...)`` or
``SoundScene.from_model(...)`` line, not mjsound's or an env's source.

A frame is the library's when its file lies in the mjsound package, in the repository's own
``envs`` package, in a ``site-packages`` / ``dist-packages`` directory or in Python's standard
library; when every frame is (``python -m mjsound ...``), the outermost one is named.

Example
-------
>>> from mjsound.user_frame import warn
>>> warn("mjsound: nothing in this scene rings", UserWarning)    # doctest: +SKIP
"""

from __future__ import annotations

import os
import sys
import sysconfig
import warnings

__all__ = ["warn", "user_stacklevel"]

_PACKAGE = os.path.dirname(os.path.abspath(__file__))
_LIBRARY_DIRS = tuple(
    {os.path.join(_PACKAGE, ""), os.path.join(os.path.dirname(_PACKAGE), "envs", "")}
    | {os.path.join(p, "") for p in (sysconfig.get_paths().get("stdlib"), sysconfig.get_paths().get("platstdlib")) if p}
)


def _is_library(filename: str) -> bool:
    if filename.startswith("<"):  # (frozen importlib and the like)
        return True
    path = os.path.abspath(filename)
    return (path.startswith(_LIBRARY_DIRS) or f"{os.sep}site-packages{os.sep}" in path
            or f"{os.sep}dist-packages{os.sep}" in path)


def user_stacklevel(skip: int = 1) -> int:
    """The ``stacklevel`` for a ``warnings.warn`` made by the function ``skip`` frames above
    this call (1: its caller) that names the first frame outside the libraries."""
    frame = sys._getframe(skip)
    level = 1
    while frame.f_back is not None and _is_library(frame.f_code.co_filename):
        frame = frame.f_back
        level += 1
    return level


def warn(message: str, category=UserWarning) -> None:
    """``warnings.warn(message, category)`` attributed to the user's frame (module docstring)."""
    warnings.warn(message, category, stacklevel=user_stacklevel(2) + 1)
