"""Motion primitives: nonic references, the shape trajectory planner that makes them
feasible, braking maneuvers, the primitive set Σ(d).
"""

from gracenav.primitives.sets import (
    CODE_VERSION,
    Maneuver,
    MotionPrimitive,
    PrimitiveReport,
    PrimitiveSample,
    PrimitiveSet,
    PrimitiveSetOptions,
    TrimPrimitive,
    cache_dir,
    primitive_set,
    rotation_matrix,
)

__all__ = [
    "CODE_VERSION",
    "Maneuver",
    "MotionPrimitive",
    "PrimitiveReport",
    "PrimitiveSample",
    "PrimitiveSet",
    "PrimitiveSetOptions",
    "TrimPrimitive",
    "cache_dir",
    "primitive_set",
    "rotation_matrix",
]
