"""Batch evaluation equals one-by-one simulation, bit for bit, whatever the thread count."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

import piezohyst as ph
from tests.models_zoo import drive, zoo

ZOO = zoo()


def perturbed_rows(m, count, rng):
    rows = []
    for _ in range(count):
        candidate = m.to_row() * (1 + rng.uniform(-0.02, 0.02, m.to_row().size))
        try:
            ph._core.validate(m.family, list(m.dims), candidate)
            rows.append(candidate)
        except ValueError:
            rows.append(m.to_row())
    return np.array(rows)


@pytest.mark.parametrize("name", list(ZOO))
def test_batch_simulate_matches_single_simulation(name, rng):
    m = ZOO[name]
    rows = perturbed_rows(m, 19, rng)  # not a multiple of the lane width
    v = drive(600)
    out = ph.batch_simulate(m, rows, v)
    assert out.shape == (19, 600)
    for j, row in enumerate(rows):
        single = ph._core.simulate(m.family, list(m.dims), row, v, ph._core.initial_state(m.family, list(m.dims), row))
        assert np.array_equal(out[j], single), j
    rmse = ph.batch_rmse(m, rows, v, out[0])
    expected = np.sqrt(np.mean((out - out[0]) ** 2, axis=1))
    np.testing.assert_allclose(rmse, expected, rtol=1e-12, atol=1e-15)
    assert rmse[0] == 0.0


def test_invalid_rows_raise_with_their_index_or_cost_what_was_asked():
    m = ph.PI([0.1, 0.2], [0.5, 0.5])
    rows = np.array([m.to_row(), [1.0, 0.3, 0.2, 0.5, 0.5], m.to_row()])
    v = np.sin(np.linspace(0, 6, 100))
    with pytest.raises(ValueError, match=r"params\[1\]: thresholds\[1\] = 0.2"):
        ph.batch_rmse(m, rows, v, v)
    cost = ph.batch_rmse(m, rows, v, v, invalid_cost=1e9)
    assert cost[1] == 1e9 and cost[0] == cost[2] < 1e9


def test_diverging_rows_cost_infinity_not_nan():
    m = ph.BoucWen(1.0, -5.0, -5.0)  # beta + gamma < 0: h grows without bound
    v = np.concatenate([np.linspace(0, 300, 300)])
    cost = ph.batch_rmse(m, np.array([m.to_row(), ph.BoucWen(1.0, 2.0, 0.5).to_row()]), v, np.zeros(300))
    assert cost[0] == np.inf and np.isfinite(cost[1])
    with pytest.raises(ValueError, match="diverged at sample"):
        m.simulate(v)


SCRIPT = """
import json, sys
import numpy as np
import piezohyst as ph
rng = np.random.default_rng(5)
n = 9
rows = np.zeros((37, 1 + 2 * n))
rows[:, 0] = rng.uniform(0.5, 1.5, 37)
rows[:, 1:1 + n] = np.sort(rng.uniform(0, 1, (37, n)), axis=1)
rows[:, 1 + n:] = rng.uniform(-0.05, 0.3, (37, n))
v = np.cumsum(rng.normal(size=3000)) / 20
t = np.sin(np.arange(3000) / 50)
pre = ph.Preisach(5, (-2, 2), rng.uniform(0, 1, 15), slope=0.2)
prows = np.array([pre.to_row()] * 5)
print(json.dumps({"threads": ph._core.thread_count(),
                  "pi": ph.batch_rmse("pi", rows, v, t, dims=[n, 0]).tolist(),
                  "sim": ph.batch_simulate("pi", rows, v, dims=[n, 0])[:, ::97].tolist(),
                  "preisach": ph.batch_rmse(pre, prows, v, t).tolist()}))
"""


def test_results_do_not_depend_on_thread_count():
    results = []
    for threads in ("1", "2"):
        env = dict(os.environ, RAYON_NUM_THREADS=threads)
        out = subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True, text=True, check=True)
        results.append(json.loads(out.stdout))
    assert [r["threads"] for r in results] == [1, 2]
    for key in ("pi", "sim", "preisach"):
        assert results[0][key] == results[1][key]
