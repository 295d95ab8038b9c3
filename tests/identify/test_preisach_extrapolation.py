"""A fitted Preisach grid continues its outer slope beyond the training input's range
(issue 14: validation inputs outside the training range)."""

from __future__ import annotations

import numpy as np
import pytest

import piezohyst as ph
from piezohyst.errors import ParameterError


def _truth() -> ph.Preisach:
    """A dense Preisach (40 levels, smooth density) over a range wider than any training span."""
    levels, lo, hi = 40, -1.5, 1.5
    grid = np.linspace(lo, hi, levels)
    a, b = np.meshgrid(grid, grid, indexing="ij")
    density = np.tril(np.exp(-0.5 * ((a - b) / 0.5) ** 2 - 0.5 * ((a + b) / 2.0) ** 2))
    return ph.Preisach(levels, (lo, hi), density, slope=0.3 * density.sum() / 3.0)


def test_training_range_unchanged_and_outer_slope_continues():
    t = np.linspace(0, 12, 6000)
    amp = np.where(t < 6, 0.8, 1.0)  # the validation half swings 25 % wider than the training half
    v = amp * np.sin(2 * np.pi * t)
    y = _truth().simulate(v)
    n = v.size // 2
    fit = ph.identify(v[:n], y[:n], model="preisach", levels=12)
    m = fit.model
    assert isinstance(m, ph.Preisach)
    lo, hi = float(v[:n].min()), float(v[:n].max())
    step = (hi - lo) / 12
    assert m.levels == 18 and m.input_range == pytest.approx((lo - 3 * step, hi + 3 * step))
    bare = ph.Preisach(12, (lo, hi), m.weight_matrix()[3:15, 3:15], m.offset + 3 * m.weights[0], m.slope, m.memory)
    # inside the training range: the same model
    np.testing.assert_allclose(m.simulate(v[:n]), bare.simulate(v[:n]), rtol=0, atol=1e-9 * np.ptp(y))
    # beyond it: the loop's outer slope goes on, the flat continuation missed by far more
    sim, flat = m.simulate(v), bare.simulate(v)
    out = (v < lo) | (v > hi)
    assert out[n:].mean() > 0.2
    span = float(np.ptp(y[n:]))
    err = 100 * np.sqrt(np.mean((sim[n:] - y[n:]) ** 2)) / span
    err_flat = 100 * np.sqrt(np.mean((flat[n:] - y[n:]) ** 2)) / span
    assert err < 0.65 * err_flat, (err, err_flat)  # 2.69 % against 4.62 %


def test_extrapolated_checks_cells():
    m = ph.Preisach(4, (0.0, 1.0), np.ones(10))
    assert m.extrapolated(0) is m
    with pytest.raises(ParameterError, match="cells"):
        m.extrapolated(-1)
