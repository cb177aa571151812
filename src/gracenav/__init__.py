"""gracenav: graceful navigation of balancing mobile robots (the ballbot).

Implements Nagarajan, Kantor & Hollis, "Integrated Planning and Control for
Graceful Navigation of Shape-Accelerated Underactuated Balancing Mobile
Robots", ICRA 2012, and goes beyond it.
"""

from __future__ import annotations

import os

# Threaded BLAS makes the many small LAPACK calls of this package ~50x slower
# on small machines; respect a user's explicit choice.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from gracenav.errors import (
    CacheError,
    ConfigError,
    GracenavError,
    MapError,
    PlanningError,
    VerificationError,
)
from gracenav.params import BallbotParams

__version__ = "0.1.0"

__all__ = [
    "BallbotParams",
    "CacheError",
    "ConfigError",
    "GracenavError",
    "MapError",
    "PlanningError",
    "VerificationError",
    "__version__",
]
