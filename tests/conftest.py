"""Shared test set-up: single-threaded BLAS, headless plotting, a private cache.

The primitive cache (``gracenav.primitives.cache_dir``) and matplotlib's font cache go
to a temporary directory of this test session, never to the user's home.
"""

from __future__ import annotations

import os
import shutil
import tempfile

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MPLBACKEND", "Agg")

_CACHE = tempfile.mkdtemp(prefix="gracenav-test-cache-")
os.environ["GRACENAV_CACHE_DIR"] = _CACHE
os.environ.setdefault("MPLCONFIGDIR", os.path.join(_CACHE, "matplotlib"))


def pytest_unconfigure(config: object) -> None:
    shutil.rmtree(_CACHE, ignore_errors=True)
