"""Identification by least squares over the linear parameters (SPEC §4).

With the structure fixed — thresholds, envelopes, rate terms, creep time constants, the
Preisach grid — the output of a PI-type or Preisach model is linear in its weights and
polynomial coefficients. The regressors (operator outputs, cell fractions, lag outputs) come
from the Rust core in one pass; the weights come from a bounded least-squares solve
(``scipy.optimize.lsq_linear``), non-negative where the model needs it (play and Preisach
weights). This is the inner, exact step of variable projection; the metaheuristics of
:mod:`piezohyst.optimize` search the few nonlinear parameters around it.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np


from . import _core
from ._validate import as_int, as_record
from .creep import Creep
from .pi import PI, GeneralizedPI, RateDependentPI
from .preisach import Preisach

__all__ = ["CEMF_PARAMETERS", "FitResult", "IdentificationResult", "KINDS", "identify_cemf", "fit_linear", "fit_metrics", "identify", "identify_mpi",
           "identify_pi", "identify_preisach"]


@dataclass(frozen=True)
class FitResult:
    """A fitted model with its free-run error on the data it was fitted to."""

    model: object
    metrics: dict
    wall_time: float

    def __repr__(self) -> str:
        m = self.metrics
        return (f"FitResult({type(self.model).__name__}, rmse={m['rmse']:.4g} ({m['rmse_percent']:.3g} % of range), "
                f"max_error={m['max_error']:.4g} ({m['max_error_percent']:.3g} %), {self.wall_time * 1e3:.1f} ms)")


def fit_metrics(predicted, measured) -> dict:
    """RMSE and max error of the free-run simulation, also in % of the measured range."""
    e = np.asarray(predicted) - np.asarray(measured)
    span = float(np.ptp(measured)) or 1.0
    rmse = float(np.sqrt(np.mean(e**2)))
    emax = float(np.max(np.abs(e)))
    return {"rmse": rmse, "max_error": emax, "rmse_percent": 100 * rmse / span, "max_error_percent": 100 * emax / span}


def _layout(model):
    """Column bounds ``(lb, ub)`` of the regressors and a function mapping the solution back
    to a model of the same structure."""
    inf = np.inf
    creep = getattr(model, "creep", None)
    m_creep = 0 if creep is None else creep.terms

    def with_creep(theta_tail):
        return None if creep is None else Creep(creep.ts, creep.taus, theta_tail)

    if isinstance(model, RateDependentPI):
        n = model.thresholds.size
        lb = np.r_[0.0, np.zeros(n), np.full(n, -inf), np.zeros(m_creep)]

        def build(t):
            return RateDependentPI(model.thresholds, t[1:1 + n], model.ts, t[0], model.beta, t[1 + n:1 + 2 * n],
                                   model.filter_tau, creep=with_creep(t[1 + 2 * n:]), units=model.units)
    elif isinstance(model, GeneralizedPI):
        n = model.thresholds.size
        lb = np.r_[np.full(4, -inf), np.zeros(n), np.zeros(m_creep)]

        def build(t):
            return GeneralizedPI(model.thresholds, t[4:4 + n], t[:4], model.rising, model.falling, model.input_range,
                                 creep=with_creep(t[4 + n:]), units=model.units)
    elif isinstance(model, PI):
        n = model.thresholds.size
        lb = np.r_[0.0, np.zeros(n), np.zeros(m_creep)]

        def build(t):
            return PI(model.thresholds, t[1:1 + n], t[0], creep=with_creep(t[1 + n:]), units=model.units)
    elif isinstance(model, Preisach):
        cells = model.weights.size
        lb = np.r_[-inf, 0.0, np.zeros(cells)]

        def build(t):
            return Preisach(model.levels, model.input_range, t[2:], t[0], t[1], model.memory, units=model.units)
    else:
        raise TypeError(f"model must be PI, GeneralizedPI, RateDependentPI or Preisach, got {type(model).__name__}")
    return lb, np.full(lb.size, inf), build


def fit_linear(model, input, output) -> FitResult:
    """Fit the linear parameters of ``model`` (its weights, linear term / polynomial, creep
    weights; Preisach offset, slope and cell weights) to a record, keeping its structure.

    Play weights, Preisach weights and slopes are constrained non-negative (a Preisach
    density is a mass; non-negative play weights keep the PI model invertible).

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst import PI, fit_linear
    >>> truth = PI([0.1, 0.3, 0.6], [0.5, 0.2, 0.1], p0=0.8)
    >>> v = np.sin(np.linspace(0, 12, 1200)) * np.linspace(1, 0.3, 1200)
    >>> fit = fit_linear(PI([0.1, 0.3, 0.6], [0, 0, 0], p0=1.0), v, truth.simulate(v))
    >>> np.allclose(fit.model.weights, truth.weights, atol=1e-9), round(fit.model.p0, 9)
    (True, 0.8)
    """
    from scipy.optimize import lsq_linear  # imported on use: keeps the command line quick to start

    t0 = time.perf_counter()
    v = as_record(input, "input", min_length=2)
    y = as_record(output, "output", min_length=2)
    if y.size != v.size:
        raise ValueError(f"output has {y.size} samples, input has {v.size}; they must match")
    lb, ub, build = _layout(model)
    A = _core.regressors(model.family, list(model.dims), model.to_row(), v)
    scale = np.maximum(np.sqrt(np.mean(A**2, axis=0)), 1e-300)   # equilibrate the columns
    sol = lsq_linear(A / scale, y, bounds=(lb * scale, ub * scale), method="bvls", lsmr_tol=None)
    theta = sol.x / scale
    fitted = build(theta)
    return FitResult(fitted, fit_metrics(fitted.simulate(v), y), time.perf_counter() - t0)


def _default_thresholds(v, n):
    span = float(np.ptp(v))
    if not span > 0:
        raise ValueError("input is constant: there is no hysteresis to identify")
    return np.arange(1, n + 1) * span / (2.0 * (n + 1))


def identify_pi(input, output, *, operators=9, thresholds=None, creep=None) -> FitResult:
    """Classical PI with ``operators`` thresholds spread over half the input range (or the
    given ones), weights and linear term by non-negative least squares."""
    v = as_record(input, "input", min_length=2)
    r = _default_thresholds(v, as_int(operators, "operators", minimum=1)) if thresholds is None else thresholds
    return fit_linear(PI(r, np.zeros(len(r)), 1.0, creep=creep), v, output)


def identify_mpi(input, output, *, operators=9, thresholds=None, rising=None, falling=None, creep=None) -> FitResult:
    """Seed 2's MPI (cubic input polynomial + generalized plays) with the envelopes given
    (identity by default); polynomial and weights by bounded least squares."""
    v = as_record(input, "input", min_length=2)
    r = _default_thresholds(v, as_int(operators, "operators", minimum=1)) if thresholds is None else thresholds
    lo, hi = float(v.min()), float(v.max())
    pad = 0.5 * (hi - lo)
    model = GeneralizedPI(r, np.zeros(len(r)), (0.0, 0.0, 0.0, 0.0), rising, falling, (lo - pad, hi + pad), creep=creep)
    return fit_linear(model, v, output)


def identify_preisach(input, output, *, levels=12, input_range=None, memory=64) -> FitResult:
    """Discretized Preisach on a ``levels x levels`` grid over the input range; offset, slope
    and cell weights (non-negative) by least squares."""
    v = as_record(input, "input", min_length=2)
    lo, hi = (float(v.min()), float(v.max())) if input_range is None else input_range
    n = as_int(levels, "levels", minimum=1)
    model = Preisach(n, (lo, hi), np.zeros(n * (n + 1) // 2), memory=memory)
    return fit_linear(model, v, output)


@dataclass(frozen=True)
class IdentificationResult:
    """What :func:`identify` returns: the model, its free-run metrics on the training record
    (and the validation record when given), the optimizer history and the wall time."""

    model: object
    train: dict
    validation: dict | None
    method: str
    wall_time: float
    history: dict | None = None

    @property
    def metrics(self) -> dict:
        return {"train": self.train, "validation": self.validation}

    def to_dict(self) -> dict:
        """JSON-ready report (the model file's ``fit`` section)."""
        return {"method": self.method, "wall_time_s": self.wall_time, "train": self.train,
                "validation": self.validation}

    def plot(self, input, output):
        """Loop, fit and residual for a record (matplotlib figure)."""
        import matplotlib.pyplot as plt

        v = as_record(input, "input")
        y = as_record(output, "output")
        yp = self.model.simulate(v)
        fig, ax = plt.subplots(1, 3, figsize=(13, 3.8))
        ax[0].plot(v, y, lw=0.8, label="measured")
        ax[0].plot(v, yp, lw=0.8, label="model")
        ax[0].set(xlabel="input", ylabel="output", title="hysteresis loop")
        ax[0].legend()
        ax[1].plot(y, lw=0.8, label="measured")
        ax[1].plot(yp, lw=0.8, label="model")
        ax[1].set(xlabel="sample", title="fit")
        ax[2].plot(yp - y, lw=0.8)
        ax[2].set(xlabel="sample", title="residual")
        fig.tight_layout()
        return fig


#: Model kinds :func:`identify` accepts.
KINDS = ("pi", "gpi", "mpi", "rdpi", "preisach", "boucwen")


def _boucwen_bounds(v, y):
    """Search box for Bouc–Wen ``(a, beta, gamma, n = 1, d)`` from the data's scales."""
    dv = float(np.ptp(v)) or 1.0
    gain = float(np.ptp(y)) / dv
    return [(0.0, 4 * gain), (1e-3 / dv, 50.0 / dv), (-50.0 / dv, 50.0 / dv), (1.0, 1.0), (0.0, 4 * gain)]


def identify(input, output, model="mpi", *, fs=None, operators=9, levels=12, optimizer="ls", rng=None,
             max_iterations=200, population_size=None, validate=None, progress=False, callback=None):
    """Identify a hysteresis model from an input/output record (free-run simulation error).

    Parameters
    ----------
    input, output : array_like
        The training record.
    model : str
        One of ``KINDS``. ``pi``, ``gpi``/``mpi``, ``rdpi`` and ``preisach`` are fitted by
        least squares over their linear parameters with a default structure (thresholds over
        half the input range; a grid over the input range); ``boucwen`` by a population
        optimizer over all its parameters, each population evaluated in one Rust batch call.
    fs : float, optional
        Sample rate, Hz (needed by ``rdpi``).
    optimizer : str
        ``"ls"`` for the linear families; ``"css"``, ``"pso"``, ``"mpso"`` or ``"de"`` for
        Bouc–Wen (``"ls"`` there means ``"de"``).
    validate : (input, output), optional
        A held-out record; its metrics are reported, it is not fitted.

    Returns
    -------
    IdentificationResult
    """
    t0 = time.perf_counter()
    if model not in KINDS:
        raise ValueError(f"model = {model!r} is unknown; expected one of {list(KINDS)}")
    v = as_record(input, "input", min_length=2)
    y = as_record(output, "output", min_length=2)
    if y.size != v.size:
        raise ValueError(f"output has {y.size} samples, input has {v.size}; they must match")
    history = None
    if model == "pi":
        fitted, method = identify_pi(v, y, operators=operators).model, "ls"
    elif model in ("gpi", "mpi"):
        fitted, method = identify_mpi(v, y, operators=operators).model, "ls"
    elif model == "preisach":
        fitted, method = identify_preisach(v, y, levels=levels).model, "ls"
    elif model == "rdpi":
        if fs is None:
            raise ValueError("fs is required for model = 'rdpi' (the rate needs the sample time)")
        r = _default_thresholds(v, as_int(operators, "operators", minimum=1))
        template = RateDependentPI(r, np.zeros(r.size), 1.0 / float(fs), 1.0, 0.0)
        fitted, method = fit_linear(template, v, y).model, "ls"
    else:
        from .differential import BoucWen
        from .optimize import minimize

        method = "de" if optimizer == "ls" else optimizer
        template = BoucWen(1.0, 1.0, 0.0)

        def cost(rows):
            return _core.batch_rmse(template.family, [], np.ascontiguousarray(rows), v, y, float("inf"))

        res = minimize(cost, _boucwen_bounds(v, y), method=method, rng=rng, max_iterations=max_iterations,
                       population_size=population_size, progress=progress, callback=callback, polish=True)
        fitted, history = BoucWen(*res.x), res.history
    train = fit_metrics(fitted.simulate(v), y)
    val = None
    if validate is not None:
        vv = as_record(validate[0], "validate input")
        vy = as_record(validate[1], "validate output")
        val = fit_metrics(fitted.simulate(vv), vy)
    return IdentificationResult(fitted, train, val, method, time.perf_counter() - t0, history)


#: Parameters searched by :func:`identify_cemf`, in seed 1's normalized form.
CEMF_PARAMETERS = ("M", "B", "K", "tem", "alpha", "beta", "gamma")


def identify_cemf(voltage, position, fs, *, capacitance=1.8e-6, bounds=None, optimizer="css", rng=None,
                  max_iterations=150, population_size=None, substeps=1, tolerance=0.05, validate=None,
                  progress=False, callback=None) -> IdentificationResult:
    """Grey-box identification of the CEMF stage model (seed 1) from the applied voltage and
    the measured displacement: ``M x'' + B x' + K x = Vin - Vh`` (``M = m/Tem``, ...) with
    the CEMF Bouc–Wen law on the stack charge, by a population optimizer over
    ``CEMF_PARAMETERS`` on the free-run simulation error. Each population is simulated in one
    Rust batch call (rayon). The stack capacitance is taken as known (seed 1: 1800 nF).

    Returns an :class:`IdentificationResult` whose ``model`` is a :class:`piezohyst.StageParameters`.
    """
    from .optimize import minimize
    from .stage import Amplifier, Stage, StageParameters

    t0 = time.perf_counter()
    u = as_record(voltage, "voltage", min_length=2)
    x = as_record(position, "position", min_length=2)
    if x.size != u.size:
        raise ValueError(f"position has {x.size} samples, voltage has {u.size}; they must match")
    fs = float(fs)
    if not fs > 0:
        raise ValueError(f"fs = {fs} must be > 0")
    gain = float(np.ptp(x)) / (float(np.ptp(u)) or 1.0)
    if not gain > 0:
        raise ValueError("position does not move: nothing to identify")
    if bounds is None:
        k_lo, k_hi = 0.3 / gain, 3.0 / gain
        w_lo, w_hi = 2 * np.pi * 1e3, 2 * np.pi * 2e4          # resonance between 1 and 20 kHz
        q = capacitance * float(np.ptp(u))                   # charge scale, C
        bounds = [(k_lo / w_hi**2, k_hi / w_lo**2), (0.0, 0.4 * np.sqrt(k_hi * k_hi / w_lo**2)), (k_lo, k_hi),
                  (1.0, 50.0), (0.0, 4.0 / capacitance), (0.0, 30.0 / q), (-30.0 / q, 30.0 / q)]
    bounds = [(float(lo), float(hi)) for lo, hi in bounds]
    if len(bounds) != len(CEMF_PARAMETERS):
        raise ValueError(f"bounds has {len(bounds)} pairs, expected {len(CEMF_PARAMETERS)} ({CEMF_PARAMETERS})")
    wide = Amplifier(-1e9, 1e9)
    template = Stage(StageParameters(1.0, 0.0, 1.0, 1.0, capacitance), wide, sample_time=1.0 / fs,
                     substeps=substeps, tolerance=tolerance).core_params()

    def rows(theta):
        theta = np.atleast_2d(theta)
        out = np.repeat(template[None, :], theta.shape[0], axis=0)
        M, B, K, tem = theta[:, 0], theta[:, 1], theta[:, 2], theta[:, 3]
        out[:, 0], out[:, 1], out[:, 2], out[:, 3] = M * tem, B * tem, K * tem, tem
        out[:, 5], out[:, 6], out[:, 7] = theta[:, 4], theta[:, 5], theta[:, 6]
        return np.ascontiguousarray(out)

    def cost(theta):
        return _core.stage_batch_rmse(rows(theta), 1.0 / fs, substeps, tolerance, u, x, float("inf"))

    method = "css" if optimizer == "ls" else optimizer
    res = minimize(cost, bounds, method=method, rng=rng, max_iterations=max_iterations,
                   population_size=population_size, progress=progress, callback=callback)
    M, B, K, tem, alpha, beta, gamma = res.x
    params = StageParameters(M * tem, B * tem, K * tem, tem, capacitance, alpha, beta, gamma)
    stage = Stage(params, wide, sample_time=1.0 / fs, substeps=substeps, tolerance=tolerance)
    train = fit_metrics(stage.simulate(u).position, x)
    val = None
    if validate is not None:
        vu = as_record(validate[0], "validate voltage")
        vx = as_record(validate[1], "validate position")
        val = fit_metrics(stage.simulate(vu).position, vx)
    return IdentificationResult(params, train, val, method, time.perf_counter() - t0, res.history)
