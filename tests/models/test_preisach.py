"""Discretized Preisach: values, wiping-out, congruency, inverse."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import piezohyst as ph


def model(levels=8, seed=0, slope=0.2, memory=64):
    rng = np.random.default_rng(seed)
    return ph.Preisach(levels, (-1.0, 1.0), rng.uniform(0, 1, levels * (levels + 1) // 2), slope=slope, memory=memory)


def test_uniform_density_everett_closed_form():
    # one cell covering the whole triangle with mass 1: up-mass after rising to a from -1
    m = ph.Preisach(1, (-1.0, 1.0), [1.0])
    a = np.linspace(-1, 1, 21)
    y = m.simulate(a)
    np.testing.assert_allclose(y, ((a + 1) / 2) ** 2, rtol=0, atol=1e-15)
    # then falling to b from the top: mass of {beta < b}: 1 - ((1 - b)/2)^2
    b = np.linspace(1, -1, 21)
    y = m.simulate(np.concatenate([a, b]))[21:]
    np.testing.assert_allclose(y, 1 - ((1 - b) / 2) ** 2, rtol=0, atol=1e-15)


def test_saturation_and_total_mass():
    m = model()
    y = m.simulate([-2.0, 2.0, -2.0, 5.0])
    assert y[0] == pytest.approx(0.2 * -2.0)
    assert y[1] == pytest.approx(m.weights.sum() + 0.4, abs=1e-12)
    assert y[3] == pytest.approx(m.weights.sum() + 1.0, abs=1e-12)


def test_wiping_out():
    m = model()
    path_minor = np.concatenate(
        [
            np.linspace(-1, 0.8, 40),
            np.linspace(0.8, -0.2, 30),
            np.linspace(-0.2, 0.5, 20),
            np.linspace(0.5, 0.0, 10),
            np.linspace(0.0, 0.9, 30),
        ]
    )
    direct = np.concatenate([np.linspace(-1, 0.8, 40), np.linspace(0.8, 0.9, 5)])
    assert m.simulate(path_minor)[-1] == pytest.approx(m.simulate(direct)[-1], abs=1e-13)


def test_congruency_of_minor_loops():
    # the same input oscillation between 0.1 and 0.4 after different histories: loops differ
    # only by a constant shift (Preisach congruency)
    m = model(slope=0.0)
    osc = np.concatenate([np.linspace(0.1, 0.4, 30), np.linspace(0.4, 0.1, 30)])
    h1 = np.concatenate([np.linspace(-1, 0.9, 50), np.linspace(0.9, 0.1, 40)])
    h2 = np.concatenate(
        [np.linspace(-1, 0.6, 50), np.linspace(0.6, -0.5, 40), np.linspace(-0.5, 0.5, 40), np.linspace(0.5, 0.1, 40)]
    )
    y1 = m.simulate(np.concatenate([h1, osc]))[-60:]
    y2 = m.simulate(np.concatenate([h2, osc]))[-60:]
    d = y1 - y2
    assert np.ptp(d) < 1e-12 and abs(d[0]) > 1e-3


def test_rate_independence():
    m = model()
    v = np.sin(np.linspace(0, 9, 200)) * np.linspace(1, 0.3, 200)
    reps = np.random.default_rng(1).integers(1, 4, v.size)
    y = m.simulate(v)
    ys = m.simulate(np.repeat(v, reps))
    assert np.array_equal(ys[np.cumsum(reps) - 1], y)


@given(seed=st.integers(0, 2**32 - 1))
def test_inverse_of_forward_is_identity_preisach(seed):
    rng = np.random.default_rng(seed)
    m = model(seed=seed % 1000)
    v = np.clip(np.cumsum(rng.normal(0, 0.15, 300)), -1.2, 1.2)
    yd = m.simulate(v)
    v_found = m.inverse().simulate(yd)
    assert np.max(np.abs(m.simulate(v_found) - yd)) <= 1e-9


def test_memory_limit():
    v = np.sin(np.linspace(0, 40, 2000)) * np.linspace(1, 0.05, 2000)  # ~13 nested extrema
    few = np.concatenate([np.linspace(-1, 0.9, 40), np.linspace(0.9, -0.6, 40), np.linspace(-0.6, 0.5, 40)])
    # within the memory, a capped model is exact
    assert np.array_equal(model(memory=4).simulate(few), model(memory=64).simulate(few))
    # beyond it, the forgotten loops change the output but it stays finite and within the
    # saturation bounds
    y = model(memory=4).simulate(v)
    assert not np.array_equal(y, model(memory=64).simulate(v))
    m = model(memory=4)
    assert np.all(np.isfinite(y))
    assert np.all(y >= 0.2 * v - 1e-12) and np.all(y <= m.weights.sum() + 0.2 * v + 1e-12)
