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

import functools
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ParamSpec, Protocol, TypeAlias, TypeVar, runtime_checkable

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

    Parameters
    ----------
    taus : sequence of float
        Time constants of the exponential settling terms, samples (> 0).
    linear : bool
        Add a ramp ``k``.

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
        """The basis's label in reports and the CLI: ``exp(tau)`` terms and ``linear`` joined
        by ``+``, ``"none"`` when empty.

        Examples
        --------
        >>> DriftBasis().name, DriftBasis(taus=(50.0, 2000.0), linear=True).name
        ('none', 'exp(50)+exp(2000)+linear')
        """
        parts = [f"exp({t:.6g})" for t in self.taus] + (["linear"] if self.linear else [])
        return "+".join(parts) or "none"

    @property
    def size(self) -> int:
        """The number of columns (fitted weights): one per ``tau`` plus one for the ramp.

        Examples
        --------
        >>> DriftBasis().size, DriftBasis(taus=(50.0, 2000.0), linear=True).size
        (0, 3)
        """
        return len(self.taus) + int(self.linear)

    def columns(self, n: int) -> FloatArray:
        """The ``(n, size)`` basis over samples ``0 ... n - 1``: the exponentials, then the ramp.

        Parameters
        ----------
        n : int
            Number of samples.

        Returns
        -------
        ndarray, shape (n, size)

        Examples
        --------
        >>> DriftBasis(taus=(1.0,), linear=True).columns(3).round(4).tolist()
        [[0.0, 0.0], [0.6321, 1.0], [0.8647, 2.0]]
        >>> DriftBasis().columns(4).shape
        (4, 0)
        """
        k = np.arange(n, dtype=np.float64)
        cols = [-np.expm1(-k / t) for t in self.taus]
        if self.linear:
            cols.append(k)
        return np.column_stack(cols) if cols else np.zeros((n, 0))

    def drift(self, weights: npt.ArrayLike) -> Drift | None:
        """The model's drift term for the fitted ``weights`` (the basis' column order); ``None``
        for the empty basis.

        Parameters
        ----------
        weights : array_like, shape (size,)
            The fitted weights of :meth:`columns`, in its column order.

        Returns
        -------
        Drift or None

        Examples
        --------
        >>> DriftBasis(taus=(100.0,), linear=True).drift([2.0, 0.01])
        Drift(taus=(100.0,), weights=(2.0,), slope=0.01)
        >>> DriftBasis().drift([]) is None
        True
        """
        w = np.asarray(weights, dtype=np.float64)
        if self.empty:
            return None
        m = len(self.taus)
        return Drift(taus=self.taus, weights=tuple(float(x) for x in w[:m]), slope=float(w[m]) if self.linear else 0.0)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (as ``piezohyst identify --json`` reports the drift basis).

        Returns
        -------
        dict
            ``{"name": ..., "taus": [...], "linear": ...}``.

        Examples
        --------
        >>> DriftBasis(taus=(100.0,), linear=True).to_dict()
        {'name': 'exp(100)+linear', 'taus': [100.0], 'linear': True}
        """
        return {"name": self.name, "taus": list(self.taus), "linear": self.linear}


def delayed(input: npt.ArrayLike, delay: int) -> FloatArray:
    """The input a model with an input delay of ``delay`` samples sees: ``input`` shifted late
    by ``delay`` samples, the first sample held before the record starts.

    Parameters
    ----------
    input : array_like, shape (N,)
        The input record.
    delay : int
        Input delay, samples (>= 0).

    Returns
    -------
    ndarray, shape (N,)

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
    ``history`` (empty: a linear fit does not iterate over candidates; a Preisach grid's holds
    the smoothing strengths it chose among, :func:`fit_linear`) and ``partial`` (always
    ``False``: a linear fit is not interrupted halfway); ``condition``: the conditioning of
    the least-squares problem.

    Parameters
    ----------
    model : HysteresisModel
        The fitted model.
    metrics : dict
        ``rmse``, ``max_error`` (output units) and both in % of the output range
        (:func:`fit_metrics`).
    wall_time : float
        Seconds the fit took.
    evaluations : int
        Least-squares solves.
    history : dict
        Empty for a linear fit.
    partial : bool
        Always ``False``.
    condition : float
        Condition number of the equilibrated regressors of the least-squares problem.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst import PI, identify_pi
    >>> v = np.sin(np.linspace(0, 12, 1200)) * np.linspace(1, 0.3, 1200)
    >>> fit = identify_pi(v, PI([0.1, 0.3], [0.5, 0.2], p0=0.8).simulate(v), thresholds=[0.1, 0.3])
    >>> type(fit.model).__name__, bool(fit.metrics["rmse"] < 1e-12), fit.partial
    ('PI', True, False)
    """

    model: LinearModel
    metrics: Metrics
    wall_time: float
    evaluations: int = 1
    history: dict[str, Any] = field(default_factory=dict)
    partial: bool = False
    #: The 2-norm condition number of the equilibrated regressors the least squares solved
    #: (PI family; ``nan`` when not computed: a Preisach grid's hundreds of columns).
    condition: float = math.nan

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

    def _scores(self) -> dict[str, float]:
        m = self.metrics
        return {"rmse (% of range)": m["rmse_percent"], "max error (% of range)": m["max_error_percent"]}


def fit_metrics(predicted: npt.ArrayLike, measured: npt.ArrayLike) -> Metrics:
    """RMSE and max error of the free-run simulation, also in % of the measured range.

    Parameters
    ----------
    predicted : array_like
        The model's output.
    measured : array_like
        The measured output (same length).

    Returns
    -------
    dict
        ``rmse``, ``max_error``, ``rmse_percent``, ``max_error_percent``.

    Examples
    --------
    >>> from piezohyst import fit_metrics
    >>> fit_metrics([0.0, 1.0, 2.0, 3.0], [0.0, 1.0, 2.0, 5.0])
    {'rmse': 1.0, 'max_error': 2.0, 'rmse_percent': 20.0, 'max_error_percent': 40.0}
    """
    p = as_record(predicted, "predicted", copy=False)
    m = as_record(measured, "measured", copy=False)
    return _fit_metrics(p, m)


def _fit_metrics(predicted: npt.ArrayLike, measured: FloatArray) -> Metrics:
    """:func:`fit_metrics` of a model's output against an already validated record: the
    prediction (not an input of the caller's) is still checked finite, with the same message."""
    p = as_record(predicted, "predicted", copy=False)
    if p.size != measured.size:
        raise ParameterError(f"predicted has {p.size} samples, measured has {measured.size}; they must match")
    # on the records scaled by their largest magnitude: values near 1e300 do not overflow the
    # squares and subnormal ones (1e-310) do not vanish from them (RMSE 0 beside a max error)
    scale = max(float(np.max(np.abs(p))), float(np.max(np.abs(measured))))
    if scale == 0.0:
        return {"rmse": 0.0, "max_error": 0.0, "rmse_percent": 0.0, "max_error_percent": 0.0}
    m = measured / scale
    e = p / scale - m
    rmse, emax = float(np.sqrt(np.mean(e**2))), float(np.max(np.abs(e)))
    span = float(np.ptp(m)) or 1.0 / scale  # a constant record: percent of one output unit
    return {
        "rmse": rmse * scale,
        "max_error": emax * scale,
        "rmse_percent": 100 * rmse / span,
        "max_error_percent": 100 * emax / span,
    }


#: The magnitudes a fit works with. Its regressors (the MPI polynomial cubes the input) are
#: squared and summed over the record: |x| <= 1e40 keeps cubes (1e120), their squares (1e240)
#: and sums of 1e9 of them finite; a range >= 1e-40 keeps their squares normal (a subnormal
#: square loses its digits, 1e-310 squared is 0). Records outside are rescaled by their unit.
FIT_MAX_MAGNITUDE = 1e40
FIT_MIN_RANGE = 1e-40


def check_fit_scale(x: FloatArray, name: str) -> None:
    """Refuse a training record outside the magnitudes a fit works with (:data:`FIT_MAX_MAGNITUDE`,
    :data:`FIT_MIN_RANGE`), naming the limit, before any numpy or SciPy warning."""
    big = float(np.max(np.abs(x)))
    if big > FIT_MAX_MAGNITUDE:
        raise ParameterError(
            f"{name} reaches {big:.3g}: a fit works on values within +-{FIT_MAX_MAGNITUDE:.0e} (its squares and "
            "cubes must stay finite); rescale the record (its values, or its unit: --input-unit / --output-unit)"
        )
    span = float(np.ptp(x))
    if 0.0 < span < FIT_MIN_RANGE:
        raise ParameterError(
            f"{name} spans {span:.3g}: a fit needs a range of at least {FIT_MIN_RANGE:.0e} (its squares must not "
            "underflow); rescale the record (its values, or its unit: --input-unit / --output-unit)"
        )


#: Fewest samples a fit takes per parameter it estimates. For least squares with white noise
#: the training residual's expected mean square is sigma^2 (1 - p/N) and a held-out record's
#: sigma^2 (1 + p/N): at N = 10 p the training RMSE understates the held-out one by 10 %
#: (sqrt(0.9 / 1.1)), at N = 2 p by 42 %, and at N <= p the fit interpolates the noise. Below
#: 10 samples per parameter a fit's figure says more about its parameter count than the actuator.
MIN_SAMPLES_PER_PARAMETER = 10


def check_samples(n: int, parameters: int, what: str, hint: str = "") -> None:
    """Refuse a fit of ``parameters`` parameters from ``n`` samples when ``n`` is below
    :data:`MIN_SAMPLES_PER_PARAMETER` times ``parameters`` (``what`` names the model), before
    any fitting (:func:`parameter_count` for the linear families)."""
    need = MIN_SAMPLES_PER_PARAMETER * parameters
    if n < need:
        raise ParameterError(
            f"the training record has {n} samples, too few to fit the {parameters} parameters of {what}: a fit "
            f"needs at least {MIN_SAMPLES_PER_PARAMETER} samples per parameter ({need}); give a longer record"
            + (f" or {hint}" if hint else "")
        )


#: Losses :func:`identify` and :func:`fit_linear` minimize.
LOSSES = ("squared", "huber")

#: Strengths of the Preisach fit's smoothness prior along the lines of constant loop width
#: that :func:`fit_linear` chooses among by default (``smoothing=None``): dimensionless,
#: relative to the data term; the one that best predicts the last :data:`PREISACH_HOLDOUT` of
#: the record from the rest wins.
PREISACH_SMOOTHINGS = (0.0, 1e-2, 1e-1)

#: The fraction of the record the choice of the smoothing predicts (its end, the state
#: carried from the rest).
PREISACH_HOLDOUT = 0.25

#: How much more than the fit without the prior (relative RMSE on the data fitted) a
#: smoothed fit may miss by and still be chosen.
PREISACH_FIT_TOLERANCE = 0.05

#: Memory (dominant extrema) of the Preisach models :func:`identify_preisach` and
#: :func:`piezohyst.identify` build: the core's largest. A decaying excitation nests a loop
#: per cycle; beyond the memory the model forgets the newest pair of extrema, so 64 (the
#: model's default) failed records of more than 32 decaying cycles (held out: 7-14 % of the
#: range where 256 gives 0.9-1.2 %).
PREISACH_MEMORY = 256

#: Huber's tuning constant: 95 % efficiency at Gaussian residuals.
HUBER_K = 1.345

#: MAD to standard deviation at Gaussian residuals.
_MAD_TO_SIGMA = 1.4826


def default_huber_delta(residuals: npt.ArrayLike) -> FloatArray:
    """Default Huber threshold of residual records: ``1.345 sigma`` with the robust
    ``sigma = 1.4826 median(|r - median(r)|)``, along the last axis.

    Parameters
    ----------
    residuals : array_like
        One record, or one per row.

    Returns
    -------
    ndarray
        One threshold per record.

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

    Parameters
    ----------
    residuals : array_like, shape (N,) or (S, N)
        One record, or one per row.
    delta : float or array_like, optional
        The threshold (one, or one per row); by default each row's :func:`default_huber_delta`.

    Returns
    -------
    ndarray
        One cost per record.

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
            offset, slope, w, creep_c = parts(t)
            return Preisach(
                model.levels,
                model.input_range,
                w,
                offset[0],
                slope[0],
                model.memory,
                creep=with_creep(creep_c),
                units=model.units,
            )

    return lb, np.full(lb.size, inf), build


def fit_linear(
    model: LinearModel,
    input: npt.ArrayLike,
    output: npt.ArrayLike,
    *,
    loss: str = "squared",
    huber_delta: float | None = None,
    offset: bool = True,
    smoothing: float | None = None,
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
    smoothing : float, optional
        Preisach only: the strength of the smoothness prior along the grid's diagonals (cells
        of equal loop width ``alpha - beta``), dimensionless, relative to the data term; it
        decides the cells a record sees only through sums (those of loops smaller than its
        last: a decaying record). ``None``: chosen among :data:`PREISACH_SMOOTHINGS` by how
        well each predicts the record's end from the rest (``history["smoothing"]``); ``0``:
        plain non-negative least squares.

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
    return _fit_output(model, v, output, name, delta, t0, offset, smoothing)


def _fit_output(
    model: LinearModel,
    v: FloatArray,
    output: npt.ArrayLike,
    loss: str,
    delta: float | None,
    t0: float,
    offset: bool = True,
    smoothing: float | None = None,
) -> FitResult:
    """:func:`fit_linear` from a validated input and checked loss: validates ``output`` and
    ``smoothing``."""
    y = as_record(output, "output", min_length=2)
    if y.size != v.size:
        raise ParameterError(f"output has {y.size} samples, input has {v.size}; they must match")
    check_fit_scale(v, "input")
    check_fit_scale(y, "output")
    return _fit_linear(model, v, y, loss, delta, t0, bool(offset), _check_smoothing(model, smoothing))


def _check_smoothing(model: LinearModel, smoothing: float | None) -> float | None:
    """``smoothing`` checked (``>= 0``, Preisach only); ``None`` (chosen by hold-out) kept."""
    if smoothing is None:
        return None
    if not isinstance(model, Preisach):
        raise ParameterError(
            f"smoothing = {smoothing!r} applies to a Preisach model, not to {type(model).__name__} (give None)"
        )
    return as_scalar(smoothing, "smoothing", nonnegative=True)


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
    if isinstance(model, RateDependentPI):
        A, lb, build = _rate_interpolation(model, A, lb, build)
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


#: The rate-dependent PI's fit keeps every play weight ``w_i + c_i rate`` non-negative up to
#: this many times the record's largest (filtered) input rate (:func:`_rate_interpolation`).
RATE_MARGIN = 4.0


def _rate_interpolation(
    model: RateDependentPI, A: FloatArray, lb: FloatArray, build: Callable[[FloatArray], LinearModel]
) -> tuple[FloatArray, FloatArray, Callable[[FloatArray], LinearModel]]:
    """The rate-dependent PI's weights ``w_i + c_i rate`` fitted as ``a_i (1 - rho) + b_i rho``,
    ``rho = rate / R``, ``a_i, b_i >= 0`` (the weights at rate 0 and at ``R``), ``R`` =
    :data:`RATE_MARGIN` times the record's largest rate: ``(A, lb, build)`` with the columns
    ``z_i (1 - rho)`` and ``z_i rho`` in place of ``z_i`` and ``z_i rate``.

    The same model (``w_i = a_i``, ``c_i = (b_i - a_i) / R``), well posed: with ``c_i`` free
    the fit could trade ``w_i`` against ``c_i`` wherever the record's rate varies little (one
    frequency: the columns ``z_i`` and ``z_i rate`` nearly collinear; rates in 1e4-1e6 V/s
    beside weights of 1e-2), and a weight that goes negative at a faster rate than the
    training's makes the model non-monotone there (a 10 Hz sine trained, 30 Hz held out: 4.8 %
    of the range where the fixed structure gives 1.9 %; now 1.1 %). The rate at each sample is
    read off the regressors (``z_i rate / z_i``), the core's definition, not a second one."""
    n = model.thresholds.size
    slots = _linear_slots(model)
    starts = np.cumsum([0] + [size for size, _ in slots])[:-1]
    # the play weights: the non-negative slot of n; the rate weights: the free slot of n
    iw = next(int(a) for (size, nonneg), a in zip(slots, starts, strict=True) if size == n and nonneg and a > 0)
    ic = next(int(a) for (size, nonneg), a in zip(slots, starts, strict=True) if size == n and not nonneg)
    Z, ZR = A[:, iw : iw + n], A[:, ic : ic + n]
    j = np.argmax(np.abs(Z), axis=1)
    rows = np.arange(A.shape[0])
    zj = Z[rows, j]
    moving = zj != 0.0
    top = float(np.max(np.abs(ZR[rows, j][moving] / zj[moving]))) if np.any(moving) else 0.0
    if not (np.isfinite(top) and top > 0.0):
        return A, lb, build  # no rate: the rate weights have nothing to act on
    R = RATE_MARGIN * top
    A = A.copy()
    A[:, iw : iw + n] = Z - ZR / R
    A[:, ic : ic + n] = ZR / R
    lb = lb.copy()
    lb[ic : ic + n] = 0.0

    def build_rates(t: FloatArray) -> LinearModel:
        t = np.array(t, dtype=np.float64)
        t[ic : ic + n] = (t[ic : ic + n] - t[iw : iw + n]) / R
        return build(t)

    return A, lb, build_rates


def _condition(A: FloatArray) -> float:
    """2-norm condition number of a regressor matrix with its columns equilibrated (the
    matrix the bounded least squares solve): ``inf`` when rank deficient."""
    s = np.linalg.svd(A, compute_uv=False)
    return float(s[0] / s[-1]) if s.size and s[-1] > 0 else math.inf


def _fit_linear(
    model: LinearModel,
    v: FloatArray,
    y: FloatArray,
    loss: str,
    delta: float | None,
    t0: float | None = None,
    offset: bool = False,
    smoothing: float | None = None,
    drift: DriftBasis | None = None,
    start: int = 0,
) -> FitResult:
    """:func:`fit_linear` of validated records (equal lengths) with a checked loss
    (``smoothing``: Preisach only, checked); with a ``drift`` basis fitted too, and the samples
    before ``start`` simulated but left out of the cost (the metrics are of the whole record)."""
    t0 = time.perf_counter() if t0 is None else t0
    if isinstance(model, Preisach):  # its own offset constant: no column to add
        check_samples(v.size, parameter_count(model, 0), _what(model), "fewer levels")
        return _fit_preisach(model, v, y, loss, delta, t0, smoothing, None, drift, start)
    A, lb, ub, build = _design(model, v, offset, drift)
    check_samples(v.size, parameter_count(model, A.shape[1]), _what(model), "fewer operators")
    A, yf = A[start:], y[start:]
    scale = np.maximum(np.sqrt(np.mean(A**2, axis=0)), 1e-300)  # equilibrate the columns
    A = A / scale
    bounds = (lb * scale, ub * scale)
    z = np.clip(_bvls(A, yf, bounds), *bounds)
    solves = 1
    if loss == "huber":
        z, k = _irls_huber(A, yf, bounds, z, delta, _qr_bounded_lstsq)
        solves += k
    fitted = build(z / scale)
    metrics = _fit_metrics(fitted.simulate(v), y)
    return FitResult(fitted, metrics, time.perf_counter() - t0, solves, condition=_condition(A))


def parameter_count(model: LinearModel, columns: int) -> int:
    """The parameters :func:`check_samples` counts for a linear fit of ``columns`` design
    columns: every column (weights, polynomial, creep weights, offset) for the PI family; for
    a Preisach grid of ``L`` levels ``L + 2`` (offset, slope and the grid's resolution). Its
    ``L (L + 1) / 2`` cells discretize one non-negative density, tied by that constraint and by
    the record's reversals, not free parameters: on yan9a's one-cycle training span (200
    samples) a 12-level grid leaves 60 cells above 0 and validates at 0.256 % of range against
    0.226 % in training, no overfit; a 24-level grid (255 cells above 0) still 0.246 %."""
    if isinstance(model, Preisach):
        return model.levels + 2
    return columns


def _what(model: LinearModel) -> str:
    """A linear model for a message: ``a PI model of 9 operators``, ``a Preisach model of 12 levels``."""
    if isinstance(model, Preisach):
        return f"a Preisach model of {model.levels} levels"
    return f"a {type(model).__name__} model of {model.thresholds.size} operators"


_P = ParamSpec("_P")
_R = TypeVar("_R")


def _one_blas_thread(fit: Callable[_P, _R]) -> Callable[_P, _R]:
    """Run ``fit`` with BLAS (OpenBLAS, MKL, ...) limited to one thread (threadpoolctl), the
    limit lifted after. The fits call BLAS thousands of times on matrices of a few hundred to
    a thousand columns, where a second thread barely helps and, on a shared machine, costs:
    waiting threads spin, and a busy core stalls every call (measured on the 2-core machine
    at load 3-6: a 1178 x 1178 Cholesky 0.017 s on one thread, 0.215 s on two; the 48-level
    Preisach fit of bench/identify_speed.py 2.1-2.2 s CPU on one, 2.9-3.2 s on two, and 6.2-6.7 s
    wall on two at load 5-6)."""

    @functools.wraps(fit)
    def limited(*args: _P.args, **kwargs: _P.kwargs) -> _R:
        try:
            from threadpoolctl import threadpool_limits
        except ImportError:  # an environment from before the dependency: BLAS keeps its threads
            return fit(*args, **kwargs)
        import scipy.linalg  # noqa: F401  (loads SciPy's BLAS first: the limit covers the libraries loaded)

        with threadpool_limits(limits=1, user_api="blas"):
            return fit(*args, **kwargs)

    return limited


@_one_blas_thread
def _fit_preisach(
    model: Preisach,
    v: FloatArray,
    y: FloatArray,
    loss: str,
    delta: float | None,
    t0: float,
    smoothing: float | None = None,
    weights: FloatArray | None = None,
    drift: DriftBasis | None = None,
    start: int = 0,
) -> FitResult:
    """:func:`fit_linear` of a Preisach grid, on the distinct relay patterns the record excites,
    with a smoothness prior of strength ``smoothing`` along the lines of constant loop width.

    A cell's regressor is its relay's state over the record (0 or 1). Cells the record never
    switches (a constant column: the offset's) and cells that always switch together (equal
    columns) cannot be told apart by any record with this history: the problem is solved over
    the distinct non-constant columns only, one weight per cell shared by the cells of a group
    (a ``p x p`` non-negative least squares through the Cholesky factor of the Gram matrix,
    :func:`_bounded_lstsq_gram`; BVLS on the whole ``N x L^2/2`` matrix took minutes), and
    never-switched cells get weight 0 (their effect is the offset's).

    The smoothness prior: a record whose loops shrink (a decaying excitation) never turns
    inside its last loop, so the cells of the smaller loops its continuation runs (both
    ``alpha`` and ``beta`` inside that loop) are seen by the record only through their row and
    column sums: any split of those sums fits it, and the least-squares split (sparse, at the
    extremes) predicts the smaller loops badly (held out: 2.0 % of the range at 48 levels, 1.3 %
    at 24). The prior adds ``smoothing * c * sum (w[i, j] - w[i + 1, j + 1])**2`` over the
    cells' neighbours along the diagonals (the same loop width ``alpha - beta``; ``c`` makes it
    dimensionless: the mean squared regressor of a cell over the mean squared difference
    operator), which fills those cells from the cells of the same loop width that larger loops
    identify: exact for a PI (uniform along every diagonal). A measured actuator's density
    need not be smooth along the diagonals where the record does see it (yan9a at 12 levels:
    training RMSE 0.226 % without the prior, 0.289 % at a strength of 0.1), so by default
    (``smoothing=None``) the strength is chosen among :data:`PREISACH_SMOOTHINGS` by hold-out:
    each fits the record but its last :data:`PREISACH_HOLDOUT` and predicts that end, the
    state carried (the regressors are the free run's: the prediction is a product, not a
    simulation); the best prediction wins (RMSE, or the Huber cost with ``loss="huber"``, the
    hold-out fits then weighted by one IRLS step's Huber weights, from which the final IRLS
    starts), among the strengths whose fit misses its own data by at most
    :data:`PREISACH_FIT_TOLERANCE` more than the fit without the prior. A decaying record's end
    has its smallest loops, so the hold-out asks what a validation span asks. ``smoothing = 0``
    is the plain non-negative least squares. ``weights``: sample weights (``sum w r^2``). The
    result's ``history`` holds the strengths tried, their hold-out errors and the one used
    (``smoothing``)."""
    lb, _, build = _layout(model)
    A = _core.regressors(model.family, list(model.dims), model.to_row(), v)[start:]
    m = 0 if model.creep is None else model.creep.terms
    head = A.shape[1] - model.weights.size - m  # offset and slope, one column per cell, the creep lags
    cells = A[:, head : A.shape[1] - m]
    # distinct relay patterns: the columns as packed bits (a relay is 0 or 1)
    bits = np.packbits(cells.T > 0.5, axis=1)
    patterns, first, group = np.unique(bits, axis=0, return_index=True, return_inverse=True)
    group = group.ravel()
    constant = (cells.max(axis=0) == cells.min(axis=0))[first]  # reductions, no copy of the matrix
    kept = np.flatnonzero(~constant)
    n = A.shape[0]  # the rows from the fit's start
    counts = np.bincount(group, minlength=patterns.shape[0])
    # one unknown per kept group: the weight of each of its cells (their columns summed, count
    # times the first's), the columns equilibrated to unit RMS in place (the matrix is N x ~L^2/2)
    C = cells[:, first[kept]]
    norm = np.maximum(np.sqrt(np.einsum("ij,ij->j", C, C) / n), 1e-300)
    C /= norm
    head_scale = np.maximum(np.sqrt(np.mean(A[:, :head] ** 2, axis=0)), 1e-300)
    # the creep lags (non-negative) and a drift basis (free): columns after the cells',
    # equilibrated like them
    extra = 0 if drift is None else drift.size
    T = np.zeros((n, 0)) if drift is None else drift.columns(v.size)[start:]
    T = np.concatenate([A[:, A.shape[1] - m :], T], axis=1)
    drift_scale = np.maximum(np.sqrt(np.mean(T**2, axis=0)), 1e-300)
    B = np.concatenate([A[:, :head] / head_scale, C, T / drift_scale], axis=1)
    del C, T
    # B's columns are the regressors / scale
    scale = np.concatenate([head_scale, counts[kept] * norm, drift_scale])
    blb = np.concatenate([lb[:head], lb[head : lb.size - m][first[kept]], lb[lb.size - m :], np.full(extra, -np.inf)])
    cells_end = head + kept.size  # the cells' unknowns are B's columns head:cells_end
    unit_penalty = None  # the prior of strength 1 per sample of the data term
    if kept.size > 1 and (smoothing is None or smoothing > 0):
        column = np.full(patterns.shape[0], -1)
        column[kept] = head + np.arange(kept.size)
        DD = _diagonal_smoothness(model.levels, column[group], B.shape[1])
        cost = float(np.mean(np.diag(DD)[head:cells_end]))
        if cost > 0:
            # in the equilibrated unknowns z = u * scale, relative to the data term's size
            unit_penalty = (float(np.mean(scale[head:cells_end] ** 2)) / cost) * DD / np.outer(scale, scale)
    bounds = (blb * scale, np.full(blb.size, np.inf))
    # the normal equations square the conditioning: solve for the output in units of its RMS, so
    # a record in other units (a gain) gives the same fit to rounding, not to the solver's tolerance
    # (and about its mean when the first column is the free offset's constant one: a record with
    # an offset then gives the same fit to rounding too)
    yf = y[start:]
    centre = float(np.mean(yf)) if np.all(A[:, 0] == 1.0) and lb[0] == -np.inf else 0.0
    unit = float(np.sqrt(np.mean((yf - centre) ** 2))) or 1.0
    yn = (yf - centre) / unit
    w = np.ones(n) if weights is None else weights[start:]
    if weights is not None:
        sw = np.sqrt(w)
        B, yn = B * sw[:, None], yn * sw
    free = np.isneginf(bounds[0])
    # the Gram matrix in two parts: the choice of the smoothing fits the first, predicts the end
    k = round((1.0 - PREISACH_HOLDOUT) * n)
    G1, b1, yy = B[:k].T @ B[:k], B[:k].T @ yn[:k], float(yn[:k] @ yn[:k])
    G, b = G1 + B[k:].T @ B[k:], b1 + B[k:].T @ yn[k:]
    history: dict[str, Any] = {}
    dn = None if delta is None else delta / unit
    solves = 0
    h = None  # the Huber weights (square roots) of the fit without the prior, when chosen by hold-out
    choose = unit_penalty is not None and smoothing is None and k >= B.shape[1] and n - k >= 2
    if unit_penalty is None or (smoothing is None and not choose):  # nothing to smooth, or too short to hold out
        smoothing = 0.0
    if choose and loss == "huber":
        # the hold-out's fits must not chase the glitches either: they are weighted by the Huber
        # weights of the least-squares fit without the prior (one IRLS step: the glitches stand
        # out of its residuals), and score the end by its cost; the final IRLS starts from them
        z0 = _gram_nnls(G, b, free)
        solves += 1
        h = _huber_sqrt_weights(B @ z0 - yn, dn, float(np.ptp(yn)) or 1.0)
        Bh, yh = B[:k] * h[:k, None], yn[:k] * h[:k]
        G1, b1, yy = Bh.T @ Bh, Bh.T @ yh, float(yh @ yh)
    if choose:
        assert unit_penalty is not None
        smoothing, history = _choose_smoothing(
            G1, b1, yy, k, B[k:], yn[k:], free, float(np.sum(w[:k])) * unit_penalty, loss, dn
        )
        history["smoothing_holdout_error"] *= unit  # in the output's unit
        history["smoothing_fit_error"] *= unit
        solves += len(PREISACH_SMOOTHINGS)
    assert smoothing is not None
    penalty = None if unit_penalty is None or smoothing == 0 else smoothing * float(np.sum(w)) * unit_penalty
    history["smoothing"] = smoothing
    if h is None:
        z = _gram_nnls(G if penalty is None else G + penalty, b, free)
    else:  # warm start: the Huber weights of the least-squares fit without the prior
        z = _bounded_lstsq_gram(B * h[:, None], yn * h, bounds, penalty)
    solves += 1
    if loss == "huber":

        def solve(A_: FloatArray, y_: FloatArray, b_: tuple[FloatArray, FloatArray]) -> FloatArray:
            return _bounded_lstsq_gram(A_, y_, b_, penalty)

        z, n_irls = _irls_huber(B, yn, bounds, z, dn, solve)
        solves += n_irls
    zb = z * unit / scale
    zb[0] += centre
    per_cell = np.zeros(patterns.shape[0])
    per_cell[kept] = zb[head:cells_end]
    theta = np.concatenate([zb[:head], per_cell[group], zb[cells_end : cells_end + m]])
    fitted = build(theta)
    if drift is not None and not drift.empty:
        fitted = fitted.with_drift(drift.drift(zb[cells_end + m :]))
    return FitResult(fitted, _fit_metrics(fitted.simulate(v), y), time.perf_counter() - t0, solves, history)


def _choose_smoothing(
    G: FloatArray,
    b: FloatArray,
    yy: float,
    n_fit: int,
    B_end: FloatArray,
    y_end: FloatArray,
    free: npt.NDArray[np.bool_],
    unit_penalty: FloatArray,
    loss: str,
    delta: float | None,
) -> tuple[float, dict[str, Any]]:
    """The strength of :data:`PREISACH_SMOOTHINGS` whose fit of the record but its end (Gram
    matrix ``G``, ``b``, ``yy = y'y`` of its ``n_fit`` samples; the prior of strength 1
    ``unit_penalty``) predicts the end (regressors ``B_end``, output ``y_end``) best, by RMSE
    or, with ``loss="huber"``, by the Huber cost (threshold ``delta``, ``None``: the default),
    among those that fit the data they fitted within :data:`PREISACH_FIT_TOLERANCE` of the
    fit without the prior: ``(strength, history)``."""
    errors: list[float] = []
    fits: list[float] = []
    for strength in PREISACH_SMOOTHINGS:
        z = _gram_nnls(G + strength * unit_penalty if strength else G, b, free)
        r = B_end @ z - y_end
        errors.append(float(huber_cost(r, delta)) if loss == "huber" else float(np.sqrt(np.mean(r * r))))
        # its residual on the data it fitted, from the Gram matrix: ||B z - y||^2 = z'Gz - 2 b'z + y'y
        fits.append(float(np.sqrt(max(float(z @ G @ z - 2.0 * (b @ z)) + yy, 0.0))))
    # the prior is to decide what the record leaves open, not to overrule what it shows: a
    # strength whose fit misses the fitted data by more than PREISACH_FIT_TOLERANCE over the
    # fit without the prior is no candidate (one cycle of a periodic record: its hold-out is
    # the part of the loop the rest never ran, which any prior predicts better)
    ok = np.array(fits) <= (1.0 + PREISACH_FIT_TOLERANCE) * fits[0]
    best = int(np.argmin(np.where(ok, errors, np.inf)))
    return float(PREISACH_SMOOTHINGS[best]), {
        "smoothing_grid": np.array(PREISACH_SMOOTHINGS),
        "smoothing_holdout_error": np.array(errors),
        "smoothing_fit_error": np.array(fits) / np.sqrt(n_fit),
    }


def _diagonal_smoothness(levels: int, column: npt.NDArray[np.intp], p: int) -> FloatArray:
    """``D^T D`` (``p x p``) of the first differences ``w[i, j] - w[i + 1, j + 1]`` along the
    diagonals of a Preisach grid, cell ``c`` (row order) being unknown ``column[c]`` (``-1``:
    not an unknown, its differences are left out; two cells of one unknown differ by 0)."""
    i, j = np.tril_indices(levels)
    inner = i + 1 < levels
    a = column[(i * (i + 1) // 2 + j)[inner]]
    b = column[((i + 1) * (i + 2) // 2 + j + 1)[inner]]
    keep = (a >= 0) & (b >= 0) & (a != b)
    a, b = a[keep], b[keep]
    DD = np.zeros((p, p))
    np.add.at(DD, (a, a), 1.0)
    np.add.at(DD, (b, b), 1.0)
    np.add.at(DD, (a, b), -1.0)
    np.add.at(DD, (b, a), -1.0)
    return DD


def _bounded_lstsq_gram(
    A: FloatArray, y: FloatArray, bounds: tuple[FloatArray, FloatArray], penalty: FloatArray | None = None
) -> FloatArray:
    """``argmin ||A z - y||^2 (+ z^T penalty z)`` with ``z >= lower`` (lower 0 or ``-inf``; no
    upper bounds), for a tall ``A`` of equilibrated, distinct columns: through the Cholesky
    factor ``R`` of the Gram matrix (``A^T A + penalty = R^T R``, ``R^T d = A^T y``; same
    minimizer, ``p x p``), the unbounded columns projected out and SciPy's NNLS on the rest. A
    Gram matrix that is numerically singular gets a ridge of ``1e-10`` of its mean diagonal
    (columns nearly collinear: any split of their weight fits the record as well)."""
    G = A.T @ A
    if penalty is not None:
        G = G + penalty
    return _gram_nnls(G, A.T @ y, np.isneginf(bounds[0]))


def _gram_nnls(G: FloatArray, b: FloatArray, free: npt.NDArray[np.bool_]) -> FloatArray:
    """``argmin z^T G z - 2 b^T z`` with ``z[~free] >= 0`` for a Gram matrix ``G``
    (:func:`_bounded_lstsq_gram`): Cholesky (with a ridge when numerically singular), then
    :func:`_mixed_nnls`."""
    from scipy.linalg import LinAlgError, cholesky, solve_triangular

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
    stol: float = 0.0,
) -> tuple[FloatArray, int]:
    """Huber M-estimate by iteratively reweighted bounded least squares from ``z``:
    ``(z, solves)``, the solves being the reweighted problems ``solve`` was given.

    Stops when an iteration moves the fitted output by less than ``rtol`` times the output's
    range (RMS): the parameters of correlated regressors creep on long after the fit has
    settled; or, with ``stol > 0``, by less than ``stol`` times the Huber threshold (the
    residuals' robust scale). The Huber cost is stationary in ``z`` at the fixed point, so a
    fit ``stol`` of the scale away from it costs about ``stol**2`` more, relatively: a search
    that only ranks candidates by cost stops at ``stol = 1e-3`` (4 to 6 solves from a warm
    start instead of about 15)."""
    lower, upper = bounds
    span = float(np.ptp(y)) or 1.0
    fit = A @ z
    solves = 0
    for _ in range(max_iterations):
        r = fit - y
        d = _huber_threshold(r, delta, span)
        w = _huber_sqrt_weights(r, d, span)
        z = np.clip(solve(A * w[:, None], y * w, bounds), lower, upper)  # bvls may overstep a bound by an ulp
        solves += 1
        new_fit = A @ z
        moved = float(np.sqrt(np.mean((new_fit - fit) ** 2)))
        fit = new_fit
        if moved <= max(rtol * span, stol * d):
            break
    return z, solves


def _qr_bounded_lstsq(A: FloatArray, y: FloatArray, bounds: tuple[FloatArray, FloatArray]) -> FloatArray:
    """``argmin ||A z - y||`` within ``bounds`` through the QR factors of ``A`` (``A = Q R``,
    the same minimizer as ``min ||R z - Q^T y||``, ``p x p``, without squaring the
    conditioning as the Gram matrix does): the unbounded solution when it respects the bounds,
    else :func:`_mixed_nnls` when the bounds are ``0`` or ``-inf`` below and ``inf`` above (the
    linear families' layout); :func:`_bvls` on ``A`` otherwise or when ``R`` is numerically
    singular. The Huber IRLS of the final fit takes it: one QR of ``N x p`` a reweighted
    problem, where SciPy's BVLS repeats dense least squares (SVD) on the whole record."""
    from scipy.linalg import qr, solve_triangular

    lower, upper = bounds
    free = np.isneginf(lower)
    if not (np.all(np.isposinf(upper)) and np.all(free | (lower == 0.0)) and A.shape[0] >= A.shape[1]):
        return _bvls(A, y, bounds)
    Q, R_ = qr(A, mode="economic", check_finite=False)
    R: FloatArray = np.asarray(R_, dtype=np.float64)
    rdiag = np.abs(np.diag(R))
    if not (np.all(np.isfinite(R)) and rdiag.min() > 1e-10 * rdiag.max()):
        return _bvls(A, y, bounds)
    d = np.asarray(Q.T @ y, dtype=np.float64)
    z: FloatArray = solve_triangular(R, d, check_finite=False)
    return z if np.all(z >= lower) else _mixed_nnls(R, d, free)


def _huber_threshold(r: FloatArray, delta: float | None, span: float) -> float:
    """The Huber threshold of residuals ``r``: ``delta``, or :func:`default_huber_delta` of
    ``r``, at least ``1e-15`` of the output's range ``span`` (a zero MAD, an exact majority,
    still weighs)."""
    return max(float(default_huber_delta(r)) if delta is None else delta, 1e-15 * span)


def _huber_sqrt_weights(r: FloatArray, delta: float | None, span: float) -> FloatArray:
    """The square roots of the Huber IRLS weights ``min(1, d / |r|)`` of residuals ``r``
    (``d``: :func:`_huber_threshold`)."""
    d = _huber_threshold(r, delta, span)
    w: FloatArray = np.sqrt(np.minimum(1.0, d / np.maximum(np.abs(r), 1e-15 * span)))
    return w


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
    ``huber_delta``, ``offset``: see :func:`fit_linear`).

    Parameters
    ----------
    input, output : array_like
        The record, equal lengths.
    operators : int
        Number of play operators when ``thresholds`` is not given.
    thresholds : array_like, optional
        The play thresholds.
    creep : Creep, optional
        Creep lags (their weights are fitted too).
    loss : {"squared", "huber"}
        The fit's cost.
    huber_delta : float, optional
        Huber threshold in the output's unit.
    offset : bool
        Fit an output offset (the model's output map).

    Returns
    -------
    FitResult

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst import PI, identify_pi
    >>> v = np.sin(np.linspace(0, 12, 1200)) * np.linspace(1, 0.3, 1200)
    >>> y = PI([0.1, 0.3], [0.5, 0.2], p0=0.8).simulate(v) + 2.0       # a sensor zero of 2
    >>> fit = identify_pi(v, y, thresholds=[0.1, 0.3])
    >>> np.round(fit.model.weights, 9).tolist(), round(fit.model.p0, 9), round(fit.model.output_map.offset, 9)
    ([0.5, 0.2], 0.8, 2.0)
    """
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
    ``huber_delta``, ``offset``: see :func:`fit_linear`).

    Parameters
    ----------
    input, output : array_like
        The record, equal lengths.
    operators : int
        Number of generalized plays when ``thresholds`` is not given.
    thresholds : array_like, optional
        The play thresholds.
    rising, falling : Envelope, optional
        The envelopes (identity by default; :func:`identify` with ``structure="fit"`` fits them).
    creep : Creep, optional
        Creep lags (their weights are fitted too).
    loss : {"squared", "huber"}
        The fit's cost.
    huber_delta : float, optional
        Huber threshold in the output's unit.
    offset : bool
        Fit an output offset (held in the polynomial's constant term).

    Returns
    -------
    FitResult

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst import identify_mpi
    >>> from piezohyst.papers import mpi_seed2
    >>> v = 0.5 + 0.45 * np.sin(np.linspace(0, 12, 1200)) * np.linspace(1, 0.3, 1200)
    >>> fit = identify_mpi(v, mpi_seed2().simulate(v), thresholds=mpi_seed2().thresholds)
    >>> bool(fit.metrics["rmse"] < 1e-9), type(fit.model).__name__
    (True, 'GeneralizedPI')
    """
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
    memory: int = PREISACH_MEMORY,
    loss: str = "squared",
    huber_delta: float | None = None,
    offset: bool = True,
    smoothing: float | None = None,
) -> FitResult:
    """Discretized Preisach on a ``levels x levels`` grid over the input range; offset, slope
    and cell weights (non-negative) by least squares (``loss``, ``huber_delta``, ``offset``,
    ``smoothing``: see :func:`fit_linear`).

    Parameters
    ----------
    input, output : array_like
        The record, equal lengths.
    levels : int
        Grid levels per axis (``levels (levels + 1) / 2`` cells).
    input_range : (float, float), optional
        The grid's edges (default: the input's range).
    memory : int
        Dominant extrema the model keeps (2..256; by default the most, :data:`PREISACH_MEMORY`).
    loss : {"squared", "huber"}
        The fit's cost.
    huber_delta : float, optional
        Huber threshold in the output's unit.
    offset : bool
        Fit an output offset (held in the model's own ``offset``).
    smoothing : float, optional
        Strength of the smoothness prior along the grid's diagonals (default: chosen by
        hold-out on the training record).

    Returns
    -------
    FitResult

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst import Preisach, identify_preisach
    >>> v = np.sin(np.linspace(0, 12, 1200)) * np.linspace(1, 0.3, 1200)
    >>> truth = Preisach(6, (-1.0, 1.0), np.linspace(0.1, 1.0, 21), slope=0.5)
    >>> fit = identify_preisach(v, truth.simulate(v), levels=6, input_range=(-1.0, 1.0))
    >>> round(fit.metrics["rmse_percent"], 2)          # % of the output range
    0.4
    """
    t0 = time.perf_counter()
    v = as_record(input, "input", min_length=2)
    model = _preisach_template(v, levels, input_range, memory)
    name, delta = _check_loss(loss, huber_delta)
    return _fit_output(model, v, output, name, delta, t0, offset, smoothing)


def _preisach_template(
    v: FloatArray, levels: int, input_range: tuple[float, float] | None, memory: int, creep: Creep | None = None
) -> Preisach:
    lo, hi = (float(v.min()), float(v.max())) if input_range is None else input_range
    n = as_int(levels, "levels", minimum=1)
    return Preisach(n, (lo, hi), np.zeros(n * (n + 1) // 2), memory=memory, creep=creep)


@dataclass(frozen=True)
class IdentificationResult(RunReport):
    """What :func:`identify` returns: the model, its free-run metrics on the training record
    (and the validation record when given), the optimizer history and the wall time.

    As every :class:`~piezohyst.optimize.RunReport`: ``wall_time`` (s), ``evaluations``
    (the candidate evaluations the fit spent: the optimizer's ``nfev`` plus the polish's, or
    the least-squares solves of a linear fit), ``history`` (the optimizer's per-iteration
    history with the method's extras; empty for a linear fit) and ``partial`` (Ctrl-C
    stopped the optimizer: the model is the best found before it).

    Parameters
    ----------
    model : object
        The identified model (a :class:`~piezohyst.models.HysteresisModel`, a
        :class:`~piezohyst.models.BoucWenBenchmark` or, for ``cemf``, the
        :class:`~piezohyst.plant.StageParameters`).
    train : dict
        Free-run metrics on the training record (:func:`fit_metrics`).
    validation : dict or None
        The same on the validation record, when given.
    method : str
        How it was fitted (``"ls"``, ``"vp-de+polish"``, ``"css"``, ...).
    wall_time : float
        Seconds the identification took.
    history : dict
        The optimizer's per-iteration history (empty for a linear fit).
    simulator : callable, optional
        How :meth:`simulate` predicts the output for models without a ``simulate(input)``.
    partial : bool
        Ctrl-C stopped the optimizer.
    evaluations : int
        Candidate evaluations the fit spent.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst import PI, identify
    >>> v = np.sin(np.linspace(0, 24, 2400)) * np.linspace(1, 0.3, 2400)
    >>> y = PI([0.2, 0.4], [0.5, 0.2], p0=0.8).simulate(v)
    >>> res = identify(v[:1200], y[:1200], "pi", operators=4, validate=(v[1200:], y[1200:]))
    >>> res.method, sorted(res.metrics), bool(res.metrics["validation"]["rmse_percent"] < 5)
    ('ls', ['train', 'validation'], True)
    """

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

    def _scores(self) -> dict[str, float]:
        spans = {"train": self.train, "validation": self.validation}
        return {
            f"{span} {label} (% of range)": m[key]
            for span, m in spans.items()
            if m is not None
            for label, key in (("rmse", "rmse_percent"), ("max error", "max_error_percent"))
            if key in m
        }

    def simulate(self, input: npt.ArrayLike) -> FloatArray:
        """The identified model's free-run output for an input record (for ``cemf``: positions
        from voltages, the stage simulated as it was identified).

        Parameters
        ----------
        input : array_like
            The input record.

        Returns
        -------
        ndarray

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst import PI, identify
        >>> v = np.sin(np.linspace(0, 12, 1200))
        >>> res = identify(v, PI([0.2], [0.5], p0=0.8).simulate(v), "pi", operators=3)
        >>> bool(np.allclose(res.simulate(v), res.model.simulate(v)))
        True
        """
        if self.simulator is not None:
            return np.asarray(self.simulator(as_record(input, "input")))
        if not isinstance(self.model, _Simulates):
            raise ParameterTypeError(f"{type(self.model).__name__} has no simulate(input) and no simulator was given")
        return self.model.simulate(input)

    @property
    def metrics(self) -> dict[str, Metrics | None]:
        """``{"train": ..., "validation": ...}`` (validation ``None`` without held-out data)."""
        return {"train": self.train, "validation": self.validation}

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready report (the model file's ``fit`` section).

        Returns
        -------
        dict

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst import PI, identify
        >>> v = np.sin(np.linspace(0, 12, 1200))
        >>> d = identify(v, PI([0.2], [0.5], p0=0.8).simulate(v), "pi", operators=3).to_dict()
        >>> sorted(d)
        ['method', 'partial', 'train', 'validation', 'wall_time_s']
        """
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
        a record, the optimizer's convergence (:meth:`RunReport.plot`, on ``ax`` if given).

        Parameters
        ----------
        input, output : array_like, optional
            A record to compare the model with (both, or neither).
        ax : matplotlib.axes.Axes, optional
            Axes of the convergence plot.

        Returns
        -------
        matplotlib.figure.Figure

        Examples
        --------
        >>> import numpy as np
        >>> import matplotlib.pyplot as plt
        >>> from piezohyst import PI, identify
        >>> v = np.sin(np.linspace(0, 12, 1200))
        >>> y = PI([0.2], [0.5], p0=0.8).simulate(v)
        >>> fig = identify(v, y, "pi", operators=3).plot(v, y)
        >>> [a.get_title() for a in fig.axes]
        ['hysteresis loop', 'fit', 'residual']
        >>> plt.close(fig)
        """
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


def _huber_location(residuals: FloatArray, delta: npt.ArrayLike) -> FloatArray:
    """The constant ``c`` that minimizes ``huber_cost(r - c, delta)``, per row.

    Safeguarded Newton steps from the median on the cost's derivative (piecewise linear, so
    a step that keeps the inlier set is exact), bisection when a step leaves the bracket.
    Unlike the median, ``c`` moves smoothly with the residuals: the profiled cost stays
    differentiable for the gradient polish, and with Gaussian residuals ``c`` is as efficient
    as the mean (95 % at ``delta = 1.345 sigma``; the median: 64 %)."""
    r = np.asarray(residuals, dtype=np.float64)
    d = np.asarray(delta, dtype=np.float64)
    d = np.expand_dims(d, -1) if np.ndim(d) else d
    lo, hi = r.min(axis=-1, keepdims=True), r.max(axis=-1, keepdims=True)
    c = np.median(r, axis=-1, keepdims=True)
    tol = 1e-14 * np.maximum(np.abs(lo), np.abs(hi))
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        for _ in range(100):
            e = r - c
            slope = np.clip(e, -d, d).sum(axis=-1, keepdims=True)  # -d cost / d c, up to a factor
            lo, hi = np.where(slope > 0, c, lo), np.where(slope < 0, c, hi)
            inside = (np.abs(e) < d).sum(axis=-1, keepdims=True)
            step = slope / inside
            new = np.where((inside > 0) & (c + step > lo) & (c + step < hi), c + step, 0.5 * (lo + hi))
            new = np.where(slope == 0, c, new)
            done = np.abs(new - c) <= tol
            c = new
            if np.all(done | ~np.isfinite(c)):
                break
    return np.asarray(c[..., 0], dtype=np.float64)


def minimize_huber(
    simulate: Callable[[FloatArray], FloatArray],
    target: FloatArray,
    bounds: Sequence[tuple[float, float]],
    delta: float | None = None,
    *,
    offset: bool = False,
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

    Parameters
    ----------
    simulate : callable
        ``simulate(X) -> outputs``: ``(S, D)`` candidates to ``(S, N)`` outputs.
    target : ndarray, shape (N,)
        The output to match.
    bounds : sequence of (float, float)
        The search box.
    delta : float, optional
        A fixed Huber threshold (default: the two-stage search above).
    offset : bool
        Score every candidate with its best constant output offset for the threshold in use
        (the Huber location M-estimate, projected out: the search runs over the shape alone);
        ``history["offset"]`` holds the best candidate's.
    **search
        Options of :func:`piezohyst.optimize.minimize`.

    Returns
    -------
    OptimizeResult
        ``fun`` is the final fixed-threshold Huber cost; ``history["best_cost"]`` holds the
        search's costs; ``history["huber_delta"]`` the threshold used.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.identify import minimize_huber
    >>> t = np.linspace(0.0, 1.0, 200)
    >>> target = 2.0 * t
    >>> target[::50] += 10.0                                  # glitches
    >>> res = minimize_huber(lambda X: X[:, :1] * t, target, [(0.0, 5.0)], rng=0, max_iterations=30)
    >>> round(float(res.x[0]), 3)                             # the slope, unmoved by the glitches
    2.0
    """
    from dataclasses import replace

    from ..optimize.core import minimize, polish_lbfgsb

    def residuals(X: FloatArray, threshold: float | None) -> FloatArray:
        r = simulate(X) - target
        if offset:
            scale = default_huber_delta(r) if threshold is None else threshold
            r = r - _huber_location(r, scale)[..., None]
        return r

    def fixed(X: FloatArray) -> FloatArray:
        return huber_cost(residuals(X, delta), delta)

    def best_offset(x: FloatArray, threshold: float) -> float:
        r = simulate(x[None, :])[0] - target
        return -float(_huber_location(r, threshold)) if offset else 0.0

    if delta is not None:
        res = minimize(fixed, bounds, polish=True, **search)
        found = {"huber_delta": float(delta), "offset": best_offset(np.asarray(res.x, dtype=np.float64), delta)}
        return replace(res, history={**res.history, **found})
    res = minimize(lambda X: huber_cost(residuals(X, None)), bounds, **search)
    x0 = np.array(res.x, dtype=np.float64)
    r0 = residuals(x0[None, :], None)[0]
    if res.message == "interrupted" or not np.all(np.isfinite(r0)):
        return replace(res, history={**res.history, "huber_delta": float("nan"), "offset": float("nan")})
    tiny = 1e-15 * (float(np.max(np.abs(target))) or 1.0)  # an exact majority leaves MAD = 0
    threshold = max(float(default_huber_delta(r0)), tiny)
    delta = threshold
    lower, upper = np.array(bounds, dtype=np.float64).T
    x, f, n = polish_lbfgsb(fixed, x0, float(fixed(x0[None, :])[0]), lower, upper, {})
    message = f"{res.message}; Huber threshold {threshold:.6g} from the MAD, then L-BFGS-B to {f:.6g}"
    found = {"huber_delta": threshold, "offset": best_offset(x, threshold)}
    return replace(res, x=x, fun=f, nfev=res.nfev + n + 1, message=message, history={**res.history, **found})


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

    Parameters
    ----------
    voltage : array_like
        The voltage across the stack, V per sample.
    position : array_like
        The measured displacement, m (same length).
    fs : float
        Sample rate, Hz.
    capacitance : float
        The stack's capacitance ``Cz``, F, taken as known.
    bounds : sequence of (float, float), optional
        Search box of ``CEMF_PARAMETERS`` (default: scaled from the record's gain and a
        resonance between 1 and 20 kHz).
    optimizer : {"css", "pso", "mpso", "de"}
        The population optimizer.
    rng : int, numpy.random.Generator or None
        Same seed, same result.
    max_iterations : int
        Populations evaluated.
    population_size : int, optional
        Candidates per population.
    substeps : int
        Integration sub-steps per sample of the simulated stage.
    tolerance : float
        Refinement tolerance of the simulated stage.
    validate : (array_like, array_like), optional
        A held-out ``(voltage, position)`` record.
    progress : bool
        Show a progress bar on stderr.
    callback : callable, optional
        ``callback(intermediate_result)`` after each iteration.
    loss : {"squared", "huber"}
        The cost.
    huber_delta : float, optional
        Huber threshold in m.
    polish : bool
        Continue with SciPy's ``least_squares`` (squared loss only).

    Returns
    -------
    IdentificationResult
        Its ``model`` is a :class:`piezohyst.StageParameters`; its ``simulate`` predicts
        positions from voltages with the identified stage; ``evaluations`` counts the
        search's simulations and the polish's.

    Examples
    --------
    >>> import numpy as np
    >>> import piezohyst as ph
    >>> from piezohyst.plant import excitation, measure
    >>> stage = ph.virtual_stage()
    >>> u, y = measure(stage, excitation(1e4, seconds=0.2), np.random.default_rng(0))
    >>> res = ph.identify_cemf(u, y, 1e4, rng=0, max_iterations=5, population_size=10)
    >>> type(res.model).__name__, res.method, res.evaluations
    ('StageParameters', 'css', 50)
    """
    from ..optimize.core import minimize
    from ..plant.stage import Amplifier, Stage, StageParameters

    t0 = time.perf_counter()
    name, delta = _check_loss(loss, huber_delta)
    u = as_record(voltage, "voltage", min_length=2)
    x = as_record(position, "position", min_length=2)
    if x.size != u.size:
        raise ParameterError(f"position has {x.size} samples, voltage has {u.size}; they must match")
    check_fit_scale(u, "voltage")
    check_fit_scale(x, "position")
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
    check_samples(u.size, sum(lo < hi for lo, hi in box), "the CEMF stage model")
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
