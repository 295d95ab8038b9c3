"""MPI identification on a 10 000-sample record: time to reach within 1 % of the best RMSE.

Usage (from the project root, after the extension is built):

    .venv/bin/python bench/identify_mpi.py [--out bench/results/identify_mpi.json]

Benchmark 1 of issue 4 item 6. All methods run in this one process, on the same record, and
are timed by wall clock with ``time.perf_counter``.

Data
    ``piezohyst.mpi_seed2()``: seed 2's Table 1 MPI model (thresholds 0.1..0.9, nine weights,
    cubic polynomial, identity envelopes). The input has 10 000 samples in [0, 1] and starts
    at 0. It is a raised cosine (20 periods) whose amplitude swells twice between 0.3 and 1.
    It is multiplied by a two-tone ripple (53 and 97 periods per record), which adds minor
    loops. The output is the model's, plus seeded Gaussian noise with a standard deviation of
    0.2 % of the output range.

Methods
    (a)    piezohyst structure-aware: ``identify_mpi(v, y, operators=9, thresholds=0.1..0.9)``.
           This is one bounded least-squares solve over the polynomial c0..c3 and the nine
           weights (>= 0), with the thresholds fixed at seed 2's values (the same structure
           as (b)). The time is the median of ``--reps`` calls. It includes the regressor
           pass, the solve and the free-run simulation that computes the RMSE.
    (a0)   ``identify_mpi(v, y, operators=9)`` with its default thresholds (spread over half
           the input range, 0.05..0.45 here). This is the call exactly as the brief gives it.
           It knows nothing about the true thresholds.
    (a+vp) Variable projection without knowing the thresholds: a short MPSO (piezohyst's,
           8 candidates x 6 iterations) over one nonlinear parameter, the largest threshold
           r_n in [0.3, 1.2] x the input span. The thresholds are r_i = i r_n / 9, the
           equal-spacing layout of seed 2 and of identify_mpi's default (whose r_n is 0.45 x
           span). Each candidate costs one ``identify_mpi(..., thresholds=...)`` solve. The
           solves run one after another in Python. One run per seed in ``--vp-seeds``.
           (A two-parameter search over the first and last threshold has narrow valleys on
           this record. It missed the 1 % target in some seeds at a similar budget, so it is
           not used.)
    (b)    The seed-2 way: piezohyst MPSO alone over all 12 parameters (a1, a2, a3, b1..b9).
           c0 = 0, identity envelopes, and the thresholds are fixed at 0.1..0.9 as in the
           seed. The cost is ``piezohyst.batch_rmse`` of the whole swarm: one Rust call per
           iteration, rayon over the swarm. Population ``--population`` (40), ``--iterations``
           (2000), one run per seed in ``--mpso-seeds``. No polish.
    (c)    pyswarms (``GlobalBestPSO``) drives a NumPy model. It searches the same 12
           parameters in the same box, normalized to [0, 1]^12, with the same population and
           iteration budget as (b). The stopping rule is ``--cap`` seconds of wall time (120)
           or that budget, whichever comes first. The pyswarms settings are c1 = c2 = 1.5;
           inertia 0.9 -> 0.4 (pyswarms' ``lin_variation`` over the budget); velocity clamp
           +-0.2 (MPSO's vmax); ``bh_strategy="reflective"``; uniform random initial swarm
           (``np.random.seed``; pyswarms draws from NumPy's global state). These settings
           were the best of six tried on this record (see ``PYSWARMS_SETTINGS_TRIED``).
           The reflective boundary matters most: with "nearest", or with pyswarms' default
           "periodic", the swarm stalls on the box edges.
           The NumPy model is vectorized over the swarm and the operators, with a Python loop
           over time: per sample ``np.minimum``, ``np.maximum`` and a row-wise ``einsum``
           (the weighted sum). Everything that is not recursive (the band edges, the
           polynomial, the error, the RMSE) is computed as whole arrays outside the loop.
           It is single-threaded NumPy (OPENBLAS_NUM_THREADS=1). Using the second core, as
           piezohyst does, means splitting the swarm over two spawned worker processes (what
           pyswarms' own ``n_processes`` does). The per-sample cost is call overhead that does
           not shrink with the swarm, so the split gains little. Before the clock starts, the
           script therefore times one call in-process and one split over a 2-process pool (3
           calls each, pool warmed) and runs (c) with the faster. ``--numpy-processes`` forces
           the choice. The model's RMSEs equal ``batch_rmse``'s to 1e-12 relative (asserted).
    (c')   The same pyswarms run (same seed, same settings), with the cost computed by
           ``piezohyst.batch_rmse`` instead of NumPy. Its full budget runs in a few seconds.
           Comparisons in the optimizer depend on costs equal to ~1e-15, so the trajectory is
           (c)'s. The script checks this over the iterations both reach. This row gives
           pyswarms' algorithm without the time cap, and the pure evaluation speed-up at
           identical trajectories. If (c) is capped before the target and the trajectories
           match, (c)'s time to target is *extrapolated*. The estimate is (c') 's iterations
           to target times (c)'s median iteration time. It is labelled as an extrapolation
           and never mixed with measured times.

Metric
    The best RMSE any run finds is taken, and the target is 1.01 x that RMSE. For each run the
    script reports the first moment its best-so-far RMSE is <= the target: wall time from the
    start of the call (optimizer set-up included) and the RMSE at that moment. It also
    reports the run's final best RMSE and its total time. One-shot methods (a), (a0) either
    reach the target or don't. Their time is the median call time. Issue target: (a) reaches
    within 1 % in <= 1 s on 2 cores.

Threads: OPENBLAS_NUM_THREADS=1 (no BLAS pool competing with rayon, as in pi_batch.py);
RAYON_NUM_THREADS=2 unless set. Results go to JSON (written atomically) and a table is
printed. The whole run takes about 2.5-3 minutes (mostly (c)'s cap).
"""

from __future__ import annotations

import argparse
import datetime as _dt
import multiprocessing as mp
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("RAYON_NUM_THREADS", "2")

import numpy as np

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

from common import machine_info, versions, write_json_atomic

DEFAULT_OUT = HERE / "results" / "identify_mpi.json"
N_SAMPLES = 10_000
N_OPS = 9
TOL = 0.01  # "within 1 % of the best RMSE"
TARGET_TIME_A = 1.0  # issue target for (a), seconds on 2 cores
RTOL_NUMPY = 1e-12
SEED_THRESHOLDS = np.arange(1, N_OPS + 1) / 10.0  # 0.1 .. 0.9 (seed 2, Table 1)
VP_BOUNDS = (0.3, 1.2)  # (a+vp): largest threshold r_n, in units of the input span
PIP_COMMAND = ".venv/bin/python -m pip install pyswarms"
#: How the pyswarms settings of (c) were chosen: S = 40, T = 2000, cost piezohyst.batch_rmse
#: (same trajectory as the NumPy model), seeds 0, 1, 2, this record; final best RMSE / best
#: RMSE found by any method. None reached 1.01 within the budget.
PYSWARMS_SETTINGS_TRIED = {
    "c1=c2=1.5, w 0.9->0.4 lin_variation, vclamp 0.2, bh reflective (used)": [1.059, 1.048, 1.034],
    "c1=c2=1.5, w 0.9->0.4 lin_variation, vclamp 0.2, bh nearest": [7.96, 6.44, 2.41],
    "c1=c2=1.5, w 0.9->0.4 lin_variation, vclamp 0.2, bh periodic (pyswarms default)": [20.1, 20.2, 16.6],
    "c1=c2=1.49618, w=0.7298 constant, vclamp 0.2, bh nearest": [1.055, 6.80, 6.84],
    "c1=c2=1.49618, w=0.7298, pyswarms defaults otherwise": [22.6, 35.8, 37.4],
    "c1=0.5, c2=0.3, w=0.9 (pyswarms documentation example), defaults otherwise": [26.2, 26.6, 32.2],
}


# --------------------------------------------------------------------------------- data


def make_record(N: int, seed: int, noise: float):
    """Input in [0, 1] (starts at 0), seed-2 MPI output plus seeded noise."""
    import piezohyst

    t = np.arange(N) / N
    swell = 0.3 + 0.7 * np.abs(np.sin(2.0 * np.pi * t))  # amplitude 0.3 .. 1, twice
    carrier = 0.5 * (1.0 - np.cos(2.0 * np.pi * 20.0 * t))  # 20 raised-cosine periods
    ripple = 1.0 + 0.2 * np.sin(2.0 * np.pi * 53.0 * t + 1.0) + 0.1 * np.sin(2.0 * np.pi * 97.0 * t + 2.0)
    x = swell * carrier * ripple
    v = x / x.max()
    truth = piezohyst.papers.mpi_seed2()
    y_clean = truth.simulate(v)
    sigma = noise * float(np.ptp(y_clean))
    y = y_clean + sigma * np.random.default_rng([seed, N]).standard_normal(N)
    reversals = int(np.count_nonzero(np.diff(np.sign(np.diff(v))) != 0))
    return v, np.ascontiguousarray(y), y_clean, truth, sigma, reversals


def template_model():
    """The search structure of (b)/(c): seed thresholds, identity envelopes, input range [0, 1]."""
    from piezohyst import GeneralizedPI

    return GeneralizedPI(SEED_THRESHOLDS, np.zeros(N_OPS), (0.0, 0.0, 0.0, 0.0), input_range=(0.0, 1.0))


def search_bounds(v, y):
    """Box of (b)/(c): a1..a3 in [-g, g], b_i in [0, g/2], g = range(y) / range(v)."""
    g = float(np.ptp(y)) / float(np.ptp(v))
    return np.array([(-g, g)] * 3 + [(0.0, 0.5 * g)] * N_OPS)


def rows_from(template_row: np.ndarray, X: np.ndarray) -> np.ndarray:
    """(S, 12) search vectors [a1, a2, a3, b1..b9] -> (S, 14 + 2n) GPI rows
    (layout ``range_lo, range_hi, poly[4], rising[4], falling[4], r[n], b[n]``)."""
    R = np.repeat(template_row[None, :], X.shape[0], axis=0)
    R[:, 3:6] = X[:, :3]  # poly = [c0 = 0, a1, a2, a3]
    R[:, 14 + N_OPS : 14 + 2 * N_OPS] = X[:, 3:]
    return np.ascontiguousarray(R)


def true_vector(truth) -> np.ndarray:
    return np.r_[truth.polynomial[1:], truth.weights]


# --------------------------------------------------------------------------- NumPy model


def mpi_rmse_numpy(X, v, y, r):
    """(S,) RMSE of S MPI parameter vectors [a1, a2, a3, b_1..b_n] (identity envelopes,
    shared thresholds r, c0 = 0): vectorized over (S, n), Python loop over time."""
    X = np.asarray(X, dtype=np.float64)
    S, n, N = X.shape[0], r.size, v.size
    a, b = X[:, :3], np.ascontiguousarray(X[:, 3:])
    # non-recursive parts, whole-array: band edges, polynomial minus target
    lo = v[:, None] - r  # (N, n)   g_l(v) - r
    hi = v[:, None] + r  # (N, n)   g_r(v) + r
    Y = np.outer(v, a[:, 0]) + np.outer(v * v, a[:, 1]) + np.outer(v * v * v, a[:, 2]) - y[:, None]  # (N, S)
    W = np.empty((N, S))  # sum_i b_i z_i(k)
    z = np.zeros((S, n))
    minimum, maximum, einsum = np.minimum, np.maximum, np.einsum
    for lk, hk, wk in zip(lo, hi, W, strict=False):  # rows are views
        minimum(z, hk, out=z)  # min(g_r(v) + r, z(k-1))
        maximum(z, lk, out=z)  # max(g_l(v) - r, .)
        einsum("ij,ij->i", b, z, out=wk)
    Y += W
    Y *= Y
    return np.sqrt(Y.sum(axis=0) / N)


_WORKER: dict = {}


def _worker_init(v, y, r):
    os.environ["OPENBLAS_NUM_THREADS"] = "1"
    _WORKER.update(v=v, y=y, r=r)


def _worker_cost(X):
    return mpi_rmse_numpy(X, _WORKER["v"], _WORKER["y"], _WORKER["r"])


class NumpyCost:
    """The NumPy model over ``processes`` worker processes (the swarm split in contiguous
    parts, as pyswarms' ``n_processes`` does), or in this process if ``processes == 1``."""

    def __init__(self, v, y, r, processes: int):
        self.v, self.y, self.r = v, y, r
        self.processes = processes
        self.pool = None
        if processes > 1:
            self.pool = mp.get_context("spawn").Pool(processes, initializer=_worker_init, initargs=(v, y, r))

    def __call__(self, X):
        if self.pool is None:
            return mpi_rmse_numpy(X, self.v, self.y, self.r)
        return np.concatenate(self.pool.map(_worker_cost, np.array_split(np.asarray(X), self.processes)))

    def close(self):
        if self.pool is not None:
            self.pool.close()
            self.pool.join()


# ---------------------------------------------------------------------------- runs


def _trajectory(times, best, nfev):
    return {"time_s": [float(t) for t in times], "best_rmse": [float(b) for b in best], "nfev": [int(n) for n in nfev]}


def run_a(v, y, reps, thresholds):
    """identify_mpi timed over reps calls; (median time, times, FitResult)."""
    from piezohyst import identify_mpi

    times, fit = [], None
    for _ in range(reps):
        t0 = time.perf_counter()
        fit = identify_mpi(v, y, operators=N_OPS, thresholds=thresholds)
        times.append(time.perf_counter() - t0)
    return times, fit


def run_vp(v, y, seed, population, iterations):
    """MPSO over the largest threshold r_n (thresholds r_i = i r_n / n, the layout of seed 2 and
    of identify_mpi's default) with an identify_mpi solve per candidate."""
    from piezohyst import identify_mpi
    from piezohyst.optimize import minimize

    best_fit = {"rmse": np.inf, "fit": None}
    span = float(np.ptp(v))

    def cost(X):
        out = np.empty(X.shape[0])
        for i, (rn,) in enumerate(X):
            fit = identify_mpi(v, y, operators=N_OPS, thresholds=span * np.arange(1, N_OPS + 1) * rn / N_OPS)
            out[i] = fit.metrics["rmse"]
            if out[i] < best_fit["rmse"]:
                best_fit.update(rmse=out[i], fit=fit)
        return out

    times = []
    t0 = time.perf_counter()
    res = minimize(
        cost,
        [VP_BOUNDS],
        method="mpso",
        rng=seed,
        max_iterations=iterations,
        population_size=population,
        callback=lambda ir: times.append(time.perf_counter() - t0),
    )
    total = time.perf_counter() - t0
    h = res.history
    return {
        "trajectory": _trajectory(times, h["best_cost"], h["nfev"]),
        "total_s": total,
        "best_rmse": float(res.fun),
        "nit": int(res.nit),
        "nfev": int(res.nfev),
        "x": {"r_n_over_input_span": float(res.x[0])},
        "fit": best_fit["fit"],
    }


def run_mpso(v, y, seed, population, iterations, bounds):
    from piezohyst.batch import batch_rmse
    from piezohyst.optimize import minimize

    model = template_model()
    trow = model.to_row()

    def cost(X):
        return batch_rmse(model, rows_from(trow, X), v, y, invalid_cost=np.inf)

    times = []
    t0 = time.perf_counter()
    res = minimize(
        cost,
        bounds,
        method="mpso",
        rng=seed,
        max_iterations=iterations,
        population_size=population,
        callback=lambda ir: times.append(time.perf_counter() - t0),
    )
    total = time.perf_counter() - t0
    h = res.history
    return {
        "trajectory": _trajectory(times, h["best_cost"], h["nfev"]),
        "total_s": total,
        "best_rmse": float(res.fun),
        "nit": int(res.nit),
        "nfev": int(res.nfev),
        "x": np.asarray(res.x).copy(),
    }


class _CapReached(Exception):
    pass


def run_pyswarms(ps, cost_fn, seed, population, iterations, bounds, cap):
    """pyswarms GlobalBestPSO on the normalized box; cost_fn takes physical (S, D) rows.
    Stops at ``iterations`` or when ``cap`` seconds have passed (checked before each
    evaluation, so the run ends at most one iteration past the cap)."""
    lo, hi = bounds[:, 0], bounds[:, 1]
    D = lo.size
    times, best, nfev = [], [], []
    state = {"best": np.inf, "x": None, "n": 0}

    def objective(U):
        if cap is not None and time.perf_counter() - t0 >= cap:
            raise _CapReached
        X = lo + U * (hi - lo)
        f = np.asarray(cost_fn(X), dtype=np.float64)
        i = int(np.argmin(f))
        if f[i] < state["best"]:
            state.update(best=float(f[i]), x=X[i].copy())
        state["n"] += f.size
        times.append(time.perf_counter() - t0)
        best.append(state["best"])
        nfev.append(state["n"])
        return f

    np.random.seed(seed)  # noqa: NPY002 -- pyswarms draws from NumPy's global random state
    capped = False
    t0 = time.perf_counter()
    opt = ps.single.GlobalBestPSO(
        n_particles=population,
        dimensions=D,
        options={"c1": 1.5, "c2": 1.5, "w": 0.9},
        bounds=(np.zeros(D), np.ones(D)),
        oh_strategy={"w": "lin_variation"},
        bh_strategy="reflective",
        velocity_clamp=(-0.2, 0.2),
    )
    try:
        opt.optimize(objective, iters=iterations, verbose=False)
    except _CapReached:
        capped = True
    total = time.perf_counter() - t0
    return {
        "trajectory": _trajectory(times, best, nfev),
        "total_s": total,
        "best_rmse": state["best"],
        "nit": len(times),
        "nfev": state["n"],
        "x": state["x"],
        "capped": capped,
    }


def import_pyswarms_quietly():
    """Import pyswarms without its default logging set-up (it writes ./report.log and adds a
    root stderr handler each time one of its objects is built): point its LOG_CFG at a config
    that only silences the pyswarms loggers. The file is kept for the run, removed at exit."""
    import atexit

    fd, path = tempfile.mkstemp(prefix="pyswarms-log-", suffix=".yaml")
    with os.fdopen(fd, "w") as f:
        f.write(
            "version: 1\ndisable_existing_loggers: false\n"
            "handlers:\n  null:\n    class: logging.NullHandler\n"
            "loggers:\n  pyswarms:\n    handlers: [null]\n    level: WARNING\n    propagate: false\n"
        )
    atexit.register(lambda: os.path.exists(path) and os.unlink(path))
    os.environ["LOG_CFG"] = path
    try:
        import pyswarms
    except ImportError:
        return None
    return pyswarms


# ---------------------------------------------------------------------------- summary


def time_to_target(traj, target):
    best = np.asarray(traj["best_rmse"])
    hit = np.flatnonzero(best <= target)
    if not hit.size:
        return None
    i = int(hit[0])
    return {"time_s": traj["time_s"][i], "iterations": i + 1, "nfev": traj["nfev"][i], "rmse": traj["best_rmse"][i]}


def thin(traj, keep_index=None, points=150):
    """Down-sampled trajectory for the JSON (log-spaced iterations, the hit and the last)."""
    n = len(traj["time_s"])
    if n == 0:
        return traj
    idx = set(np.unique(np.geomspace(1, n, points).astype(int) - 1).tolist()) | {n - 1}
    if keep_index is not None:
        idx.add(keep_index)
    idx = sorted(idx)
    return {"iteration": [i + 1 for i in idx], **{k: [traj[k][i] for i in idx] for k in traj}}


def param_error(x, truth_vec):
    if x is None:
        return None
    x = np.asarray(x)
    return {
        "max_abs_error_poly_a1_a3": float(np.max(np.abs(x[:3] - truth_vec[:3]))),
        "max_abs_error_weights": float(np.max(np.abs(x[3:] - truth_vec[3:]))),
    }


def fmt_t(x):
    if x is None:
        return "—"
    return f"{x * 1e3:.1f} ms" if x < 1 else f"{x:.2f} s"


# --------------------------------------------------------------------------------- main


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT, help=f"JSON output (default {DEFAULT_OUT})")
    ap.add_argument("--seed", type=int, default=2, help="data (noise) seed")
    ap.add_argument("--noise", type=float, default=0.002, help="noise std as a fraction of the output range")
    ap.add_argument("--reps", type=int, default=9, help="repetitions of the one-shot least-squares calls")
    ap.add_argument("--population", type=int, default=40, help="swarm size of (b) and (c)")
    ap.add_argument("--iterations", type=int, default=2000, help="iteration budget of (b) and (c)")
    ap.add_argument("--mpso-seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--vp-seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--vp-population", type=int, default=8)
    ap.add_argument("--vp-iterations", type=int, default=6)
    ap.add_argument("--pyswarms-seed", type=int, default=0)
    ap.add_argument("--cap", type=float, default=120.0, help="wall-time cap of (c), seconds")
    ap.add_argument(
        "--numpy-processes",
        type=int,
        default=None,
        help="worker processes for the NumPy model (default: 1 or 2, whichever is faster here)",
    )
    args = ap.parse_args(argv)

    from piezohyst import _core
    from piezohyst.batch import batch_rmse

    t_start = time.perf_counter()
    info = machine_info()
    vers = versions()
    cpus = info["cpus_usable"] or os.cpu_count() or 1

    v, y, y_clean, truth, sigma, reversals = make_record(N_SAMPLES, args.seed, args.noise)
    truth_vec = true_vector(truth)
    truth_rmse = float(np.sqrt(np.mean((y_clean - y) ** 2)))
    bounds = search_bounds(v, y)
    print(
        f"record: N={N_SAMPLES}, input [0, 1] with {reversals} reversals, output range {np.ptp(y_clean):.4f}, "
        f"noise std {sigma:.3g} ({100 * args.noise:g} % of range); true-parameter RMSE {truth_rmse:.5g}; "
        f"rayon threads {_core.thread_count()}",
        flush=True,
    )

    runs = []  # each: method, label, kind (oneshot/iterative), ...

    # (a) least squares, seed thresholds
    times, fit = run_a(v, y, args.reps, SEED_THRESHOLDS)
    runs.append(
        {
            "method": "a",
            "label": "(a) identify_mpi LS, r = 0.1..0.9",
            "kind": "oneshot",
            "times_s": times,
            "median_s": statistics.median(times),
            "min_s": min(times),
            "best_rmse": fit.metrics["rmse"],
            "fit_metrics": fit.metrics,
            "x": np.r_[fit.model.polynomial[1:], fit.model.weights],
            "c0": fit.model.polynomial[0],
            "description": "identify_mpi(v, y, operators=9, thresholds=0.1..0.9): bounded least squares "
            "over c0..c3 and b_i >= 0, thresholds fixed at seed 2's; median of "
            f"{args.reps} calls (regressors + solve + free-run RMSE)",
        }
    )
    print(
        f"(a)    {runs[-1]['median_s'] * 1e3:.1f} ms (median of {args.reps}; first call {times[0] * 1e3:.0f} ms, "
        f"it imports scipy.optimize), RMSE {runs[-1]['best_rmse']:.6g}",
        flush=True,
    )

    # (a0) least squares, identify_mpi's default thresholds
    times, fit0 = run_a(v, y, args.reps, None)
    runs.append(
        {
            "method": "a0",
            "label": "(a0) identify_mpi LS, default r",
            "kind": "oneshot",
            "times_s": times,
            "median_s": statistics.median(times),
            "min_s": min(times),
            "best_rmse": fit0.metrics["rmse"],
            "fit_metrics": fit0.metrics,
            "thresholds": fit0.model.thresholds.tolist(),
            "description": "identify_mpi(v, y, operators=9): default thresholds over half the input "
            "range (no knowledge of the true thresholds)",
        }
    )
    print(f"(a0)   {runs[-1]['median_s'] * 1e3:.1f} ms, RMSE {runs[-1]['best_rmse']:.6g}", flush=True)

    # (a+vp) variable projection over the threshold scale r_n
    for s in args.vp_seeds:
        r = run_vp(v, y, s, args.vp_population, args.vp_iterations)
        fit_vp = r.pop("fit")
        r.update(
            method="a+vp",
            label=f"(a+vp) MPSO(r_n) + LS, seed {s}",
            kind="iterative",
            seed=s,
            description=f"MPSO ({args.vp_population} x {args.vp_iterations}) over the largest threshold "
            f"r_n in {VP_BOUNDS} x input span, thresholds r_i = i r_n / 9 (identify_mpi's "
            "default layout, whose r_n is 0.45 x span), one identify_mpi least-squares solve per "
            "candidate (sequential in Python); the true thresholds are not given",
            x_linear=None if fit_vp is None else np.r_[fit_vp.model.polynomial, fit_vp.model.weights],
        )
        runs.append(r)
        print(f"(a+vp) seed {s}: {r['total_s']:.2f} s, RMSE {r['best_rmse']:.6g}, r = {r['x']}", flush=True)

    # (b) MPSO alone on all 12 parameters, piezohyst batch cost
    for s in args.mpso_seeds:
        r = run_mpso(v, y, s, args.population, args.iterations, bounds)
        r.update(
            method="b",
            label=f"(b) MPSO alone, seed {s}",
            kind="iterative",
            seed=s,
            description=f"piezohyst MPSO over a1..a3, b1..b9 (thresholds fixed 0.1..0.9, c0 = 0), "
            f"S = {args.population}, T = {args.iterations}, cost = piezohyst.batch_rmse "
            "of the whole swarm per iteration, no polish",
        )
        runs.append(r)
        print(f"(b)    seed {s}: {r['total_s']:.2f} s, RMSE {r['best_rmse']:.6g}", flush=True)

    # (c) pyswarms + NumPy, and (c') pyswarms + piezohyst
    ps = import_pyswarms_quietly()
    pyswarms_info = {
        "available": ps is not None,
        "version": getattr(ps, "__version__", None),
        "install_command": PIP_COMMAND,
    }
    numpy_check = None
    if ps is None:
        print(
            f"(c)    SKIPPED: pyswarms is not installed in this environment. Install it with\n"
            f"           {PIP_COMMAND}\n       (a benchmark-only dependency) and run again.",
            flush=True,
        )
    else:
        model = template_model()
        trow = model.to_row()
        # correctness of the NumPy model against piezohyst on a random swarm in the box
        X = np.random.default_rng(123).uniform(bounds[:, 0], bounds[:, 1], (args.population, bounds.shape[0]))
        ref = batch_rmse(model, rows_from(trow, X), v, y)
        got = mpi_rmse_numpy(X, v, y, SEED_THRESHOLDS)
        np.testing.assert_allclose(got, ref, rtol=RTOL_NUMPY, atol=0, err_msg="NumPy MPI model != piezohyst")
        numpy_check = {
            "rows": int(X.shape[0]),
            "max_rel_diff": float(np.max(np.abs(got - ref) / ref)),
            "rtol": RTOL_NUMPY,
        }
        # 1 or 2 processes for the NumPy model: whichever is faster here (untimed set-up)
        choices = [args.numpy_processes] if args.numpy_processes else sorted({1, min(2, cpus)})
        numpy_choice = {}
        cost_np = None
        for p in choices:
            c = NumpyCost(v, y, SEED_THRESHOLDS, p)
            np.testing.assert_allclose(c(X), ref, rtol=RTOL_NUMPY, atol=0)  # also warms the pool
            ts = []
            for _ in range(3 if len(choices) > 1 else 0):
                t0 = time.perf_counter()
                c(X)
                ts.append(time.perf_counter() - t0)
            numpy_choice[p] = statistics.median(ts) if ts else None
            if cost_np is None or (ts and numpy_choice[p] < numpy_choice[cost_np.processes]):
                if cost_np is not None:
                    cost_np.close()
                cost_np = c
            else:
                c.close()
        nproc = cost_np.processes
        numpy_check["processes_trial_median_s"] = {str(k): w for k, w in numpy_choice.items()}
        numpy_check["processes_used"] = nproc
        try:
            print(
                f"(c)    pyswarms {ps.__version__} + NumPy model on {nproc} process(es), cap {args.cap:g} s ...",
                flush=True,
            )
            r = run_pyswarms(ps, cost_np, args.pyswarms_seed, args.population, args.iterations, bounds, args.cap)
        finally:
            cost_np.close()
        r.update(
            method="c",
            label="(c) pyswarms + NumPy",
            kind="iterative",
            seed=args.pyswarms_seed,
            numpy_processes=nproc,
            description=f"pyswarms {ps.__version__} GlobalBestPSO (c1 = c2 = 1.5, w 0.9 -> 0.4 lin_variation, "
            "velocity clamp 0.2, bh reflective, normalized box) driving a NumPy MPI model "
            f"(vectorized over swarm and operators, Python loop over time) in {nproc} "
            f"process(es); S = {args.population}, T = {args.iterations} or {args.cap:g} s, "
            "whichever first",
        )
        runs.append(r)
        print(
            f"(c)    {r['total_s']:.2f} s, {r['nit']} iterations{' (capped)' if r['capped'] else ''}, "
            f"RMSE {r['best_rmse']:.6g}",
            flush=True,
        )

        def cost_ph(X):
            return batch_rmse(model, rows_from(trow, X), v, y, invalid_cost=np.inf)

        r2 = run_pyswarms(ps, cost_ph, args.pyswarms_seed, args.population, args.iterations, bounds, None)
        r2.update(
            method="c'",
            label="(c') pyswarms + piezohyst",
            kind="iterative",
            seed=args.pyswarms_seed,
            description="the same pyswarms run (same seed and settings) with the cost from "
            "piezohyst.batch_rmse: pyswarms' algorithm without the cap, and the "
            "evaluation speed-up at an identical trajectory",
        )
        runs.append(r2)
        print(f"(c')   {r2['total_s']:.2f} s, {r2['nit']} iterations, RMSE {r2['best_rmse']:.6g}", flush=True)

    # ------------------------------------------------------------------ summary
    best_rmse = min(r["best_rmse"] for r in runs)
    best_run = min(runs, key=lambda r: r["best_rmse"])["label"]
    target = (1.0 + TOL) * best_rmse
    for r in runs:
        if r["kind"] == "oneshot":
            ok = r["best_rmse"] <= target
            r["reached"] = ok
            r["time_to_target_s"] = r["median_s"] if ok else None
            r["rmse_at_target"] = r["best_rmse"] if ok else None
            r["total_s"] = r["median_s"]
            r["first_call_s"] = r["times_s"][0]
            r["evaluations"] = "1 solve"
        else:
            hit = time_to_target(r["trajectory"], target)
            r["reached"] = hit is not None
            r["time_to_target_s"] = None if hit is None else hit["time_s"]
            r["rmse_at_target"] = None if hit is None else hit["rmse"]
            r["iterations_to_target"] = None if hit is None else hit["iterations"]
            r["nfev_to_target"] = None if hit is None else hit["nfev"]
            dt = np.diff(np.r_[0.0, r["trajectory"]["time_s"]])
            r["median_iteration_s"] = float(np.median(dt)) if dt.size else None
            r["evaluations"] = f"{r['nfev']}"
        r["best_over_overall_best"] = r["best_rmse"] / best_rmse
        if "x" in r and r.get("method") in ("a", "b", "c", "c'"):
            r["param_error_vs_truth"] = param_error(r["x"], truth_vec)

    # (c) vs (c'): same trajectory? extrapolate (c) if it was capped
    rc = next((r for r in runs if r["method"] == "c"), None)
    rc2 = next((r for r in runs if r["method"] == "c'"), None)
    if rc is not None and rc2 is not None:
        # best-so-far RMSE of both runs over the iterations both reached (full, unthinned)
        m = min(len(rc["trajectory"]["best_rmse"]), len(rc2["trajectory"]["best_rmse"]))
        b1 = np.asarray(rc["trajectory"]["best_rmse"][:m])
        b2 = np.asarray(rc2["trajectory"]["best_rmse"][:m])
        rel = float(np.max(np.abs(b1 - b2) / b2)) if m else None
        same = rel is not None and rel <= 1e-9
        rc["same_trajectory_as_c_prime"] = {
            "compared_iterations": m,
            "max_rel_diff": rel,
            "same": same,
            "tolerance": 1e-9,
        }
        rc["speedup_per_iteration_c_prime_over_c"] = rc["median_iteration_s"] / rc2["median_iteration_s"]
        rc["extrapolated_time_to_target_s"] = None
        if not rc["reached"] and rc["capped"] and same and rc2["reached"]:
            rc["extrapolated_time_to_target_s"] = rc2["iterations_to_target"] * rc["median_iteration_s"]
            rc["extrapolation"] = "(c') iterations to target x (c) median iteration time; not measured"
        rc["full_budget_estimate_s"] = args.iterations * rc["median_iteration_s"]

    for r in runs:
        if r["kind"] == "iterative":
            r["trajectory"] = thin(r["trajectory"], None if not r["reached"] else r["iterations_to_target"] - 1)

    ra = runs[0]
    headline = {
        "target_rmse": target,
        "best_rmse": best_rmse,
        "best_run": best_run,
        "tolerance": TOL,
        "a_time_to_target_s": ra["time_to_target_s"],
        "a_reached": ra["reached"],
        "a_target_time_s": TARGET_TIME_A,
        "pass": bool(ra["reached"] and ra["time_to_target_s"] <= TARGET_TIME_A),
        "rayon_threads": _core.thread_count(),
        "b_median_time_to_target_s": (
            statistics.median([r["time_to_target_s"] for r in runs if r["method"] == "b"])
            if all(r["reached"] for r in runs if r["method"] == "b")
            else None
        ),
        "b_reached": [r["reached"] for r in runs if r["method"] == "b"],
        "pyswarms_available": ps is not None,
    }
    for r in runs:
        if "x" in r and r["x"] is not None:
            r["x"] = np.asarray(r["x"]).tolist() if not isinstance(r["x"], dict) else r["x"]
        if "x_linear" in r and r["x_linear"] is not None:
            r["x_linear"] = np.asarray(r["x_linear"]).tolist()

    payload = {
        "benchmark": "identify_mpi",
        "timestamp_utc": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "machine": info,
        "versions": {**vers, "pyswarms": pyswarms_info["version"]},
        "data": {
            "model": "piezohyst.mpi_seed2() (seed 2 Table 1: r = 0.1..0.9, b, P = 0.2547 v - 0.00358 v^2 + "
            "0.7123 v^3, identity envelopes)",
            "N": N_SAMPLES,
            "input": "v = swell * raised-cosine carrier (20 periods) * (1 + 0.2 sin(53) + "
            "0.1 sin(97)), normalized to [0, 1], starts at 0; swell 0.3..1 twice",
            "input_reversals": reversals,
            "output_range": float(np.ptp(y_clean)),
            "noise_std": sigma,
            "noise_fraction_of_range": args.noise,
            "noise_seed": args.seed,
            "true_parameter_rmse": truth_rmse,
            "true_vector_a1_a3_b": truth_vec.tolist(),
        },
        "method": {
            "metric": f"wall time until the run's best-so-far RMSE <= (1 + {TOL}) x the best RMSE any run "
            "found (optimizer set-up included); one-shot least squares: median call time",
            "search_box_b_c": {
                "a1..a3": bounds[0].tolist(),
                "b_i": bounds[3].tolist(),
                "rule": "a_j in [-g, g], b_i in [0, g/2], g = range(y)/range(v)",
            },
            "budget_b_c": {"population": args.population, "iterations": args.iterations, "cap_c_s": args.cap},
            "threads": "OPENBLAS_NUM_THREADS=1; RAYON_NUM_THREADS=2 unless set; NumPy model in this "
            "process or split over a 2-process pool, whichever was faster in an untimed trial "
            "(see numpy_model_check)",
            "pyswarms": pyswarms_info,
            "pyswarms_settings_tried": PYSWARMS_SETTINGS_TRIED,
            "numpy_model_check": numpy_check,
            "note": "(a) minimizes the squared error exactly over a superset of (b)/(c)'s search space "
            "(c0 free, polynomial unbounded), so no run of (b)/(c) can beat it on this record",
        },
        "runs": runs,
        "headline": headline,
        "wall_time_s": None,
    }
    try:
        payload["machine"]["loadavg_at_end"] = list(os.getloadavg())
    except OSError:
        pass
    payload["versions"]["extension_sha256_at_end"] = versions()["extension_sha256"]
    payload["wall_time_s"] = round(time.perf_counter() - t_start, 2)
    write_json_atomic(args.out, payload)

    # table
    print()
    print(
        f"MPI identification, N = {N_SAMPLES}, noise {100 * args.noise:g} % of range — {info['cpu_model']}, "
        f"{cpus} usable CPUs, rayon {_core.thread_count()} threads, piezohyst {vers['piezohyst']}"
    )
    print(
        f"best RMSE found {best_rmse:.6g} ({best_run}); target = 1.01 x best = {target:.6g}; "
        f"true-parameter RMSE {truth_rmse:.6g}"
    )
    hdr = (
        f"{'run':<34} {'evals':>7} | {'reached':>7} {'time->target':>12} {'RMSE at target':>14} | "
        f"{'best RMSE':>10} {'x best':>7} {'total time':>10} {'iters':>6}"
    )
    print(hdr)
    print("-" * len(hdr))
    for r in runs:
        at = "—" if r["rmse_at_target"] is None else f"{r['rmse_at_target']:.6g}"
        print(
            f"{r['label']:<34} {r['evaluations']:>7} | {'yes' if r['reached'] else 'NO':>7} "
            f"{fmt_t(r['time_to_target_s']):>12} "
            f"{at:>14} | "
            f"{r['best_rmse']:>10.6g} {r['best_over_overall_best']:>7.4f} {fmt_t(r['total_s']):>10} "
            f"{(r.get('nit') or '—')!s:>6}"
        )
    if rc is not None:
        sm = rc["same_trajectory_as_c_prime"]
        print(
            f"(c) vs (c'): same trajectory over {sm['compared_iterations']} compared iterations: {sm['same']} "
            f"(max rel diff {sm['max_rel_diff']:.1e}); per-iteration time {fmt_t(rc['median_iteration_s'])} "
            f"vs {fmt_t(rc2['median_iteration_s'])} ({rc['speedup_per_iteration_c_prime_over_c']:.0f}x); "
            + (
                f"(c) full budget would take ~{rc['full_budget_estimate_s']:.0f} s"
                if rc["capped"]
                else "(c) ran its full budget"
            )
            + (
                f"; (c) extrapolated time to target {rc['extrapolated_time_to_target_s']:.0f} s (not measured)"
                if rc.get("extrapolated_time_to_target_s")
                else ""
            )
        )
    elif ps is None:
        print(f"(c) skipped: pyswarms not installed ({PIP_COMMAND})")
    verdict = "PASS" if headline["pass"] else "FAIL"
    print(
        f"Target (a) within 1 % of the best RMSE in <= {TARGET_TIME_A:g} s on 2 cores: {verdict} "
        f"({fmt_t(ra['time_to_target_s'])}). Wrote {args.out} in {payload['wall_time_s']} s."
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
