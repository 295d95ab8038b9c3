"""TuningResult is a RunReport (issue 18): evaluations = nfev, one history row per iteration,
a convergence plot and a notebook display."""

import matplotlib
import numpy as np

import piezohyst as ph
from piezohyst.control import TuningResult
from piezohyst.optimize import RunReport

matplotlib.use("Agg")

STAGE = ph.virtual_stage()


def test_tuning_result_is_a_run_report():
    import matplotlib.pyplot as plt
    from matplotlib.figure import Figure

    ref = ph.sine(10, 4e-6, 0.1, 1 / STAGE.sample_time, offset=7e-6)[1]
    res = ph.tune(
        ph.PID(kp=1e6, ki=1e9),
        {"kp": (1e5, 1e7), "ki": (1e8, 1e10)},
        ref,
        stage=STAGE,
        method="de",
        rng=1,
        max_iterations=3,
        population_size=5,
        skip=0.02,
    )
    assert isinstance(res, RunReport) and isinstance(res, TuningResult)
    assert res.evaluations == res.nfev == 3 * 5
    assert res.partial is False and res.wall_time > 0
    cols = res._history_columns()
    assert cols and all(c.size == 3 for c in cols.values())
    assert np.array_equal(cols["best_cost"], res.history["best_cost"])
    fig = res.plot()
    assert isinstance(fig, Figure)
    plt.close(fig)
    html = res._repr_html_()
    assert "PID" in html and "evaluations" in html and "15" in html
