"""Issue 14 item 7: the rate-dependent PI with its structure fitted (``--structure fit``) on
realistic 5 kHz records: a +-150 V drive (rates up to 1e5 V/s, one-sample steps 1e6 V/s), a
quiet lead-in with a noisy voltage monitor, an output offset, 0.2 % noise; rate-dependent
hysteresis from three generators (a rate-dependent PI of another structure, a PI behind a
700 Hz stage resonance, a Bouc-Wen behind a 400 Hz one). Held out with the state carried,
it is never more than 1.5 times the best fixed-structure family, and where the record's
rate barely varies (one frequency) it does not extrapolate to another rate with negative
play weights: the rate weights are fitted as the weights at rate 0 and at 4 times the
record's largest rate, both non-negative (identify.core._rate_interpolation)."""

import numpy as np
import pytest
from scipy import signal

from piezohyst import identify
from piezohyst.identify import core
from piezohyst.models import PI, BoucWen, RateDependentPI

FS = 5000.0
TS = 1 / FS


def drive(kind, seed, n=10_000):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS
    if kind == "chirp":
        v = 150 * signal.chirp(t, 1.0, t[-1], rng.uniform(60, 100), method="logarithmic")
    elif kind == "triangle":
        v = 150 * signal.sawtooth(2 * np.pi * rng.uniform(5, 30) * t, 0.5)
    else:
        f = np.sort(rng.uniform([2, 10, 40], [5, 25, 80]))
        s = sum(a * np.sin(2 * np.pi * fi * t + rng.uniform(0, 6)) for a, fi in zip([1.0, 0.45, 0.2], f, strict=True))
        v = 150 * s / np.max(np.abs(s))
    v[: n // 10] = 0.0  # the lead-in
    return v + 0.05 * rng.standard_normal(n)  # the voltage monitor's noise


def stage(kind, v, seed):
    rng = np.random.default_rng(50 + seed)
    if kind == "rdpi":
        r = np.linspace(5, 120, 7) * rng.uniform(0.8, 1.2)
        w = 0.02 * np.exp(-r / 60)
        return RateDependentPI(r, w, TS, 0.06, rng.uniform(2e-4, 6e-4), w * 2e-5, 4 * TS).simulate(v)
    f0 = 700.0 if kind == "pi+resonance" else 400.0
    y = (
        PI(np.linspace(5, 120, 9), 0.015 * np.exp(-np.linspace(5, 120, 9) / 50), 0.06).simulate(v)
        if kind == "pi+resonance"
        else BoucWen(a=0.015, beta=0.02, gamma=0.005, d=0.08).simulate(v)
    )
    w0 = 2 * np.pi * f0
    b, a = signal.bilinear([w0**2], [1, 0.4 * w0, w0**2], FS)
    return signal.lfilter(b, a, y)


def record(kind, shape, seed):
    v = drive(shape, seed)
    y = stage(kind, v, seed) + 3.0  # um, with the sensor's offset
    return v, y + 2e-3 * np.ptp(y) * np.random.default_rng(9 + seed).standard_normal(v.size)


def held_out(v, y, model, **kw):
    k = int(0.6 * v.size)
    return identify(v[:k], y[:k], model, fs=FS, validate=(v[k:], y[k:]), gap=v[k:k], **kw)


@pytest.mark.parametrize(
    ("kind", "shape", "measured"),
    [("rdpi", "chirp", 0.877), ("pi+resonance", "triangle", 0.266), ("boucwen+resonance", "multisine", 0.415)],
)
def test_structure_fit_is_within_reach_of_the_best_family(kind, shape, measured):
    v, y = record(kind, shape, 0)
    best = min(held_out(v, y, m).validation["rmse_percent"] for m in ("pi", "mpi", "preisach", "rdpi"))
    fit = held_out(v, y, "rdpi", structure="fit", rng=0)
    val = fit.validation["rmse_percent"]
    assert val <= 1.5 * best
    assert val == pytest.approx(measured, abs=0.01)
    # the conditioning is reported: the equilibrated regressors of the final fit (measured
    # 7e2-2e3; 1e5 on the triangle, whose constant |rate| makes z_i and z_i rate collinear)
    assert 1.0 < fit.history["condition"] < 1e6


@pytest.mark.parametrize(("seed", "measured"), [(0, 1.494), (1, 0.980), (2, 0.909)])
def test_one_rate_trained_another_held_out(seed, measured):
    # a 10 Hz sine trained, 30 Hz held out: with free rate weights the search traded the play
    # weights against them (held out 2.40, 1.97, 2.07 %, above the fixed structure's 1.91,
    # 2.01, 1.92 %); now below it
    rng = np.random.default_rng(seed)
    t = np.arange(7500) / FS
    v = np.concatenate([np.zeros(1500), 150 * np.sin(2 * np.pi * 10 * t), 150 * np.sin(2 * np.pi * 30 * t)])
    v = v + 0.05 * rng.standard_normal(v.size)
    y = stage("rdpi", v, 0) + 7.0
    y = y + 2e-3 * np.ptp(y) * rng.standard_normal(v.size)
    k = 9000
    fixed = identify(v[:k], y[:k], "rdpi", fs=FS, validate=(v[k:], y[k:]), gap=v[k:k])
    fit = identify(v[:k], y[:k], "rdpi", fs=FS, structure="fit", rng=0, validate=(v[k:], y[k:]), gap=v[k:k])
    assert fit.validation["rmse_percent"] == pytest.approx(measured, abs=0.01)
    assert fit.validation["rmse_percent"] < fixed.validation["rmse_percent"]
    m = fit.model
    # every play weight w_i + c_i rate is non-negative up to 4 times the training's fastest
    # (filtered) rate: rate(k) = rate(k-1) + a (|v(k) - v(k-1)| / ts - rate(k-1))
    a = 1 - np.exp(-TS / m.filter_tau) if m.filter_tau > 0 else 1.0
    rate = signal.lfilter([a], [1, a - 1], np.r_[0.0, np.abs(np.diff(v[:k])) / TS])
    top = core.RATE_MARGIN * rate.max()
    assert np.all(m.weights >= 0)
    assert np.all(m.weights + m.rate_weights * top >= -1e-9 * m.weights.max())


def test_units_and_offsets_do_not_change_the_fit():
    # the output in um, in m with an offset, in nm with another: the same % to rounding
    v, y = record("rdpi", "multisine", 1)
    ref = held_out(v, y, "rdpi")
    for gain, offset in ((1e-6, 5e-5), (1e3, 8e4)):
        res = held_out(v, gain * y + offset, "rdpi")
        assert res.validation["rmse_percent"] == pytest.approx(ref.validation["rmse_percent"], rel=1e-6)
        assert res.train["rmse_percent"] == pytest.approx(ref.train["rmse_percent"], rel=1e-6)
