"""Every palette primitive's largest verified domain on the MuJoCo plant: from the centre
and the axis extremes of S it ends in G (independent physics for the verified domains)."""

from __future__ import annotations

from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pytest

from gracenav.palette import load_palette
from gracenav.policies import run_policy

pytest.importorskip("mujoco")


def _goal_values(name: str) -> list[float]:
    pal = load_palette()  # in a worker process: its own palette
    pol = pal[name]
    ell = np.linalg.cholesky(np.linalg.inv(pol.start_domain.shape_matrix))
    out = []
    for u in [np.zeros(4), *np.eye(4), *(-np.eye(4))]:
        res = run_policy(pol, pol.start_domain.center + ell @ u, plant="mujoco")
        out.append(float(pol.goal_domain.value(res.position_state[-1])))
        out.append(float(res.max_domain_value))
    return out


@pytest.mark.slow
def test_every_policy_ends_in_its_goal_domain_on_mujoco(palette) -> None:
    """Each primitive's largest verified start domain (the policy or its largest variant)."""
    largest: dict[str, tuple[float, str]] = {}
    for pol in palette:
        best = largest.get(pol.primitive.name)
        if best is None or pol.scale > best[0]:
            largest[pol.primitive.name] = (pol.scale, pol.name)
    names = [name for _, name in largest.values()]
    with ProcessPoolExecutor(max_workers=2) as pool:
        results = dict(zip(names, pool.map(_goal_values, names), strict=True))
    for name, values in results.items():
        goal, outer = np.array(values[0::2]), np.array(values[1::2])
        assert np.all(goal <= 1.0), (name, goal)
        assert np.all(outer <= 1.0), (name, outer)


def test_run_policy_model3d_matches_mujoco_closely(palette) -> None:
    pol = palette["cruise_x_to_cruise_y_1_1"]
    p0 = pol.start_domain.center + np.array([0.05, -0.03, 0.0, 0.02])
    a = run_policy(pol, p0)
    b = run_policy(pol, p0, plant="mujoco")
    assert a.position_state.shape == (pol.primitive.num_ticks + 1, 4)
    np.testing.assert_allclose(a.position_state, b.position_state, atol=1e-5)
