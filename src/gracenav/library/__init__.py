"""Automatic instantiation of motion policies: the motion policy library L(Π, M).

Paper Sec. IV-A. The dynamics of the ballbot are invariant to translations and
rotations of its position variables, so every policy of the palette Π can be
placed anywhere on the map M in any orientation. Instantiation points are the
nodes of a square lattice of spacing d (the palette's distance parameter) along
X and Y, anchored at the map's minimum corner; each palette policy is placed at
each point in the four orientations k · 90° (k = 0..3, counter-clockwise about
the policy's start). An instantiation is kept iff its outer domain D'(t),
projected on the XY plane and swept over [0, t_f], grown by the robot's
footprint, is obstacle free and inside the map.

Coverage is the fraction of uniformly sampled position states of the bounded
position state space (free positions with clearance >= footprint, velocities
uniform in [-v_max, v_max]², v_max the largest trim speed of the palette) that
lie in at least one instantiated start domain S. Below the target, the lattice
spacing is halved (d/2, d/4, ...) and instantiation repeats, up to a limit.

Library data are columnar numpy arrays, one row per instantiated policy, in
*type* order: type t = 4 p + k (palette policy p at orientation k), then
instantiation point (row-major on the lattice). Orientation k rotates
positions, velocities, accelerations and the body lean (a vector toward the
direction of motion) by the exact quarter-turn matrix :func:`quarter_turn`.
Domains have shape matrices M ⊗ I₂ in (x, y, ẋ, ẏ) (per-axis 2 × 2 M coupling
position and velocity, the same for x and y), which are invariant under
rotations of the plane: they rotate trivially, and the XY projection of D'(t)
is a disc of radius (outer position factor) × (position extent of D(t)).

Modules: :mod:`~gracenav.library.types` (policy types, instantiated policies),
:mod:`~gracenav.library.sweeps` (swept outer domains sampled),
:mod:`~gracenav.library.push_fans` (the catches a design push calls for),
:mod:`~gracenav.library.sweep_check` (the compiled check of sweeps against the map),
:mod:`~gracenav.library.instantiation` (lattice placement, memory budget,
:func:`build_library`), :mod:`~gracenav.library.library` (the library, its start index
and coverage).
"""

from gracenav.library.instantiation import (
    DEFAULT_DESIGN_PUSH,
    DEFAULT_MEMORY_LIMIT,
    DEFAULT_SPEED_CLEARANCE,
    ESTIMATE_SAMPLES,
    LATTICE_POINT_BYTES,
    MAX_DESIGN_PUSH,
    MAX_SPEED_CLEARANCE,
    POLICY_BYTES,
    LibrarySizeEstimate,
    build_library,
    estimate_library_size,
    expected_library_size,
    lattice_origin,
    lattice_points,
    max_trim_speed,
)
from gracenav.library.library import (
    DEFAULT_COVERAGE_SAMPLES,
    PolicyLibrary,
    sample_position_states,
)
from gracenav.library.push_fans import (
    PushFan,
    push_fan,
)
from gracenav.library.sweeps import (
    sweep_samples,
    swept_discs,
)
from gracenav.library.types import (
    ORIENTATIONS,
    InstantiatedPolicy,
    InstantiationIteration,
    PolicyTypes,
    quarter_turn,
)

__all__ = [
    "DEFAULT_COVERAGE_SAMPLES",
    "DEFAULT_DESIGN_PUSH",
    "DEFAULT_MEMORY_LIMIT",
    "DEFAULT_SPEED_CLEARANCE",
    "ESTIMATE_SAMPLES",
    "LATTICE_POINT_BYTES",
    "MAX_DESIGN_PUSH",
    "MAX_SPEED_CLEARANCE",
    "ORIENTATIONS",
    "POLICY_BYTES",
    "InstantiatedPolicy",
    "InstantiationIteration",
    "LibrarySizeEstimate",
    "PolicyLibrary",
    "PolicyTypes",
    "PushFan",
    "build_library",
    "estimate_library_size",
    "expected_library_size",
    "lattice_origin",
    "lattice_points",
    "max_trim_speed",
    "push_fan",
    "quarter_turn",
    "sample_position_states",
    "sweep_samples",
    "swept_discs",
]
