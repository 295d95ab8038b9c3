"""Identification by least squares over the linear parameters (docs/spec.md §4).

With the structure fixed — thresholds, envelopes, rate terms, creep time constants, the
Preisach grid — the output of a PI-type or Preisach model is linear in its weights and
polynomial coefficients. The regressors (operator outputs, cell fractions, lag outputs) come
from the Rust core in one pass; the weights come from a bounded least-squares solve
(``scipy.optimize.lsq_linear``), non-negative where the model needs it (play and Preisach
weights). This is the inner, exact step of variable projection; the metaheuristics of
:mod:`piezohyst.optimize` search the few nonlinear parameters around it.

Inputs are validated once, by the public functions; the private helpers (leading
underscore) take records already validated (finite 1-D float64 arrays of checked lengths).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol, TypeAlias, runtime_checkable

import numpy as np
import numpy.typing as npt

from .. import _core
from .._validate import as_int, as_record, as_scalar
from ..errors import ParameterError, ParameterTypeError
from ..models.creep import Creep
from ..models.model import Drift
from ..models.pi import PI, Envelope, GeneralizedPI, RateDependentPI
from ..models.preisach import Preisach
from ..optimize.report import RunReport

if TYPE_CHECKING:  # pragma: no cover - typing only
    from matplotlib.figure import Figure

    from ..optimize.core import IntermediateResult, OptimizeResult

__all__ = [
    "CEMF_PARAMETERS",
    "LOSSES",
    "DriftBasis",
    "FitResult",
    "IdentificationResult",
    "default_huber_delta",
    "delayed",
    "fit_linear",
    "fit_metrics",
    "huber_cost",
    "identify_cemf",
    "identify_mpi",
    "identify_pi",
    "identify_preisach",
    "minimize_huber",
]

FloatArray: TypeAlias = npt.NDArray[np.float64]
#: Free-run metrics: ``rmse``, ``max_error``, ``rmse_percent``, ``max_error_percent``.
Metrics: TypeAlias = dict[str, float]
#: The models :func:`fit_linear` fits.
LinearModel: TypeAlias = PI | GeneralizedPI | RateDependentPI | Preisach
#: Play thresholds given by the caller.
Thresholds: TypeAlias = Sequence[float] | npt.NDArray[Any]
#: Seeds the population optimizers take (:func:`piezohyst.optimize.minimize`).
RngLike: TypeAlias = int | np.integer[Any] | np.random.Generator | np.random.SeedSequence | None
#: ``callback(intermediate_result)`` of the population optimizers.
Callback: TypeAlias = "Callable[[IntermediateResult], object]"
#: A bounded linear least-squares solver ``(A, y, (lower, upper)) -> z``.
BoundedSolver: TypeAlias = Callable[[FloatArray, FloatArray, tuple[FloatArray, FloatArray]], FloatArray]


@dataclass(frozen=True)
class DriftBasis:
    """The shape of a drift term fitted with a model: exponential settling terms
    ``1 - exp(-k / tau)`` (``taus`` in samples) and, with ``linear``, a ramp ``k``, ``k`` the
    samples since the simulation's first sample (the training record's). Their weights are
    fitted with the model's linear parameters (free columns of the least squares); :meth:`drift`
    turns the weights into the model's :class:`~piezohyst.models.model.Drift`.

    Examples
    --------
    >>> b = DriftBasis(taus=(100.0,), linear=True)
    >>> b.name, b.columns(3).shape
    ('exp(100)+linear', (3, 2))
    """

    taus: tuple[float, ...] = ()
    linear: bool = False

    def __post_init__(self) -> None:
        taus = tuple(as_scalar(t, "drift tau", positive=True) for t in self.taus)
        object.__setattr__(self, "taus", taus)
        object.__setattr__(self, "linear", bool(self.linear))

    @property
    def empty(self) -> bool:
        """No column: no drift."""
        return not self.taus and not self.linear

    @property
    def name(self) -> str:
        parts = [f"exp({t:.6g})" for t in self.taus] + (["linear"] if self.linear else [])
        return "+".join(parts) or "none"

    @property
    def size(self) -> int:
        return len(self.taus) + int(self.linear)

    def columns(self, n: int) -> FloatArray:
        """The ``(n, size)`` basis over samples ``0 ... n - 1``: the exponentials, then the ramp."""
        k = np.arange(n, dtype=np.float64)
        cols = [-np.expm1(-k / t) for t in self.taus]
        if self.linear:
            cols.append(k)
        return np.column_stack(cols) if cols else np.zeros((n, 0))

    def drift(self, weights: npt.ArrayLike) -> Drift | None:
        """The model's drift term for the fitted ``weights`` (the basis' column order); ``None``
        for the empty basis."""
        w = np.asarray(weights, dtype=np.float64)
        if self.empty:
            return None
        m = len(self.taus)
        return Drift(taus=self.taus, weights=tuple(float(x) for x in w[:m]), slope=float(w[m]) if self.linear else 0.0)

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "taus": list(self.taus), "linear": self.linear}


def delayed(input: npt.ArrayLike, delay: int) -> FloatArray:
    """The input a model with an input delay of ``delay`` samples sees: ``input`` shifted late
    by ``delay`` samples, the first sample held before the record starts.

    Examples
    --------
    >>> delayed([1.0, 2.0, 3.0, 4.0], 2).tolist()
    [1.0, 1.0, 1.0, 2.0]
    """
    v = as_record(input, "input")
    d = as_int(delay, "delay", minimum=0)
    if d == 0:
        return v
    if d >= v.size:
        return np.full(v.size, v[0])
    return np.concatenate([np.full(d, v[0]), v[:-d]])


@runtime_checkable
class _Simulates(Protocol):
    def simulate(self, input: npt.ArrayLike, /) -> FloatArray: ...


@dataclass(frozen=True, repr=False)
class FitResult(RunReport):
    """A fitted model with its free-run error on the data it was fitted to.

    As every :class:`~piezohyst.optimize.RunReport`: ``wall_time`` (s), ``evaluations`` (the
    bounded least-squares solves: 1, or 1 plus the reweighted solves of the Huber loss),
    ``history`` (empty: a linear fit does not iterate over candidates) and ``partial``
    (always ``False``: a linear fit is not interrupted halfway)."""

    model: LinearModel
    metrics: Metrics
    wall_time: float
    evaluations: int = 1
    history: dict[str, Any] = field(default_factory=dict)
    partial: bool = False

    def __repr__(self) -> str:
        m = self.metrics
        return (
            f"FitResult({type(self.model).__name__}, rmse={m['rmse']:.4g} ({m['rmse_percent']:.3g} % of range), "
            f"max_error={m['max_error']:.4g} ({m['max_error_percent']:.3g} %), {self.wall_time * 1e3:.1f} ms)"
        )

    def _headline(self) -> str:
        m = self.metrics
        return (
            f"{type(self.model).__name__} fitted by least squares: rmse {m['rmse']:.4g} "
            f"({m['rmse_percent']:.3g} % of range), max error {m['max_error']:.4g} ({m['max_error_percent']:.3g} %)"
        )


def fit_metrics(predicted: npt.ArrayLike, measured: npt.ArrayLike) -> Metrics:
    """RMSE and max error of the free-run simulation, also in % of the measured range."""
    p = as_record(predicted, "predicted", copy=False)
    m = as_record(measured, "measured", copy=False)
    return _fit_metrics(p, m)


def _fit_metrics(predicted: npt.ArrayLike, measured: FloatArray) -> Metrics:
    """:func:`fit_metrics` of a model's output against an already validated record: the
    prediction (not an input of the caller's) is still checked finite, with the same message."""
    p = as_record(predicted, "predicted", copy=False)
    if p.size != measured.size:
        raise ParameterError(f"predicted has {p.size} samples, measured has {measured.size}; they must match")
    e = p - measured
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


def default_huber_delta(residuals: npt.ArrayLike) -> FloatArray:
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
    mad: FloatArray = np.median(np.abs(r - np.median(r, axis=-1, keepdims=True)), axis=-1)
    return HUBER_K * _MAD_TO_SIGMA * mad


def huber_cost(residuals: npt.ArrayLike, delta: npt.ArrayLike | None = None) -> FloatArray:
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


def _check_loss(loss: object, delta: object) -> tuple[str, float | None]:
    """``(loss, delta)`` checked: delta ``None`` (the MAD default) or a positive number."""
    if loss not in LOSSES:
        raise ParameterError(f"loss = {loss!r} is unknown; expected one of {list(LOSSES)}")
    name = LOSSES[LOSSES.index(loss)]
    if delta is None:
        return name, None
    if loss != "huber":
        raise ParameterError(f"huber_delta = {delta!r} is only used with loss = 'huber', got loss = {loss!r}")
    return name, as_scalar(delta, "huber_delta", positive=True)


def _linear_slots(model: LinearModel) -> list[tuple[int, bool]]:
    """``(length, non-negative)`` of the model's linear slots in regressor-column order, as
    the core's layout table declares them (``_core.family_layout``: ``linear`` and
    ``nonnegative``). Names are not spelled here: a slot renamed in the table is followed."""
    layout = _core.family_layout(model.family, list(model.dims))
    length = {name: size for name, _, size in layout["groups"]}
    return [(length[name], name in layout["nonnegative"]) for name in layout["linear"]]


def _layout(model: LinearModel) -> tuple[FloatArray, FloatArray, Callable[[FloatArray], LinearModel]]:
    """Column bounds ``(lb, ub)`` of the regressors and a function mapping the solution back
    to a model of the same structure."""
    inf = np.inf
    creep = getattr(model, "creep", None)
    if not isinstance(model, (PI, GeneralizedPI, RateDependentPI, Preisach)):
        raise ParameterTypeError(
            f"model must be PI, GeneralizedPI, RateDependentPI or Preisach, got {type(model).__name__}"
        )
    slots = _linear_slots(model)
    lb = np.concatenate([np.full(size, 0.0 if nonnegative else -inf) for size, nonnegative in slots])

    def parts(t: FloatArray) -> list[FloatArray]:
        """The solution split into the linear slots, in the table's (regressor-column) order."""
        ends = np.cumsum([size for size, _ in slots])
        return [t[end - size : end] for (size, _), end in zip(slots, ends, strict=True)]

    def with_creep(theta_tail: FloatArray) -> Creep | None:
        return None if creep is None else Creep(creep.ts, creep.taus, theta_tail)

    if isinstance(model, RateDependentPI):

        def build(t: FloatArray) -> LinearModel:
            p0, w, c, creep_c = parts(t)
            return RateDependentPI(
                model.thresholds,
                w,
                model.ts,
                p0[0],
                model.beta,
                c,
                model.filter_tau,
                creep=with_creep(creep_c),
                units=model.units,
            )
    elif isinstance(model, GeneralizedPI):

        def build(t: FloatArray) -> LinearModel:
            poly, b, creep_c = parts(t)
            return GeneralizedPI(
                model.thresholds,
                b,
                poly,
                model.rising,
                model.falling,
                model.input_range,
                creep=with_creep(creep_c),
                units=model.units,
            )
    elif isinstance(model, PI):

        def build(t: FloatArray) -> LinearModel:
            p0, w, creep_c = parts(t)
            return PI(model.thresholds, w, p0[0], creep=with_creep(creep_c), units=model.units)
    else:

        def build(t: FloatArray) -> LinearModel:
            offset, slope, w = parts(t)
            return Preisach(model.levels, model.input_range, w, offset[0], slope[0], model.memory, units=model.units)

    return lb, np.full(lb.size, inf), build


def fit_linear(
    model: LinearModel,
    input: npt.ArrayLike,
    output: npt.ArrayLike,
    *,
    loss: str = "squared",
    huber_delta: float | None = None,
    offset: bool = True,
) -> FitResult:
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
    offset : bool
        Fit an output offset (a sensor's zero): one more least-squares column, a constant,
        whose coefficient becomes ``model.output_map.offset``. Families with a constant term
        of their own (the GPI polynomial's ``c0``, the Preisach ``offset``) fit it there and
        get no second one. ``False``: no column is added (the fit of earlier versions).

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
    t0 = time.perf_counter()
    name, delta = _check_loss(loss, huber_delta)
    v = as_record(input, "input", min_length=2)
    return _fit_output(model, v, output, name, delta, t0, offset)


def _fit_output(
    model: LinearModel,
    v: FloatArray,
    output: npt.ArrayLike,
    loss: str,
    delta: float | None,
    t0: float,
    offset: bool = True,
) -> FitResult:
    """:func:`fit_linear` from a validated input and checked loss: validates ``output``."""
    y = as_record(output, "output", min_length=2)
    if y.size != v.size:
        raise ParameterError(f"output has {y.size} samples, input has {v.size}; they must match")
    return _fit_linear(model, v, y, loss, delta, t0, bool(offset))


def _bvls(A: FloatArray, y: FloatArray, bounds: tuple[FloatArray, FloatArray]) -> FloatArray:
    """SciPy's bounded-variable least squares ``argmin ||A z - y||`` within ``bounds``."""
    from scipy.optimize import lsq_linear  # imported on use: keeps the command line quick to start

    x: FloatArray = lsq_linear(A, y, bounds=bounds, method="bvls", lsmr_tol=None).x
    return x


def _has_constant(A: FloatArray) -> bool:
    """Whether a regressor matrix already has a constant non-zero column (the GPI polynomial's
    ``c0``, the Preisach ``offset``): the family then fits an output offset of its own."""
    return bool(np.any(np.all(A == A[:1], axis=0) & (A[0] != 0.0)))


def _design(
    model: LinearModel, v: FloatArray, offset: bool, drift: DriftBasis | None = None
) -> tuple[FloatArray, FloatArray, FloatArray, Callable[[FloatArray], LinearModel]]:
    """``(A, lb, ub, build)``: the regressors of ``model`` on ``v`` with their bounds, and the
    map from a solution to a model. With ``offset`` and no constant column in the family's
    regressors, a column of ones is appended (unbounded) and ``build`` puts its coefficient in
    the model's output map (``output_map.offset``; the gain stays 1, the weights absorb it).
    With a ``drift`` basis its columns are appended last (unbounded) and ``build`` gives the
    model their :class:`~piezohyst.models.model.Drift`. The family's parameter row is unchanged."""
    lb, ub, build = _layout(model)
    A = _core.regressors(model.family, list(model.dims), model.to_row(), v)
    if offset and not _has_constant(A):
        A = np.column_stack([A, np.ones(v.size)])
        lb, ub = np.append(lb, -np.inf), np.append(ub, np.inf)
        family = build

        def build(t: FloatArray) -> LinearModel:
            return family(t[:-1]).with_output_map(offset=float(t[-1]))

    if drift is None or drift.empty:
        return A, lb, ub, build
    k = drift.size
    A = np.column_stack([A, drift.columns(v.size)])
    mapped = build

    def build_drift(t: FloatArray) -> LinearModel:
        return mapped(t[:-k]).with_drift(drift.drift(t[-k:]))

    return A, np.append(lb, np.full(k, -np.inf)), np.append(ub, np.full(k, np.inf)), build_drift


def _fit_linear(
    model: LinearModel,
    v: FloatArray,
    y: FloatArray,
    loss: str,
    delta: float | None,
    t0: float | None = None,
    offset: bool = False,
    drift: DriftBasis | None = None,
    start: int = 0,
) -> FitResult:
    """:func:`fit_linear` of validated records (equal lengths) with a checked loss; with a
    ``drift`` basis fitted too, and the samples before ``start`` simulated but left out of the
    cost (the metrics are of the whole record)."""
    t0 = time.perf_counter() if t0 is None else t0
    if isinstance(model, Preisach):  # its own offset constant: no column to add
        return _fit_preisach(model, v, y, loss, delta, t0, drift, start)
    A, lb, ub, build = _design(model, v, offset, drift)
    A, yf = A[start:], y[start:]
    scale = np.maximum(np.sqrt(np.mean(A**2, axis=0)), 1e-300)  # equilibrate the columns
    A = A / scale
    bounds = (lb * scale, ub * scale)
    z = np.clip(_bvls(A, yf, bounds), *bounds)
    solves = 1
    if loss == "huber":
        z, k = _irls_huber(A, yf, bounds, z, delta, _bvls)
        solves += k
    fitted = build(z / scale)
    return FitResult(fitted, _fit_metrics(fitted.simulate(v), y), time.perf_counter() - t0, solves)


def _fit_preisach(
    model: Preisach,
    v: FloatArray,
    y: FloatArray,
    loss: str,
    delta: float | None,
    t0: float,
    drift: DriftBasis | None = None,
    start: int = 0,
) -> FitResult:
    """:func:`fit_linear` of a Preisach grid, on the distinct relay patterns the record excites.

    A cell's regressor is its relay's state over the record (0 or 1). Cells the record never
    switches (a constant column: the offset's) and cells that always switch together (equal
    columns) cannot be told apart by any record with this history: the problem is solved over
    the distinct non-constant columns only (a ``p x p`` non-negative least squares through the
    Gram matrix's Cholesky factor, :func:`_bounded_lstsq_gram`; BVLS on the whole ``N x L^2/2``
    matrix took minutes), each group's weight is shared equally by its cells (the smoothest
    density that fits) and never-switched cells get weight 0 (their effect is the offset's)."""
    lb, _, build = _layout(model)
    A = _core.regressors(model.family, list(model.dims), model.to_row(), v)[start:]
    head = A.shape[1] - model.weights.size  # offset and slope, then one column per cell
    cells = A[:, head:]
    # distinct relay patterns: the columns as packed bits (a relay is 0 or 1)
    bits = np.packbits(cells.T > 0.5, axis=1)
    patterns, first, group = np.unique(bits, axis=0, return_index=True, return_inverse=True)
    group = group.ravel()
    constant = np.all(cells[:, first] == cells[:1, first], axis=0)
    kept = np.flatnonzero(~constant)
    extra = 0 if drift is None else drift.size
    T = np.zeros((v.size, 0)) if drift is None else drift.columns(v.size)
    B = np.concatenate([A[:, :head], cells[:, first[kept]], T[start:]], axis=1)
    blb = np.concatenate([lb[:head], lb[head:][first[kept]], np.full(extra, -np.inf)])
    scale = np.maximum(np.sqrt(np.mean(B**2, axis=0)), 1e-300)
    B = B / scale
    bounds = (blb * scale, np.full(blb.size, np.inf))
    # the normal equations square the conditioning: solve for the output in units of its RMS, so
    # a record in other units (a gain) gives the same fit to rounding, not to the solver's tolerance
    # (and about its mean when the first column is the free offset's constant one: a record with
    # an offset then gives the same fit to rounding too)
    yf = y[start:]
    centre = float(np.mean(yf)) if np.all(A[:, 0] == 1.0) and lb[0] == -np.inf else 0.0
    unit = float(np.sqrt(np.mean((yf - centre) ** 2))) or 1.0
    yn = (yf - centre) / unit
    z = _bounded_lstsq_gram(B, yn, bounds)
    solves = 1
    if loss == "huber":
        z, k = _irls_huber(B, yn, bounds, z, None if delta is None else delta / unit, _bounded_lstsq_gram)
        solves += k
    zb = z * unit / scale
    zb[0] += centre
    total = np.zeros(patterns.shape[0])
    total[kept] = zb[head : zb.size - extra]
    counts = np.bincount(group, minlength=patterns.shape[0])
    theta = np.concatenate([zb[:head], total[group] / counts[group]])
    fitted = build(theta)
    if drift is not None and not drift.empty:
        fitted = fitted.with_drift(drift.drift(zb[zb.size - extra :]))
    return FitResult(fitted, _fit_metrics(fitted.simulate(v), y), time.perf_counter() - t0, solves)


def _bounded_lstsq_gram(A: FloatArray, y: FloatArray, bounds: tuple[FloatArray, FloatArray]) -> FloatArray:
    """``argmin ||A z - y||`` with ``z >= lower`` (lower 0 or ``-inf``; no upper bounds), for
    a tall ``A`` of equilibrated, distinct columns: through the Gram matrix's Cholesky factor
    ``R`` (``A^T A = R^T R``, ``R^T d = A^T y``; same minimizer, ``p x p``), the unbounded
    columns projected out and SciPy's NNLS on the rest. A Gram matrix that is numerically
    singular gets a ridge of ``1e-10`` of its mean diagonal (columns nearly collinear: any
    split of their weight fits the record as well)."""
    from scipy.linalg import LinAlgError, cholesky, solve_triangular

    lower, _ = bounds
    free = np.isneginf(lower)
    G = A.T @ A
    b = A.T @ y
    ridge = 0.0
    for _ in range(8):
        try:
            R = cholesky(G + ridge * np.eye(G.shape[0]), lower=False, check_finite=False)
            break
        except LinAlgError:
            ridge = max(10 * ridge, 1e-10 * float(np.mean(np.diag(G))))
    else:
        raise ParameterError("the regressors are not finite: no least-squares solution")
    d = solve_triangular(R, b, trans="T", check_finite=False)
    return _mixed_nnls(R, d, free)


def _mixed_nnls(R: FloatArray, d: FloatArray, free: npt.NDArray[np.bool_]) -> FloatArray:
    """``argmin ||R z - d||`` with ``z[~free] >= 0`` and ``z[free]`` unbounded: the free
    columns are projected out (QR), the rest is SciPy's NNLS, then the free part by back
    substitution. Exact, and much cheaper than BVLS for the small systems of the search."""
    from scipy.linalg import qr, solve_triangular
    from scipy.optimize import nnls

    z = np.zeros(R.shape[1])
    F, W = R[:, free], R[:, ~free]
    if F.shape[1]:
        Q, RF = qr(F, mode="economic", check_finite=False)
        PW, Pd = W - Q @ (Q.T @ W), d - Q @ (Q.T @ d)
    else:
        PW, Pd = W, d
    b = nnls(PW, Pd, maxiter=50 * max(W.shape[1], 1))[0] if W.shape[1] else np.zeros(0)
    z[~free] = b
    if F.shape[1]:
        z[free] = solve_triangular(RF, Q.T @ (d - W @ b), check_finite=False)
    return z


def _irls_huber(
    A: FloatArray,
    y: FloatArray,
    bounds: tuple[FloatArray, FloatArray],
    z: FloatArray,
    delta: float | None,
    solve: BoundedSolver,
    max_iterations: int = 100,
    rtol: float = 1e-9,
) -> tuple[FloatArray, int]:
    """Huber M-estimate by iteratively reweighted bounded least squares from ``z``:
    ``(z, solves)``, the solves being the reweighted problems ``solve`` was given.

    Stops when an iteration moves the fitted output by less than ``rtol`` times the output's
    range (RMS): the parameters of correlated regressors creep on long after the fit has
    settled."""
    lower, upper = bounds
    span = float(np.ptp(y)) or 1.0
    tiny = 1e-15 * span  # a zero MAD (an exact majority) still weighs
    fit = A @ z
    solves = 0
    for _ in range(max_iterations):
        r = fit - y
        d = max(float(default_huber_delta(r)) if delta is None else delta, tiny)
        w = np.sqrt(np.minimum(1.0, d / np.maximum(np.abs(r), tiny)))
        z = np.clip(solve(A * w[:, None], y * w, bounds), lower, upper)  # bvls may overstep a bound by an ulp
        solves += 1
        new_fit = A @ z
        moved = float(np.sqrt(np.mean((new_fit - fit) ** 2)))
        fit = new_fit
        if moved <= rtol * span:
            break
    return z, solves


def _default_thresholds(v: FloatArray, n: int) -> FloatArray:
    span = float(np.ptp(v))
    if not span > 0:
        raise ParameterError("input is constant: there is no hysteresis to identify")
    return np.arange(1, n + 1, dtype=np.float64) * span / (2.0 * (n + 1))


def identify_pi(
    input: npt.ArrayLike,
    output: npt.ArrayLike,
    *,
    operators: int = 9,
    thresholds: Thresholds | None = None,
    creep: Creep | None = None,
    loss: str = "squared",
    huber_delta: float | None = None,
    offset: bool = True,
) -> FitResult:
    """Classical PI with ``operators`` thresholds spread over half the input range (or the
    given ones), weights and linear term by non-negative least squares (``loss``,
    ``huber_delta``, ``offset``: see :func:`fit_linear`)."""
    t0 = time.perf_counter()
    v = as_record(input, "input", min_length=2)
    r = _default_thresholds(v, as_int(operators, "operators", minimum=1)) if thresholds is None else thresholds
    model = PI(r, np.zeros(len(r)), 1.0, creep=creep)
    name, delta = _check_loss(loss, huber_delta)
    return _fit_output(model, v, output, name, delta, t0, offset)


def identify_mpi(
    input: npt.ArrayLike,
    output: npt.ArrayLike,
    *,
    operators: int = 9,
    thresholds: Thresholds | None = None,
    rising: Envelope | None = None,
    falling: Envelope | None = None,
    creep: Creep | None = None,
    loss: str = "squared",
    huber_delta: float | None = None,
    offset: bool = True,
) -> FitResult:
    """Seed 2's MPI (cubic input polynomial + generalized plays) with the envelopes given
    (identity by default); polynomial and weights by bounded least squares (``loss``,
    ``huber_delta``, ``offset``: see :func:`fit_linear`)."""
    t0 = time.perf_counter()
    v = as_record(input, "input", min_length=2)
    r = _default_thresholds(v, as_int(operators, "operators", minimum=1)) if thresholds is None else thresholds
    model = _mpi_template(v, r, rising, falling, creep)
    name, delta = _check_loss(loss, huber_delta)
    return _fit_output(model, v, output, name, delta, t0, offset)


def _mpi_template(
    v: FloatArray, r: Thresholds, rising: Envelope | None, falling: Envelope | None, creep: Creep | None
) -> GeneralizedPI:
    """MPI of thresholds ``r`` and the envelopes given over the input range padded by half its span."""
    lo, hi = float(v.min()), float(v.max())
    pad = 0.5 * (hi - lo)
    return GeneralizedPI(r, np.zeros(len(r)), (0.0, 0.0, 0.0, 0.0), rising, falling, (lo - pad, hi + pad), creep=creep)


def identify_preisach(
    input: npt.ArrayLike,
    output: npt.ArrayLike,
    *,
    levels: int = 12,
    input_range: tuple[float, float] | None = None,
    memory: int = 64,
    loss: str = "squared",
    huber_delta: float | None = None,
    offset: bool = True,
) -> FitResult:
    """Discretized Preisach on a ``levels x levels`` grid over the input range; offset, slope
    and cell weights (non-negative) by least squares (``loss``, ``huber_delta``, ``offset``: see
    :func:`fit_linear`)."""
    t0 = time.perf_counter()
    v = as_record(input, "input", min_length=2)
    model = _preisach_template(v, levels, input_range, memory)
    name, delta = _check_loss(loss, huber_delta)
    return _fit_output(model, v, output, name, delta, t0, offset)


def _preisach_template(v: FloatArray, levels: int, input_range: tuple[float, float] | None, memory: int) -> Preisach:
    lo, hi = (float(v.min()), float(v.max())) if input_range is None else input_range
    n = as_int(levels, "levels", minimum=1)
    return Preisach(n, (lo, hi), np.zeros(n * (n + 1) // 2), memory=memory)


@dataclass(frozen=True)
class IdentificationResult(RunReport):
    """What :func:`identify` returns: the model, its free-run metrics on the training record
    (and the validation record when given), the optimizer history and the wall time.

    As every :class:`~piezohyst.optimize.RunReport`: ``wall_time`` (s), ``evaluations``
    (the candidate evaluations the fit spent: the optimizer's ``nfev`` plus the polish's, or
    the least-squares solves of a linear fit), ``history`` (the optimizer's per-iteration
    history with the method's extras; empty for a linear fit) and ``partial`` (Ctrl-C
    stopped the optimizer: the model is the best found before it)."""

    model: object
    train: Metrics
    validation: Metrics | None
    method: str
    wall_time: float
    #: ``None`` is taken as ``{}`` (no iterations).
    history: dict[str, Any] = field(default_factory=dict)
    #: How :meth:`simulate` predicts the output for models without a ``simulate(input)`` of their
    #: own (the CEMF stage's parameters); ``None``: ``model.simulate``.
    simulator: Callable[[FloatArray], FloatArray] | None = field(default=None, repr=False, compare=False)
    #: ``True`` when Ctrl-C stopped the optimizer: the model is the best found before it.
    partial: bool = False
    evaluations: int = 0

    def __post_init__(self) -> None:
        if not self.history:  # None from callers of the former signature
            object.__setattr__(self, "history", {})

    def _headline(self) -> str:
        t = self.train
        text = (
            f"{type(self.model).__name__} identified by {self.method}: rmse {t['rmse']:.4g} "
            f"({t['rmse_percent']:.3g} % of range)"
        )
        if self.validation is not None:
            text += f", validation rmse {self.validation['rmse']:.4g} ({self.validation['rmse_percent']:.3g} %)"
        return text + (" (partial)" if self.partial else "")

    def simulate(self, input: npt.ArrayLike) -> FloatArray:
        """The identified model's free-run output for an input record (for ``cemf``: positions
        from voltages, the stage simulated as it was identified)."""
        if self.simulator is not None:
            return np.asarray(self.simulator(as_record(input, "input")))
        if not isinstance(self.model, _Simulates):
            raise ParameterTypeError(f"{type(self.model).__name__} has no simulate(input) and no simulator was given")
        return self.model.simulate(input)

    @property
    def metrics(self) -> dict[str, Metrics | None]:
        return {"train": self.train, "validation": self.validation}

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready report (the model file's ``fit`` section)."""
        return {
            "method": self.method,
            "wall_time_s": self.wall_time,
            "train": self.train,
            "validation": self.validation,
            "partial": self.partial,
        }

    def plot(
        self, input: npt.ArrayLike | None = None, output: npt.ArrayLike | None = None, *, ax: Any = None
    ) -> Figure:
        """Loop, fit and residual for a record ``(input, output)`` (matplotlib figure); without
        a record, the optimizer's convergence (:meth:`RunReport.plot`, on ``ax`` if given)."""
        if input is None and output is None:
            return super().plot(ax=ax)
        if input is None or output is None:
            raise ParameterTypeError("plot() needs both input and output (or neither, for the convergence plot)")
        import matplotlib.pyplot as plt

        v = as_record(input, "input")
        y = as_record(output, "output")
        yp = self.simulate(v)
        fig, axes = plt.subplots(1, 3, figsize=(13, 3.8))
        axes[0].plot(v, y, lw=0.8, label="measured")
        axes[0].plot(v, yp, lw=0.8, label="model")
        axes[0].set(xlabel="input", ylabel="output", title="hysteresis loop")
        axes[0].legend()
        axes[1].plot(y, lw=0.8, label="measured")
        axes[1].plot(yp, lw=0.8, label="model")
        axes[1].set(xlabel="sample", title="fit")
        axes[2].plot(yp - y, lw=0.8)
        axes[2].set(xlabel="sample", title="residual")
        fig.tight_layout()
        return fig


def minimize_huber(
    simulate: Callable[[FloatArray], FloatArray],
    target: FloatArray,
    bounds: Sequence[tuple[float, float]],
    delta: float | None = None,
    **search: Any,
) -> OptimizeResult:
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

    def fixed(X: FloatArray) -> FloatArray:
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
    threshold = max(float(default_huber_delta(r0)), tiny)
    delta = threshold
    lower, upper = np.array(bounds, dtype=np.float64).T
    x, f, n = polish_lbfgsb(fixed, x0, float(fixed(x0[None, :])[0]), lower, upper, {})
    message = f"{res.message}; Huber threshold {threshold:.6g} from the MAD, then L-BFGS-B to {f:.6g}"
    return replace(
        res, x=x, fun=f, nfev=res.nfev + n + 1, message=message, history={**res.history, "huber_delta": threshold}
    )


#: Parameters searched by :func:`identify_cemf`, in seed 1's normalized form.
CEMF_PARAMETERS = ("M", "B", "K", "tem", "alpha", "beta", "gamma")


def identify_cemf(
    voltage: npt.ArrayLike,
    position: npt.ArrayLike,
    fs: float,
    *,
    capacitance: float = 1.8e-6,
    bounds: Sequence[tuple[float, float]] | None = None,
    optimizer: str = "css",
    rng: RngLike = None,
    max_iterations: int = 150,
    population_size: int | None = None,
    substeps: int = 1,
    tolerance: float = 0.05,
    validate: tuple[npt.ArrayLike, npt.ArrayLike] | None = None,
    progress: bool = False,
    callback: Callback | None = None,
    loss: str = "squared",
    huber_delta: float | None = None,
    polish: bool = False,
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
    its ``simulate`` predicts positions from voltages with the identified stage; ``evaluations``
    counts the search's simulations and the polish's.
    """
    from ..optimize.core import minimize
    from ..plant.stage import Amplifier, Stage, StageParameters

    t0 = time.perf_counter()
    name, delta = _check_loss(loss, huber_delta)
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
            (0.0, float(0.4 * np.sqrt(k_hi * k_hi / w_lo**2))),
            (k_lo, k_hi),
            (1.0, 50.0),
            (0.0, 4.0 / capacitance),
            (0.0, 30.0 / q),
            (-30.0 / q, 30.0 / q),
        ]
    box = [(float(lo), float(hi)) for lo, hi in bounds]
    if len(box) != len(CEMF_PARAMETERS):
        raise ParameterError(f"bounds has {len(box)} pairs, expected {len(CEMF_PARAMETERS)} ({CEMF_PARAMETERS})")
    wide = Amplifier(-1e9, 1e9)
    template: FloatArray = Stage(
        StageParameters(1.0, 0.0, 1.0, 1.0, capacitance),
        wide,
        sample_time=1.0 / fs,
        substeps=substeps,
        tolerance=tolerance,
    ).core_params()

    def rows(theta: FloatArray) -> FloatArray:
        theta = np.atleast_2d(theta)
        out = np.repeat(template[None, :], theta.shape[0], axis=0)
        M, B, K, tem = theta[:, 0], theta[:, 1], theta[:, 2], theta[:, 3]
        out[:, 0], out[:, 1], out[:, 2], out[:, 3] = M * tem, B * tem, K * tem, tem
        out[:, 5], out[:, 6], out[:, 7] = theta[:, 4], theta[:, 5], theta[:, 6]
        return np.ascontiguousarray(out)

    def unbounded(theta: FloatArray) -> npt.NDArray[np.bool_]:
        # Bouc-Wen (n = 1) keeps Vh bounded for every input only if beta >= |gamma|; a model
        # outside that may fit the record yet run away on another drive (or in an observer)
        theta = np.atleast_2d(theta)
        return theta[:, 5] < np.abs(theta[:, 6])

    def cost(theta: FloatArray) -> FloatArray:
        c = _core.stage_batch_rmse(rows(theta), 1.0 / fs, substeps, tolerance, u, x, float("inf"))
        c[unbounded(theta)] = np.inf
        return c

    def simulate(theta: FloatArray) -> FloatArray:
        out = _stage_positions(rows(theta), 1.0 / fs, substeps, tolerance, u)
        out[unbounded(theta)] = np.nan
        return out

    method = "css" if optimizer == "ls" else optimizer
    search: dict[str, Any] = dict(
        method=method,
        rng=rng,
        max_iterations=max_iterations,
        population_size=population_size,
        progress=progress,
        callback=callback,
    )
    if not isinstance(polish, bool):
        raise ParameterTypeError(f"polish must be True or False, got {polish!r}")
    if name == "squared":
        res = minimize(cost, box, **search)
    else:
        res = minimize_huber(simulate, x, box, delta, **search)
    theta: FloatArray = np.array(res.x, dtype=np.float64)
    history: dict[str, Any] = dict(res.history)
    evaluations = int(res.nfev)
    if polish and name == "squared" and res.message != "interrupted" and np.isfinite(res.fun):
        theta, info = _polish_simulation(simulate, x, theta, box)
        history["polish"] = info
        evaluations += int(info["nfev"])
        method += "+least_squares"
    M, B, K, tem, alpha, beta, gamma = (float(t) for t in theta)
    params = StageParameters(M * tem, B * tem, K * tem, tem, capacitance, alpha, beta, gamma)
    stage = Stage(params, wide, sample_time=1.0 / fs, substeps=substeps, tolerance=tolerance)
    train = _fit_metrics(stage.simulate(u).position, x)
    val = None
    if validate is not None:
        vu = as_record(validate[0], "validate voltage")
        vx = as_record(validate[1], "validate position")
        val = _fit_metrics(stage.simulate(vu).position, vx)
    if name == "huber":
        method += "+huber"

    def positions(u_: FloatArray) -> FloatArray:
        p: FloatArray = stage.simulate(u_).position
        return p

    return IdentificationResult(
        params,
        train,
        val,
        method,
        time.perf_counter() - t0,
        history,
        simulator=positions,
        partial=res.interrupted,
        evaluations=evaluations,
    )


def _polish_simulation(
    simulate: Callable[[FloatArray], FloatArray],
    target: FloatArray,
    x0: FloatArray,
    bounds: Sequence[tuple[float, float]],
    max_nfev: int | None = None,
) -> tuple[FloatArray, dict[str, Any]]:
    """SciPy ``least_squares`` (``trf`` within ``bounds``, forward-difference Jacobian,
    ``x_scale="jac"``) on ``simulate(theta[None])[0] - target`` from ``x0``; a failed
    simulation (NaN row) returns a large constant residual. Returns ``(theta, info)`` with the
    better of ``x0`` and the polished point."""
    from scipy.optimize import least_squares

    lower, upper = np.array(bounds, dtype=np.float64).T
    span = float(np.ptp(target)) or 1.0
    wall = np.full(target.size, 10.0)
    calls = 0

    def fun(theta: FloatArray) -> FloatArray:
        nonlocal calls
        calls += 1
        r = (simulate(theta[None, :])[0] - target) / span
        return r if np.all(np.isfinite(r)) else wall

    def rmse(theta: FloatArray) -> float:
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
        diff_step=np.full(start.size, 1e-6),  # one relative step per parameter (a scalar, broadcast)
        xtol=1e-12,
        ftol=1e-12,
        gtol=1e-12,
        max_nfev=max_nfev or 100 * (x0.size + 1),
    )
    x1 = np.clip(sol.x, lower, upper)
    after = rmse(x1)
    info = {"rmse_before": before, "rmse_after": min(before, after), "nfev": calls, "message": str(sol.message)}
    return (x1 if after < before else np.array(x0, dtype=np.float64)), info


def _stage_positions(rows: FloatArray, ts: float, substeps: int, tolerance: float, u: FloatArray) -> FloatArray:
    """``(S, N)`` open-loop positions of stage rows from rest, as ``stage_batch_rmse`` scores
    them; a NaN row where the core refuses the row or the run fails."""
    out = np.full((rows.shape[0], u.size), np.nan)
    for i, row in enumerate(rows):  # a loop over the population, each run in Rust
        try:
            out[i] = _core.stage_simulate(row, ts, substeps, tolerance, u, np.zeros(_core.STAGE_STATE_LEN))[0]
        except (ValueError, RuntimeError):
            pass
    return out
