"""Decentralized control of a multi-axis stage (issue 19): one packaged controller per axis
(PID/FilteredPID with feedforward, SMC, ... — the kinds of :mod:`.controllers`), run together
in the Rust core on a :class:`~piezohyst.plant.MultiAxisStage`, optionally behind the static
decoupling matrix ``G^-1 diag(G)``. Their tuning by sequential loop closing is
:func:`piezohyst.control.tuning.tune_axes` (what :func:`piezohyst.tune` runs on a multi-axis
stage).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from functools import cached_property
from typing import TYPE_CHECKING, Any, Self

import numpy as np
import numpy.typing as npt

from .._validate import as_scalar
from ..errors import ParameterError, ParameterTypeError
from ..signals.metrics import tracking_metrics
from ..signals.response import Response
from .controllers import check_sample_rate, is_controller
from .simulation import ClosedLoopResult, ControllerLike, FloatArray, RngLike, _check_reference, seed_from

if TYPE_CHECKING:  # pragma: no cover - typing only
    from matplotlib.figure import Figure

    from ..plant.multiaxis import MultiAxisStage

__all__ = ["MultiAxisResult", "closed_loop_multi"]

_SIGNALS = ("reference", "command", "voltage", "position", "measured")
_UNITS = {"reference": "m", "command": "V", "voltage": "V", "position": "m", "measured": "m"}


class MultiAxisResult(Response):
    """Signals of one multi-axis closed-loop run, one row per controller sample: a
    :class:`~piezohyst.signals.Response` with signals ``<signal>_<axis>`` (``reference_x``,
    ``position_y``, ...; the references are its inputs).

    ``reference``, ``command``, ``voltage`` (what each actuator applied at the end of the
    period), ``position`` (true output) and ``measured`` (sensor reading) are ``(N, n_axes)``
    arrays; :meth:`axis` gives one axis as a :class:`ClosedLoopResult`; ``metrics`` the
    tracking metrics per axis from ``skip_samples`` on.

    Parameters
    ----------
    sample_time : float
        Controller period, s.
    names : sequence of str
        Axis names.
    signals : mapping of str to array_like, shape (N, n_axes)
        ``reference``, ``command``, ``voltage``, ``position``, ``measured``.
    terms : sequence of mapping of str to array_like
        Per axis, its controller's internal terms.
    controllers : sequence of str
        Per axis, the controller's name.
    decoupled : bool
        Whether the static decoupling matrix ran.
    skip_samples : int
        First samples left out of ``metrics``.

    Examples
    --------
    >>> import numpy as np
    >>> import piezohyst as ph
    >>> from piezohyst.plant import MultiAxisStage
    >>> xy = MultiAxisStage.from_axes([ph.virtual_stage()] * 2, coupling=0.05)
    >>> ref = np.full((500, 2), 5e-6)
    >>> res = ph.control.multiaxis.closed_loop_multi(xy, [ph.PID(kp=1e6, ki=5e9)] * 2, ref, rng=1)
    >>> res.position.shape, res.names, sorted(res.signals)[:2]
    ((500, 2), ('x', 'y'), ['command_x', 'command_y'])
    """

    sample_time: float
    names: tuple[str, ...]
    terms: tuple[dict[str, FloatArray], ...]
    controllers: tuple[str, ...]
    decoupled: bool
    skip_samples: int

    def __init__(
        self,
        sample_time: float,
        names: Sequence[str],
        signals: Mapping[str, npt.ArrayLike],
        terms: Sequence[Mapping[str, npt.ArrayLike]] = (),
        controllers: Sequence[str] = (),
        decoupled: bool = False,
        skip_samples: int = 0,
    ) -> None:
        ts = float(sample_time)
        names = tuple(names)
        arrays = {k: np.asarray(signals[k], dtype=np.float64) for k in _SIGNALS}
        n = arrays["reference"].shape[0]
        flat: dict[str, npt.ArrayLike] = {}
        units: dict[str, str] = {}
        for k in _SIGNALS:
            if arrays[k].shape != (n, len(names)):
                raise ParameterError(f"{k} has shape {arrays[k].shape}, expected ({n}, {len(names)})")
            for i, nm in enumerate(names):
                flat[f"{k}_{nm}"] = arrays[k][:, i]
                units[f"{k}_{nm}"] = _UNITS[k]
        super().__init__(
            np.arange(n) * ts,
            flat,
            inputs=[f"reference_{nm}" for nm in names],
            units=units,
            title=" / ".join(controllers),
        )
        object.__setattr__(self, "sample_time", ts)
        object.__setattr__(self, "names", names)
        object.__setattr__(
            self, "terms", tuple({k: np.asarray(v, dtype=np.float64) for k, v in t.items()} for t in terms)
        )
        object.__setattr__(self, "controllers", tuple(str(c) for c in controllers))
        object.__setattr__(self, "decoupled", bool(decoupled))
        object.__setattr__(self, "skip_samples", int(skip_samples))

    def _stacked(self, kind: str) -> FloatArray:
        return np.column_stack([self.signals[f"{kind}_{nm}"] for nm in self.names])

    @property
    def reference(self) -> FloatArray:
        """Desired outputs, ``(N, n_axes)``, m."""
        return self._stacked("reference")

    @property
    def command(self) -> FloatArray:
        """Controller outputs (before decoupling), ``(N, n_axes)``, V."""
        return self._stacked("command")

    @property
    def voltage(self) -> FloatArray:
        """What each actuator applied at the end of the period, ``(N, n_axes)``, V."""
        return self._stacked("voltage")

    @property
    def position(self) -> FloatArray:
        """True outputs, ``(N, n_axes)``, m."""
        return self._stacked("position")

    @property
    def measured(self) -> FloatArray:
        """Sensor readings the controllers used, ``(N, n_axes)``, m."""
        return self._stacked("measured")

    @property
    def error(self) -> FloatArray:
        """Tracking errors ``reference - position``, ``(N, n_axes)``, m."""
        return self.reference - self.position

    def _index(self, axis: int | str) -> int:
        if isinstance(axis, str):
            if axis not in self.names:
                raise ParameterError(f"axis = {axis!r} is not one of {list(self.names)}")
            return self.names.index(axis)
        if not 0 <= int(axis) < len(self.names):
            raise ParameterError(f"axis = {axis} is out of range for {len(self.names)} axes")
        return int(axis)

    def axis(self, axis: int | str) -> ClosedLoopResult:
        """One axis's signals as a single-axis :class:`ClosedLoopResult` (its ``final_state``
        is empty).

        Parameters
        ----------
        axis : int or str
            Index or name.

        Returns
        -------
        ClosedLoopResult

        Examples
        --------
        >>> import numpy as np
        >>> import piezohyst as ph
        >>> from piezohyst.plant import MultiAxisStage
        >>> xy = MultiAxisStage.from_axes([ph.virtual_stage()] * 2)
        >>> res = ph.control.multiaxis.closed_loop_multi(xy, [ph.PID(kp=1e6, ki=5e9)] * 2, np.full((300, 2), 4e-6))
        >>> res.axis("y").position.shape
        (300,)
        """
        i = self._index(axis)
        nm = self.names[i]
        sig = self.signals
        return ClosedLoopResult(
            self.sample_time,
            sig[f"reference_{nm}"],
            sig[f"command_{nm}"],
            sig[f"voltage_{nm}"],
            sig[f"position_{nm}"],
            sig[f"measured_{nm}"],
            self.terms[i] if self.terms else {},
            np.zeros(0),
            self.controllers[i] if self.controllers else "",
            self.skip_samples,
        )

    @cached_property
    def metrics(self) -> dict[str, dict[str, float]]:
        """Per axis name, :func:`piezohyst.metrics.tracking_metrics` of its output against its
        reference from ``skip_samples`` on; for an axis whose reference holds still (a
        crosstalk measurement) only ``rmse`` and ``max_error`` (the relative figures need a
        range)."""
        k = self.skip_samples
        out = {}
        for nm in self.names:
            r, y = self.signals[f"reference_{nm}"][k:], self.signals[f"position_{nm}"][k:]
            if np.ptp(r) > 0:
                out[nm] = tracking_metrics(r, y)
            else:
                e = y - r
                out[nm] = {"rmse": float(np.sqrt(np.mean(e**2))), "max_error": float(np.abs(e).max())}
        return out

    @property
    def rmse(self) -> FloatArray:
        """Per-axis tracking RMSE from ``skip_samples`` on, m."""
        k = self.skip_samples
        return np.asarray(np.sqrt(np.mean(self.error[k:] ** 2, axis=0)), dtype=np.float64)

    def with_skip(self, seconds: float) -> Self:
        """The same run with ``metrics`` and ``rmse`` leaving out the first ``seconds``.

        Parameters
        ----------
        seconds : float

        Returns
        -------
        MultiAxisResult

        Examples
        --------
        >>> import numpy as np
        >>> import piezohyst as ph
        >>> from piezohyst.plant import MultiAxisStage
        >>> xy = MultiAxisStage.from_axes([ph.virtual_stage()] * 2)
        >>> res = ph.control.multiaxis.closed_loop_multi(xy, [ph.PID(kp=1e6, ki=5e9)] * 2, np.full((300, 2), 4e-6))
        >>> res.with_skip(0.01).skip_samples
        100
        """
        k = round(as_scalar(seconds, "seconds", nonnegative=True) / self.sample_time)
        if k >= self.n_time - 1:
            raise ParameterError(f"skip = {seconds} s leaves fewer than 2 of the run's {self.n_time} samples")
        return type(self)(
            self.sample_time,
            self.names,
            {s: self._stacked(s) for s in _SIGNALS},
            self.terms,
            self.controllers,
            self.decoupled,
            k,
        )

    def _mat_fields(self) -> dict[str, Any]:
        return {
            "sample_time": self.sample_time,
            "names": list(self.names),
            "controllers": list(self.controllers),
            "decoupled": self.decoupled,
            "skip_samples": self.skip_samples,
        }

    @classmethod
    def _from_mat_fields(cls, f: Any) -> Self:
        e = f.extra
        names = [str(n) for n in np.atleast_1d(e["names"])]
        sig = {k: np.column_stack([f.signals[f"{k}_{nm}"] for nm in names]) for k in _SIGNALS}
        ctl = [str(c) for c in np.atleast_1d(e["controllers"])]
        return cls(float(e["sample_time"]), names, sig, (), ctl, bool(e["decoupled"]), int(e["skip_samples"]))

    def to_pandas(self) -> Any:
        """The signals as a ``pandas.DataFrame`` indexed by time: columns ``<signal>_<axis>``
        and ``error_<axis>`` (needs pandas).

        Returns
        -------
        pandas.DataFrame

        Examples
        --------
        >>> import numpy as np
        >>> import piezohyst as ph
        >>> from piezohyst.plant import MultiAxisStage
        >>> xy = MultiAxisStage.from_axes([ph.virtual_stage()] * 2)
        >>> res = ph.control.multiaxis.closed_loop_multi(xy, [ph.PID(kp=1e6)] * 2, np.full((100, 2), 1e-6))
        >>> try:
        ...     cols = list(res.to_pandas().columns)
        ... except ImportError:
        ...     cols = None
        >>> cols is None or "error_y" in cols
        True
        """
        df = super().to_pandas()
        err = self.error
        for i, nm in enumerate(self.names):
            df[f"error_{nm}"] = err[:, i]
        return df

    def plot(self, signals: Sequence[str] | None = None, *, ax: Any = None) -> Figure:
        """Per axis, tracking (µm) and error (µm) in two rows of panels; naming ``signals``
        gives :meth:`Response.plot`'s panels instead.

        Parameters
        ----------
        signals : sequence of str, optional
            Signals to draw as :meth:`Response.plot` does.
        ax : array of matplotlib axes, shape (2, n_axes), optional
            Where to draw.

        Returns
        -------
        matplotlib.figure.Figure

        Examples
        --------
        >>> import numpy as np
        >>> import matplotlib.pyplot as plt
        >>> import piezohyst as ph
        >>> from piezohyst.plant import MultiAxisStage
        >>> xy = MultiAxisStage.from_axes([ph.virtual_stage()] * 2)
        >>> res = ph.control.multiaxis.closed_loop_multi(xy, [ph.PID(kp=1e6, ki=5e9)] * 2, np.full((300, 2), 4e-6))
        >>> fig = res.plot()
        >>> len(fig.axes)
        4
        >>> plt.close(fig)
        """
        if signals is not None:
            return super().plot(signals, ax=ax)
        import matplotlib.pyplot as plt

        n = len(self.names)
        if ax is None:
            fig, ax = plt.subplots(2, n, sharex=True, figsize=(4 * n, 5), squeeze=False)
        else:
            ax = np.asarray(ax).reshape(2, n)
            fig = ax[0, 0].figure
        err = self.error
        for i, nm in enumerate(self.names):
            ax[0, i].plot(self.time, self.signals[f"reference_{nm}"] * 1e6, "k--", lw=1, label="reference")
            ax[0, i].plot(self.time, self.signals[f"position_{nm}"] * 1e6, lw=1, label=nm)
            ax[0, i].set_ylabel(f"{nm} (µm)")
            ax[0, i].legend(loc="upper right")
            ax[1, i].plot(self.time, err[:, i] * 1e6, lw=0.8)
            ax[1, i].set_ylabel(f"{nm} error (µm)")
            ax[1, i].set_xlabel("time (s)")
        return fig


def _controllers(stage: MultiAxisStage, controllers: object) -> list[ControllerLike]:
    if not isinstance(controllers, Sequence) or len(controllers) != stage.n_axes:
        raise ParameterError(f"controllers must be a list of {stage.n_axes} controllers, one per axis")
    for j, c in enumerate(controllers):
        if not is_controller(c):
            raise ParameterTypeError(
                f"controllers[{j}] must be a piezohyst controller (PID, SMC, ...), got {type(c).__name__}"
            )
    return list(controllers)


def _references(stage: MultiAxisStage, reference: npt.ArrayLike, name: str = "reference") -> FloatArray:
    x = np.array(reference, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] != stage.n_axes or x.shape[0] < 2:
        raise ParameterError(
            f"{name} has shape {x.shape}; expected (samples >= 2, {stage.n_axes}), one column per axis"
        )
    for i, view in enumerate(stage.views):
        col = np.ascontiguousarray(x[:, i])
        try:
            _check_reference(view, col)
        except ParameterError as e:
            raise ParameterError(f"{name}[:, {i}] (axis {stage.names[i]}): {e}") from None
    return np.ascontiguousarray(x)


def _decoupling(stage: MultiAxisStage, decouple: bool | npt.ArrayLike | None) -> FloatArray | None:
    """The matrix a run uses: ``None`` the stage's own (:meth:`MultiAxisStage.with_decoupling`),
    else as :meth:`MultiAxisStage.with_decoupling` reads ``decouple``."""
    chosen = stage if decouple is None else stage.with_decoupling(decouple)
    return None if chosen.decoupling is None else np.ascontiguousarray(chosen.decoupling)


def _check_signs(stage: MultiAxisStage, t: FloatArray | None) -> None:
    """Each controller's loop gain at DC must be positive (``(G T)_ii > 0``): a packaged
    controller with a negative plant gain feeds its error back positively."""
    g = stage.dc_gain() if t is None else stage.dc_gain() @ t
    bad = np.flatnonzero(np.diag(g) <= 0)
    if bad.size:
        i = int(bad[0])
        raise ParameterError(
            f"axis {stage.names[i]}: the DC gain from its actuator to its output is {g[i, i]:.4g} m/V "
            f"{'with this decoupling' if t is not None else ''}; a controller would feed its error back "
            "positively: run with decouple=True (or flip the actuator's sign)"
        )


def _seeds(rng: RngLike | Sequence[int], n: int) -> list[int]:
    """One sensor-noise seed per axis: a list of ``n`` seeds (each as :func:`closed_loop`'s
    ``rng``: axis ``i`` then sees the noise a single-axis run with ``rng=rng[i]`` sees), or
    ``n`` seeds drawn from one ``rng``."""
    if isinstance(rng, Sequence):
        if len(rng) != n:
            raise ParameterError(f"rng has {len(rng)} seeds, one per axis ({n})")
        return [seed_from(int(r)) for r in rng]
    g = np.random.default_rng(seed_from(rng))
    return [int(s) for s in g.integers(0, 2**63 - 1, size=n)]


def _derivatives(
    x: FloatArray, ts: float, controllers: Sequence[ControllerLike]
) -> tuple[FloatArray | None, FloatArray | None]:
    if not any(getattr(c, "uses_reference_derivatives", True) for c in controllers):
        return None, None
    v = np.ascontiguousarray(np.gradient(x, ts, axis=0))
    return v, np.ascontiguousarray(np.gradient(v, ts, axis=0))


def closed_loop_multi(
    stage: MultiAxisStage,
    controllers: Sequence[ControllerLike],
    reference: npt.ArrayLike,
    *,
    decouple: bool | npt.ArrayLike | None = None,
    rng: RngLike | Sequence[int] = None,
) -> MultiAxisResult:
    """Run one controller per axis on ``stage`` from rest, tracking ``reference``.

    Each controller is packed for its axis's single-axis view (``stage.views[i]``: sample
    time, amplifier range, sensor, static gain for the feedforward default) and reads its own
    output's sensor; the loop (sensors, controllers, decoupling, the coupled plant) runs in
    Rust, allocating nothing per sample.

    Parameters
    ----------
    stage : MultiAxisStage
        The plant.
    controllers : sequence of controller configurations
        One per axis (``PID``, ``FilteredPID``, ``SMC``, ``Compensated``, ...).
    reference : array_like, shape (N, n_axes)
        Desired outputs per controller sample, m; each column within its axis's stroke.
    decouple : bool or array_like, shape (n_axes, n_axes), optional
        ``True``: the actuators get ``stage.decoupler() @ c`` for the commands ``c`` (static
        inverse of the DC gain matrix, the axes' gains kept); a matrix: that matrix;
        ``False``: ``c``; ``None`` (default): the stage's own setting
        (:meth:`~piezohyst.plant.MultiAxisStage.with_decoupling`, none unless set).
    rng : int, Generator, or sequence of int
        Sensor-noise seeds: one seed per axis (axis ``i`` then sees the noise of a single-axis
        :func:`~piezohyst.closed_loop` with ``rng=rng[i]``), or one seed for all.

    Returns
    -------
    MultiAxisResult

    Examples
    --------
    >>> import numpy as np
    >>> import piezohyst as ph
    >>> from piezohyst.plant import MultiAxisStage
    >>> from piezohyst.control.multiaxis import closed_loop_multi
    >>> s = ph.virtual_stage()
    >>> xy = MultiAxisStage.from_axes([s, s], coupling=0.05)
    >>> t = np.arange(0, 0.2, s.sample_time)
    >>> ref = np.column_stack([7e-6 + 5e-6 * np.sin(2 * np.pi * 10 * t), np.full(t.size, 7e-6)])
    >>> pid = ph.PID(kp=2e6, ki=2e9)
    >>> plain = closed_loop_multi(xy, [pid, pid], ref, rng=1).with_skip(0.05)
    >>> decoupled = closed_loop_multi(xy, [pid, pid], ref, decouple=True, rng=1).with_skip(0.05)
    >>> bool(decoupled.rmse[1] < plain.rmse[1])
    True
    """
    from ..plant.multiaxis import MultiAxisStage

    if not isinstance(stage, MultiAxisStage):
        raise ParameterTypeError(f"stage must be a MultiAxisStage, got {type(stage).__name__}")
    ctl = _controllers(stage, controllers)
    x = _references(stage, reference)
    for c in ctl:
        check_sample_rate(c, stage.sample_time)
    specs = [c.core(v) for c, v in zip(ctl, stage.views, strict=True)]
    v, a = _derivatives(x, stage.sample_time, ctl)
    t = _decoupling(stage, decouple)
    _check_signs(stage, t)
    d = stage.compiled.closed_loop(specs, x, v, a, _seeds(rng, stage.n_axes), t)
    signals = {
        "reference": x,
        "command": d["command"],
        "voltage": d["voltage"],
        "position": d["position"],
        "measured": d["measured"],
    }
    terms = [
        {nm: arr[:, j] for j, nm in enumerate(names)} for arr, names in zip(d["terms"], d["term_names"], strict=True)
    ]
    return MultiAxisResult(
        stage.sample_time, stage.names, signals, terms, [type(c).__name__ for c in ctl], t is not None
    )
