"""identify(): the robust Huber loss (IRLS for the linear families, an MM-style population
search for the others), dispatch to the CEMF stage and the Bouc–Wen benchmark, and the
result's plot."""

import numpy as np
import pytest

import piezohyst as ph
from piezohyst import _core
from piezohyst.boucwen_benchmark import FS, BoucWenBenchmark, identify_boucwen_benchmark
from piezohyst.identify import KINDS, default_huber_delta, huber_cost
from piezohyst.identify.core import _default_thresholds, _huber_location, _stage_positions


def drive(n=3000, seed=0):
    rng = np.random.default_rng(seed)
    return np.clip(0.5 + 0.45 * np.sin(np.linspace(0, 25, n)) * np.linspace(1, 0.2, n) + rng.normal(0, 0.01, n), 0, 1)


def noisy_and_glitched(y, seed):
    """``y`` + white noise (0.2 % of the range), and the same with 1 % of the samples hit by
    glitches of 50-100 % of the range, either sign."""
    rng = np.random.default_rng(seed)
    span = np.ptp(y)
    noisy = y + rng.normal(0, 0.002 * span, y.size)
    glitched = noisy.copy()
    idx = rng.choice(y.size, y.size // 100, replace=False)
    glitched[idx] += rng.choice([-1.0, 1.0], idx.size) * rng.uniform(0.5, 1.0, idx.size) * span
    return noisy, glitched


def val_rmse(res, u, clean):
    return float(np.sqrt(np.mean((res.model.simulate(u) - clean) ** 2)))


# ----------------------------------------------------------------------------- the Huber cost


def test_huber_cost_hand_computed():
    r = np.array([0.0, 1.0, -1.0, 1.0])
    assert float(huber_cost(r, delta=10.0)) == pytest.approx(np.sqrt(0.75), rel=1e-15)  # = RMSE below delta
    # rho(0) = 0, rho(3) = 1 * (3 - 1/2) = 2.5 -> sqrt(2 * 2.5 / 2)
    assert float(huber_cost([0.0, 3.0], delta=1.0)) == pytest.approx(np.sqrt(2.5), rel=1e-15)
    # median of [-1, 0, 1, 2, 100] is 1, absolute deviations [2, 1, 0, 1, 99] -> MAD 1
    assert float(default_huber_delta([-1.0, 0.0, 1.0, 2.0, 100.0])) == pytest.approx(1.345 * 1.4826, rel=1e-15)


def test_huber_cost_row_wise():
    rng = np.random.default_rng(0)
    R = rng.normal(size=(3, 500))
    R[1, ::50] += 1e3  # glitches on row 1 only
    R[2, 7] = np.nan  # a failed simulation
    c = huber_cost(R)
    assert c.shape == (3,) and np.isinf(c[2])
    assert 0.9 < c[0] < 1.0  # unit noise: a little below its RMS
    # 2 % glitches of 1000 add about 2 * 0.02 * delta * 1000 (delta ~ 1.35) to the square, not
    # 0.02 * 1000**2 as to the RMSE's (141)
    assert 6.5 < c[1] < 8.0 and c[1] < 0.06 * np.sqrt(np.mean(R[1] ** 2))
    assert float(huber_cost(R[1])) == c[1]
    # scale-equivariant with the default threshold, RMSE with a huge one
    np.testing.assert_allclose(huber_cost(-7.0 * R[:2]), 7.0 * c[:2], rtol=1e-12)
    np.testing.assert_allclose(huber_cost(R[:2], delta=1e9), np.sqrt(np.mean(R[:2] ** 2, axis=1)), rtol=1e-12)


# ----------------------------------------------------------------------------- linear families


def test_huber_location_minimizes_the_huber_cost():
    from scipy.optimize import minimize_scalar

    rng = np.random.default_rng(3)
    r = np.stack(
        [rng.normal(0.3, 1.0, 501), rng.standard_t(2, 501) - 2.0, np.r_[rng.normal(0, 1, 490), np.full(11, 80.0)]]
    )
    delta = np.array([1.345, 0.5, 1.345])
    c = _huber_location(r, delta)
    for row, d, got in zip(r, delta, c, strict=True):
        ref = minimize_scalar(lambda m: float(huber_cost(row - m, d)), bracket=(-1, 1), tol=1e-12).x
        assert got == pytest.approx(ref, abs=1e-6)
        # a stationary point of the cost: the clipped residuals sum to zero
        assert abs(np.clip(row - got, -d, d).sum()) < 1e-9 * row.size
    # far glitches move it as little as the threshold allows; a huge threshold gives the mean
    assert abs(c[2]) < 0.2
    assert _huber_location(r, 1e9) == pytest.approx(r.mean(axis=1), abs=1e-12)
    # it moves smoothly with the residuals (the median jumps between samples)
    shifted = _huber_location(r[0] + np.linspace(0, 1e-6, r.shape[1]), 1.345)
    assert 0 < shifted - c[0] < 1e-6


def test_linear_huber_fit_resists_glitches():
    v, v_val = drive(), drive(2000, 7)
    truth = ph.PI(_default_thresholds(v, 6), [0.4, 0.2, 0.15, 0.1, 0.05, 0.02], p0=0.6)  # the default structure
    clean_val = truth.simulate(v_val)
    noisy, glitched = noisy_and_glitched(truth.simulate(v), seed=3)

    ls = ph.identify(v, glitched, "pi", operators=6)
    hub = ph.identify(v, glitched, "pi", operators=6, loss="huber")
    assert hub.method == "ls+huber" and ls.method == "ls"
    # measured: 3.7e-3 (least squares) against 1.2e-4 (Huber), a ratio of 0.03
    assert val_rmse(hub, v_val, clean_val) < 0.1 * val_rmse(ls, v_val, clean_val)
    np.testing.assert_allclose(hub.model.weights, truth.weights, atol=0.01)

    # without glitches the two agree (measured 1.08e-4 and 1.21e-4)
    ls0 = ph.identify(v, noisy, "pi", operators=6)
    hub0 = ph.identify(v, noisy, "pi", operators=6, loss="huber")
    assert val_rmse(hub0, v_val, clean_val) == pytest.approx(val_rmse(ls0, v_val, clean_val), rel=0.3)
    np.testing.assert_allclose(hub0.model.weights, ls0.model.weights, atol=0.005)
    # a fixed threshold of ~3 noise sigmas is as good
    fixed = ph.identify(v, glitched, "pi", operators=6, loss="huber", huber_delta=0.006 * np.ptp(noisy))
    assert val_rmse(fixed, v_val, clean_val) < 0.1 * val_rmse(ls, v_val, clean_val)


@pytest.mark.parametrize("kind", ["mpi", "preisach", "rdpi"])
def test_every_linear_kind_takes_the_huber_loss(kind):
    v = drive(1500, 1)
    kw = {"fs": 1000.0} if kind == "rdpi" else {}
    # a truth of the kind's default structure: its least-squares fit to the seed-2 MPI
    truth = ph.identify(v, ph.papers.mpi_seed2().simulate(v), kind, levels=6, **kw).model
    y = truth.simulate(v)
    noisy, glitched = noisy_and_glitched(y, seed=4)
    ls = ph.identify(v, glitched, kind, levels=6, **kw)
    hub = ph.identify(v, glitched, kind, levels=6, loss="huber", **kw)
    ls_clean = ph.identify(v, noisy, kind, levels=6, **kw)
    assert hub.method == "ls+huber"
    # measured ratios 0.03-0.04; with glitches Huber does as well as least squares without
    assert val_rmse(hub, v, y) < 0.1 * val_rmse(ls, v, y)
    assert val_rmse(hub, v, y) == pytest.approx(val_rmse(ls_clean, v, y), rel=0.3)


# ----------------------------------------------------------------------------- population paths


def test_boucwen_huber_fit_resists_glitches():
    truth = ph.BoucWen(1.2, 3.0, 1.0, d=2.0)
    v = 1.5 * np.sin(np.linspace(0, 30, 3000)) * np.linspace(1, 0.3, 3000)
    v_val = 1.2 * np.sin(np.linspace(0, 20, 2000) + 0.3) * np.linspace(0.5, 1, 2000)
    clean_val = truth.simulate(v_val)
    noisy, glitched = noisy_and_glitched(truth.simulate(v), seed=0)
    run = dict(optimizer="de", rng=1, max_iterations=40)

    ls = ph.identify(v, glitched, "boucwen", **run)
    hub = ph.identify(v, glitched, "boucwen", loss="huber", **run)
    assert hub.method == "de+huber"
    # measured: 1.9e-2 (RMSE cost) against 5.3e-4 (Huber)
    assert val_rmse(hub, v_val, clean_val) < 0.1 * val_rmse(ls, v_val, clean_val)
    delta = hub.history["huber_delta"]
    assert 0 < delta < 0.05 * np.ptp(noisy)  # near the noise, far below the glitches

    ls0 = ph.identify(v, noisy, "boucwen", **run)
    hub0 = ph.identify(v, noisy, "boucwen", loss="huber", **run)
    assert val_rmse(hub0, v_val, clean_val) == pytest.approx(val_rmse(ls0, v_val, clean_val), rel=0.5)
    m, t = hub0.model, truth
    np.testing.assert_allclose([m.a, m.beta, m.gamma, m.d], [t.a, t.beta, t.gamma, t.d], rtol=0.1)

    # a given threshold is kept and used throughout
    fixed = ph.identify(v, glitched, "boucwen", loss="huber", huber_delta=0.02, **run)
    assert fixed.history["huber_delta"] == 0.02
    assert val_rmse(fixed, v_val, clean_val) < 0.1 * val_rmse(ls, v_val, clean_val)


def short_stage_record(duration=0.2):
    stage = ph.virtual_stage()
    fs = 1.0 / stage.sample_time
    _, u = ph.variable_amplitude_sine(5, 70, duration, fs, offset=75)
    r = stage.simulate(u)
    return np.r_[0.0, r.voltage[:-1]], r.position, fs, stage


def test_stage_positions_are_what_the_batch_rmse_scores():
    # the Huber path simulates stage rows one by one; it must score the same positions
    va, x, fs, stage = short_stage_record()
    base = ph.Stage(stage.params, ph.Amplifier(-1e9, 1e9), sample_time=1.0 / fs).core_params()
    rows = np.stack([base, base, base])
    rows[1, 2] *= 1.3  # stiffer
    rows[2, 5] *= 0.5  # less CEMF
    pos = _stage_positions(rows, 1.0 / fs, 1, 0.05, va)
    rmse = _core.stage_batch_rmse(rows, 1.0 / fs, 1, 0.05, va, x, float("inf"))
    np.testing.assert_allclose(np.sqrt(np.mean((pos - x) ** 2, axis=1)), rmse, rtol=1e-12)
    assert len(set(np.round(rmse, 15))) == 3


# ----------------------------------------------------------------------------- dispatch


def test_cemf_dispatch():
    va, x, fs, _ = short_stage_record()
    run = dict(optimizer="de", rng=1, max_iterations=5)
    res = ph.identify(va, x, "cemf", fs=fs, **run)
    direct = ph.identify_cemf(va, x, fs, **run)
    assert isinstance(res.model, ph.StageParameters) and res.model == direct.model
    assert res.method == "de" and res.train == direct.train
    assert res.history["best_cost"].size == 5
    # options reach identify_cemf; validation is reported
    with pytest.raises(ValueError, match=r"bounds has 1 pairs, expected 7"):
        ph.identify(va, x, "cemf", fs=fs, bounds=[(0.0, 1.0)], **run)
    validated = ph.identify(va[:1000], x[:1000], "cemf", fs=fs, validate=(va, x), **run)
    assert validated.validation["rmse"] > 0 and validated.validation != validated.train
    hub = ph.identify(va, x, "cemf", fs=fs, loss="huber", **run)
    assert hub.method == "de+huber" and hub.history["huber_delta"] > 0
    with pytest.raises(ValueError, match="fs is required for model = 'cemf'"):
        ph.identify(va, x, "cemf")


def benchmark_record(n=512):
    rng = np.random.default_rng(1)
    lines = np.zeros(n // 2 + 1, complex)
    lines[4:103] = np.exp(2j * np.pi * rng.random(99))
    u = np.fft.irfft(lines, n)
    u = np.tile(50 * u / u.std(), 2)
    return u, BoucWenBenchmark().simulate(u)


def test_boucwen_benchmark_dispatch():
    u, y = benchmark_record()
    res = ph.identify(u, y, "boucwen-benchmark", rng=0, max_iterations=4, fit_range=(512, 1024), polish=False)
    direct = identify_boucwen_benchmark(
        u, y, FS, optimizer="de", rng=0, max_iterations=4, fit_range=(512, 1024), polish=False
    )
    assert isinstance(res.model, BoucWenBenchmark) and repr(res.model) == repr(direct.model)
    assert res.method == direct.method and res.train == direct.train
    assert res.history["best_cost"].size == 4
    with pytest.raises(ValueError, match="loss = 'huber' is not available for model = 'boucwen-benchmark'"):
        ph.identify(u, y, "boucwen-benchmark", loss="huber")


def test_bad_arguments():
    with pytest.raises(ValueError, match="model = 'spline' is unknown; expected one of") as e:
        ph.identify([0.0, 1.0], [0.0, 1.0], "spline")
    assert all(repr(k) in str(e.value) for k in KINDS)
    assert {"cemf", "boucwen-benchmark", "pi", "mpi", "boucwen"} <= set(KINDS)
    v = drive(200)
    with pytest.raises(ValueError, match=r"loss = 'l1' is unknown; expected one of \['squared', 'huber'\]"):
        ph.identify(v, v, "pi", loss="l1")
    with pytest.raises(ValueError, match="huber_delta = 0.1 is only used with loss = 'huber'"):
        ph.identify(v, v, "pi", huber_delta=0.1)
    with pytest.raises(ValueError, match="huber_delta = -1.0 must be > 0"):
        ph.identify(v, v, "pi", loss="huber", huber_delta=-1.0)
    with pytest.raises(ValueError, match="huber_delta = nan is not finite"):
        ph.fit_linear(ph.PI([0.1], [0.0]), v, v, loss="huber", huber_delta=float("nan"))
    with pytest.raises(TypeError, match=r"unexpected keyword arguments \['bounds'\] for model = 'pi'"):
        ph.identify(v, v, "pi", bounds=[(0, 1)])


# ----------------------------------------------------------------------------- plot


def test_plot_carries_the_data():
    matplotlib = pytest.importorskip("matplotlib")
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    v = drive(800, 2)
    y = ph.papers.mpi_seed2().simulate(v) + np.random.default_rng(0).normal(0, 0.003, v.size)
    res = ph.identify(v, y, "pi", operators=4)
    yp = res.model.simulate(v)
    fig = res.plot(v, y)
    try:
        loop, fit, residual = fig.axes
        assert len(fig.axes) == 3
        (m_line, p_line) = loop.get_lines()
        np.testing.assert_array_equal(m_line.get_xdata(), v)
        np.testing.assert_array_equal(m_line.get_ydata(), y)
        np.testing.assert_array_equal(p_line.get_xdata(), v)
        np.testing.assert_array_equal(p_line.get_ydata(), yp)
        assert [t.get_text() for t in loop.get_legend().get_texts()] == ["measured", "model"]
        np.testing.assert_array_equal(fit.get_lines()[0].get_ydata(), y)
        np.testing.assert_array_equal(fit.get_lines()[1].get_ydata(), yp)
        (r_line,) = residual.get_lines()
        np.testing.assert_array_equal(r_line.get_ydata(), yp - y)
        assert np.sqrt(np.mean(r_line.get_ydata() ** 2)) == pytest.approx(res.train["rmse"], rel=1e-12)
        fig.canvas.draw()  # renders without error on Agg
    finally:
        plt.close(fig)


def test_qr_bounded_solver_is_the_bvls_solution():
    """The final Huber IRLS solves each reweighted problem through the QR factors of the
    regressors (identify.core._qr_bounded_lstsq) instead of SciPy's BVLS: the same minimizer,
    bounds active or not, a free offset column included; a rank-deficient matrix goes to BVLS."""
    from scipy.optimize import lsq_linear

    from piezohyst.identify.core import _qr_bounded_lstsq

    rng = np.random.default_rng(3)
    A = rng.standard_normal((400, 6))
    A[:, 5] = 1.0
    lb = np.array([0.0, 0.0, 0.0, 0.0, 0.0, -np.inf])
    ub = np.full(6, np.inf)
    for truth in ([1.0, 2.0, 0.5, 0.3, 0.1, -4.0], [1.0, -2.0, 0.5, -0.3, 0.1, 4.0]):  # bounds idle, active
        y = A @ np.array(truth) + 0.01 * rng.standard_normal(400)
        z = _qr_bounded_lstsq(A, y, (lb, ub))
        ref = lsq_linear(A, y, bounds=(lb, ub), method="bvls").x
        np.testing.assert_allclose(z, ref, rtol=1e-9, atol=1e-12)
        assert np.all(z >= lb)
    B = np.column_stack([A, A[:, 0]])  # two equal columns: rank deficient
    y = B @ np.r_[1.0, 2.0, 0.5, 0.3, 0.1, -4.0, 1.0]
    z = _qr_bounded_lstsq(B, y, (np.r_[lb, 0.0], np.r_[ub, np.inf]))
    assert np.sqrt(np.mean((B @ z - y) ** 2)) < 1e-9


def test_the_heavy_fits_run_blas_on_one_thread(monkeypatch):
    """The Preisach fit and variable projection hold BLAS to one thread while they run (on a
    shared machine a second thread's spinning cost 1.5-3x; identify.core._one_blas_thread),
    and give it back after."""
    threadpoolctl = pytest.importorskip("threadpoolctl")
    import importlib

    core = importlib.import_module("piezohyst.identify.core")
    varpro = importlib.import_module("piezohyst.identify.varpro")

    def blas_threads():
        return {i["num_threads"] for i in threadpoolctl.threadpool_info() if i["user_api"] == "blas"}

    seen = []
    for module, name in ((core, "_gram_nnls"), (varpro, "_small_bounded_lstsq")):
        real = getattr(module, name)
        monkeypatch.setattr(module, name, lambda *a, _real=real, **k: seen.append(blas_threads()) or _real(*a, **k))
    before = blas_threads()
    v = drive(800, 2)
    ph.identify(v, v**2, "preisach", levels=6)
    ph.identify(v, v**2, "mpi", structure="fit", operators=3, rng=0, max_iterations=2)
    assert len(seen) > 2 and all(s == {1} for s in seen)
    assert blas_threads() == before
