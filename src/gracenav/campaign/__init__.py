"""Campaigns: many trials of one base scenario with drawn pushes, noise and plant factors.

A campaign file names a base scenario and the distributions of what varies between
trials. Every trial's inputs are drawn from its own seed, spawned from the campaign
seed by :class:`numpy.random.SeedSequence` (trial ``i`` uses child ``i``), so a trial
does not depend on the number of workers or on which trials already ran.
"""

from __future__ import annotations

from gracenav.campaign.results import wilson_interval
from gracenav.campaign.runner import run_campaign
from gracenav.campaign.spec import Campaign, load_campaign, parse_campaign

__all__ = ["Campaign", "load_campaign", "parse_campaign", "run_campaign", "wilson_interval"]
