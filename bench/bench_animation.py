"""Speed of the navigation GIF: full redraws against blitting, on one episode.

Runs the paper's Fig. 5 scenario once, then writes the GIF of its first run
``--repeats`` times each way, alternating:

* full redraw: ``FuncAnimation`` + ``PillowWriter``, the whole figure drawn for every
  frame (how :func:`gracenav.plotting.navigation.animate_episode` worked before);
* blitting: ``animate_episode`` as shipped (static background drawn once, moving
  artists per frame, one shared palette, frames stored as changed rectangles).

Prints the medians, their ratio and the sizes of both files. Target: <= 2 s for the
blitting GIF. Timings on a shared machine are noisy: compare within one run.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python bench/bench_animation.py [--repeats 3]
"""

from __future__ import annotations

import argparse
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import statistics
import tempfile
import time
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from gracenav.plotting._figure import agg_figure
from gracenav.plotting.navigation import animate_episode, draw_map, outer_domain_outline
from gracenav.scenarios import load_scenario, run_scenario


def animate_full_redraw(result: Any, run: int, path: str | Path, *, fps: int = 10) -> Path:
    """The GIF drawn in full for every frame (the former ``animate_episode``)."""
    from matplotlib.animation import FuncAnimation, PillowWriter

    ep = result.episodes[run]
    p = ep.position_state
    lib = result.library
    fig = agg_figure(figsize=(5, 5), constrained_layout=True)
    ax = fig.subplots()
    draw_map(ax, result.world_map)
    for g in result.scenario.goals:
        ax.plot(g[0], g[1], "*", color="green", ms=14, mec="k")
    (trail,) = ax.plot([], [], "-", color="tab:blue", lw=1.5)
    (body,) = ax.plot([], [], "-", color="tab:orange", lw=4, solid_capstyle="round")
    (ball,) = ax.plot([], [], "o", color="tab:blue", ms=8)
    (dom,) = ax.plot([], [], "-", color="tab:orange", lw=0.8, alpha=0.7)
    title = ax.set_title("")
    step = max(1, round(1.0 / (fps * (ep.time[1] - ep.time[0]))))
    frames = list(range(0, ep.time.size, step))
    lean_scale = 0.6 / np.deg2rad(5.0)
    ang = np.linspace(0, 2 * np.pi, 50)
    cache: dict[int, Any] = {}

    def update(i: int) -> tuple[Any, ...]:
        trail.set_data(p[: i + 1, 0], p[: i + 1, 1])
        ball.set_data([p[i, 0]], [p[i, 1]])
        tip = p[i, :2] + lean_scale * ep.lean[i]
        body.set_data([p[i, 0], tip[0]], [p[i, 1], tip[1]])
        pid = int(ep.policy[i])
        if pid >= 0:
            name, xs, ys = outer_domain_outline(lib, ep, i, cache, ang)
            dom.set_data(xs, ys)
            title.set_text(f"t = {ep.time[i]:5.1f} s  {name}")
        else:
            dom.set_data([], [])
            title.set_text(f"t = {ep.time[i]:5.1f} s  balancing")
        return trail, body, ball, dom, title

    anim = FuncAnimation(fig, update, frames=frames, blit=False)
    out = Path(path)
    anim.save(str(out), writer=PillowWriter(fps=fps))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3, help="GIFs written each way (median)")
    args = ap.parse_args()
    path = Path(
        str(resources.files("gracenav") / "data" / "scenarios" / "fig5_point_to_point.yaml")
    )
    result = run_scenario(load_scenario(path))
    ep = result.episodes[0]
    times: dict[str, list[float]] = {"full redraw": [], "blitting": []}
    sizes: dict[str, int] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(args.repeats):
            order = [("full redraw", animate_full_redraw), ("blitting", animate_episode)]
            for name, fn in order if k % 2 == 0 else order[::-1]:
                out = Path(tmp) / f"{name.replace(' ', '_')}.gif"
                t0 = time.perf_counter()
                fn(result, 0, out)
                times[name].append(time.perf_counter() - t0)
                sizes[name] = out.stat().st_size
    med = {k: statistics.median(v) for k, v in times.items()}
    print(f"{result.scenario.name}, run 1: {ep.time[-1]:.2f} s simulated, {ep.time.size} ticks")
    print(f"{'method':<12}  {'median (s)':>10}  {'file (kB)':>9}")
    for name in times:
        print(f"{name:<12}  {med[name]:>10.2f}  {sizes[name] / 1e3:>9.0f}")
    print(f"speed-up (full redraw / blitting, medians of {args.repeats}): ", end="")
    print(f"{med['full redraw'] / med['blitting']:.1f}x")
    print("target: blitting GIF <= 2 s")


if __name__ == "__main__":
    main()
