"""The memory budget of a scenario: the peak resident memory of running it, estimated
before anything is allocated, and the most library halvings that fit.

A map is refused only when it would not fit the budget (``planner.memory_limit_gib``,
2 GiB by default). Without ``planner.max_halvings`` a scenario refines its library up to
:data:`DEFAULT_MAX_HALVINGS` times, fewer where that would not fit; a ``max_halvings``
given that would not fit is refused, with the largest that would.

The estimate of a run's peak (bytes) is

    RUN_BASE_BYTES + OUTPUT_BYTES + MAP_CELL_BYTES × cells + RUN_POINT_BYTES × P
    + RUN_POLICY_BYTES × N + STORED_EDGE_BYTES × E + 4 × L

with L the entries of the graph's (point, type) lookup table, P × T for T palette
policy types when that is at most :data:`gracenav.planning.graph.DENSE_LOOKUP`, else 0,
and P the lattice points of the last pass, N its policies (the upper figure of
:func:`gracenav.library.expected_library_size`: its estimate plus two standard errors)
and E the edges of the reversed graph the controller stores, ≈
:data:`STORED_EDGES_PER_POLICY` × N when that is at most
:data:`gracenav.planning.graph.STORED_EDGES` (beyond it the searches generate the edges
from the lattice and store none). The constants are the peak resident memory of
``gracenav run`` (``/usr/bin/time -v``), measured on the 30 m × 50 m warehouse at 3 cm
and a 100 m × 100 m office at 5 cm, with 0 and 1 halvings (bench/bench_bigmaps.py): the
estimate lies above each measured peak, by 2 % (the warehouse at d) to 33 % (the
warehouse at d/2, whose peak varied between 0.66 and 0.86 GiB); see docs/design/memory.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from gracenav.errors import ConfigError
from gracenav.library import (
    DEFAULT_DESIGN_PUSH,
    DEFAULT_SPEED_CLEARANCE,
    expected_library_size,
    lattice_points,
)

__all__ = [
    "DEFAULT_MAX_HALVINGS",
    "DEFAULT_MEMORY_LIMIT_GIB",
    "MAX_MEMORY_LIMIT_GIB",
    "MemoryEstimate",
    "choose_halvings",
    "estimate_run_memory",
]

GIB = 2**30
"""Bytes in a GiB."""

DEFAULT_MAX_HALVINGS = 1
"""Most spacing halvings of a scenario's library when ``planner.max_halvings`` is not
given (fewer where they would not fit the memory budget)."""

DEFAULT_MEMORY_LIMIT_GIB = 2.0
"""Default memory budget of a scenario (GiB), ``planner.memory_limit_gib``."""

MAX_MEMORY_LIMIT_GIB = 1024.0
"""Largest memory budget accepted (GiB)."""

RUN_BASE_BYTES = 320 * 2**20
"""The interpreter with numpy, scipy, numba and matplotlib loaded and the palette: the
resident memory of ``gracenav run`` at its first control command on a 5 m room."""

OUTPUT_BYTES = 224 * 2**20
"""Writing the results: figures and animation (measured +220 MiB over the first control
command on the warehouse and the office)."""

MAP_CELL_BYTES = 28
"""Per map cell: occupancy grid, clearance field and its distance transform, and the
sweep check's lower bound on the clearance (8)."""

RUN_POINT_BYTES = 256
"""Per lattice point of the last pass: coordinates, clearance and a flag per scale group
(164 with the shipped palette) while instantiating."""

RUN_POLICY_BYTES = 290
"""Per library policy of the last pass: the library (128), instantiation's temporaries,
the previous pass's library, the graph's lattice tables, the controller's trees and
catches."""

STORED_EDGES_PER_POLICY = 18
"""Edges per policy of the gracefully-prepares graph, to estimate the stored reversed
graph: 16.3–17.8 measured on offices and warehouses (28 on an open hall, whose graphs
beyond 1.6 M policies are too large to store)."""

STORED_EDGE_BYTES = 12
"""Per edge of a stored reversed graph (an int32 index and a float64 cost)."""


@dataclass(frozen=True)
class MemoryEstimate:
    """The estimated peak resident memory of running a scenario with a library of
    ``halvings`` halvings (:func:`estimate_run_memory`).

    Attributes
    ----------
    halvings : int
    spacing : float
        Lattice spacing of the last pass (m).
    lattice_points : int
        Lattice points of the last pass.
    policies : float or None
        Library policies budgeted for (an upper estimate); None when the rest alone
        exceeds the limit it was asked against (the policies were not estimated).
    stored_edges : float
        Edges of the reversed graph the controller is expected to store (0: none).
    bytes : float
        The estimated peak (a lower bound when ``policies`` is None).
    """

    halvings: int
    spacing: float
    lattice_points: int
    policies: float | None
    stored_edges: float
    bytes: float

    @property
    def gib(self) -> float:
        """:attr:`bytes` in GiB."""
        return self.bytes / GIB

    def describe(self) -> str:
        """The estimate in words: "about 1.93 GiB (about 4.9e+06 policies at spacing
        0.25 m)", or "at least ..." when the policies were not estimated."""
        where = f"at spacing {self.spacing:g} m"
        if self.policies is None:
            points = f"a lattice of {self.lattice_points:.3g} points"
            return f"at least {self.gib:.2f} GiB ({points} {where})"
        return f"about {self.gib:.2f} GiB (about {self.policies:.3g} policies {where})"


def estimate_run_memory(
    world_map: Any,
    palette: Any,
    halvings: int,
    *,
    footprint_radius: float = 0.2,
    speed_clearance: float = DEFAULT_SPEED_CLEARANCE,
    limit: float | None = None,
    whole_map: Any = None,
    design_push: float = DEFAULT_DESIGN_PUSH,
    policy_cap: float | None = None,
) -> MemoryEstimate:
    """Estimate the peak resident memory (bytes) of running a scenario on ``world_map``
    whose library refines the lattice ``halvings`` times (see the module docstring).

    Nothing proportional to the library is allocated: the lattice is counted by
    arithmetic, and the policies are estimated from the clearance at the lattice points
    and instantiation's check at a sample of them (about 0.1 s on a 100 m map). With a
    ``limit``, when the policies' upper bound from the clearance alone fits it (and is
    within ``policy_cap``), the sample is not checked and the bound is what is budgeted
    for: the answer to "does it fit" is the one the sample would give, without its cost
    (seconds on a small map with a design push).

    Parameters
    ----------
    world_map : WorldMap
    palette : Palette
    halvings : int
        Halvings of the library's last pass (spacing d / 2^halvings).
    footprint_radius : float
        (m)
    speed_clearance : float
        The library's stopping allowance (s).
    limit : float, optional
        Bytes of the budget: when the lattice and the rest alone exceed it, the
        policies are not estimated (:attr:`MemoryEstimate.policies` is None).
    whole_map : WorldMap, optional
        The map the run is measured on, when ``world_map`` is a region of it that the
        library is built on (:mod:`gracenav.scenarios.region`): its cells count too.
    design_push : float
        The library's design push (N s).
    policy_cap : float, optional
        With ``limit``: policies above which the sample is checked even when the bound
        fits the limit (:func:`choose_halvings`' ``policy_cap``).

    Returns
    -------
    MemoryEstimate
    """
    from gracenav.planning.graph import DENSE_LOOKUP, STORED_EDGES

    spacing = float(palette.d) / 2**halvings
    points = lattice_points(world_map, spacing)
    cells = int(world_map.occupied.size)
    if whole_map is not None and whole_map is not world_map:
        cells += int(whole_map.occupied.size)
    lookup = points * 4 * len(palette.policies)  # the graph's (point, type) table
    fixed = float(
        RUN_BASE_BYTES
        + OUTPUT_BYTES
        + MAP_CELL_BYTES * cells
        + RUN_POINT_BYTES * points
        + 4 * (lookup if lookup <= DENSE_LOOKUP else 0)
    )
    if limit is not None and fixed > limit:
        return MemoryEstimate(halvings, spacing, points, None, 0.0, fixed)
    sample_above = None
    if limit is not None:
        # The most policies whose peak fits for sure: the peak with the stored edges
        # capped at STORED_EDGES grows with the policies, and is never below the
        # estimate's (beyond the cap the graph stores none).
        room = limit - fixed
        per_policy = RUN_POLICY_BYTES + STORED_EDGE_BYTES * STORED_EDGES_PER_POLICY
        sample_above = max(
            min(room / per_policy, STORED_EDGES / STORED_EDGES_PER_POLICY),
            (room - STORED_EDGE_BYTES * STORED_EDGES) / RUN_POLICY_BYTES,
        )
        if policy_cap is not None:
            sample_above = min(sample_above, float(policy_cap))
    est = expected_library_size(
        palette,
        world_map,
        spacing,
        footprint_radius=footprint_radius,
        speed_clearance=speed_clearance,
        design_push=design_push,
        sample_above=sample_above,
    )
    policies = est.upper()
    edges = STORED_EDGES_PER_POLICY * policies
    stored = edges if edges <= STORED_EDGES else 0.0
    total = fixed + RUN_POLICY_BYTES * policies + STORED_EDGE_BYTES * stored
    return MemoryEstimate(halvings, spacing, points, policies, stored, total)


def choose_halvings(
    world_map: Any,
    palette: Any,
    *,
    max_halvings: int | None,
    memory_limit: float,
    footprint_radius: float = 0.2,
    speed_clearance: float = DEFAULT_SPEED_CLEARANCE,
    source: str = "scenario",
    keys: tuple[str, str] = ("planner.max_halvings", "planner.memory_limit_gib"),
    whole_map: Any = None,
    policy_cap: float | None = None,
    design_push: float = DEFAULT_DESIGN_PUSH,
) -> MemoryEstimate:
    """The halvings of a library that fit ``memory_limit`` bytes, with their estimate.

    ``max_halvings`` None: the most, up to :data:`DEFAULT_MAX_HALVINGS`, whose estimated
    peak (:func:`estimate_run_memory`) fits. An ``int``: those halvings, if they fit.

    Parameters
    ----------
    world_map, palette, footprint_radius, speed_clearance, design_push
        As :func:`estimate_run_memory`.
    max_halvings : int or None
    memory_limit : float
        Bytes.
    source : str
        What the messages name first (the scenario file).
    keys : (str, str)
        How the messages name the halvings and the budget settings: the scenario keys,
        or command-line options (``--max-halvings``, ``--memory-limit-gib``).
    whole_map : WorldMap, optional
        As :func:`estimate_run_memory`.
    policy_cap : float, optional
        With ``max_halvings`` None, also fewer halvings while the estimated policies
        exceed this (never fewer than none): a task's region takes a coarser lattice
        rather than a later first command (:data:`gracenav.scenarios.region.REGION_POLICIES`).

    Raises
    ------
    ConfigError
        When the given halvings, or (automatic) even one pass at spacing d, would not
        fit: one line with the estimate, the budget and what to do.
    """
    halvings_key, limit_key = keys
    option = halvings_key.startswith("--")
    budget = f"the memory budget of {memory_limit / GIB:.3g} GiB ({limit_key})"
    (x0, y0), (x1, y1) = world_map.bounds
    area = f"this {x1 - x0:g} m × {y1 - y0:g} m map"
    top = DEFAULT_MAX_HALVINGS if max_halvings is None else max_halvings
    first: MemoryEstimate | None = None
    for h in range(top, -1, -1):
        est = estimate_run_memory(
            world_map,
            palette,
            h,
            footprint_radius=footprint_radius,
            speed_clearance=speed_clearance,
            limit=memory_limit,
            whole_map=whole_map,
            design_push=design_push,
            policy_cap=policy_cap if max_halvings is None and h > 0 else None,
        )
        if est.bytes <= memory_limit:
            capped = (
                max_halvings is None
                and policy_cap is not None
                and h > 0
                and est.policies is not None
                and est.policies > policy_cap
            )
            if capped:
                continue
            if first is None or max_halvings is None:
                return est
            fit = (
                f"{halvings_key} {h}"
                if option
                else f"{halvings_key} <= {h} (or leave it out to choose automatically)"
            )
            raise ConfigError(
                f"{source}: '{halvings_key}' {max_halvings} on {area} would need "
                f"{first.describe()}, more than {budget}; use {fit}, or raise {limit_key} "
                "if the machine has the memory"
            )
        if first is None:
            first = est
    assert first is not None
    # est: one pass at spacing d, the least this map can need.
    if max_halvings:
        lead = (
            f"'{halvings_key}' {max_halvings} on {area} would need {first.describe()}, and "
            f"even no halvings {est.describe()}"
        )
    else:
        lead = f"{area} needs {est.describe()} even without halvings"
    raise ConfigError(
        f"{source}: {lead}, more than {budget}; plan on a smaller map or a region of it, "
        f"or raise {limit_key} to {'at least ' if est.policies is None else ''}"
        f"{math.ceil(10 * est.gib) / 10:g} if the machine has the memory"
    )
