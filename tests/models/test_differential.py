"""Bouc–Wen, Duhem, Dahl against tight ODE references."""

import itertools

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import piezohyst as ph


def ode_reference(rhs, v, h0=0.0):
    """Integrate dh/dt = rhs(h, dv/dt) with v linear between samples (1 s per sample)."""
    h = [h0]
    x = h0
    for a, b in itertools.pairwise(v):
        dv = b - a
        sol = solve_ivp(lambda t, y: [rhs(y[0], a + dv * t, dv)], (0, 1), [x], method="DOP853", rtol=1e-12, atol=1e-14)
        x = sol.y[0, -1]
        h.append(x)
    return np.array(h)


@pytest.mark.parametrize("a,beta,gamma,amp", [(1.0, 2.0, 0.5, 1.5), (5e4, 800.0, -1100.0, 1e-3), (0.8, 1.0, -0.6, 3.0)])
def test_bouc_wen_exact_integrator_matches_ode(a, beta, gamma, amp):
    rng = np.random.default_rng(3)
    v = np.concatenate([[0.0], amp * np.sin(np.linspace(0, 8, 80)) + amp * 0.1 * rng.normal(size=80)])
    m = ph.BoucWen(a, beta, gamma, n=1, d=0.0)
    h = -m.simulate(v)

    def rhs(h, w, dw):
        return a * dw - beta * abs(dw) * h - gamma * dw * abs(h)

    ref = ode_reference(rhs, v)
    scale = np.max(np.abs(ref))
    assert np.max(np.abs(h - ref[1:] if h.size != ref.size else h - ref)) <= 1e-8 * scale


def test_bouc_wen_general_n_matches_ode():
    a, beta, gamma, n = 1.0, 1.5, 0.5, 2.0
    v = np.concatenate([[0.0], 2 * np.sin(np.linspace(0, 9, 60))])
    h = -ph.BoucWen(a, beta, gamma, n=n).simulate(v)

    def rhs(h, w, dw):
        return a * dw - beta * abs(dw) * abs(h) ** (n - 1) * h - gamma * dw * abs(h) ** n

    ref = ode_reference(rhs, v)
    assert np.max(np.abs(h - ref)) <= 1e-6 * np.max(np.abs(ref))


def test_bouc_wen_h_stays_bounded_on_long_random_input():
    a, beta, gamma = 1.0, 2.0, 0.5
    rng = np.random.default_rng(0)
    v = np.cumsum(rng.normal(size=200_000))
    h = -ph.BoucWen(a, beta, gamma).simulate(v)
    # |h| <= a / (beta - |gamma|)... the tight bound for beta > |gamma| is a/(beta - gamma)
    assert np.max(np.abs(h)) <= a / (beta - gamma) + 1e-12
    assert np.all(np.isfinite(h))


def test_dahl_exponent_one_equals_bouc_wen():
    sigma, hc = 3.0, 0.7
    v = np.sin(np.linspace(0, 20, 500)) * 2
    dahl = ph.Dahl(sigma, hc, 1.0).simulate(v)
    bw = -ph.BoucWen(sigma, sigma / hc, 0.0).simulate(v)
    np.testing.assert_allclose(dahl, bw, rtol=0, atol=1e-12)


@pytest.mark.parametrize("a", [0.5, 2.0])
def test_dahl_closed_form_matches_ode(a):
    sigma, hc = 2.0, 1.0
    v = np.concatenate([[0.0], 1.5 * np.sin(np.linspace(0, 7, 50))])
    h = ph.Dahl(sigma, hc, a).simulate(v)

    def rhs(h, w, dw):
        base = max(1 - h / hc * np.sign(dw), 0.0)
        return sigma * dw * base**a

    ref = ode_reference(rhs, v)
    assert np.max(np.abs(h - ref)) <= 1e-8


@pytest.mark.parametrize("alpha", [0.0, 0.3, 4.0])
def test_duhem_closed_form_matches_ode(alpha):
    f = (0.1, 0.8, -0.1, 0.05)
    g = (0.5, 0.1, 0.2, -0.02)
    v = np.concatenate([[0.0], 1.5 * np.sin(np.linspace(0, 7, 50))])
    y = ph.Duhem(alpha, f, g).simulate(v)
    pf, pg = np.polynomial.Polynomial(f), np.polynomial.Polynomial(g)

    def rhs(y, u, du):
        return alpha * abs(du) * (pf(u) - y) + pg(u) * du

    ref = ode_reference(rhs, v)
    assert np.max(np.abs(y - ref)) <= 1e-9 * max(1.0, np.max(np.abs(ref)))


def test_bouc_wen_benchmark_form():
    m = ph.BoucWen.from_benchmark(5e4, 1e3, 0.8, -1.1, 1.0)
    assert (m.a, m.beta, m.gamma, m.n) == (5e4, 800.0, -1100.0, 1.0)


def test_bouc_wen_per_sample_inverse():
    # y = d w - h is increasing when d exceeds the largest dh/dw = a + (beta - gamma) * a / (beta - gamma)
    m = ph.BoucWen(1.0, 2.0, 0.5, d=2.5)
    v = 1.5 * np.sin(np.linspace(0, 12, 600)) * np.linspace(1, 0.3, 600)
    yd = m.simulate(v)
    v_found = m.inverse().simulate(yd)
    assert np.max(np.abs(m.simulate(v_found) - yd)) <= 1e-9
    assert np.max(np.abs(v_found - v)) <= 1e-9
