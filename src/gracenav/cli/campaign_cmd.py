"""``gracenav campaign``: many trials of one scenario with drawn inputs."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from gracenav.cli._common import add_params_argument, load_params

__all__ = ["register"]


def register(sub: Any) -> None:
    """Add the ``campaign`` command."""
    c = sub.add_parser(
        "campaign",
        help="run a campaign (YAML): many trials of a scenario with drawn pushes, noise, plants",
        description=(
            "Run every trial of a campaign on a local process pool and write DIR/trials.jsonl "
            "(one line per finished trial: re-running the same command resumes), "
            "DIR/results.csv, DIR/results.parquet (with pyarrow), DIR/summary.json (success "
            "rates with Wilson 95 %% intervals per planner and impulse bin) and DIR/table.md."
        ),
    )
    c.add_argument("campaign", type=Path, help="campaign YAML file")
    c.add_argument("--out", type=Path, required=True, help="output directory")
    c.add_argument(
        "--processes",
        type=int,
        default=None,
        help="worker processes (default: the number of cores)",
    )
    add_params_argument(c)
    c.set_defaults(func=run_campaign_cmd)


def run_campaign_cmd(args: argparse.Namespace) -> int:
    """Run ``gracenav campaign``."""
    from gracenav._progress import Progress
    from gracenav.campaign import load_campaign, run_campaign
    from gracenav.campaign.results import write_results
    from gracenav.errors import ConfigError

    if args.processes is not None and not 1 <= args.processes <= 256:
        raise ConfigError(f"--processes must be an integer in [1, 256], got {args.processes}")
    campaign = load_campaign(args.campaign)
    params = load_params(args)
    total = campaign.trials * len(campaign.planners)
    with Progress(total, f"{campaign.name}: trials") as bar:
        last = [0]

        def progress(done: int, n: int) -> None:
            bar.update(done - last[0])
            last[0] = done

        rows = run_campaign(
            campaign, args.out, processes=args.processes, params=params, progress=progress
        )
    written = write_results(rows, args.out)
    print(f"wrote {', '.join(str(p) for p in written)}")
    return 0
