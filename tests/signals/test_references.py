"""Reference signals (docs/spec.md §6): exact values, spectra, sweeps, steps and bad input."""

import re

import numpy as np
import pytest

from piezohyst.references import chirp, multisine, sine, staircase, triangle, variable_amplitude_sine


def _time_ok(t, fs, n):
    assert t.dtype == np.float64 and t.ndim == 1 and t.size == n
    assert t[0] == 0.0
    np.testing.assert_allclose(np.diff(t), 1.0 / fs, rtol=1e-9)


# ----------------------------------------------------------------------------- sine


def test_sine_values_and_time_axis():
    t, x = sine(5.0, 2.0, 1.0, 1000.0, offset=3.0)
    _time_ok(t, 1000.0, 1000)
    assert x.dtype == np.float64 and x.shape == t.shape
    np.testing.assert_allclose(x, 3.0 + 2.0 * np.sin(2 * np.pi * 5.0 * t - np.pi / 2), atol=1e-14)
    assert x[0] == pytest.approx(1.0)  # default phase starts at the minimum
    assert x.max() == pytest.approx(5.0) and x.min() == pytest.approx(1.0)


def test_sine_at_nyquist_allowed():
    _t, x = sine(50.0, 1.0, 0.1, 100.0, phase=0.0)
    assert np.max(np.abs(x)) < 1e-12


# ----------------------------------------------------------------------------- triangle

FS, F, A, C = 10_000.0, 5.0, 2.0, 1.0  # corners fall on samples: every 1000 samples
N_PERIOD = int(FS / F)


def test_triangle_sharp_slope_peaks_period():
    t, x = triangle(F, A, 1.0, FS, offset=C)
    _time_ok(t, FS, 10_000)
    assert x[0] == pytest.approx(C - A)  # starts at the minimum like sine's default
    assert x[N_PERIOD // 2] == pytest.approx(C + A)
    assert x.max() == pytest.approx(C + A) and x.min() == pytest.approx(C - A)
    v = np.diff(x) * FS
    slope = 4 * A * F
    np.testing.assert_allclose(np.abs(v), slope, rtol=1e-9)  # straight ramps everywhere
    rising = v[: N_PERIOD // 2]
    assert np.all(rising > 0) and np.all(v[N_PERIOD // 2 : N_PERIOD] < 0)
    np.testing.assert_allclose(x[N_PERIOD:], x[:-N_PERIOD], atol=1e-12)


def test_triangle_phase_matches_sine():
    for phase in (0.0, 0.7, -2.0, 3.0):
        _t, xt = triangle(F, 1.0, 0.4, FS, phase=phase)
        _, xs = sine(F, 1.0, 0.4, FS, phase=phase)
        assert np.array_equal(np.sign(np.round(xt, 9)), np.sign(np.round(xs, 9)))
        np.testing.assert_allclose(xt, 2 / np.pi * np.arcsin(np.clip(xs, -1, 1)), atol=1e-9)


@pytest.mark.parametrize("rounding", [0.1, 0.3, 0.6, 0.9])
def test_triangle_rounded_is_smooth_and_keeps_period_and_range(rounding):
    t, x = triangle(F, A, 1.0, FS, offset=C, rounding=rounding)
    _, sharp = triangle(F, A, 1.0, FS, offset=C)
    # Peak-to-peak and extremes unchanged (corners are on samples).
    assert x.max() == pytest.approx(C + A, abs=1e-12)
    assert x.min() == pytest.approx(C - A, abs=1e-12)
    assert x[0] == pytest.approx(C - A, abs=1e-12)
    assert x[N_PERIOD // 2] == pytest.approx(C + A, abs=1e-12)
    # Period unchanged.
    np.testing.assert_allclose(x[N_PERIOD:], x[:-N_PERIOD], atol=1e-12)
    # Straight parts: documented slope s = 4 A f / (1 - r (1 - 2/pi)).
    s = 4 * A * F / (1 - rounding * (1 - 2 / np.pi))
    v = np.diff(x) * FS
    w = rounding / (2 * F)  # blend duration in seconds
    tm = (t[:-1] + t[1:]) / 2
    phase_in_half = np.mod(tm, 1 / (2 * F))
    straight = (phase_in_half > w / 2 + 2 / FS) & (phase_in_half < 1 / (2 * F) - w / 2 - 2 / FS)
    assert straight.any()
    np.testing.assert_allclose(np.abs(v[straight]), s, rtol=1e-9)
    # Continuous velocity: the second difference is bounded by the blend's peak
    # acceleration pi s / w, whereas the sharp wave jumps by 2 s / fs at every corner.
    acc = np.diff(x, 2) * FS**2
    assert np.max(np.abs(acc)) <= np.pi * s / w * 1.001
    assert np.max(np.abs(acc)) == pytest.approx(np.pi * s / w, rel=1e-3)
    assert np.max(np.abs(np.diff(v))) < 0.05 * s
    assert np.max(np.abs(np.diff(sharp, 2))) * FS == pytest.approx(2 * 4 * A * F)
    # Velocity is 0 at the turn-arounds, and the acceleration is also continuous: its
    # sample-to-sample change stays within the blend's peak jerk pi^2 s / w^2 (a jump of
    # pi s / w at the blend ends would be far larger).
    assert abs(v[N_PERIOD // 2 - 1] + v[N_PERIOD // 2]) < 1e-6 * s
    assert np.max(np.abs(np.diff(acc))) <= np.pi**2 * s / w**2 / FS * 1.01
    assert np.pi**2 * s / w**2 / FS < 0.35 * np.pi * s / w


def test_triangle_rounding_one_is_sine_and_zero_is_sharp():
    _, x1 = triangle(F, A, 0.5, FS, offset=C, rounding=1.0)
    _, xs = sine(F, A, 0.5, FS, offset=C)
    np.testing.assert_allclose(x1, xs, atol=1e-12)
    _, x0 = triangle(F, A, 0.5, FS, offset=C, rounding=0.0)
    _, xd = triangle(F, A, 0.5, FS, offset=C)
    assert np.array_equal(x0, xd)


# ----------------------------------------------------------------------------- variable amplitude


def test_variable_amplitude_sine_demo_call_and_nested_peaks():
    fs, f = 10_000.0, 10.0
    t, x = variable_amplitude_sine(f, 0.45, 0.5, fs, offset=0.5)  # as demo.py calls it
    _time_ok(t, fs, 5000)
    assert x[0] == pytest.approx(0.5)
    env = 1.0 - 0.8 * t / t[-1]
    np.testing.assert_allclose(x, 0.5 + 0.45 * env * np.sin(2 * np.pi * f * t), atol=1e-14)
    # Peaks at t = (k + 1/4)/f; every turn-around lies inside the previous one.
    k = np.arange(5)
    top = x[(250 + 1000 * k)]
    bottom = x[(750 + 1000 * k)]
    np.testing.assert_allclose(top, 0.5 + 0.45 * env[250 + 1000 * k], rtol=1e-12)
    assert np.all(np.diff(top) < 0) and np.all(np.diff(bottom) > 0)
    assert np.all(top > 0.5) and np.all(bottom < 0.5)


def test_variable_amplitude_sine_exponential_envelope():
    t, x = variable_amplitude_sine(1.0, 1.0, 4.25, 4.0, final_fraction=0.25, envelope="exponential")
    assert t[-1] == 4.0
    # Peaks at t = 0.25, 1.25, ...: envelope 0.25 ** (t / 4)
    np.testing.assert_allclose(x[[1, 5, 9, 13]], 0.25 ** (np.array([0.25, 1.25, 2.25, 3.25]) / 4), rtol=1e-12)


# ----------------------------------------------------------------------------- multisine


def test_multisine_rms_and_flat_band_limited_spectrum():
    fs, period = 1000.0, 1.0
    t, x = multisine(10.0, 50.5, 0.3, period, fs, periods=3, offset=2.0, rng=1)
    _time_ok(t, fs, 3000)
    n = 1000
    np.testing.assert_allclose(x[n:], x[:-n], atol=1e-12)  # periodic
    assert np.sqrt(np.mean((x - 2.0) ** 2)) == pytest.approx(0.3, rel=1e-12)
    assert np.mean(x) == pytest.approx(2.0, abs=1e-12)
    spec = np.abs(np.fft.rfft(x[:n] - 2.0)) / (n / 2)
    band = np.arange(10, 51)  # bins of 1 Hz in [10, 50.5]
    expected = 0.3 * np.sqrt(2 / band.size)  # flat amplitude: RMS^2 = K a^2 / 2
    np.testing.assert_allclose(spec[band], expected, rtol=1e-9)
    outside = np.ones(spec.size, bool)
    outside[band] = False
    assert np.max(spec[outside]) < 1e-12


def test_multisine_band_edges_inclusive_and_resolution_from_period():
    fs = 200.0
    _t, x = multisine(1.0, 3.0, 1.0, 4.0, fs, rng=0)  # resolution 0.25 Hz: 1.0, 1.25, ..., 3.0
    spec = np.abs(np.fft.rfft(x))
    lines = np.flatnonzero(spec > 1e-9 * spec.max())
    assert lines.tolist() == list(range(4, 13))


def test_multisine_peak_scaling():
    _, x = multisine(2.0, 40.0, 1.5, 0.5, 1000.0, scale="peak", offset=-1.0, rng=5)
    assert np.max(np.abs(x + 1.0)) == pytest.approx(1.5, rel=1e-12)


def test_multisine_rng_reproducible_and_independent():
    args = (1.0, 20.0, 1.0, 1.0, 100.0)
    _, a = multisine(*args, rng=42)
    _, b = multisine(*args, rng=42)
    _, c = multisine(*args, rng=43)
    assert np.array_equal(a, b)
    assert not np.allclose(a, c)
    _, d = multisine(*args, rng=np.random.default_rng(42))
    assert np.array_equal(a, d)
    g = np.random.default_rng(9)
    _, e1 = multisine(*args, rng=g)
    _, e2 = multisine(*args, rng=g)  # the generator is advanced
    assert not np.allclose(e1, e2)
    # The global state is neither used nor touched.
    np.random.seed(0)
    before = np.random.get_state()[1].copy()
    multisine(*args, rng=1)
    assert np.array_equal(np.random.get_state()[1], before)


# ----------------------------------------------------------------------------- chirp


def _crossing_frequencies(t, x):
    """Local frequency from consecutive zero crossings (linear interpolation)."""
    i = np.flatnonzero(np.sign(x[:-1]) * np.sign(x[1:]) < 0)
    tc = t[i] - x[i] * (t[i + 1] - t[i]) / (x[i + 1] - x[i])
    return (tc[:-1] + tc[1:]) / 2, 1.0 / (2 * np.diff(tc)), tc[:-1], tc[1:]


@pytest.mark.parametrize("method", ["linear", "logarithmic"])
@pytest.mark.parametrize("f0,f1", [(5.0, 200.0), (200.0, 5.0)])
def test_chirp_instantaneous_frequency(method, f0, f1):
    fs = 100_000.0
    t, x = chirp(f0, f1, 1.0, 1.0 + 1 / fs, fs, method=method, phase=0.0)
    T = t[-1]
    assert T == pytest.approx(1.0)
    assert x[0] == pytest.approx(0.0, abs=1e-12)
    tm, fm, ta, tb = _crossing_frequencies(t, x)
    # Between two crossings the phase advances by pi: 1 / (2 dt) is the mean of f(t) there.
    if method == "linear":
        law = f0 + (f1 - f0) * tm / T
    else:
        lam = np.log(f1 / f0) / T
        law = f0 * (np.exp(lam * tb) - np.exp(lam * ta)) / (lam * (tb - ta))
    np.testing.assert_allclose(fm, law, rtol=1e-5)
    # Start and end: extrapolate the measured frequencies to t = 0 and t = T.
    if method == "linear":
        fit = np.polyval(np.polyfit(tm, fm, 1), [0.0, T])
        np.testing.assert_allclose(fit, [f0, f1], rtol=1e-4)
    else:
        fit = np.exp(np.polyval(np.polyfit(tm, np.log(fm), 1), [0.0, T]))
        np.testing.assert_allclose(fit, [f0, f1], rtol=5e-3)
    if method == "logarithmic":  # half-way in time = geometric mean in frequency
        j = np.argmin(np.abs(tm - 0.5))
        assert fm[j] == pytest.approx(np.sqrt(f0 * f1), rel=0.02)


def test_chirp_offset_amplitude_default_phase():
    _t, x = chirp(10.0, 20.0, 2.0, 0.5, 1000.0, offset=1.0)
    assert x[0] == pytest.approx(-1.0)
    assert x.max() <= 3.0 + 1e-12 and x.min() >= -1.0 - 1e-12
    _, same = chirp(10.0, 10.0, 2.0, 0.5, 1000.0, method="logarithmic", offset=1.0)
    _, s = sine(10.0, 2.0, 0.5, 1000.0, offset=1.0)
    np.testing.assert_allclose(same, s, atol=1e-9)


# ----------------------------------------------------------------------------- staircase


def test_staircase_levels_and_dwell():
    fs = 1000.0
    levels = [0.0, 1.0, 2.0, 1.0, 0.0]
    t, x = staircase(levels, 0.25, fs, offset=0.5)
    _time_ok(t, fs, 1250)
    starts = np.r_[0, np.flatnonzero(np.diff(x)) + 1]
    assert np.diff(np.r_[starts, x.size]).tolist() == [250] * 5
    assert (x[starts] - 0.5).tolist() == levels


def test_staircase_per_level_dwell():
    _t, x = staircase([3.0, -1.0, 2.0], [0.01, 0.002, 0.0051], 1000.0)
    assert x.tolist() == [3.0] * 10 + [-1.0] * 2 + [2.0] * 5


# ----------------------------------------------------------------------------- bad input

BAD = [
    (sine, dict(freq=float("nan"), amplitude=1, duration=1, fs=100), ValueError, "freq = nan"),
    (sine, dict(freq=1, amplitude=1, duration=1, fs=0), ValueError, "fs = 0.0"),
    (sine, dict(freq=1, amplitude=1, duration=1, fs=-10.0), ValueError, "fs = -10.0"),
    (sine, dict(freq=1, amplitude=1, duration=float("inf"), fs=100), ValueError, "duration = inf"),
    (sine, dict(freq=1, amplitude=1, duration=0.01, fs=100), ValueError, "duration * fs"),
    (sine, dict(freq=60, amplitude=1, duration=1, fs=100), ValueError, "freq = 60.0 is above the Nyquist"),
    (sine, dict(freq=0, amplitude=1, duration=1, fs=100), ValueError, "freq = 0.0"),
    (sine, dict(freq=-1, amplitude=1, duration=1, fs=100), ValueError, "freq = -1.0"),
    (sine, dict(freq=1, amplitude=-1, duration=1, fs=100), ValueError, "amplitude = -1.0"),
    (sine, dict(freq="1", amplitude=1, duration=1, fs=100), TypeError, "freq"),
    (sine, dict(freq=1, amplitude=None, duration=1, fs=100), TypeError, "amplitude"),
    (triangle, dict(freq=1, amplitude=1, duration=1, fs=100, rounding=-0.1), ValueError, "rounding = -0.1"),
    (triangle, dict(freq=1, amplitude=1, duration=1, fs=100, rounding=1.5), ValueError, "rounding = 1.5"),
    (triangle, dict(freq=1, amplitude=1, duration=1, fs=100, rounding=float("nan")), ValueError, "rounding = nan"),
    (triangle, dict(freq=1, amplitude=1, duration=1, fs=100, rounding="0.2"), TypeError, "rounding"),
    (triangle, dict(freq=1, amplitude=1, duration=1, fs=100, offset=float("-inf")), ValueError, "offset = -inf"),
    (triangle, dict(freq=51, amplitude=1, duration=1, fs=100), ValueError, "freq = 51.0"),
    (
        variable_amplitude_sine,
        dict(freq=1, amplitude=1, duration=1, fs=100, final_fraction=1.5),
        ValueError,
        "final_fraction = 1.5",
    ),
    (
        variable_amplitude_sine,
        dict(freq=1, amplitude=1, duration=1, fs=100, envelope="cubic"),
        ValueError,
        "envelope = 'cubic'",
    ),
    (variable_amplitude_sine, dict(freq=1, amplitude=1, duration=1, fs=100, envelope=3), TypeError, "envelope"),
    (
        variable_amplitude_sine,
        dict(freq=1, amplitude=1, duration=1, fs=100, final_fraction=0.0, envelope="exponential"),
        ValueError,
        "final_fraction = 0.0",
    ),
    (
        multisine,
        dict(f_min=50, f_max=50, amplitude=1, period=1, fs=1000),
        ValueError,
        "f_min = 50.0 must be < f_max = 50.0",
    ),
    (multisine, dict(f_min=60, f_max=50, amplitude=1, period=1, fs=1000), ValueError, "f_min = 60.0"),
    (
        multisine,
        dict(f_min=1, f_max=600, amplitude=1, period=1, fs=1000),
        ValueError,
        "f_max = 600.0 is above the Nyquist",
    ),
    (multisine, dict(f_min=0, f_max=10, amplitude=1, period=1, fs=1000), ValueError, "f_min = 0.0"),
    (multisine, dict(f_min=10.2, f_max=10.8, amplitude=1, period=1, fs=1000), ValueError, "lengthen period"),
    (multisine, dict(f_min=1, f_max=10, amplitude=1, period=1, fs=1000, rng=1.5), TypeError, "rng"),
    (multisine, dict(f_min=1, f_max=10, amplitude=1, period=1, fs=1000, rng="a"), TypeError, "rng"),
    (multisine, dict(f_min=1, f_max=10, amplitude=1, period=1, fs=1000, rng=True), TypeError, "rng"),
    (
        multisine,
        dict(f_min=1, f_max=10, amplitude=1, period=1, fs=1000, rng=np.random.RandomState(0)),
        TypeError,
        "rng",
    ),
    (multisine, dict(f_min=1, f_max=10, amplitude=1, period=1, fs=1000, rng=-3), ValueError, "rng = -3"),
    (multisine, dict(f_min=1, f_max=10, amplitude=1, period=1, fs=1000, periods=0), ValueError, "periods = 0"),
    (multisine, dict(f_min=1, f_max=10, amplitude=1, period=1, fs=1000, periods=1.5), TypeError, "periods"),
    (multisine, dict(f_min=1, f_max=10, amplitude=1, period=1, fs=1000, scale="max"), ValueError, "scale = 'max'"),
    (multisine, dict(f_min=1, f_max=10, amplitude=1, period=0.001, fs=1000), ValueError, "period * fs"),
    (chirp, dict(f_start=1, f_end=600, amplitude=1, duration=1, fs=1000), ValueError, "f_end = 600.0"),
    (chirp, dict(f_start=0, f_end=10, amplitude=1, duration=1, fs=1000), ValueError, "f_start = 0.0"),
    (
        chirp,
        dict(f_start=1, f_end=10, amplitude=1, duration=1, fs=1000, method="quadratic"),
        ValueError,
        "method = 'quadratic'",
    ),
    (chirp, dict(f_start=1, f_end=float("nan"), amplitude=1, duration=1, fs=1000), ValueError, "f_end = nan"),
    (staircase, dict(levels=[], dwell=1, fs=10), ValueError, "levels is empty"),
    (staircase, dict(levels=[1.0, float("nan")], dwell=1, fs=10), ValueError, "levels[1] = nan"),
    (staircase, dict(levels=[[1.0, 2.0]], dwell=1, fs=10), ValueError, "levels must be 1-D"),
    (staircase, dict(levels="abc", dwell=1, fs=10), TypeError, "levels"),
    (staircase, dict(levels=[1, 2], dwell=0, fs=10), ValueError, "dwell = 0.0"),
    (staircase, dict(levels=[1, 2], dwell=[1, -1], fs=10), ValueError, "dwell[1] = -1.0"),
    (staircase, dict(levels=[1, 2], dwell=[1, 1, 1], fs=10), ValueError, "dwell has length 3"),
    (staircase, dict(levels=[1, 2], dwell=[1, 0.01], fs=10), ValueError, "dwell[1] = 0.01"),
    (staircase, dict(levels=[1], dwell=0.1, fs=10), ValueError, "at least 2"),
    (staircase, dict(levels=[1, 2], dwell=1, fs=float("inf")), ValueError, "fs = inf"),
    (staircase, dict(levels=[1, 2], dwell=None, fs=10), TypeError, "dwell"),
]


@pytest.mark.parametrize("fn,kwargs,exc,msg", BAD, ids=[f"{b[0].__name__}-{b[3]}" for b in BAD])
def test_bad_input(fn, kwargs, exc, msg):
    with pytest.raises(exc, match=re.escape(msg)):
        fn(**kwargs)
