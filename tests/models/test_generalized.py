"""Generalized PI / MPI and rate-dependent PI."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import piezohyst as ph
from piezohyst import Envelope

ENVELOPE_PAIRS = {
    "identity": (Envelope.identity(), Envelope.identity()),
    "polynomial": (Envelope.polynomial(0.0, 1.0, 0.0, 0.05), Envelope.polynomial(0.02, 0.9, 0.05, 0.07)),
    "tanh": (Envelope.tanh(2.0, 0.8, 0.0, 0.0), Envelope.tanh(2.1, 0.75, 0.05, 0.02)),
}


def gpi(kind, poly=(0.0, 0.6, 0.0, 0.1)):
    rising, falling = ENVELOPE_PAIRS[kind]
    r = np.linspace(0.05, 0.8, 9)
    w = np.array([0.5, 0.2, 0.15, 0.1, 0.08, 0.06, 0.04, 0.03, 0.02])
    return ph.GeneralizedPI(r, w, poly, rising, falling, input_range=(-1.5, 1.5))


def test_generalized_play_hand_values():
    g = ph.GeneralizedPlay(0.5, Envelope.polynomial(0, 2.0), Envelope.polynomial(0, 1.0), input_range=(-1, 1))
    # rising: max(2v - 0.5, ...), falling: min(v + 0.5, ...)
    assert g.simulate([0.0, 1.0, 0.8, 0.2]).tolist() == [0.0, 1.5, 1.3, 0.7]


def test_identity_envelopes_reduce_to_classical_pi(rng):
    r = np.sort(rng.uniform(0, 1, 7))
    w = rng.uniform(0, 1, 7)
    classical = ph.PI(r, w, p0=0.7)
    generalized = ph.GeneralizedPI(r, w, (0.0, 0.7, 0.0, 0.0))
    v = rng.uniform(-2, 2, 500)
    assert np.array_equal(classical.simulate(v), generalized.simulate(v))


def test_seed2_reference_parameters():
    m = ph.papers.mpi_seed2()
    assert m.thresholds.tolist() == pytest.approx([0.1 * i for i in range(1, 10)])
    assert m.weights.tolist() == [0.2054, 0.1985, 0.0237, 0.0148, 0.0456, 0.0645, 0.0051, 0.0014, 0.0033]
    assert m.polynomial == (0.0, 0.2547, -0.00358, 0.7123)
    # on the loading curve from 0 to 1: P(1) + sum b_i (1 - r_i)
    expected = 0.2547 - 0.00358 + 0.7123 + sum(b * (1 - r) for b, r in zip(m.weights, m.thresholds, strict=False))
    assert m.simulate(np.linspace(0, 1, 11))[-1] == pytest.approx(expected, abs=1e-15)


@pytest.mark.parametrize("kind", list(ENVELOPE_PAIRS))
@given(seed=st.integers(0, 2**32 - 1))
def test_inverse_of_forward_is_identity_gpi(kind, seed):
    rng = np.random.default_rng(seed)
    m = gpi(kind)
    v = np.clip(np.cumsum(rng.normal(0, 0.1, 400)), -1.4, 1.4)
    yd = m.simulate(v)
    v_found = m.inverse().simulate(yd)
    assert np.max(np.abs(m.simulate(v_found) - yd)) <= 1e-9


@given(seed=st.integers(0, 2**32 - 1))
def test_inverse_of_forward_is_identity_mpi_seed2(seed):
    rng = np.random.default_rng(seed)
    m = ph.papers.mpi_seed2()
    v = np.clip(0.5 + np.cumsum(rng.normal(0, 0.05, 400)), 0, 1)
    yd = m.simulate(v)
    v_found = m.inverse().simulate(yd)
    assert np.max(np.abs(m.simulate(v_found) - yd)) <= 1e-9
    assert np.max(np.abs(v_found - v)) <= 1e-9


@pytest.mark.parametrize("kind", ["identity", "polynomial", "tanh"])
def test_analytic_gpi_inverse_for_equal_envelopes(kind, rng):
    g = ENVELOPE_PAIRS[kind][0]
    r = np.concatenate([[0.0], np.linspace(0.1, 0.8, 6)])
    w = np.array([0.8, 0.3, 0.2, 0.1, 0.1, 0.05, 0.05])
    m = ph.GeneralizedPI(r, w, (0, 0, 0, 0), g, g, input_range=(-1.5, 1.5))
    v = 1.2 * np.sin(np.linspace(0, 12, 600)) * np.linspace(1, 0.3, 600)
    yd = m.simulate(v)
    v_analytic = m.analytic_inverse().simulate(yd)
    np.testing.assert_allclose(v_analytic, v, rtol=0, atol=1e-9)
    np.testing.assert_allclose(v_analytic, m.inverse().simulate(yd), rtol=0, atol=1e-9)


def test_analytic_gpi_inverse_refused_with_reason():
    with pytest.raises(ValueError, match="envelopes differ"):
        gpi("polynomial").analytic_inverse()
    with pytest.raises(ValueError, match="polynomial"):
        ph.papers.mpi_seed2().analytic_inverse()


def rdpi(ts=1e-3, beta=2e-4):
    return ph.RateDependentPI(
        np.linspace(0.05, 0.6, 8),
        np.linspace(0.3, 0.05, 8),
        ts=ts,
        p0=0.8,
        beta=beta,
        rate_weights=np.full(8, 1e-4),
        filter_tau=2e-3,
    )


def loop_width_at_zero(v, y):
    """Falling-branch minus rising-branch output where the input crosses 0 (last period)."""
    dv = np.diff(v)
    up = np.flatnonzero((v[:-1] < 0) & (v[1:] >= 0) & (dv > 0))[-1]
    down = np.flatnonzero((v[:-1] > 0) & (v[1:] <= 0) & (dv < 0))[-1]

    def at(k):
        return y[k] + (y[k + 1] - y[k]) * (0 - v[k]) / (v[k + 1] - v[k])

    return at(down) - at(up)


def test_rate_dependent_pi_widens_loops_with_rate():
    m = rdpi(beta=2e-4)
    widths = []
    for freq in (1.0, 10.0, 50.0):
        t = np.arange(0, 3 / freq, 1e-4)
        v = np.sin(2 * np.pi * freq * t)
        m_fast = ph.RateDependentPI(
            m.thresholds, m.weights, ts=1e-4, p0=m.p0, beta=m.beta, rate_weights=m.rate_weights, filter_tau=m.filter_tau
        )
        widths.append(loop_width_at_zero(v, m_fast.simulate(v)))
    assert widths[0] < widths[1] < widths[2]
    # without rate terms it is the static PI, bit for bit
    static = ph.RateDependentPI(np.linspace(0.05, 0.6, 8), np.linspace(0.3, 0.05, 8), ts=1e-3, p0=0.8)
    pi = ph.PI(np.linspace(0.05, 0.6, 8), np.linspace(0.3, 0.05, 8), p0=0.8)
    v = np.sin(np.linspace(0, 30, 1000))
    assert np.array_equal(static.simulate(v), pi.simulate(v))


def test_rate_dependent_thresholds_follow_the_documented_rate():
    # one operator, p0 = 0: output = (w + c rate) * z with r = r0 + beta rate
    m = ph.RateDependentPI([0.1], [1.0], ts=0.01, p0=0.0, beta=0.01, rate_weights=[0.5])
    y = m.simulate([0.0, 1.0, 1.5])
    # k=0: rate 0 -> z = 0 ; k=1: rate = 100, r = 1.1, z = max(1 - 1.1, min(2.1, 0)) = 0
    # k=2: rate = 50, r = 0.6, z = max(0.9, ...) = 0.9, w = 1 + 25
    assert y.tolist() == pytest.approx([0.0, 0.0, 26 * 0.9], abs=1e-12)


@given(seed=st.integers(0, 2**32 - 1))
def test_inverse_of_forward_is_identity_rdpi(seed):
    rng = np.random.default_rng(seed)
    m = rdpi()
    v = np.cumsum(rng.normal(0, 0.02, 500))
    yd = m.simulate(v)
    v_found = m.inverse().simulate(yd)
    assert np.max(np.abs(m.simulate(v_found) - yd)) <= 1e-9
