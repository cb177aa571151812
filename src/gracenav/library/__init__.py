"""The policy library: the palette instantiated on a map (lattice placement, swept-domain
checks, start-domain index, coverage).
"""

from gracenav.library.library import (
    DEFAULT_COVERAGE_SAMPLES,
    DEFAULT_MEMORY_LIMIT,
    DEFAULT_SPEED_CLEARANCE,
    MAX_SPEED_CLEARANCE,
    ORIENTATIONS,
    POLICY_BYTES,
    InstantiatedPolicy,
    InstantiationIteration,
    PolicyLibrary,
    PolicyTypes,
    build_library,
    estimate_library_size,
    max_trim_speed,
    quarter_turn,
    sample_position_states,
    sweep_samples,
)

__all__ = [
    "DEFAULT_COVERAGE_SAMPLES",
    "DEFAULT_MEMORY_LIMIT",
    "DEFAULT_SPEED_CLEARANCE",
    "MAX_SPEED_CLEARANCE",
    "ORIENTATIONS",
    "POLICY_BYTES",
    "InstantiatedPolicy",
    "InstantiationIteration",
    "PolicyLibrary",
    "PolicyTypes",
    "build_library",
    "estimate_library_size",
    "max_trim_speed",
    "quarter_turn",
    "sample_position_states",
    "sweep_samples",
]
