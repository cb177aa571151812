"""Motion primitives: nonic references, the shape trajectory planner that makes them
feasible, the primitive set Σ(d).
"""

from gracenav.primitives.motion import (
    Maneuver,
    MotionPrimitive,
    PrimitiveReport,
    PrimitiveSample,
    PrimitiveSet,
    PrimitiveSetOptions,
    TrimPrimitive,
)
from gracenav.primitives.sets import (
    CODE_VERSION,
    cache_dir,
    primitive_set,
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
]
