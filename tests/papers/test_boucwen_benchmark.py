"""Bouc–Wen hysteretic benchmark (docs/spec.md §3.3): reproduction of the official training record,
periodic steady state, the integrator against an adaptive high-order reference, the
MATLAB-style decimation against a literal transcription of MATLAB's algorithm, bad input."""

from pathlib import Path

import numpy as np
import pytest
from scipy import signal
from scipy.integrate import solve_ivp

from piezohyst import _core
from piezohyst.boucwen_benchmark import BoucWenBenchmark, decimate, load_train_multisine, upsample

DATA = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "boucwen" / "train_multisine.csv"
N = 8192  # samples per period of the training multisine
NOISE = 8e-6  # m, output noise of the record (docs/spec.md §3.3)


def rms(x):
    return float(np.sqrt(np.mean(np.square(x))))


@pytest.fixture(scope="module")
def record():
    if not DATA.exists():
        pytest.skip(f"training record not found at {DATA}")
    return load_train_multisine(DATA)


@pytest.fixture(scope="module")
def simulated(record):
    u, _, fs = record
    return BoucWenBenchmark().simulate(u, fs=fs)


# --- the training record -------------------------------------------------------------


def test_loader(record):
    u, y, fs = record
    assert fs == 750.0
    assert u.shape == y.shape == (5 * N,)
    assert u.dtype == y.dtype == np.float64
    assert 49.9 < u.std() < 50.1
    np.testing.assert_array_equal(u[N:], u[:-N])  # 5 identical periods


def test_input_is_the_subsampled_high_rate_multisine(record):
    """The generator builds the multisine at 15 kHz with lines 54..1639 x 750/8192 Hz
    (5-150 Hz) and keeps every 20th sample: the record's spectrum has exactly those
    lines, so periodic band-limited interpolation recovers the integrated input."""
    u = record[0]
    mag = np.abs(np.fft.rfft(u[:N]))
    lines = np.flatnonzero(mag > 1e-9 * mag.max())
    np.testing.assert_array_equal(lines, np.arange(54, 1640))


def test_true_model_reproduces_training_output(record, simulated):
    _, y, _ = record
    err = simulated - y
    assert rms(err) <= 1e-5
    assert rms(err) <= 1.0 * NOISE  # reached: 7.37e-6 m
    per_period = [rms(e) for e in err.reshape(5, N)]
    assert max(per_period) <= 1e-5, per_period


def test_residual_is_noise_only(record, simulated):
    """After the first period the response is periodic, so a model error repeats from
    period to period while the noise does not: the period-averaged residual of periods
    2-5 must have the RMS of averaged noise (sigma / 2). Observed ratio 0.99; a
    systematic error of 1.6e-6 m RMS would push it to 1.09."""
    _, y, _ = record
    err = (simulated - y).reshape(5, N)[1:]
    mean = err.mean(axis=0)
    sigma = rms(err - mean) * np.sqrt(4 / 3)  # unbiased per-sample noise estimate
    assert rms(mean) <= 1.08 * sigma / 2
    corr = np.corrcoef(err)
    assert np.abs(corr[np.triu_indices(4, 1)]).max() < 0.05


def test_upsampling_choice(record, simulated):
    """Band-limited (FFT) upsampling is the generator's; linear interpolation and a
    zero-order hold miss the record by 1.04e-5 m and 1.03e-4 m."""
    u, y, fs = record
    bw = BoucWenBenchmark()
    e_fft = rms(simulated - y)
    e_lin = rms(bw.simulate(u, fs=fs, interpolation="linear") - y)
    e_zoh = rms(bw.simulate(u, fs=fs, interpolation="zoh") - y)
    assert e_fft < 0.75 * e_lin < 0.1 * e_zoh


def test_extra_period_as_the_official_script(record, simulated):
    """The official script simulates one period more and drops it; without it only the
    last few samples feel the decimation filter's end reflection, by far below noise."""
    u, _, fs = record
    longer = BoucWenBenchmark().simulate(np.concatenate([u, u[:N]]), fs=fs)[: 5 * N]
    diff = np.abs(longer - simulated)
    assert diff[:-8].max() < 1e-12
    assert diff.max() < 1e-6


def test_periodic_steady_state(simulated):
    """After the first period the simulated output repeats (measured: to 4e-18 m). The
    last 8 samples (the decimation filters' reach, about 5 samples at 750 Hz) see the
    end-of-record reflection and are left out."""
    p = simulated.reshape(5, N)
    scale = np.abs(simulated).max()
    assert np.abs(p[1] - p[0]).max() > 1e-3 * scale  # the first period holds the transient
    for k in (1, 2):
        np.testing.assert_allclose(p[k + 1], p[k], rtol=0, atol=1e-12)
    np.testing.assert_allclose(p[4][:-8], p[3][:-8], rtol=0, atol=1e-12)


# --- the integrator ---------------------------------------------------------------


AMPS, FREQS, PHASES = (40.0, 25.0, 10.0), (7.0, 31.0, 97.0), (0.0, 0.3, 1.0)


def smooth_force(t):
    return sum(a * np.sin(2 * np.pi * f * t + p) for a, f, p in zip(AMPS, FREQS, PHASES, strict=False))


@pytest.fixture(scope="module")
def reference():
    """The continuous system (its own right-hand side, written out here) integrated by
    DOP853 at rtol 1e-10 (a 1e-12 run agrees with it to 1e-12 m on this grid)."""
    p = BoucWenBenchmark()

    def rhs(t, x):
        y, v, z = x
        u = smooth_force(t)
        dz = p.alpha * v - p.beta * (p.gamma * abs(v) * z + p.delta * v * abs(z))
        return [v, (u - p.damping * v - p.stiffness * y - z) / p.mass, dz]

    return solve_ivp(
        rhs, (0.0, 1.0), [0.0, 0.0, 0.0], method="DOP853", rtol=1e-10, atol=[1e-15, 1e-12, 1e-9], dense_output=True
    )


def test_integrator_against_solve_ivp(reference):
    """Newmark (average acceleration) + trapezoidal z is second order; its leading error
    is the period elongation (w h)^2 / 12, at most 1.4e-4 relative for the fastest
    component here (97 Hz, w h = 0.041 at 15 kHz), i.e. about 2e-7 m of the 1.35e-3 m
    response. Measured: 9.6e-8 m at 15 kHz, 4.0e-7 m at 7.5 kHz (ratio 4.1)."""
    bw = BoucWenBenchmark()
    errors = {}
    for fs in (7500.0, 15000.0):
        t = np.arange(round(fs) + 1) / fs
        y, z = bw.integrate(smooth_force(t), 1.0 / fs, return_z=True)
        ref = reference.sol(t)
        errors[fs] = np.abs(y - ref[0]).max()
        scale = np.abs(ref[0]).max()
        assert errors[fs] <= (2 * np.pi * 97.0 / fs) ** 2 / 12 * scale * 1.2
        assert np.abs(z - ref[2]).max() <= (2 * np.pi * 97.0 / fs) ** 2 / 12 * np.abs(ref[2]).max() * 1.2
    assert errors[15000.0] < 2e-7
    assert 3.5 < errors[7500.0] / errors[15000.0] < 4.6  # second order


def test_integrate_continues_from_state():
    """The core's state [y, y', y'', z] carries a run over from one call to the next."""
    bw = BoucWenBenchmark()
    u = smooth_force(np.arange(3001) / 15000.0)
    y_all, z_all = _core.boucwen_benchmark_integrate(bw.params(), u[1:], 1 / 15000, bw.initial_state(None, u[0]))
    state = bw.initial_state(None, u[0])
    y1, _ = _core.boucwen_benchmark_integrate(bw.params(), u[1:1001], 1 / 15000, state)
    y2, z2 = _core.boucwen_benchmark_integrate(bw.params(), u[1001:], 1 / 15000, state)
    np.testing.assert_array_equal(np.concatenate([y1, y2]), y_all)
    np.testing.assert_array_equal(z2, z_all[1000:])
    assert state[0] == y_all[-1] and state[3] == z_all[-1]


def test_initial_state_and_upsample_one():
    bw = BoucWenBenchmark()
    u = smooth_force(np.arange(500) / 750.0)
    y, z = bw.simulate(u, upsample=1, initial_state=(1e-4, 0.0, 2.0), return_z=True)
    assert y[0] == 1e-4 and z[0] == 2.0
    np.testing.assert_array_equal(y, bw.integrate(u, 1 / 750.0, initial_state=(1e-4, 0.0, 2.0)))


# --- resampling -----------------------------------------------------------------


def matlab_decimate_fir(x, r):
    """MATLAB decimate(x, r, 'fir') transcribed literally (1-based indices in comments):
    b = fir1(30, 1/r); prepend 2*x(1) - x(32:-1:2), filter; append
    2*x(nd) - x(nd-1:-1:nd-62), filter on; keep list = 16:r:nd, then the tail."""
    b = signal.firwin(31, 1.0 / r)  # = fir1(30, 1/r) (Hamming, unit DC gain)
    nd, nfilt = x.size, 31
    nout = -(-nd // r)
    head = 2 * x[0] - x[nfilt:0:-1]
    _, zi = signal.lfilter(b, 1.0, head, zi=np.zeros(30))
    body, zf = signal.lfilter(b, 1.0, x, zi=zi)
    tail = 2 * x[-1] - x[nd - 2 : nd - 2 - 2 * nfilt : -1]
    tail, _ = signal.lfilter(b, 1.0, tail, zi=zf)
    lst = np.arange(16, nd + 1, r)  # round(grpdelay + 1.25) = 16
    out = body[lst - 1]
    nbeg = r - (nd - lst[-1])
    return np.concatenate([out, tail[nbeg - 1 : nbeg - 1 + (nout - out.size) * r : r]])


@pytest.mark.parametrize("r", [2, 3, 5])
@pytest.mark.parametrize("n", [100, 101, 997])
def test_decimate_is_matlabs(r, n, rng):
    x = np.cumsum(rng.normal(size=n))
    np.testing.assert_allclose(decimate(x, r), matlab_decimate_fir(x, r), rtol=0, atol=1e-12 * np.abs(x).max())


def test_decimate_cascade_over_prime_factors(rng):
    x = np.cumsum(rng.normal(size=2000))
    ref = matlab_decimate_fir(matlab_decimate_fir(matlab_decimate_fir(x, 2), 2), 5)
    np.testing.assert_allclose(decimate(x, 20), ref, rtol=0, atol=1e-12 * np.abs(x).max())
    np.testing.assert_array_equal(decimate(x, 1), x)


def test_upsample_methods(rng):
    n, r = 64, 20
    k = np.arange(1, 20)
    lines = np.zeros(n // 2 + 1, complex)
    lines[k] = np.exp(2j * np.pi * rng.random(k.size))
    fine_true = np.fft.irfft(lines, n * r) * r  # the band-limited signal at the high rate
    coarse = fine_true[::r]
    np.testing.assert_allclose(upsample(coarse, r), fine_true, atol=1e-12)
    for method in ("fft", "linear", "zoh"):
        fine = upsample(coarse, r, method)
        assert fine.size == n * r
        np.testing.assert_allclose(fine[::r], coarse, atol=1e-12)
    np.testing.assert_array_equal(upsample(coarse, r, "zoh")[3::r], coarse)
    np.testing.assert_array_equal(upsample(coarse, 1), coarse)
    odd = np.sin(2 * np.pi * 3 * np.arange(15) / 15)  # odd length: no Nyquist line
    np.testing.assert_allclose(upsample(odd, 4), np.sin(2 * np.pi * 3 * np.arange(60) / 60), atol=1e-12)


# --- bad input -------------------------------------------------------------------


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"mass": 0.0}, "mass = 0.0 must be > 0"),
        ({"mass": -2.0}, "mass = -2.0 must be > 0"),
        ({"damping": -1.0}, "damping = -1.0 must be >= 0"),
        ({"stiffness": -5.0}, "stiffness = -5.0 must be >= 0"),
        ({"alpha": -1.0}, "alpha = -1.0 must be >= 0"),
        ({"beta": -1.0}, "beta = -1.0 must be >= 0"),
        ({"gamma": float("nan")}, "gamma = nan is not finite"),
        ({"delta": float("inf")}, "delta = inf is not finite"),
        ({"nu": 0.5}, "nu = 0.5 must be >= 1"),
    ],
)
def test_bad_parameters(kwargs, message):
    with pytest.raises(ValueError, match=message.replace("(", r"\(")):
        BoucWenBenchmark(**kwargs)


@pytest.mark.parametrize(
    "u, kwargs, message",
    [
        ([1.0, np.nan, 2.0], {}, r"u\[1\] = nan is not finite"),
        ([1.0, 2.0, np.inf], {}, r"u\[2\] = inf is not finite"),
        ([], {}, "u has 0 samples"),
        ([1.0, 2.0], {"fs": 0.0}, "fs = 0.0 must be > 0"),
        ([1.0, 2.0], {"fs": -750.0}, "fs = -750.0 must be > 0"),
        ([1.0, 2.0], {"fs": np.nan}, "fs = nan is not finite"),
        ([1.0, 2.0], {"upsample": 0}, "upsample = 0 must be >= 1"),
        ([1.0, 2.0], {"upsample": -20}, "upsample = -20 must be >= 1"),
        ([1.0, 2.0], {"interpolation": "cubic"}, "interpolation = 'cubic' is unknown"),
        ([1.0, 2.0], {"initial_state": (0.0, 0.0)}, "initial_state has length 2, expected 3"),
        ([1.0, 2.0], {"initial_state": (0.0, np.nan, 0.0)}, r"initial_state\[1\] = nan is not finite"),
    ],
)
def test_bad_simulate_input(u, kwargs, message):
    with pytest.raises(ValueError, match=message):
        BoucWenBenchmark().simulate(u, **kwargs)


def test_bad_integrate_and_core_input():
    bw = BoucWenBenchmark()
    with pytest.raises(ValueError, match="h = 0.0 must be > 0"):
        bw.integrate([0.0, 1.0], 0.0)
    with pytest.raises(ValueError, match=r"u\[0\] = nan is not finite"):
        bw.integrate([np.nan, 1.0], 1e-4)
    params = bw.params()
    with pytest.raises(ValueError, match="mass = -1 must be > 0"):
        _core.boucwen_benchmark_integrate(np.array([-1.0, *params[1:]]), np.zeros(3), 1e-4, np.zeros(4))
    with pytest.raises(ValueError, match="params has length 3, expected 8"):
        _core.boucwen_benchmark_integrate(params[:3], np.zeros(3), 1e-4, np.zeros(4))
    with pytest.raises(ValueError, match="h = -0.001 must be > 0"):
        _core.boucwen_benchmark_integrate(params, np.zeros(3), -1e-3, np.zeros(4))
    with pytest.raises(ValueError, match="state has length 3, expected 4"):
        _core.boucwen_benchmark_integrate(params, np.zeros(3), 1e-4, np.zeros(3))
    with pytest.raises(ValueError, match=r"(?i)input\[1\] = inf is not finite"):
        _core.boucwen_benchmark_integrate(params, np.array([0.0, np.inf]), 1e-4, np.zeros(4))
    with pytest.raises(ValueError, match="factor = 0 must be >= 1"):
        decimate(np.zeros(10), 0)
    with pytest.raises(ValueError, match="factor = 0 must be >= 1"):
        _core.boucwen_benchmark_decimate(np.zeros(10), 0)
    with pytest.raises(ValueError, match=r"(?i)x\[2\] = nan is not finite"):
        _core.boucwen_benchmark_decimate(np.array([0.0, 1.0, np.nan]), 2)


def test_unresolvable_input_is_reported():
    """An absurd force (1e100 N) makes the implicit step's equation non-monotone at
    15 kHz: the simulation must stop with a ValueError, not return inf/NaN."""
    u = 1e100 * np.sin(2 * np.pi * 5 * np.arange(100) / 750.0)
    with pytest.raises(ValueError, match="could not be solved|diverged"):
        BoucWenBenchmark().simulate(u)


def test_loader_rejects_other_files(tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("x,y\n1,2\n")
    with pytest.raises(ValueError, match="header = 'x,y', expected 'u,y'"):
        load_train_multisine(bad)
    bad.write_text("u,y\n1,nan\n")
    with pytest.raises(ValueError, match=r"y\[0\] = nan is not finite"):
        load_train_multisine(bad)
