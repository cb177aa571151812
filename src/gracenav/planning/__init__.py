"""Planning on the library: the gracefully prepares graph, single-goal policy trees (whole
and lazy), their compiled searches, and tree repair for moving obstacles.
"""

from gracenav.planning.graph import (
    STORED_EDGES,
    CostCriterion,
    PreparesGraph,
    build_graph,
    gracefully_prepares,
)
from gracenav.planning.trees import (
    LazyPolicyTree,
    PolicyPath,
    PolicyTree,
    plan_path,
    plan_tree,
)

__all__ = [
    "STORED_EDGES",
    "CostCriterion",
    "LazyPolicyTree",
    "PolicyPath",
    "PolicyTree",
    "PreparesGraph",
    "build_graph",
    "gracefully_prepares",
    "plan_path",
    "plan_tree",
]
