"""MIMO feedforward (issue 15 item 4): the linear part's least-squares inverse within a
bandwidth, the per-actuator hysteresis inverse, the iteration on a nonlinear model, the mirror
geometry; every number checked against an independent computation."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import scipy.signal

import piezohyst as ph
from piezohyst.control.mimo import MimoFeedforward, frequency_response, mirror_matrix, periodic_response

FS = 6400.0


def resonant_mimo(seed: int = 0, scale: float = 1.0):
    """A 3x3 discrete system with two lightly damped modes (640 and 790 Hz, like the FSM) and a
    coupled first-order part; DC gain ~ 2e-5 m/V."""
    rng = np.random.default_rng(seed)
    blocks = []
    for f0, zeta in ((640.0 * scale, 0.03), (790.0 * scale, 0.02)):
        w0 = 2 * np.pi * f0
        blocks.append(np.array([[0.0, 1.0], [-(w0**2), -2 * zeta * w0]]))
    ac = np.zeros((6, 6))
    ac[:2, :2], ac[2:4, 2:4] = blocks
    ac[4:, 4:] = np.diag([-2 * np.pi * 300.0, -2 * np.pi * 1500.0])
    bc = rng.standard_normal((6, 3))
    bc[[1, 3]] *= (2 * np.pi * 700.0) ** 2
    bc[4:] *= 2 * np.pi * 800.0
    cc = np.zeros((3, 6))
    cc[:, [0, 2, 4, 5]] = rng.standard_normal((3, 4))
    cc += 0.2 * rng.standard_normal((3, 6)) * np.array([1, 0, 1, 0, 1, 1])
    a, b, c, d, _ = scipy.signal.cont2discrete((ac, bc, cc, np.zeros((3, 3))), 1 / FS, method="zoh")
    g0 = c @ np.linalg.solve(np.eye(6) - a, b)
    k = 2e-5 / np.linalg.norm(g0, 2)
    return a, b, k * c, k * d


def lissajous(n: int = 6400, amp: float = 1e-6):
    t = np.arange(n) / FS
    return np.column_stack(
        [
            amp * np.sin(2 * np.pi * 20 * t),
            amp * np.sin(2 * np.pi * 30 * t + 0.5),
            0.3 * amp * np.cos(2 * np.pi * 10 * t),
        ]
    )


def test_frequency_response_matches_scipy_per_channel():
    a, b, c, d = resonant_mimo()
    f = np.array([0.0, 100.0, 640.0, 800.0, 3000.0])
    g = frequency_response(a, b, c, d, f, FS)
    z = np.exp(2j * np.pi * f / FS)
    direct = np.stack([c @ np.linalg.inv(zk * np.eye(6) - a) @ b + d for zk in z])
    np.testing.assert_allclose(g, direct, rtol=1e-9, atol=1e-9 * np.abs(direct).max())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", scipy.signal.BadCoefficients)  # scipy goes through a transfer function
        _, h = scipy.signal.dfreqresp(
            scipy.signal.dlti(a, b[:, [1]], c[[2]], d[[2], [1]], dt=1 / FS), 2 * np.pi * f / FS
        )
    np.testing.assert_allclose(g[:, 2, 1], h, rtol=1e-6)  # scipy's polynomials: 1e-7 relative
    # a defective A (a Jordan block) takes the per-frequency solve: the same numbers
    aj = np.array([[0.5, 1.0], [0.0, 0.5]])
    gj = frequency_response(aj, np.eye(2), np.eye(2), np.zeros((2, 2)), [10.0], 100.0)[0]
    z = np.exp(2j * np.pi * 10 / 100)
    np.testing.assert_allclose(gj, np.linalg.inv(z * np.eye(2) - aj), rtol=1e-12)


def test_periodic_response_is_the_steady_state_of_a_time_simulation():
    a, b, c, d = resonant_mimo()
    rng = np.random.default_rng(3)
    w = rng.standard_normal((512, 3))
    _, y, _ = scipy.signal.dlsim(scipy.signal.dlti(a, b, c, d, dt=1 / FS), np.tile(w, (40, 1)))
    np.testing.assert_allclose(periodic_response(a, b, c, d, w), y[-512:], rtol=0, atol=1e-9 * np.abs(y).max())


def test_linear_inverse_tracks_a_lissajous_within_the_bandwidth():
    a, b, c, d = resonant_mimo()
    r = lissajous()
    ff = MimoFeedforward(a, b, c, d, fs=FS, bandwidth=1000.0, regularization=1e-8)
    y = periodic_response(a, b, c, d, ff.linear_command(r))
    assert np.sqrt(np.mean((y - r) ** 2)) < 1e-4 * np.sqrt(np.mean(r**2))
    # the naive static inverse (DC gain only) misses the dynamics: 100x worse at least
    g0 = frequency_response(a, b, c, d, [0.0], FS)[0].real
    y0 = periodic_response(a, b, c, d, np.linalg.solve(g0, r.T).T)
    assert np.sqrt(np.mean((y0 - r) ** 2)) > 100 * np.sqrt(np.mean((y - r) ** 2))
    # content above the bandwidth is not followed (and not amplified)
    t = np.arange(6400) / FS
    high = r + 0.1e-6 * np.sin(2 * np.pi * 2000 * t)[:, None]
    w_high = ff.linear_command(high)
    np.testing.assert_allclose(w_high, ff.linear_command(r), atol=1e-12 * np.abs(w_high).max() + 1e-15)


def test_hysteresis_inverse_per_actuator_removes_the_hysteresis_error():
    a, b, c, d = resonant_mimo()
    r = lissajous(amp=4e-6)
    pis = [ph.PI([0.0, 0.02, 0.05, 0.1], [1.0, 0.3 + 0.05 * i, 0.2, 0.1]) for i in range(3)]

    def plant(v):  # Hammerstein: each actuator's PI, then the linear dynamics (steady state, last period)
        w = np.column_stack([pis[i].simulate(v[:, i]) for i in range(3)])
        return periodic_response(a, b, c, d, w[-r.shape[0] :])

    full = MimoFeedforward(a, b, c, d, fs=FS, hysteresis=pis, bandwidth=1000.0)
    linear_only = MimoFeedforward(a, b, c, d, fs=FS, bandwidth=1000.0)
    e_full = plant(full.command(r, periods=2)) - r
    e_lin = plant(linear_only.command(r, periods=2)) - r
    rms = np.sqrt(np.mean(r**2))
    assert np.sqrt(np.mean(e_full**2)) < 1e-3 * rms
    assert np.sqrt(np.mean(e_lin**2)) > 0.05 * rms  # the hysteresis left in: > 5 % error


def test_iteration_on_a_model_with_hysteresis_in_the_loop():
    a, b, c, d = resonant_mimo()
    r = lissajous(n=1280, amp=3e-6)
    pis = [ph.PI([0.0, 0.03, 0.08], [0.8, 0.3, 0.2]) for _ in range(3)]

    def model(u):  # hysteresis the linear inverse does not know of; full time simulation
        w = np.column_stack([pis[i].simulate(u[:, i]) for i in range(3)])
        n = r.shape[0]
        return np.vstack([periodic_response(a, b, c, d, w[k : k + n]) for k in range(0, w.shape[0], n)])

    # the feedforward's linear part: the best linear approximation, the PI's secant gain at this level
    probe = np.tile(MimoFeedforward(a, b, c, d, fs=FS).linear_command(r), (2, 1))
    k = [np.std(pis[i].simulate(probe[:, i])) / np.std(probe[:, i]) for i in range(3)]
    ff = MimoFeedforward(a, b * np.array(k), c, d, fs=FS, bandwidth=1000.0)
    u, err = ff.iterate(model, r, iterations=8, periods=2)
    assert u.shape == (1280, 3) and err.shape == (9,)
    assert err[-1] < 0.02 * err[0] and np.all(np.diff(err[:4]) < 0)


def test_mirror_matrix_maps_tip_tilt_piston():
    m = mirror_matrix(0.02)
    # a pure tip (about x) moves the sensor at 90 deg by +r * tip and the two others by -r/2 * tip
    np.testing.assert_allclose(m @ [0.0, 1e-4, 0.0], 1e-4 * 0.02 * np.array([1.0, -0.5, -0.5]), atol=1e-18)
    np.testing.assert_allclose(m @ [1e-6, 0, 0], [1e-6] * 3)
    with pytest.raises(ph.ParameterError, match="collinear"):
        mirror_matrix(0.02, (0.0, 180.0, 0.0))


def test_bad_arguments_are_named():
    a, b, c, d = resonant_mimo()
    with pytest.raises(ph.ParameterError, match=r"A \(6, 6\), B \(6, 3\), C \(2, 6\), D \(3, 3\) do not fit"):
        MimoFeedforward(a, b, c[:2], d, fs=FS)
    with pytest.raises(ph.ParameterError, match="not stable"):
        MimoFeedforward(1.01 * np.eye(2), np.eye(2), np.eye(2), np.zeros((2, 2)), fs=FS)
    with pytest.raises(ph.ParameterError, match=r"bandwidth = 4000 Hz is above the Nyquist frequency 3200 Hz"):
        MimoFeedforward(a, b, c, d, fs=FS, bandwidth=4000.0)
    with pytest.raises(ph.ParameterError, match="hysteresis has 2 models, the linear part has 3 inputs"):
        MimoFeedforward(a, b, c, d, fs=FS, hysteresis=[ph.PI([0.0], [1.0])] * 2)
    ff = MimoFeedforward(a, b, c, d, fs=FS)
    with pytest.raises(ph.ParameterError, match=r"reference has shape \(100, 2\), expected \(N, 3\)"):
        ff.linear_command(np.zeros((100, 2)))
    with pytest.raises(ph.ParameterError, match=r"reference\[3, 1\] = nan is not finite"):
        ff.linear_command(np.where(np.arange(300).reshape(100, 3) == 10, np.nan, 0.0))
    with pytest.raises(ph.ParameterError, match=r"A\[0, 1\] = inf is not finite"):
        MimoFeedforward([[0.5, np.inf], [0, 0.5]], np.eye(2), np.eye(2), np.zeros((2, 2)), fs=FS)


def _hammerstein(a, b, c, d, th, wt):
    from piezohyst.models.mimo import MimoModel

    n = a.shape[0]
    return MimoModel(A=a, B=b, C=c, D=d, E=b.copy(), F=d.copy(), G=np.zeros((3, n)), H=np.eye(3),
                     thresholds=th, weights=wt, fs=FS, structure="hammerstein")  # fmt: skip


def test_virtual_mirror_tip_tilt_lissajous_with_a_perturbed_plant():
    """The feedforward of a Hammerstein model (plays per actuator, then 3x3 dynamics with modes
    at 640/790 Hz) on a mirror that differs from it (poles 1 % lower, gains +2 %, hysteresis
    weights +20 %, thresholds -10 %): a 150/200 Hz tip/tilt Lissajous, error in % of amplitude."""
    from scipy.linalg import expm, logm

    a, b, c, d = resonant_mimo()
    th = np.tile(np.linspace(0, 0.25, 6), (3, 1))
    wt = np.tile([-0.5, 0.2, 0.12, 0.08, 0.06, 0.04], (3, 1))
    model = _hammerstein(a, b, c, d, th, wt)
    plant = _hammerstein(np.real(expm(0.99 * logm(a))), 1.02 * b, c, d, 0.9 * th, 1.2 * wt)
    m = mirror_matrix(0.02)
    n, amp = 6400, 2e-4  # 1 s; 0.2 mrad
    t = np.arange(n) / FS
    ptt = np.column_stack([np.zeros(n), amp * np.sin(2 * np.pi * 150 * t), amp * np.sin(2 * np.pi * 200 * t + 0.3)])
    r = ptt @ m.T

    def error(sys_, u):  # tip/tilt RMS error of the third period, % of the amplitude
        y = sys_.simulate(np.tile(u, (3, 1)), init="rest")[-n:]
        e = np.linalg.solve(m, (y - r).T).T[:, 1:]
        return np.sqrt(np.mean(e**2, axis=0)) / amp * 100

    ff = MimoFeedforward.from_model(model, bandwidth=1000.0)
    assert len(ff.hysteresis) == 3  # the cascade was recognised: a PI per actuator
    g0 = frequency_response(a, b, c, d, [0.0], FS)[0].real
    static = error(plant, np.linalg.solve(g0, r.T).T)
    linear = error(plant, MimoFeedforward(a, b, c, d, fs=FS, bandwidth=1000.0).linear_command(r))
    full = error(plant, ff.command(r, periods=3)[-n:])
    crime = error(model, ff.command(r, periods=3)[-n:])
    # measured: static 13.6 / 19.6 %, linear 3.9 / 6.5 %, full 2.1 / 2.0 %, on the model itself < 0.002 %
    assert np.all(static > 10) and np.all(linear < 8) and np.all(full < 2.5)
    assert np.all(full < 0.6 * linear) and np.all(crime < 0.01)
    # the model-based iteration from that start keeps it (the model is already inverted)
    u_it, err = ff.iterate(lambda u: model.simulate(u, init="rest"), r, iterations=2, periods=3)
    assert err[-1] <= err[0] and np.all(error(plant, u_it) < 2.5)


def test_from_model_linearizes_the_feedback_of_an_lfr():
    from piezohyst.models.mimo import MimoModel

    a, b, c, d = resonant_mimo()
    rng = np.random.default_rng(5)
    g = 1e5 * c  # the feedback signal: displacement in units of 10 um
    kw = dict(A=a, B=b, C=c, D=d, E=-0.02 * b, F=np.zeros((3, 3)), G=g, H=np.zeros((3, 3)), fs=FS, structure="lfr")
    th = np.tile(np.linspace(0, 0.5, 5), (3, 1))
    wt = np.abs(rng.standard_normal((3, 5)))
    lfr = MimoModel(thresholds=th, weights=wt, **kw)
    ff = MimoFeedforward.from_model(lfr)
    k = wt.sum(axis=1)
    np.testing.assert_allclose(ff.A, a + (-0.02 * b) @ np.diag(k) @ g, rtol=1e-15)
    assert ff.hysteresis == ()
    ffa = MimoFeedforward.from_model(lfr, amplitude=[0.25, 0.25, 0.25])
    k_a = (wt * np.clip(1 - th / 0.25, 0, None)).sum(axis=1)
    np.testing.assert_allclose(ffa.A, a + (-0.02 * b) @ np.diag(k_a) @ g, rtol=1e-15)
    with pytest.raises(ph.ParameterError, match=r"amplitude must be 3 finite values > 0"):
        MimoFeedforward.from_model(lfr, amplitude=[1.0, -1.0, 1.0])
    # the iteration through the LFR's own simulation inverts it: 100x below the linear start
    r = lissajous(n=1280, amp=2e-6)
    _u, err = ff.iterate(lambda v: lfr.simulate(v, init="rest"), r, iterations=10, periods=3, gain=0.8)
    assert err[-1] < 0.01 * err[0]


def test_fsm_models_feedforward_on_the_held_out_mirror():
    """The gallery's numbers (examples/plot_mimo_feedforward.py): the FSM model identified on
    realizations 1-3 drives the one identified on 4-6, a 90/120 Hz tip/tilt Lissajous."""
    from pathlib import Path

    from piezohyst.models.mimo import load_mimo_model

    data = Path(__file__).resolve().parents[2] / "examples" / "data"
    model, mirror = load_mimo_model(data / "fsm_lfr_123.json"), load_mimo_model(data / "fsm_lfr_456.json")
    n, amp = 3200, 1e-4
    t = np.arange(n) / model.fs
    ptt = np.column_stack([np.zeros(n), amp * np.sin(2 * np.pi * 90 * t), amp * np.sin(2 * np.pi * 120 * t + 0.3)])
    m = mirror_matrix(0.02)
    r = ptt @ m.T

    def error(u):
        y = mirror.simulate(np.tile(u, (3, 1)), init="rest")[-n:]
        return np.sqrt(np.mean((np.linalg.solve(m, y.T).T[:, 1:] - ptt[:, 1:]) ** 2, axis=0)) / amp * 100

    ff = MimoFeedforward.from_model(model, bandwidth=1500.0)
    g0 = frequency_response(ff.A, ff.B, ff.C, ff.D, [0.0], model.fs)[0].real
    static = error(np.linalg.solve(g0, r.T).T)
    linear = error(ff.linear_command(r))
    u, model_error = ff.iterate(lambda v: model.simulate(v, init="rest"), r, iterations=3, periods=3, gain=0.7)
    full = error(u)
    # measured: static 10.4 / 11.7 %, linear 1.43 / 2.27 %, full 1.04 / 1.03 % of 0.1 mrad
    assert np.all(static > 8) and np.all(linear < 3) and np.all(full < 1.3)
    assert np.all(full <= linear) and model_error[-1] < 0.2 * model_error[0]
