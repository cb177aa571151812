"""The hybrid controller on a lazy tree (what it uses where the graph keeps no reversed
graph): the same runs as with the whole tree, forced on small maps by lowering
:data:`gracenav.planning.graph.STORED_EDGES`."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

import numpy as np
import pytest
import yaml

import gracenav.planning.graph as graph_module
from gracenav.errors import ConfigError
from gracenav.execution import ExecutionOptions, HybridController, TaskStatus
from gracenav.library import build_library
from gracenav.planning import LazyPolicyTree, PolicyTree
from gracenav.planning.graph import build_graph
from gracenav.policies import PrimitiveKind
from gracenav.sim import Push, state_from_position
from gracenav.world import load_map
from gracenav.world.moving import MovingObstacle

SCENARIOS = Path(str(resources.files("gracenav") / "data" / "scenarios"))


def _map(name: str):  # type: ignore[no-untyped-def]
    return load_map(yaml.safe_load((SCENARIOS / name).read_text())["map"])


def _controllers(lib, monkeypatch: pytest.MonkeyPatch):  # type: ignore[no-untyped-def]
    whole = HybridController(lib, build_graph(lib))
    monkeypatch.setattr(graph_module, "STORED_EDGES", 0)
    lazy = HybridController(lib, build_graph(lib))
    return whole, lazy


def _same_runs(a, b) -> None:  # type: ignore[no-untyped-def]
    assert a.status is b.status
    assert [(e.from_policy, e.to_policy, e.reason, e.tick) for e in a.events] == [
        (e.from_policy, e.to_policy, e.reason, e.tick) for e in b.events
    ]
    np.testing.assert_array_equal(a.states, b.states)


def test_point_to_point_with_pushes_as_with_the_whole_tree(
    fig5_library, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Pushed twice on the way (domain exits, recoveries): the lazy tree's runs switch
    to the same policies at the same ticks as the whole tree's, to the goal."""
    whole, lazy = _controllers(fig5_library, monkeypatch)
    r = whole.params.ball_radius
    pushes = (Push(2.0, (0.0, -12.0)), Push(5.0, (10.0, 6.0)))
    for start, goal in (((0.0, 0.0), (2.0, 2.0)), ((3.0, 0.0), (0.0, 2.0))):
        x0 = state_from_position([*start, 0.0, 0.0], r)
        g = [[*goal, 0.0, 0.0]]
        opts = ExecutionOptions(max_time=60.0)
        a = whole.run(x0, g, disturbances=pushes, options=opts)
        b = lazy.run(x0, g, disturbances=pushes, options=opts)
        assert a.status is TaskStatus.GOAL_REACHED
        _same_runs(a, b)
        assert sum(e.reason.value in ("domain_exit", "capture") for e in b.events) >= 1
        tree = lazy.tree(lazy.goal_policy(g[0]))
        assert isinstance(tree, LazyPolicyTree)
        assert 0 < tree.expanded < 0.8 * len(fig5_library)  # not the whole tree
        assert isinstance(whole.tree(whole.goal_policy(g[0])), PolicyTree)


def test_surveillance_as_with_the_whole_tree(palette, monkeypatch: pytest.MonkeyPatch) -> None:
    """One loop of the paper's surveillance task: each next goal's tree is read at the
    previous goal policy; the same switches as with whole trees."""
    spec = yaml.safe_load((SCENARIOS / "fig8_surveillance.yaml").read_text())
    lib = build_library(
        palette, _map("fig8_surveillance.yaml"), footprint_radius=0.2, max_halvings=1
    )
    whole, lazy = _controllers(lib, monkeypatch)
    x0 = state_from_position(spec["task"]["start"], whole.params.ball_radius)
    goals = spec["task"]["goals"]
    opts = ExecutionOptions(max_time=40.0)
    a = whole.run(x0, goals, loops=2, options=opts)
    b = lazy.run(x0, goals, loops=2, options=opts)
    assert a.status is TaskStatus.LOOPS_COMPLETED
    _same_runs(a, b)


def test_recovery_point_on_a_lazy_tree_reaches_the_goal(
    fig5_library, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Balancing mode's point on a lazy tree is a rest-trim start that reaches the goal
    (by the whole tree), and the nearest one the search knows."""
    whole, lazy = _controllers(fig5_library, monkeypatch)
    lib = fig5_library
    goal = whole.goal_policy([2.0, 2.0, 0.0, 0.0])
    full = whole.tree(goal)
    rest = lib.trim_indices(PrimitiveKind.REST)
    good = {tuple(xy) for xy in lib.start_xy[rest[np.isfinite(full.cost_to_go[rest])]]}
    rng = np.random.default_rng(5)
    checked = 0
    for here in rng.uniform(0.3, 3.2, size=(12, 2)):
        tree = lazy.tree(goal)
        q = lazy.recovery_point(np.array([*here, 0.0, 0.0]), tree)
        if np.array_equal(q, here):
            continue
        assert tuple(q) in good
        checked += 1
    assert checked >= 6


def test_moving_obstacles_on_a_lazy_tree_are_refused(
    fig5_library, monkeypatch: pytest.MonkeyPatch
) -> None:
    _, lazy = _controllers(fig5_library, monkeypatch)
    person = MovingObstacle(radius=0.25, path=((3.0, 0.0), (3.0, 3.0)), speed=0.5)
    x0 = state_from_position([0.0, 0.0, 0.0, 0.0], lazy.params.ball_radius)
    with pytest.raises(ConfigError, match="moving obstacles need the whole single-goal tree"):
        lazy.run(x0, [[2.0, 2.0, 0.0, 0.0]], moving_obstacles=[person])
