"""Tracking and gain tuning by simulation (docs/spec.md §5, seed 1: the SMC gains are tuned with CSS
on the identified model).

:func:`track` runs one controller on a stage and returns the signals with the tracking
metrics; :func:`tune` searches controller gains with any population optimizer of
:mod:`piezohyst.optimize`, each population simulated in one Rust batch (rayon, no signals
recorded), the objective being the closed-loop tracking RMSE on the plant given — the
*identified* model, not the hardware.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any, cast

import numpy as np
import numpy.typing as npt

from .. import _core
from .._validate import as_record, as_scalar
from ..errors import ComputationError, ParameterError, ParameterTypeError
from ..optimize.report import RunReport
from .controllers import is_controller
from .simulation import (
    ClosedLoopResult,
    ControllerLike,
    FloatArray,
    RngLike,
    UserController,
    _check_reference,
    _prepare,
    closed_loop,
    seed_from,
)

if TYPE_CHECKING:  # pragma: no cover - typing only
    from ..optimize.core import IntermediateResult, Optimizer
    from ..plant.multiaxis import MultiAxisStage
    from ..plant.stage import Stage, StageParameters


__all__ = ["MultiAxisTuningResult", "TuningResult", "stage_from_model", "track", "tune", "tune_axes"]


def track(
    controller: ControllerLike | UserController,
    reference: npt.ArrayLike,
    *,
    stage: Stage | None = None,
    velocity: npt.ArrayLike | None = None,
    acceleration: npt.ArrayLike | None = None,
    rng: RngLike = None,
    skip: float = 0.0,
) -> ClosedLoopResult:
    """Track ``reference`` (m per controller sample) with ``controller`` on ``stage`` (default:
    the virtual stage). The result's ``metrics`` (RMSE, max error, % of range, linearity
    error, seed-2-style normalized errors) leave out the first ``skip`` seconds.

    Parameters
    ----------
    controller : controller configuration
        The controller (``PID``, ``SMC``, ``InverseFeedforward``, a loaded controller file, ...).
    reference : array_like
        Desired position, m per controller sample.
    stage : Stage, optional
        The plant (default: :func:`piezohyst.virtual_stage`).
    velocity, acceleration : array_like, optional
        The reference's derivatives (default: central differences, where the controller uses them).
    rng : int, numpy.random.Generator or None
        Sensor noise's seed.
    skip : float
        Seconds at the start left out of the metrics.

    Returns
    -------
    ClosedLoopResult

    Examples
    --------
    >>> import piezohyst as ph
    >>> stage = ph.virtual_stage()
    >>> t, ref = ph.sine(5, 5e-6, 0.4, 1 / stage.sample_time, offset=7e-6)
    >>> res = ph.track(ph.PID(kp=2e6, ki=2e9), ref, stage=stage, rng=1, skip=0.2)
    >>> bool(res.metrics["rmse"] < 0.1e-6)
    True
    """
    from ..plant.stage import virtual_stage

    stage = virtual_stage() if stage is None else stage
    res = closed_loop(stage, controller, reference, velocity=velocity, acceleration=acceleration, rng=rng)
    skip = as_scalar(skip, "skip", nonnegative=True)
    first = round(skip / stage.sample_time)
    if first >= res.reference.size - 1:
        raise ParameterError(f"skip = {skip} s leaves fewer than 2 of the reference's {res.reference.size} samples")
    return res._with_skip(first)


def _with_fields(controller: Any, values: Mapping[str, object]) -> Any:
    """``controller`` with fields replaced; a dotted name reaches into a wrapped controller
    (``"inner.kp"`` of a :class:`~piezohyst.Compensated`)."""
    direct = {n: v for n, v in values.items() if "." not in n}
    nested: dict[str, dict[str, object]] = {}
    for n, v in values.items():
        if "." in n:
            head, rest = n.split(".", 1)
            nested.setdefault(head, {})[rest] = v
    for head, inner in nested.items():
        direct[head] = _with_fields(getattr(controller, head), inner)
    return replace(controller, **direct) if direct else controller


def _plants(stage: Stage, stages: Sequence[Stage] | None) -> list[Stage]:
    """The plants a tuning runs on: ``stage``, or ``stage`` then ``stages``."""
    from ..plant.stage import Stage

    if stages is None:
        return [stage]
    if isinstance(stages, Stage) or not isinstance(stages, Sequence) or not stages:
        raise ParameterTypeError("stages must be a non-empty list of Stage")
    for j, s in enumerate(stages):
        if not isinstance(s, Stage):
            raise ParameterTypeError(f"stages[{j}] must be a Stage, got {type(s).__name__}")
        if s.sample_time != stage.sample_time:
            raise ParameterError(
                f"stages[{j}] runs at {s.sample_time} s, the tuning stage at {stage.sample_time} s: tune at one rate"
            )
    return [stage, *stages]


def _aggregator(aggregate: str | float) -> Callable[[FloatArray], FloatArray]:
    """Per-candidate cost over plants (axis 0): mean, worst or a percentile."""
    if aggregate == "mean":
        return lambda c: np.asarray(c.mean(axis=0))
    if aggregate == "worst":
        return lambda c: np.asarray(c.max(axis=0))
    if isinstance(aggregate, str) or isinstance(aggregate, bool):
        raise ParameterError(f"aggregate = {aggregate!r} must be 'mean', 'worst' or a percentile in (0, 100]")
    q = as_scalar(aggregate, "aggregate")
    if not 0 < q <= 100:
        raise ParameterError(f"aggregate = {q} must be 'mean', 'worst' or a percentile in (0, 100]")
    # an infinite cost (unstable, saturated) counts as the largest: percentile of +inf is inf
    return lambda c: np.asarray(np.percentile(c, q, axis=0, method="higher"))


def stage_from_model(stage: Stage, model: StageParameters) -> Stage:
    """``stage`` (amplifier, sensor, loop rate) with its physics replaced by an identified
    CEMF model (:class:`StageParameters`): the plant on which gains are tuned.

    Parameters
    ----------
    stage : Stage
        The stage whose amplifier, sensor and loop rate are kept.
    model : StageParameters
        The identified physics (e.g. :func:`piezohyst.identify_cemf`'s model).

    Returns
    -------
    Stage

    Examples
    --------
    >>> import dataclasses
    >>> import piezohyst as ph
    >>> stage = ph.virtual_stage()
    >>> model = dataclasses.replace(stage.params, mass=0.08)        # an identified model, say
    >>> plant = ph.stage_from_model(stage, model)
    >>> plant.params.mass, plant.sensor == stage.sensor
    (0.08, True)
    """
    return replace(stage, params=model)


@dataclass(frozen=True)
class TuningResult(RunReport):
    """A tuned controller and how it got there.

    ``controller`` is the best configuration; ``rmse`` its tracking RMSE on the tuning plant
    (m, averaged over the references); ``gains`` the tuned values by name; ``history`` the
    optimizer's per-iteration history; ``wall_time`` in s. ``partial`` is ``True`` when
    Ctrl-C stopped the search: the controller is the best found before it. As a
    :class:`~piezohyst.optimize.RunReport`, ``evaluations`` is ``nfev``.

    Parameters
    ----------
    controller : controller configuration
        The best configuration found.
    gains : dict
        The tuned values by name.
    rmse : float
        Its tracking RMSE on the tuning plant, m.
    history : dict
        The optimizer's per-iteration history.
    wall_time : float
        Seconds the tuning took.
    nfev : int
        Candidate configurations simulated.
    partial : bool
        Ctrl-C stopped the search.

    Examples
    --------
    >>> import numpy as np
    >>> import piezohyst as ph
    >>> stage = ph.virtual_stage()
    >>> ref = 5e-6 * (1 - np.cos(2 * np.pi * 10 * np.arange(0, 0.2, 1e-4)))
    >>> res = ph.tune(ph.PID(kp=1e6, ki=5e9), {"kp": (1e5, 1e7)}, ref, stage=stage, max_iterations=5, rng=0)
    >>> sorted(res.gains), res.evaluations, type(res.controller).__name__
    (['kp'], 100, 'PID')
    """

    controller: ControllerLike
    gains: dict[str, float]
    rmse: float
    history: dict[str, npt.NDArray[Any]]
    wall_time: float
    nfev: int
    partial: bool = False

    @property
    def evaluations(self) -> int:
        """Candidate configurations simulated (``nfev``)."""
        return self.nfev

    def _headline(self) -> str:
        return f"{type(self.controller).__name__} tuned: RMSE {self.rmse:.4g} m"

    def _scores(self) -> dict[str, float]:
        return {"rmse (m)": float(self.rmse)}


def tune(
    controller: ControllerLike | Sequence[ControllerLike],
    gains: dict[str, Sequence[float]] | Sequence[dict[str, Sequence[float]] | None],
    references: npt.ArrayLike,
    *,
    stage: Stage | MultiAxisStage | None = None,
    method: str | type[Optimizer] = "css",
    max_iterations: int = 40,
    population_size: int | None = None,
    rng: RngLike = None,
    skip: float = 0.1,
    saturation_limit: float = 0.01,
    log_scale: bool = True,
    variants: Iterable[Mapping[str, object]] | None = None,
    stages: Sequence[Stage] | None = None,
    aggregate: str | float = "mean",
    objective: str = "rmse",
    progress: bool = False,
    callback: Callable[[IntermediateResult], object] | None = None,
) -> TuningResult:
    """Tune ``gains`` of ``controller`` for the closed-loop tracking RMSE on ``stage``, or on a
    set of ``stages`` (robust tuning: worst case or a percentile over perturbed plants).

    Parameters
    ----------
    controller : controller configuration
        The template (e.g. ``SMC(model)``); its other fields stay as they are. On a
        :class:`~piezohyst.plant.MultiAxisStage`: one per axis, tuned by sequential loop
        closing (:func:`tune_axes`; ``gains`` then one box for all axes or one per axis).
    gains : dict of name -> (low, high)
        Fields to tune and their search box; a dotted name reaches into a wrapped controller
        (``"inner.kp"`` of a :class:`~piezohyst.Compensated`).
    references : array_like or list of array_like
        Reference(s), m per sample; the cost is the mean RMSE over them.
    stage : Stage, optional
        The plant to tune on — normally :func:`stage_from_model` of the identified model.
    method : {"css", "pso", "mpso", "de"}
        Population optimizer (:func:`piezohyst.optimize.minimize`).
    skip : float
        Seconds left out of each RMSE (start-up transient).
    saturation_limit : float
        Candidates whose command sits on a limit for more than this fraction of the samples
        are rejected (voltage-limit constraint); unstable sliding dynamics are rejected by the
        controller's own validation (the cost is ``inf``).
    log_scale : bool
        Search ``log10`` of the gains (all bounds must then be > 0): gains span decades.
    variants : list of dict, optional
        Field overrides the same gains must serve, e.g. ``[{"cemf": False}, {"cemf": True}]``
        (seed 1 compares its two cases with identical gains): the cost is the mean RMSE over
        every variant and reference, and a candidate must satisfy the constraints in each.
    max_iterations : int
        Populations evaluated.
    population_size : int, optional
        Candidates per population.
    rng : int, numpy.random.Generator or None
        Seeds the optimizer and the sensor noise.
    stages : list of Stage, optional
        Tune for this set of plants instead of ``stage`` alone (e.g.
        :func:`piezohyst.plant.perturbations` of the identified model's stage: the plant as
        identified and its ±20 % variants): each candidate runs on every stage (the same
        references, variants and noise seeds), must satisfy the saturation constraint on each,
        and its cost is ``aggregate`` of the per-stage costs. The controller is packed for
        ``stage`` (the nominal plant; its feedforward defaults, limits and observer delay come
        from there) and run unchanged on the others, as it would run on a stage it was not
        identified on.
    aggregate : {"mean", "worst"} or float
        How the per-stage costs combine: their mean, their maximum, or a percentile (a number
        in ``(0, 100]``; 100 is the worst case).
    objective : {"rmse", "max_error"}
        The tracking figure minimized (mean over references and variants): the RMSE
        (default) or the largest error, each from ``skip`` on (tune for the figure you report:
        seed 2's Table 4 is a normalized maximum error).
    progress : bool
        Show a progress bar on stderr.
    callback : callable, optional
        ``callback(intermediate_result)`` after each iteration.

    Returns
    -------
    TuningResult
        The best controller (its ``tuned_sample_time`` set to ``stage``'s sample time when
        it has that field), its cost (``rmse``, m) and the optimizer's history.

    Examples
    --------
    >>> import piezohyst as ph
    >>> from piezohyst.plant import perturbations
    >>> stage = ph.virtual_stage()
    >>> _, ref = ph.triangle(5, 5e-6, 0.3, 1 / stage.sample_time, offset=7e-6)
    >>> pid = ph.PID(ff_gain=1 / stage.params.static_gain)
    >>> box = {"kp": (1e4, 1e7), "ki": (1e8, 1e11)}
    >>> res = ph.tune(pid, box, ref, stage=stage, stages=perturbations(stage, ["stiffness"]),
    ...               aggregate="worst", rng=1, max_iterations=4, population_size=8)
    >>> bool(res.rmse < 0.1e-6), res.controller.tuned_sample_time
    (True, 0.0001)
    """
    from ..optimize.core import minimize
    from ..plant.multiaxis import MultiAxisStage
    from ..plant.stage import virtual_stage

    if isinstance(stage, MultiAxisStage):  # one controller per axis: sequential loop closing
        if variants is not None or stages is not None or aggregate != "mean" or callback is not None or progress:
            raise ParameterError("variants, stages, aggregate, callback and progress are single-axis options of tune")
        return tune_axes(
            stage,
            cast("Sequence[ControllerLike]", controller),
            gains,
            references,
            method=cast("str", method),
            max_iterations=max_iterations,
            population_size=population_size,
            rng=rng,
            skip=skip,
            saturation_limit=saturation_limit,
            log_scale=log_scale,
            objective=objective,
        )
    controller = cast("ControllerLike", controller)
    t0 = time.perf_counter()
    stage = virtual_stage() if stage is None else stage
    if not is_controller(controller):
        raise ParameterTypeError(f"controller must be a piezohyst controller, got {type(controller).__name__}")
    if not isinstance(gains, dict) or not gains:
        raise ParameterError("gains must be a non-empty dict of name -> (low, high)")
    names = list(gains)
    fields = getattr(controller, "__dataclass_fields__", {})
    if "tuned_sample_time" in fields and getattr(controller, "tuned_sample_time", None) is not None:
        # tuned anew at this stage's rate: the candidates run as they will run (no rate scaling)
        controller = replace(controller, tuned_sample_time=None)

    def has_field(name: str) -> bool:
        obj: object = controller
        for part in name.split("."):
            if part not in getattr(obj, "__dataclass_fields__", {}):
                return False
            obj = getattr(obj, part)
        return True

    box = []
    for n in names:
        if not has_field(n):
            raise ParameterError(f"gains: {type(controller).__name__} has no field {n!r}")
        lo, hi = (as_scalar(b, f"gains[{n!r}]") for b in gains[n])
        if not lo < hi:
            raise ParameterError(f"gains[{n!r}] = ({lo}, {hi}): low must be < high")
        if log_scale and not lo > 0:
            raise ParameterError(f"gains[{n!r}] low = {lo} must be > 0 with log_scale=True")
        box.append((math.log10(lo), math.log10(hi)) if log_scale else (lo, hi))
    items: list[npt.ArrayLike]
    if np.ndim(references) == 1:
        items = [references]
    elif isinstance(references, Iterable):
        items = list(references)
    else:
        raise ParameterTypeError(f"references must be an array or a list of arrays, got {type(references).__name__}")
    refs = [as_record(r, f"references[{j}]", min_length=2) for j, r in enumerate(items)]
    first = round(as_scalar(skip, "skip", nonnegative=True) / stage.sample_time)
    seeds = np.random.default_rng(seed_from(rng)).integers(0, 2**63 - 1, size=len(refs))

    variants = [{}] if variants is None else [dict(v) for v in variants]
    for v in variants:
        for n in v:
            if not has_field(n):
                raise ParameterError(f"variants: {type(controller).__name__} has no field {n!r}")
    plants = _plants(stage, stages)
    combine = _aggregator(aggregate)
    if objective not in ("rmse", "max_error"):
        raise ParameterError(f"objective = {objective!r} must be 'rmse' or 'max_error'")
    column = 0 if objective == "rmse" else 1

    def candidate(theta: FloatArray) -> ControllerLike:
        values = 10.0**theta if log_scale else theta
        tuned: ControllerLike = _with_fields(controller, {n: float(v) for n, v in zip(names, values, strict=False)})
        return tuned

    def cost(X: FloatArray) -> FloatArray:
        scen: list[tuple[_core._ControllerSpec, FloatArray, FloatArray, FloatArray, int]] = []
        valid: list[bool] = []
        for row in X:
            try:
                c = candidate(np.asarray(row))
                specs = [
                    (_prepare(stage, _with_fields(c, var), r, None, None), seed)
                    for var in variants
                    for r, seed in zip(refs, seeds, strict=False)
                ]
                for plant in plants[1:]:  # the references within each plant's stroke
                    for r in refs:
                        _check_reference(plant, r)
            except (ValueError, TypeError):
                valid.append(False)
                continue
            valid.append(True)
            scen.extend((spec, x, v, a, int(seed)) for (x, v, a, spec), seed in specs)
        out = np.full(len(X), np.inf)
        if scen:
            per_plant = []
            for plant in plants:
                m = plant.compiled.closed_loop_batch_tracking(scen, plant.rest_state(), first)
                m = m.reshape(-1, len(variants) * len(refs), 3)
                figure = m[:, :, column].mean(axis=1)
                figure[(m[:, :, 2] > saturation_limit).any(axis=1)] = np.inf
                per_plant.append(figure)
            out[np.flatnonzero(valid)] = combine(np.array(per_plant))
        return out

    res = minimize(
        cost,
        box,
        method=method,
        max_iterations=max_iterations,
        population_size=population_size,
        rng=rng,
        progress=progress,
        callback=callback,
    )
    if res.x is None or not np.isfinite(res.fun):
        raise ComputationError("tuning found no stable candidate within the gain bounds")
    best = candidate(res.x)
    if "tuned_sample_time" in fields:
        best = replace(best, tuned_sample_time=stage.sample_time)
    values = 10.0**res.x if log_scale else res.x
    return TuningResult(
        best,
        {n: float(v) for n, v in zip(names, values, strict=False)},
        float(res.fun),
        res.history,
        time.perf_counter() - t0,
        int(res.nfev),
        partial=res.interrupted,
    )


# -- multi-axis stages (issue 19): sequential loop closing -------------------------------


@dataclass(frozen=True)
class MultiAxisTuningResult(TuningResult):
    """Controllers of every axis tuned by sequential loop closing (:func:`tune_axes`).

    A :class:`TuningResult` whose ``controller`` is the tuple of the axes' controllers,
    ``gains`` the tuned values as ``"<axis>.<field>"``, ``rmse`` the mean of ``axis_rmse``;
    ``axes`` holds each axis's own tuning (the last pass).

    Parameters
    ----------
    controller, gains, rmse, history, wall_time, nfev, partial
        As :class:`TuningResult`.
    axes : tuple of TuningResult
        Each axis's tuning (its last pass).
    axis_rmse : ndarray
        Per-axis tracking RMSE (m) of the final controllers, all loops closed, mean over the
        references.

    Examples
    --------
    >>> import numpy as np
    >>> import piezohyst as ph
    >>> from piezohyst.plant import MultiAxisStage
    >>> s = ph.virtual_stage()
    >>> xy = MultiAxisStage.from_axes([s, s], coupling=0.05)
    >>> ref = np.column_stack([np.full(1500, 6e-6), np.full(1500, 4e-6)])
    >>> res = ph.tune([ph.PID(kp=1e6, ki=1e9)] * 2, {"ki": (1e8, 1e11)}, ref, stage=xy,
    ...               max_iterations=3, population_size=6, rng=0)
    >>> len(res.controller), sorted(res.gains), res.axis_rmse.shape
    (2, ['x.ki', 'y.ki'], (2,))
    """

    axes: tuple[TuningResult, ...] = ()
    axis_rmse: FloatArray = field(default_factory=lambda: np.zeros(0))

    def _headline(self) -> str:
        names = "/".join(type(c).__name__ for c in cast("tuple[object, ...]", self.controller))
        return f"{names} tuned per axis: RMSE {self.rmse:.4g} m"


def tune_axes(
    stage: MultiAxisStage,
    controllers: Sequence[ControllerLike],
    gains: Mapping[str, Sequence[float]] | Sequence[Mapping[str, Sequence[float]] | None],
    references: npt.ArrayLike,
    *,
    decouple: bool | npt.ArrayLike | None = None,
    passes: int = 1,
    method: str = "css",
    max_iterations: int = 40,
    population_size: int | None = None,
    rng: RngLike = None,
    skip: float = 0.1,
    saturation_limit: float = 0.01,
    log_scale: bool = True,
    objective: str = "rmse",
) -> MultiAxisTuningResult:
    """Tune each axis's controller with the other axes' loops closed (decentralized,
    sequential loop closing), each by :func:`piezohyst.tune`'s procedure and budget.

    Axis after axis (in order, ``passes`` times), the axis's ``gains`` are searched by the
    population optimizer (``method``, ``max_iterations``, ``population_size``) for the
    axis's own tracking figure (mean over ``references``), every axis tracking its
    reference: the axes before it with their tuned controllers, the axes after it with the
    ones given. A candidate whose command sits on a limit for more than ``saturation_limit``
    of the samples, or whose loop diverges, costs ``inf``. ``piezohyst.tune(controllers, ...,
    stage=multi_axis_stage)`` calls this.

    Parameters
    ----------
    stage : MultiAxisStage
        The plant (normally one built from identified models).
    controllers : sequence of controller configurations
        One template per axis.
    gains : dict, or sequence of (dict or None)
        Search box ``{field: (low, high)}``: one for every axis, or one per axis (``None``:
        leave that axis as given).
    references : array_like, shape (N, n_axes), or a list of such
        References; the cost is the mean over them.
    decouple : bool or array_like, optional
        As :func:`~piezohyst.control.multiaxis.closed_loop_multi` (tune the loops that will
        run; default: the stage's own setting, so ``tune`` on ``stage.with_decoupling()``
        tunes the decoupled loops).
    passes : int
        Sweeps over the axes (a second pass retunes each axis with the others tuned).
    method, max_iterations, population_size, rng, skip, saturation_limit, log_scale, objective
        As :func:`piezohyst.tune`.

    Returns
    -------
    MultiAxisTuningResult

    Examples
    --------
    >>> import numpy as np
    >>> import piezohyst as ph
    >>> from piezohyst.plant import MultiAxisStage
    >>> from piezohyst.control.tuning import tune_axes
    >>> s = ph.virtual_stage()
    >>> xy = MultiAxisStage.from_axes([s, s], coupling=0.05)
    >>> ref = np.column_stack([np.full(1500, 6e-6), np.full(1500, 4e-6)])
    >>> res = tune_axes(xy, [ph.PID(kp=1e6, ki=1e9)] * 2, {"ki": (1e8, 1e11)}, ref,
    ...                 max_iterations=3, population_size=6, rng=0)
    >>> bool(res.axis_rmse.max() < 0.05e-6), res.nfev
    (True, 36)
    """
    from ..optimize.core import minimize
    from ..plant.multiaxis import MultiAxisStage
    from .multiaxis import _check_signs, _controllers, _decoupling, _derivatives, _references, _seeds

    t0 = time.perf_counter()
    if not isinstance(stage, MultiAxisStage):
        raise ParameterTypeError(f"stage must be a MultiAxisStage, got {type(stage).__name__}")
    n = stage.n_axes
    ctl = _controllers(stage, controllers)
    boxes: list[Mapping[str, Sequence[float]] | None]
    if isinstance(gains, Mapping):
        boxes = [gains] * n
    elif isinstance(gains, Sequence) and len(gains) == n:
        boxes = list(gains)
    else:
        raise ParameterError(f"gains must be a dict or a list of {n} dicts (or None), one per axis")
    if all(not b for b in boxes):
        raise ParameterError("gains names no field to tune on any axis")
    if objective not in ("rmse", "max_error"):
        raise ParameterError(f"objective = {objective!r} must be 'rmse' or 'max_error'")
    passes = int(passes)
    if passes < 1:
        raise ParameterError(f"passes = {passes} must be >= 1")
    items = [references] if np.ndim(references) == 2 else list(cast("Sequence[npt.ArrayLike]", references))
    refs = [_references(stage, r, f"references[{j}]") for j, r in enumerate(items)]
    derivs = [_derivatives(r, stage.sample_time, ctl) for r in refs]
    seeds = _seeds(rng, n)
    first = round(as_scalar(skip, "skip", nonnegative=True) / stage.sample_time)
    if first >= min(r.shape[0] for r in refs) - 1:
        raise ParameterError(f"skip = {skip} s leaves fewer than 2 samples of a reference")
    t = _decoupling(stage, decouple)
    _check_signs(stage, t)
    column = 0 if objective == "rmse" else 1
    fields_of = {i: list(b) for i, b in enumerate(boxes) if b}
    bounds: dict[int, list[tuple[float, float]]] = {}
    for i, names in fields_of.items():
        box = boxes[i]
        assert box is not None
        bounds[i] = []
        for nm in names:
            if nm not in getattr(ctl[i], "__dataclass_fields__", {}) and "." not in nm:
                raise ParameterError(f"gains: {type(ctl[i]).__name__} (axis {stage.names[i]}) has no field {nm!r}")
            lo, hi = (as_scalar(b, f"gains[{nm!r}]") for b in box[nm])
            if not lo < hi:
                raise ParameterError(f"gains[{nm!r}] = ({lo}, {hi}): low must be < high")
            if log_scale and not lo > 0:
                raise ParameterError(f"gains[{nm!r}] low = {lo} must be > 0 with log_scale=True")
            bounds[i].append((float(np.log10(lo)), float(np.log10(hi))) if log_scale else (lo, hi))

    def figures(candidates: list[list[ControllerLike]]) -> FloatArray:
        """``(S, n_axes, 3)`` figures, mean over the references (saturation: the worst)."""
        specs = [[c.core(v) for c, v in zip(row, stage.views, strict=True)] for row in candidates]
        out = []
        for r, (v, a) in zip(refs, derivs, strict=True):
            out.append(stage.compiled.closed_loop_batch_tracking(specs, r, v, a, seeds, first, t))
        m = np.array(out)  # (R, S, N, 3)
        res = m.mean(axis=0)
        res[:, :, 2] = m[:, :, :, 2].max(axis=0)
        return np.asarray(res, dtype=np.float64)

    tuned = list(ctl)
    per_axis: dict[int, TuningResult] = {}
    nfev = 0
    history: dict[str, Any] = {}
    for _ in range(passes):
        for i, names in fields_of.items():
            ti = time.perf_counter()
            template = tuned[i]
            fields = getattr(template, "__dataclass_fields__", {})
            if "tuned_sample_time" in fields and getattr(template, "tuned_sample_time", None) is not None:
                template = replace(cast("Any", template), tuned_sample_time=None)

            def candidate(theta: FloatArray, template: Any = template, names: list[str] = names) -> ControllerLike:
                values = 10.0**theta if log_scale else theta
                return cast(
                    "ControllerLike",
                    _with_fields(template, {nm: float(v) for nm, v in zip(names, values, strict=True)}),
                )

            def cost(X: FloatArray, i: int = i, candidate: Any = candidate) -> FloatArray:
                rows: list[list[ControllerLike]] = []
                valid: list[int] = []
                for j, row in enumerate(X):
                    try:
                        c = candidate(np.asarray(row))
                        c.core(stage.views[i])  # validates the gains
                    except (ValueError, TypeError):
                        continue
                    rows.append([*tuned[:i], c, *tuned[i + 1 :]])
                    valid.append(j)
                out = np.full(len(X), np.inf)
                if rows:
                    f = figures(rows)
                    fig = f[:, i, column].copy()
                    fig[f[:, i, 2] > saturation_limit] = np.inf
                    fig[~np.all(np.isfinite(f[:, :, 0]), axis=1)] = np.inf
                    out[np.array(valid)] = fig
                return out

            res = minimize(
                cost,
                bounds[i],
                method=method,
                max_iterations=max_iterations,
                population_size=population_size,
                rng=rng,
            )
            if res.x is None or not np.isfinite(res.fun):
                raise ComputationError(f"tuning axis {stage.names[i]} found no stable candidate within the gain bounds")
            best = candidate(res.x)
            if "tuned_sample_time" in fields:
                best = cast("ControllerLike", replace(cast("Any", best), tuned_sample_time=stage.sample_time))
            tuned[i] = best
            values = 10.0**res.x if log_scale else res.x
            per_axis[i] = TuningResult(
                best,
                {nm: float(v) for nm, v in zip(names, values, strict=True)},
                float(res.fun),
                res.history,
                time.perf_counter() - ti,
                int(res.nfev),
                partial=res.interrupted,
            )
            history = res.history
            nfev += int(res.nfev)
    final = figures([tuned])[0]
    axis_rmse = final[:, column].astype(np.float64)
    gains_out = {f"{stage.names[i]}.{k}": v for i, r in per_axis.items() for k, v in r.gains.items()}
    return MultiAxisTuningResult(
        cast("ControllerLike", tuple(tuned)),
        gains_out,
        float(axis_rmse.mean()),
        history,
        time.perf_counter() - t0,
        nfev,
        partial=any(r.partial for r in per_axis.values()),
        axes=tuple(per_axis[i] for i in sorted(per_axis)),
        axis_rmse=axis_rmse,
    )
