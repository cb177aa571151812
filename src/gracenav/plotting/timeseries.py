"""Time-series figures: ball position and body lean against time."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["plot_balance"]


def plot_balance(
    time: ArrayLike,
    position: ArrayLike,
    lean: ArrayLike,
    path: str | Path,
    *,
    title: str = "Balancing",
) -> Path:
    """Save a PNG with ball position (top) and body lean in degrees (bottom) against time.

    Parameters
    ----------
    time : array_like, shape (N,)
        Time (s).
    position : array_like, shape (N, 2)
        Ball position x, y (m).
    lean : array_like, shape (N, 2)
        Body lean φ_x, φ_y (rad); plotted in degrees.
    path : str or Path
        Output PNG file.
    title : str
        Figure title.

    Returns
    -------
    Path
        The written file.
    """
    from gracenav.plotting._figure import agg_figure

    t = np.asarray(time, dtype=float)
    pos = np.asarray(position, dtype=float)
    phi = np.rad2deg(np.asarray(lean, dtype=float))
    fig = agg_figure(figsize=(7, 5), constrained_layout=True)
    ax1, ax2 = fig.subplots(2, 1, sharex=True)
    ax1.plot(t, pos[:, 0] * 100.0, label="x")
    ax1.plot(t, pos[:, 1] * 100.0, label="y")
    ax1.set_ylabel("ball position (cm)")
    ax1.grid(True, alpha=0.3)
    ax1.legend()
    ax1.set_title(title)
    ax2.plot(t, phi[:, 0], label="lean x")
    ax2.plot(t, phi[:, 1], label="lean y")
    ax2.set_ylabel("body lean (°)")
    ax2.set_xlabel("time (s)")
    ax2.grid(True, alpha=0.3)
    ax2.legend()
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=120)
    return out
