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
from typing import TYPE_CHECKING, Any

# Threaded BLAS makes the many small LAPACK calls of this package ~50x slower
# on small machines; respect a user's explicit choice.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from gracenav.errors import (
    CacheError,
    ConfigError,
    GracenavError,
    MapError,
    PlanningError,
)
from gracenav.params import BallbotParams

__version__ = "0.1.0"

if TYPE_CHECKING:
    from gracenav.control import design_gains
    from gracenav.execution import (
        Command,
        Episode,
        ExecutionOptions,
        HybridController,
        TaskStatus,
    )
    from gracenav.library import PolicyLibrary, build_library
    from gracenav.model import Ballbot3D, PlanarBallbot
    from gracenav.palette import Palette, load_palette
    from gracenav.planning import LazyPolicyTree, PolicyPath, PolicyTree, plan_path, plan_tree
    from gracenav.planning.graph import PreparesGraph, build_graph
    from gracenav.policies import MotionPolicy, run_policy
    from gracenav.primitives import primitive_set
    from gracenav.primitives.shape_planner import plan_shape_trajectory
    from gracenav.scenarios import load_scenario, run_scenario
    from gracenav.sim import (
        BodyForce,
        Drag,
        Model3DPlant,
        MujocoPlant,
        Plant,
        Push,
        StateJump,
        position_state,
        simulate,
        simulate_batch,
        state_from_position,
    )
    from gracenav.world import MovingObstacle, WorldMap, load_map

# Imported on first use (see __getattr__); the block above gives type checkers the same
# names with their real types.
_LAZY = {
    "Ballbot3D": "gracenav.model",
    "PlanarBallbot": "gracenav.model",
    "design_gains": "gracenav.control",
    "simulate": "gracenav.sim",
    "simulate_batch": "gracenav.sim",
    "run_policy": "gracenav.policies",
    "state_from_position": "gracenav.sim",
    "position_state": "gracenav.sim",
    "Push": "gracenav.sim",
    "BodyForce": "gracenav.sim",
    "StateJump": "gracenav.sim",
    "Drag": "gracenav.sim",
    "primitive_set": "gracenav.primitives",
    "plan_shape_trajectory": "gracenav.primitives.shape_planner",
    "MotionPolicy": "gracenav.policies",
    "Palette": "gracenav.palette",
    "load_palette": "gracenav.palette",
    "WorldMap": "gracenav.world",
    "MovingObstacle": "gracenav.world",
    "load_map": "gracenav.world",
    "PolicyLibrary": "gracenav.library",
    "build_library": "gracenav.library",
    "PreparesGraph": "gracenav.planning.graph",
    "build_graph": "gracenav.planning.graph",
    "PolicyTree": "gracenav.planning",
    "LazyPolicyTree": "gracenav.planning",
    "PolicyPath": "gracenav.planning",
    "plan_tree": "gracenav.planning",
    "plan_path": "gracenav.planning",
    "HybridController": "gracenav.execution",
    "ExecutionOptions": "gracenav.execution",
    "TaskStatus": "gracenav.execution",
    "Episode": "gracenav.execution",
    "Command": "gracenav.execution",
    "Plant": "gracenav.sim",
    "Model3DPlant": "gracenav.sim",
    "MujocoPlant": "gracenav.sim",
    "load_scenario": "gracenav.scenarios",
    "run_scenario": "gracenav.scenarios",
}

__all__ = [
    "Ballbot3D",
    "BallbotParams",
    "BodyForce",
    "CacheError",
    "Command",
    "ConfigError",
    "Drag",
    "Episode",
    "ExecutionOptions",
    "GracenavError",
    "HybridController",
    "LazyPolicyTree",
    "MapError",
    "Model3DPlant",
    "MotionPolicy",
    "MovingObstacle",
    "MujocoPlant",
    "Palette",
    "PlanarBallbot",
    "PlanningError",
    "Plant",
    "PolicyLibrary",
    "PolicyPath",
    "PolicyTree",
    "PreparesGraph",
    "Push",
    "StateJump",
    "TaskStatus",
    "WorldMap",
    "__version__",
    "build_graph",
    "build_library",
    "design_gains",
    "load_map",
    "load_palette",
    "load_scenario",
    "plan_path",
    "plan_shape_trajectory",
    "plan_tree",
    "position_state",
    "primitive_set",
    "run_policy",
    "run_scenario",
    "simulate",
    "simulate_batch",
    "state_from_position",
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
