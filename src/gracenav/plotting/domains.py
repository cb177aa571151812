"""Paper Fig. 3(b): the XY projection of one motion policy's domains."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from gracenav.policies import MotionPolicy

__all__ = ["plot_domain"]


def _ellipse_xy(shape_xy: np.ndarray, center: np.ndarray, n: int = 121) -> np.ndarray:
    """Points (n, 2) of {u : (u − c)ᵀ Q (u − c) = 1}."""
    ang = np.linspace(0.0, 2.0 * np.pi, n)
    ell = np.linalg.cholesky(np.linalg.inv(shape_xy))
    return center + (ell @ np.vstack([np.cos(ang), np.sin(ang)])).T


def plot_domain(policy: MotionPolicy, path: str | Path, *, samples: int = 60) -> Path:
    """Save a PNG of the XY projections of S, D'(t) over [0, t_f], G and the reference path.

    Parameters
    ----------
    policy : MotionPolicy
    path : str or Path
        Output PNG.
    samples : int
        Number of times at which D'(t) is drawn.

    Returns
    -------
    Path
    """
    from gracenav.plotting._figure import agg_figure

    fig = agg_figure(figsize=(5.5, 5.5), constrained_layout=True)
    ax = fig.subplots()
    for t in np.linspace(0.0, policy.duration, samples):
        d = policy.outer_domain(float(t))
        pts = _ellipse_xy(d.xy_projection(), d.center[:2])
        ax.fill(pts[:, 0], pts[:, 1], color="tab:orange", alpha=0.04, lw=0)
        ax.plot(pts[:, 0], pts[:, 1], color="tab:orange", alpha=0.25, lw=0.5)
    for dom, color, label in (
        (policy.start_domain, "tab:blue", "S = D(0)"),
        (policy.goal_domain, "tab:green", "G = D(t_f)"),
    ):
        pts = _ellipse_xy(dom.xy_projection(), dom.center[:2])
        ax.plot(pts[:, 0], pts[:, 1], color=color, lw=2, label=label)
    pos = policy.primitive.position
    ax.plot(pos[:, 0], pos[:, 1], "k-", lw=1.5, label="reference σ(t)")
    ax.plot([], [], color="tab:orange", label="D'(t)")
    ax.set_aspect("equal")
    ax.set_xlabel("X (m)")
    ax.set_ylabel("Y (m)")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    ax.set_title(f"{policy.name}: XY projection of the policy domain")
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=120)
    return out
