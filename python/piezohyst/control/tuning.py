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
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

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
    from ..plant.stage import Stage, StageParameters


__all__ = ["TuningResult", "stage_from_model", "track", "tune"]


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
    controller: ControllerLike,
    gains: dict[str, Sequence[float]],
    references: npt.ArrayLike,
    *,
    stage: Stage | None = None,
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
        The template (e.g. ``SMC(model)``); its other fields stay as they are.
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
    from ..plant.stage import virtual_stage

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
