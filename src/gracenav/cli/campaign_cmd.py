"""``gracenav campaign``: seeded Monte Carlo studies over a scenario."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from gracenav.cli._common import add_params_argument, load_params

__all__ = ["register"]


def register(sub: Any) -> None:
    """Add the ``campaign`` command."""
    c = sub.add_parser(
        "campaign",
        help="run a seeded Monte Carlo campaign over a scenario (resumable)",
        description=(
            "Run the trials of a campaign file (YAML): a base scenario and what to draw "
            "for each trial (a push's impulse in N s, direction and time; the position "
            "noise; plant parameter factors). Trial i draws from its own generator seeded "
            "by (seed, i), so a re-run reproduces every trial and trials do not depend on "
            "the number of processes. Each finished trial is appended to DIR/trials.jsonl; "
            "running the same campaign into the same DIR again resumes it. At the end "
            "DIR/results.csv (one row per trial) and DIR/summary.json (success rates with "
            "Wilson 95 %% intervals, overall and per 4 N s impulse bin) are written. The "
            "format is described in README.md."
        ),
    )
    c.add_argument("campaign", type=Path, help="campaign YAML file")
    c.add_argument("--out", type=Path, required=True, help="campaign directory")
    c.add_argument(
        "--processes",
        type=int,
        default=None,
        help="worker processes (default: the machine's cores; 1 runs in this process)",
    )
    add_params_argument(c)
    c.set_defaults(func=run_campaign_cmd)


def run_campaign_cmd(args: argparse.Namespace) -> int:
    """Run ``gracenav campaign``."""
    from gracenav._progress import Progress
    from gracenav.campaign import load_campaign, run_campaign
    from gracenav.errors import ConfigError

    if args.processes is not None and not 1 <= args.processes <= 256:
        raise ConfigError(f"--processes must be an integer in [1, 256], got {args.processes}")
    spec = load_campaign(args.campaign)
    params = load_params(args)
    with Progress(spec.trials, f"campaign {spec.name}") as bar:

        def progress(done: int, total: int) -> None:
            bar.update(done - bar.count)

        records = run_campaign(
            spec, args.out, processes=args.processes, params=params, progress=progress
        )
    ok = sum(1 for r in records if r["reached_goal"])
    print(
        f"{spec.name}: {ok} of {len(records)} trials reached the goal; wrote "
        f"{args.out / 'results.csv'}, {args.out / 'summary.json'}",
        file=sys.stdout,
    )
    return 0
