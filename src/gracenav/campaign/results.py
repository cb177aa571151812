"""Campaign results: tables, Wilson intervals, summary and figures."""

from __future__ import annotations

import csv
import json
import math
import statistics
from pathlib import Path
from typing import Any

__all__ = ["plot_results", "summarise", "wilson_interval", "write_results"]


def wilson_interval(successes: int, n: int, z: float = 1.959963984540054) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion (default 95 %: ``z`` is the normal
    quantile), by :meth:`scipy.stats.binomtest` ``.proportion_ci(method="wilson")``.

    Returns (nan, nan) for ``n == 0``; the bounds are exactly 0 (no success) and 1 (no
    failure) at the ends.
    """
    if n <= 0:
        return (math.nan, math.nan)
    from scipy import stats

    level = 2.0 * float(stats.norm.cdf(z)) - 1.0
    ci = stats.binomtest(int(successes), int(n)).proportion_ci(
        confidence_level=level, method="wilson"
    )
    lo = 0.0 if successes == 0 else max(0.0, float(ci.low))
    hi = 1.0 if successes == n else min(1.0, float(ci.high))
    return (lo, hi)


def _rate(rows: list[dict[str, Any]]) -> dict[str, Any]:
    n = len(rows)
    k = sum(1 for r in rows if r["reached_goal"])
    lo, hi = wilson_interval(k, n)
    return {"n": n, "successes": k, "rate": k / n if n else None, "ci95": [lo, hi] if n else None}


def _fmt(v: float | None, digits: int = 1) -> str:
    return "–" if v is None else f"{v:.{digits}f}"


def _median(values: list[float]) -> float | None:
    """:func:`statistics.median` (the mean of the middle two for an even count); None
    if empty."""
    return statistics.median(values) if values else None


def _values(rows: list[dict[str, Any]], key: str) -> list[float]:
    return [float(r[key]) for r in rows if r.get(key) is not None]


def summarise(rows: list[dict[str, Any]], *, bins: int = 5) -> dict[str, Any]:
    """Success rates with Wilson 95 % intervals per planner and per impulse bin, the
    count of each outcome, and medians of the measures (time to goal over the trials
    that reached it)."""
    out: dict[str, Any] = {"trials": len(rows), "planners": {}}
    order = list(dict.fromkeys(r["planner"] for r in rows))
    for planner in order:
        rs = [r for r in rows if r["planner"] == planner]
        entry = _rate(rs)
        outcomes: dict[str, int] = {}
        for r in rs:
            outcomes[str(r.get("outcome"))] = outcomes.get(str(r.get("outcome")), 0) + 1
        entry["outcomes"] = dict(sorted(outcomes.items()))
        entry["median_time_s"] = _median(_values([r for r in rs if r["reached_goal"]], "time_s"))
        lean = _values(rs, "max_lean_deg")
        entry["median_max_lean_deg"] = _median(lean)
        entry["max_lean_deg"] = max(lean) if lean else None
        entry["median_max_jerk_mps3"] = _median(_values(rs, "max_jerk_mps3"))
        entry["median_p95_jerk_mps3"] = _median(_values(rs, "p95_jerk_mps3"))
        entry["fallback_trials"] = sum(1 for r in rs if (r.get("fallbacks") or 0) > 0)
        entry["worker_losses"] = sum(int(r.get("worker_losses") or 0) for r in rs)
        imp = [r["impulse_ns"] for r in rs if r.get("impulse_ns") is not None]
        if imp:
            lo, hi = min(imp), max(imp)
            width = (hi - lo) / bins or 1.0
            entry["impulse_bins"] = []
            for b in range(bins):
                a, z = lo + b * width, lo + (b + 1) * width
                sel = [
                    r
                    for r in rs
                    if r.get("impulse_ns") is not None
                    and (a <= r["impulse_ns"] < z or (b == bins - 1 and r["impulse_ns"] == z))
                ]
                entry["impulse_bins"].append({"low_ns": a, "high_ns": z, **_rate(sel)})
        out["planners"][planner] = entry
    return out


def write_results(rows: list[dict[str, Any]], directory: Path) -> list[Path]:
    """Write results.csv (and results.parquet if pyarrow is there), summary.json, table.md."""
    import sys

    written = []
    cols: list[str] = []
    for r in rows:
        cols += [k for k in r if k not in cols]
    with open(directory / "results.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=cols)
        w.writeheader()
        for r in rows:
            w.writerow({k: r.get(k) for k in cols})
    written.append(directory / "results.csv")
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        print(
            "gracenav campaign: pyarrow not installed, results.parquet skipped "
            "(pip install 'gracenav[campaign]')",
            file=sys.stderr,
        )
    else:
        table = pa.table({k: [r.get(k) for r in rows] for k in cols})
        pq.write_table(table, directory / "results.parquet")
        written.append(directory / "results.parquet")
    summary = summarise(rows)
    (directory / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    written.append(directory / "summary.json")
    lines = [
        "| planner | trials | success | 95 % CI | median time to goal (s) | "
        "max lean (°) median / max | max jerk (m/s³) median | p95 jerk (m/s³) median | "
        "contacts | no plan |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for planner, e in summary["planners"].items():
        ci = e["ci95"]
        lines.append(
            f"| {planner} | {e['n']} | {e['rate']:.1%} | [{ci[0]:.1%}, {ci[1]:.1%}] | "
            f"{_fmt(e['median_time_s'])} | {_fmt(e['median_max_lean_deg'])} / "
            f"{_fmt(e['max_lean_deg'])} | {_fmt(e['median_max_jerk_mps3'], 1)} | "
            f"{_fmt(e['median_p95_jerk_mps3'], 1)} | "
            f"{e['outcomes'].get('contact', 0)} | {e['outcomes'].get('no_plan', 0)} |"
        )
    lines += _bin_table(summary)
    (directory / "table.md").write_text("\n".join(lines) + "\n")
    written.append(directory / "table.md")
    written += plot_results(rows, summary, directory)
    return written


def _bin_table(summary: dict[str, Any]) -> list[str]:
    """Success per impulse bin, one column per planner (empty without pushes)."""
    planners = [p for p, e in summary["planners"].items() if "impulse_bins" in e]
    if not planners:
        return []
    head = "| push impulse (N s) | " + " | ".join(planners) + " |"
    lines = ["", head, "|---|" + "---|" * len(planners)]
    bins = summary["planners"][planners[0]]["impulse_bins"]
    for k, b in enumerate(bins):
        cells = []
        for p in planners:
            e = summary["planners"][p]["impulse_bins"][k]
            if e["n"]:
                lo, hi = e["ci95"]
                cells.append(f"{e['successes']}/{e['n']} [{lo:.0%}, {hi:.0%}]")
            else:
                cells.append("–")
        lines.append(f"| {b['low_ns']:.1f}–{b['high_ns']:.1f} | " + " | ".join(cells) + " |")
    return lines


def plot_results(
    rows: list[dict[str, Any]], summary: dict[str, Any], directory: Path
) -> list[Path]:
    """Write success_vs_impulse.png (if pushed), time_to_goal.png and lean.png (the
    planners' histograms on the same bins)."""
    import numpy as np

    from gracenav.plotting._figure import agg_figure

    written = []
    planners = list(summary["planners"])
    if any("impulse_bins" in e for e in summary["planners"].values()):
        fig = agg_figure(figsize=(5, 3.5))
        ax = fig.subplots()
        for planner in planners:
            bins = [b for b in summary["planners"][planner].get("impulse_bins", []) if b["n"]]
            x = [(b["low_ns"] + b["high_ns"]) / 2 for b in bins]
            y = [b["rate"] for b in bins]
            err = [
                [max(0.0, b["rate"] - b["ci95"][0]) for b in bins],
                [max(0.0, b["ci95"][1] - b["rate"]) for b in bins],
            ]
            ax.errorbar(x, y, yerr=err, marker="o", capsize=3, label=planner)
        ax.set_xlabel("push impulse (N s)")
        ax.set_ylabel("success rate (Wilson 95 %)")
        ax.set_ylim(-0.05, 1.05)
        ax.legend()
        fig.tight_layout()
        fig.savefig(directory / "success_vs_impulse.png", dpi=120)
        written.append(directory / "success_vs_impulse.png")
    for key, name, label in (
        ("time_s", "time_to_goal.png", "time to goal (s)"),
        ("max_lean_deg", "lean.png", "max lean (°)"),
    ):
        fig = agg_figure(figsize=(5, 3.5))
        ax = fig.subplots()
        by_planner = {
            planner: [
                r[key]
                for r in rows
                if r["planner"] == planner
                and r.get(key) is not None
                and (key != "time_s" or r["reached_goal"])
            ]
            for planner in planners
        }
        every = [v for vals in by_planner.values() for v in vals]
        if every:
            # One set of bins for every planner, so their counts compare bar by bar.
            edges = np.histogram_bin_edges(every, bins=20).tolist()
            for planner, vals in by_planner.items():
                if vals:
                    ax.hist(vals, bins=edges, alpha=0.5, label=planner)
        ax.set_xlabel(label)
        ax.set_ylabel("trials")
        ax.legend()
        fig.tight_layout()
        fig.savefig(directory / name, dpi=120)
        written.append(directory / name)
    return written
