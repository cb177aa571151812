"""The user cache directory shared by every on-disk cache of gracenav.

``$GRACENAV_CACHE_DIR`` when set, otherwise the platform's user cache
directory for ``gracenav`` (``$XDG_CACHE_HOME/gracenav`` or
``~/.cache/gracenav`` on Linux, ``~/Library/Caches/gracenav`` on macOS,
``%LOCALAPPDATA%\\gracenav\\Cache`` on Windows), as :mod:`platformdirs` defines it.

Cache files are named by a hash of what they are *built from* (parameters,
options, format and algorithm versions), never of a computed float, so the
same request finds the same file on any numpy/scipy build.
"""

from __future__ import annotations

import os
from pathlib import Path

import platformdirs

__all__ = ["CACHE_DIR_ENV", "cache_dir"]

#: Environment variable that overrides the cache directory.
CACHE_DIR_ENV = "GRACENAV_CACHE_DIR"


def cache_dir() -> Path:
    """Directory of gracenav's on-disk caches (it may not exist yet)."""
    env = os.environ.get(CACHE_DIR_ENV)
    return Path(env) if env else Path(platformdirs.user_cache_dir("gracenav", appauthor=False))
