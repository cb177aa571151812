"""Figure of a motion primitive set: ball paths in the plane (paper Fig. 3(a))."""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

import numpy as np

from gracenav.primitives import Maneuver, MotionPrimitive, PrimitiveSet

__all__ = ["plot_primitives"]

# Colour per family of maneuver, keyed by (start is rest, end is rest).
_FAMILY_COLOURS = {
    "rest to rest": "#1f77b4",
    "start": "#2ca02c",
    "stop": "#d62728",
    "cruise to cruise": "#9467bd",
    "trim": "#7f7f7f",
}


def _family(p: MotionPrimitive) -> str:
    if not isinstance(p, Maneuver):
        return "trim"
    if p.start_trim == "rest" and p.end_trim == "rest":
        return "rest to rest"
    if p.start_trim == "rest":
        return "start"
    if p.end_trim == "rest":
        return "stop"
    return "cruise to cruise"


def plot_primitives(
    primitives: PrimitiveSet | Iterable[MotionPrimitive],
    path: str | Path,
    *,
    d: float | None = None,
    samples_per_second: float = 64.0,
    title: str = "Motion primitive set",
) -> Path:
    """Save a PNG of the XY ball paths of a primitive set, one line per primitive.

    Every primitive is drawn in its own frame (starting at the origin), on a
    grid at multiples of the distance parameter d, as in the paper's Fig. 3(a).
    Trim primitives are drawn over their nominal duration (the rest trim is the
    dot at the origin).

    Parameters
    ----------
    primitives : PrimitiveSet or iterable of MotionPrimitive
        The primitives to draw.
    path : str or Path
        Output PNG file; parent folders are created.
    d : float, optional
        Grid spacing (m); default the set's d, or 0.5 m.
    samples_per_second : float
        Sampling rate of the drawn paths (1/s).
    title : str
        Figure title.

    Returns
    -------
    Path
        The written file.
    """
    from gracenav.plotting._figure import agg_figure

    prims = list(primitives)
    if d is None:
        d = primitives.d if isinstance(primitives, PrimitiveSet) else 0.5
    fig = agg_figure(figsize=(7, 7), constrained_layout=True)
    ax = fig.subplots()
    extent = np.zeros(2)
    low = np.zeros(2)
    seen: set[str] = set()
    for p in prims:
        n = max(2, round(p.duration * samples_per_second) + 1)
        xy = p.sample(np.linspace(0.0, p.duration, n)).position[:, :2]
        extent = np.maximum(extent, xy.max(axis=0))
        low = np.minimum(low, xy.min(axis=0))
        fam = _family(p)
        label = fam if fam not in seen else None
        seen.add(fam)
        colour = _FAMILY_COLOURS[fam]
        if p.is_trim and not np.any(p.end_velocity):
            ax.plot([0.0], [0.0], "o", color=colour, ms=6, label=label, zorder=3)
            continue
        ax.plot(xy[:, 0], xy[:, 1], "-", color=colour, lw=1.3, alpha=0.85, label=label)
        ax.plot(xy[-1, 0], xy[-1, 1], ".", color=colour, ms=5)
    hi = extent + 0.2 * d
    lo = low - 0.2 * d
    ax.set_xticks(np.arange(np.ceil(lo[0] / d), np.floor(hi[0] / d) + 1) * d)
    ax.set_yticks(np.arange(np.ceil(lo[1] / d), np.floor(hi[1] / d) + 1) * d)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    ax.grid(True, alpha=0.4)
    ax.set_xlabel("X (m)")
    ax.set_ylabel("Y (m)")
    ax.set_title(f"{title} (d = {d:g} m, {len(prims)} primitives)")
    ax.legend(loc="upper left", fontsize=8)
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=120)
    return out
