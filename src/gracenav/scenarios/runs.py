"""The runs of a scenario: each start's episode summarised (:class:`RunSummary`), the
result of all of them (:class:`ScenarioResult`)."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from gracenav.params import BallbotParams
from gracenav.scenarios.spec import Scenario
from gracenav.sim import Push
from gracenav.world.moving import moving_clearance

__all__ = ["RunSummary", "ScenarioResult"]


@dataclass(frozen=True)
class RunSummary:
    """Machine-readable outcome of one run (one start) of a scenario.

    Every quantity's name ends with its unit (``_s``, ``_m``, ``_mps``, ``_deg``, ``_nm``
    (N m), ``_mps3`` (m/s³), ``_ms``); ``final_error_m`` is None for surveillance (no
    single goal). ``max_jerk_mps3`` and ``p95_jerk_mps3`` (its 95th percentile over the
    ticks) are the ball's jerk from the true state, the plant's ball velocity fitted
    over 0.3 s windows (:mod:`gracenav.execution.smoothness`), leaving out the ticks
    whose window holds a push (the impulse is a velocity step from outside).

    The simulated robot passes through obstacles (the plant has no contact model), so a
    run is judged on its footprint too: ``contact`` is true if the footprint overlapped
    an obstacle or the map edge at some tick (``min_clearance_m`` < 0; the first such
    time is ``contact_time_s``), and such a run never counts as ``reached_goal``.
    ``stop_reason`` is what the hybrid controller reported (:class:`TaskStatus`
    values); :attr:`outcome` is the verdict: ``contact`` for a run with contact,
    ``stop_reason`` otherwise. ``verified_recoveries`` counts switches after a domain
    exit straight into a policy whose start domain contains the state, ``captures``
    those of them into a catch placed at the state (:mod:`gracenav.execution.capture`);
    ``balancing_s`` is the time spent in balancing mode, the unverified last resort.
    With moving obstacles, the clearance and contact are measured against their true
    positions too; ``replans`` counts the tree repairs (median and largest wall time in
    ``replan_ms_median``, ``replan_ms_max``) and ``blocked_s`` the time spent holding
    while no way to the goal was free.
    """

    start: tuple[float, ...]
    reached_goal: bool
    stop_reason: str
    time_s: float
    path_length_m: float
    final_error_m: float | None
    final_speed_mps: float
    max_lean_deg: float
    max_torque_nm: float
    max_jerk_mps3: float
    p95_jerk_mps3: float
    switches: int
    non_graceful_switches: int
    max_graceful_torque_jump_nm: float
    min_clearance_m: float
    goals_reached: int
    tree_ms: float
    contact: bool = False
    contact_time_s: float | None = None
    verified_recoveries: int = 0
    captures: int = 0
    balancing_s: float = 0.0
    replans: int = 0
    replan_ms_median: float = 0.0
    replan_ms_max: float = 0.0
    blocked_s: float = 0.0

    def __post_init__(self) -> None:
        if self.contact and self.reached_goal:
            raise ValueError("a run with contact cannot have reached its goal")

    @property
    def outcome(self) -> str:
        """``"contact"`` if the footprint touched an obstacle, else ``stop_reason``
        (``goal_reached``, ``loops_completed``, ``no_policy``, ``timeout``,
        ``no_progress``, ``fell``)."""
        return "contact" if self.contact else self.stop_reason

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (strict JSON: a non-finite number becomes None): ``start``,
        ``reached_goal``, ``outcome``, ``stop_reason``, ``contact``, ``contact_time_s``,
        then the measures."""
        head = ("start", "reached_goal", "outcome", "stop_reason", "contact", "contact_time_s")
        values = {k: getattr(self, k) for k in head}
        values.update({k: getattr(self, k) for k in self.__dataclass_fields__ if k not in head})
        return {k: _json_value(v) for k, v in values.items()}


def _json_value(v: Any) -> Any:
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, (list, tuple)):
        return [_json_value(e) for e in v]
    return v


@dataclass(frozen=True)
class ScenarioResult:
    """A scenario's episodes, per-run summaries and the library figures."""

    scenario: Scenario
    episodes: tuple[Any, ...]
    runs: tuple[RunSummary, ...]
    library_size: int
    graph_edges: int
    coverage: float
    library_seconds: float
    world_map: Any = field(repr=False)
    library: Any = field(repr=False)
    plant_params: BallbotParams | None = None
    """The simulated plant's parameters (None: the palette's)."""


def _run_starts(
    scenario: Scenario,
    world_map: Any,
    plant_params: BallbotParams,
    radius: float,
    run: Callable[[np.ndarray], Any],
    progress: Callable[[int, int], None] | None,
) -> tuple[tuple[Any, ...], tuple[RunSummary, ...]]:
    """Run every start of the task with ``run`` (plant state (8,) → Episode), each
    starting where the controller believes it is (``radius``: its ball radius, m), and
    summarise the runs on ``world_map`` for ``plant_params``; ``progress`` after each."""
    from gracenav.sim import state_from_position

    episodes = []
    runs = []
    for i, start in enumerate(scenario.starts):
        ep = run(state_from_position(np.asarray(start), radius))
        episodes.append(ep)
        runs.append(_summarise(ep, start, scenario, world_map, plant_params))
        if progress is not None:
            progress(i + 1, len(scenario.starts))
    return tuple(episodes), tuple(runs)


def _summarise(
    ep: Any, start: Sequence[float], sc: Scenario, world_map: Any, params: BallbotParams
) -> RunSummary:
    p = ep.position_state
    goal = np.asarray(sc.goals[-1] if sc.kind == "point_to_point" else sc.goals[0])
    jumps = ep.graceful_torque_jumps()
    clearance = world_map.clearance(p[:, :2]) - sc.footprint_radius
    if sc.moving_obstacles:  # at their true positions, tick by tick
        moving = moving_clearance(sc.moving_obstacles, p[:, :2], ep.time) - sc.footprint_radius
        clearance = np.minimum(clearance, moving)
    latencies = [1000.0 * e.latency_s for e in ep.replans]
    touching = np.flatnonzero(clearance < 0.0)
    jerk = ep.jerk_profile([d.time for d in sc.disturbances if isinstance(d, Push)])
    contact = bool(touching.size)
    return RunSummary(
        start=tuple(float(v) for v in start),
        reached_goal=bool(ep.reached_goal) and not contact,
        stop_reason=ep.status.value,
        time_s=float(ep.time[-1]),
        path_length_m=ep.path_length,
        final_error_m=float(np.linalg.norm(p[-1, :2] - goal[:2]))
        if sc.kind == "point_to_point"
        else None,
        final_speed_mps=float(np.linalg.norm(p[-1, 2:])),
        max_lean_deg=float(np.rad2deg(np.max(np.abs(ep.lean)))),
        max_torque_nm=float(np.max(np.abs(ep.inputs))),
        max_jerk_mps3=jerk.max,
        p95_jerk_mps3=jerk.p95,
        switches=ep.switches,
        non_graceful_switches=ep.non_graceful_switches,
        max_graceful_torque_jump_nm=float(np.max(jumps)) if jumps.size else 0.0,
        min_clearance_m=float(np.min(clearance)),
        goals_reached=len(ep.goals_reached),
        tree_ms=1000.0 * float(np.median(ep.tree_seconds)) if ep.tree_seconds else 0.0,
        contact=contact,
        contact_time_s=float(ep.time[touching[0]]) if contact else None,
        verified_recoveries=ep.verified_recoveries,
        captures=sum(1 for e in ep.events if e.reason.value == "capture"),
        balancing_s=ep.balancing_time,
        replans=len(ep.replans),
        replan_ms_median=float(np.median(latencies)) if latencies else 0.0,
        replan_ms_max=float(np.max(latencies)) if latencies else 0.0,
        blocked_s=ep.blocked_time,
    )
