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


def _coverage_grid(
    library: PolicyLibrary, rng: np.random.Generator
) -> tuple[np.ndarray, tuple[float, float, float, float]]:
    """Fraction of sampled position states covered in each cell (NaN outside the
    state space), shape (ny, nx), and the image extent."""
    wmap = library.world_map
    (x0, y0), (x1, y1) = wmap.bounds
    h = max(wmap.resolution, max(x1 - x0, y1 - y0) / _HEAT_CELLS)
    nx = max(1, int(np.ceil((x1 - x0) / h)))
    ny = max(1, int(np.ceil((y1 - y0) / h)))
    k = _HEAT_VELOCITIES
    cx = x0 + (np.arange(nx) + 0.5) * h
    cy = y0 + (np.arange(ny) + 0.5) * h
    gx, gy = np.meshgrid(cx, cy)
    xy = np.repeat(np.column_stack([gx.ravel(), gy.ravel()]), k, axis=0)
    xy += rng.uniform(-0.5 * h, 0.5 * h, size=xy.shape)
    xy = np.clip(xy, (x0, y0), (np.nextafter(x1, x0), np.nextafter(y1, y0)))
    v_max = max_trim_speed(library.palette)
    v = rng.uniform(-v_max, v_max, size=xy.shape)
    inside = wmap.is_free(xy) & (wmap.clearance(xy) >= library.footprint_radius)
    covered = np.zeros(xy.shape[0], dtype=bool)
    covered[inside] = library.start_domain_covers(np.column_stack([xy, v])[inside])
    n_in = inside.reshape(-1, k).sum(axis=1)
    n_cov = covered.reshape(-1, k).sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        frac = np.where(n_in > 0, n_cov / np.maximum(n_in, 1), np.nan)
    return frac.reshape(ny, nx), (x0, x0 + nx * h, y0, y0 + ny * h)


def plot_library(
    library: PolicyLibrary,
    path: str | Path,
    *,
    coverage: bool = False,
    seed: int = 0,
) -> Path:
    """Save a PNG of a motion policy library on its map.

    The left (or only) panel shows the map with obstacles in black, the instantiation
    points, the XY projections of the start domains S (circles) and the start velocities
    of the policies (arrows, red), as in the paper's Fig. 4. With ``coverage=True`` a
    second panel shows, for each cell of a grid over the map, the fraction of sampled
    position states (positions in the cell with clearance >= the footprint radius,
    velocities uniform in [−v_max, v_max]²) that lie in at least one start domain; cells
    outside the sampled state space are blank, uncovered regions are dark; and a third
    panel the domain scale: at each instantiation point, the largest start domain size
    S/G placed there (scaled domains: large in open space, small near obstacles).

    Parameters
    ----------
    library : PolicyLibrary
    path : str or Path
        Output PNG file (parent folders are created).
    coverage : bool
        Add the coverage heat map.
    seed : int
        Seed of the coverage samples and of the subset drawn for very large libraries.

    Returns
    -------
    Path
        The written file.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rng = np.random.default_rng(seed)
    ncols = 3 if coverage else 1
    fig, axes_any = plt.subplots(
        1, ncols, figsize=(6.5 * ncols, 6.0), constrained_layout=True, squeeze=False
    )
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
        im = cax.imshow(
            frac,
            origin="lower",
            extent=extent,
            cmap="viridis",
            vmin=0.0,
            vmax=1.0,
            interpolation="nearest",
            zorder=1,
        )
        _draw_map(cax, library)
        fig.colorbar(im, ax=cax, shrink=0.8, label="fraction of sampled states covered")
        cax.set_title(
            f"start-domain coverage {library.coverage:.1%} "
            f"(|ẋ|, |ẏ| <= {max_trim_speed(library.palette):.2g} m/s)",
            fontsize=9,
        )
        _draw_scales(axes[2], library)
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=130)
    plt.close(fig)
    return out
