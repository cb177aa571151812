"""Trials of ``examples/campaigns/random_pairs.yaml`` for the tests of one mechanism."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

from gracenav.campaign import Campaign, load_campaign
from gracenav.campaign.runner import trial_result

PAIRS = Path(__file__).resolve().parent.parent / "examples" / "campaigns" / "random_pairs.yaml"


def pairs_campaign(
    *, online_starts: bool, online_ends: bool = True, position_filter: bool = True
) -> Campaign:
    """The campaign with ``planner.online_starts``, ``planner.online_ends`` and
    ``simulation.position_filter`` set: the tests of captures, holds and set-aside
    policies turn online starts off, since a start designed online takes the place of
    the captures they look at; those of domain exits under sensor noise turn the
    position filter off."""
    campaign = load_campaign(PAIRS)
    doc = dict(campaign.scenario)
    doc["planner"] = {
        **(doc.get("planner") or {}),
        "online_starts": online_starts,
        "online_ends": online_ends,
    }
    doc["simulation"] = {**(doc.get("simulation") or {}), "position_filter": position_filter}
    return dataclasses.replace(campaign, scenario=doc)


def pairs_trial(
    index: int,
    *,
    online_starts: bool,
    online_ends: bool = True,
    position_filter: bool = True,
    palette: str | None = None,
) -> tuple[dict[str, Any], Any]:
    """gracenav's result row and run of trial ``index`` (:func:`trial_result`), on the
    shipped palette named ``palette`` (default: the default palette)."""
    from gracenav.palette import load_palette

    campaign = pairs_campaign(
        online_starts=online_starts, online_ends=online_ends, position_filter=position_filter
    )
    pal = load_palette(palette) if palette is not None else None
    return trial_result(campaign, index, "gracenav", palette=pal)


def launch_without_fine_copies(monkeypatch: Any) -> None:
    """Starts designed online launch onto no fine copy (``LaunchOptions(fine=False)``):
    trial 19's start then keeps the capture regulator and its way ends through a
    maneuver designed online, the mechanisms its tests look at (with fine copies it
    launches onto one whose way also ends so, 3.4 s sooner: ``tests/test_launch.py``)."""
    import functools

    import gracenav.execution.controller as controller_module
    from gracenav.execution.launch import LaunchOptions

    monkeypatch.setattr(
        controller_module, "LaunchOptions", functools.partial(LaunchOptions, fine=False)
    )
