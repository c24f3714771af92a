"""Where varint keeps its files: the per-user cache directory.

The bottom of the house: nothing here imports the rest of varint, so every
module may ask where the cache is (results, generated kernels, the
symbolic facts of models) without an import cycle.
"""

from __future__ import annotations

import os
from pathlib import Path

import platformdirs

__all__ = ["cache_dir"]


def cache_dir() -> Path:
    """The per-user cache directory (not created here).

    ``$VARINT_CACHE_DIR`` if set; otherwise the platform's convention, from
    :func:`platformdirs.user_cache_dir`: ``$XDG_CACHE_HOME/varint`` or
    ``~/.cache/varint`` on Linux, ``~/Library/Caches/varint`` on macOS,
    ``%LOCALAPPDATA%\\varint\\Cache`` on Windows.
    """
    path = os.environ.get("VARINT_CACHE_DIR")
    if path:
        return Path(path).expanduser()
    # appauthor=False: no vendor folder above "varint" on Windows.
    return Path(platformdirs.user_cache_dir("varint", appauthor=False))
