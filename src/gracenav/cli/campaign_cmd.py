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
            "Run every trial of a campaign on a local process pool (or a Dask cluster) and "
            "write DIR/trials.jsonl, one line per finished trial: re-running the same "
            "command resumes, and adding a planner to the file runs only its trials. When "
            "all trials are done, DIR/results/ is written as a unit: results.csv, "
            "results.parquet (with pyarrow), summary.json (success rates with Wilson 95 %% "
            "intervals per planner and impulse bin, outcomes, medians), table.md and PNG "
            "figures. Planners: gracenav (verified policies with the balancing-mode "
            "fallback), gracenav_paper (without it, as in the paper), decoupled (A* path, "
            "smoothed and timed, tracked by the same controllers)."
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
    c.add_argument(
        "--cluster",
        metavar="ADDRESS",
        default=None,
        help=(
            "run the trials on the Dask scheduler at ADDRESS (e.g. tcp://10.0.0.5:8786; "
            "overrides the file's 'cluster'); needs pip install 'gracenav[cluster]'"
        ),
    )
    add_params_argument(c)
    c.set_defaults(func=run_campaign_cmd)


def run_campaign_cmd(args: argparse.Namespace) -> int:
    """Run ``gracenav campaign``."""
    from gracenav._util.io import OutputDir
    from gracenav._util.progress import Progress
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
            campaign,
            args.out,
            processes=args.processes,
            params=params,
            progress=progress,
            cluster=args.cluster,
        )
    with OutputDir(args.out / "results") as results:
        names = [p.name for p in write_results(rows, results.staging)]
    print(f"wrote {args.out / 'results'}: {', '.join(names)}")
    return 0
