"""The one entry point of identification, :func:`identify`: a registry of model kinds, each
with its fitter — least squares for the linear families (:mod:`piezohyst.identify.core`),
variable projection for their structure (:mod:`piezohyst.identify.varpro`), population
optimizers for Bouc–Wen, seed 1's CEMF stage model and the Bouc–Wen benchmark system
(:mod:`piezohyst.identify.boucwen_benchmark`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any, TypeAlias

import numpy as np
import numpy.typing as npt

from .. import _core
from .._validate import as_int, as_record, as_scalar
from ..errors import ParameterError, ParameterTypeError
from ..models.boucwen_benchmark import FS, UPSAMPLE, BoucWenBenchmark
from ..models.creep import Creep
from ..models.differential import BoucWen
from ..models.model import HysteresisModel
from ..models.pi import PI, GeneralizedPI, ModifiedPI, RateDependentPI
from ..models.preisach import Preisach
from ..optimize.core import minimize
from .boucwen_benchmark import identify_boucwen_benchmark
from .core import (
    PREISACH_MEMORY,
    Callback,
    DriftBasis,
    FitResult,
    FloatArray,
    IdentificationResult,
    LinearModel,
    RngLike,
    _check_loss,
    _default_thresholds,
    _fit_linear,
    _fit_metrics,
    _mpi_template,
    _preisach_template,
    check_fit_scale,
    check_samples,
    delayed,
    identify_cemf,
    minimize_huber,
)
from .losses import check_weights, fit_linear_weighted
from .validation import (
    VALIDATE_FROM,
    ValidatedResult,
    diagnose,
    estimate_period,
    residual_whiteness,
    scored_metrics,
    trust,
)
from .varpro import identify_vp

__all__ = ["KINDS", "LEAST_SQUARES_KINDS", "STRUCTURES", "identify"]

#: ``structure`` values of :func:`identify`: the default structure, or identified with it by
#: variable projection.
STRUCTURES = ("fixed", "fit")

#: Kinds whose fitted model has no output map (not a :class:`~piezohyst.HysteresisModel`).
_NO_OUTPUT_MAP = ("cemf", "boucwen-benchmark")

#: Kinds that fit a drift term and start their cost later (fixed structure).
_DRIFT_KINDS = ("pi", "gpi", "mpi", "rdpi", "preisach", "boucwen")

#: How far beyond the training input's range a fitted Preisach grid continues its outermost
#: cells (:meth:`~piezohyst.Preisach.extrapolated`), as a fraction of that range (rounded up to
#: whole cells): a validation input a little beyond it (a 5 kHz lookalike record: 2.6 % of the
#: samples) then follows the loop's outer slope instead of the reversible slope alone.
PREISACH_EXTRAPOLATION = 0.25

#: Keywords :func:`identify` passes on to :func:`piezohyst.varpro.identify_vp`.
_VP_OPTIONS = ("envelope", "bounds", "polish", "starts")


#: A held-out record: ``(input, output)``, or for ``boucwen-benchmark`` ``(input, output, (start, stop))``.
HeldOut = tuple[npt.ArrayLike, npt.ArrayLike] | tuple[npt.ArrayLike, npt.ArrayLike, tuple[int, int]]


@dataclass(frozen=True)
class _Call:
    """One :func:`identify` call, checked, as the kind's fitter sees it."""

    input: npt.ArrayLike
    output: npt.ArrayLike
    kind: str
    fs: float | None
    operators: int
    levels: int
    creep: int
    loss: str
    delta: float | None
    validate: HeldOut | None
    search: dict[str, Any]
    options: dict[str, Any]
    t0: float
    offset: bool = True
    weights: FloatArray | None = None
    drift: DriftBasis | None = None
    start: int = 0
    creep_horizon: float = 1.0


@dataclass(frozen=True)
class _Kind:
    """A registered model kind: its fitter, whether it takes ``**options``, whether variable
    projection fits its structure, and its optimizer iterations by default."""

    fit: Callable[[_Call], IdentificationResult]
    options: bool = False
    structure: bool = False
    iterations: int = 200


#: The model kinds :func:`identify` accepts, in the order of ``KINDS``.
_REGISTRY: dict[str, _Kind] = {}


def _register(
    kind: str,
    fit: Callable[[_Call], IdentificationResult],
    *,
    options: bool = False,
    structure: bool = False,
    iterations: int = 200,
) -> None:
    _REGISTRY[kind] = _Kind(fit, options, structure, iterations)


def _boucwen_bounds(v: FloatArray, y: FloatArray) -> list[tuple[float, float]]:
    """Search box for Bouc–Wen ``(a, beta, gamma, n = 1, d)`` from the data's scales."""
    dv = float(np.ptp(v)) or 1.0
    gain = float(np.ptp(y)) / dv
    return [(0.0, 4 * gain), (1e-3 / dv, 50.0 / dv), (-50.0 / dv, 50.0 / dv), (1.0, 1.0), (0.0, 4 * gain)]


def identify(
    input: npt.ArrayLike,
    output: npt.ArrayLike,
    model: str = "mpi",
    *,
    fs: float | None = None,
    operators: int = 9,
    levels: int = 12,
    structure: str = "fixed",
    creep: int = 0,
    optimizer: str = "ls",
    rng: RngLike = None,
    max_iterations: int | None = None,
    population_size: int | None = None,
    validate: HeldOut | None = None,
    progress: bool = False,
    callback: Callback | None = None,
    loss: str = "squared",
    huber_delta: float | None = None,
    offset: bool | None = None,
    validate_from: str | None = None,
    gap: npt.ArrayLike | None = None,
    warmup: int = 0,
    periodic: int | str | None = None,
    weights: npt.ArrayLike | None = None,
    diagnosis: bool = True,
    input_delay: int = 0,
    drift: DriftBasis | None = None,
    fit_start: int = 0,
    creep_horizon: float = 1.0,
    **options: Any,
) -> IdentificationResult:
    """Identify a hysteresis model from an input/output record (free-run simulation error).

    One entry point for every model kind: the linear families by least squares, the
    differential and stage models by a population optimizer, each population simulated in one
    Rust batch call.

    Parameters
    ----------
    input, output : array_like
        The training record. For ``cemf``: the voltage across the stack (V) and the
        displacement; for ``boucwen-benchmark``: force (N) and displacement (m).
    model : str
        One of ``KINDS``:

        - ``pi``, ``gpi``/``mpi``, ``rdpi``, ``preisach``: least squares over the linear
          parameters with a default structure (thresholds over half the input range; a grid
          over the input range); with ``structure="fit"`` (not ``preisach``) the structure is
          identified too, by variable projection (:func:`piezohyst.varpro.identify_vp`);
        - ``boucwen``: a population optimizer over all its parameters (then L-BFGS-B);
        - ``cemf``: seed 1's grey-box stage model, :func:`identify_cemf` (needs ``fs``);
        - ``boucwen-benchmark``: the Noël–Schoukens oscillator,
          :func:`piezohyst.boucwen_benchmark.identify_boucwen_benchmark` (``fs`` defaults to
          the benchmark's 750 Hz).
    fs : float, optional
        Sample rate, Hz (needed by ``rdpi``, ``cemf`` and ``creep``).
    operators, levels : int
        Play operators (PI family) and Preisach grid size.
    structure : {"fixed", "fit"}
        PI family only. ``"fixed"`` (default): the default structure, weights by least squares.
        ``"fit"``: variable projection — a population optimizer (``optimizer``, default DE)
        over the nonlinear structure parameters (threshold spread; rising/falling envelopes
        of ``gpi``/``mpi``; ``beta`` and ``filter_tau`` of ``rdpi``; creep time constants),
        the weights solved exactly by bounded least squares for every candidate, the cost the
        free-run RMSE; then a Gauss–Newton polish. Options ``envelope``, ``bounds``,
        ``polish``, ``starts`` of :func:`piezohyst.varpro.identify_vp` are accepted then.
    creep : int
        PI family and ``preisach``: number of creep lags added to the model (needs ``fs``). Fixed
        structure: time constants log-spaced over ``[2 Ts, creep_horizon T]`` (``T`` the
        record's duration), one in the middle of each of ``creep`` equal decade bands; ``structure="fit"`` searches
        each within its band.
    optimizer : str
        ``"ls"`` for the linear families; ``"css"``, ``"pso"``, ``"mpso"`` or ``"de"`` for the
        others and for ``structure="fit"`` (``"ls"`` there means each kind's default:
        ``"de"``, or ``"css"`` for ``cemf``).
    rng, population_size, progress, callback
        Passed to the population optimizer (:func:`piezohyst.optimize.minimize`).
    max_iterations : int, optional
        Optimizer iterations; by default 200 (``boucwen``), 150 (``cemf``), 30
        (``boucwen-benchmark``), 60 (``structure="fit"``).
    validate : tuple, optional
        A held-out record ``(input, output)``; its metrics are reported, it is not fitted.
        ``boucwen-benchmark`` also takes ``(input, output, (start, stop))``: the whole record
        simulated from rest and scored on samples ``start:stop`` (the oscillator's memory is long).
    loss : {"squared", "huber", "linf"}
        ``"linf"``: the minimax fit (the largest error made smallest) — a linear program
        (:func:`scipy.optimize.linprog`) for the linear families (fixed structure), the
        max-abs error of the free run as the population optimizer's cost for ``boucwen``.
        ``"squared"``: the RMSE of the free-run simulation. ``"huber"``: the robust Huber
        cost, for records with glitches — iteratively reweighted least squares for the
        linear families (:func:`fit_linear`), :func:`huber_cost` of the simulated residuals
        for the population optimizers (``boucwen``, ``cemf``; not ``boucwen-benchmark``) by
        :func:`minimize_huber`. The reported metrics stay RMSE and max error.
    huber_delta : float, optional
        Huber threshold in the output's unit; by default 1.345 times the MAD-based robust
        sigma of the residuals (:func:`default_huber_delta`).
    offset : bool, optional
        Fit an output offset (the sensor's zero), stored in the model's output map
        (``model.output_map.offset``; :class:`~piezohyst.OutputMap`). Linear families: one
        more least-squares column (GPI/MPI and Preisach fit it in their own constant term,
        ``c0`` / ``offset``, and get no second one); ``boucwen``: projected out of every
        candidate's cost (the best offset of its simulated output, in closed form). A gain
        error needs no map gain: the weights (Bouc–Wen: ``a`` and ``d``) absorb it. ``None``
        (default): ``True`` for every kind whose model has an output map, i.e. all but
        ``cemf`` and ``boucwen-benchmark`` (whose simulations start at rest at zero).
        ``False``: no offset beyond the family's own (the fit of earlier versions).
    validate_from : {"carried", "rest"}, optional
        How the validation record is simulated; by default ``"carried"`` when ``gap`` is given
        (the caller says where the validation sits), else ``"rest"`` (a record of another run,
        the former behaviour). ``"carried"``: it is taken to follow
        the training record (after the input ``gap``, if given): the model runs from the
        training record's start through the validation record and only the validation record
        is scored, so the validation starts from the state the training left (a record of
        another run has no such state: use ``"rest"``). ``"rest"``: simulated from the model's
        rest state.
    gap : array_like, optional
        ``validate_from="carried"``: the input between the training record's end and the
        validation record's start (simulated, not scored).
    warmup : int
        Samples at the start of each scored record (training, validation) left out of the
        metrics (the model's initial transient).
    periodic : int or "auto", optional
        For periodic records: the period in samples (``"auto"``: estimated from the input's
        autocorrelation); one period of the input is simulated before each simulation so it
        starts in the periodic steady state.
    weights : array_like, optional
        Sample weights (``>= 0``, one per training sample) of the linear families' fit
        (weighted least squares / Huber; ``max w |r|`` for ``"linf"``).
    diagnosis : bool
        When the fit is not trustworthy (:func:`~piezohyst.identify.validation.trust`), refit
        to name the likely cause (:func:`~piezohyst.identify.validation.diagnose`).
    input_delay : int
        The model's input delay in samples (every kind with an output map): the family is
        fitted to the input delayed (:func:`~piezohyst.identify.structure.delayed`, the first
        sample held) and the model holds the delay
        (:meth:`~piezohyst.HysteresisModel.with_input_delay`), so it simulates the record as
        given. :func:`~piezohyst.identify.structure.choose_structure` chooses it.
    drift : DriftBasis, optional
        A drift term fitted with the model (linear families with a fixed structure: free
        least-squares columns; ``boucwen`` with the squared loss: projected out of every
        candidate, as the offset), held by the model (:meth:`~piezohyst.HysteresisModel.with_drift`),
        counted from the training record's first sample.
    creep_horizon : float
        The upper edge of the slowest creep band, in record durations (default 1; fixed
        structure): ``10`` places lags slower than the record, whose response to the input's
        level a short training record shows as a trend.
    fit_start : int
        Samples at the start of the training record simulated but left out of the fit's cost
        (a quiet lead-in, the wiping-out of the unknown initial memory:
        :func:`~piezohyst.identify.structure.fit_start`); linear families with a fixed
        structure and ``boucwen``. The reported training metrics cover the whole record.
    **options
        Further keywords of :func:`identify_cemf` or of
        :func:`~piezohyst.boucwen_benchmark.identify_boucwen_benchmark` (e.g. ``bounds``,
        ``fit_range``), or of :func:`~piezohyst.varpro.identify_vp` with ``structure="fit"``
        (``envelope``, ``bounds``, ``polish``, ``starts``); refused otherwise.

    Returns
    -------
    ValidatedResult
        An :class:`IdentificationResult` (``method`` names the optimizer, with ``+huber`` for
        the Huber loss, ``+linf`` for the minimax one) whose ``assessment`` holds how the
        spans were scored, the residuals' whiteness, the trust verdict and, when not trusted,
        the diagnosis (``boucwen-benchmark``: none, it scores its own ranges).

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst import PI, identify
    >>> v = 0.5 + 0.4 * np.sin(np.linspace(0, 30, 1500)) * np.linspace(1, 0.3, 1500)
    >>> truth = PI(np.arange(1, 5) * np.ptp(v) / 10, [0.4, 0.2, 0.1, 0.05], p0=0.6)   # the default structure
    >>> y = truth.simulate(v)
    >>> y[::100] += 0.5                                   # glitches on 1 % of the samples
    >>> fits = {loss: identify(v, y, "pi", operators=4, loss=loss) for loss in ("squared", "huber")}
    >>> {k: round(float(np.sqrt(np.mean((f.model.simulate(v) - truth.simulate(v)) ** 2))), 4) for k, f in fits.items()}
    {'squared': 0.0052, 'huber': 0.0}
    """
    t0 = time.perf_counter()
    if model not in KINDS:
        raise ParameterError(f"model = {model!r} is unknown; expected one of {list(KINDS)}")
    if loss == "linf":
        if huber_delta is not None:
            raise ParameterError(f"huber_delta = {huber_delta!r} is only used with loss = 'huber', got loss = 'linf'")
        delta = None
        if structure == "fit" or model in ("cemf", "boucwen-benchmark"):
            raise ParameterError(
                f"loss = 'linf' applies to the fixed-structure linear families and boucwen, not to model = "
                f"{model!r}{' with structure = fit' if structure == 'fit' else ''}"
            )
    else:
        loss, delta = _check_loss(loss, huber_delta)
    if validate_from is None:
        validate_from = "rest" if gap is None else "carried"
    if validate_from not in VALIDATE_FROM:
        raise ParameterError(f"validate_from = {validate_from!r} is unknown; expected one of {list(VALIDATE_FROM)}")
    w = None
    if weights is not None:
        if structure == "fit" or model not in ("pi", "gpi", "mpi", "rdpi", "preisach"):
            raise ParameterError(
                f"weights apply to the fixed-structure linear families (pi, gpi, mpi, rdpi, preisach), not to "
                f"model = {model!r}{' with structure = fit' if structure == 'fit' else ''}"
            )
        w = check_weights(weights, np.size(input))
    d = as_int(input_delay, "input_delay", minimum=0)
    start = as_int(fit_start, "fit_start", minimum=0)
    horizon = as_scalar(creep_horizon, "creep_horizon", positive=True)
    if horizon != 1.0 and (structure == "fit" or model not in ("pi", "gpi", "mpi", "rdpi", "preisach")):
        raise ParameterError(
            f"creep_horizon applies to the PI family and preisach with a fixed structure, not to model = {model!r}"
            f"{' with structure = fit' if structure == 'fit' else ''}"
        )
    if drift is not None and not isinstance(drift, DriftBasis):
        raise ParameterTypeError(f"drift must be a DriftBasis or None, got {type(drift).__name__}")
    basis = None if drift is None or drift.empty else drift
    if (basis is not None or start) and (structure == "fit" or model not in _DRIFT_KINDS):
        raise ParameterError(
            f"drift / fit_start apply to the fixed-structure linear families and boucwen, not to model = "
            f"{model!r}{' with structure = fit' if structure == 'fit' else ''}"
        )
    if basis is not None and model == "boucwen" and loss != "squared":
        raise ParameterError(f"drift applies to boucwen with loss = 'squared', not {loss!r}")
    if start and start >= np.size(input) - 1:
        raise ParameterError(f"fit_start = {start} leaves fewer than 2 samples of the training record to fit")
    if d and model in _NO_OUTPUT_MAP:
        raise ParameterError(f"input_delay applies to models with an output map; model = {model!r} has none")
    fit_input: npt.ArrayLike = input
    fit_validate = validate
    if d:
        fit_input = delayed(input, d)
        if validate is not None:  # the fitters report it: as the delayed model sees it
            fit_validate = (delayed(validate[0], d), validate[1])
    res = _identify(
        fit_input,
        output,
        model,
        fs,
        operators,
        levels,
        structure,
        creep,
        optimizer,
        rng,
        max_iterations,
        population_size,
        fit_validate,
        progress,
        callback,
        loss,
        delta,
        w,
        offset,
        t0,
        options,
        basis,
        start,
        horizon,
    )
    if model == "boucwen-benchmark":
        return res
    if d:
        assert isinstance(res.model, HysteresisModel)  # the kinds with an output map
        res = replace(res, model=res.model.with_input_delay(d))
    return _assess(
        res,
        input,
        output,
        validate,
        validate_from,
        gap,
        warmup,
        periodic,
        fs,
        diagnosis,
        model,
        start,
        dict(
            operators=operators,
            levels=levels,
            creep=creep,
            validate_from=validate_from,
            warmup=warmup,
            periodic=periodic,
        ),
    )


def _identify(
    input: npt.ArrayLike,
    output: npt.ArrayLike,
    model: str,
    fs: float | None,
    operators: int,
    levels: int,
    structure: str,
    creep: int,
    optimizer: str,
    rng: RngLike,
    max_iterations: int | None,
    population_size: int | None,
    validate: HeldOut | None,
    progress: bool,
    callback: Callback | None,
    loss: str,
    delta: float | None,
    weights: FloatArray | None,
    offset: bool | None,
    t0: float,
    options: dict[str, Any],
    drift: DriftBasis | None = None,
    start: int = 0,
    horizon: float = 1.0,
) -> IdentificationResult:
    """The kind's fit (:func:`identify` once its own arguments are checked)."""
    if structure not in STRUCTURES:
        raise ParameterError(f"structure = {structure!r} is unknown; expected one of {list(STRUCTURES)}")
    creep = as_int(creep, "creep")
    kind = _REGISTRY[model]
    if offset and model in _NO_OUTPUT_MAP:
        raise ParameterError(
            f"offset = {offset!r} applies to models with an output map; model = {model!r} has none "
            "(give offset = None or False)"
        )
    offset = model not in _NO_OUTPUT_MAP if offset is None else bool(offset)
    if structure == "fit" and not kind.structure:
        raise ParameterError(
            f"structure = 'fit' applies to model = {' / '.join(repr(k) for k in _VP_KINDS)}; "
            f"{model!r} has no fixed structure to fit (use structure = 'fixed')"
        )
    if creep and not kind.structure and model != "preisach":
        raise ParameterError(
            f"creep = {creep} applies to model = {' / '.join(repr(k) for k in (*_VP_KINDS, 'preisach'))}, "
            f"not to {model!r}"
        )
    if isinstance(validate, tuple) and len(validate) == 3 and model != "boucwen-benchmark":
        raise ParameterError(
            f"validate = (input, output, range) applies to model = 'boucwen-benchmark'; "
            f"give (input, output) for model = {model!r}"
        )
    if structure == "fit":
        unknown = sorted(set(options) - set(_VP_OPTIONS))
        if unknown:
            raise ParameterTypeError(
                f"identify() got unexpected keyword arguments {unknown} for model = {model!r}, "
                f"structure = 'fit' (accepted: {list(_VP_OPTIONS)})"
            )
        return _named(
            identify_vp(
                input,
                output,
                model,
                fs=fs,
                operators=operators,
                creep=creep,
                optimizer="de" if optimizer == "ls" else optimizer,
                rng=rng,
                max_iterations=max_iterations,
                population_size=population_size,
                validate=None if validate is None else (validate[0], validate[1]),  # 3-tuples refused above
                progress=progress,
                callback=callback,
                loss=loss,
                huber_delta=delta,
                offset=offset,
                **options,
            ),
            model,
        )
    if options and not kind.options:
        raise ParameterTypeError(f"identify() got unexpected keyword arguments {sorted(options)} for model = {model!r}")
    if max_iterations is None:
        max_iterations = kind.iterations
    search: dict[str, Any] = dict(
        optimizer=optimizer,
        rng=rng,
        max_iterations=max_iterations,
        population_size=population_size,
        validate=validate,
        progress=progress,
        callback=callback,
    )
    call = _Call(
        input,
        output,
        model,
        fs,
        operators,
        levels,
        creep,
        loss,
        delta,
        validate,
        search,
        options,
        t0,
        bool(offset),
        weights,
        drift,
        start,
        horizon,
    )
    return _named(kind.fit(call), model)


def _named(res: IdentificationResult, model: str) -> IdentificationResult:
    """The result with its model named as the kind fitted: an ``mpi`` fit is a
    :class:`~piezohyst.models.pi.ModifiedPI` (kind ``"mpi"`` in files and reports)."""
    if model == "mpi" and isinstance(res.model, GeneralizedPI) and not isinstance(res.model, ModifiedPI):
        return replace(res, model=ModifiedPI.from_gpi(res.model))
    return res


def _assess(
    res: IdentificationResult,
    input: npt.ArrayLike,
    output: npt.ArrayLike,
    validate: HeldOut | None,
    validate_from: str,
    gap: npt.ArrayLike | None,
    warmup: int,
    periodic: int | str | None,
    fs: float | None,
    diagnosis: bool,
    model: str,
    start: int,
    settings: dict[str, Any],
) -> ValidatedResult:
    """The fitted model scored honestly: training record (warm-up and periodic state as asked;
    from the fit's start when later), validation record with the state carried (or from
    rest), whiteness, verdict, diagnosis."""
    # the kind's fitter has validated the records (each is validated once): only converted here
    v = np.asarray(input, dtype=np.float64)
    y = np.asarray(output, dtype=np.float64)
    period = None
    if periodic is not None:
        period = estimate_period(v) if periodic == "auto" else as_int(periodic, "periodic", minimum=1)
        if period > v.size:
            raise ParameterError(f"periodic = {period} is longer than the training record ({v.size} samples)")
    wu = as_int(warmup, "warmup", minimum=0)
    if wu >= v.size - 1:
        raise ParameterError(f"warmup = {wu} leaves fewer than 2 samples of the training record ({v.size}) to score")
    sim = res.simulate if res.simulator is None else res.simulator  # the records are valid already
    tw = max(wu, start)  # the training samples the fit counted
    train, r_train = scored_metrics(sim, v, y, warmup=tw, periodic=period)
    assessment: dict[str, Any] = {"validate_from": validate_from, "warmup": wu, "periodic": period}
    if start:
        assessment["fit_start"] = start
    assessment["train"] = residual_whiteness(r_train, v[tw:]) if r_train.size >= 4 else None
    val = None
    scored = (train, r_train, v[tw:])
    if validate is not None:
        vv = np.asarray(validate[0], dtype=np.float64)
        vy = np.asarray(validate[1], dtype=np.float64)
        if vy.size != vv.size:
            raise ParameterError(
                f"validate output has {vy.size} samples, validate input has {vv.size}; they must match"
            )
        if wu >= vv.size - 1:
            raise ParameterError(
                f"warmup = {wu} leaves fewer than 2 samples of the validation record ({vv.size}) to score"
            )
        if validate_from == "carried":
            between = np.zeros(0) if gap is None else as_record(gap, "gap", min_length=0)
            u = np.concatenate([v, between, vv])
            lead = v.size + between.size
            val, r_val = scored_metrics(
                sim, u, np.concatenate([np.zeros(lead), vy]), start=lead, warmup=wu, periodic=period
            )
            assessment["gap"] = int(between.size)
        else:
            if gap is not None:
                raise ParameterError("gap is only used with validate_from = 'carried'")
            val, r_val = scored_metrics(sim, vv, vy, warmup=wu, periodic=period)
        assessment["validation"] = residual_whiteness(r_val, vv[wu:]) if r_val.size >= 4 else None
        scored = (val, r_val, vv[wu:])
    elif gap is not None:
        raise ParameterError("gap is only used with a validation record (validate)")
    metrics, residual, scored_input = scored
    whiteness = residual_whiteness(residual, scored_input) if residual.size >= 4 else None
    trusted, reasons = trust(metrics, whiteness) if whiteness is not None else (True, [])
    assessment.update(trusted=trusted, reasons=reasons, scored="validation" if val is not None else "train")
    if not trusted and diagnosis and whiteness is not None and model not in ("cemf",):
        assessment["diagnosis"] = _diagnose(v, y, wu, period, fs, model, settings, residual, whiteness)
    fields = {f: getattr(res, f) for f in res.__dataclass_fields__}
    fields.update(train=train, validation=val)
    return ValidatedResult(**fields, assessment=assessment)


#: Creep time constants (s) of the diagnosis's sample-rate check: piezo creep's decades.
_PHYSICAL_TAUS = np.array([0.003, 0.03, 0.3, 3.0, 30.0])

#: The kinds a diagnosis refits as they are (linear, fast); the others are refitted as ``mpi``.
_QUICK = ("pi", "gpi", "mpi", "rdpi", "preisach")


def _diagnose(
    v: FloatArray,
    y: FloatArray,
    warmup: int,
    period: int | None,
    fs: float | None,
    model: str,
    settings: dict[str, Any],
    residual: FloatArray,
    whiteness: dict[str, Any],
) -> list[dict[str, Any]]:
    quick = model if model in _QUICK else "mpi"
    creep = settings["creep"] if quick in ("pi", "gpi", "mpi", "rdpi") else 0

    def refit(vi: FloatArray, yo: FloatArray, rate: float | None) -> float:
        """In-sample RMSE (% of range) of the quick kind refitted to a rearranged training record
        (the records are valid already: the fit is called past the public door)."""
        try:
            fitted = _identify_linear(
                quick, vi, yo, rate, settings["operators"], settings["levels"], "squared", None, creep, offset=True
            )
            metrics, _ = scored_metrics(fitted.model.simulate, vi, yo, warmup=min(warmup, vi.size - 2), periodic=period)
        except ParameterError:
            return float("inf")
        return float(metrics["rmse_percent"])

    # the refits score their own training record: compared with the same fit of the record as given
    def rate_refit(rate: float) -> float:
        """In-sample RMSE (%) of an MPI with creep lags of physical time constants at ``rate``."""
        lags = Creep(1.0 / rate, _PHYSICAL_TAUS, np.zeros(_PHYSICAL_TAUS.size))
        r = _default_thresholds(v, as_int(settings["operators"], "operators", minimum=1))
        return float(_fit_linear(_mpi_template(v, r, None, None, lags), v, y, "squared", None).metrics["rmse_percent"])

    base = refit(v, y, fs)
    return diagnose(refit, (v, y), residual, whiteness, base, fs, rate_refit=rate_refit)


#: What a fitter of :func:`_free_run` returns: ``(model, method, history, partial, evaluations)``.
_Fitted: TypeAlias = tuple[Any, str, dict[str, Any], bool, int]


def _free_run(fit: Callable[[_Call, FloatArray, FloatArray], _Fitted]) -> Callable[[_Call], IdentificationResult]:
    """A fitter for the kinds identified here on one record: ``fit(call, v, y)`` gives
    ``(model, method, history, partial, evaluations)`` from the validated record; the metrics
    are the fitted model's free run. The records are validated here, once."""

    def run(c: _Call) -> IdentificationResult:
        v = as_record(c.input, "input", min_length=2)
        y = as_record(c.output, "output", min_length=2)
        if y.size != v.size:
            raise ParameterError(f"output has {y.size} samples, input has {v.size}; they must match")
        check_fit_scale(v, "input")
        check_fit_scale(y, "output")
        fitted, method, history, partial, evaluations = fit(c, v, y)
        if c.loss in ("huber", "linf"):
            method += "+" + c.loss
        train = _fit_metrics(fitted.simulate(v), y)
        val = None
        if c.validate is not None:
            vv = as_record(c.validate[0], "validate input")
            vy = as_record(c.validate[1], "validate output")
            val = _fit_metrics(fitted.simulate(vv), vy)
        return IdentificationResult(
            fitted,
            train,
            val,
            method,
            time.perf_counter() - c.t0,
            history,
            partial=partial,
            evaluations=evaluations,
        )

    return run


@_free_run
def _fit_linear_kind(c: _Call, v: FloatArray, y: FloatArray) -> _Fitted:
    fit = _identify_linear(
        c.kind,
        v,
        y,
        c.fs,
        c.operators,
        c.levels,
        c.loss,
        c.delta,
        c.creep,
        c.offset,
        c.weights,
        c.drift,
        c.start,
        c.creep_horizon,
    )
    model = fit.model
    if isinstance(model, Preisach):  # its grid is the training input's range: continue it beyond
        model = model.extrapolated(math.ceil(PREISACH_EXTRAPOLATION * model.levels))
    return model, "ls", dict(fit.history), False, fit.evaluations


@_free_run
def _fit_boucwen(c: _Call, v: FloatArray, y: FloatArray) -> _Fitted:
    return _identify_boucwen(v, y, c.loss, c.delta, c.search, c.offset, c.drift, c.start)


def _fit_cemf(c: _Call) -> IdentificationResult:
    if c.fs is None:
        raise ParameterError("fs is required for model = 'cemf' (the stage is simulated at the sample time)")
    return identify_cemf(c.input, c.output, c.fs, loss=c.loss, huber_delta=c.delta, **c.search, **c.options)


def _fit_benchmark(c: _Call) -> IdentificationResult:
    return _identify_benchmark(c.input, c.output, c.fs, c.loss, c.search, c.options)


def _identify_linear(
    model: str,
    v: FloatArray,
    y: FloatArray,
    fs: float | None,
    operators: int,
    levels: int,
    loss: str,
    delta: float | None,
    creep: int = 0,
    offset: bool = False,
    weights: FloatArray | None = None,
    drift: DriftBasis | None = None,
    start: int = 0,
    horizon: float = 1.0,
) -> FitResult:
    """The least-squares kinds' fit, from the validated record (the checks and their order
    are those of :func:`identify_pi`, :func:`identify_mpi`, :func:`identify_preisach` and
    :func:`fit_linear`, without validating the record again)."""
    template = _linear_template(model, v, fs, operators, levels, creep, horizon)
    if loss == "linf" or weights is not None:
        return fit_linear_weighted(template, v, y, loss, delta, weights, offset=offset, drift=drift, start=start)
    return _fit_linear(template, v, y, loss, delta, offset=offset, drift=drift, start=start)


def _linear_template(
    model: str, v: FloatArray, fs: float | None, operators: int, levels: int, creep: int = 0, horizon: float = 1.0
) -> LinearModel:
    """The fixed structure of a least-squares kind for the training input ``v`` (its linear
    parameters zero): default thresholds, envelopes, grid and creep lags."""
    lags = _default_creep(v.size, fs, creep, horizon)
    template: LinearModel
    if model == "pi":
        r = _default_thresholds(v, as_int(operators, "operators", minimum=1))
        template = PI(r, np.zeros(len(r)), 1.0, creep=lags)
    elif model in ("gpi", "mpi"):
        r = _default_thresholds(v, as_int(operators, "operators", minimum=1))
        template = _mpi_template(v, r, None, None, lags)
    elif model == "preisach":
        template = _preisach_template(v, levels, None, PREISACH_MEMORY, lags)
    else:
        if fs is None:
            raise ParameterError("fs is required for model = 'rdpi' (the rate needs the sample time)")
        r = _default_thresholds(v, as_int(operators, "operators", minimum=1))
        template = RateDependentPI(r, np.zeros(r.size), 1.0 / float(fs), 1.0, 0.0, creep=lags)
    return template


def _default_creep(n: int, fs: float | None, terms: int, horizon: float = 1.0) -> Creep | None:
    """``terms`` creep lags for a record of ``n`` samples at ``fs``: one time constant in the
    middle (in decades) of each of ``terms`` equal bands of ``[2 Ts, horizon n Ts]``; ``None``
    for 0."""
    if not terms:
        return None
    if fs is None:
        raise ParameterError(f"fs is required with creep = {terms} (the lags need the sample time)")
    fs = as_scalar(fs, "fs", positive=True)
    lo, hi = np.log10(2.0 / fs), np.log10(horizon * n / fs)
    w = (hi - lo) / terms
    return Creep(1.0 / fs, 10.0 ** (lo + w * (np.arange(terms) + 0.5)), np.zeros(terms))


def _identify_boucwen(
    v: FloatArray,
    y: FloatArray,
    loss: str,
    delta: float | None,
    search: dict[str, Any],
    offset: bool = False,
    drift: DriftBasis | None = None,
    start: int = 0,
) -> _Fitted:
    """Bouc–Wen by a population optimizer: ``(model, method, history, partial, evaluations)``.

    With ``offset`` the output offset is projected out of every candidate (variable
    projection): each simulated output is scored with its best offset — the mean residual
    for the RMSE, the Huber location at the threshold in use for the Huber cost (smooth in
    the parameters, unlike the median, which stalled the gradient polish: validation RMSE
    1.5x the least-squares fit's on a glitch-free record) — so the search runs over the shape alone
    and an offset in the record cannot bend the loop; the fitted model carries the offset
    in its output map. Bouc–Wen scales with ``a`` and ``d``: no gain is fitted. A ``drift``
    basis (squared loss) is projected out with the offset (the least-squares drift of each
    candidate's residual); the samples before ``start`` are simulated, not scored."""
    search = dict(search)
    if drift is not None or start:
        return _identify_boucwen_projected(v, y, search, offset, drift, start)
    search.pop("validate")
    optimizer = search.pop("optimizer")
    method = "de" if optimizer == "ls" else optimizer
    family = BoucWen(1.0, 1.0, 0.0).family
    bounds = _boucwen_bounds(v, y)
    check_samples(v.size, sum(lo < hi for lo, hi in bounds) + bool(offset), "a Bouc-Wen model")

    # the rows stay inside the box, where every Bouc-Wen row is valid (n = 1, finite)
    # the offset that is best for the loss: mean (squared), mid-range (linf); huber's depends
    # on the threshold, minimize_huber projects it out
    def centre(r: FloatArray) -> FloatArray:
        if loss == "linf":
            return np.asarray(0.5 * (r.max(axis=-1, keepdims=True) + r.min(axis=-1, keepdims=True)), dtype=np.float64)
        return np.asarray(np.mean(r, axis=-1, keepdims=True), dtype=np.float64)

    def raw(rows: FloatArray) -> FloatArray:
        out: FloatArray = _core.batch_simulate(family, [], np.ascontiguousarray(rows), v)
        return out

    def simulate(rows: FloatArray) -> FloatArray:
        out = raw(rows)
        if offset:
            with np.errstate(invalid="ignore", over="ignore"):
                out += centre(y - out)
        return out

    if loss == "huber":
        res = minimize_huber(raw, y, bounds, delta, offset=offset, method=method, **search)
    elif loss == "linf":

        def worst(rows: FloatArray) -> FloatArray:
            r = simulate(rows) - y
            with np.errstate(invalid="ignore", over="ignore"):
                c: FloatArray = np.max(np.abs(r), axis=-1)
            return np.where(np.isfinite(c), c, np.inf)

        res = minimize(worst, bounds, method=method, polish=True, **search)
    elif offset:

        def cost(rows: FloatArray) -> FloatArray:
            r = simulate(rows) - y
            with np.errstate(invalid="ignore", over="ignore"):
                c: FloatArray = np.sqrt(np.mean(r * r, axis=-1))
            return np.where(np.isfinite(c), c, np.inf)

        res = minimize(cost, bounds, method=method, polish=True, **search)
    else:

        def cost(rows: FloatArray) -> FloatArray:
            return _core.batch_rmse(family, [], np.ascontiguousarray(rows), v, y, float("inf"))

        res = minimize(cost, bounds, method=method, polish=True, **search)
    fitted = BoucWen(*np.asarray(res.x, dtype=np.float64))
    if offset:
        best = res.history["offset"] if loss == "huber" else float(centre(y - fitted.simulate(v))[0])
        fitted = fitted.with_output_map(offset=best)
    return fitted, method, dict(res.history), res.interrupted, int(res.nfev)


def _identify_boucwen_projected(
    v: FloatArray, y: FloatArray, search: dict[str, Any], offset: bool, drift: DriftBasis | None, start: int
) -> _Fitted:
    """Bouc–Wen with the squared loss on the samples from ``start``, the offset (with
    ``offset``) and the ``drift`` columns projected out of every candidate's residual."""
    search.pop("validate")
    optimizer = search.pop("optimizer")
    method = "de" if optimizer == "ls" else optimizer
    family = BoucWen(1.0, 1.0, 0.0).family
    bounds = _boucwen_bounds(v, y)
    n = v.size
    cols = [np.ones((n, 1))] if offset else []
    if drift is not None:
        cols.append(drift.columns(n))
    basis = np.column_stack(cols) if cols else np.zeros((n, 0))
    scale = np.maximum(np.sqrt(np.mean(basis[start:] ** 2, axis=0)), 1e-300)
    q, _ = np.linalg.qr(basis[start:] / scale) if basis.shape[1] else (np.zeros((n - start, 0)), None)
    # with the offset projected out, a constant shift of the output changes no cost: centred,
    # the residuals' squares stay small (no cancellation in the projected sum below)
    ys = y[start:] - (float(np.mean(y[start:])) if offset else 0.0)

    def cost(rows: FloatArray) -> FloatArray:
        # |r - Q Q'r|^2 = |r|^2 - |Q'r|^2 (Q orthonormal): the best offset and drift of each
        # candidate removed without forming the projected residual (one pass over the samples
        # fewer per candidate)
        out: FloatArray = _core.batch_simulate(family, [], np.ascontiguousarray(rows), v)[..., start:]
        with np.errstate(invalid="ignore", over="ignore"):
            r = ys - out
            p = r @ q
            ss = np.einsum("...i,...i->...", r, r) - np.einsum("...i,...i->...", p, p)
            c: FloatArray = np.sqrt(np.maximum(ss, 0.0) / r.shape[-1])
        return np.where(np.isfinite(c), c, np.inf)

    res = minimize(cost, bounds, method=method, polish=True, **search)
    fitted = BoucWen(*np.asarray(res.x, dtype=np.float64))
    if basis.shape[1]:
        coef = np.linalg.lstsq(basis[start:], y[start:] - fitted.simulate(v)[start:], rcond=None)[0]
        if offset:
            fitted = fitted.with_output_map(offset=float(coef[0]))
        if drift is not None:
            fitted = fitted.with_drift(drift.drift(coef[1:] if offset else coef))
    return fitted, method, dict(res.history), res.interrupted, int(res.nfev)


def _identify_benchmark(
    u: npt.ArrayLike,
    y: npt.ArrayLike,
    fs: float | None,
    loss: str,
    search: dict[str, Any],
    options: dict[str, Any],
) -> IdentificationResult:
    """Dispatch to :func:`piezohyst.identify.boucwen_benchmark.identify_boucwen_benchmark`."""
    if loss != "squared":
        # its cost is the RMSE computed inside the Rust batch call, with its own polish
        raise ParameterError("loss = 'huber' is not available for model = 'boucwen-benchmark'; use loss = 'squared'")
    search = dict(search)
    if search["optimizer"] == "ls":
        search["optimizer"] = "de"
    rate = FS if fs is None else fs
    res = identify_boucwen_benchmark(u, y, rate, **search, **options)
    upsample, interpolation = options.get("upsample", UPSAMPLE), options.get("interpolation", "fft")
    model = res.model
    assert isinstance(model, BoucWenBenchmark)  # what identify_boucwen_benchmark identifies

    def simulator(u_: FloatArray) -> FloatArray:
        out: FloatArray = model.simulate(u_, rate, upsample, interpolation=interpolation)
        return out

    return replace(res, simulator=simulator)


# The registry: one entry per model kind, in the order of KINDS.
for _k in ("pi", "gpi", "mpi", "rdpi"):
    _register(_k, _fit_linear_kind, structure=True)
_register("preisach", _fit_linear_kind)
_register("boucwen", _fit_boucwen, iterations=200)
_register("cemf", _fit_cemf, options=True, iterations=150)
_register("boucwen-benchmark", _fit_benchmark, options=True, iterations=30)
del _k

#: Model kinds :func:`identify` accepts.
KINDS = tuple(_REGISTRY)

#: Kinds linear in their parameters: fitted by one least-squares solve (no optimizer) with the
#: default structure.
LEAST_SQUARES_KINDS = tuple(k for k, spec in _REGISTRY.items() if spec.fit is _fit_linear_kind)

#: Kinds whose structure variable projection identifies.
_VP_KINDS = tuple(k for k, spec in _REGISTRY.items() if spec.structure)
