"""Population optimizers (docs/spec.md §4): CSS, PSO, MPSO, DE; ask/tell, minimize, determinism."""

import dataclasses
import io
import sys
import time

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import piezohyst as ph
from piezohyst.optimize import (
    CSS,
    DE,
    METHODS,
    MPSO,
    PSO,
    IntermediateResult,
    Optimizer,
    OptimizeResult,
    css_charges,
    css_forces,
    minimize,
)

SHIFT = np.array([0.5, -1.2, 0.8, 1.5, -0.3, 2.0, -2.2, 0.1])


def sphere(X):
    return np.sum((X - SHIFT[: X.shape[1]]) ** 2, axis=1)


def rosenbrock(X):
    return np.sum(100.0 * (X[:, 1:] - X[:, :-1] ** 2) ** 2 + (1.0 - X[:, :-1]) ** 2, axis=1)


def rastrigin(X):
    return 10.0 * X.shape[1] + np.sum(X**2 - 10.0 * np.cos(2.0 * np.pi * X), axis=1)


# ------------------------------------------------------------------------------------------
# accuracy within a budget
# ------------------------------------------------------------------------------------------
# shifted sphere, D = 8, bounds [-5, 5], 40 x 300 = 12 000 evaluations: cost and max |x - x*|
SPHERE_TOL = {"css": (1e-8, 1e-4), "pso": (1e-9, 1e-4), "mpso": (1e-14, 1e-7), "de": (1e-6, 1e-3)}
# Rosenbrock, D = 4, bounds [-2.048, 2.048], 40 x 1000 = 40 000 evaluations (min 0 at x = 1)
ROSEN_TOL = {"css": (0.1, 0.6), "pso": (0.01, 0.2), "mpso": (0.05, 0.4), "de": (1e-12, 1e-6)}


@pytest.mark.parametrize("method", sorted(METHODS))
def test_shifted_sphere_8d(method):
    res = minimize(sphere, [(-5.0, 5.0)] * 8, method=method, rng=0, population_size=40, max_iterations=300)
    f_tol, x_tol = SPHERE_TOL[method]
    assert res.success and res.nit == 300 and res.nfev == 12_000
    assert res.fun < f_tol
    assert np.max(np.abs(res.x - SHIFT)) < x_tol


@pytest.mark.parametrize("method", sorted(METHODS))
def test_rosenbrock_4d(method):
    res = minimize(rosenbrock, [(-2.048, 2.048)] * 4, method=method, rng=0, population_size=40, max_iterations=1000)
    f_tol, x_tol = ROSEN_TOL[method]
    assert res.fun < f_tol
    assert np.max(np.abs(res.x - 1.0)) < x_tol
    # the best-so-far history is monotone and ends at the result
    h = res.history["best_cost"]
    assert np.all(np.diff(h) <= 0) and h[-1] == res.fun


def test_css_beats_random_search_on_rastrigin():
    D, S, T = 6, 40, 300
    res = minimize(rastrigin, [(-5.12, 5.12)] * D, method="css", rng=0, population_size=S, max_iterations=T)
    g = np.random.default_rng(0)
    random_best = rastrigin(-5.12 + 10.24 * g.random((S * T, D))).min()
    assert res.nfev == S * T
    # measured: CSS 1.98 (seeds 0-5: 1.98-4.94), random search 25.4 (12 000 evaluations each)
    assert res.fun < 6.0
    assert random_best > 15.0
    assert res.fun < 0.3 * random_best


# ------------------------------------------------------------------------------------------
# the formulas
# ------------------------------------------------------------------------------------------
def test_mpso_inertia_formula():
    opt = MPSO([(0, 1)] * 2, rng=0, max_iterations=50, w_max=0.95, w_min=0.3)
    for t in range(51):
        assert opt.inertia(t) == pytest.approx(0.3 + 0.65 * (1 - t / 50) ** 2, rel=1e-15)
    assert opt.inertia(0) == 0.95 and opt.inertia(50) == pytest.approx(0.3)
    assert np.all(np.diff([opt.inertia(t) for t in range(51)]) < 0)


def test_mpso_velocity_uses_the_inertia_schedule():
    # with c1 = c2 = c3 = 0 the velocity only decays: V_t = w(t) V_{t-1}
    T = 12
    opt = MPSO(
        [(-1e6, 1e6)] * 3,
        population_size=5,
        rng=1,
        max_iterations=T,
        c1=0,
        c2=0,
        c3=0,
        vmax=1e-3,
        init=np.zeros((5, 3)),
    )
    V0 = opt.velocities
    X = [opt.ask()]
    for _ in range(T - 1):
        opt.tell(np.arange(5.0))
        X.append(opt.ask())
    np.testing.assert_allclose(X[1] - X[0], opt.inertia(0) * V0, rtol=1e-12)
    for k in range(1, T - 1):
        np.testing.assert_allclose(X[k + 1] - X[k], opt.inertia(k) * (X[k] - X[k - 1]), rtol=1e-9)


def test_pso_inertia_is_constant():
    opt = PSO([(0, 1)], w=0.6)
    assert opt.inertia(0) == opt.inertia(100) == 0.6


def test_css_charges_and_forces_hand_computed():
    # X0 best (f=1), X1 (f=2), X2 worst (f=3); a = 1.5, eps = 0
    X = np.array([[0.0, 0.0], [2.0, 0.0], [1.0, 1.0]])
    f = np.array([1.0, 2.0, 3.0])
    q, p, F = css_forces(X, f, a=1.5, eps=0.0, rand=np.full((3, 3), 0.5))
    # q_i = (f_i - f_worst)/(f_best - f_worst)
    np.testing.assert_allclose(q, [1.0, 0.5, 0.0])
    # p[i, j]: i better than j attracts j; worse i attracts j if (f_j - f_best)/(f_i - f_j) > rand:
    #   j=1, i=2: (2-1)/(3-2) = 1 > 0.5;  j=0 (the best): ratio 0, never
    np.testing.assert_array_equal(p, [[0, 1, 1], [0, 0, 1], [0, 1, 0]])
    # F_0 = 0 (nothing attracts the best)
    # F_1: from X0, r_01 = 2/|(1,0)| = 2 >= a -> q_0/r^2 = 1/4, times (X0 - X1) = (-2, 0);
    #      from X2: q_2 = 0
    # F_2: from X0, r_02 = sqrt2/|(0.5,0.5)| = 2 -> 1/4 (X0 - X2) = (-0.25, -0.25);
    #      from X1, r_12 = sqrt2/|(1.5,0.5)| = sqrt(0.8) < a -> q_1/a^3 r_12 = 0.5/3.375*0.894427191
    #      times (X1 - X2) = (1, -1)
    c = 0.5 / 3.375 * np.sqrt(0.8)
    np.testing.assert_allclose(F, [[0.0, 0.0], [-0.5, 0.0], [-0.25 + c, -0.25 - c]], rtol=1e-14, atol=1e-15)


def test_css_probabilistic_attraction_by_worse_particles():
    X = np.array([[0.0, 0.0], [2.0, 0.0], [1.0, 1.0], [3.0, 3.0]])
    f = np.array([1.0, 1.2, 3.0, 4.0])
    # j = 1 by i = 2: ratio (1.2 - 1)/(3 - 1.2) = 1/9
    u = np.full((4, 4), 0.5)
    _, p, _ = css_forces(X, f, a=1.0, eps=0.0, rand=u)
    assert p[2, 1] == 0
    u[2, 1] = 0.1
    _, p, _ = css_forces(X, f, a=1.0, eps=0.0, rand=u)
    assert p[2, 1] == 1
    # equal costs do not attract each other; an infinite cost attracts nobody and has q = 0
    q, p, _ = css_forces(X, [1.0, 1.0, 2.0, np.inf], a=1.0, eps=0.0, rand=np.zeros((4, 4)))
    assert p[0, 1] == p[1, 0] == 0 and np.all(p[3] == 0) and np.all(p[:3, 3] == 1)
    np.testing.assert_allclose(q, [1.0, 1.0, 0.0, 0.0])


def test_css_charges_edge_cases():
    np.testing.assert_array_equal(css_charges([2.0, 2.0, np.inf]), [1.0, 1.0, 0.0])
    np.testing.assert_array_equal(css_charges([np.inf, np.inf]), [0.0, 0.0])


def test_css_first_move_follows_the_force():
    # k_a = 0.5 at it = 0 and V = 0: X_new - X = rand_1 * 0.5 * F_j with rand_1 in [0, 1)
    X0 = np.array([[0.0, 0.0], [2.0, 0.0], [1.0, 1.0], [-1.0, 2.0]])
    opt = CSS([(-10, 10)] * 2, rng=3, init=X0, max_iterations=10, normalize=False)
    assert opt.a == pytest.approx(2.0) and opt.memory_size == 1
    f = np.array([1.0, 2.0, 3.0, 4.0])  # every ratio that matters is >= 1: p is deterministic
    assert np.array_equal(opt.ask(), X0)
    opt.tell(f)
    _, _, F = css_forces(X0, f, a=opt.a, eps=opt.eps, rand=np.full((4, 4), 0.999))
    step = opt.ask() - X0
    for j in range(4):
        if np.allclose(F[j], 0):
            assert np.allclose(step[j], 0)
        else:
            s = np.dot(step[j], F[j]) / np.dot(F[j], F[j])
            assert 0 <= s < 0.5
            np.testing.assert_allclose(step[j], s * F[j], rtol=1e-12, atol=1e-14)
    xs, fs = opt.charged_memory
    np.testing.assert_array_equal(xs, X0[:1])
    np.testing.assert_array_equal(fs, [1.0])


def test_css_normalized_moves_follow_the_unit_box_force():
    # normalize=True: forces in the unit box (a = 0.1), steps scaled back by each range
    X0 = np.array([[0.0, 0.0], [2.0, 0.0], [1.0, 1.0], [-1.0, 2.0]])
    bounds = [(-10, 10), (-1000, 1000)]
    X0[:, 1] *= 100
    opt = CSS(bounds, rng=3, init=X0, max_iterations=10)
    assert opt.a == pytest.approx(0.1)
    f = np.array([1.0, 2.0, 3.0, 4.0])
    opt.ask()
    opt.tell(f)
    rng = np.array([20.0, 2000.0])
    U = (X0 - np.array([-10.0, -1000.0])) / rng
    _, _, F = css_forces(U, f, a=0.1, eps=1e-10, rand=np.full((4, 4), 0.999))
    step = (opt.ask() - X0) / rng
    for j in range(4):
        if np.allclose(F[j], 0):
            assert np.allclose(step[j], 0)
        else:
            s = np.dot(step[j], F[j]) / np.dot(F[j], F[j])
            assert 0 <= s < 0.5
            np.testing.assert_allclose(step[j], s * F[j], rtol=1e-9, atol=1e-14)


def test_css_out_of_bounds_components_come_from_memory_or_uniform():
    opt = CSS([(0, 1)] * 3, population_size=8, rng=0, max_iterations=50, cmcr=1.0, par=0.0)
    opt.ask()
    f = np.arange(8.0)
    opt.tell(f)
    memory = opt.charged_memory[0]
    assert memory.shape == (2, 3)  # N // 4
    Xn = opt._harmony_bounds(np.full((8, 3), 5.0))  # every component out of bounds
    for d in range(3):  # cmcr = 1, par = 0: every value is the memory's value in that component
        assert set(Xn[:, d]) <= set(memory[:, d])


# ------------------------------------------------------------------------------------------
# ask / tell protocol and bounds
# ------------------------------------------------------------------------------------------
@given(
    method=st.sampled_from(sorted(METHODS)),
    lower=st.lists(st.floats(-1e3, 1e3), min_size=1, max_size=4),
    widths=st.lists(st.floats(0.0, 1e3), min_size=4, max_size=4),
    seed=st.integers(0, 2**32 - 1),
    mode=st.sampled_from(["random", "inf", "outward", "all_inf"]),
    S=st.integers(4, 10),
    T=st.integers(1, 8),
)
def test_ask_never_leaves_bounds(method, lower, widths, seed, mode, S, T):
    lo = np.array(lower)
    hi = lo + np.array(widths[: lo.size])
    if np.all(hi == lo):
        hi[0] = lo[0] + 1.0
    opt = METHODS[method](np.stack([lo, hi], axis=1), population_size=S, rng=seed, max_iterations=T)
    g = np.random.default_rng(seed)
    while not opt.done:
        X = opt.ask()
        assert X.shape == (S, lo.size)
        assert np.all(X >= lo) and np.all(X <= hi)
        if mode == "random":
            f = g.random(S)
        elif mode == "inf":
            f = np.where(g.random(S) < 0.5, np.inf, g.random(S))
        elif mode == "outward":  # pushes every candidate towards a corner, hard
            f = -1e6 * X.sum(axis=1) / (1.0 + np.abs(X).sum(axis=1))
        else:
            f = np.full(S, np.inf)
        opt.tell(f)
    assert opt.iteration == T


def test_ask_tell_protocol():
    opt = DE([(0, 1)] * 2, population_size=6, rng=0, max_iterations=2)
    with pytest.raises(RuntimeError, match="without a pending ask"):
        opt.tell(np.zeros(6))
    assert opt.best_x is None and opt.best_cost == np.inf and opt.iteration == 0
    X = opt.ask()
    assert np.array_equal(opt.ask(), X)  # asking again does not move anything
    X[:] = 99.0  # the caller's copy
    assert np.all(opt.ask() <= 1.0)
    with pytest.raises(ValueError, match=r"costs has shape \(5,\), expected \(6,\)"):
        opt.tell(np.zeros(5))
    opt.tell(np.arange(6.0))
    opt.ask()
    opt.tell(np.arange(6.0))
    assert opt.done
    with pytest.raises(RuntimeError, match="max_iterations = 2"):
        opt.ask()
    r = opt.result()
    assert r.success and r.message == "maximum number of iterations reached" and r.nit == 2 and r.nfev == 12


def test_optimizer_is_the_base_of_all_methods():
    for cls in METHODS.values():
        assert issubclass(cls, Optimizer)


# ------------------------------------------------------------------------------------------
# determinism
# ------------------------------------------------------------------------------------------
def _run(method, rng):
    return minimize(rastrigin, [(-5.12, 5.12)] * 3, method=method, rng=rng, population_size=12, max_iterations=40)


@pytest.mark.parametrize("method", sorted(METHODS))
def test_same_seed_same_history_different_seed_different(method):
    a, b, c = _run(method, 7), _run(method, np.random.default_rng(7)), _run(method, 8)
    for key in ("best_cost", "mean_cost", "best_x", "n_finite", "nfev"):
        np.testing.assert_array_equal(a.history[key], b.history[key])
    np.testing.assert_array_equal(a.x, b.x)
    assert a.fun == b.fun
    assert not np.array_equal(a.history["mean_cost"], c.history["mean_cost"])


def test_minimize_and_ask_tell_agree():
    res = minimize(sphere, [(-5, 5)] * 3, method="css", rng=5, population_size=8, max_iterations=30)
    opt = CSS([(-5, 5)] * 3, population_size=8, rng=5, max_iterations=30)
    while not opt.done:
        opt.tell(sphere(opt.ask()))
    np.testing.assert_array_equal(opt.history["best_x"], res.history["best_x"])
    assert opt.best_cost == res.fun


# ------------------------------------------------------------------------------------------
# minimize: callbacks, infinities, NaN, polish, interrupt, progress
# ------------------------------------------------------------------------------------------
def test_callback_return_true_stops():
    seen = []

    def cb(r):
        assert isinstance(r, IntermediateResult)
        seen.append((r.nit, r.fun, r.x.copy(), r.nfev))
        return r.nit == 5

    res = minimize(sphere, [(-5, 5)] * 2, method="pso", rng=0, population_size=10, max_iterations=100, callback=cb)
    assert res.nit == 5 and res.nfev == 50 and len(seen) == 5
    assert res.message == "stopped by callback" and res.success is False
    assert [s[0] for s in seen] == [1, 2, 3, 4, 5]
    assert seen[-1][1] == res.fun and np.array_equal(seen[-1][2], res.x)
    assert res.history["best_cost"].shape == (5,)


def test_callback_stop_iteration_stops():
    def cb(r):
        if r.fun < 1.0:
            raise StopIteration

    res = minimize(sphere, [(-5, 5)] * 2, method="de", rng=0, population_size=10, max_iterations=100, callback=cb)
    assert res.message == "stopped by callback" and res.fun < 1.0 and res.nit < 100


def test_tol_stops_on_converged_population():
    res = minimize(
        sphere, [(-5, 5)] * 2, method="de", rng=0, population_size=10, max_iterations=1000, tol=1e-3, atol=1e-12
    )
    assert res.success and res.message.startswith("converged") and res.nit < 1000


def test_infinite_costs_are_handled():
    # invalid half-space x0 < 0.7 costs +inf; the constrained optimum sits on its edge
    def fun(X):
        f = sphere(X)
        return np.where(X[:, 0] < 0.7, np.inf, f)

    # optimum 0.2^2 at x = (0.7, -1.2, 0.8); CSS approaches edges slowly
    for method, tol in {"css": 5e-3, "pso": 1e-8, "mpso": 1e-8, "de": 1e-8}.items():
        res = minimize(fun, [(-5, 5)] * 3, method=method, rng=1, population_size=20, max_iterations=200)
        assert res.success and np.isfinite(res.fun)
        assert res.x[0] >= 0.7
        assert res.fun == pytest.approx(0.2**2, abs=tol)
        h = res.history
        assert np.all(np.isfinite(h["mean_cost"])) and np.all(h["n_finite"] <= 20)


def test_all_infinite_costs():
    for method in sorted(METHODS):
        res = minimize(
            lambda X: np.full(X.shape[0], np.inf),
            [(0, 1)] * 2,
            method=method,
            rng=0,
            population_size=6,
            max_iterations=5,
            polish=True,
        )
        assert res.success is False and res.message == "no finite cost found"
        assert res.fun == np.inf and res.x.shape == (2,) and res.nit == 5
        assert np.all(res.history["mean_cost"] == np.inf) and np.all(res.history["n_finite"] == 0)


def test_nan_cost_raises_with_index():
    def fun(X):
        f = sphere(X)
        f[3] = np.nan
        return f

    with pytest.raises(ValueError, match="fun_batch returned NaN at index 3"):
        minimize(fun, [(-5, 5)] * 2, method="css", rng=0, population_size=8)
    opt = PSO([(-5, 5)] * 2, population_size=8, rng=0)
    opt.ask()
    with pytest.raises(ValueError, match=r"costs\[3\] is NaN"):
        opt.tell([0, 1, 2, np.nan, 4, 5, 6, 7])
    with pytest.raises(ValueError, match=r"costs\[1\] = -inf"):
        opt.tell([0, -np.inf, 2, 3, 4, 5, 6, 7])


def test_polish_improves_a_smooth_problem():
    kw = dict(method="pso", rng=0, population_size=20, max_iterations=30)
    plain = minimize(rosenbrock, [(-2.048, 2.048)] * 4, **kw)
    polished = minimize(rosenbrock, [(-2.048, 2.048)] * 4, polish=True, **kw)
    assert plain.fun > 1e-2
    assert polished.fun < 1e-8 and np.max(np.abs(polished.x - 1.0)) < 1e-3
    assert polished.nfev > plain.nfev == 600
    assert "polish improved" in polished.message and polished.success
    np.testing.assert_array_equal(polished.history["best_cost"], plain.history["best_cost"])
    # the polish stays inside the bounds when the optimum is outside them
    res = minimize(sphere, [(-1, 1)] * 3, method="de", rng=0, population_size=10, max_iterations=20, polish=True)
    np.testing.assert_allclose(res.x, np.clip(SHIFT[:3], -1, 1), atol=1e-6)


def test_keyboard_interrupt_returns_best_so_far():
    calls = []

    def fun(X):
        calls.append(1)
        if len(calls) == 4:
            raise KeyboardInterrupt
        return sphere(X)

    res = minimize(fun, [(-5, 5)] * 2, method="mpso", rng=0, population_size=10, max_iterations=50, polish=True)
    assert res.success is False and res.message == "interrupted"
    assert res.nit == 3 and res.nfev == 30 and np.isfinite(res.fun)


def test_one_batch_call_per_iteration():
    shapes = []

    def fun(X):
        shapes.append(X.shape)
        return sphere(X)

    minimize(fun, [(-5, 5)] * 3, method="css", rng=0, population_size=12, max_iterations=7)
    assert shapes == [(12, 3)] * 7


def test_progress_bar(capsys):
    minimize(sphere, [(-5, 5)] * 2, method="pso", rng=0, population_size=8, max_iterations=10)
    assert capsys.readouterr().err == ""
    minimize(sphere, [(-5, 5)] * 2, method="pso", rng=0, population_size=8, max_iterations=10, progress=True)
    err = capsys.readouterr().err
    # stderr is not a terminal here: plain lines, no carriage return (a log stays readable)
    assert err.startswith("pso: 10/10 (100 %), best ") and err.endswith(" s\n") and "\r" not in err
    assert err.count("\n") == 1  # a run under a second: only the closing line


def test_progress_bar_on_a_terminal(monkeypatch):
    """On a terminal the optimizer's progress is a tqdm bar rewritten in place (a slow run:
    the bar appears after half a second)."""

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    term = Terminal()
    monkeypatch.setattr(sys, "stderr", term)

    def slow(X):
        time.sleep(0.06)
        return np.sum(X**2, axis=1)

    minimize(slow, [(-5, 5)] * 2, method="pso", rng=0, population_size=8, max_iterations=15, progress=True)
    out = term.getvalue()
    assert out.startswith("\rpso:") and "15/15" in out and out.endswith("\n")


def test_result_object():
    res = minimize(sphere, [(-5, 5)] * 2, method="css", rng=0, population_size=8, max_iterations=10)
    assert isinstance(res, OptimizeResult) and res.method == "css"
    with pytest.raises(dataclasses.FrozenInstanceError):
        res.fun = 0.0
    assert not res.x.flags.writeable and not res.history["best_x"].flags.writeable
    assert res.history["best_x"].shape == (10, 2) and res.history["nfev"][-1] == 80
    assert res.wall_time > 0


# ------------------------------------------------------------------------------------------
# bad input
# ------------------------------------------------------------------------------------------
def test_bad_input():
    ok = [(0, 1)] * 2
    with pytest.raises(ValueError, match=r"bounds\[1\] = \(2.0, 1.0\): lower > upper"):
        minimize(sphere, [(0, 1), (2, 1)])
    with pytest.raises(ValueError, match=r"bounds\[0\].*not finite"):
        minimize(sphere, [(0, np.inf)])
    with pytest.raises(ValueError, match=r"bounds must have shape \(D, 2\)"):
        minimize(sphere, [0, 1])
    with pytest.raises(ValueError, match="lower == upper"):
        minimize(sphere, [(1, 1)])
    with pytest.raises(ValueError, match="population_size = 3 must be >= 4"):
        minimize(sphere, ok, population_size=3)
    with pytest.raises(ValueError, match="max_iterations = 0 must be >= 1"):
        minimize(sphere, ok, max_iterations=0)
    with pytest.raises(ValueError, match="method = 'nelder' is not one of"):
        minimize(sphere, ok, method="nelder")
    with pytest.raises(ValueError, match=r"fun_batch returned shape \(20, 1\) for an input of shape \(20, 2\)"):
        minimize(lambda X: sphere(X)[:, None], ok, population_size=20)
    with pytest.raises(TypeError, match="fun_batch must be callable"):
        minimize("sphere", ok)
    with pytest.raises(TypeError, match="callback must be callable"):
        minimize(sphere, ok, callback=3)
    with pytest.raises(TypeError, match="method 'pso'.*cmcr"):
        minimize(sphere, ok, method="pso", cmcr=0.9)
    with pytest.raises(ValueError, match="cmcr = 1.5 must be in"):
        CSS(ok, cmcr=1.5)
    with pytest.raises(ValueError, match="CR = -0.1 must be in"):
        DE(ok, CR=-0.1)
    with pytest.raises(ValueError, match="w_min = 0.9 must be <= w_max = 0.4"):
        MPSO(ok, w_min=0.9, w_max=0.4)
    with pytest.raises(TypeError, match="rng must be None, an int seed or a numpy.random.Generator"):
        PSO(ok, rng="seed")
    with pytest.raises(ValueError, match=r"init\[0, 1\] = 2.0 is outside bounds\[1\]"):
        PSO(ok, init=[[0.5, 2.0]] * 4)
    with pytest.raises(ValueError, match="init = 'sobol'"):
        PSO(ok, init="sobol")


# ------------------------------------------------------------------------------------------
# integration: identify a PI model with the Rust batch cost
# ------------------------------------------------------------------------------------------
PI_TRUE = ph.PI(thresholds=[0.1, 0.25, 0.4, 0.55, 0.7], weights=[0.5, 0.3, 0.2, 0.15, 0.1], p0=0.6)
PI_FREE = np.r_[0, 6:11]  # row layout [p0, r_1..r_5, w_1..w_5]: fit p0 and the weights
# per method: (population_size, max_iterations); all reach RMSE < 1e-3 of the output range
PI_BUDGET = {"css": (20, 3000), "pso": (40, 800), "mpso": (40, 800), "de": (40, 800)}


@pytest.fixture(scope="module")
def pi_record():
    t = np.linspace(0.0, 1.0, 2000)
    v = 0.5 + 0.45 * np.sin(2 * np.pi * 5 * t) * (1 - 0.8 * t)  # decaying: nested minor loops
    return v, PI_TRUE.simulate(v)


@pytest.mark.parametrize("method", sorted(METHODS))
def test_identify_pi_weights_with_batch_rmse(method, pi_record):
    v, y = pi_record
    template = PI_TRUE.to_row()

    def cost(X):
        rows = np.repeat(template[None, :], X.shape[0], axis=0)
        rows[:, PI_FREE] = X
        return ph.batch_rmse(PI_TRUE, rows, v, y, invalid_cost=np.inf)

    S, T = PI_BUDGET[method]
    res = minimize(cost, [(0.0, 2.0)] + [(0.0, 1.0)] * 5, method=method, rng=0, population_size=S, max_iterations=T)
    y_range = np.ptp(y)
    assert res.fun < 1e-3 * y_range
    fitted = ph.PI(thresholds=PI_TRUE.thresholds, weights=res.x[1:], p0=res.x[0])
    assert np.sqrt(np.mean((fitted.simulate(v) - y) ** 2)) == pytest.approx(res.fun, rel=1e-9, abs=1e-15)
    if method == "de":  # DE recovers the parameters themselves
        np.testing.assert_allclose(res.x, template[PI_FREE], atol=1e-6)


def test_identify_pi_css_with_polish(pi_record):
    v, y = pi_record
    template = PI_TRUE.to_row()

    def cost(X):
        rows = np.repeat(template[None, :], X.shape[0], axis=0)
        rows[:, PI_FREE] = X
        return ph.batch_rmse(PI_TRUE, rows, v, y, invalid_cost=np.inf)

    res = minimize(
        cost, [(0.0, 2.0)] + [(0.0, 1.0)] * 5, method="css", rng=0, population_size=40, max_iterations=200, polish=True
    )
    assert res.fun < 1e-5 * np.ptp(y)
