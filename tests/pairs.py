"""Trials of ``examples/campaigns/random_pairs.yaml`` for the tests of one mechanism."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

from gracenav.campaign import Campaign, load_campaign
from gracenav.campaign.runner import trial_result

PAIRS = Path(__file__).resolve().parent.parent / "examples" / "campaigns" / "random_pairs.yaml"


def pairs_campaign(*, online_starts: bool) -> Campaign:
    """The campaign with ``planner.online_starts`` set: the tests of captures, holds
    and set-aside policies turn it off, since a start designed online takes the place
    of the captures they look at."""
    campaign = load_campaign(PAIRS)
    doc = dict(campaign.scenario)
    doc["planner"] = {**(doc.get("planner") or {}), "online_starts": online_starts}
    return dataclasses.replace(campaign, scenario=doc)


def pairs_trial(index: int, *, online_starts: bool) -> tuple[dict[str, Any], Any]:
    """gracenav's result row and run of trial ``index`` (:func:`trial_result`)."""
    return trial_result(pairs_campaign(online_starts=online_starts), index, "gracenav")
