"""Least squares over the linear parameters: exact recovery on simulated data, and a real
record fitted to the accuracy it supports."""

from pathlib import Path

import numpy as np
import pytest

import piezohyst as ph
from piezohyst import _core

SHARED = Path(__file__).resolve().parents[2].parent / "shared" / "data"


def drive(n=3000, seed=0):
    rng = np.random.default_rng(seed)
    return np.clip(0.5 + 0.45 * np.sin(np.linspace(0, 25, n)) * np.linspace(1, 0.2, n) + rng.normal(0, 0.01, n), 0, 1)


@pytest.mark.parametrize(
    "model",
    [
        ph.papers.mpi_seed2(),
        ph.PI([0.05, 0.15, 0.3], [0.4, 0.2, 0.1], p0=0.7),
        ph.PI([0.05, 0.15], [0.4, 0.2], p0=0.7, creep=ph.Creep(1e-3, [0.01, 0.1], [0.05, 0.03])),
        ph.RateDependentPI([0.05, 0.2], [0.4, 0.2], ts=1e-3, p0=0.6, beta=1e-4, rate_weights=[1e-3, -5e-4]),
        ph.Preisach(5, (0.0, 1.0), np.linspace(0.05, 1.0, 15), offset=0.1, slope=0.3),
    ],
    ids=["mpi", "pi", "pi+creep", "rdpi", "preisach"],
)
def test_regressors_reproduce_the_output_and_least_squares_recovers_the_parameters(model):
    v = drive()
    y = model.simulate(v)
    A = _core.regressors(model.family, list(model.dims), model.to_row(), v)
    assert A.shape[0] == v.size and np.linalg.matrix_rank(A) == A.shape[1]
    fit = ph.fit_linear(model, v, y)
    assert fit.metrics["rmse_percent"] < 1e-8
    np.testing.assert_allclose(fit.model.simulate(v), y, rtol=0, atol=1e-10)


def test_weights_are_recovered_exactly_when_the_structure_is_right():
    truth = ph.papers.mpi_seed2()
    v = drive()
    template = ph.GeneralizedPI(truth.thresholds, np.zeros(9), (0, 0, 0, 0), input_range=(0, 1))
    fit = ph.fit_linear(template, v, truth.simulate(v))
    np.testing.assert_allclose(fit.model.weights, truth.weights, atol=1e-9)
    np.testing.assert_allclose(fit.model.polynomial, truth.polynomial, atol=1e-9)


def test_play_weights_stay_non_negative_under_noise():
    truth = ph.PI([0.05, 0.15, 0.3], [0.4, 0.0, 0.1], p0=0.7)
    v = drive()
    y = truth.simulate(v) + np.random.default_rng(1).normal(0, 0.01, v.size)
    fit = ph.fit_linear(ph.PI(truth.thresholds, np.ones(3), 1.0), v, y)
    assert np.all(fit.model.weights >= 0) and fit.model.p0 >= 0
    assert fit.metrics["rmse"] < 0.0105  # the noise level, not more


def test_bad_input():
    with pytest.raises(TypeError, match="model must be"):
        ph.fit_linear(ph.BoucWen(1, 1, 0), [0.0, 1.0], [0.0, 1.0])
    with pytest.raises(ValueError, match="output has 3 samples, input has 2"):
        ph.fit_linear(ph.PI([0.1], [1.0]), [0.0, 1.0], [0.0, 1.0, 2.0])
    with pytest.raises(ValueError, match="input is constant"):
        ph.identify_pi(np.ones(10), np.arange(10.0))


@pytest.mark.skipif(not (SHARED / "piezo" / "yan9a_model_1hz.dat").exists(), reason="shared data not present")
def test_real_record_one_cycle():
    # the original scripts identify on one 1 Hz cycle (200 samples/s) from row 3152
    rec = ph.load_yan9a_model_record(SHARED / "piezo" / "yan9a_model_1hz.dat")
    seg = slice(3152, 3152 + 1000)
    v, y = rec.input[seg], rec.output[seg]
    pre = ph.identify_preisach(v, y, levels=10)
    mpi = ph.identify_mpi(v, y)
    assert pre.metrics["rmse_percent"] < 0.3 and pre.metrics["max_error_percent"] < 1.0  # measured 0.25 / 0.93
    assert mpi.metrics["rmse_percent"] < 1.6  # measured 1.45


@pytest.mark.parametrize("method", ["de", "css"])
def test_identify_bouc_wen_recovers_the_parameters(method):
    truth = ph.BoucWen(1.2, 3.0, 1.0, d=2.0)
    v = 1.5 * np.sin(np.linspace(0, 30, 3000)) * np.linspace(1, 0.3, 3000)
    res = ph.identify(v, truth.simulate(v), "boucwen", optimizer=method, rng=1, max_iterations=150)
    m = res.model
    np.testing.assert_allclose([m.a, m.beta, m.gamma, m.d], [1.2, 3.0, 1.0, 2.0], rtol=1e-3)
    assert res.train["rmse_percent"] < 1e-3 and res.history["best_cost"].size >= 1
    # same seed, same result
    again = ph.identify(v, truth.simulate(v), "boucwen", optimizer=method, rng=1, max_iterations=150)
    assert again.model == res.model


def test_identify_reports_validation_metrics():
    truth = ph.papers.mpi_seed2()
    v_train, v_val = drive(2000, 1), drive(1500, 2)
    res = ph.identify(v_train, truth.simulate(v_train), "mpi", validate=(v_val, truth.simulate(v_val)))
    assert res.train["rmse_percent"] < 0.5 and res.validation["rmse_percent"] < 0.5
    assert set(res.to_dict()) == {"method", "wall_time_s", "train", "validation", "partial"}
    assert res.to_dict()["partial"] is False


def test_identify_bad_input():
    with pytest.raises(ValueError, match="model = 'spline' is unknown"):
        ph.identify([0.0, 1.0], [0.0, 1.0], "spline")
    with pytest.raises(ValueError, match="fs is required"):
        ph.identify(drive(100), drive(100), "rdpi")


def test_identify_cemf_stage_from_simulated_measurements():
    # data from the virtual stage (creep, electrostriction, amplifier dynamics: more physics than
    # the CEMF model being fitted), voltage = amplifier output, position = true position
    stage = ph.virtual_stage()
    fs = 1.0 / stage.sample_time
    _, u = ph.variable_amplitude_sine(5, 70, 0.6, fs, offset=75)
    r = stage.simulate(u)
    va, x = np.r_[0.0, r.voltage[:-1]], r.position
    res = ph.identify_cemf(va, x, fs, optimizer="de", rng=1, max_iterations=100)
    assert res.train["rmse_percent"] < 0.5  # measured 0.28 %
    p = res.model
    k_true = stage.params.stiffness / stage.params.tem
    assert abs(p.stiffness / p.tem - k_true) / k_true < 0.1  # K = k/Tem within 10 % (measured 6 %)
    assert res.history["best_cost"][-1] <= res.history["best_cost"][0]
    with pytest.raises(ValueError, match="position has 3 samples, voltage has 2"):
        ph.identify_cemf([0.0, 1.0], [0.0, 1.0, 2.0], fs)
    with pytest.raises(ValueError, match="fs = -1.0 must be > 0"):
        ph.identify_cemf([0.0, 1.0], [0.0, 1.0], -1.0)


@pytest.mark.parametrize(
    ("kind", "kwargs", "parameters"),
    [
        ("pi", {}, 11),  # 9 weights, p0, offset
        ("mpi", {}, 13),  # 9 weights, cubic polynomial
        ("rdpi", {"fs": 100.0}, 20),
        ("preisach", {"levels": 12}, 14),  # levels + offset and slope
        ("boucwen", {"rng": 0, "max_iterations": 2}, 5),  # a, beta, gamma, d, offset (n fixed)
    ],
)
def test_a_fit_needs_ten_samples_per_parameter(kind, kwargs, parameters):
    """Issue 20: a 9-operator PI from 2 samples was "identified" without a word. At 10 samples
    per parameter the training RMSE understates the held-out one by at most about 10 %."""
    v = drive(2000)
    y = ph.PI([0.1, 0.3, 0.6], [0.5, 0.2, 0.1], p0=0.8).simulate(v)
    need = 10 * parameters
    for n in (2, need - 1):
        with pytest.raises(ph.ParameterError, match=rf"has {n} samples, too few to fit the {parameters} parameters"):
            ph.identify(v[:n], y[:n], kind, **kwargs)
    fit = ph.identify(v[:need], y[:need], kind, **kwargs)  # exactly enough
    assert np.all(np.isfinite(fit.model.simulate(v)))


def test_the_sample_check_covers_every_public_fit():
    v = drive(2000)
    y = ph.PI([0.1, 0.3, 0.6], [0.5, 0.2, 0.1], p0=0.8).simulate(v)
    few = "too few to fit"
    with pytest.raises(ph.ParameterError, match=few):
        ph.identify_pi(v[:20], y[:20])
    with pytest.raises(ph.ParameterError, match=few):
        ph.identify_mpi(v[:20], y[:20])
    with pytest.raises(ph.ParameterError, match=few):
        ph.identify_preisach(v[:20], y[:20], levels=4)
    with pytest.raises(ph.ParameterError, match=few):
        ph.fit_linear(ph.PI([0.1, 0.3], [0, 0]), v[:30], y[:30])  # 4 parameters: 40 samples
    ph.fit_linear(ph.PI([0.1, 0.3], [0, 0]), v[:40], y[:40])
    with pytest.raises(ph.ParameterError, match=few):  # weighted and minimax fits too
        ph.identify(v[:50], y[:50], "pi", weights=np.ones(50))
    with pytest.raises(ph.ParameterError, match=few):
        ph.identify(v[:50], y[:50], "pi", loss="linf")
    with pytest.raises(ph.ParameterError, match=few):
        ph.identify(v[:50], y[:50], "mpi", structure="fit", rng=0, max_iterations=2)


@pytest.mark.parametrize("scale", [1e301, 1e-310])
@pytest.mark.parametrize("kind", ["pi", "mpi", "preisach", "boucwen", "rdpi"])
def test_records_beyond_the_fit_range_are_refused_before_any_warning(scale, kind, recwarn):
    """Issue 20: values near 1e301 printed five numpy/SciPy warnings, then "weights[0] = nan";
    subnormal values fitted to "RMSE 0 %". Both are refused first, naming the limit."""
    v = drive(600)
    y = ph.PI([0.1, 0.3, 0.6], [0.5, 0.2, 0.1], p0=0.8).simulate(v)
    limit = r"within \+-1e\+40" if scale > 1 else r"a range of at least 1e-40"
    with pytest.raises(ph.ParameterError, match=rf"input (reaches|spans) .*: a fit .*{limit}.*rescale the record"):
        ph.identify(v * scale, y, kind, fs=100.0, rng=0, max_iterations=2)
    with pytest.raises(ph.ParameterError, match=rf"output (reaches|spans) .*{limit}"):
        ph.identify(v, y * scale, kind, fs=100.0, rng=0, max_iterations=2)
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)]


def test_every_public_fit_checks_the_range():
    v = drive(600)
    y = ph.PI([0.1, 0.3, 0.6], [0.5, 0.2, 0.1], p0=0.8).simulate(v)
    for fit in (ph.identify_pi, ph.identify_mpi, ph.identify_preisach):
        with pytest.raises(ph.ParameterError, match=r"output reaches \d\.\d+e\+301"):
            fit(v, y * 1e301)
    with pytest.raises(ph.ParameterError, match=r"input reaches"):
        ph.fit_linear(ph.PI([0.1, 0.3], [0, 0]), v * 1e100, y)
    with pytest.raises(ph.ParameterError, match=r"input reaches"):
        ph.identify_vp(v * 1e100, y, "pi", rng=0, max_iterations=2)
    # inside the range, a record rescaled by a power of two gives the same fit scaled (exactly)
    a = ph.identify_pi(v, y).model
    b = ph.identify_pi(v, y * 2.0**100).model
    np.testing.assert_allclose(b.simulate(v), a.simulate(v) * 2.0**100, rtol=1e-9)


def test_metrics_are_computed_on_normalized_data():
    """RMSE and max error agree at any scale: no overflow to inf near 1e300, no underflow to 0
    (beside a non-zero max error) for subnormal records."""
    rng = np.random.default_rng(0)
    measured = rng.standard_normal(1000)
    predicted = measured + 0.1 * rng.standard_normal(1000)
    ref = ph.fit_metrics(predicted, measured)
    for scale in (1e300, 2.0**-1030, 1e-310):
        m = ph.fit_metrics(predicted * scale, measured * scale)
        # percentages are scale-free; subnormal inputs carry fewer digits (1e-310: about 11)
        tol = 1e-12 if scale > 1e-300 else 1e-6
        assert m["rmse_percent"] == pytest.approx(ref["rmse_percent"], rel=tol)
        assert m["max_error_percent"] == pytest.approx(ref["max_error_percent"], rel=tol)
        assert m["rmse"] > 0 and m["rmse"] <= m["max_error"]
        assert m["rmse"] == pytest.approx(ref["rmse"] * scale, rel=tol)
    assert ph.metrics.rms([3e300, -4e300]) == pytest.approx(np.sqrt(12.5) * 1e300)
    assert ph.metrics.rms([3e-310, 4e-310]) > 0
    assert ph.metrics.rmse([0.0, 0.0], [1e-310, -1e-310]) == pytest.approx(1e-310, rel=1e-3)
