"""The disturbance recovery figure (paper Fig. 7 style): what it draws, and the command."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

import numpy as np
import pytest
import yaml
from PIL import Image

from gracenav.cli import main
from gracenav.params import BallbotParams
from gracenav.plotting.recovery import plot_recovery, recovery_data
from gracenav.policies import flat_position_state
from gracenav.scenarios import parse_scenario, run_scenario

SCENARIOS = Path(str(resources.files("gracenav") / "data" / "scenarios"))
PUSH_TIME = 3.0  # a multiple of the control period 1/1024 s: a tick of the episode
IMPULSE = (0.0, -15.0)  # N s


def _scenario(disturbances: list[dict]) -> dict:  # type: ignore[type-arg]
    data = yaml.safe_load((SCENARIOS / "fig5_point_to_point.yaml").read_text())
    data["task"]["starts"] = [[0.0, 2.0, 0.0, 0.0]]
    data["disturbances"] = disturbances
    return data


@pytest.fixture(scope="module")
def pushed():  # type: ignore[no-untyped-def]
    data = _scenario([{"kind": "push", "time": PUSH_TIME, "impulse": list(IMPULSE)}])
    return run_scenario(parse_scenario(data, source="push.yaml"))


def test_push_arrow_is_drawn_where_the_push_acted(pushed, tmp_path) -> None:  # type: ignore[no-untyped-def]
    out = tmp_path / "recovery.png"
    data = plot_recovery(pushed, out, size=(6.0, 5.0), dpi=100)
    with Image.open(out) as im:
        assert im.format == "PNG" and im.size == (600, 500)
    ep = pushed.episodes[0]
    p = ep.position_state
    tick = int(np.flatnonzero(ep.time == PUSH_TIME)[0])
    (arrow,) = data.arrows
    assert arrow.kind == "push" and arrow.time == PUSH_TIME
    np.testing.assert_allclose(arrow.tail, p[tick, :2], rtol=0.0, atol=1e-12)
    # Length proportional to the impulse: the largest push is 15 % of the 4 m map side.
    assert arrow.magnitude == pytest.approx(15.0, rel=1e-12)
    np.testing.assert_allclose(arrow.vector, 0.6 / 15.0 * np.asarray(IMPULSE), atol=1e-12)
    assert data.impulse_scale == pytest.approx(0.04, rel=1e-12)
    assert arrow.label == "push 15 N s"
    np.testing.assert_allclose(data.path, p[:, :2], rtol=0.0, atol=0.0)


def test_switch_markers_and_domains_are_the_episodes(pushed) -> None:  # type: ignore[no-untyped-def]
    data = recovery_data(pushed)
    ep = pushed.episodes[0]
    p = ep.position_state
    events = [e for e in ep.events if e.reason.value != "start"]
    assert len(data.switches) == len(events) == ep.switches
    for marker, e in zip(data.switches, events, strict=True):
        assert marker.time == e.time and marker.reason == e.reason.value
        assert marker.graceful == e.reason.graceful
        np.testing.assert_allclose(marker.xy, p[e.tick, :2], rtol=0.0, atol=0.0)
    # The push forces a switch at the tick it acts (the state leaves D'(t)).
    assert any(not m.graceful and abs(m.time - PUSH_TIME) < 0.01 for m in data.switches)
    t0, t1 = data.window
    assert t0 == PUSH_TIME and PUSH_TIME < t1 <= ep.time[-1]
    tick = int(np.flatnonzero(ep.time == PUSH_TIME)[0])
    assert data.policies[0] == int(ep.policy[tick])  # the policy the push interrupted
    lib = pushed.library
    for pid, outline in zip(data.policies, data.start_domains, strict=True):
        s = lib.policy(pid).start_domain
        d = outline - np.asarray(s.center)[:2]
        # Each outline point is on the boundary of S's XY projection: dᵀ Q d = 1.
        np.testing.assert_allclose(
            np.einsum("ni,ij,nj->n", d, s.xy_projection(), d), 1.0, rtol=1e-9
        )
    assert data.exits and all(t0 <= x.time <= t1 for x in data.exits)


def test_a_push_after_the_run_ended_is_refused() -> None:
    data = _scenario([{"kind": "push", "time": 50.0, "impulse": [5.0, 0.0]}])
    res = run_scenario(parse_scenario(data, source="late.yaml"))
    assert res.episodes[0].time[-1] < 50.0
    with pytest.raises(ValueError, match="no push or drag acted during run 0"):
        recovery_data(res)


def test_plot_recovery_command_on_the_fig7_drag(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    out = tmp_path / "fig7.png"
    assert main(["plot", "recovery", str(SCENARIOS / "fig7_drag.yaml"), "--out", str(out)]) == 0
    assert capsys.readouterr().out.startswith("run 1: goal_reached")
    with Image.open(out) as im:
        assert im.size == (780, 780)  # 6.5 in × 120 dpi


def test_plot_recovery_command_errors(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    fig5 = SCENARIOS / "fig5_point_to_point.yaml"
    out = tmp_path / "f.png"
    assert main(["plot", "recovery", str(fig5), "--out", str(out)]) == 2
    assert capsys.readouterr().err == (
        f"gracenav: error: {fig5}: the scenario has no disturbances; a recovery figure "
        "needs a push or a drag under 'disturbances'\n"
    )
    fig7 = SCENARIOS / "fig7_drag.yaml"
    assert main(["plot", "recovery", str(fig7), "--run", "2", "--out", str(out)]) == 2
    assert capsys.readouterr().err == (
        f"gracenav: error: --run 2: {fig7} has 1 start(s); use --run 1\n"
    )
    assert not out.exists()


def test_catches_placed_at_the_state_are_drawn_with_their_domains(pushed) -> None:  # type: ignore[no-untyped-def]
    """The 15 N s push leaves every library S; a catch placed at the state takes over
    (verified S containing the state), and the figure draws its S and D'(t)."""
    ep = pushed.episodes[0]
    assert ep.captures and ep.reached_goal
    when, plan = ep.captures[0]
    tick = next(e.tick for e in ep.events if e.reason.value == "capture")
    assert ep.time[tick] == pytest.approx(when, abs=1e-12)
    # In the controller's coordinates (nominal radius: the plant's here) the state at
    # the capture lies in the catch's S, and the catch's G in the shift's S if any.
    # A pushed catch's S holds the flat output's position state (ball plus L times the
    # lean); the others the ball's.
    state = ep.position_state[tick]
    if plan.catch.policy.flat_start:
        lean, rate = ep.states[tick, 2:4], ep.states[tick, 6:8]
        state = flat_position_state(state, lean, rate, BallbotParams())
    assert plan.catch.start_domain.contains(state)
    data = recovery_data(pushed)
    assert data.window[0] <= when <= data.window[1]
    assert len(data.catch_start_domains) == len(plan.policies)
    for placed, outline in zip(plan.policies, data.catch_start_domains, strict=True):
        s = placed.start_domain
        d = outline - np.asarray(s.center)[:2]
        np.testing.assert_allclose(
            np.einsum("ni,ij,nj->n", d, s.xy_projection(), d), 1.0, rtol=1e-9
        )
    # D'(t) every 0.25 s and at the end of each placed policy.
    expected = sum(
        len({*range(0, p.primitive.num_ticks + 1, 256), p.primitive.num_ticks})
        for p in plan.policies
    )
    assert len(data.catch_outer_domains) == expected
    # The swept D' the figure draws stays clear of the obstacles by the footprint.
    pts = np.concatenate(data.catch_outer_domains)
    assert np.min(pushed.world_map.clearance(pts)) >= pushed.library.footprint_radius - 1e-9
