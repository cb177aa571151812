"""gracenav: graceful navigation of balancing mobile robots (the ballbot).

Implements Nagarajan, Kantor & Hollis, "Integrated Planning and Control for
Graceful Navigation of Shape-Accelerated Underactuated Balancing Mobile
Robots", ICRA 2012, and goes beyond it.

The main entry points are re-exported here and imported on first use, so
``import gracenav`` stays light::

    from gracenav import load_palette, load_map, build_library, build_graph
    from gracenav import HybridController, load_scenario, run_scenario
"""

from __future__ import annotations

import importlib
import os
from typing import Any

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

_LAZY = {
    "Ballbot3D": "gracenav.model",
    "PlanarBallbot": "gracenav.model",
    "design_gains": "gracenav.control",
    "simulate": "gracenav.simulate",
    "simulate_batch": "gracenav.simulate",
    "run_policy": "gracenav.simulate",
    "primitive_set": "gracenav.primitives",
    "plan_shape_trajectory": "gracenav.shape_planner",
    "MotionPolicy": "gracenav.policies",
    "Palette": "gracenav.palette",
    "load_palette": "gracenav.palette",
    "WorldMap": "gracenav.world",
    "MovingObstacle": "gracenav.world",
    "load_map": "gracenav.world",
    "PolicyLibrary": "gracenav.library",
    "build_library": "gracenav.library",
    "PreparesGraph": "gracenav.graph",
    "build_graph": "gracenav.graph",
    "PolicyTree": "gracenav.planning",
    "LazyPolicyTree": "gracenav.planning",
    "PolicyPath": "gracenav.planning",
    "plan_tree": "gracenav.planning",
    "plan_path": "gracenav.planning",
    "HybridController": "gracenav.execution",
    "Episode": "gracenav.execution",
    "load_scenario": "gracenav.scenarios",
    "run_scenario": "gracenav.scenarios",
}

__all__ = [
    "BallbotParams",
    "CacheError",
    "ConfigError",
    "GracenavError",
    "MapError",
    "PlanningError",
    "VerificationError",
    "__version__",
    *sorted(_LAZY),
]


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'gracenav' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(__all__)
