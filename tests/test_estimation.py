"""The position estimator (gracenav.control.estimation): its gain against the Riccati
recursion iterated, its error against the closed forms on simulated measurements, exact
pass-through without noise, and what it changes on a noisy random pair."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gracenav.control import CONTROL_RATE, PositionEstimator
from gracenav.control.estimation import DEFAULT_DRIFT, steady_state_gain
from gracenav.errors import ConfigError
from gracenav.params import BallbotParams

R = BallbotParams().ball_radius
DT = 1.0 / CONTROL_RATE


def riccati_gain(r: float, q: float, steps: int = 200_000) -> float:
    """The Kalman gain after iterating the prior variance's recursion to its fixed point
    (written apart from the closed form the module uses)."""
    prior = 1.0
    for _ in range(steps):
        nxt = prior * r / (prior + r) + q
        if nxt == prior:
            break
        prior = nxt
    return prior / (prior + r)


@pytest.mark.parametrize(
    ("r", "q"), [(1e-2, 1e-6), (2.2e-3, 2.2e-6), (1.0, 1.0), (1e-6, 1e-3), (5.0, 1e-5)]
)
def test_gain_is_the_riccati_fixed_point(r: float, q: float) -> None:
    assert steady_state_gain(r, q) == pytest.approx(riccati_gain(r, q), rel=1e-9)


def test_gain_limits() -> None:
    assert steady_state_gain(0.0, 1e-3) == 1.0
    assert steady_state_gain(0.0, 0.0) == 1.0
    assert steady_state_gain(1e-3, 0.0) == 0.0
    with pytest.raises(ConfigError):
        steady_state_gain(-1.0, 1.0)


def test_five_millimetres_at_the_control_rate() -> None:
    est = PositionEstimator(R, DT, position_std=0.005)
    # The default drift, positive (a zero drift would make K = 0: dead reckoning).
    assert DEFAULT_DRIFT > 0.0
    assert est.gain == PositionEstimator(R, DT, 0.005, drift=DEFAULT_DRIFT).gain
    # K = 0.031: a time constant of about 32 ms (the module's figures).
    assert est.gain == pytest.approx(0.0308, abs=5e-4)
    assert DT / est.gain == pytest.approx(0.0317, abs=5e-4)


def test_without_noise_the_measurement_passes_through() -> None:
    est = PositionEstimator(R, DT)
    assert est.passes_through and est.error_std == 0.0
    rng = np.random.default_rng(3)
    x0 = rng.standard_normal(8)
    assert np.array_equal(est.reset(x0), x0)
    for _ in range(50):
        x = rng.standard_normal(8)
        assert est.update(x) is x  # the measurement itself, not a copy


def smooth_motion(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Ball angles and rates (n, 2) of a smooth motion, exact at the ticks."""
    t = np.arange(n) * DT
    w = np.array([0.7, 1.3])
    amp = np.array([20.0, 12.0])  # rad: metres of rolling
    angle = amp * np.sin(w * t[:, None])
    rate = amp * w * np.cos(w * t[:, None])
    return angle, rate


def filtered_errors(
    est: PositionEstimator,
    angle: np.ndarray,
    rate: np.ndarray,
    sigma: float,
    rng: np.random.Generator,
) -> np.ndarray:
    """The estimate's error (rad, shape (n, 2)) of the true ball angles ``angle`` from
    measurements with ``sigma`` (m) of white noise on the position and exact rates;
    the rates must pass through unchanged."""
    errors = np.empty_like(angle)
    for k in range(len(angle)):
        x = np.zeros(8)
        x[0:2] = angle[k] + rng.standard_normal(2) * sigma / R
        x[4:6] = rate[k]
        y = est.reset(x) if k == 0 else est.update(x)
        errors[k] = y[0:2] - angle[k]
        assert np.array_equal(y[4:6], rate[k])
    return errors


def test_error_with_exact_rates_matches_the_closed_form() -> None:
    """With exact rates the error obeys e' = (1 − K) e + K v (plus the trapezoid's
    O(Δt³) error), whose steady standard deviation is σ √(K / (2 − K)); its mean stays
    near zero (no lag)."""
    n, sigma = 80_000, 0.005
    angle, rate = smooth_motion(n)
    rng = np.random.default_rng(11)
    est = PositionEstimator(R, DT, position_std=sigma)
    tail = filtered_errors(est, angle, rate, sigma, rng)[2000:] * R
    k = est.gain
    expected = sigma * math.sqrt(k / (2.0 - k))
    assert np.std(tail, axis=0) == pytest.approx([expected, expected], rel=0.05)
    # Successive errors are correlated (1 − K per tick): the mean's spread is larger.
    assert np.all(np.abs(np.mean(tail, axis=0)) < 5 * expected * math.sqrt(2.0 / (k * len(tail))))
    # Against the raw measurement: 8 times less noise.
    assert expected < sigma / 7.0


def test_error_matches_the_posterior_when_the_model_holds() -> None:
    """Truth built as the filter's model (a walk whose steps are the trapezoid of the
    measured rates plus white noise of the stated drift and rate noise): the error's
    standard deviation is the posterior's, √((1 − K) P⁻) (``error_std``)."""
    n, sigma, rate_std, drift = 60_000, 0.004, 0.02, 0.01
    est = PositionEstimator(R, DT, position_std=sigma, rate_std=rate_std, drift=drift)
    rng = np.random.default_rng(5)
    q = est.process_var
    _, rate = smooth_motion(n)
    angle = np.zeros((n, 2))
    for k in range(1, n):
        step = 0.5 * DT * (rate[k - 1] + rate[k])
        angle[k] = angle[k - 1] + step + rng.standard_normal(2) * math.sqrt(q)
    errors = filtered_errors(est, angle, rate, sigma, rng)
    assert np.std(errors[2000:], axis=0) == pytest.approx([est.error_std, est.error_std], rel=0.05)


def test_a_step_of_the_position_is_followed_within_its_time_constant() -> None:
    est = PositionEstimator(R, DT, position_std=0.005)
    x = np.zeros(8)
    est.reset(x)
    x[0] = 0.1 / R  # 10 cm, as a relocalisation would
    for _ in range(round(5 * DT / est.gain / DT)):  # five time constants
        y = est.update(x)
    assert abs(y[0] - x[0]) * R < 0.1 * math.exp(-4.5)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"ball_radius": 0.0, "dt": DT},
        {"ball_radius": R, "dt": -1.0},
        {"ball_radius": R, "dt": DT, "drift": 0.0},
        {"ball_radius": R, "dt": DT, "position_std": -0.001},
        {"ball_radius": R, "dt": DT, "rate_std": math.nan},
    ],
)
def test_bad_arguments_are_refused(kwargs: dict[str, float]) -> None:
    with pytest.raises(ConfigError):
        PositionEstimator(**kwargs)


@pytest.mark.slow
def test_noisy_pair_keeps_to_its_domains_with_the_filter() -> None:
    """Random pairs trial 147 (5 mm of position noise, the nonic palette): on the raw
    measurement the noise takes the state out of the fine copies' domains and catches
    follow; on the filtered position the same way runs without a domain exit, sooner."""
    from pairs import pairs_trial

    rows = {
        on: pairs_trial(147, online_starts=True, position_filter=on, palette="nonic")[0]
        for on in (False, True)
    }
    assert rows[False]["noise_std_m"] == pytest.approx(0.005)
    assert rows[False]["verified_recoveries"] >= 1
    assert rows[True]["outcome"] == "goal_reached"
    assert rows[True]["verified_recoveries"] == 0
    assert rows[True]["time_s"] < rows[False]["time_s"] - 5.0
