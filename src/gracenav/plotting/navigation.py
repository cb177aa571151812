"""Navigation figures: paths with obstacles and domains (paper Figs. 5, 7, 8), body
angles against time (Figs. 6, 9), and an animation of one run."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from gracenav.plotting._figure import agg_figure

if TYPE_CHECKING:
    from matplotlib.backends.backend_agg import FigureCanvasAgg

__all__ = ["animate_episode", "draw_map", "outer_domain_outline", "plot_lean", "plot_paths"]

_GIF_COLOURS = 64  # palette of the animation: white, black, greys and a few line colours


_MAP_PIXELS = 1024
"""Most map cells drawn along a side: a larger grid is drawn in blocks of k × k cells, a
block black when any of its cells is (no obstacle vanishes from the figure)."""


def draw_map(ax: Any, world_map: Any) -> None:
    """Draw the map's bounds and obstacles (black) on ``ax``."""
    (x0, y0), (x1, y1) = world_map.bounds
    grid = np.asarray(world_map.occupied, dtype=bool)
    extent = (x0, x1, y0, y1)
    k = -(-max(grid.shape) // _MAP_PIXELS)
    if k > 1:
        ny, nx = grid.shape
        padded = np.zeros((-(-ny // k) * k, -(-nx // k) * k), dtype=bool)
        padded[:ny, :nx] = grid
        blocks = padded.reshape(padded.shape[0] // k, k, padded.shape[1] // k, k)
        grid = np.asarray(blocks.any(axis=(1, 3)))
        # The padding lies beyond the map (cut off by the limits): the image spans
        # whole blocks.
        side = k * world_map.resolution
        extent = (x0, x0 + grid.shape[1] * side, y0, y0 + grid.shape[0] * side)
    occ = grid.astype(np.float32)
    ax.imshow(
        np.ma.masked_where(occ == 0, occ),
        origin="lower",
        extent=extent,
        cmap="Greys",
        vmin=0.0,
        vmax=1.0,
        interpolation="nearest",
        zorder=1,
    )
    ax.plot([x0, x1, x1, x0, x0], [y0, y0, y1, y1, y0], "k-", lw=1.5)
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal")
    ax.set_xlabel("X (m)")
    ax.set_ylabel("Y (m)")


def _circle(ax: Any, c: Any, r: float, **kw: Any) -> None:
    ang = np.linspace(0, 2 * np.pi, 60)
    ax.plot(c[0] + r * np.cos(ang), c[1] + r * np.sin(ang), **kw)


def plot_paths(result: Any, path: str | Path) -> Path:
    """Reference and simulated paths of every run, the start domains of the executed
    policies, the goal(s), obstacles and domain exits. Saves a PNG."""
    import matplotlib

    fig = agg_figure(figsize=(6.5, 6.5), constrained_layout=True)
    ax = fig.subplots()
    draw_map(ax, result.world_map)
    lib = result.library
    colors = matplotlib.rcParams["axes.prop_cycle"].by_key()["color"]
    for k, ep in enumerate(result.episodes):
        c = colors[k % len(colors)]
        for pid in dict.fromkeys(int(i) for i in ep.policy if i >= 0):
            pol = lib.policy(pid)
            s = pol.start_domain
            rad = float(np.sqrt(np.linalg.inv(s.xy_projection())[0, 0]))
            _circle(ax, s.center, rad, color=c, alpha=0.25, lw=0.8)
        ref = ep.reference
        ax.plot(ref[:, 0], ref[:, 1], "--", color=c, lw=1, alpha=0.8)
        p = ep.position_state
        ax.plot(p[:, 0], p[:, 1], "-", color=c, lw=2, label=f"run {k + 1}")
        ax.plot(p[0, 0], p[0, 1], "o", color=c)
        for d in result.scenario.disturbances:
            t0 = getattr(d, "start_time", getattr(d, "time", 0.0))
            t1 = getattr(d, "end_time", t0 + 0.05)
            sel = (ep.time >= t0) & (ep.time <= t1)
            ax.plot(p[sel, 0], p[sel, 1], "-", color="red", lw=3.5, alpha=0.5, zorder=4)
        for ob in getattr(ep, "moving_obstacles", ()):
            # Where each moving obstacle went while present, and its disc at its
            # nearest approach to the robot.
            live = ob.present(ep.time)
            if np.any(live):
                track = ob.position(ep.time[live])
                ax.plot(track[:, 0], track[:, 1], ":", color="tab:red", lw=1.2)
                k_near = int(np.argmin(np.linalg.norm(p[live, :2] - track, axis=1)))
                _circle(ax, track[k_near], ob.radius, color="tab:red", alpha=0.8, lw=1.5)
                ax.plot(*p[live][k_near, :2], "s", color="tab:red", ms=4)
        exits = [
            e.tick
            for e in ep.events
            if e.reason.value in ("domain_exit", "not_in_goal", "balancing", "obstacle")
        ]
        if exits:
            ax.plot(p[exits, 0], p[exits, 1], "x", color="red", ms=7, mew=2)
    for g in result.scenario.goals:
        ax.plot(g[0], g[1], "*", color="green", ms=16, mec="k", zorder=5)
        if np.hypot(g[2], g[3]) > 0:
            ax.annotate(
                "",
                xy=(g[0] + g[2], g[1] + g[3]),
                xytext=(g[0], g[1]),
                arrowprops={"arrowstyle": "->", "color": "green", "lw": 2},
            )
    ax.plot([], [], "k--", lw=1, label="reference")
    if any(
        e.reason.value in ("domain_exit", "not_in_goal", "balancing")
        for ep in result.episodes
        for e in ep.events
    ):
        ax.plot([], [], "x", color="red", mew=2, label="domain exit")
    if result.scenario.disturbances:
        ax.plot([], [], "-", color="red", lw=3.5, alpha=0.5, label="pushed / dragged")
    ax.legend(loc="lower right", fontsize=8)
    ax.set_title(f"{result.scenario.name}: {len(result.episodes)} run(s)")
    out = Path(path)
    fig.savefig(out, dpi=120)
    return out


def plot_lean(result: Any, path: str | Path) -> Path:
    """Body angles (degrees) against time of every run, one panel per run. Saves a PNG."""
    n = len(result.episodes)
    fig = agg_figure(figsize=(7, 2.2 * n + 0.6), constrained_layout=True)
    axes = fig.subplots(n, 1, sharex=False, squeeze=False)
    for k, ep in enumerate(result.episodes):
        ax = axes[k, 0]
        deg = np.rad2deg(ep.lean)
        ax.plot(ep.time, deg[:, 0], label="X")
        ax.plot(ep.time, deg[:, 1], label="Y")
        for e in ep.events:
            if not e.reason.graceful and e.reason.value != "start":
                ax.axvline(e.time, color="red", lw=0.6, alpha=0.5)
        ax.set_ylabel("body angle (°)")
        ax.grid(True, alpha=0.3)
        ax.set_title(f"run {k + 1}", fontsize=9)
        ax.legend(loc="upper right", fontsize=8)
    axes[-1, 0].set_xlabel("time (s)")
    out = Path(path)
    fig.savefig(out, dpi=110)
    return out


def outer_domain_outline(
    library: Any, ep: Any, i: int, policies: dict[int, Any], angles: np.ndarray
) -> tuple[str, np.ndarray, np.ndarray]:
    """Name of the policy executing at tick ``i`` of episode ``ep`` (a policy, not
    balancing mode) and the XY outline of its outer domain D'(t) at that tick, a circle
    sampled at ``angles`` (rad). ``policies`` caches library views by row."""
    pid = int(ep.policy[i])
    pol = policies.setdefault(pid, library.policy(pid))
    start = next(
        (e.time for e in reversed(ep.events) if e.to_policy == pid and e.time <= ep.time[i] + 1e-9),
        0.0,
    )
    d = pol.outer_domain(float(ep.time[i] - start))
    rad = float(np.sqrt(np.linalg.inv(d.xy_projection())[0, 0]))
    return pol.name, d.center[0] + rad * np.cos(angles), d.center[1] + rad * np.sin(angles)


def animate_episode(result: Any, run: int, path: str | Path, *, fps: int = 10) -> Path:
    """A GIF of run ``run``: the ball, the body's lean, the current policy's outer domain
    and the path so far, at ``fps`` frames per simulated second (played in real time).

    The map, obstacles and goals are drawn once; each frame restores that background
    and draws only the moving artists (blitting). The title (time and policy) is set by
    Pillow in the title's font, size and place: a matplotlib text costs more to draw
    than the rest of a frame. Frames share one 64-colour palette, taken from three
    frames (no pixel moves by more than a few levels of 255), and Pillow stores each
    frame as the rectangle that changed since the previous one, its palette reduced to
    the colours it uses (``optimize``).

    Parameters
    ----------
    result : ScenarioResult
        As returned by :func:`gracenav.scenarios.run_scenario`.
    run : int
        Index of the episode in ``result.episodes``.
    path : str or Path
        Output file (GIF).
    fps : int
        Frames per simulated second; each frame lasts 1/fps s.

    Returns
    -------
    Path
        ``path``.
    """
    from matplotlib.colors import to_hex
    from matplotlib.font_manager import findfont
    from PIL import Image, ImageDraw, ImageFont

    ep = result.episodes[run]
    p = ep.position_state
    lean = ep.lean
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
    title = ax.set_title("t = 0.0 s")  # reserves the title's place in the layout
    # Moving obstacles, drawn where they truly were at each frame (absent: no outline).
    others = tuple(getattr(ep, "moving_obstacles", ()))
    discs = [ax.plot([], [], "-", color="tab:red", lw=1.5)[0] for _ in others]
    moving = (trail, body, ball, dom, *discs)
    for a in (*moving, title):
        a.set_animated(True)  # left out of the full draw: drawn per frame below
    step = max(1, round(1.0 / (fps * (ep.time[1] - ep.time[0]))))
    frames = range(0, ep.time.size, step)
    lean_scale = 0.6 / np.deg2rad(5.0)  # 5° of lean drawn as 0.6 m
    ang = np.linspace(0, 2 * np.pi, 50)
    policies: dict[int, Any] = {}

    def update(i: int) -> str:
        """Set the moving artists to tick ``i``; return the title."""
        trail.set_data(p[: i + 1, 0], p[: i + 1, 1])
        ball.set_data([p[i, 0]], [p[i, 1]])
        tip = p[i, :2] + lean_scale * lean[i]
        body.set_data([p[i, 0], tip[0]], [p[i, 1], tip[1]])
        for ob, disc in zip(others, discs, strict=True):
            if ob.present(ep.time[i]):
                c = ob.position(ep.time[i])
                disc.set_data(c[0] + ob.radius * np.cos(ang), c[1] + ob.radius * np.sin(ang))
            else:
                disc.set_data([], [])
        pid = int(ep.policy[i])
        if pid < 0:  # -1 balancing mode, -2 the terminal regulator at the goal
            dom.set_data([], [])
            return f"t = {ep.time[i]:6.2f} s  {'balancing' if pid == -1 else 'terminal'}"
        name, xs, ys = outer_domain_outline(lib, ep, i, policies, ang)
        dom.set_data(xs, ys)
        return f"t = {ep.time[i]:6.2f} s  {name}"

    canvas = cast("FigureCanvasAgg", fig.canvas)  # agg_figure's: blitting reads its buffer
    canvas.draw()  # lays the figure out once and renders the static background
    fig.set_layout_engine("none")  # keep that layout: nothing is drawn in full again
    background = canvas.copy_from_bbox(fig.bbox)
    width, height = canvas.get_width_height()
    props = title.get_fontproperties()
    font = ImageFont.truetype(findfont(props), props.get_size_in_points() * fig.dpi / 72.0)
    x, y = title.get_transform().transform(title.get_position())
    title_at = (float(x), float(height - y))  # middle of the baseline, from the top

    def render(i: int) -> Any:
        text = update(i)
        canvas.restore_region(background)
        for a in moving:
            ax.draw_artist(a)
        rgba = Image.frombuffer("RGBA", (width, height), canvas.buffer_rgba(), "raw", "RGBA", 0, 1)
        rgb = rgba.convert("RGB")
        ImageDraw.Draw(rgb).text(
            title_at, text, fill=to_hex(title.get_color()), font=font, anchor="ms"
        )
        return rgb

    samples = [render(i) for i in (frames[0], frames[len(frames) // 2], frames[-1])]
    strip = Image.new("RGB", (width, 3 * height))
    for k, im in enumerate(samples):
        strip.paste(im, (0, k * height))
    palette = strip.quantize(_GIF_COLOURS, method=Image.Quantize.FASTOCTREE)
    images = [render(i).quantize(palette=palette, dither=Image.Dither.NONE) for i in frames]
    out = Path(path)
    images[0].save(
        out,
        save_all=True,
        append_images=images[1:],
        duration=round(1000 / fps),
        loop=0,
        optimize=True,
    )
    return out
