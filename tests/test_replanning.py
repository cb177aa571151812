"""Moving obstacles: their motion, the blocked policies, the tree repair, and runs
with a person crossing a corridor and a cart in a doorway."""

from __future__ import annotations

import csv
import json
import math
import re
from importlib import resources
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
import yaml

from gracenav.errors import ConfigError
from gracenav.library import build_library
from gracenav.planning import plan_tree
from gracenav.planning.graph import build_graph
from gracenav.planning.repair import (
    SWEEP_STEP,
    KnownObstacle,
    ObstacleSensing,
    SweptDomains,
    blocked_policies,
    repair_tree,
    sense,
)
from gracenav.scenarios import load_scenario, parse_scenario, run_scenario, write_outputs
from gracenav.world import load_map
from gracenav.world.moving import MovingObstacle, moving_clearance

SCENARIOS = Path(str(resources.files("gracenav") / "data" / "scenarios"))


@pytest.fixture(scope="module")
def small(palette):
    wm = load_map({"bounds": [[0, 0], [3.5, 3.5]], "obstacles": [], "resolution": 0.05})
    lib = build_library(palette, wm, footprint_radius=0.2, max_halvings=0)
    return lib, build_graph(lib)


def test_moving_obstacle_closed_form() -> None:
    ob = MovingObstacle(0.3, ((0.0, 0.0), (3.0, 0.0), (3.0, 4.0)), speed=1.0, appear=2.0, leave=20)
    assert ob.length == pytest.approx(7.0)
    pos = ob.position([0.0, 2.0, 3.5, 6.0, 100.0])
    np.testing.assert_allclose(pos, [[0, 0], [0, 0], [1.5, 0], [3, 1], [3, 4]], atol=1e-12)
    np.testing.assert_allclose(ob.velocity(3.0), [1.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(ob.velocity(6.0), [0.0, 1.0], atol=1e-12)
    np.testing.assert_allclose(ob.velocity(50.0), [0.0, 0.0])  # end of its path
    np.testing.assert_allclose(ob.velocity(25.0), [0.0, 0.0])  # gone
    assert list(ob.present([1.9, 2.0, 19.9, 20.0])) == [False, True, True, False]
    # Finite differences of the position equal the velocity.
    t = 4.2
    fd = (ob.position(t + 1e-6) - ob.position(t - 1e-6)) / 2e-6
    np.testing.assert_allclose(fd, ob.velocity(t), atol=1e-6)
    c = moving_clearance([ob], [[1.5, 1.0], [1.5, 1.0]], [3.5, 1.0])
    assert c[0] == pytest.approx(0.7) and c[1] == math.inf
    with pytest.raises(ValueError, match="leave"):
        MovingObstacle(0.3, ((0.0, 0.0),), appear=5.0, leave=5.0)


def test_sensing_range() -> None:
    ob = MovingObstacle(0.5, ((4.0, 0.0),))
    s = ObstacleSensing(range=3.0)
    assert sense([ob], np.array([0.4, 0.0]), 0.0, s) == ()  # edge 3.1 m away
    known = sense([ob], np.array([0.6, 0.0]), 0.0, s)  # edge 2.9 m away
    assert len(known) == 1 and known[0].center == (4.0, 0.0) and known[0].radius == 0.5


def _masked_tree(graph, goal: int, blocked: np.ndarray):
    """Full search on the graph without the blocked policies (an independent route)."""
    a = graph.csr("time").tocoo()
    keep = ~blocked[a.row] & ~blocked[a.col]
    m = sp.csr_matrix((a.data[keep], (a.row[keep], a.col[keep])), shape=a.shape)
    tree = plan_tree(m.tocsc(), goal)
    if blocked[goal]:
        tree.cost_to_go[:] = np.inf
    return tree


def test_repair_equals_a_full_search(small) -> None:
    """A chain of repairs (blocking discs of policies, then freeing them) gives the
    costs of a full search without the blocked policies, exactly, and next policies that
    attain them."""
    lib, graph = small
    trims = lib.trim_indices()
    goal = int(trims[len(trims) // 2])
    tree = plan_tree(graph.csc("time"), goal)
    rng = np.random.default_rng(3)
    prev = np.zeros(len(lib), dtype=bool)
    cost = graph.node_cost("time")
    for k in range(25):
        c, r = rng.uniform(0, 3.5, 2), rng.uniform(0.2, 1.2)
        blocked = np.linalg.norm(lib.start_xy - c, axis=1) < r
        if k % 6 == 5:
            blocked[:] = False  # everything freed at once
        if k == 7:
            blocked[goal] = True  # the goal itself: nothing reaches it
        tree, _ = repair_tree(tree, graph, prev, blocked)
        ref = _masked_tree(graph, goal, blocked)
        fin = np.isfinite(ref.cost_to_go)
        assert np.array_equal(fin, np.isfinite(tree.cost_to_go)), k
        np.testing.assert_array_equal(tree.cost_to_go[fin], ref.cost_to_go[fin])
        assert not np.any(fin & blocked)
        src = np.flatnonzero(fin & (np.arange(len(lib)) != goal))
        nxt = tree.next_policy[src]
        assert np.all(nxt >= 0) and not np.any(blocked[nxt])
        np.testing.assert_array_equal(cost[src] + tree.cost_to_go[nxt], tree.cost_to_go[src])
        prev = blocked


def _brute_distance(lib, row: int, ob: KnownObstacle, period: float) -> float:
    """Smallest clearance between row's D' (sampled at every control tick, through
    InstantiatedPolicy, not the compiled kernel) and the obstacle's capsule."""
    inst = lib.policy(row)
    pol = inst.policy
    t = np.arange(pol.primitive.num_ticks + 1) * pol.primitive.dt
    ref = inst.position_state(t)[:, :2]
    rad = np.broadcast_to(pol.outer_extents(t)[0], t.shape)
    c = np.asarray(ob.center)
    b = c + np.asarray(ob.velocity) * (pol.duration + period)
    ab = b - c
    s = np.clip((ref - c) @ ab / max(float(ab @ ab), 1e-300), 0, 1) if ab @ ab > 0 else 0.0
    near = c + np.multiply.outer(s, ab) if ab @ ab > 0 else c
    return float(np.min(np.linalg.norm(ref - near, axis=1) - rad))


def test_blocked_policies_against_a_brute_force(small) -> None:
    """The compiled test is conservative by at most the sample spacing: every policy
    whose D' (every tick) meets the grown capsule is blocked, and every blocked one
    comes within the grown capsule plus one sample step."""
    lib, _ = small
    swept = SweptDomains.of_palette(lib.palette)
    sensing = ObstacleSensing()
    rng = np.random.default_rng(5)
    for _ in range(3):
        ob = KnownObstacle(
            0, tuple(rng.uniform(0.5, 3.0, 2)), tuple(rng.uniform(-0.8, 0.8, 2)), 0.3
        )
        blocked = blocked_policies(lib, swept, [ob], footprint=0.2, sensing=sensing)
        grow = ob.radius + 0.2 + sensing.margin
        rows = rng.choice(len(lib), 300, replace=False)
        for i in rows:
            d = _brute_distance(lib, int(i), ob, sensing.period)
            if d < grow:
                assert blocked[i], (i, d)
            if blocked[i]:
                assert d < grow + SWEEP_STEP, (i, d)
        assert 0 < blocked.sum() < len(lib)


def test_scenario_schema_of_moving_obstacles() -> None:
    data = yaml.safe_load((SCENARIOS / "doorway_cart.yaml").read_text())
    for patch, message in (
        ({"radius": -1}, "'moving_obstacles[0].radius' must be a number in (0, 5] m, got -1"),
        ({"leave": 2.0}, "'moving_obstacles[0].leave' 2 s must come after appear (3 s)"),
        ({"appear": 100.0}, "would never appear"),
        ({"path": []}, "'moving_obstacles[0].path'"),
        ({"colour": "red"}, "unknown key"),
    ):
        d = json.loads(json.dumps(data))
        d["moving_obstacles"][0].update(patch)
        with pytest.raises(ConfigError, match=re.escape(message)):
            parse_scenario(d, source="s.yaml")


def _check_run(result, out: Path) -> dict:
    sc = result.scenario
    run = result.runs[0]
    ep = result.episodes[0]
    p = ep.position_state
    # Clearance from every moving obstacle at its true position, tick by tick.
    for ob in sc.moving_obstacles:
        live = ob.present(ep.time)
        gap = np.linalg.norm(p[live, :2] - ob.position(ep.time[live]), axis=1) - ob.radius
        assert np.all(gap >= sc.footprint_radius), float(np.min(gap))
    assert run.reached_goal and not run.contact
    assert run.final_error_m < 0.01
    assert run.replans == len(ep.replans) >= 2
    assert 0.0 < run.replan_ms_median <= run.replan_ms_max
    write_outputs(result, out, animation=False)
    with open(out / "events.csv") as fh:
        rows = list(csv.DictReader(fh))
    replans = [r for r in rows if r["reason"].startswith("replan:")]
    assert len(replans) == run.replans and all(float(r["latency_ms"]) > 0 for r in replans)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["runs"][0]["replans"] == run.replans
    return summary


def _starts_clear_of_known_obstacles(result) -> int:
    """Every policy the controller started was clear of every obstacle it knew: its D'
    over its whole duration (every tick, brute force) stays beyond the footprint plus
    the obstacle's radius from the obstacle's motion over that duration (its true
    position and velocity at the switch; zero margin). Returns the switches checked."""
    sc, ep = result.scenario, result.episodes[0]
    lib = result.library
    sensing = ObstacleSensing(range=sc.sensing_range)
    checked = 0
    for e in ep.events:
        if e.to_policy < 0:
            continue
        xy = ep.position_state[e.tick, :2]
        for ob in sense(sc.moving_obstacles, xy, e.time, sensing):
            d = _brute_distance(lib, e.to_policy, ob, 0.0)
            assert d >= ob.radius + sc.footprint_radius, (e, d)
            checked += 1
    return checked


def test_person_crossing_a_corridor(tmp_path: Path) -> None:
    result = run_scenario(load_scenario(SCENARIOS / "corridor_person.yaml"))
    _check_run(result, tmp_path)
    assert _starts_clear_of_known_obstacles(result) >= 2
    reasons = {r.reason for r in result.episodes[0].replans}
    assert {"obstacle_sensed", "obstacle_moved"} <= reasons


def test_cart_in_a_doorway_for_5_s(tmp_path: Path) -> None:
    result = run_scenario(load_scenario(SCENARIOS / "doorway_cart.yaml"))
    _check_run(result, tmp_path)
    _starts_clear_of_known_obstacles(result)  # asserts each start it finds
    ep, run = result.episodes[0], result.runs[0]
    p = ep.position_state
    # The robot waits while the cart is there (3-8 s) and goes through afterwards.
    cart = (ep.time >= 3.0) & (ep.time < 8.0)
    assert np.all(p[cart, 0] < 5.0 - 0.35 - 0.2)
    assert run.blocked_s >= 1.0
    assert {r.reason for r in ep.replans} >= {"obstacle_sensed", "obstacle_cleared"}


def test_a_cart_that_never_leaves_blocks_the_task() -> None:
    data = yaml.safe_load((SCENARIOS / "doorway_cart.yaml").read_text())
    del data["moving_obstacles"][0]["leave"]
    data["simulation"]["max_time"] = 15.0
    result = run_scenario(parse_scenario(data, source="s.yaml"))
    run = result.runs[0]
    assert run.outcome == "blocked" and not run.contact and not run.reached_goal
    assert run.blocked_s > 5.0
