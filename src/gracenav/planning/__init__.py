"""Planning on the library: the gracefully prepares graph, single-goal policy trees (whole
and lazy), their compiled searches, and tree repair for moving obstacles.
"""

from gracenav.planning.trees import (
    CostCriterion,
    LazyPolicyTree,
    PolicyPath,
    PolicyTree,
    plan_path,
    plan_tree,
)

__all__ = [
    "CostCriterion",
    "LazyPolicyTree",
    "PolicyPath",
    "PolicyTree",
    "plan_path",
    "plan_tree",
]
