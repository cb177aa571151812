"""The maneuvers designed when a task starts (:mod:`gracenav.execution.online`): from
rest onto a cruise state (online starts) and from cruise or rest to rest (online ends)."""

from __future__ import annotations

import math

import numpy as np
import pytest

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


def _nonic_speeds(duration: float, v0: float, distance: float, v1: float) -> np.ndarray:
    """Speeds along a line of the nonic from 0 at ``v0`` to ``distance`` at ``v1`` with
    acceleration, jerk and snap zero at both ends, solved here from its ten boundary
    conditions (not through :class:`~gracenav.primitives.references.NonicReference`)."""
    from math import factorial

    rows, rhs = [], []
    for t, values in ((0.0, (0.0, v0, 0.0, 0.0, 0.0)), (duration, (distance, v1, 0.0, 0.0, 0.0))):
        for der, value in enumerate(values):
            rows.append(
                [
                    factorial(k) // factorial(k - der) * t ** (k - der) if k >= der else 0.0
                    for k in range(10)
                ]
            )
            rhs.append(value)
    c = np.linalg.solve(np.array(rows, dtype=float), np.array(rhs))
    t = np.linspace(0.0, duration, 4001)
    return sum(k * c[k] * t ** (k - 1) for k in range(1, 10))


@pytest.mark.parametrize("to_rest", [False, True], ids=["start", "end"])
def test_an_online_maneuver_reaches_farther_only_by_lasting_longer(palette, to_rest) -> None:
    """Between rest and the cruise along x, 2.5 m apart: no nonic within the palette's
    4.5 s keeps within its 0.8 m/s (it covers at most about 2.05 m), one within 6.5 s
    does (:data:`gracenav.execution.online.LONGEST`, the default of online starts and
    ends). The shortest is the first duration on the grid whose speeds, from the nonic
    solved independently, keep within the palette's speed and do not run backwards, and
    the shape trajectory planner makes it feasible on the 3D model within the lean and
    torque limits."""
    from gracenav.execution.online import LONGEST

    opts = palette.primitive_options
    cruise, end = np.array([0.5, 0.0]), np.array([2.5, 0.0])
    v0, v1 = (cruise, ZERO) if to_rest else (ZERO, cruise)
    assert opts.max_duration == 4.5 and LONGEST == 6.5
    assert shortest(ZERO, end, v0, v1, palette) == np.inf
    assert design(ZERO, end, v0, v1, palette, 0.0, name="online") is None
    least = shortest(ZERO, end, v0, v1, palette, LONGEST)
    assert opts.max_duration < least <= LONGEST

    def keeps(duration: float) -> bool:
        speed = _nonic_speeds(duration, v0[0], end[0], v1[0])
        return bool(speed.max() <= opts.max_speed and speed.min() >= -opts.max_backward_speed)

    assert keeps(least) and not keeps(least - opts.duration_step)
    made = design(ZERO, end, v0, v1, palette, least, name="online", longest=LONGEST)
    assert made is not None and least <= made.duration <= LONGEST
    assert np.allclose(made.displacement, end)
    report = made.reports[0]
    assert report.peak_lean <= opts.max_lean + 1e-12
    assert report.peak_torque <= palette.params.torque_limit + 1e-9


def test_online_maneuvers_keep_below_the_design_push_floor_on_a_fast_palette() -> None:
    """Above :data:`gracenav.library.push_fans.FAN_FLOOR` the library keeps its own
    policies' room for the design push's catches; a maneuver designed online gets no such
    check, so where the library keeps a design push it keeps within the floor: on the
    speed palette (maneuvers up to 1.32 m/s) the shortest start from rest onto the
    0.5 m/s cruise 2.5 m ahead within the floor keeps within 0.8 m/s on the nonic solved
    independently, where the palette's speed allows a shorter, faster one;
    without a design push the palette's speed applies, and a palette within the floor
    (the default) is not changed."""
    import types

    from gracenav.execution.online import LONGEST, speed_limit
    from gracenav.library.push_fans import FAN_FLOOR
    from gracenav.palette import load_palette

    fast = load_palette("speed")
    default = load_palette()
    assert fast.primitive_options.max_speed > FAN_FLOOR == 0.8
    pushed = types.SimpleNamespace(palette=fast, design_push=8.0)
    assert speed_limit(pushed) == FAN_FLOOR  # type: ignore[arg-type]
    unpushed = types.SimpleNamespace(palette=fast, design_push=0.0)
    assert speed_limit(unpushed) == fast.primitive_options.max_speed  # type: ignore[arg-type]
    plain = types.SimpleNamespace(palette=default, design_push=8.0)
    assert speed_limit(plain) == default.primitive_options.max_speed  # type: ignore[arg-type]

    cruise, end = np.array([0.5, 0.0]), np.array([2.5, 0.0])
    free = shortest(ZERO, end, ZERO, cruise, fast, LONGEST)
    least = shortest(ZERO, end, ZERO, cruise, fast, LONGEST, FAN_FLOOR)
    assert free < least <= LONGEST
    assert _nonic_speeds(least, 0.0, end[0], cruise[0]).max() <= FAN_FLOOR
    assert _nonic_speeds(free, 0.0, end[0], cruise[0]).max() > FAN_FLOOR
    step = fast.primitive_options.duration_step
    assert _nonic_speeds(least - step, 0.0, end[0], cruise[0]).max() > FAN_FLOOR


def test_what_is_designed_and_sized_is_remembered_as_made(palette, fig5_library) -> None:  # type: ignore[no-untyped-def]
    """A task designs and sizes its start's and end's maneuvers again for the same
    displacements (checked, then run): the second call returns what the first made,
    which equals a fresh computation (the same duration and plan; the same S and
    report), and any other input is made afresh. The domain shape is kept too."""
    import gracenav.execution.online as online
    from gracenav.policies import PrimitiveKind, domain_shape
    from gracenav.policies.shape import _domain_shape

    lib = fig5_library
    rows = lib.trim_indices(PrimitiveKind.CRUISE)
    rows = rows[np.isclose(lib.start_state[rows, 2], 0.5) & np.isclose(lib.start_state[rows, 3], 0)]
    sized = None
    for row in rows[:: max(1, rows.size // 40)]:  # a launch 1.5 m behind a trim that fits
        end = lib.start_xy[row]
        start = end - np.array([1.5, 0.25])
        made = design(start, end, ZERO, lib.start_state[row, 2:4], palette, 0.0, name="online")
        if made is None:
            continue
        then = lib.policy(int(row)).start_domain
        sized = online.size_where_it_runs(lib, made, start, then)
        if sized.report is not None:  # a verification ran: kept
            break
    assert sized is not None and sized.report is not None and made is not None
    velocity = lib.start_state[row, 2:4]
    assert design(start, end, ZERO, velocity, palette, 0.0, name="online") is made
    fresh = online._design(end - start, ZERO, velocity, palette, 0.0, "online", None, None)
    assert fresh is not None and fresh is not made
    assert fresh.duration == made.duration
    for field in ("coefficients", "theta", "theta_dot"):
        np.testing.assert_array_equal(getattr(fresh.plans[0], field), getattr(made.plans[0], field))
    assert design(start, end, ZERO, velocity, palette, 0.5, name="online") is not made
    assert online.size_where_it_runs(lib, made, start, then) is sized
    again = online._size_where_it_runs(lib, made, start, then)
    np.testing.assert_array_equal(again.start_domain.shape_matrix, sized.start_domain.shape_matrix)
    assert again.report is not None and again.report.passed == sized.report.passed
    assert online.size_where_it_runs(lib, made, start + 0.01, then) is not sized
    # The domain shape: one computation per gains and horizon, equal to a fresh one.
    horizon = palette.options.shape_horizon
    shape = domain_shape(palette.gains, horizon=horizon)
    assert domain_shape(palette.gains, horizon=horizon) is shape
    key = (palette.gains.lqr.tobytes(), palette.gains.params, float(horizon))
    assert _domain_shape.__wrapped__(*key) == shape
    assert domain_shape(palette.gains, horizon=2.0 * horizon) != shape


def _design_in_child(palette, out) -> None:  # type: ignore[no-untyped-def]
    made = design(ZERO, np.array([1.5, 0.25]), ZERO, np.array([0.5, 0.0]), palette, 0.0, name="c")
    out.put(None if made is None else made.duration)


def test_a_forked_child_remembers_without_the_parents_lock(palette) -> None:  # type: ignore[no-untyped-def]
    """A process forked while a thread of its parent holds the lock of what is
    remembered designs in the child all the same (the child gets a lock of its own)."""
    import multiprocessing

    import gracenav.execution.online as online

    ctx = multiprocessing.get_context("fork")
    out = ctx.Queue()
    with online._remembered:  # held while the child is forked
        child = ctx.Process(target=_design_in_child, args=(palette, out))
        child.start()
    child.join(120.0)  # a hang guard
    assert child.exitcode == 0
    duration = out.get(timeout=5.0)
    made = design(ZERO, np.array([1.5, 0.25]), ZERO, np.array([0.5, 0.0]), palette, 0.0, name="c")
    assert made is not None and duration == made.duration


def test_the_shortest_duration_is_remembered_as_scanned(palette) -> None:  # type: ignore[no-untyped-def]
    """``shortest`` answers again what a scan of the duration grid (:func:`admissible`'s
    first) gives, for displacements and speeds it has seen and not seen, inf included
    (a displacement no nonic within the palette's speed covers in ``longest``)."""
    from gracenav.execution.online import admissible

    opts, params = palette.primitive_options, palette.params

    def scanned(disp, v0, v1, longest, max_speed):  # type: ignore[no-untyped-def]
        first = admissible(disp, v0, v1, opts, 0.0, params, longest, max_speed)
        return next((d for d, _ in first), math.inf)

    cruise = np.array([0.5, 0.0])
    cases = [
        (np.array([1.5, 0.25]), ZERO, cruise, None, None),
        (np.array([1.5, 0.25]), ZERO, cruise, 6.5, 0.8),
        (np.array([0.75, -0.5]), ZERO, cruise, 6.5, 0.8),
        (np.array([1.0, 0.0]), cruise, ZERO, 6.5, 0.8),
        (np.array([9.0, 0.0]), ZERO, cruise, None, None),  # too far: inf
    ]
    for _ in range(2):  # made, then remembered
        for disp, v0, v1, longest, max_speed in cases:
            got = shortest(ZERO, disp, v0, v1, palette, longest, max_speed)
            assert got == scanned(disp, v0, v1, longest, max_speed)
    assert shortest(ZERO, cases[0][0], ZERO, cruise, palette) != math.inf
    assert shortest(ZERO, cases[-1][0], ZERO, cruise, palette) == math.inf
