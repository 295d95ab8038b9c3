"""Closed-loop simulation: controller at its sample time, amplifier and stage with
sub-steps, sensor with noise, quantization and delay. The loop runs in the Rust core
(``crates/core/src/plant/closed_loop.rs``); a batch of scenarios runs in parallel.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from .. import _core
from .._validate import as_record
from ..errors import ParameterError, ParameterTypeError
from ..signals.metrics import tracking_metrics
from .controllers import is_controller

__all__ = ["ClosedLoopResult", "closed_loop", "closed_loop_batch", "seed_from"]


def seed_from(rng) -> int:
    """A 63-bit seed for the core's noise generator from an int, a Generator or None (0)."""
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


@dataclass(frozen=True)
class ClosedLoopResult:
    """Signals of one closed-loop run, one value per controller sample.

    ``position`` is the true position at ``time``; ``measured`` the sensor reading the
    controller used at that sample; ``command`` the controller output; ``voltage`` the
    amplifier output at the end of the period; ``terms`` the controller's internal terms.
    """

    sample_time: float
    reference: np.ndarray
    command: np.ndarray
    voltage: np.ndarray
    position: np.ndarray
    measured: np.ndarray
    terms: dict
    final_state: np.ndarray
    controller: str = ""

    @property
    def time(self) -> np.ndarray:
        """Sample instants, s."""
        return np.arange(self.reference.size) * self.sample_time

    @property
    def metrics(self) -> dict:
        """Tracking metrics of ``position`` against ``reference`` (see
        :func:`piezohyst.metrics.tracking_metrics`): RMSE and max error (m, and % of the
        reference range), seed-2-style normalized errors and the linearity error; from sample
        ``skip_samples`` on (set by :func:`piezohyst.track`); computed on first use."""
        cached = self.__dict__.get("_metrics")
        if cached is None:
            k = self.__dict__.get("skip_samples", 0)
            cached = tracking_metrics(self.reference[k:], self.position[k:])
            object.__setattr__(self, "_metrics", cached)
        return cached

    @property
    def error(self) -> np.ndarray:
        """Tracking error ``reference - position``, m."""
        return self.reference - self.position

    def to_pandas(self):
        """The signals as a ``pandas.DataFrame`` indexed by time (needs pandas)."""
        try:
            import pandas as pd
        except ImportError:
            raise ImportError("to_pandas() needs pandas, which is not installed") from None
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

    def plot(self, *, zoom=None, ax=None):
        """Tracking (µm) with the error below; ``zoom=(t0, t1)`` adds an inset window."""
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


def _derivatives(x, ts, velocity, acceleration, needed):
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


_EMPTY = np.zeros(0)


def _check_reference(stage, x):
    """Finite and within the stroke (two reductions over ``x``; the error names the first
    offending sample: a non-finite one before one beyond the stroke, as before)."""
    lowest, highest = x.min(), x.max()
    if not (np.isfinite(lowest) and np.isfinite(highest)):
        as_record(x, "reference")  # raises, naming the first NaN/inf
    p, a = stage.params, stage.amplifier
    creep = 1 + sum(p.creep_weights)
    reach = [p.static_gain * (v * creep + p.electrostriction * v * v) for v in (a.v_min, a.v_max)]
    lo, hi = min(reach), max(reach)
    if lowest < lo or highest > hi:
        k = int(np.flatnonzero((x < lo) | (x > hi))[0])
        raise ParameterError(
            f"reference[{k}] = {x[k]:.6g} m is beyond the stage's stroke "
            f"[{lo:.3g}, {hi:.3g}] m for amplifier range [{a.v_min}, {a.v_max}] V"
        )


def _prepare(stage, controller, reference, velocity, acceleration):
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


def _result(stage, x, d, controller) -> ClosedLoopResult:
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
    stage, controller, reference, *, velocity=None, acceleration=None, rng=None, initial_state=None
) -> ClosedLoopResult:
    """Run ``controller`` on ``stage`` tracking ``reference`` (m, one value per sample).

    Parameters
    ----------
    stage : Stage
        Plant, amplifier, sensor and loop rate (e.g. :func:`piezohyst.virtual_stage`).
    controller : OpenLoop, PID, ...
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
    x, v, a, spec = _prepare(stage, controller, reference, velocity, acceleration)
    init = stage.rest_state() if initial_state is None else as_record(initial_state, "initial_state")
    s = stage.sensor
    d = _core.closed_loop(
        stage.core_params(),
        stage.sample_time,
        stage.substeps,
        stage.tolerance,
        s.quantization,
        s.noise_std,
        s.delay,
        spec,
        x,
        v,
        a,
        init,
        seed_from(rng),
    )
    return _result(stage, x, d, controller)


def closed_loop_batch(stage, scenarios, *, rng=None, initial_state=None) -> list:
    """Run many ``(controller, reference)`` scenarios in parallel on one stage.

    Each scenario gets its own noise seed drawn from ``rng``; results are identical whatever
    the number of threads.
    """
    seeds_rng = np.random.default_rng(seed_from(rng))
    init = stage.rest_state() if initial_state is None else as_record(initial_state, "initial_state")
    prepared, core = [], []
    for j, item in enumerate(scenarios):
        try:
            controller, reference = item
        except (TypeError, ValueError):
            raise ParameterTypeError(f"scenarios[{j}] must be a (controller, reference) pair") from None
        try:
            x, v, a, spec = _prepare(stage, controller, reference, None, None)
        except (ValueError, TypeError) as e:
            raise type(e)(f"scenarios[{j}]: {e}") from None
        prepared.append((x, controller))
        core.append((spec, x, v, a, int(seeds_rng.integers(0, 2**63 - 1))))
    s = stage.sensor
    out = _core.closed_loop_batch(
        stage.core_params(),
        stage.sample_time,
        stage.substeps,
        stage.tolerance,
        s.quantization,
        s.noise_std,
        s.delay,
        core,
        init,
    )
    return [_result(stage, x, d, c) for (x, c), d in zip(prepared, out, strict=False)]
