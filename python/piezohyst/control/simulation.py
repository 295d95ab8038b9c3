"""Closed-loop simulation: controller at its sample time, amplifier and stage with
sub-steps, sensor with noise, quantization and delay. The loop runs in the Rust core
(``crates/core/src/plant/closed_loop.rs``); a batch of scenarios runs in parallel.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import Field
from functools import cached_property, lru_cache
from typing import TYPE_CHECKING, Any, ClassVar, Protocol, Self, TypeAlias

import numpy as np
import numpy.typing as npt

from .. import _core
from .._validate import as_record
from ..errors import ParameterError, ParameterTypeError
from ..signals.metrics import tracking_metrics
from ..signals.response import MatSignals, Response
from ..signals.results import require_pandas
from .controllers import check_sample_rate, is_controller

if TYPE_CHECKING:  # pragma: no cover - typing only
    import pandas as pd
    from matplotlib.figure import Figure

    from ..plant.stage import Stage

FloatArray: TypeAlias = npt.NDArray[np.float64]
RngLike: TypeAlias = int | np.integer[Any] | np.random.Generator | None
"""A noise seed: a non-negative int, a NumPy ``Generator`` or ``None`` (seed 0)."""


class ControllerLike(Protocol):
    """What the closed loop runs: a controller configuration (a frozen dataclass such as
    :class:`~piezohyst.PID`) that packs itself for the core."""

    __dataclass_fields__: ClassVar[dict[str, Field[Any]]]

    def core(self, stage: Stage) -> _core._ControllerSpec: ...


class UserController(Protocol):
    """A controller written in Python: any object with ``step(reference, measured) ->
    command`` (m, m -> V), optionally ``reset(measured)`` (called once with the first reading
    before the run) and ``uses_reference_derivatives = True`` (then ``step(reference,
    measured, velocity, acceleration)``). :func:`closed_loop` runs it from the Rust loop, one
    Python call per sample: the slow path (about a microsecond of Python per sample, against
    tens of nanoseconds for a packaged controller), for prototyping a law before writing it in
    Rust.

    Parameters
    ----------
    *args, **kwargs
        None: a protocol is a type to check against, not a class to instantiate; any class
        with a matching ``step`` is a ``UserController``.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst import closed_loop, virtual_stage
    >>> class Integral:
    ...     def __init__(self, ki, ts):
    ...         self.ki, self.ts, self.u, self.calls = ki, ts, 0.0, 0
    ...     def step(self, reference, measured):
    ...         self.calls += 1
    ...         self.u += self.ki * self.ts * (reference - measured)
    ...         return self.u
    >>> stage = virtual_stage()
    >>> t = np.arange(0, 0.05, stage.sample_time)
    >>> ref = 10e-6 * (1 - np.cos(2 * np.pi * 20 * t)) / 2
    >>> law = Integral(2e9, stage.sample_time)
    >>> r = closed_loop(stage, law, ref)
    >>> law.calls == ref.size, round(r.metrics["rmse_percent"], 1)     # one call per sample
    (True, 16.7)
    """

    def step(self, reference: float, measured: float, /) -> float:
        """The command for this sample.

        Parameters
        ----------
        reference : float
            The reference position, m.
        measured : float
            The sensor's reading, m.

        Returns
        -------
        float
            The command, V.

        Examples
        --------
        >>> class Proportional:
        ...     def step(self, reference, measured):
        ...         return 1e5 * (reference - measured)
        >>> round(Proportional().step(2e-6, 1e-6), 12)
        0.1
        """
        ...


__all__ = [
    "ClosedLoopResult",
    "UserController",
    "closed_loop",
    "closed_loop_batch",
    "closed_loop_batch_stages",
    "closed_loop_perturbed",
    "seed_from",
]


def seed_from(rng: RngLike) -> int:
    """A 63-bit seed for the core's noise generator from an int, a Generator or None (0).

    Parameters
    ----------
    rng : int, numpy.random.Generator or None
        A non-negative int (the same seed each time), a Generator (advanced by one draw) or
        ``None``.

    Returns
    -------
    int
        The seed, in ``[0, 2**63 - 1)``.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.control.simulation import seed_from
    >>> seed_from(None), seed_from(3) == seed_from(3), seed_from(3) == seed_from(4)
    (0, True, False)
    >>> g = np.random.default_rng(1)
    >>> seed_from(g) == seed_from(g)                            # the Generator advances
    False
    """
    if rng is None:
        return 0
    if isinstance(rng, np.random.Generator):
        return int(rng.integers(0, 2**63 - 1))
    if isinstance(rng, (int, np.integer)) and not isinstance(rng, bool):
        if rng < 0:
            raise ParameterError(f"rng = {rng} must be a non-negative int or a numpy Generator")
        return _seed_of_int(int(rng))
    raise ParameterTypeError(f"rng must be an int, a numpy.random.Generator or None, got {type(rng).__name__}")


@lru_cache(maxsize=1024)
def _seed_of_int(rng: int) -> int:
    # a fresh Generator costs ~20 us, a noticeable part of a short run's overhead
    return int(np.random.default_rng(rng).integers(0, 2**63 - 1))


class ClosedLoopResult(Response):
    """Signals of one closed-loop run, one value per controller sample: a
    :class:`~piezohyst.signals.Response` whose input is ``reference``.

    ``position`` is the true position at ``time``; ``measured`` the sensor reading the
    controller used at that sample; ``command`` the controller output; ``voltage`` the
    amplifier output at the end of the period; ``terms`` the controller's internal terms
    (also signals ``term_<name>``). ``skip_samples`` is the number of first samples the
    ``metrics`` leave out (set by :func:`piezohyst.track`). The title is ``controller``.

    Parameters
    ----------
    sample_time : float
        Controller period, s.
    reference, command, voltage, position, measured : array_like, shape (N,)
        The signals (m, V, V, m, m).
    terms : mapping of str to array_like, shape (N,)
        The controller's internal terms.
    final_state : array_like
        Stage state at the end ``[va, x, v, vh, creep[8]]``.
    controller : str
        Name of the controller that ran.
    skip_samples : int
        First samples left out of ``metrics`` (default 0).

    Examples
    --------
    >>> import numpy as np
    >>> import piezohyst as ph
    >>> res = ph.closed_loop(ph.virtual_stage(), ph.PID(kp=1e6, ki=5e9), np.full(1000, 5e-6), rng=1)
    >>> res.n_time, res.units["position"], sorted(res.terms)[:2]
    (1000, 'm', ['D', 'I'])
    >>> bool(np.allclose(res.error, res.reference - res.position))
    True
    """

    sample_time: float
    terms: dict[str, FloatArray]
    final_state: FloatArray
    controller: str
    skip_samples: int

    def __init__(
        self,
        sample_time: float,
        reference: npt.ArrayLike,
        command: npt.ArrayLike,
        voltage: npt.ArrayLike,
        position: npt.ArrayLike,
        measured: npt.ArrayLike,
        terms: Mapping[str, npt.ArrayLike],
        final_state: npt.ArrayLike,
        controller: str = "",
        skip_samples: int = 0,
    ) -> None:
        ts = float(sample_time)
        ref = np.asarray(reference, dtype=np.float64)
        signals: dict[str, npt.ArrayLike] = {
            "reference": ref,
            "command": command,
            "voltage": voltage,
            "position": position,
            "measured": measured,
        }
        signals.update({f"term_{k}": v for k, v in terms.items()})
        super().__init__(
            np.arange(ref.size) * ts,
            signals,
            inputs=["reference"],
            units={"reference": "m", "command": "V", "voltage": "V", "position": "m", "measured": "m"},
            final_state=final_state,
            title=controller,
        )
        object.__setattr__(self, "sample_time", ts)
        object.__setattr__(self, "terms", {k: self.signals[f"term_{k}"] for k in terms})
        object.__setattr__(self, "controller", str(controller))
        object.__setattr__(self, "skip_samples", int(skip_samples))

    # the signals, typed (Response also reads them by name)
    @property
    def reference(self) -> FloatArray:
        """Desired position per sample, m."""
        return self.signals["reference"]

    @property
    def command(self) -> FloatArray:
        """Controller output per sample, V."""
        return self.signals["command"]

    @property
    def voltage(self) -> FloatArray:
        """Amplifier output at the end of each period, V."""
        return self.signals["voltage"]

    @property
    def position(self) -> FloatArray:
        """True position at ``time``, m."""
        return self.signals["position"]

    @property
    def measured(self) -> FloatArray:
        """Sensor reading the controller used at each sample, m."""
        return self.signals["measured"]

    def _mat_fields(self) -> dict[str, Any]:
        return {
            "sample_time": self.sample_time,
            "controller": self.controller,
            "skip_samples": self.skip_samples,
            "terms": list(self.terms),
        }

    @classmethod
    def _from_mat_fields(cls, f: MatSignals) -> Self:
        s, final_state, extra = f.signals, f.final_state, f.extra
        terms = {str(k): s[f"term_{k}"] for k in extra["terms"]}
        state = np.zeros(0) if final_state is None else final_state
        return cls(
            float(extra["sample_time"]),
            s["reference"],
            s["command"],
            s["voltage"],
            s["position"],
            s["measured"],
            terms,
            state,
            str(extra["controller"]),
            int(extra["skip_samples"]),
        )

    def _with_skip(self, k: int) -> ClosedLoopResult:
        """The same run with ``metrics`` leaving out the first ``k`` samples."""
        return type(self)(
            self.sample_time,
            self.reference,
            self.command,
            self.voltage,
            self.position,
            self.measured,
            self.terms,
            self.final_state,
            self.controller,
            k,
        )

    @cached_property
    def metrics(self) -> dict[str, float]:
        """Tracking metrics of ``position`` against ``reference`` (see
        :func:`piezohyst.metrics.tracking_metrics`): RMSE and max error (m, and % of the
        reference range), seed-2-style normalized errors and the linearity error; from sample
        ``skip_samples`` on (set by :func:`piezohyst.track`); computed on first use."""
        k = self.skip_samples
        return tracking_metrics(self.reference[k:], self.position[k:])

    @property
    def error(self) -> FloatArray:
        """Tracking error ``reference - position``, m."""
        return self.reference - self.position

    def to_pandas(self) -> pd.DataFrame:
        """The signals as a ``pandas.DataFrame`` indexed by time (needs pandas: without it an
        ``ImportError`` says ``pip install pandas``).

        Returns
        -------
        pandas.DataFrame
            Columns ``reference``, ``command``, ``voltage``, ``position``, ``measured``,
            ``error`` and ``term_<name>``.

        Examples
        --------
        >>> import numpy as np
        >>> import piezohyst as ph
        >>> res = ph.closed_loop(ph.virtual_stage(), ph.PID(kp=1e6), np.full(100, 1e-6), rng=1)
        >>> try:
        ...     df = res.to_pandas()
        ... except ImportError:           # pandas is optional
        ...     df = None
        >>> df is None or list(df.columns)[:3] == ["reference", "command", "voltage"]
        True
        """
        pd = require_pandas(type(self).__name__)
        cols = {
            "reference": self.reference,
            "command": self.command,
            "voltage": self.voltage,
            "position": self.position,
            "measured": self.measured,
            "error": self.error,
        }
        cols.update({f"term_{k}": v for k, v in self.terms.items()})
        return pd.DataFrame(cols, index=pd.Index(self.time, name="time"))

    def plot(
        self, signals: Sequence[str] | None = None, *, zoom: tuple[float, float] | None = None, ax: Any = None
    ) -> Figure:
        """Tracking (µm) with the error below; ``zoom=(t0, t1)`` adds an inset window.

        Naming ``signals`` gives :meth:`Response.plot`'s panels (one per unit) instead.

        Parameters
        ----------
        signals : sequence of str, optional
            Signals to draw as :meth:`Response.plot` does.
        zoom : (float, float), optional
            Time window of an inset, s.
        ax : sequence of 2 matplotlib axes, optional
            Where to draw tracking and error (default: a new figure).

        Returns
        -------
        matplotlib.figure.Figure

        Examples
        --------
        >>> import numpy as np
        >>> import matplotlib.pyplot as plt
        >>> import piezohyst as ph
        >>> res = ph.closed_loop(ph.virtual_stage(), ph.PID(kp=1e6, ki=5e9), np.full(1000, 5e-6), rng=1)
        >>> fig = res.plot(zoom=(0.0, 0.01))
        >>> [a.get_ylabel() for a in fig.axes[:2]]
        ['position (µm)', 'error (µm)']
        >>> plt.close(fig)
        """
        if signals is not None:
            return super().plot(signals, ax=ax)
        import matplotlib.pyplot as plt

        if ax is None:
            fig, ax = plt.subplots(2, 1, sharex=True, figsize=(8, 5))
        else:
            fig = ax[0].figure
        ax[0].plot(self.time, self.reference * 1e6, "k--", lw=1, label="reference")
        ax[0].plot(self.time, self.position * 1e6, lw=1, label=self.controller or "position")
        ax[0].set_ylabel("position (µm)")
        ax[0].legend(loc="upper right")
        ax[1].plot(self.time, self.error * 1e6, lw=0.8)
        ax[1].set_ylabel("error (µm)")
        ax[1].set_xlabel("time (s)")
        if zoom is not None:
            t0, t1 = zoom
            inset = ax[0].inset_axes([0.05, 0.55, 0.3, 0.4])
            sel = (self.time >= t0) & (self.time <= t1)
            inset.plot(self.time[sel], self.reference[sel] * 1e6, "k--", lw=1)
            inset.plot(self.time[sel], self.position[sel] * 1e6, lw=1)
            ax[0].indicate_inset_zoom(inset)
        return fig


def _derivatives(
    x: FloatArray, ts: float, velocity: npt.ArrayLike | None, acceleration: npt.ArrayLike | None, needed: bool
) -> tuple[FloatArray, FloatArray]:
    """Reference velocity and acceleration: given, or central differences when the controller
    uses them, or empty (the core reads zeros) when it does not."""
    if velocity is not None:
        v = as_record(velocity, "velocity")
    else:
        v = np.gradient(x, ts) if needed else _EMPTY
    if acceleration is not None:
        a = as_record(acceleration, "acceleration")
    elif needed or velocity is not None:
        a = np.gradient(v, ts) if v.size else _EMPTY
    else:
        a = _EMPTY
    return v, a


_EMPTY: FloatArray = np.zeros(0)


def _check_reference(stage: Stage, x: FloatArray) -> None:
    """Finite and within the stroke (two reductions over ``x``; the error names the first
    offending sample: a non-finite one before one beyond the stroke, as before)."""
    lowest, highest = x.min(), x.max()
    if not (np.isfinite(lowest) and np.isfinite(highest)):
        as_record(x, "reference")  # raises, naming the first NaN/inf
    a = stage.amplifier
    lo, hi = stage.stroke()
    if lowest < lo or highest > hi:
        k = int(np.flatnonzero((x < lo) | (x > hi))[0])
        raise ParameterError(
            f"reference[{k}] = {x[k]:.6g} m is beyond the stage's stroke "
            f"[{lo:.3g}, {hi:.3g}] m for amplifier range [{a.v_min}, {a.v_max}] V"
        )


def _prepare(
    stage: Stage,
    controller: ControllerLike,
    reference: npt.ArrayLike,
    velocity: npt.ArrayLike | None,
    acceleration: npt.ArrayLike | None,
) -> tuple[FloatArray, FloatArray, FloatArray, _core._ControllerSpec]:
    if not is_controller(controller):
        raise ParameterTypeError(
            f"controller must be a piezohyst controller (OpenLoop, PID, ...), got {type(controller).__name__}"
        )
    # no copy here: the core returns the result's own copy of the reference; NaN/inf are
    # found by _check_reference's min/max (one pass less than as_record's own check)
    x = as_record(reference, "reference", min_length=2, copy=False, finite=False)
    _check_reference(stage, x)
    v, a = _derivatives(
        x, stage.sample_time, velocity, acceleration, getattr(controller, "uses_reference_derivatives", True)
    )
    if v.size not in (0, x.size) or a.size not in (0, x.size):
        raise ParameterError(f"velocity/acceleration must have the reference's length {x.size}")
    return x, v, a, controller.core(stage)


def _result(stage: Stage, d: Mapping[str, Any], controller: object) -> ClosedLoopResult:
    names = list(d["term_names"])
    terms = {n: d["terms"][:, i] for i, n in enumerate(names)}
    return ClosedLoopResult(
        sample_time=stage.sample_time,
        reference=d["reference"],
        command=d["command"],
        voltage=d["voltage"],
        position=d["position"],
        measured=d["measured"],
        terms=terms,
        final_state=np.asarray(d["final_state"]),
        controller=type(controller).__name__,
    )


def closed_loop(
    stage: Stage,
    controller: ControllerLike | UserController,
    reference: npt.ArrayLike,
    *,
    velocity: npt.ArrayLike | None = None,
    acceleration: npt.ArrayLike | None = None,
    rng: RngLike = None,
    initial_state: npt.ArrayLike | None = None,
) -> ClosedLoopResult:
    """Run ``controller`` on ``stage`` tracking ``reference`` (m, one value per sample).

    Parameters
    ----------
    stage : Stage
        Plant, amplifier, sensor and loop rate (e.g. :func:`piezohyst.virtual_stage`).
    controller : OpenLoop, PID, ... or UserController
        A packaged controller (its step runs in Rust), or any object with
        ``step(reference, measured) -> command`` (:class:`UserController`: called from the
        Rust loop once per sample, the slow path).
    reference : array_like
        Desired position per controller sample, m. Must stay within the stage's stroke.
    velocity, acceleration : array_like, optional
        Reference derivatives; by default central differences of ``reference``.
    rng : int or numpy.random.Generator, optional
        Sensor-noise seed; same seed, same run.
    initial_state : array_like, optional
        Stage state ``[va, x, v, vh, creep[8]]`` (default: at rest).

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst import PID, closed_loop, virtual_stage
    >>> stage = virtual_stage()
    >>> t = np.arange(0, 0.2, stage.sample_time)
    >>> ref = 10e-6 * (1 - np.cos(2 * np.pi * 10 * t)) / 2
    >>> res = closed_loop(stage, PID(kp=2e6, ki=2e9), ref, rng=1)
    >>> bool(res.metrics["rmse"] < 0.2e-6)
    True
    """
    init = stage.rest_state() if initial_state is None else as_record(initial_state, "initial_state")
    if not is_controller(controller) and callable(getattr(controller, "step", None)):
        return _closed_loop_python(stage, controller, reference, velocity, acceleration, rng, init)
    x, v, a, spec = _prepare(stage, controller, reference, velocity, acceleration)  # type: ignore[arg-type]
    check_sample_rate(controller, stage.sample_time)
    d = stage.compiled.closed_loop(_core.Scenario(spec, x, v, a, seed_from(rng)), init)
    return _result(stage, d, controller)


def _closed_loop_python(
    stage: Stage,
    controller: Any,
    reference: npt.ArrayLike,
    velocity: npt.ArrayLike | None,
    acceleration: npt.ArrayLike | None,
    rng: RngLike,
    init: FloatArray,
) -> ClosedLoopResult:
    """The slow path of :func:`closed_loop`: a :class:`UserController` called per sample."""
    x = as_record(reference, "reference", min_length=2)
    _check_reference(stage, x)
    derivatives = bool(getattr(controller, "uses_reference_derivatives", False))
    v, a = _derivatives(x, stage.sample_time, velocity, acceleration, derivatives)
    if v.size not in (0, x.size) or a.size not in (0, x.size):
        raise ParameterError(f"velocity/acceleration must have the reference's length {x.size}")
    user_step = controller.step
    reset = getattr(controller, "reset", None)
    first = [True]

    def step(r: float, vel: float, acc: float, y: float) -> float:
        if first[0]:
            first[0] = False
            if callable(reset):
                reset(y)
        out = user_step(r, y, vel, acc) if derivatives else user_step(r, y)
        return float(out)

    d = stage.compiled.closed_loop_python(step, x, v, a, seed_from(rng), init)
    return _result(stage, d, controller)


def closed_loop_batch(
    stage: Stage,
    scenarios: Iterable[tuple[ControllerLike, npt.ArrayLike]],
    *,
    rng: RngLike = None,
    initial_state: npt.ArrayLike | None = None,
) -> list[ClosedLoopResult]:
    """Run many ``(controller, reference)`` scenarios in parallel on one stage.

    Each scenario gets its own noise seed drawn from ``rng``; results are identical whatever
    the number of threads.

    Parameters
    ----------
    stage : Stage
        The plant.
    scenarios : iterable of (controller, reference)
        Each a controller configuration and its reference (m per sample).
    rng : int, numpy.random.Generator or None
        Source of the scenarios' noise seeds.
    initial_state : array_like, optional
        The stage's state at the start of every scenario (default: at rest).

    Returns
    -------
    list of ClosedLoopResult

    Examples
    --------
    >>> import numpy as np
    >>> import piezohyst as ph
    >>> stage = ph.virtual_stage()
    >>> ref = np.full(2000, 5e-6)
    >>> runs = ph.closed_loop_batch(stage, [(ph.PID(kp=k, ki=5e9), ref) for k in (5e5, 1e6, 2e6)], rng=1)
    >>> len(runs), [r.controller.split("(")[0] for r in runs]
    (3, ['PID', 'PID', 'PID'])
    """
    seeds_rng = np.random.default_rng(seed_from(rng))
    init = stage.rest_state() if initial_state is None else as_record(initial_state, "initial_state")
    prepared: list[ControllerLike] = []
    core: list[tuple[_core._ControllerSpec, FloatArray, FloatArray, FloatArray, int]] = []
    for j, item in enumerate(scenarios):
        try:
            controller, reference = item
        except (TypeError, ValueError):
            raise ParameterTypeError(f"scenarios[{j}] must be a (controller, reference) pair") from None
        try:
            x, v, a, spec = _prepare(stage, controller, reference, None, None)
        except (ValueError, TypeError) as e:
            raise type(e)(f"scenarios[{j}]: {e}") from None
        check_sample_rate(controller, stage.sample_time)
        prepared.append(controller)
        core.append((spec, x, v, a, int(seeds_rng.integers(0, 2**63 - 1))))
    out = stage.compiled.closed_loop_batch(core, init)
    return [_result(stage, d, c) for c, d in zip(prepared, out, strict=False)]


def closed_loop_batch_stages(
    stage: Stage,
    controller: ControllerLike,
    reference: npt.ArrayLike,
    params: npt.ArrayLike,
    seeds: npt.ArrayLike,
    *,
    skip: int = 0,
    initial_state: npt.ArrayLike | None = None,
) -> FloatArray:
    """Tracking figures of ``controller`` (packed for ``stage``, the nominal stage it was designed
    for) on many stages: row ``j`` of ``params`` (``(S, STAGE_PARAM_LEN)``, the layout of
    :meth:`Stage.core_params`) is the plant of run ``j``, with ``stage``'s amplifier rows as given,
    control period, integration settings and sensor, and ``seeds[j]`` its sensor-noise seed.

    Returns an ``(S, 3)`` array ``[rmse, max_error, saturated_fraction]`` of ``reference - true
    position`` from sample ``skip`` on (``inf`` for a run that diverged). One rayon task per row in
    the Rust core, the GIL released; row ``j``'s figures depend on row ``j`` and ``seeds[j]`` only
    (the same bits whatever the number of threads or how the rows are split into calls).

    Parameters
    ----------
    stage : Stage
        The nominal stage the controller is packed for.
    controller : PID, FilteredPID, ...
        The controller configuration.
    reference : array_like, shape (N,)
        The reference position, m, one value per control period.
    params : array_like, shape (S, STAGE_PARAM_LEN)
        One plant per row, in the layout of :meth:`Stage.core_params`.
    seeds : array_like of int, shape (S,)
        Each run's sensor-noise seed (non-negative).
    skip : int, optional
        First samples left out of the figures.
    initial_state : array_like, optional
        Every run's initial stage state (default: the stage at rest).

    Returns
    -------
    ndarray, shape (S, 3)
        ``[rmse, max_error, saturated_fraction]`` per row.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst import PID, closed_loop, virtual_stage
    >>> stage = virtual_stage()
    >>> t = np.arange(0, 0.05, stage.sample_time)
    >>> ref = 10e-6 * (1 - np.cos(2 * np.pi * 20 * t)) / 2
    >>> rows = np.tile(stage.core_params(), (3, 1))
    >>> rows[1, 2] *= 1.2  # a 20 % stiffer part
    >>> m = closed_loop_batch_stages(stage, PID(kp=2e6, ki=2e9), ref, rows, np.array([5, 5, 6], dtype=np.uint64))
    >>> m.shape, bool(m[0, 0] != m[1, 0]), bool(m[0, 0] != m[2, 0])
    ((3, 3), True, True)
    """
    x, v, a, spec = _prepare(stage, controller, reference, None, None)
    rows = np.ascontiguousarray(params, dtype=np.float64)
    if rows.ndim != 2:
        raise ParameterError(f"params must be a 2-D array (S, {_core.STAGE_PARAM_LEN}), got shape {rows.shape}")
    s = np.asarray(seeds)
    if s.ndim != 1 or not (np.issubdtype(s.dtype, np.integer) and (s.size == 0 or s.min() >= 0)):
        raise ParameterError("seeds must be a 1-D array of non-negative integers, one per row of params")
    init = stage.rest_state() if initial_state is None else as_record(initial_state, "initial_state")
    if isinstance(skip, bool) or not isinstance(skip, (int, np.integer)) or skip < 0:
        raise ParameterError(f"skip = {skip!r} must be a non-negative int (samples)")
    scenario = _core.Scenario(spec, x, v, a, 0)
    return stage.compiled.closed_loop_batch_stages(rows, scenario, s.astype(np.uint64), init, int(skip))


def closed_loop_perturbed(
    stage: Stage,
    controller: ControllerLike,
    reference: npt.ArrayLike,
    params: npt.ArrayLike,
    seed: int,
    *,
    skip: int = 0,
    initial_state: npt.ArrayLike | None = None,
) -> ClosedLoopResult:
    """One run of :func:`closed_loop_batch_stages` with its signals: ``controller`` packed for
    ``stage`` (the nominal stage) runs on the plant of the parameter row ``params`` with sensor-noise
    seed ``seed`` (the core's seed, as given). The metrics leave out the first ``skip`` samples, so
    ``rmse`` and ``max_error`` are the batch's row to rounding.

    Parameters
    ----------
    stage : Stage
        The nominal stage the controller is packed for.
    controller : PID, FilteredPID, ...
        The controller configuration.
    reference : array_like, shape (N,)
        The reference position, m, one value per control period.
    params : array_like, shape (STAGE_PARAM_LEN,)
        The plant, in the layout of :meth:`Stage.core_params`.
    seed : int
        The sensor-noise seed, in ``[0, 2**64)``.
    skip : int, optional
        First samples left out of the metrics.
    initial_state : array_like, optional
        The initial stage state (default: the stage at rest).

    Returns
    -------
    ClosedLoopResult

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst import PID, virtual_stage
    >>> from piezohyst.control.simulation import closed_loop_batch_stages, closed_loop_perturbed
    >>> stage = virtual_stage()
    >>> t = np.arange(0, 0.05, stage.sample_time)
    >>> ref = 10e-6 * (1 - np.cos(2 * np.pi * 20 * t)) / 2
    >>> row = stage.core_params().copy()
    >>> row[2] *= 1.2                                           # a 20 % stiffer part
    >>> pid = PID(kp=2e6, ki=2e9)
    >>> r = closed_loop_perturbed(stage, pid, ref, row, 5, skip=100)
    >>> m = closed_loop_batch_stages(stage, pid, ref, row[None, :], np.array([5], dtype=np.uint64), skip=100)
    >>> bool(np.isclose(r.metrics["rmse"], m[0, 0], rtol=1e-9)), r.position.shape
    (True, (500,))
    """
    x, v, a, spec = _prepare(stage, controller, reference, None, None)
    row = as_record(params, "params")
    s = stage.sensor
    plant = _core.Stage(row, stage.sample_time, stage.substeps, stage.tolerance, s.quantization, s.noise_std, s.delay)
    init = stage.rest_state() if initial_state is None else as_record(initial_state, "initial_state")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= seed < 2**64:
        raise ParameterError(f"seed = {seed!r} must be an integer in [0, 2**64)")
    d = plant.closed_loop(_core.Scenario(spec, x, v, a, int(seed)), init)
    return _result(stage, d, controller)._with_skip(int(skip))
