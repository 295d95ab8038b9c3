"""Identification by least squares over the linear parameters (docs/spec.md §4).

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
from dataclasses import dataclass, field

import numpy as np

from .. import _core
from .._validate import as_int, as_record, as_scalar
from ..errors import ParameterError, ParameterTypeError
from ..models.creep import Creep
from ..models.pi import PI, GeneralizedPI, RateDependentPI
from ..models.preisach import Preisach

__all__ = [
    "CEMF_PARAMETERS",
    "LOSSES",
    "FitResult",
    "IdentificationResult",
    "default_huber_delta",
    "fit_linear",
    "fit_metrics",
    "huber_cost",
    "identify_cemf",
    "identify_mpi",
    "identify_pi",
    "identify_preisach",
    "minimize_huber",
]


@dataclass(frozen=True)
class FitResult:
    """A fitted model with its free-run error on the data it was fitted to."""

    model: object
    metrics: dict
    wall_time: float

    def __repr__(self) -> str:
        m = self.metrics
        return (
            f"FitResult({type(self.model).__name__}, rmse={m['rmse']:.4g} ({m['rmse_percent']:.3g} % of range), "
            f"max_error={m['max_error']:.4g} ({m['max_error_percent']:.3g} %), {self.wall_time * 1e3:.1f} ms)"
        )


def fit_metrics(predicted, measured) -> dict:
    """RMSE and max error of the free-run simulation, also in % of the measured range."""
    predicted = as_record(predicted, "predicted", copy=False)
    measured = as_record(measured, "measured", copy=False)
    if predicted.size != measured.size:
        raise ParameterError(f"predicted has {predicted.size} samples, measured has {measured.size}; they must match")
    e = predicted - measured
    span = float(np.ptp(measured)) or 1.0
    rmse = float(np.sqrt(np.mean(e**2)))
    emax = float(np.max(np.abs(e)))
    return {"rmse": rmse, "max_error": emax, "rmse_percent": 100 * rmse / span, "max_error_percent": 100 * emax / span}


#: Losses :func:`identify` and :func:`fit_linear` minimize.
LOSSES = ("squared", "huber")

#: Huber's tuning constant: 95 % efficiency at Gaussian residuals.
HUBER_K = 1.345

#: MAD to standard deviation at Gaussian residuals.
_MAD_TO_SIGMA = 1.4826


def default_huber_delta(residuals) -> np.ndarray:
    """Default Huber threshold of residual records: ``1.345 sigma`` with the robust
    ``sigma = 1.4826 median(|r - median(r)|)``, along the last axis.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.identify import default_huber_delta
    >>> r = np.array([-1.0, 0.0, 1.0, 2.0, 100.0])       # the glitch does not move it
    >>> round(float(default_huber_delta(r)), 6)
    1.994097
    """
    r = np.asarray(residuals, dtype=np.float64)
    mad = np.median(np.abs(r - np.median(r, axis=-1, keepdims=True)), axis=-1)
    return HUBER_K * _MAD_TO_SIGMA * mad


def huber_cost(residuals, delta=None) -> np.ndarray:
    """Huber cost of residual records, in the residuals' unit: ``sqrt(2 mean(rho(r)))`` with
    ``rho(r) = r**2 / 2`` for ``|r| <= delta`` and ``delta (|r| - delta / 2)`` beyond, along
    the last axis (one value per row of an ``(S, N)`` array).

    It equals the RMSE when no residual exceeds ``delta``; a glitch adds in proportion to
    its size, not its square. ``delta=None`` takes each row's :func:`default_huber_delta`,
    which makes the cost scale with the residuals (``huber_cost(c r) = |c| huber_cost(r)``): a
    robust RMS, minimized as S-estimators minimize a robust scale, with the MAD's 50 %
    breakdown point. A row with non-finite residuals (a diverged simulation) costs ``inf``.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.identify import huber_cost
    >>> r = np.array([0.0, 1.0, -1.0, 1.0])
    >>> float(huber_cost(r, delta=10.0)), float(np.sqrt(np.mean(r**2)))
    (0.8660254037844386, 0.8660254037844386)
    >>> float(huber_cost(np.r_[r, 1e6], delta=1.0)) < 1e3               # RMSE would be 4.5e5
    True
    """
    r = np.asarray(residuals, dtype=np.float64)
    d = default_huber_delta(r) if delta is None else np.asarray(delta, dtype=np.float64)
    d = np.expand_dims(d, -1) if np.ndim(d) else d
    a = np.abs(r)
    with np.errstate(invalid="ignore", over="ignore"):
        rho = np.where(a <= d, 0.5 * a * a, d * (a - 0.5 * d))
        cost = np.sqrt(2.0 * np.mean(rho, axis=-1))
    return np.where(np.all(np.isfinite(r), axis=-1), cost, np.inf)


def _check_loss(loss, delta):
    """``(loss, delta)`` checked: delta ``None`` (the MAD default) or a positive number."""
    if loss not in LOSSES:
        raise ParameterError(f"loss = {loss!r} is unknown; expected one of {list(LOSSES)}")
    if delta is None:
        return loss, None
    if loss != "huber":
        raise ParameterError(f"huber_delta = {delta!r} is only used with loss = 'huber', got loss = {loss!r}")
    return loss, as_scalar(delta, "huber_delta", positive=True)


#: Linear slots (names of the core's layout table) that fits keep non-negative.
_NONNEGATIVE = frozenset({"p0", "w", "b", "slope", "creep_c"})


def _linear_slots(model):
    """``(name, length)`` of the model's linear slots in regressor-column order (the core's
    layout table, ``_core.family_layout``)."""
    layout = _core.family_layout(model.family, list(model.dims))
    length = {name: size for name, _, size in layout["groups"]}
    return [(name, length[name]) for name in layout["linear"]]


def _layout(model):
    """Column bounds ``(lb, ub)`` of the regressors and a function mapping the solution back
    to a model of the same structure."""
    inf = np.inf
    creep = getattr(model, "creep", None)
    if not isinstance(model, (PI, GeneralizedPI, RateDependentPI, Preisach)):
        raise ParameterTypeError(
            f"model must be PI, GeneralizedPI, RateDependentPI or Preisach, got {type(model).__name__}"
        )
    slots = _linear_slots(model)
    lb = np.concatenate([np.full(size, 0.0 if name in _NONNEGATIVE else -inf) for name, size in slots])

    def parts(t):
        ends = np.cumsum([size for _, size in slots])
        return {name: t[end - size : end] for (name, size), end in zip(slots, ends, strict=True)}

    def with_creep(theta_tail):
        return None if creep is None else Creep(creep.ts, creep.taus, theta_tail)

    if isinstance(model, RateDependentPI):

        def build(t):
            p = parts(t)
            return RateDependentPI(
                model.thresholds,
                p["w"],
                model.ts,
                p["p0"][0],
                model.beta,
                p["c"],
                model.filter_tau,
                creep=with_creep(p["creep_c"]),
                units=model.units,
            )
    elif isinstance(model, GeneralizedPI):

        def build(t):
            p = parts(t)
            return GeneralizedPI(
                model.thresholds,
                p["b"],
                p["poly"],
                model.rising,
                model.falling,
                model.input_range,
                creep=with_creep(p["creep_c"]),
                units=model.units,
            )
    elif isinstance(model, PI):

        def build(t):
            p = parts(t)
            return PI(model.thresholds, p["w"], p["p0"][0], creep=with_creep(p["creep_c"]), units=model.units)
    else:

        def build(t):
            p = parts(t)
            return Preisach(
                model.levels, model.input_range, p["w"], p["offset"][0], p["slope"][0], model.memory, units=model.units
            )

    return lb, np.full(lb.size, inf), build


def fit_linear(model, input, output, *, loss="squared", huber_delta=None) -> FitResult:
    """Fit the linear parameters of ``model`` (its weights, linear term / polynomial, creep
    weights; Preisach offset, slope and cell weights) to a record, keeping its structure.

    Play weights, Preisach weights and slopes are constrained non-negative (a Preisach
    density is a mass; non-negative play weights keep the PI model invertible).

    Parameters
    ----------
    model : PI, GeneralizedPI, RateDependentPI or Preisach
        The structure to keep; its linear parameters are ignored.
    input, output : array_like
        The record, equal lengths.
    loss : {"squared", "huber"}
        ``"squared"``: bounded least squares. ``"huber"``: the Huber M-estimate by
        iteratively reweighted bounded least squares (weights ``min(1, delta / |r|)``) from
        the least-squares solution, for records with glitches.
    huber_delta : float, optional
        Huber threshold in the output's unit; by default :func:`default_huber_delta` of the
        current residuals, re-estimated at each iteration.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst import PI, fit_linear
    >>> truth = PI([0.1, 0.3, 0.6], [0.5, 0.2, 0.1], p0=0.8)
    >>> v = np.sin(np.linspace(0, 12, 1200)) * np.linspace(1, 0.3, 1200)
    >>> fit = fit_linear(PI([0.1, 0.3, 0.6], [0, 0, 0], p0=1.0), v, truth.simulate(v))
    >>> np.allclose(fit.model.weights, truth.weights, atol=1e-9), round(fit.model.p0, 9)
    (True, 0.8)

    A glitch of 100 on one sample in 100 barely moves the Huber fit:

    >>> y = truth.simulate(v)
    >>> y[::100] += 100.0
    >>> robust = fit_linear(PI([0.1, 0.3, 0.6], [0, 0, 0]), v, y, loss="huber")
    >>> bool(np.max(np.abs(robust.model.weights - truth.weights)) < 1e-6)
    True
    """
    from scipy.optimize import lsq_linear  # imported on use: keeps the command line quick to start

    t0 = time.perf_counter()
    loss, delta = _check_loss(loss, huber_delta)
    v = as_record(input, "input", min_length=2)
    y = as_record(output, "output", min_length=2)
    if y.size != v.size:
        raise ParameterError(f"output has {y.size} samples, input has {v.size}; they must match")
    lb, ub, build = _layout(model)
    A = _core.regressors(model.family, list(model.dims), model.to_row(), v)
    scale = np.maximum(np.sqrt(np.mean(A**2, axis=0)), 1e-300)  # equilibrate the columns
    A = A / scale
    bounds = (lb * scale, ub * scale)
    z = np.clip(lsq_linear(A, y, bounds=bounds, method="bvls", lsmr_tol=None).x, *bounds)
    if loss == "huber":
        z = _irls_huber(A, y, bounds, z, delta, lsq_linear)
    fitted = build(z / scale)
    return FitResult(fitted, fit_metrics(fitted.simulate(v), y), time.perf_counter() - t0)


def _irls_huber(A, y, bounds, z, delta, lsq_linear, max_iterations=100, rtol=1e-9):
    """Huber M-estimate by iteratively reweighted bounded least squares from ``z``.

    Stops when an iteration moves the fitted output by less than ``rtol`` times the output's
    range (RMS): the parameters of correlated regressors creep on long after the fit has
    settled."""
    lower, upper = bounds
    span = float(np.ptp(y)) or 1.0
    tiny = 1e-15 * span  # a zero MAD (an exact majority) still weighs
    fit = A @ z
    for _ in range(max_iterations):
        r = fit - y
        d = max(float(default_huber_delta(r)) if delta is None else delta, tiny)
        w = np.sqrt(np.minimum(1.0, d / np.maximum(np.abs(r), tiny)))
        sol = lsq_linear(A * w[:, None], y * w, bounds=bounds, method="bvls", lsmr_tol=None)
        z = np.clip(sol.x, lower, upper)  # bvls may overstep a bound by an ulp
        new_fit = A @ z
        moved = float(np.sqrt(np.mean((new_fit - fit) ** 2)))
        fit = new_fit
        if moved <= rtol * span:
            break
    return z


def _default_thresholds(v, n):
    span = float(np.ptp(v))
    if not span > 0:
        raise ParameterError("input is constant: there is no hysteresis to identify")
    return np.arange(1, n + 1) * span / (2.0 * (n + 1))


def identify_pi(
    input, output, *, operators=9, thresholds=None, creep=None, loss="squared", huber_delta=None
) -> FitResult:
    """Classical PI with ``operators`` thresholds spread over half the input range (or the
    given ones), weights and linear term by non-negative least squares (``loss``,
    ``huber_delta``: see :func:`fit_linear`)."""
    v = as_record(input, "input", min_length=2)
    r = _default_thresholds(v, as_int(operators, "operators", minimum=1)) if thresholds is None else thresholds
    return fit_linear(PI(r, np.zeros(len(r)), 1.0, creep=creep), v, output, loss=loss, huber_delta=huber_delta)


def identify_mpi(
    input,
    output,
    *,
    operators=9,
    thresholds=None,
    rising=None,
    falling=None,
    creep=None,
    loss="squared",
    huber_delta=None,
) -> FitResult:
    """Seed 2's MPI (cubic input polynomial + generalized plays) with the envelopes given
    (identity by default); polynomial and weights by bounded least squares (``loss``,
    ``huber_delta``: see :func:`fit_linear`)."""
    v = as_record(input, "input", min_length=2)
    r = _default_thresholds(v, as_int(operators, "operators", minimum=1)) if thresholds is None else thresholds
    lo, hi = float(v.min()), float(v.max())
    pad = 0.5 * (hi - lo)
    model = GeneralizedPI(r, np.zeros(len(r)), (0.0, 0.0, 0.0, 0.0), rising, falling, (lo - pad, hi + pad), creep=creep)
    return fit_linear(model, v, output, loss=loss, huber_delta=huber_delta)


def identify_preisach(
    input, output, *, levels=12, input_range=None, memory=64, loss="squared", huber_delta=None
) -> FitResult:
    """Discretized Preisach on a ``levels x levels`` grid over the input range; offset, slope
    and cell weights (non-negative) by least squares (``loss``, ``huber_delta``: see
    :func:`fit_linear`)."""
    v = as_record(input, "input", min_length=2)
    lo, hi = (float(v.min()), float(v.max())) if input_range is None else input_range
    n = as_int(levels, "levels", minimum=1)
    model = Preisach(n, (lo, hi), np.zeros(n * (n + 1) // 2), memory=memory)
    return fit_linear(model, v, output, loss=loss, huber_delta=huber_delta)


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
    #: How :meth:`simulate` predicts the output for models without a ``simulate(input)`` of their
    #: own (the CEMF stage's parameters); ``None``: ``model.simulate``.
    simulator: object = field(default=None, repr=False, compare=False)
    #: ``True`` when Ctrl-C stopped the optimizer: the model is the best found before it.
    partial: bool = False

    def simulate(self, input) -> np.ndarray:
        """The identified model's free-run output for an input record (for ``cemf``: positions
        from voltages, the stage simulated as it was identified)."""
        if self.simulator is not None:
            return np.asarray(self.simulator(as_record(input, "input")))
        return self.model.simulate(input)

    @property
    def metrics(self) -> dict:
        return {"train": self.train, "validation": self.validation}

    def to_dict(self) -> dict:
        """JSON-ready report (the model file's ``fit`` section)."""
        return {
            "method": self.method,
            "wall_time_s": self.wall_time,
            "train": self.train,
            "validation": self.validation,
            "partial": self.partial,
        }

    def plot(self, input, output):
        """Loop, fit and residual for a record (matplotlib figure)."""
        import matplotlib.pyplot as plt

        v = as_record(input, "input")
        y = as_record(output, "output")
        yp = self.simulate(v)
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


def minimize_huber(simulate, target, bounds, delta=None, **search):
    """Minimize the Huber cost of ``simulate(X) - target`` over a box with a population
    optimizer, then L-BFGS-B.

    ``simulate(X)`` maps the ``(S, D)`` population to ``(S, N)`` outputs (NaN rows for
    failed runs); ``search`` goes to :func:`piezohyst.optimize.minimize` (``method``,
    ``rng``, ``max_iterations``, ...; not ``polish``).

    With ``delta`` given, the population search and the polish minimize
    ``huber_cost(r, delta)``. Without it, the search is in two stages, as an MM-estimate: the
    population minimizes the scale-equivariant ``huber_cost(r)`` (each candidate's threshold
    from its own residuals' MAD: a robust scale, unmoved by glitches); ``delta`` is then
    :func:`default_huber_delta` of the best candidate's residuals, and L-BFGS-B continues from
    it on ``huber_cost(r, delta)`` with that threshold fixed. Why not one stage: the per-candidate
    threshold makes the cost non-smooth (the MAD jumps between samples), which stalls
    gradient polishing, and a fixed threshold cannot be set before any fit exists.

    Returns
    -------
    OptimizeResult
        ``fun`` is the final fixed-threshold Huber cost; ``history["best_cost"]`` holds the
        search's costs; ``history["huber_delta"]`` the threshold used.
    """
    from dataclasses import replace

    from ..optimize.core import minimize, polish_lbfgsb

    def fixed(X):
        return huber_cost(simulate(X) - target, delta)

    if delta is not None:
        res = minimize(fixed, bounds, polish=True, **search)
        return replace(res, history={**res.history, "huber_delta": float(delta)})
    res = minimize(lambda X: huber_cost(simulate(X) - target), bounds, **search)
    x0 = np.array(res.x, dtype=np.float64)
    r0 = simulate(x0[None, :])[0] - target
    if res.message == "interrupted" or not np.all(np.isfinite(r0)):
        return replace(res, history={**res.history, "huber_delta": float("nan")})
    tiny = 1e-15 * (float(np.max(np.abs(target))) or 1.0)  # an exact majority leaves MAD = 0
    delta = max(float(default_huber_delta(r0)), tiny)
    lower, upper = np.array(bounds, dtype=np.float64).T
    x, f, n = polish_lbfgsb(fixed, x0, float(fixed(x0[None, :])[0]), lower, upper, {})
    message = f"{res.message}; Huber threshold {delta:.6g} from the MAD, then L-BFGS-B to {f:.6g}"
    return replace(
        res, x=x, fun=f, nfev=res.nfev + n + 1, message=message, history={**res.history, "huber_delta": delta}
    )


#: Parameters searched by :func:`identify_cemf`, in seed 1's normalized form.
CEMF_PARAMETERS = ("M", "B", "K", "tem", "alpha", "beta", "gamma")


def identify_cemf(
    voltage,
    position,
    fs,
    *,
    capacitance=1.8e-6,
    bounds=None,
    optimizer="css",
    rng=None,
    max_iterations=150,
    population_size=None,
    substeps=1,
    tolerance=0.05,
    validate=None,
    progress=False,
    callback=None,
    loss="squared",
    huber_delta=None,
    polish=False,
) -> IdentificationResult:
    """Grey-box identification of the CEMF stage model (seed 1) from the applied voltage and
    the measured displacement: ``M x'' + B x' + K x = Vin - Vh`` (``M = m/Tem``, ...) with
    the CEMF Bouc–Wen law on the stack charge, by a population optimizer over
    ``CEMF_PARAMETERS`` on the free-run simulation error. Each population is simulated in one
    Rust batch call (rayon). The stack capacitance is taken as known (seed 1: 1800 nF).

    ``loss="huber"`` minimizes :func:`huber_cost` of the simulated position residuals
    instead of their RMSE, by :func:`minimize_huber` (``huber_delta``: the threshold in the
    position's unit, by default from the MAD). The core has no batch simulation of the stage,
    so the Huber cost simulates the population's rows one Rust call each, without rayon:
    slower than the RMSE.

    ``polish=True`` (squared loss only) continues from the search's best with SciPy's
    ``least_squares`` (trust-region reflective inside ``bounds``, Jacobian by forward
    differences, one Rust simulation per row) on the position residual, and keeps the result
    if its RMSE is lower; ``history["polish"]`` then holds the RMSE before and after, the
    simulations run and SciPy's message. On a noise-free record of a stage that is exactly the
    CEMF model it reaches the true parameters from a search result tens of percent off
    (``tests/test_identify_recovery.py``): the mass and ``Tem`` need dynamic content in the
    record (near the resonance), a slow record only fixes ``K`` and the products of ``alpha``,
    ``beta``, ``gamma`` with ``Cz K + Tem``.

    Returns an :class:`IdentificationResult` whose ``model`` is a :class:`piezohyst.StageParameters`;
    its ``simulate`` predicts positions from voltages with the identified stage.
    """
    from ..optimize.core import minimize
    from ..plant.stage import Amplifier, Stage, StageParameters

    t0 = time.perf_counter()
    loss, delta = _check_loss(loss, huber_delta)
    u = as_record(voltage, "voltage", min_length=2)
    x = as_record(position, "position", min_length=2)
    if x.size != u.size:
        raise ParameterError(f"position has {x.size} samples, voltage has {u.size}; they must match")
    fs = float(fs)
    if not fs > 0:
        raise ParameterError(f"fs = {fs} must be > 0")
    gain = float(np.ptp(x)) / (float(np.ptp(u)) or 1.0)
    if not gain > 0:
        raise ParameterError("position does not move: nothing to identify")
    if bounds is None:
        k_lo, k_hi = 0.3 / gain, 3.0 / gain
        w_lo, w_hi = 2 * np.pi * 1e3, 2 * np.pi * 2e4  # resonance between 1 and 20 kHz
        q = capacitance * float(np.ptp(u))  # charge scale, C
        bounds = [
            (k_lo / w_hi**2, k_hi / w_lo**2),
            (0.0, 0.4 * np.sqrt(k_hi * k_hi / w_lo**2)),
            (k_lo, k_hi),
            (1.0, 50.0),
            (0.0, 4.0 / capacitance),
            (0.0, 30.0 / q),
            (-30.0 / q, 30.0 / q),
        ]
    bounds = [(float(lo), float(hi)) for lo, hi in bounds]
    if len(bounds) != len(CEMF_PARAMETERS):
        raise ParameterError(f"bounds has {len(bounds)} pairs, expected {len(CEMF_PARAMETERS)} ({CEMF_PARAMETERS})")
    wide = Amplifier(-1e9, 1e9)
    template = Stage(
        StageParameters(1.0, 0.0, 1.0, 1.0, capacitance),
        wide,
        sample_time=1.0 / fs,
        substeps=substeps,
        tolerance=tolerance,
    ).core_params()

    def rows(theta):
        theta = np.atleast_2d(theta)
        out = np.repeat(template[None, :], theta.shape[0], axis=0)
        M, B, K, tem = theta[:, 0], theta[:, 1], theta[:, 2], theta[:, 3]
        out[:, 0], out[:, 1], out[:, 2], out[:, 3] = M * tem, B * tem, K * tem, tem
        out[:, 5], out[:, 6], out[:, 7] = theta[:, 4], theta[:, 5], theta[:, 6]
        return np.ascontiguousarray(out)

    def unbounded(theta):
        # Bouc-Wen (n = 1) keeps Vh bounded for every input only if beta >= |gamma|; a model
        # outside that may fit the record yet run away on another drive (or in an observer)
        theta = np.atleast_2d(theta)
        return theta[:, 5] < np.abs(theta[:, 6])

    def cost(theta):
        c = _core.stage_batch_rmse(rows(theta), 1.0 / fs, substeps, tolerance, u, x, float("inf"))
        c[unbounded(theta)] = np.inf
        return c

    def simulate(theta):
        out = _stage_positions(rows(theta), 1.0 / fs, substeps, tolerance, u)
        out[unbounded(theta)] = np.nan
        return out

    method = "css" if optimizer == "ls" else optimizer
    search = dict(
        method=method,
        rng=rng,
        max_iterations=max_iterations,
        population_size=population_size,
        progress=progress,
        callback=callback,
    )
    if not isinstance(polish, bool):
        raise ParameterTypeError(f"polish must be True or False, got {polish!r}")
    if loss == "squared":
        res = minimize(cost, bounds, **search)
    else:
        res = minimize_huber(simulate, x, bounds, delta, **search)
    theta, history = np.array(res.x, dtype=np.float64), res.history
    if polish and loss == "squared" and res.message != "interrupted" and np.isfinite(res.fun):
        theta, info = _polish_simulation(simulate, x, theta, bounds)
        history = {**res.history, "polish": info}
        method += "+least_squares"
    M, B, K, tem, alpha, beta, gamma = theta
    params = StageParameters(M * tem, B * tem, K * tem, tem, capacitance, alpha, beta, gamma)
    stage = Stage(params, wide, sample_time=1.0 / fs, substeps=substeps, tolerance=tolerance)
    train = fit_metrics(stage.simulate(u).position, x)
    val = None
    if validate is not None:
        vu = as_record(validate[0], "validate voltage")
        vx = as_record(validate[1], "validate position")
        val = fit_metrics(stage.simulate(vu).position, vx)
    if loss == "huber":
        method += "+huber"
    return IdentificationResult(
        params,
        train,
        val,
        method,
        time.perf_counter() - t0,
        history,
        simulator=lambda u_: stage.simulate(u_).position,
        partial=res.interrupted,
    )


def _polish_simulation(simulate, target, x0, bounds, max_nfev=None):
    """SciPy ``least_squares`` (``trf`` within ``bounds``, forward-difference Jacobian,
    ``x_scale="jac"``) on ``simulate(theta[None])[0] - target`` from ``x0``; a failed
    simulation (NaN row) returns a large constant residual. Returns ``(theta, info)`` with the
    better of ``x0`` and the polished point."""
    from scipy.optimize import least_squares

    lower, upper = np.array(bounds, dtype=np.float64).T
    span = float(np.ptp(target)) or 1.0
    wall = np.full(target.size, 10.0)
    calls = 0

    def fun(theta):
        nonlocal calls
        calls += 1
        r = (simulate(theta[None, :])[0] - target) / span
        return r if np.all(np.isfinite(r)) else wall

    def rmse(theta):
        return float(np.sqrt(np.mean(fun(theta) ** 2))) * span

    width = upper - lower
    start = np.clip(x0, lower + 1e-9 * width, upper - 1e-9 * width)
    before = rmse(x0)
    sol = least_squares(
        fun,
        start,
        bounds=(lower, upper),
        method="trf",
        x_scale="jac",
        diff_step=1e-6,
        xtol=1e-12,
        ftol=1e-12,
        gtol=1e-12,
        max_nfev=max_nfev or 100 * (x0.size + 1),
    )
    x1 = np.clip(sol.x, lower, upper)
    after = rmse(x1)
    info = {"rmse_before": before, "rmse_after": min(before, after), "nfev": calls, "message": str(sol.message)}
    return (x1 if after < before else np.array(x0, dtype=np.float64)), info


def _stage_positions(rows, ts, substeps, tolerance, u):
    """``(S, N)`` open-loop positions of stage rows from rest, as ``stage_batch_rmse`` scores
    them; a NaN row where the core refuses the row or the run fails."""
    out = np.full((rows.shape[0], u.size), np.nan)
    for i, row in enumerate(rows):  # a loop over the population, each run in Rust
        try:
            out[i] = _core.stage_simulate(row, ts, substeps, tolerance, u, np.zeros(_core.STAGE_STATE_LEN))[0]
        except (ValueError, RuntimeError):
            pass
    return out
