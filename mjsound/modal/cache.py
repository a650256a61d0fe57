"""Where analysed models are kept on disk (importing this module costs nothing: no trimesh,
no scipy), so that a process whose models are all cached starts without loading the
analysis stack."""

from __future__ import annotations

import os

__all__ = ["cache_dir"]


def cache_dir() -> str:
    """``$MJSOUND_CACHE_DIR`` or the platform user cache dir (``~/.cache/mjsound``)."""
    env = os.environ.get("MJSOUND_CACHE_DIR")
    if env:
        return env
    import platformdirs

    return platformdirs.user_cache_dir("mjsound")
