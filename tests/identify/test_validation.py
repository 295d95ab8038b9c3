"""Honest validation (state carried, warm-up, periodic steady state), residual whiteness, the
minimax and weighted fits, and the diagnosis of untrustworthy fits on records generated to
carry each defect."""

import numpy as np
import pytest

import piezohyst as ph
from piezohyst.errors import ParameterError
from piezohyst.identify.validation import estimate_period, residual_whiteness


def decaying(n, seed=0, cycles=12.0, noise=0.0):
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 2 * np.pi * cycles, n)
    v = 0.5 + 0.45 * np.sin(t) * np.linspace(1, 0.3, n)
    return v + rng.normal(0, noise, n) if noise else v


def causes(res):
    return [c["cause"] for c in res.assessment.get("diagnosis", [])]


# ---------------------------------------------------------------------------------------------
# state carried


def test_carried_validation_scores_the_validation_span_of_one_simulation():
    truth = ph.PI([0.05, 0.15, 0.3], [0.4, 0.2, 0.1], p0=0.7, creep=ph.Creep(1e-3, [0.2, 2.0], [0.08, 0.05]))
    v = decaying(6000, cycles=20)
    y = truth.simulate(v) + np.random.default_rng(1).normal(0, 1e-3, v.size)
    a, b, c, d = 0, 3000, 3400, 6000
    res = ph.identify(v[a:b], y[a:b], "pi", fs=1000, creep=2, validate=(v[c:d], y[c:d]), gap=v[b:c])
    assert res.assessment["validate_from"] == "carried" and res.assessment["gap"] == c - b
    # the reported figure is the model run from the training start, scored on the validation span
    full = res.model.simulate(v[a:d])
    assert ph.fit_metrics(full[c - a :], y[c:d]) == pytest.approx(res.validation, rel=1e-12)
    rest = ph.identify(v[a:b], y[a:b], "pi", fs=1000, creep=2, validate=(v[c:d], y[c:d]), validate_from="rest")
    assert ph.fit_metrics(res.model.simulate(v[c:d]), y[c:d]) == pytest.approx(rest.validation, rel=1e-12)
    # the creep state left by the training span is what the validation starts from
    assert res.validation["rmse_percent"] < 0.5 * rest.validation["rmse_percent"]


def test_warmup_and_periodic_state():
    period = 250
    v = 0.5 + 0.4 * np.sin(2 * np.pi * np.arange(2000) / period)
    truth = ph.PI(default_thresholds(v, 3), [0.4, 0.2, 0.1], p0=0.7)
    y = truth.simulate(np.concatenate([v[:period], v]))[period:]  # the periodic steady state
    assert estimate_period(v) == period
    plain = ph.identify(v[:1000], y[:1000], "pi", operators=3, validate=(v[1000:], y[1000:]), validate_from="rest")
    periodic = ph.identify(
        v[:1000], y[:1000], "pi", operators=3, validate=(v[1000:], y[1000:]), validate_from="rest", periodic="auto"
    )
    assert periodic.assessment["periodic"] == period
    sim = periodic.model.simulate(np.concatenate([v[1000 : 1000 + period], v[1000:]]))[period:]
    assert periodic.validation == pytest.approx(ph.fit_metrics(sim, y[1000:]), rel=1e-12)
    # from rest the first quarter period is off the steady-state loop; one period first removes that
    assert periodic.validation["max_error"] < 0.5 * plain.validation["max_error"]
    warm = ph.identify(
        v[:1000], y[:1000], "pi", operators=3, validate=(v[1000:], y[1000:]), validate_from="rest", warmup=period
    )
    sim = warm.model.simulate(v[1000:])
    assert warm.validation == pytest.approx(ph.fit_metrics(sim[period:], y[1000 + period :]), rel=1e-12)
    with pytest.raises(ParameterError, match="warmup = 999"):
        ph.identify(v[:1000], y[:1000], "pi", warmup=999)
    with pytest.raises(ParameterError, match="validate_from = 'later'"):
        ph.identify(v[:1000], y[:1000], "pi", validate_from="later")
    with pytest.raises(ParameterError, match="not periodic|does not repeat"):
        estimate_period(np.linspace(0, 1, 500) ** 2)


def test_residual_whiteness_tells_white_noise_from_structure_and_finds_the_lag():
    rng = np.random.default_rng(3)
    n = 4000
    e = rng.normal(size=n)
    u = rng.normal(size=n)
    w = residual_whiteness(e, u)
    assert w["autocorrelation_outside"] < 0.15 and w["ljung_box_p"] > 0.001
    smooth = np.convolve(e, np.ones(20) / 20, mode="same")
    s = residual_whiteness(smooth, u)
    assert s["autocorrelation_outside"] > 0.3 and s["ljung_box_p"] < 1e-6
    lagged = np.concatenate([np.zeros(7), u[:-7]]) + 0.1 * e  # the residual follows the input 7 samples late
    assert residual_whiteness(lagged, u)["cross_peak_lag"] == 7


# ---------------------------------------------------------------------------------------------
# minimax and weighted fits


def test_linf_minimizes_the_largest_error_and_weights_ignore_a_corrupted_stretch():
    truth = ph.PI([0.05, 0.15, 0.3], [0.4, 0.2, 0.1], p0=0.7)
    v = decaying(3000)
    rng = np.random.default_rng(0)
    y = truth.simulate(v) + rng.uniform(-0.01, 0.01, v.size)
    y[::300] += 0.05  # a few glitches: least squares spreads them, minimax bounds them
    l2 = ph.identify(v, y, "pi", operators=3)
    linf = ph.identify(v, y, "pi", operators=3, loss="linf")
    assert linf.method == "ls+linf"
    assert linf.train["max_error"] < l2.train["max_error"] - 1e-3
    # on the LP optimum the largest error is met at several samples (equioscillation)
    r = np.abs(linf.model.simulate(v) - y)
    assert np.sum(r > r.max() * (1 - 1e-6)) >= 2

    truth = ph.PI(default_thresholds(v, 3), [0.4, 0.2, 0.1], p0=0.7)
    y2 = truth.simulate(v)
    y2[1000:1200] += 0.3  # a stretch the sensor got wrong
    weights = np.ones(v.size)
    weights[1000:1200] = 0.0
    fit = ph.identify(v, y2, "pi", operators=3, weights=weights)
    np.testing.assert_allclose(fit.model.weights, truth.weights, atol=1e-9)
    with pytest.raises(ParameterError, match="weights"):
        ph.identify(v, y2, "pi", weights=-weights)
    with pytest.raises(ParameterError, match="weights has 10 samples"):
        ph.identify(v, y2, "pi", weights=np.ones(10))


# ---------------------------------------------------------------------------------------------
# say when not to trust it: each defect named


def default_thresholds(v, n):
    return np.arange(1, n + 1) * np.ptp(v) / (2 * (n + 1))  # identify's default structure


def mpi_record(n=4000, seed=0):
    v = decaying(n, seed=seed, cycles=16)
    truth = ph.PI(default_thresholds(v[: n // 2], 9), np.linspace(0.3, 0.02, 9), p0=0.6)
    rng = np.random.default_rng(seed)
    return v, truth.simulate(v) + rng.normal(0, 2e-4, n)


def test_a_clean_record_is_trusted():
    v, y = mpi_record()
    res = ph.identify(v[:2000], y[:2000], "mpi", validate=(v[2000:], y[2000:]), validate_from="carried")
    assert res.assessment["trusted"] and res.validation["rmse_percent"] < 0.2
    assert "diagnosis" not in res.assessment


def test_an_offset_in_the_validation_span_is_named():
    v, y = mpi_record()
    y = y.copy()
    y[2000:] += 0.15 * np.ptp(y)  # the sensor re-zeroed between the spans
    res = ph.identify(v[:2000], y[:2000], "mpi", validate=(v[2000:], y[2000:]), validate_from="carried")
    assert not res.assessment["trusted"]
    assert causes(res)[0] == "offset"


def test_drift_is_named():
    v, y = mpi_record()
    y = y + np.linspace(0, 0.4 * np.ptp(y), y.size)
    res = ph.identify(v[:2000], y[:2000], "mpi", validate=(v[2000:], y[2000:]), validate_from="carried")
    assert not res.assessment["trusted"] and "drift" in causes(res)


def test_a_delay_is_named_with_its_lag():
    d = 40
    v0, y0 = mpi_record()
    v, y = v0[d:], y0[:-d]  # the output d samples late relative to the input
    res = ph.identify(v[:2000], y[:2000], "mpi", validate=(v[2000:], y[2000:]), validate_from="carried")
    assert not res.assessment["trusted"]
    found = [c for c in res.assessment["diagnosis"] if c["cause"] == "delay"]
    assert found and abs(found[0]["lag"] - d) <= 0.25 * d


def test_swapped_columns_are_named():
    v, y = mpi_record()
    res = ph.identify(y[:2000], v[:2000], "pi", validate=(y[2000:], v[2000:]), validate_from="carried")
    assert not res.assessment["trusted"] and "swapped columns" in causes(res)


def test_a_time_column_in_ms_read_as_s_is_named():
    fs = 1000.0
    truth = ph.GeneralizedPI(
        [0.05, 0.15],
        [0.4, 0.2],
        (0.0, 0.6, 0.0, 0.0),
        input_range=(-1.0, 2.0),
        creep=ph.Creep(1 / fs, [0.05, 0.5], [0.3, 0.2]),
    )
    n = 6000
    rng = np.random.default_rng(0)
    steps = np.repeat(rng.uniform(0.1, 0.9, n // 300), 300)  # staircase: creep shows after each step
    y = truth.simulate(steps) + rng.normal(0, 1e-4, n)
    # identified with fs = 1 Hz (timestamps in ms taken for seconds), the creep-free mpi fails
    res = ph.identify(
        steps[:3000], y[:3000], "mpi", fs=fs / 1000, validate=(steps[3000:], y[3000:]), validate_from="carried"
    )
    assert not res.assessment["trusted"] and "sample rate" in causes(res)
