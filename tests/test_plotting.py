"""Figures leave matplotlib's global state alone: no backend switch, no pyplot figures."""

from __future__ import annotations

from pathlib import Path

import matplotlib
import numpy as np
from PIL import Image

from gracenav.campaign.results import plot_results
from gracenav.palette import load_palette
from gracenav.plotting.domains import plot_domain
from gracenav.plotting.timeseries import plot_balance


def test_plotting_keeps_the_backend_and_makes_no_pyplot_figures(tmp_path: Path) -> None:
    import matplotlib.pyplot as plt  # only here: the package itself never imports pyplot

    before = matplotlib.get_backend()
    matplotlib.use("pdf")  # a user's backend that is not Agg
    try:
        t = np.linspace(0.0, 1.0, 20)
        plot_balance(t, np.zeros((20, 2)), np.zeros((20, 2)), tmp_path / "balance.png")
        plot_domain(load_palette()["rest_to_cruise_x_2_0"], tmp_path / "domain.png")
        rows = [
            {"planner": "gracenav", "time_s": 5.0, "max_lean_deg": 2.0, "reached_goal": True},
            {"planner": "gracenav", "time_s": 6.0, "max_lean_deg": 3.0, "reached_goal": True},
        ]
        plot_results(rows, {"planners": {"gracenav": {}}}, tmp_path)
        assert matplotlib.get_backend() == "pdf"
        assert plt.get_fignums() == []
    finally:
        matplotlib.use(before)
    with Image.open(tmp_path / "balance.png") as im:
        assert im.size == (840, 600)  # 7 × 5 in at 120 dpi
    with Image.open(tmp_path / "domain.png") as im:
        assert im.size == (660, 660)
    with Image.open(tmp_path / "lean.png") as im:
        assert im.size == (600, 420)
