"""Play and PI: hand-checked values, play band, rate independence, wiping-out, inverses."""

import itertools

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

import piezohyst as ph

finite = st.floats(-5, 5, allow_nan=False, allow_infinity=False)
inputs = arrays(np.float64, st.integers(1, 200), elements=finite)


def random_pi(rng, n=6, signed=False):
    r = np.sort(rng.uniform(0.0, 1.0, n)) + np.arange(n) * 1e-3
    w = rng.uniform(0.05, 0.5, n)
    if signed:  # negative weights that keep every partial sum positive
        w[1::2] *= -0.3
    return ph.PI(r, w, p0=rng.uniform(0.3, 1.5))


def test_pi_hand_values():
    m = ph.PI([0.5, 1.0], [1.0, 2.0], p0=0.5)
    v = [0.0, 2.0, 1.0, -1.0]
    # z_0.5: 0, 1.5, 1.5, -0.5 ; z_1: 0, 1, 1, 0
    expected = [0.0, 0.5 * 2 + 1.5 + 2.0, 0.5 + 1.5 + 2.0, -0.5 - 0.5 + 0.0]
    assert m.simulate(v).tolist() == expected


@given(inputs, st.floats(0, 3))
def test_play_stays_in_band_and_moves_less_than_input(v, r):
    z = ph.PlayOperator(r).simulate(v)
    assert np.all(z >= v - r - 1e-12) and np.all(z <= v + r + 1e-12)
    assert np.all(np.abs(np.diff(z)) <= np.abs(np.diff(v)) + 1e-12)
    assert z[0] == max(v[0] - r, min(v[0] + r, 0.0))


@given(inputs, st.lists(st.integers(0, 3), min_size=200, max_size=200))
def test_repeating_samples_changes_nothing_at_matched_samples(v, repeats):
    m = ph.PI([0.1, 0.4, 0.9], [0.3, 0.2, 0.5], p0=1.0)
    reps = np.array(repeats[: v.size]) + 1
    stretched = np.repeat(v, reps)
    y = m.simulate(v)
    ys = m.simulate(stretched)
    last = np.cumsum(reps) - 1
    assert np.array_equal(ys[last], y)


def test_time_stretching_with_interpolated_samples_changes_nothing(rng):
    m = random_pi(rng)
    v = rng.uniform(-2, 2, 300)
    fine = np.concatenate([np.linspace(a, b, 7, endpoint=False) for a, b in itertools.pairwise(v)] + [v[-1:]])
    y, yf = m.simulate(v), m.simulate(fine)
    np.testing.assert_allclose(yf[::7], y, rtol=0, atol=1e-12)


def test_wiping_out_pi():
    m = ph.PI([0.1, 0.3, 0.6], [0.4, 0.3, 0.2], p0=1.0)
    up = np.linspace(0, 2, 50)
    minor = np.concatenate([np.linspace(2, 1.0, 20), np.linspace(1.0, 1.8, 20), np.linspace(1.8, 1.3, 20)])
    after = np.linspace(1.3, 2.5, 40)
    with_minor = m.simulate(np.concatenate([up, minor, after]))
    straight = m.simulate(np.concatenate([up, [2.0], np.linspace(2.0, 2.5, 10)]))
    assert with_minor[-1] == straight[-1]
    assert np.array_equal(m.simulate(np.concatenate([up, minor, after]), initial_state=None)[-1:], straight[-1:])


def test_analytic_inverse_equals_per_sample_inverse(rng):
    for signed in (False, True):
        for _ in range(5):
            m = random_pi(rng, n=8, signed=signed)
            yd = m.simulate(2.0 * np.sin(np.linspace(0, 20, 800)) * np.linspace(1, 0.2, 800) + rng.normal(0, 0.05, 800))
            v_exact = m.inverse().simulate(yd)
            v_analytic = m.analytic_inverse().simulate(yd)
            assert np.max(np.abs(v_exact - v_analytic)) <= 1e-12


def test_analytic_inverse_parameters_match_spec():
    m = ph.PI([1.0, 2.0], [1.0, 2.0], p0=1.0)
    inv = m.analytic_inverse()
    # S = 1, 2, 4; r' = phi(r) = [1, 1*2 + 1*1] ; p' = -p_i/(S_i S_{i-1})
    assert inv.p0 == 1.0
    assert inv.thresholds.tolist() == [1.0, 3.0]
    assert inv.weights.tolist() == [-0.5, -0.25]


@given(st.integers(0, 2**32 - 1))
def test_inverse_of_forward_is_identity_pi(seed):
    rng = np.random.default_rng(seed)
    m = random_pi(rng, n=int(rng.integers(1, 12)), signed=bool(rng.integers(2)))
    v = 3 * np.cumsum(rng.normal(size=300)) / np.sqrt(300)
    yd = m.simulate(v)
    v_found = m.inverse().simulate(yd)
    assert np.max(np.abs(m.simulate(v_found) - yd)) <= 1e-9
    assert np.max(np.abs(v_found - v)) <= 1e-9


def test_non_invertible_pi_has_no_inverse_and_says_which_partial_sum():
    m = ph.PI([0.2, 0.4], [-0.5, -0.6], p0=1.0)
    with pytest.raises(ValueError, match=r"S\[2\] = p0 \+ sum\(weights\[:2\]\) = -0.0999"):
        m.analytic_inverse()


def test_step_matches_simulate_and_state_round_trips(rng):
    m = random_pi(rng)
    v = rng.uniform(-1, 1, 100)
    y = m.simulate(v)
    ys = [m.step(x) for x in v]
    assert np.array_equal(ys, y)
    saved = m.state
    tail = rng.uniform(-1, 1, 20)
    y_tail = m.simulate(tail, initial_state=saved)
    assert np.array_equal([m.step(x) for x in tail], y_tail)
    m.reset()
    assert np.array_equal(m.state, np.zeros(6))


def test_inverse_step_tracks_forward_state(rng):
    m = random_pi(rng)
    yd = m.simulate(np.sin(np.linspace(0, 10, 200)))
    inv = m.inverse()
    v = [inv.step(x) for x in yd]
    assert np.array_equal(v, m.inverse().simulate(yd))
    fwd = m.simulate(v)
    assert np.max(np.abs(fwd - yd)) <= 1e-12
    m.simulate(v)  # the model's own state is untouched by simulate
    assert np.array_equal(m.state, np.zeros(6))


def test_creep_composes_and_stays_invertible(rng):
    creep = ph.Creep(1e-3, [0.01, 0.1, 1.0], [0.02, 0.02, 0.02])
    base = random_pi(rng)
    m = ph.PI(base.thresholds, base.weights, base.p0, creep=creep)
    v = np.concatenate([np.linspace(0, 1, 100), np.ones(3000)])
    y = m.simulate(v)
    np.testing.assert_allclose(y - base.simulate(v), creep.simulate(v), rtol=0, atol=1e-14)
    assert y[-1] - y[100] > 0.03  # keeps creeping while the input is held
    v_found = m.inverse().simulate(y)
    assert np.max(np.abs(m.simulate(v_found) - y)) <= 1e-9


def test_creep_step_response_is_the_sum_of_exponentials():
    ts, taus, c = 1e-3, np.array([0.01, 0.1, 1.0]), np.array([0.5, 0.3, 0.2])
    y = ph.Creep(ts, taus, c).simulate(np.ones(5000))
    k = np.arange(1, 5001)[:, None]
    expected = (c * (1 - np.exp(-k * ts / taus))).sum(axis=1)
    np.testing.assert_allclose(y, expected, rtol=0, atol=1e-13)
