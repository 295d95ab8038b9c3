"""FitResult and IdentificationResult are RunReports (wall time, evaluations, history, partial),
and :func:`identify` validates each record it is given once, at the public door."""

import html
from collections import Counter

import numpy as np
import pytest

import piezohyst as ph
from piezohyst import _validate
from piezohyst.identify import FitResult, IdentificationResult, boucwen_benchmark, core, dispatch, varpro
from piezohyst.models.boucwen_benchmark import BoucWenBenchmark
from piezohyst.optimize import RunReport

IDENTIFY_MODULES = (core, dispatch, varpro, boucwen_benchmark)


def drive(n=1200, seed=0):
    rng = np.random.default_rng(seed)
    return 0.5 + 0.45 * np.sin(np.linspace(0, 25, n)) * np.linspace(1, 0.2, n) + rng.normal(0, 0.002, n)


def pi_record(n=1200):
    v = drive(n)
    return v, ph.PI([0.05, 0.15, 0.3], [0.4, 0.2, 0.1], p0=0.7).simulate(v)


def bench_record(n=256):
    rng = np.random.default_rng(1)
    lines = np.zeros(n // 2 + 1, complex)
    lines[4:50] = np.exp(2j * np.pi * rng.random(46))
    force = np.tile(50 * np.fft.irfft(lines, n) / np.fft.irfft(lines, n).std(), 2)
    return force, BoucWenBenchmark().simulate(force), n


def check_report(res, *, iterates):
    assert isinstance(res, RunReport)
    assert isinstance(res.wall_time, float) and res.wall_time > 0
    assert isinstance(res.evaluations, int) and res.evaluations > 0
    assert isinstance(res.history, dict)
    assert bool(res.history) is iterates
    assert res.partial is False
    page = res._repr_html_()
    assert f"{res.wall_time:.3g} s" in page and str(res.evaluations) in page
    assert html.escape(res._headline()) in page


def test_fit_result_is_a_run_report():
    v, y = pi_record()
    fit = ph.fit_linear(ph.PI([0.05, 0.15, 0.3], [0, 0, 0]), v, y)
    assert isinstance(fit, FitResult)
    check_report(fit, iterates=False)
    assert fit.evaluations == 1  # one bounded least-squares solve
    assert repr(fit).startswith("FitResult(PI, rmse=")
    assert "PI fitted by least squares" in fit._headline()
    assert fit._history_columns() == {}


def test_fit_result_huber_counts_its_reweighted_solves():
    v, y = pi_record()
    y = y.copy()
    y[::100] += 1.0
    fit = ph.fit_linear(ph.PI([0.05, 0.15, 0.3], [0, 0, 0]), v, y, loss="huber")
    check_report(fit, iterates=False)
    assert fit.evaluations > 1


def test_fit_result_former_constructor_still_works():
    v, y = pi_record()
    model = ph.fit_linear(ph.PI([0.05, 0.15, 0.3], [0, 0, 0]), v, y).model
    metrics = {"rmse": 0.1, "max_error": 0.2, "rmse_percent": 1.0, "max_error_percent": 2.0}
    fit = FitResult(model, metrics, 0.5)
    assert (fit.evaluations, fit.history, fit.partial, fit.wall_time) == (1, {}, False, 0.5)
    assert "500.0 ms" in repr(fit)


def test_identify_linear_is_a_run_report():
    v, y = pi_record()
    res = ph.identify(v, y, "pi", operators=3)
    assert isinstance(res, IdentificationResult)
    check_report(res, iterates=False)
    assert res.evaluations == 1 and res.history == {}
    assert "PI identified by ls" in res._headline()


def test_identify_with_an_optimizer_is_a_run_report():
    v = drive(600)
    y = ph.BoucWen(0.8, 2.0, 0.5, 1.0, 0.3).simulate(v)
    res = ph.identify(v, y, "boucwen", rng=0, max_iterations=5, validate=(v, y))
    check_report(res, iterates=True)
    assert res.history["best_cost"].size == 5
    assert res.evaluations >= res.history["nfev"][-1]  # the search's candidates, then the polish's
    assert "validation rmse" in res._headline()
    assert res._history_columns()["best_cost"].size == 5


def test_identify_vp_counts_candidates_and_polish():
    v = drive(600)
    res = ph.identify(v, v**2, "mpi", structure="fit", operators=3, rng=0, max_iterations=3)
    check_report(res, iterates=True)
    assert res.evaluations > res.history["nfev"][-1] + res.history["polish"]["nfev"] - 1


def test_identification_result_former_constructor_still_works():
    metrics = {"rmse": 0.1, "max_error": 0.2, "rmse_percent": 1.0, "max_error_percent": 2.0}
    res = IdentificationResult(ph.PI([0.1], [1.0]), metrics, None, "ls", 0.25, None)
    assert (res.history, res.evaluations, res.partial) == ({}, 0, False)
    assert set(res.to_dict()) == {"method", "wall_time_s", "train", "validation", "partial"}
    assert "0.25 s" in res._repr_html_()


def test_identify_cemf_and_benchmark_count_their_evaluations():
    stage = ph.virtual_stage()
    fs = 1.0 / stage.sample_time
    _, u = ph.variable_amplitude_sine(5, 70, 0.3, fs, offset=75)
    r = stage.simulate(u)
    res = ph.identify(np.r_[0.0, r.voltage[:-1]], r.position, "cemf", fs=fs, rng=1, max_iterations=3)
    check_report(res, iterates=True)
    assert res.evaluations == res.history["nfev"][-1]

    force, y, n = bench_record()
    bench = ph.identify(
        force, y, "boucwen-benchmark", fit_range=(n, 2 * n), warmup=n, rng=0, max_iterations=2, starts=1
    )
    check_report(bench, iterates=True)
    assert bench.evaluations == bench.history["nfev"][-1] + bench.history["polish"]["nfev"]


@pytest.fixture
def validations(monkeypatch):
    """Names given to ``as_record`` by the identification modules, counted."""
    seen = Counter()

    def counting(x, name, **kwargs):
        seen[name] += 1
        return _validate.as_record(x, name, **kwargs)

    for module in IDENTIFY_MODULES:
        monkeypatch.setattr(module, "as_record", counting)
    return seen


@pytest.mark.parametrize(
    "kwargs",
    [
        dict(model="pi", operators=3),
        dict(model="mpi", operators=3, loss="huber"),
        dict(model="rdpi", operators=3, fs=1000.0),
        dict(model="preisach", levels=4),
        dict(model="pi", operators=3, creep=1, fs=1000.0),
        dict(model="boucwen", rng=0, max_iterations=2),
        dict(model="mpi", operators=3, structure="fit", rng=0, max_iterations=2),
    ],
    ids=["pi", "mpi-huber", "rdpi", "preisach", "pi-creep", "boucwen", "mpi-fit"],
)
def test_identify_validates_each_record_once(validations, kwargs):
    v, y = pi_record(400)
    vv, vy = pi_record(300)
    ph.identify(v, y, validate=(vv, vy), **kwargs)
    records = {k: n for k, n in validations.items() if k != "predicted"}  # the model's outputs, checked finite
    assert records == {"input": 1, "output": 1, "validate input": 1, "validate output": 1}


def test_identify_cemf_validates_each_record_once(validations):
    stage = ph.virtual_stage()
    fs = 1.0 / stage.sample_time
    _, u = ph.variable_amplitude_sine(5, 70, 0.3, fs, offset=75)
    r = stage.simulate(u)
    ph.identify(r.voltage, r.position, "cemf", fs=fs, rng=1, max_iterations=2, validate=(r.voltage, r.position))
    records = {k: n for k, n in validations.items() if k != "predicted"}
    assert records == {"voltage": 1, "position": 1, "validate voltage": 1, "validate position": 1}


@pytest.mark.parametrize("public", ["fit_linear", "identify_pi", "identify_mpi", "identify_preisach"])
def test_linear_entry_points_validate_each_record_once(validations, public):
    v, y = pi_record(400)
    if public == "fit_linear":
        ph.fit_linear(ph.PI([0.05, 0.15, 0.3], [0, 0, 0]), v, y)
    else:
        getattr(ph, public)(v, y)
    assert {k: n for k, n in validations.items() if k != "predicted"} == {"input": 1, "output": 1}


def test_identify_boucwen_benchmark_validates_each_record_once(validations):
    force, y, n = bench_record()
    ph.identify(
        force, y, "boucwen-benchmark", fit_range=(n, 2 * n), warmup=n, rng=0, max_iterations=2, validate=(force, y)
    )
    records = {k: n for k, n in validations.items() if k != "predicted"}
    assert records == {"u": 1, "y": 1, "validate u": 1, "validate y": 1}
