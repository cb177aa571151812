"""A library policy the robot keeps leaving is set aside for the rest of the way
(:attr:`gracenav.execution.ExecutionOptions.set_aside_exits`)."""

from __future__ import annotations

import pytest
from pairs import pairs_trial

from gracenav import ConfigError
from gracenav.execution import EventReason, ExecutionOptions
from gracenav.execution.supervisor import Supervisor


def _trial_147():  # type: ignore[no-untyped-def]
    # On the raw measurement: the position filter keeps this trial in the fine copy's
    # domains (tests/test_estimation.py).
    # On the nonic palette, whose way out of this start is the fine copy.
    return pairs_trial(147, online_starts=False, position_filter=False, palette="nonic")


@pytest.mark.slow
def test_a_policy_left_twice_is_set_aside_and_the_task_goes_on(monkeypatch) -> None:
    """Trial 147 of random_pairs.yaml (position noise 5 mm, the nonic palette): the only
    way out of the start is a fine copy (a quarter of the domains) that the noisy state
    leaves within 1.2-1.7 s. Started again after every capture, it kept the robot there
    until the task timed out. Set aside after its second exit, the tree is repaired
    without it, the robot is caught onto another way, never starts it again, and reaches
    the goal without balancing mode."""
    row, res = _trial_147()
    ep = res.episodes[0]
    assert row["reached_goal"] and row["balancing_s"] == 0.0
    left = [r for r in ep.replans if r.reason == "policy_left"]
    assert len(left) == 1 and left[0].blocked == 1 and left[0].changed > 0
    # A domain exit switches to a capture (or a verified policy) from a library row.
    exits = [
        e
        for e in ep.events
        if e.from_policy >= 0 and e.reason in (EventReason.CAPTURE, EventReason.DOMAIN_EXIT)
    ]
    aside = exits[1].from_policy
    assert exits[0].from_policy == aside and aside >= 0
    assert exits[1].time == pytest.approx(left[0].time)
    assert all(e.to_policy != aside for e in ep.events if e.time > left[0].time)
    # Without setting it aside, the same trial times out where it started.
    monkeypatch.setattr(Supervisor, "_set_aside", lambda self, row: None)
    again, res = _trial_147()
    assert not again["reached_goal"] and again["outcome"] == "timeout"
    assert not [r for r in res.episodes[0].replans if r.reason == "policy_left"]


@pytest.mark.parametrize("bad", [-1, True, 1.5])
def test_set_aside_exits_must_be_a_count(bad) -> None:
    with pytest.raises(ConfigError, match="set_aside_exits"):
        ExecutionOptions(set_aside_exits=bad)


def test_policies_are_set_aside_after_two_exits_by_default() -> None:
    assert ExecutionOptions().set_aside_exits == 2
