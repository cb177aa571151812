"""Starts at rest through one maneuver designed and verified at the start
(``ExecutionOptions.online_starts``, :mod:`gracenav.execution.launch`)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from reverify import assert_holds_from_unchosen_points

from gracenav.campaign import load_campaign
from gracenav.campaign.runner import trial_result
from gracenav.execution import CAPTURE, EventReason, ExecutionOptions
from gracenav.policies import PrimitiveKind

ROOT = Path(__file__).resolve().parent.parent
PAIRS = ROOT / "examples" / "campaigns" / "random_pairs.yaml"


def _campaign(online: bool):  # type: ignore[no-untyped-def]
    campaign = load_campaign(PAIRS)
    doc = dict(campaign.scenario)
    doc["planner"] = {**(doc.get("planner") or {}), "online_starts": online}
    return dataclasses.replace(campaign, scenario=doc)


def test_online_starts_are_off_by_default() -> None:
    assert ExecutionOptions().online_starts is False


@pytest.mark.slow
def test_a_start_takes_one_verified_maneuver_onto_a_cruise_trim() -> None:
    """Trial 5 of the random pairs (at rest 0.35 m from the room's obstacles): a shift and
    a maneuver from rest without the option, one maneuver from the start onto a library
    cruise trim with it; every containment of the switch holds exactly, the maneuver
    holds again from points its verification did not choose, and the task ends sooner
    without touching anything."""
    row0, _ = trial_result(_campaign(False), 5, "gracenav")
    row, result = trial_result(_campaign(True), 5, "gracenav")
    assert row0["reached_goal"] and row["reached_goal"]
    assert row["min_clearance_m"] >= 0.0 and row["balancing_s"] == 0.0
    assert row["time_s"] <= row0["time_s"] - 1.0
    ep, lib = result.episodes[0], result.library
    assert ep.events[0].to_policy == CAPTURE
    (t0, plan), *_ = ep.captures
    assert t0 == 0.0 and plan.shifts == ()
    launch = plan.catch
    assert launch.policy.name == "launch"
    start = np.array([row["start_x"], row["start_y"], 0.0, 0.0])
    assert launch.start_domain.contains(start)
    trim = lib.policy(plan.rest_row)
    assert trim.policy.primitive.kind is PrimitiveKind.CRUISE
    assert trim.start_domain.contains_domain(launch.goal_domain)
    switch = ep.events[1]
    assert switch.reason is EventReason.GRACEFUL and switch.to_policy == plan.rest_row
    assert switch.time == pytest.approx(launch.duration, abs=1.5 / 1024)
    assert launch.policy.starts_from_still_band
    assert_holds_from_unchosen_points(
        launch.policy, lib.palette.options, boundary_points=24, interior=6, seed=5
    )
