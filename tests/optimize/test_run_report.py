"""OptimizeResult is a RunReport (issue 18): evaluations = nfev, partial = interrupted or stopped
by the callback, one history row per iteration, a convergence plot and a notebook display."""

import matplotlib
import numpy as np
import pytest

from piezohyst.optimize import OptimizeResult, RunReport, minimize

matplotlib.use("Agg")


def sphere(X):
    return np.sum((X - 0.3) ** 2, axis=1)


def test_a_finished_run_is_a_complete_run_report():
    res = minimize(sphere, [(-1, 1)] * 3, method="pso", rng=1, max_iterations=15, population_size=8)
    assert isinstance(res, RunReport) and isinstance(res, OptimizeResult)
    assert res.evaluations == res.nfev == 15 * 8
    assert res.partial is False and res.success and not res.interrupted
    assert res.wall_time > 0
    cols = res._history_columns()
    assert set(cols) >= {"best_cost", "mean_cost", "n_finite", "nfev", "best_x[0]", "best_x[2]"}
    assert all(c.size == res.nit for c in cols.values())
    assert np.array_equal(cols["best_x[1]"], res.history["best_x"][:, 1])


def test_polish_counts_in_evaluations():
    res = minimize(sphere, [(-1, 1)] * 2, method="de", rng=2, max_iterations=5, population_size=8, polish=True)
    assert res.evaluations == res.nfev > 5 * 8
    assert res.partial is False
    assert all(c.size == res.nit for c in res._history_columns().values())


def test_stopped_by_the_callback_is_partial():
    res = minimize(sphere, [(-1, 1)] * 2, method="css", rng=3, max_iterations=50, callback=lambda r: r.nit >= 4)
    assert res.message.startswith("stopped by callback")
    assert res.partial is True and res.success is False and res.interrupted is False
    assert res.nit == 4 and res.evaluations == res.nfev
    assert all(c.size == 4 for c in res._history_columns().values())
    # with a polish after the stop, still partial
    polished = minimize(
        sphere, [(-1, 1)] * 2, method="css", rng=3, max_iterations=50, callback=lambda r: r.nit >= 4, polish=True
    )
    assert polished.partial is True and "polish" in polished.message


def test_interrupted_is_partial():
    calls = []

    def fun(X):
        calls.append(1)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return sphere(X)

    res = minimize(fun, [(-1, 1)] * 2, method="de", rng=4, max_iterations=20, population_size=6)
    assert res.interrupted and res.partial and not res.success
    assert res.nit == 2 and res.evaluations == 12
    assert all(c.size == 2 for c in res._history_columns().values())


def test_plot_and_html():
    import matplotlib.pyplot as plt
    from matplotlib.figure import Figure

    res = minimize(sphere, [(-1, 1)] * 2, method="mpso", rng=5, max_iterations=10, population_size=6)
    fig = res.plot()
    assert isinstance(fig, Figure)
    line = fig.axes[0].get_lines()[0]
    assert np.array_equal(line.get_ydata(), res.history["best_cost"])
    plt.close(fig)
    html = res._repr_html_()
    assert "evaluations" in html and str(res.nfev) in html and "mpso" in html
    assert "<td>no</td>" in html


def test_optimizer_result_is_a_run_report_too():
    from piezohyst.optimize import PSO

    opt = PSO([(-1, 1)] * 2, population_size=6, rng=0, max_iterations=3)
    X = opt.ask()
    opt.tell(sphere(X))
    res = opt.result()
    assert isinstance(res, RunReport)
    assert res.evaluations == 6 and res.partial is False and res.message == "running"
    assert all(c.size == 1 for c in res._history_columns().values())


@pytest.mark.parametrize("attr", ["evaluations", "partial", "nfev"])
def test_read_only(attr):
    res = minimize(sphere, [(-1, 1)] * 2, method="de", rng=1, max_iterations=2, population_size=5)
    with pytest.raises(AttributeError):
        setattr(res, attr, 1)
