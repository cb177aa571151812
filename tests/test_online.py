"""The maneuvers designed when a task starts (:mod:`gracenav.execution.online`): from
rest onto a cruise state (online starts) and from cruise or rest to rest (online ends)."""

from __future__ import annotations

import numpy as np

from gracenav.execution.online import design, shortest

ZERO = np.zeros(2)
DIAGONAL = 0.35359116


def _bound_holds(palette, moving, ends, *, to_rest: bool) -> int:  # type: ignore[no-untyped-def]
    """For each velocity of ``moving`` and each end (a along it, c across), a maneuver
    from rest at the origin to the end at that velocity, or (``to_rest``) from the
    origin at that velocity to rest at the end: ``online.shortest`` (speed and direction
    alone) never exceeds the designed duration, a design started from it is the design
    started from zero, and the nonic's end velocities and trims are the ones asked for.
    Returns how many were designed."""
    designed = 0
    for vel in moving:
        u = vel / np.hypot(*vel) if np.any(vel) else np.array([1.0, 0.0])
        for a, c in ends:
            end = a * u + c * np.array([-u[1], u[0]])
            v0, v1 = (vel, ZERO) if to_rest else (ZERO, vel)
            bound = shortest(ZERO, end, v0, v1, palette)
            full = design(ZERO, end, v0, v1, palette, 0.0, name="online")
            if full is None:
                continue
            designed += 1
            assert bound <= full.duration
            assert np.allclose(full.start_velocity, v0) and np.allclose(full.end_velocity, v1)
            assert full.start_trim == ("cruise" if np.any(v0) else "rest")
            assert full.end_trim == ("cruise" if np.any(v1) else "rest")
            again = design(ZERO, end, v0, v1, palette, bound, name="online")
            assert again is not None and again.duration == full.duration
    return designed


def test_the_kinematic_bound_is_a_lower_bound_on_a_start(palette) -> None:
    moving = np.array([[0.5, 0.0], [0.0, -0.5], [DIAGONAL, DIAGONAL], [-DIAGONAL, DIAGONAL]])
    ends = [(0.6, 0.1), (1.2, -0.3), (0.9, 0.45), (0.45, 0.0), (1.8, 0.2)]
    assert _bound_holds(palette, moving, ends, to_rest=False) >= 12


def test_the_kinematic_bound_is_a_lower_bound_on_an_end(palette) -> None:
    """From cruise and from rest to rest, a tiny displacement included (the design
    starts at 0.5 s: shorter references make the shape planner's system singular)."""
    moving = np.array([[0.5, 0.0], [DIAGONAL, DIAGONAL], [0.0, 0.0]])
    ends = [(0.5, 0.0), (0.9, 0.45), (1.2, -0.5), (0.3, 0.3), (0.01, 0.0)]
    assert _bound_holds(palette, moving, ends, to_rest=True) >= 8


def test_a_limited_palette_bounds_the_ball_jerk_of_what_is_designed_online(palette) -> None:
    """On a palette of limited references the nonics designed online keep the ball's jerk
    within the palette's bound, as its maneuvers do: the launch from rest onto the cruise
    along x over 1 m (the default palette's is the shortest feasible nonic, whose ball jerk
    exceeds 2 m/s³) lasts longer, the shortest nonic within the bound, and the kinematic bound
    (``shortest``) still holds; on the default (nonic) palette no jerk bound applies."""
    import dataclasses

    from gracenav.policies.catches import ball_jerk
    from gracenav.primitives.references import NonicReference

    def jerk(duration: float) -> float:
        ref = NonicReference.between(duration, ZERO, ZERO, end, velocity)
        return ball_jerk(ref, palette.params)

    bound = 2.0
    end, velocity = np.array([1.0, 0.0]), np.array([0.5, 0.0])
    options = dataclasses.replace(
        palette.primitive_options, reference="limited", max_ball_jerk=bound
    )
    limited = dataclasses.replace(palette, primitive_options=options)
    fast = design(ZERO, end, ZERO, velocity, palette, 0.0, name="online")
    smooth = design(ZERO, end, ZERO, velocity, limited, 0.0, name="online")
    assert fast is not None and smooth is not None
    assert jerk(fast.duration) > bound
    assert smooth.duration > fast.duration
    assert (
        jerk(smooth.duration)
        <= bound
        < jerk(smooth.duration - palette.primitive_options.duration_step)
    )
    assert shortest(ZERO, end, ZERO, velocity, limited) <= smooth.duration
    assert shortest(ZERO, end, ZERO, velocity, palette) <= fast.duration
