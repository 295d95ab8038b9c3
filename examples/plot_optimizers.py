"""
Population optimizers: CSS, PSO, MPSO and DE on one fit
=======================================================

Fit a Bouc–Wen hysteresis model (``a``, ``beta``, ``gamma``, ``d``) to a noisy record with
each of the package's population optimizers (ask/tell objects; :func:`piezohyst.minimize`
drives them). Every population is simulated in one Rust call (:func:`piezohyst.batch_rmse`),
so a run of 40 iterations × 40 candidates takes a fraction of a second.
"""

import matplotlib.pyplot as plt
import numpy as np

import piezohyst as ph

rng = np.random.default_rng(0)
t = np.linspace(0, 1, 1500)
v = 0.5 + 0.45 * np.exp(-2 * t) * np.sin(2 * np.pi * 5 * t)
truth = ph.BoucWen(a=0.5, beta=2.0, gamma=0.5, d=1.0)
y = truth.simulate(v) + 1e-3 * rng.standard_normal(v.size)

bounds = [(0.05, 1.0), (0.1, 5.0), (-1.0, 1.0), (0.5, 2.0)]  # a, beta, gamma, d


def cost(X):
    """RMSE of each candidate (rows a, beta, gamma, d; the exponent n fixed at 1)."""
    rows = np.column_stack([X[:, 0], X[:, 1], X[:, 2], np.ones(len(X)), X[:, 3]])
    return ph.batch_rmse(truth, rows, v, y)


fig, ax = plt.subplots(figsize=(7, 3.6), layout="constrained")
for method in ("css", "pso", "mpso", "de"):
    res = ph.minimize(cost, bounds, method=method, population_size=40, max_iterations=40, rng=1)
    print(f"{method:4s} RMSE {res.fun:.2e} after {res.nfev} evaluations: a, beta, gamma, d = {np.round(res.x, 3)}")
    ax.semilogy(res.history["best_cost"], label=method.upper())
ax.axhline(1e-3, color="k", lw=0.8, ls="--", label="noise level")
ax.set(xlabel="iteration", ylabel="best RMSE so far")
ax.legend()
