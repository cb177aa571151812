"""Point-to-point navigation with the library API (the README's example).

Run: python examples/navigate.py  (prints the outcome; writes nothing)
"""

from __future__ import annotations

import numpy as np

from gracenav import (
    HybridController,
    build_graph,
    build_library,
    load_map,
    load_palette,
    state_from_position,
)


def main() -> None:
    palette = load_palette()  # verified motion policies (the shipped palette)
    world = load_map(
        {
            "bounds": [[-1, -1], [3.5, 3]],
            "obstacles": [{"rectangle": {"min": [0.75, 1], "max": [1.25, 1.5]}}],
        }
    )
    library = build_library(palette, world, max_halvings=1)  # automatic instantiation
    graph = build_graph(library)  # gracefully prepares graph
    robot = HybridController(library, graph)  # single-goal trees are built on demand
    x0 = state_from_position([0, 0, 0, 0], palette.params.ball_radius)
    episode = robot.run(x0, [[2.0, 2.0, 0.0, 0.0]])  # point-to-point
    x, y = episode.position_state[-1, :2]
    print(
        f"{len(library)} library policies; {episode.status.value} after "
        f"{episode.time[-1]:.2f} s at ({x:.3f}, {y:.3f}) m; max lean "
        f"{np.rad2deg(np.abs(episode.lean).max()):.2f}°; {episode.switches} switches"
    )


if __name__ == "__main__":
    main()
