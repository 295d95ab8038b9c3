"""Tracking and compensation metrics (docs/spec.md §6): hand-computed values, loops whose width is
known analytically, invariances, and bad input named by argument and value."""

import numpy as np
import pytest

import piezohyst as ph
from piezohyst.metrics import hysteresis_percent, linearity_error, max_error, rmse, tracking_metrics


def triangle_cycles(cycles, n=101):
    """0 -> 1 -> 0 repeated, turning points sampled once."""
    up = np.linspace(0.0, 1.0, n)
    return np.r_[np.tile(np.r_[up, up[::-1][1:-1]], cycles), 0.0]


# ----------------------------------------------------------------------------- errors


def test_rmse_and_max_error_hand_computed():
    r, y = [0.0, 1.0, 2.0, 3.0], [0.0, 1.0, 2.0, 5.0]
    assert rmse(r, y) == 1.0  # sqrt(2**2 / 4)
    assert max_error(r, y) == 2.0
    # the sign of the error does not matter
    assert rmse(y, r) == 1.0 and max_error(y, r) == 2.0
    assert rmse([1.0, 2.0], [2.0, 0.0]) == pytest.approx(np.sqrt((1 + 4) / 2), abs=1e-15)
    assert max_error([1.0, 2.0], [2.0, 0.0]) == 2.0
    # one sample is enough, and a constant reference is fine for the absolute errors
    assert rmse([3.0], [1.0]) == 2.0 and max_error([3.0, 3.0], [3.0, 2.5]) == 0.5


def test_tracking_metrics_hand_computed():
    m = tracking_metrics([0.0, 1.0, 2.0, 3.0], [0.0, 1.0, 2.0, 5.0])
    assert set(m) == {
        "rmse",
        "max_error",
        "rmse_percent",
        "max_error_percent",
        "normalized_max_error",
        "normalized_rms_error",
        "linearity_error",
    }
    # e = [0, 0, 0, 2], reference range 3; LS line of y on x: y = 1.6 x - 0.4, residuals
    # [0.4, -0.2, -0.8, 0.6], output range 5 -> linearity 0.8 / 5 = 16 %
    expected = {
        "rmse": 1.0,
        "max_error": 2.0,
        "rmse_percent": 100 / 3,
        "max_error_percent": 200 / 3,
        "normalized_max_error": 2 / 3,
        "normalized_rms_error": 1 / 3,
        "linearity_error": 16.0,
    }
    for key, value in expected.items():
        assert m[key] == pytest.approx(value, rel=1e-12, abs=1e-12), key


def test_tracking_metrics_sine_error_has_the_rms_of_a_sine():
    t = np.arange(4000) / 4000
    ref = 10 * np.sin(2 * np.pi * 2 * t)  # range 20
    out = ref + 0.5 * np.sin(2 * np.pi * 7 * t)
    m = tracking_metrics(ref, out)
    assert m["normalized_max_error"] == pytest.approx(0.5 / 20, rel=1e-6)
    assert m["normalized_rms_error"] == pytest.approx(0.5 / np.sqrt(2) / 20, rel=1e-9)
    assert m["rmse_percent"] == pytest.approx(100 * m["normalized_rms_error"], rel=1e-12)


def test_tracking_metrics_of_a_constant_output_reports_no_linearity():
    m = tracking_metrics([0.0, 1.0, 2.0], [1.0, 1.0, 1.0])
    assert np.isnan(m["linearity_error"]) and m["max_error"] == 1.0


# ----------------------------------------------------------------------------- linearity


def test_linearity_error_of_any_line_is_zero():
    x = np.linspace(-3.0, 7.0, 501)
    assert linearity_error(x, 2.0 * x + 5.0) == pytest.approx(0.0, abs=1e-12)
    assert linearity_error(x, -0.5 * x + 1e6) == pytest.approx(0.0, abs=1e-6)  # offset far from zero


def test_linearity_error_of_a_known_bump():
    # LS line of [0, 1, 3, 3, 4] on [0..4] is y = x + 0.2; worst deviation 0.8 at x = 2; range 4
    assert linearity_error([0, 1, 2, 3, 4], [0, 1, 3, 3, 4]) == pytest.approx(20.0, rel=1e-12)
    # a parabola on a symmetric grid: y = x**2 on [-1, 1]: the LS line is y = mean(x**2) = 1/3
    # (slope 0 by symmetry, sample mean of x**2 for 2001 points), worst deviation at x = +-1
    x = np.linspace(-1, 1, 2001)
    mean_sq = np.mean(x**2)
    assert linearity_error(x, x**2) == pytest.approx(100 * (1 - mean_sq), rel=1e-12)


def test_linearity_error_ignores_gain_and_offset():
    x = np.linspace(0, 1, 300)
    y = x + 0.05 * np.sin(3 * np.pi * x)
    base = linearity_error(x, y)
    assert base > 1.0
    assert linearity_error(x, 3 * y - 7) == pytest.approx(base, rel=1e-10)
    assert linearity_error(2 * x + 4, y) == pytest.approx(base, rel=1e-10)


# ----------------------------------------------------------------------------- hysteresis


def test_hysteresis_of_a_parallelogram_loop():
    # ascending y = 2x - 0.15, descending y = 2x + 0.15: width 0.3, output range 2.3
    up = np.linspace(0.0, 1.0, 37)  # sample grid not aligned with the levels
    x = np.r_[up, up[::-1], up]
    y = np.r_[2 * up - 0.15, 2 * up[::-1] + 0.15, 2 * up - 0.15]
    assert hysteresis_percent(x, y) == pytest.approx(100 * 0.3 / 2.3, rel=1e-12)
    assert hysteresis_percent(x, y, levels=7) == pytest.approx(100 * 0.3 / 2.3, rel=1e-12)
    # the path read backwards is the same loop
    assert hysteresis_percent(x[::-1], y[::-1]) == pytest.approx(100 * 0.3 / 2.3, rel=1e-12)


def test_hysteresis_of_a_line_is_zero():
    x = triangle_cycles(3)
    assert hysteresis_percent(x, 2.0 * x + 1.0) == pytest.approx(0.0, abs=1e-12)
    assert hysteresis_percent(np.linspace(0, 1, 50), np.linspace(0, 1, 50) ** 3) == 0.0  # one branch only


def test_hysteresis_of_an_ellipse():
    # x = cos t, y = cos(t - phi): at x = 0 the branches are +-sin(phi), the widest point;
    # output range 2 -> 100 sin(phi) %
    phi = 0.3
    t = np.linspace(0, 4 * np.pi, 40001)
    x, y = np.cos(t), np.cos(t - phi)
    assert hysteresis_percent(x, y, levels=201) == pytest.approx(100 * np.sin(phi), rel=1e-6)


def test_hysteresis_of_a_play_operator_loop():
    # one play (threshold r = 0.1) on a 0..1 triangle, after the first half cycle: branches
    # y = x - r and y = x + r, output range 1 - 2r -> 2r / (1 - 2r) = 25 %
    x = triangle_cycles(3)
    y = ph.PI([0.1], [1.0], p0=0.0).simulate(x)
    assert hysteresis_percent(x[200:], y[200:]) == pytest.approx(25.0, rel=1e-9)


def test_a_jump_where_the_input_holds_is_not_width():
    # one rising sweep with the output jumping by 5 while the input holds at 0.5: one branch,
    # 0 %, whether the hold sits on a level (levels=3: 0, 0.5, 1) or not (levels=4)
    x = np.r_[np.linspace(0, 0.5, 6), np.linspace(0.5, 1, 6)]
    y = x + np.r_[np.zeros(6), np.full(6, 5.0)]
    assert hysteresis_percent(x, y, levels=3) == 0.0
    assert hysteresis_percent(x, y, levels=4) == 0.0
    # coming back down along y = x + 5 opens a loop of width 5 below the hold only
    x2 = np.r_[x, np.linspace(1, 0, 11)[1:]]
    y2 = np.r_[y, np.linspace(1, 0, 11)[1:] + 5.0]
    assert hysteresis_percent(x2, y2, levels=3) == pytest.approx(100 * 5 / 6, rel=1e-12)
    assert hysteresis_percent(x2[:-5], y2[:-5], levels=3) == 0.0  # not yet below the hold


# ----------------------------------------------------------------------------- bad input


@pytest.mark.parametrize("fun", [rmse, max_error, linearity_error, tracking_metrics, hysteresis_percent])
def test_bad_records(fun):
    first = {
        rmse: "reference",
        max_error: "reference",
        tracking_metrics: "reference",
        linearity_error: "desired",
        hysteresis_percent: "input",
    }[fun]
    good = [0.0, 1.0, 2.0]
    with pytest.raises(ValueError, match=rf"{first}\[1\] = nan is not finite"):
        fun([0.0, np.nan, 2.0], good)
    with pytest.raises(ValueError, match=r"output\[2\] = inf is not finite"):
        fun(good, [0.0, 1.0, np.inf])
    with pytest.raises(ValueError, match=rf"output has 2 samples, {first} has 3; they must match"):
        fun(good, [0.0, 1.0])
    with pytest.raises(ValueError, match=rf"{first} has 0 samples"):
        fun([], [])
    with pytest.raises(ValueError, match=rf"{first} must be 1-D, got shape \(1, 3\)"):
        fun([good], good)
    with pytest.raises(TypeError, match=f"{first} must be"):
        fun("abc", good)


def test_zero_range_and_short_records():
    with pytest.raises(ValueError, match=r"reference has zero range \(every sample = 2.0\)"):
        tracking_metrics([2.0, 2.0, 2.0], [1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="desired has zero range"):
        linearity_error([1.0, 1.0], [0.0, 1.0])
    with pytest.raises(ValueError, match="output has zero range"):
        linearity_error([0.0, 1.0], [1.0, 1.0])
    with pytest.raises(ValueError, match="input has zero range"):
        hysteresis_percent([1.0, 1.0, 1.0], [0.0, 1.0, 2.0])
    with pytest.raises(ValueError, match="output has zero range"):
        hysteresis_percent([0.0, 1.0, 0.0], [1.0, 1.0, 1.0])
    with pytest.raises(ValueError, match="desired has 1 samples, at least 2 needed"):
        linearity_error([1.0], [1.0])
    with pytest.raises(ValueError, match="levels = 1 must be >= 2"):
        hysteresis_percent([0.0, 1.0], [0.0, 1.0], levels=1)
    with pytest.raises(TypeError, match="levels must be an integer"):
        hysteresis_percent([0.0, 1.0], [0.0, 1.0], levels=2.5)
