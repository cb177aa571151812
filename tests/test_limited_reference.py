"""Limited references: polynomial flat outputs that keep the lean and torque within the
limits for the shortest duration, C⁴ at their ends like the nonic."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gracenav.errors import ConfigError
from gracenav.params import BallbotParams
from gracenav.primitives import PrimitiveSetOptions
from gracenav.primitives.design import _plan_limited, _plan_maneuver
from gracenav.primitives.limited import (
    LimitedReferenceOptions,
    PolynomialReference,
    _load_program,
    limited_reference,
)
from gracenav.primitives.references import (
    NonicReference,
    flat_output_gain,
    flat_output_lengths,
)

PARAMS = BallbotParams()
LEAN = math.radians(4.5)
GRID = np.arange(1, 37) * 0.125


def _loads(ref: object, duration: float, n: int = 4001) -> tuple[float, float]:
    """Largest |lean| (rad) and |linearised torque| + Coulomb friction (N m) of a
    reference on ``n`` samples: the formulas written out again, per axis."""
    t = np.linspace(0.0, duration, n)
    y1, y2, y3, y4 = (ref.value(t, o) for o in (1, 2, 3, 4))  # type: ignore[attr-defined]
    kappa = flat_output_gain(PARAMS)
    lengths = flat_output_lengths(PARAMS)
    r, a, b = PARAMS.ball_radius, PARAMS.alpha(), PARAMS.beta()
    phi, phid, phidd = y2 / kappa, y3 / kappa, y4 / kappa
    thd = (y1 - lengths * phid) / r - phid
    thdd = (y2 - lengths * phidd) / r - phidd
    tau = a * thdd + (a + b) * phidd + PARAMS.viscous_friction * thd
    return float(np.max(np.hypot(phi[:, 0], phi[:, 1]))), float(
        np.max(np.abs(tau)) + PARAMS.coulomb_friction
    )


@pytest.mark.parametrize("seed", range(4))
def test_ends_are_those_of_a_trim_exactly(seed: int) -> None:
    rng = np.random.default_rng(seed)
    v0, v1 = rng.uniform(-0.5, 0.5, 2), rng.uniform(-0.5, 0.5, 2)
    disp = rng.uniform(0.5, 1.5, 2)
    T = 3.0
    got = _load_program(
        T,
        v0,
        disp,
        v1,
        PARAMS,
        LEAN,
        PARAMS.torque_limit,
        LimitedReferenceOptions(max_speed=2.0, max_backward_speed=5.0, max_ball_jerk=None),
    )
    assert got is not None
    ref = PolynomialReference(T, got[1])
    ends = np.array([0.0, T])
    np.testing.assert_allclose(ref.value(ends, 0), [[0, 0], disp], atol=1e-12)
    np.testing.assert_allclose(ref.value(ends, 1), [v0, v1], atol=1e-12)
    for order in (2, 3, 4):  # what the shape planner asks of a reference: <= 1e-9
        assert np.max(np.abs(ref.value(ends, order))) <= 1e-11


def test_the_nonic_is_never_better_at_its_own_duration() -> None:
    # The nonic is one polynomial of degree <= 15 with the same ends: the program's
    # least load cannot exceed the nonic's.
    disp, zero = np.array([0.5, 0.0]), np.zeros(2)
    for T in (2.25, 2.75, 3.5):
        nonic = NonicReference.between(T, zero, zero, disp, zero)
        lean, tau = _loads(nonic, T)
        z_nonic = max(
            lean / (LEAN * math.cos(math.pi / 16)),
            (tau - PARAMS.coulomb_friction) / (PARAMS.torque_limit - PARAMS.coulomb_friction),
        )
        got = _load_program(
            T,
            zero,
            disp,
            zero,
            PARAMS,
            LEAN,
            PARAMS.torque_limit,
            LimitedReferenceOptions(max_ball_jerk=None),
        )
        assert got is not None
        assert got[0] <= z_nonic * (1 + 1e-6)


def test_limits_hold_between_the_samples_and_the_duration_beats_the_nonic() -> None:
    disp, zero = np.array([0.5, 0.0]), np.zeros(2)
    free = LimitedReferenceOptions(max_ball_jerk=None)
    ref = limited_reference(zero, disp, zero, PARAMS, max_lean=LEAN, durations=GRID, options=free)
    assert ref is not None
    lean, tau = _loads(ref, ref.duration)
    assert lean <= LEAN * 1.01  # the program holds them at 161 samples
    assert tau <= PARAMS.torque_limit * 1.01
    # Shorter than the nonic at the same limits (2.75 s on the shipped grid), never
    # shorter than bang-bang acceleration at the lean limit, 2 sqrt(D / (κ φ_max)).
    nonic = _plan_maneuver("rest", "rest", (1, 0), 0.5, PARAMS, PrimitiveSetOptions())
    assert nonic is not None
    assert ref.duration <= 0.8 * nonic.duration
    assert ref.duration >= 2.0 * math.sqrt(0.5 / (flat_output_gain(PARAMS) * LEAN))


def _ball_jerk(ref: object, duration: float, n: int = 4001) -> float:
    """Largest |y⁽³⁾ − (L/κ) y⁽⁵⁾| (m/s³): the ball's jerk on the linearised model."""
    t = np.linspace(0.0, duration, n)
    lk = flat_output_lengths(PARAMS) / flat_output_gain(PARAMS)
    j = ref.value(t, 3) - lk * ref.value(t, 5)  # type: ignore[attr-defined]
    return float(np.max(np.hypot(j[:, 0], j[:, 1])))


def test_the_ball_jerk_bound_holds_and_costs_time() -> None:
    disp, zero = np.array([0.5, 0.0]), np.zeros(2)
    grid = np.arange(1, 161) * 0.03125
    durations = []
    for jerk in (None, 10.0, 6.0, 3.0):
        opts = LimitedReferenceOptions(max_ball_jerk=jerk)
        ref = limited_reference(
            zero, disp, zero, PARAMS, max_lean=LEAN, durations=grid, options=opts
        )
        assert ref is not None
        if jerk is not None:
            assert _ball_jerk(ref, ref.duration) <= jerk * 1.02
        durations.append(ref.duration)
    assert durations == sorted(durations)  # a tighter bound never shortens it
    # Unbounded, the ball jerks two orders of magnitude more than the nonic's 5.6 m/s³.
    free = limited_reference(
        zero,
        disp,
        zero,
        PARAMS,
        max_lean=LEAN,
        durations=grid,
        options=LimitedReferenceOptions(max_ball_jerk=None),
    )
    assert free is not None and _ball_jerk(free, free.duration) > 50.0
    nonic = NonicReference.between(2.75, zero, zero, disp, zero)
    assert _ball_jerk(nonic, 2.75) == pytest.approx(5.61, abs=0.01)


def test_rotation_turns_every_derivative() -> None:
    zero = np.zeros(2)
    ref = limited_reference(zero, [0.5, 0.5], zero, PARAMS, max_lean=LEAN, durations=GRID)
    assert ref is not None
    c, s = math.cos(0.7), math.sin(0.7)
    rot = np.array([[c, -s], [s, c]])
    t = np.linspace(0.0, ref.duration, 50)
    for order in range(5):
        np.testing.assert_allclose(
            ref.rotated(rot).value(t, order), ref.value(t, order) @ rot.T, atol=1e-12
        )


def test_a_limited_maneuver_is_feasible_on_the_3d_model() -> None:
    options = PrimitiveSetOptions(reference="limited")
    grid = [0.125 * k for k in range(1, 37)]
    got = _plan_limited(
        np.zeros(2), np.array([0.5, 0.0]), np.array([0.5, 0.0]), grid, PARAMS, options
    )
    assert got is not None
    duration, (res0, res1) = got
    for res in (res0, res1):
        assert res.converged
        assert res.peak_lean <= LEAN and res.peak_torque <= PARAMS.torque_limit
    nonic = _plan_maneuver("rest", "cruise_x", (1, 0), 0.5, PARAMS, PrimitiveSetOptions())
    assert nonic is not None and duration <= nonic.duration


def test_options_are_checked() -> None:
    with pytest.raises(ConfigError, match="degree"):
        LimitedReferenceOptions(degree=9)
    with pytest.raises(ConfigError, match="reference"):
        PrimitiveSetOptions(reference="cubic")  # type: ignore[arg-type]
    # The nonic keeps the keys of sets and palettes built before the option existed.
    assert "reference" not in PrimitiveSetOptions().to_dict()
    assert PrimitiveSetOptions(reference="limited").to_dict()["reference"] == "limited"


def test_speed_levels_keep_the_first_set_and_add_trims_whose_moves_last_as_long() -> None:
    from gracenav.primitives.design import _trim_velocities, _trims
    from gracenav.primitives.motion import speed_catalogue, trim_names

    base = PrimitiveSetOptions()
    fast = PrimitiveSetOptions(cruise_speeds=(1.0, 1.2), max_speed=1.35)
    assert "cruise_speeds" not in base.to_dict()
    assert PrimitiveSetOptions.from_dict(fast.to_dict()) == fast
    vb, vf = _trim_velocities(0.5, base), _trim_velocities(0.5, fast)
    for name, v in vb.items():  # the first level is unchanged
        np.testing.assert_array_equal(vf[name], v)
    trims = {t.name: t for t in _trims(0.5, PARAMS, fast)}
    assert trim_names(3) == ("cruise3_x", "cruise3_y", "cruise3_xy")
    for level, speed, cells in ((2, 1.0, 2), (3, 1.2, 3)):
        x, _, xy = trim_names(level)
        np.testing.assert_allclose(trims[x].displacement, [0.5 * cells, 0.0], atol=1e-12)
        # Speeds within a planner step of the asked ones, moves a whole number of steps.
        assert abs(np.hypot(*trims[x].start_velocity) - speed) <= speed * 2e-3
        assert abs(np.hypot(*trims[xy].start_velocity) - speed) <= speed * 2e-3
        for t in (trims[x], trims[xy]):
            steps = t.duration / fast.planner.step
            assert abs(steps - round(steps)) < 1e-9
    # Every maneuver of a level joins trims of that level, the level below or rest.
    names = set(trims) | {"rest"}
    for level in (2, 3):
        for start, end, cands in speed_catalogue(level):
            assert start in names and end in names and len(cands) >= 5
    with pytest.raises(ConfigError, match="ascending"):
        PrimitiveSetOptions(cruise_speeds=(1.0, 0.9), max_speed=1.5)
    with pytest.raises(ConfigError, match="max_speed"):
        PrimitiveSetOptions(cruise_speeds=(1.0,))
