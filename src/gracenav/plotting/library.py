"""Figures of a motion policy library: start domains on the map (paper Fig. 4 style) and
its coverage of the position state space."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from gracenav.library import PolicyLibrary, max_trim_speed

if TYPE_CHECKING:
    from matplotlib.axes import Axes

__all__ = ["plot_library"]

#: Largest number of distinct start-domain circles drawn; beyond it a random subset.
MAX_CIRCLES = 20_000
_HEAT_CELLS = 100  # heat-map cells along the longer side of the map, at most
_HEAT_VELOCITIES = 48  # sampled position states per heat-map cell
#: The same for the capture panel (a capture is planned for each state no library S holds).
_CAPTURE_CELLS = 30
_CAPTURE_VELOCITIES = 8
#: Largest speed (m/s) of the capture panel's states, as in bench/bench_coverage.py.
_CAPTURE_SPEED = 0.5


def _draw_map(ax: Axes, library: PolicyLibrary) -> None:
    wmap = library.world_map
    (x0, y0), (x1, y1) = wmap.bounds
    ax.imshow(
        np.where(wmap.occupied, 1.0, np.nan),
        origin="lower",
        extent=(x0, x1, y0, y1),
        cmap="gray_r",
        vmin=0.0,
        vmax=1.0,
        interpolation="nearest",
        zorder=3,
    )
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal")
    ax.set_xlabel("X (m)")
    ax.set_ylabel("Y (m)")


def _draw_domains(ax: Axes, library: PolicyLibrary, rng: np.random.Generator) -> str:
    """Circles: XY projections of the distinct start domains; arrows: start velocities."""
    from matplotlib.collections import EllipseCollection

    types = library.types
    t = library.type_index
    radius = types.start_xy_radius[t]
    vel = library.start_state[:, 2:4]
    circles = np.unique(np.column_stack([library.start_xy, radius]), axis=0)
    note = ""
    if circles.shape[0] > MAX_CIRCLES:
        keep = rng.choice(circles.shape[0], MAX_CIRCLES, replace=False)
        note = f" (random {MAX_CIRCLES} of {circles.shape[0]} start domains drawn)"
        circles = circles[keep]
    if circles.shape[0]:
        coll = EllipseCollection(
            widths=2 * circles[:, 2],
            heights=2 * circles[:, 2],
            angles=np.zeros(circles.shape[0]),
            units="xy",
            offsets=circles[:, :2],
            offset_transform=ax.transData,
            facecolors="none",
            edgecolors="tab:blue",
            linewidths=0.5,
            alpha=0.5,
            zorder=2,
        )
        ax.add_collection(coll)
    points = np.unique(library.start_xy, axis=0)
    ax.plot(points[:, 0], points[:, 1], ".", color="tab:blue", ms=2, zorder=2)
    arrows = np.unique(np.column_stack([library.start_xy, vel]), axis=0)
    arrows = arrows[np.hypot(arrows[:, 2], arrows[:, 3]) > 0]
    if arrows.shape[0] > MAX_CIRCLES:
        arrows = arrows[rng.choice(arrows.shape[0], MAX_CIRCLES, replace=False)]
    if arrows.shape[0]:
        v_max = max(max_trim_speed(library.palette), 1e-9)
        ax.quiver(
            arrows[:, 0],
            arrows[:, 1],
            arrows[:, 2],
            arrows[:, 3],
            angles="xy",
            scale_units="xy",
            scale=v_max / (0.4 * library.spacing),
            width=0.002,
            color="tab:red",
            alpha=0.6,
            zorder=2,
        )
    return note


def _draw_scales(ax: Axes, library: PolicyLibrary) -> None:
    """Instantiation points coloured by the largest start domain size S/G placed there."""
    types = library.types
    t = library.type_index
    scale = types.start_radii[t, 0] / types.goal_radii[t, 0]
    point = library.point_index
    order = np.lexsort((-scale, point))
    first = np.ones(order.size, dtype=bool)
    first[1:] = point[order][1:] != point[order][:-1]
    rows = order[first]
    _draw_map(ax, library)
    levels = np.unique(np.round(scale, 6))
    if rows.size:
        sc = ax.scatter(
            library.start_xy[rows, 0],
            library.start_xy[rows, 1],
            c=scale[rows],
            cmap="plasma",
            vmin=float(levels[0]),
            vmax=float(max(levels[-1], levels[0] + 1e-9)),
            s=12,
            zorder=2,
        )
        ax.figure.colorbar(sc, ax=ax, shrink=0.8, label="largest start domain placed (S/G)")
    ax.set_title(
        "domain scale by instantiation point (sizes: " + ", ".join(f"{v:g}" for v in levels) + ")",
        fontsize=9,
    )


def _cell_samples(
    library: PolicyLibrary, cells: int, per_cell: int, rng: np.random.Generator
) -> tuple[np.ndarray, tuple[int, int], tuple[float, float, float, float]]:
    """``per_cell`` positions drawn in each cell of a grid of at most ``cells`` cells
    along the map's longer side (cell by cell), the grid's shape (ny, nx) and extent."""
    wmap = library.world_map
    (x0, y0), (x1, y1) = wmap.bounds
    h = max(wmap.resolution, max(x1 - x0, y1 - y0) / cells)
    nx = max(1, int(np.ceil((x1 - x0) / h)))
    ny = max(1, int(np.ceil((y1 - y0) / h)))
    cx = x0 + (np.arange(nx) + 0.5) * h
    cy = y0 + (np.arange(ny) + 0.5) * h
    gx, gy = np.meshgrid(cx, cy)
    xy = np.repeat(np.column_stack([gx.ravel(), gy.ravel()]), per_cell, axis=0)
    xy += rng.uniform(-0.5 * h, 0.5 * h, size=xy.shape)
    xy = np.clip(xy, (x0, y0), (np.nextafter(x1, x0), np.nextafter(y1, y0)))
    return xy, (ny, nx), (x0, x0 + nx * h, y0, y0 + ny * h)


def _cell_fractions(inside: np.ndarray, covered: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """Share of each cell's samples inside the state space that are covered (NaN
    where none is inside), shape ``shape``."""
    n_in = inside.reshape(shape[0] * shape[1], -1).sum(axis=1)
    n_cov = covered.reshape(shape[0] * shape[1], -1).sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        frac = np.where(n_in > 0, n_cov / np.maximum(n_in, 1), np.nan)
    return frac.reshape(shape)


def _coverage_grid(
    library: PolicyLibrary, rng: np.random.Generator
) -> tuple[np.ndarray, tuple[float, float, float, float]]:
    """Fraction of sampled position states covered in each cell (NaN outside the
    state space), shape (ny, nx), and the image extent."""
    wmap = library.world_map
    xy, shape, extent = _cell_samples(library, _HEAT_CELLS, _HEAT_VELOCITIES, rng)
    v_max = max_trim_speed(library.palette)
    v = rng.uniform(-v_max, v_max, size=xy.shape)
    inside = wmap.is_free(xy) & (wmap.clearance(xy) >= library.footprint_radius)
    covered = np.zeros(xy.shape[0], dtype=bool)
    covered[inside] = library.start_domain_covers(np.column_stack([xy, v])[inside])
    return _cell_fractions(inside, covered, shape), extent


def _capture_grid(
    library: PolicyLibrary, rng: np.random.Generator, *, progress: bool
) -> tuple[np.ndarray, tuple[float, float, float, float], float]:
    """As :func:`_coverage_grid`, on a coarser grid, for states at |v| <= 0.5 m/s
    (uniform on the disc) covered by a library S or a capture planned with the plan
    lean (:meth:`gracenav.execution.capture.Capture.covers`); also the share of all of them."""
    from gracenav._util.progress import Progress
    from gracenav.execution.capture import capture_for

    wmap = library.world_map
    xy, shape, extent = _cell_samples(library, _CAPTURE_CELLS, _CAPTURE_VELOCITIES, rng)
    speed = _CAPTURE_SPEED * np.sqrt(rng.uniform(size=xy.shape[0]))
    angle = rng.uniform(0.0, 2.0 * np.pi, size=xy.shape[0])
    states = np.column_stack([xy, speed * np.cos(angle), speed * np.sin(angle)])
    inside = wmap.is_free(xy) & (wmap.clearance(xy) >= library.footprint_radius)
    covered = np.zeros(xy.shape[0], dtype=bool)
    covered[inside] = library.start_domain_covers(states[inside])
    todo = np.flatnonzero(inside & ~covered)
    capture = capture_for(library)
    chunk = 64
    with Progress(todo.size, "captures", enabled=progress) as bar:
        for k in range(0, todo.size, chunk):
            rows = todo[k : k + chunk]
            covered[rows] = capture.covers(states[rows])
            bar.update(rows.size)
    share = float(np.mean(covered[inside])) if np.any(inside) else float("nan")
    return _cell_fractions(inside, covered, shape), extent, share


def _draw_heat(ax: Axes, library: PolicyLibrary, frac: np.ndarray, extent: Any) -> None:
    """Draw a coverage heat map (``frac`` from 0 to 1, NaN blank) under the map."""
    im = ax.imshow(
        frac,
        origin="lower",
        extent=extent,
        cmap="viridis",
        vmin=0.0,
        vmax=1.0,
        interpolation="nearest",
        zorder=1,
    )
    _draw_map(ax, library)
    ax.figure.colorbar(im, ax=ax, shrink=0.8, label="fraction of sampled states covered")


def plot_library(
    library: PolicyLibrary,
    path: str | Path,
    *,
    coverage: bool = False,
    seed: int = 0,
    progress: bool = False,
) -> Path:
    """Save a PNG of a motion policy library on its map.

    The left (or only) panel shows the map with obstacles in black, the instantiation
    points, the XY projections of the start domains S (circles) and the start velocities
    of the policies (arrows, red), as in the paper's Fig. 4. With ``coverage=True`` a
    second panel shows, for each cell of a grid over the map, the fraction of sampled
    position states (positions in the cell with clearance >= the footprint radius,
    velocities uniform in [−v_max, v_max]²) that lie in at least one start domain; cells
    outside the sampled state space are blank, uncovered regions are dark; a third
    panel the domain scale: at each instantiation point, the largest start domain size
    S/G placed there (scaled domains: large in open space, small near obstacles); and,
    if the palette has catches, a fourth panel the coverage with captures: on a
    coarser grid, states at up to 0.5 m/s (uniform on the disc, as the coverage
    bench draws them) in a library S or with a capture planned at the plan lean
    (:mod:`gracenav.execution.capture`), what a push leaves a verified policy for.

    Parameters
    ----------
    library : PolicyLibrary
    path : str or Path
        Output PNG file (parent folders are created).
    coverage : bool
        Add the coverage heat map.
    seed : int
        Seed of the coverage samples and of the subset drawn for very large libraries.
    progress : bool
        Show a progress bar (on a terminal) while captures are planned.

    Returns
    -------
    Path
        The written file.
    """
    from gracenav.execution.capture import capture_for
    from gracenav.plotting._figure import agg_figure

    rng = np.random.default_rng(seed)
    captures = coverage and capture_for(library).available
    ncols = (4 if captures else 3) if coverage else 1
    fig = agg_figure(figsize=(6.5 * ncols, 6.0), constrained_layout=True)
    axes_any = fig.subplots(1, ncols, squeeze=False)
    axes: list[Any] = list(axes_any[0])
    ax = axes[0]
    _draw_map(ax, library)
    note = _draw_domains(ax, library, rng)
    ax.set_title(
        f"{library.world_map.name}: {len(library)} policies, spacing {library.spacing:g} m{note}",
        fontsize=9,
    )
    if coverage:
        cax = axes[1]
        frac, extent = _coverage_grid(library, rng)
        _draw_heat(cax, library, frac, extent)
        cax.set_title(
            f"start-domain coverage {library.coverage:.1%} "
            f"(|ẋ|, |ẏ| <= {max_trim_speed(library.palette):.2g} m/s)",
            fontsize=9,
        )
        _draw_scales(axes[2], library)
        if captures:
            frac, extent, share = _capture_grid(library, rng, progress=progress)
            _draw_heat(axes[3], library, frac, extent)
            axes[3].set_title(
                f"with captures: {share:.1%} of sampled states (|v| <= {_CAPTURE_SPEED:g} m/s)",
                fontsize=9,
            )
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=130)
    return out
