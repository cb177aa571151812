"""Shifts keep the ball's jerk within a bound (``CatchOptions.shift_max_ball_jerk``):
the ball moves against the lean, so a short nonic jerks it however smooth the flat
output is."""

from __future__ import annotations

import numpy as np
import pytest

from gracenav import BallbotParams, ConfigError
from gracenav.execution.smoothness import jerk_profile
from gracenav.policies.catches import _jerk_duration, ball_jerk, shift_primitive
from gracenav.policies.options import CatchOptions
from gracenav.primitives.references import (
    NonicReference,
    flat_output_gain,
    flat_output_lengths,
)
from gracenav.sim import position_state, simulate

PARAMS = BallbotParams()
ZERO = np.zeros(2)


def _nonic(duration: float, offset: tuple[float, float]) -> NonicReference:
    return NonicReference.between(duration, ZERO, ZERO, np.asarray(offset), ZERO)


def test_ball_jerk_is_the_third_derivative_of_the_linearised_ball() -> None:
    """Independent of the closed form: the linearised ball x = y − (L/κ) ÿ sampled
    finely and differentiated three times by finite differences."""
    ref = _nonic(1.5, (0.12, -0.05))
    lag = flat_output_lengths(PARAMS) / flat_output_gain(PARAMS)
    h = 1e-4
    t = np.arange(0.0, 1.5 + h / 2, h)
    ball = ref.value(t, 0) - lag * ref.value(t, 2)
    jerk = np.diff(ball, n=3, axis=0) / h**3
    # The differences stand 1.5 h inside the ends, where the nonic's ball jerk peaks
    # and falls fastest: 0.2 % below the end value.
    assert ball_jerk(ref, PARAMS) == pytest.approx(np.max(np.hypot(*jerk.T)), rel=5e-3)
    # The nonic's T⁻⁵ term: at the start the jerk is (L/κ) y⁽⁵⁾(0) = (L/κ) 15120 D / T⁵.
    d = np.hypot(0.12, 0.05)
    assert ball_jerk(ref, PARAMS) == pytest.approx(
        float(np.mean(lag)) * 15120.0 * d / 1.5**5, rel=0.01
    )


@pytest.mark.parametrize("offset", [(0.03125, 0.0), (0.1, 0.15), (0.34375, 0.03125)])
def test_shift_is_the_shortest_within_the_jerk_bound(palette, offset) -> None:
    """The shift's nonic keeps the bound, one planning step (1/128 s) shorter would
    not, and the 3D model tracking the shift from its plan start jerks the ball within
    15 % of it (the feedback adds a little). The default bound, 12 m/s³."""
    opts = CatchOptions()
    bound = opts.shift_max_ball_jerk
    assert bound == 12.0
    gains = palette.gains

    def nonic(t: float) -> NonicReference:
        return _nonic(t, offset)

    least = _jerk_duration(nonic, opts, gains)
    assert ball_jerk(nonic(least), PARAMS) <= bound < ball_jerk(nonic(least - 1 / 128), PARAMS)
    prim = shift_primitive(offset, opts, gains)
    assert prim is not None
    moving = prim.duration - opts.tail
    assert moving >= least - 1e-9
    assert ball_jerk(nonic(moving), PARAMS) <= bound
    run = simulate(prim.states[0], prim.reference(), gains)
    ball = position_state(run.states, PARAMS.ball_radius)
    t = np.arange(ball.shape[0]) * prim.dt
    assert jerk_profile(t, ball[:, 2:4]).max <= 1.15 * bound
    np.testing.assert_allclose(ball[-1, :2] - ball[0, :2], offset, atol=0.01)


def test_without_the_bound_small_shifts_jerk_far_more(palette) -> None:
    """Without the bound (palettes built before it) a 3 cm shift takes the 1 s floor
    and jerks the ball at about 55 m/s³; with 12 m/s³ it lasts 1.36 s, with 6 m/s³
    1.56 s. A palette file written before the option reads as no bound."""
    gains = palette.gains
    free = shift_primitive((0.03125, 0.0), CatchOptions(shift_max_ball_jerk=None), gains)
    bounded = shift_primitive((0.03125, 0.0), CatchOptions(), gains)
    tighter = shift_primitive((0.03125, 0.0), CatchOptions(shift_max_ball_jerk=6.0), gains)
    assert free is not None and bounded is not None and tighter is not None
    tail = CatchOptions().tail
    assert free.duration - tail == pytest.approx(1.0)
    assert ball_jerk(_nonic(1.0, (0.03125, 0.0)), PARAMS) > 50.0
    assert bounded.duration - tail == pytest.approx(1.359375)
    assert tighter.duration - tail == pytest.approx(1.5625)
    assert CatchOptions.from_dict({}).shift_max_ball_jerk is None
    with pytest.raises(ConfigError, match="shift_max_ball_jerk"):
        CatchOptions(shift_max_ball_jerk=0.0)


def test_the_bound_is_a_palette_limit_and_changes_the_key(palette) -> None:
    """Stated once in :class:`PaletteLimits` (``palette build --shift-max-ball-jerk``):
    it reaches the catches' options, is read back from the shipped palette, changes the
    palette key, and no bound hashes as the options did before the option existed (the
    keys of palettes built then stay valid)."""
    import dataclasses

    from gracenav.palette import PaletteLimits, palette_key
    from gracenav.palette.palette import _options_key

    limits = PaletteLimits(shift_max_ball_jerk=6.0)
    opts = limits.verification_options()
    assert opts.catch is not None and opts.catch.shift_max_ball_jerk == 6.0
    assert "shifts at most 6 m/s³" in limits.describe(60.0)
    assert PaletteLimits.of(palette).shift_max_ball_jerk == 3.0
    assert PaletteLimits().verification_options() == palette.options
    prim = palette.primitive_options
    same = palette_key(palette.params, palette.gains, palette.options, palette.d, prim)
    assert same == palette.key
    catch = palette.options.catch
    assert catch is not None
    free = dataclasses.replace(
        palette.options, catch=dataclasses.replace(catch, shift_max_ball_jerk=None)
    )
    assert palette_key(palette.params, palette.gains, free, palette.d, prim) != palette.key
    before = dataclasses.asdict(free)
    del before["catch"]["shift_max_ball_jerk"]
    assert _options_key(free) == before
