"""Variable projection for the PI family (docs/spec.md §4): a population optimizer over the few
nonlinear structure parameters, an exact bounded least-squares solve over the linear ones.

For a fixed structure (thresholds, envelopes, rate terms, creep time constants) the output
of a PI, GPI/MPI or rate-dependent PI model is linear in its weights and polynomial
coefficients: ``y = A(theta) w`` with the regressors ``A(theta)`` computed by the Rust core
in one pass over the record. Variable projection eliminates ``w``: for every candidate
``theta`` of the population the weights are the bounded least-squares solution (play weights
non-negative, as :func:`piezohyst.fit_linear`), and the candidate's cost is the free-run RMSE
of the model so fitted. The regressors are the operator outputs of a free run (no measured
output is fed back), so ``A(theta) w`` *is* the model's free-run simulation and its RMSE is
the simulation error, computed without a second pass.

The nonlinear parameters (names of :func:`vp_parameters`), all dimensionless or in seconds:

``spread``
    The largest play threshold as a fraction of the training input's span; the ``n``
    thresholds are ``r_i = (i / n) * spread * span``. The fixed default structure of
    :func:`piezohyst.identify` is ``spread = n / (2 (n + 1))``.
Envelopes (``gpi``/``mpi``), in the normalized input ``u = (v - c) / h`` of the training
record (``c`` its mid-range, ``h`` its half span, so ``u`` runs over ``[-1, 1]``); an envelope
is ``g(v) = c + h e(u)``:
    ``envelope="polynomial"``: the rising envelope is
    ``e_l(u) = u + q2 (u^2 - 1) + q3 (u^3 - u)`` (``rising_q2``, ``rising_q3``): it maps the
    training range onto itself, which pins the common offset and scale of the two envelopes
    (a common offset is absorbed by the polynomial's constant, a common scale by the
    thresholds); the falling envelope is ``e_r(u) = offset + scale (u + q2 (u^2 - 1) +
    q3 (u^3 - u))`` (``falling_offset``, ``falling_scale``, ``falling_q2``, ``falling_q3``).
    ``q2 = q3 = 0``, ``offset = 0``, ``scale = 1`` is the identity envelope.

    ``envelope="tanh"``: the same with the shape ``s(u) = -1 + 2 (tanh(a u + b) -
    tanh(b - a)) / (tanh(a + b) - tanh(b - a))`` (``rising_steepness`` ``a > 0``,
    ``rising_center`` ``b``; likewise ``falling_...``), which tends to the identity as
    ``a -> 0``.

    ``envelope="identity"``: no envelope parameters.
``beta``, ``filter_tau`` (``rdpi``)
    Threshold growth per unit input rate (s) and the rate's low-pass time constant (s).
``log10_tau_1`` ... (``creep=m``)
    ``log10`` of the creep lags' time constants in seconds; by default each searches its own
    band of ``[log10(2 Ts), log10(T)]`` (``T`` the record's duration) split into ``m`` equal
    bands, which keeps them ordered and distinct.

Candidates whose envelopes are not increasing on the model's input range (the training range
padded by 10 % of its span on each side) or cross there cost ``inf``: the optimizer rejects
them. The best candidate of the population search is polished by SciPy's ``least_squares``
(trust-region reflective, inside the bounds) on the residual vector ``A(theta) w(theta) - y``
with finite-difference Jacobians: Gauss–Newton on the projected functional, the classical
variable-projection step (Golub & Pereyra), which converges fast on zero-residual records.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any, Literal, TypeAlias

import numpy as np
import numpy.typing as npt

from .._validate import as_int, as_record, as_scalar
from ..errors import ParameterError, ParameterTypeError
from ..models.creep import Creep
from ..models.pi import PI, Envelope, GeneralizedPI, RateDependentPI
from .core import _one_blas_thread

if TYPE_CHECKING:  # pragma: no cover - typing only
    from .core import Callback, IdentificationResult, LinearModel, RngLike

__all__ = ["ENVELOPES", "VP_KINDS", "identify_vp", "vp_parameters"]

#: Model kinds :func:`identify_vp` fits.
VP_KINDS = ("pi", "gpi", "mpi", "rdpi")

#: Envelope parametrizations of the ``gpi``/``mpi`` search.
ENVELOPES = ("polynomial", "tanh", "identity")

#: Padding of the envelopes' checked input range, a fraction of the training span per side.
PAD = 0.1

#: Population iterations when ``max_iterations`` is not given.
DEFAULT_ITERATIONS = 60

FloatArray: TypeAlias = npt.NDArray[np.float64]
#: A parameter's hard domain ``(lo, hi, lo_open)``, ``None`` for the whole real line.
_Domain: TypeAlias = tuple[float, float, bool] | None
#: A row of the parameter table: ``(name, default lower, default upper, domain)``.
_Row: TypeAlias = tuple[str, float, float, _Domain]
#: Bounds the caller gives: ``{name: (lower, upper) or value}``.
BoundsSpec: TypeAlias = Mapping[str, Any]

# (name, default lower, default upper, hard domain (lo, hi, lo_open)) per parameter group
_SPREAD: list[_Row] = [("spread", 0.1, 1.0, (0.0, math.inf, True))]
_POLY_RISING: list[_Row] = [("rising_q2", -0.5, 0.5, None), ("rising_q3", -0.5, 0.5, None)]
_POLY_FALLING: list[_Row] = [
    ("falling_offset", -0.3, 0.3, None),
    ("falling_scale", 0.7, 1.3, (0.0, math.inf, True)),
    ("falling_q2", -0.5, 0.5, None),
    ("falling_q3", -0.5, 0.5, None),
]
_TANH_RISING: list[_Row] = [("rising_steepness", 0.05, 3.0, (0.0, math.inf, True)), ("rising_center", -1.5, 1.5, None)]
_TANH_FALLING: list[_Row] = [
    ("falling_offset", -0.3, 0.3, None),
    ("falling_scale", 0.7, 1.3, (0.0, math.inf, True)),
    ("falling_steepness", 0.05, 3.0, (0.0, math.inf, True)),
    ("falling_center", -1.5, 1.5, None),
]


def _tanh_shape_coefficients(
    a: float, b: float, offset: float, scale: float, c: float, h: float
) -> tuple[float, float, float, float]:
    """``Envelope.tanh`` coefficients of ``g(v) = c + h (offset + scale s(u))``, ``u = (v - c) / h``,
    ``s(u) = -1 + 2 (tanh(a u + b) - t0) / (t1 - t0)``, ``t0 = tanh(b - a)``, ``t1 = tanh(a + b)``."""
    t0, t1 = math.tanh(b - a), math.tanh(a + b)
    d = t1 - t0
    if not d > 0:
        raise ParameterError("tanh envelope: flat on the training range")
    k = 2.0 * h * scale / d
    return (k, a / h, b - a * c / h, c + h * (offset - scale) - k * t0)


def _poly_shape_coefficients(
    q2: float, q3: float, offset: float, scale: float, c: float, h: float
) -> tuple[float, float, float, float]:
    """``Envelope.polynomial`` coefficients of ``g(v) = c + h (offset + scale (u + q2 (u^2 - 1) +
    q3 (u^3 - u)))`` with ``u = (v - c) / h``, expanded in ``v``."""
    e0, e1, e2, e3 = offset - scale * q2, scale * (1.0 - q3), scale * q2, scale * q3
    al, be = 1.0 / h, -c / h
    return (
        c + h * (e0 + e1 * be + e2 * be**2 + e3 * be**3),
        h * (e1 * al + 2 * e2 * al * be + 3 * e3 * al * be**2),
        h * (e2 * al**2 + 3 * e3 * al**2 * be),
        h * e3 * al**3,
    )


def vp_parameters(model: str = "mpi", *, envelope: str = "polynomial", creep: int = 0) -> tuple[str, ...]:
    """Names of the nonlinear parameters :func:`identify_vp` searches, in order.

    Parameters
    ----------
    model : str, default "mpi"
        The model family (one of :data:`VP_KINDS`).
    envelope : str, default "polynomial"
        The envelope of a generalized or modified PI model (one of :data:`ENVELOPES`).
    creep : int, default 0
        Number of creep time constants (rate-dependent PI).

    Returns
    -------
    tuple of str

    Examples
    --------
    >>> from piezohyst.varpro import vp_parameters
    >>> vp_parameters("mpi")
    ('spread', 'rising_q2', 'rising_q3', 'falling_offset', 'falling_scale', 'falling_q2', 'falling_q3')
    >>> vp_parameters("rdpi", creep=2)
    ('spread', 'beta', 'filter_tau', 'log10_tau_1', 'log10_tau_2')
    """
    return tuple(p[0] for p in _groups(model, envelope, creep, None))


def _groups(model: str, envelope: str, creep: int, scales: dict[str, float] | None) -> list[_Row]:
    """The parameter table ``[(name, lower, upper, domain)]`` with data-scaled defaults."""
    if model not in VP_KINDS:
        raise ParameterError(
            f"model = {model!r} has no structure to fit by variable projection; expected one of {list(VP_KINDS)}"
        )
    if envelope not in ENVELOPES:
        raise ParameterError(f"envelope = {envelope!r} is unknown; expected one of {list(ENVELOPES)}")
    table = list(_SPREAD)
    if model in ("gpi", "mpi"):
        if envelope == "polynomial":
            table += _POLY_RISING + _POLY_FALLING
        elif envelope == "tanh":
            table += _TANH_RISING + _TANH_FALLING
    if model == "rdpi":
        beta_hi, tau_hi = (1.0, 1.0) if scales is None else (scales["beta_max"], scales["tau_max"])
        table += [("beta", 0.0, beta_hi, (0.0, math.inf, False)), ("filter_tau", 0.0, tau_hi, (0.0, math.inf, False))]
    if creep:
        lo, hi = (-3.0, 0.0) if scales is None else (scales["log_tau_min"], scales["log_tau_max"])
        w = (hi - lo) / creep
        table += [(f"log10_tau_{j + 1}", lo + j * w, lo + (j + 1) * w, None) for j in range(creep)]
    return table


def _search_box(
    table: list[_Row], bounds: BoundsSpec | None
) -> tuple[list[str], FloatArray, FloatArray, dict[str, float]]:
    """``(names, lower, upper, fixed)`` from the default table and the user's ``bounds``
    mapping ``{name: (lower, upper) or value}``, checked with messages naming the entry."""
    names = [t[0] for t in table]
    lower = {t[0]: t[1] for t in table}
    upper = {t[0]: t[2] for t in table}
    fixed: dict[str, float] = {}
    if bounds is not None:
        if not isinstance(bounds, dict):
            raise ParameterTypeError(
                f"bounds must be a dict {{name: (lower, upper) or value}}, got {type(bounds).__name__}"
            )
        unknown = sorted(set(bounds) - set(names), key=str)
        if unknown:
            raise ParameterError(
                f"bounds: {unknown[0]!r} is not a parameter of this search; expected names among {names}"
            )
        for name, b in bounds.items():
            if isinstance(b, (tuple, list, np.ndarray)):
                if len(b) != 2:
                    raise ParameterError(f"bounds[{name!r}] = {b!r} must be a (lower, upper) pair or a value")
                lo = as_scalar(b[0], f"bounds[{name!r}] lower")
                hi = as_scalar(b[1], f"bounds[{name!r}] upper")
                if lo > hi:
                    raise ParameterError(f"bounds[{name!r}] = ({lo}, {hi}): lower > upper")
                if lo == hi:
                    fixed[name] = lo
                else:
                    lower[name], upper[name] = lo, hi
            else:
                fixed[name] = as_scalar(b, f"bounds[{name!r}]")
    for name, _, _, domain in table:
        if domain is None:
            continue
        dlo, dhi, open_lo = domain
        vals = [fixed[name]] if name in fixed else [lower[name], upper[name]]
        for x in vals:
            if x < dlo or (open_lo and x == dlo) or x > dhi:
                rel = ">" if open_lo else ">="
                raise ParameterError(
                    f"bounds[{name!r}]: {x} is outside the parameter's domain ({name} must be {rel} {dlo})"
                )
    free = [n for n in names if n not in fixed]
    if not free:
        raise ParameterError(
            "bounds fixes every parameter; nothing to search (use identify(..., structure='fixed') "
            "or leave a parameter free)"
        )
    return free, np.array([lower[n] for n in free]), np.array([upper[n] for n in free]), fixed


class _Problem:
    """The projected problem: candidate structure -> template model -> regressors -> weights."""

    #: Fit an output offset (a constant regressor, :func:`piezohyst.identify.core._design`).
    offset: bool = False
    #: Huber loss, the population search: a candidate's linear parameters are one weighted
    #: least-squares solve with the Huber weights of the best candidate so far (``robust``)
    #: instead of an IRLS to convergence (about 15 solves). Its cost, the Huber cost of that
    #: fit, is an achievable cost, so an upper bound of the candidate's projected cost; the
    #: bound is exact to second order in the weights' change, as the cost is stationary at
    #: the IRLS fixed point, and the glitches the weights hold down are the same samples for
    #: every structure. The first candidate, with no weights yet, runs the IRLS (to 1e-3 of
    #: the Huber threshold). Outside the search (the polish, whose finite-difference Jacobian
    #: needs the residual to rounding): the IRLS to convergence from those weights.
    search: bool = False
    #: Huber loss: the lowest cost seen and the square roots of its IRLS weights, each
    #: candidate's warm start.
    best: float = math.inf
    robust: FloatArray | None = None

    def __init__(
        self,
        model: str,
        v: FloatArray,
        y: FloatArray,
        fs: float | None,
        operators: int,
        envelope: str,
        creep: int,
        loss: str,
        delta: float | None,
    ):
        self.model, self.v, self.y, self.envelope, self.creep = model, v, y, envelope, creep
        self.loss, self.delta = loss, delta
        self.n = operators
        self.ts = None if fs is None else 1.0 / fs
        lo, hi = float(v.min()), float(v.max())
        self.span = hi - lo
        self.c, self.h = 0.5 * (lo + hi), 0.5 * (hi - lo)
        self.input_range = (lo - PAD * self.span, hi + PAD * self.span)
        self.yspan = float(np.ptp(y)) or 1.0
        scales = None
        if self.ts is not None:
            duration = v.size * self.ts
            rate = np.abs(np.diff(v)) / self.ts
            rmax = float(rate.max()) if rate.size else 0.0
            scales = {
                "beta_max": 0.5 * self.span / rmax if rmax > 0 else 1.0,
                "tau_max": min(50.0 * self.ts, 0.1 * duration),
                "log_tau_min": math.log10(2.0 * self.ts),
                "log_tau_max": math.log10(duration),
            }
        self.table = _groups(model, envelope, creep, scales)
        self.names = [t[0] for t in self.table]

    def _sample_time(self) -> float:
        if self.ts is None:  # identify_vp requires ts for rdpi and creep before building this
            raise ParameterError("ts is required for a rate-dependent model or creep terms")
        return self.ts

    def template(self, p: dict[str, float]) -> LinearModel:
        """The model of structure ``p`` (a dict of every parameter) with zero linear part;
        ``ValueError`` when the structure is invalid."""
        r = np.arange(1, self.n + 1, dtype=np.float64) * (p["spread"] * self.span / self.n)
        creep = None
        if self.creep:
            taus = 10.0 ** np.array([p[f"log10_tau_{j + 1}"] for j in range(self.creep)])
            creep = Creep(self._sample_time(), taus, np.zeros(self.creep))
        zeros = np.zeros(self.n)
        if self.model == "pi":
            return PI(r, zeros, 1.0, creep=creep)
        if self.model == "rdpi":
            return RateDependentPI(r, zeros, self._sample_time(), 1.0, p["beta"], None, p["filter_tau"], creep=creep)
        c, h = self.c, self.h
        rising: Envelope | None
        falling: Envelope | None
        if self.envelope == "polynomial":
            rising = Envelope.polynomial(*_poly_shape_coefficients(p["rising_q2"], p["rising_q3"], 0.0, 1.0, c, h))
            falling = Envelope.polynomial(
                *_poly_shape_coefficients(
                    p["falling_q2"], p["falling_q3"], p["falling_offset"], p["falling_scale"], c, h
                )
            )
        elif self.envelope == "tanh":
            rising = Envelope.tanh(*_tanh_shape_coefficients(p["rising_steepness"], p["rising_center"], 0.0, 1.0, c, h))
            falling = Envelope.tanh(
                *_tanh_shape_coefficients(
                    p["falling_steepness"], p["falling_center"], p["falling_offset"], p["falling_scale"], c, h
                )
            )
        else:
            rising = falling = None
        return GeneralizedPI(r, zeros, (0.0, 0.0, 0.0, 0.0), rising, falling, self.input_range, creep=creep)

    def solve(self, template: LinearModel) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """``(z, scale, A_scaled, fit)``: the bounded least-squares weights (equilibrated
        columns) of ``template`` and the fitted free-run output ``A z``."""
        from .core import _design, _irls_huber

        A, lb, ub, _ = _design(template, self.v, self.offset)
        scale = np.maximum(np.sqrt(np.mean(A**2, axis=0)), 1e-300)
        A = A / scale
        lbs, ubs = lb * scale, ub * scale
        if self.loss == "huber" and self.robust is not None:
            # warm start: the sample weights of the best candidate so far (the glitches are the
            # same samples for every structure), so the IRLS starts near its fixed point
            w = self.robust
            z = _small_bounded_lstsq(A * w[:, None], self.y * w, lbs, ubs)
            if not self.search:
                z, _ = _irls_huber(A, self.y, (lbs, ubs), z, self.delta, _small_solve)
        else:
            z = _small_bounded_lstsq(A, self.y, lbs, ubs)
            if self.loss == "huber":
                z, _ = _irls_huber(
                    A, self.y, (lbs, ubs), z, self.delta, _small_solve, stol=1e-3 if self.search else 0.0
                )
        return z, scale, A, A @ z

    def residual(self, p: dict[str, float]) -> FloatArray | None:
        """Free-run residual of the projected candidate, or ``None`` if it is invalid."""
        try:
            template = self.template(p)
        except ValueError:
            return None
        fit = self.solve(template)[3]
        r = fit - self.y
        return r if np.all(np.isfinite(r)) else None

    def cost(self, p: dict[str, float]) -> float:
        from .core import _huber_sqrt_weights, huber_cost

        r = self.residual(p)
        if r is None:
            return math.inf
        if self.loss == "huber":
            c = float(huber_cost(r, self.delta))
            if c < self.best:
                self.best, self.robust = c, _huber_sqrt_weights(r, self.delta, self.yspan)
            return c
        return float(np.sqrt(np.mean(r * r)))


def _small_bounded_lstsq(A: FloatArray, y: FloatArray, lb: FloatArray, ub: FloatArray) -> FloatArray:
    """``argmin ||A z - y||`` within ``lb <= z <= ub`` through the ``p x p`` triangle of the
    Gram matrix: ``A^T A = R^T R``, ``R^T d = A^T y`` turn it into ``min ||R z - d||`` (same
    minimizer), solved unconstrained when that respects the bounds, else by BVLS on the small
    system. Falls back to BVLS on ``A`` when the Gram matrix is numerically singular."""
    from scipy.linalg import LinAlgError, cholesky, solve_triangular
    from scipy.optimize import lsq_linear

    G = A.T @ A
    b = A.T @ y
    try:
        R = cholesky(G, lower=False, check_finite=False)
        d = solve_triangular(R, b, trans="T", check_finite=False)
        z = solve_triangular(R, d, check_finite=False)
        ok = bool(np.all(np.isfinite(z)) and np.all(np.diag(R) > 1e-7 * np.sqrt(A.shape[0])))
    except (LinAlgError, ValueError):
        ok = False
    if not ok:
        return np.clip(lsq_linear(A, y, bounds=(lb, ub), method="bvls", lsmr_tol=None).x, lb, ub)
    if np.all(z >= lb) and np.all(z <= ub):
        return z
    free = np.isneginf(lb)
    if np.all(np.isposinf(ub)) and np.all(free | (lb == 0.0)):
        from .core import _mixed_nnls

        return _mixed_nnls(R, d, free)
    return np.clip(lsq_linear(R, d, bounds=(lb, ub), method="bvls", lsmr_tol=None).x, lb, ub)


def _small_solve(A: FloatArray, y: FloatArray, bounds: tuple[FloatArray, FloatArray]) -> FloatArray:
    """The bounded solver of :func:`piezohyst.identify.core._irls_huber` that solves each
    reweighted problem through :func:`_small_bounded_lstsq`: the IRLS of the Huber loss at the
    cost of ``p x p`` solves."""
    return _small_bounded_lstsq(A, y, bounds[0], bounds[1])


@_one_blas_thread
def identify_vp(
    input: npt.ArrayLike,
    output: npt.ArrayLike,
    model: str = "mpi",
    *,
    fs: float | None = None,
    operators: int = 9,
    envelope: str = "polynomial",
    creep: int = 0,
    bounds: BoundsSpec | None = None,
    optimizer: str = "de",
    rng: RngLike = None,
    max_iterations: int | None = None,
    population_size: int | None = None,
    polish: bool = True,
    starts: int = 3,
    validate: tuple[npt.ArrayLike, npt.ArrayLike] | None = None,
    progress: bool = False,
    callback: Callback | None = None,
    loss: str = "squared",
    huber_delta: float | None = None,
    offset: bool = True,
) -> IdentificationResult:
    """Identify a PI-family model with its structure by variable projection (docs/spec.md §4).

    A population optimizer (:func:`piezohyst.optimize.minimize`) searches the nonlinear
    structure parameters (see the module documentation and :func:`vp_parameters`: the
    threshold spread, the rising/falling envelopes of ``gpi``/``mpi``, the rate terms of
    ``rdpi``, creep time constants); for each candidate the linear parameters are solved
    exactly by bounded least squares on the Rust core's regressors, and the candidate costs
    the free-run RMSE of the fitted model (``inf`` for invalid envelopes). The best candidate
    is then polished by Gauss–Newton on the projected residual (``polish``), and its weights
    are solved once more as :func:`piezohyst.fit_linear` does.

    Parameters
    ----------
    input, output : array_like
        Training record.
    model : {"pi", "gpi", "mpi", "rdpi"}
        ``gpi`` and ``mpi`` are the same search (MPI: cubic input polynomial + generalized
        plays).
    fs : float, optional
        Sample rate, Hz; required by ``rdpi`` and by ``creep``.
    operators : int
        Number of play operators.
    envelope : {"polynomial", "tanh", "identity"}
        Envelope parametrization of ``gpi``/``mpi``.
    creep : int
        Number of creep lags added to the output (0: none).
    bounds : dict, optional
        ``{name: (lower, upper) or value}`` overriding the default box of a parameter, or
        fixing it (a value, or ``lower == upper``). Names as :func:`vp_parameters`.
    optimizer : {"de", "css", "pso", "mpso"}
        Population method (``"ls"`` means ``"de"``).
    rng, max_iterations, population_size, progress, callback
        As in :func:`piezohyst.optimize.minimize` (default ``max_iterations`` 60).
    polish : bool
        Gauss–Newton polish (SciPy ``least_squares``, ``trf``, within the bounds): a short
        screening run from each of the ``starts`` best distinct candidates the search evaluated
        and from the default fixed structure, then to convergence from the best of them; with
        ``loss="huber"``, from the search's best only, with SciPy's ``loss="huber"`` on the
        projected residual (``f_scale`` the Huber threshold; at most ``20 (D + 1)``
        residuals). The polished structure replaces the search's best only if it costs less.
    starts : int
        Distinct search candidates screened by the polish (>= 0; default 3).
    validate : (input, output), optional
        Held-out record, reported only.
    loss, huber_delta
        ``"huber"``: a candidate's cost is the :func:`huber_cost` of its residuals
        (``huber_delta`` as in :func:`fit_linear`). In the search its weights are one weighted
        least-squares solve with the Huber weights of the best candidate so far (an achievable
        cost, exact to second order in the weights' change; the first candidate runs the IRLS);
        in the polish and the final fit, the Huber IRLS to convergence.
    offset : bool
        Fit an output offset with every candidate's weights (a constant regressor; the model's
        ``output_map.offset``), as :func:`fit_linear` does.

    Returns
    -------
    IdentificationResult
        ``method`` is ``"vp-<optimizer>"`` (``+polish``, ``+huber``); ``evaluations`` counts
        the candidate structures evaluated (search and polish); ``history`` holds the
        optimizer's per-iteration history plus ``"parameters"`` (the searched names),
        ``"structure"`` (every structure parameter of the result by name), ``"condition"``
        (the 2-norm condition number of the final fit's equilibrated regressors) and, when polished,
        ``"polish"`` (costs before and after, evaluations, SciPy's message, the screened
        costs).

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.varpro import identify_vp
    >>> v = 0.5 + 0.45 * np.sin(np.linspace(0, 20, 800)) * np.linspace(1, 0.3, 800)
    >>> res = identify_vp(v, v ** 2, "mpi", operators=3, rng=0, max_iterations=5)
    >>> res.method, bool(res.train["rmse_percent"] < 0.01)
    ('vp-de+polish', True)
    """
    from ..optimize.core import minimize
    from .core import IdentificationResult, _check_loss, _fit_linear, _fit_metrics, default_huber_delta, huber_cost

    t0 = time.perf_counter()
    loss, delta = _check_loss(loss, huber_delta)
    v = as_record(input, "input", min_length=2)
    y = as_record(output, "output", min_length=2)
    if y.size != v.size:
        raise ParameterError(f"output has {y.size} samples, input has {v.size}; they must match")
    from .core import check_fit_scale

    check_fit_scale(v, "input")
    check_fit_scale(y, "output")
    if not np.ptp(v) > 0:
        raise ParameterError("input is constant: there is no hysteresis to identify")
    n = as_int(operators, "operators", minimum=1)
    creep = as_int(creep, "creep")
    if fs is not None:
        fs = as_scalar(fs, "fs", positive=True)
    if fs is None and model == "rdpi":
        raise ParameterError("fs is required for model = 'rdpi' (the rate needs the sample time)")
    if fs is None and creep:
        raise ParameterError("fs is required with creep (the lags need the sample time)")
    if model not in VP_KINDS:
        raise ParameterError(
            f"model = {model!r} has no structure to fit by variable projection; expected one of {list(VP_KINDS)}"
        )
    if envelope not in ENVELOPES:
        raise ParameterError(f"envelope = {envelope!r} is unknown; expected one of {list(ENVELOPES)}")
    if model not in ("gpi", "mpi") and envelope == "tanh":
        raise ParameterError(f"envelope = {envelope!r} applies to model = 'gpi'/'mpi' only; {model!r} has no envelopes")
    problem = _Problem(model, v, y, fs, n, envelope if model in ("gpi", "mpi") else "identity", creep, loss, delta)
    problem.offset = bool(offset)
    names, lower, upper, fixed = _search_box(problem.table, bounds)
    unknowns = (4 if model in ("gpi", "mpi") else 1) + n * (2 if model == "rdpi" else 1) + creep
    from .core import check_samples

    check_samples(
        v.size,
        unknowns + len(names),
        f"this {model} model ({unknowns} linear, {len(names)} structure)",
        "fewer operators or creep lags",
    )
    if isinstance(optimizer, str) and optimizer == "ls":
        optimizer = "de"
    if not isinstance(polish, bool):
        raise ParameterTypeError(f"polish must be True or False, got {polish!r}")
    starts = as_int(starts, "starts")
    if max_iterations is None:
        max_iterations = DEFAULT_ITERATIONS

    def full(x: FloatArray) -> dict[str, float]:
        p = dict(fixed)
        p.update(zip(names, (float(t) for t in x), strict=False))
        return p

    seen_x: list[FloatArray] = []
    seen_f: list[FloatArray] = []

    def cost_batch(
        X: FloatArray,
    ) -> FloatArray:  # the population: a loop over candidates, each one Rust pass + a small solve
        X = np.atleast_2d(X)
        f = np.array([problem.cost(full(x)) for x in X])
        seen_x.append(np.array(X, dtype=np.float64))
        seen_f.append(f)
        return f

    problem.search = True
    res = minimize(
        cost_batch,
        list(zip(lower, upper, strict=False)),
        method=optimizer,
        rng=rng,
        max_iterations=max_iterations,
        population_size=population_size,
        progress=progress,
        callback=callback,
    )
    if not np.isfinite(res.fun):
        raise ParameterError(
            "every candidate structure was invalid (envelopes not increasing or crossing on the input "
            "range): check the bounds"
        )
    problem.search = False
    x = np.array(res.x, dtype=np.float64)
    history: dict[str, Any] = dict(res.history)
    history["parameters"] = tuple(names)
    method = "vp-" + (res.method or str(optimizer))
    evaluations = int(res.nfev)
    if polish and res.message != "interrupted":
        before = float(res.fun)
        if loss == "squared":
            # Gauss-Newton from the best distinct candidates of the search and from the default
            # structure (a short screening run each), then to convergence from the best
            default = np.array([_default_value(problem, name, n) for name in names])
            candidates = _distinct(np.concatenate(seen_x), np.concatenate(seen_f), lower, upper, starts)
            candidates.append(np.clip(default, lower, upper))
            screened: list[float] = []
            nfev = 0
            best: tuple[FloatArray, float] | None = None
            for x0 in candidates:
                xs, k, _ = _gauss_newton(problem, full, x0, lower, upper, max_nfev=10 * (len(names) + 1))
                fs_ = problem.cost(full(xs))
                nfev += k + 1
                screened.append(fs_)
                if best is None or fs_ < best[1]:
                    best = (xs, fs_)
            assert best is not None  # candidates holds the default structure at least
            x1, k, message = _gauss_newton(problem, full, best[0], lower, upper)
            f1 = problem.cost(full(x1))
            nfev += k + 1
            extra: dict[str, Any] = {"screened": np.array(screened)}
        else:
            # Gauss-Newton with SciPy's Huber loss on the projected (IRLS-weighted) residual:
            # D + 1 residuals a step and few steps, where L-BFGS-B on the cost needed 2 D + 1
            # a step and hundreds in all
            r0 = problem.residual(full(x))
            if r0 is not None:  # the search's cost was a bound (one weighted solve): the IRLS's own
                before = float(huber_cost(r0, problem.delta))
            scale = problem.delta if problem.delta is not None or r0 is None else float(default_huber_delta(r0))
            x1, k, message = _gauss_newton(
                problem, full, x, lower, upper, max_nfev=20 * (len(names) + 1), loss="huber", f_scale=scale or 1.0
            )
            f1 = problem.cost(full(x1))
            nfev = k + 2
            extra = {}
        evaluations += nfev
        if f1 < before:
            x = x1
        history["polish"] = {
            "cost_before": before,
            "cost_after": min(f1, before),
            "nfev": nfev,
            "message": message,
            **extra,
        }
        method += "+polish"
    structure = full(x)
    history["structure"] = structure
    final = _fit_linear(problem.template(structure), v, y, loss, delta, offset=bool(offset))
    fitted = final.model
    evaluations += final.evaluations
    history["condition"] = final.condition
    train = _fit_metrics(fitted.simulate(v), y)
    val = None
    if validate is not None:
        vv = as_record(validate[0], "validate input")
        vy = as_record(validate[1], "validate output")
        if vy.size != vv.size:
            raise ParameterError(
                f"validate output has {vy.size} samples, validate input has {vv.size}; they must match"
            )
        val = _fit_metrics(fitted.simulate(vv), vy)
    if loss == "huber":
        method += "+huber"
    return IdentificationResult(
        fitted,
        train,
        val,
        method,
        time.perf_counter() - t0,
        history,
        partial=res.interrupted,
        evaluations=evaluations,
    )


def _default_value(problem: _Problem, name: str, n: int) -> float:
    """The fixed default structure's value of a parameter (identity envelopes, thresholds
    over half the span, no rate terms, creep lags in the middle of their bands)."""
    if name == "spread":
        return n / (2.0 * (n + 1))
    if name == "falling_scale":
        return 1.0
    if name.endswith("steepness"):
        return 0.05
    if name.startswith("log10_tau_"):
        row = next(t for t in problem.table if t[0] == name)
        return 0.5 * (row[1] + row[2])
    return 0.0


def _distinct(X: FloatArray, f: FloatArray, lower: FloatArray, upper: FloatArray, count: int) -> list[FloatArray]:
    """Up to ``count`` of the evaluated candidates ``X`` (costs ``f``), best first, no two
    within 10 % of the box's span of each other in every coordinate."""
    span = np.where(upper > lower, upper - lower, 1.0)
    chosen: list[FloatArray] = []
    picked: list[FloatArray] = []
    for i in np.argsort(f, kind="stable"):
        if len(chosen) >= count or not np.isfinite(f[i]):
            break
        z = (X[i] - lower) / span
        if all(np.max(np.abs(z - c)) > 0.1 for c in picked):
            chosen.append(X[i])
            picked.append(z)
    return chosen


def _gauss_newton(
    problem: _Problem,
    full: Callable[[FloatArray], dict[str, float]],
    x0: FloatArray,
    lower: FloatArray,
    upper: FloatArray,
    max_nfev: int | None = None,
    loss: Literal["linear", "huber"] = "linear",
    f_scale: float = 1.0,
) -> tuple[FloatArray, int, str]:
    """SciPy ``least_squares`` (``trf``, 2-point Jacobian, within the bounds) on the
    projected residual. An invalid structure returns a large constant residual, a wall the
    trust region backs off from. Returns ``(x, nfev, message)``."""
    from scipy.optimize import least_squares

    wall = np.full(problem.y.size, 10.0 * problem.yspan)
    n_calls = 0

    def fun(x: FloatArray) -> FloatArray:
        nonlocal n_calls
        n_calls += 1
        r = problem.residual(full(x))
        return wall if r is None else r

    # keep x0 strictly feasible for trf
    span = upper - lower
    x0 = np.clip(x0, lower + 1e-9 * span, upper - 1e-9 * span)
    sol = least_squares(
        fun,
        x0,
        bounds=(lower, upper),
        method="trf",
        x_scale=np.where(span > 0, span, 1.0),
        diff_step=np.full(x0.size, 1e-7),  # one relative step per parameter (a scalar, broadcast)
        xtol=1e-12,
        ftol=1e-12,
        gtol=1e-12,
        max_nfev=50 * (x0.size + 1) if max_nfev is None else max_nfev,
        loss=loss,
        f_scale=f_scale,
    )
    return np.clip(sol.x, lower, upper), n_calls, str(sol.message)
