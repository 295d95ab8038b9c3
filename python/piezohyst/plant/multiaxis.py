"""Multi-axis stages: ``N`` actuators driving coupled dynamics (an XY(Z) flexure stage, a
3-actuator steering mirror), one sensor per output (issue 19).

Two ways to build one:

- :meth:`MultiAxisStage.from_axes`: each axis a single-axis :class:`~piezohyst.plant.Stage`
  (its amplifier, hysteresis, creep, modes, DAC, drift and sensor as they are), the outputs a
  static ``coupling`` of the axes' positions: output ``i`` is ``sum_j coupling[i, j] x_j``.
  The identity is ``N`` independent stages.
- :meth:`MultiAxisStage.from_model`: the dynamics of an identified
  :class:`~piezohyst.models.mimo.MimoModel` (e.g. from the FSM records), a hysteresis law per
  actuator ahead of it, the actuators' voltage ranges and a sensor per output.

The closed loop (one controller per axis, optionally behind a static decoupling matrix) runs
in the Rust core: :func:`piezohyst.control.multiaxis.closed_loop_multi`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import TYPE_CHECKING, Any, TypeAlias

import numpy as np
import numpy.typing as npt

from .. import _core
from .._validate import as_scalar
from ..errors import ParameterError, ParameterTypeError
from .stage import Amplifier, Sensor, Stage, StageParameters, _law_row

if TYPE_CHECKING:  # pragma: no cover - typing only
    from ..models.mimo import MimoModel
    from ..models.model import HysteresisModel

FloatArray: TypeAlias = npt.NDArray[np.float64]

__all__ = ["MAX_AXES", "MultiAxisStage"]

#: Most axes a multi-axis stage has (the core's fixed per-sample buffers).
MAX_AXES = 8

_DEFAULT_NAMES = ("x", "y", "z", "a", "b", "c", "d", "e")


def _names(names: Sequence[str] | None, n: int) -> tuple[str, ...]:
    out = tuple(_DEFAULT_NAMES[:n]) if names is None else tuple(str(s) for s in names)
    if len(out) != n:
        raise ParameterError(f"names has {len(out)} entries, one per axis ({n})")
    if len(set(out)) != n or not all(s.isidentifier() for s in out):
        raise ParameterError(f"names = {list(out)} must be distinct identifiers")
    return out


def _axes_count(n: int, what: str) -> None:
    if not 1 <= n <= MAX_AXES:
        raise ParameterError(f"{what} has {n} axes; a multi-axis stage has 1 to {MAX_AXES}")


@dataclass(frozen=True)
class MultiAxisStage:
    """``N`` coupled axes with one actuator and one sensor each (build it with
    :meth:`from_axes` or :meth:`from_model`).

    Parameters
    ----------
    views : tuple of Stage
        Per axis, the single-axis stage its controller is packed for (sample time, amplifier
        range, sensor, static gain): for :meth:`from_axes` the axis's own stage; for
        :meth:`from_model` a stand-in with the model's sample time, the actuator's range, the
        output's sensor and the magnitude of the model's DC gain from that actuator to that
        output.
    coupling : ndarray, shape (N, N)
        Static coupling of the axes' positions (:meth:`from_axes`), or ``None``.
    model : MimoModel or None
        The identified dynamics (:meth:`from_model`), or ``None``.
    hysteresis : tuple of (HysteresisModel or None)
        Per actuator, the law ahead of the model (:meth:`from_model`).
    names : tuple of str
        Axis names (``"x", "y", "z", ...`` by default).
    decoupling : ndarray, shape (N, N), or None
        A static matrix ahead of the actuators that every closed loop on this stage runs with
        by default (:meth:`with_decoupling`), or ``None``.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.plant import MultiAxisStage, virtual_stage
    >>> xy = MultiAxisStage.from_axes([virtual_stage(), virtual_stage()], coupling=0.05)
    >>> xy.n_axes, xy.names, xy.coupling.tolist()
    (2, ('x', 'y'), [[1.0, 0.05], [0.05, 1.0]])
    """

    views: tuple[Stage, ...]
    coupling: FloatArray | None = None
    model: MimoModel | None = None
    hysteresis: tuple[HysteresisModel | None, ...] = ()
    names: tuple[str, ...] = field(default=())
    decoupling: FloatArray | None = None

    @classmethod
    def from_axes(
        cls,
        axes: Sequence[Stage],
        coupling: npt.ArrayLike | float = 0.0,
        *,
        names: Sequence[str] | None = None,
    ) -> MultiAxisStage:
        """Single-axis stages whose positions are mixed by a static ``coupling``.

        Parameters
        ----------
        axes : sequence of Stage
            One stage per axis (each with its amplifier, hysteresis, modes, sensor...), all at
            one sample time.
        coupling : float or array_like, shape (N, N)
            A matrix: output ``i`` is ``sum_j coupling[i, j] x_j`` (its diagonal is usually 1);
            a number ``c``: every off-diagonal entry ``c`` and a unit diagonal (``0``: the
            axes are independent).
        names : sequence of str, optional
            Axis names (default ``x, y, z, ...``).

        Returns
        -------
        MultiAxisStage

        Examples
        --------
        >>> from piezohyst.plant import MultiAxisStage, virtual_stage
        >>> xy = MultiAxisStage.from_axes([virtual_stage()] * 2, coupling=[[1.0, 0.0], [0.05, 1.0]])
        >>> float(xy.dc_gain()[1, 0] / xy.dc_gain()[0, 0])
        0.05
        """
        if isinstance(axes, Stage) or not isinstance(axes, Sequence):
            raise ParameterTypeError(f"axes must be a list of Stage, got {type(axes).__name__}")
        n = len(axes)
        _axes_count(n, "axes")
        for j, s in enumerate(axes):
            if not isinstance(s, Stage):
                raise ParameterTypeError(f"axes[{j}] must be a Stage, got {type(s).__name__}")
            if s.sample_time != axes[0].sample_time:
                raise ParameterError(
                    f"axes[{j}] runs at {s.sample_time} s, axes[0] at {axes[0].sample_time} s: one sample time"
                )
        if np.ndim(coupling) == 0:
            c = as_scalar(coupling, "coupling")
            mat = np.full((n, n), c) + (1.0 - c) * np.eye(n)
        else:
            mat = np.array(coupling, dtype=np.float64)
            if mat.shape != (n, n):
                raise ParameterError(f"coupling has shape {mat.shape}, expected ({n}, {n})")
        bad = np.flatnonzero(~np.isfinite(mat))
        if bad.size:
            raise ParameterError(f"coupling[{bad[0] // n}, {bad[0] % n}] = {mat.flat[bad[0]]} is not finite")
        return cls(views=tuple(axes), coupling=mat, names=_names(names, n))

    @classmethod
    def from_model(
        cls,
        model: MimoModel,
        hysteresis: Sequence[HysteresisModel | None] | None = None,
        *,
        amplifiers: Sequence[Amplifier] | Amplifier | None = None,
        sensors: Sequence[Sensor] | Sensor | None = None,
        names: Sequence[str] | None = None,
    ) -> MultiAxisStage:
        """The dynamics of an identified MIMO model (``nu == ny``) with a hysteresis law per
        actuator.

        Actuator ``j``'s command is clipped to its amplifier's range, passes ``hysteresis[j]``
        (volts in, volts out; ``None``: none) and drives the model's input ``j``; output ``i``
        is read by ``sensors[i]``. The command is held over the period (the outputs at sample
        ``k`` are ``C x_k + D u_{k-1} + F w_{k-1}``). The sample time is ``1 / model.fs``.

        Parameters
        ----------
        model : MimoModel
            The dynamics (linear, Hammerstein or LFR), inputs in V and outputs in m.
        hysteresis : sequence of HysteresisModel or None, optional
            One per actuator (default: none).
        amplifiers : Amplifier or sequence of Amplifier, optional
            The actuators' voltage ranges (default :class:`Amplifier`'s).
        sensors : Sensor or sequence of Sensor, optional
            One per output (default: an ideal sensor).
        names : sequence of str, optional
            Axis names.

        Returns
        -------
        MultiAxisStage

        Examples
        --------
        >>> from piezohyst.models.mimo import MimoModel
        >>> from piezohyst.plant import MultiAxisStage
        >>> m = MimoModel.linear([[0.9, 0.0], [0.0, 0.8]], [[1e-8, 0.0], [1e-9, 2e-8]], [[1.0, 0.0], [0.0, 1.0]],
        ...                      [[0.0, 0.0], [0.0, 0.0]], fs=5000.0)
        >>> st = MultiAxisStage.from_model(m)
        >>> st.n_axes, st.sample_time, st.dc_gain().round(9).tolist()
        (2, 0.0002, [[1e-07, 0.0], [5e-09, 1e-07]])
        """
        from ..models.mimo import MimoModel

        if not isinstance(model, MimoModel):
            raise ParameterTypeError(f"model must be a MimoModel, got {type(model).__name__}")
        n = model.nu
        if model.ny != n:
            raise ParameterError(f"model has {model.nu} inputs and {model.ny} outputs; one actuator per output")
        _axes_count(n, "model")
        laws = (None,) * n if hysteresis is None else tuple(hysteresis)
        if len(laws) != n:
            raise ParameterError(f"hysteresis has {len(laws)} entries, one per actuator ({n})")
        amps = _per_axis(amplifiers, Amplifier, n, "amplifiers")
        sens = _per_axis(sensors, Sensor, n, "sensors")
        ts = 1.0 / float(model.fs)
        g = _model_dc_gain(model)
        views = []
        for i in range(n):
            if not (np.isfinite(g[i, i]) and g[i, i] != 0):
                raise ParameterError(
                    f"the model's DC gain from actuator {i} to output {i} is {g[i, i]:.4g} m/V: no axis"
                )
            # a stand-in single-axis stage: the controllers read its sample time, amplifier
            # range, sensor and static gain (Tem / k = |G_ii|) from it
            params = StageParameters(mass=1e-3, damping=1.0, stiffness=1.0 / abs(g[i, i]), tem=1.0)
            views.append(Stage(params, amplifier=amps[i], sensor=sens[i], sample_time=ts))
        return cls(views=tuple(views), model=model, hysteresis=laws, names=_names(names, n))

    @property
    def n_axes(self) -> int:
        """Number of axes ``N``."""
        return len(self.views)

    @property
    def sample_time(self) -> float:
        """Controller period, s."""
        return self.views[0].sample_time

    def dc_gain(self) -> FloatArray:
        """The static gain matrix ``(N, N)``, m/V: output ``i`` per volt on actuator ``j``
        (without hysteresis or creep).

        Returns
        -------
        ndarray, shape (N, N)

        Examples
        --------
        >>> from piezohyst.plant import MultiAxisStage, virtual_stage
        >>> s = virtual_stage()
        >>> g = MultiAxisStage.from_axes([s, s], coupling=0.1).dc_gain()
        >>> bool(abs(g[0, 1] / s.params.static_gain - 0.1) < 1e-12)
        True
        """
        if self.model is not None:
            return _model_dc_gain(self.model)
        assert self.coupling is not None
        gains = np.array([s.params.static_gain for s in self.views])
        return np.asarray(self.coupling * gains[None, :], dtype=np.float64)

    def axis_gains(self) -> FloatArray:
        """The static gain each axis's controller is packed for (its view's ``Tem / k``), m/V.

        Returns
        -------
        ndarray, shape (N,)

        Examples
        --------
        >>> from piezohyst.plant import MultiAxisStage, virtual_stage
        >>> s = virtual_stage()
        >>> bool(MultiAxisStage.from_axes([s, s]).axis_gains()[0] == s.params.static_gain)
        True
        """
        return np.array([v.params.static_gain for v in self.views], dtype=np.float64)

    def decoupler(self) -> FloatArray:
        """The static decoupling matrix ``T = G^-1 diag(g)`` (``G``: :meth:`dc_gain`, ``g``:
        :meth:`axis_gains`, ``diag(G)`` for stages with a unit coupling diagonal): the actuators
        get ``T c`` for the controllers' commands ``c``, so at DC controller ``i`` moves output
        ``i`` alone, with its axis's gain. ``ParameterError`` when ``G`` is singular.

        Returns
        -------
        ndarray, shape (N, N)

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst.plant import MultiAxisStage, virtual_stage
        >>> xy = MultiAxisStage.from_axes([virtual_stage()] * 2, coupling=0.05)
        >>> g, t = xy.dc_gain(), xy.decoupler()
        >>> bool(np.allclose(g @ t, np.diag(np.diag(g))))
        True
        """
        g = self.dc_gain()
        cond = np.linalg.cond(g)
        if not np.isfinite(cond) or cond > 1e12:
            raise ParameterError(f"the DC gain matrix is singular (condition number {cond:.3g}): no static decoupling")
        return np.asarray(np.linalg.solve(g, np.diag(self.axis_gains())), dtype=np.float64)

    def with_decoupling(self, decouple: bool | npt.ArrayLike = True) -> MultiAxisStage:
        """The same stage with a static matrix ahead of the actuators: ``True`` the
        :meth:`decoupler`, a matrix that matrix, ``False`` none. Closed loops and
        :func:`piezohyst.tune` on the result run behind it unless told otherwise.

        Parameters
        ----------
        decouple : bool or array_like, shape (N, N)

        Returns
        -------
        MultiAxisStage

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst.plant import MultiAxisStage, virtual_stage
        >>> xy = MultiAxisStage.from_axes([virtual_stage()] * 2, coupling=0.05).with_decoupling()
        >>> bool(np.allclose(xy.decoupling, xy.decoupler()))
        True
        """
        if decouple is True:
            return replace(self, decoupling=self.decoupler())
        if decouple is False:
            return replace(self, decoupling=None)
        t = np.array(decouple, dtype=np.float64)
        n = self.n_axes
        if t.shape != (n, n) or not np.all(np.isfinite(t)):
            raise ParameterError(f"decouple must be True, False or a finite ({n}, {n}) matrix, got shape {t.shape}")
        return replace(self, decoupling=t)

    def stroke(self, axis: int) -> tuple[float, float]:
        """Reachable output range of ``axis`` with the other actuators at rest, m (from the
        axis's stage; for a model, its DC gain over the actuator's range).

        Parameters
        ----------
        axis : int
            Axis index.

        Returns
        -------
        (float, float)

        Examples
        --------
        >>> from piezohyst.plant import MultiAxisStage, virtual_stage
        >>> s = virtual_stage()
        >>> MultiAxisStage.from_axes([s, s]).stroke(1) == s.stroke()
        True
        """
        v = self.views[axis]
        if self.model is None:
            return v.stroke()
        g = self.axis_gains()[axis]
        return (g * v.amplifier.v_min, g * v.amplifier.v_max)

    @cached_property
    def compiled(self) -> Any:
        """The Rust core's multi-axis plant, built and validated once."""
        if self.model is None:
            assert self.coupling is not None
            return _core.MultiAxisPlant.stages([s.compiled for s in self.views], np.ascontiguousarray(self.coupling))
        m = self.model
        laws = [
            None if law is None else _law_row(law, v.amplifier)
            for law, v in zip(self.hysteresis, self.views, strict=True)
        ]

        def mat(x: npt.ArrayLike) -> FloatArray:
            return np.ascontiguousarray(x, dtype=np.float64)

        return _core.MultiAxisPlant.lfr(
            mat(m.A),
            mat(m.B),
            mat(m.C),
            mat(m.D),
            mat(m.E),
            mat(m.F),
            mat(m.G),
            mat(m.H),
            mat(m.thresholds),
            mat(m.weights),
            laws,
            [(v.amplifier.v_min, v.amplifier.v_max) for v in self.views],
            [(v.sensor.quantization, v.sensor.noise_std, v.sensor.delay) for v in self.views],
            self.sample_time,
            m.static_channels,
        )

    def with_sensors(self, sensors: Sequence[Sensor] | Sensor) -> MultiAxisStage:
        """The same stage with other sensors (one per output, or one for all).

        Parameters
        ----------
        sensors : Sensor or sequence of Sensor

        Returns
        -------
        MultiAxisStage

        Examples
        --------
        >>> from piezohyst.plant import MultiAxisStage, Sensor, virtual_stage
        >>> xy = MultiAxisStage.from_axes([virtual_stage()] * 2).with_sensors(Sensor(delay=2))
        >>> [v.sensor.delay for v in xy.views]
        [2, 2]
        """
        sens = _per_axis(sensors, Sensor, self.n_axes, "sensors")
        return replace(self, views=tuple(replace(v, sensor=s) for v, s in zip(self.views, sens, strict=True)))

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state.pop("compiled", None)
        return state

    def __repr__(self) -> str:
        kind = "model" if self.model is not None else "axes"
        return f"MultiAxisStage({kind}: {self.n_axes} axes {', '.join(self.names)}, Ts = {self.sample_time:g} s)"


def _per_axis(x: object, kind: type, n: int, name: str) -> tuple[Any, ...]:
    if x is None:
        return (kind(),) * n
    if isinstance(x, kind):
        return (x,) * n
    if not isinstance(x, Sequence) or len(x) != n:
        raise ParameterError(f"{name} must be a {kind.__name__} or a list of {n} (one per axis)")
    for j, v in enumerate(x):
        if not isinstance(v, kind):
            raise ParameterTypeError(f"{name}[{j}] must be a {kind.__name__}, got {type(v).__name__}")
    return tuple(x)


def _model_dc_gain(model: MimoModel) -> FloatArray:
    """The model's static gain, m/V: its dynamics with each play bank at its large-signal
    slope (``w = W z``, ``W = diag(sum of the channel's weights)``, what a play passes once
    the input has moved beyond its threshold), ``D' + C' (I - A')^-1 B'``."""
    a, b, c, d = model.linear_part()
    w = np.diag(np.asarray(model.weights, dtype=np.float64).sum(axis=1)) if model.nw else np.zeros((0, 0))
    e, f, g, h = (np.asarray(x, dtype=np.float64) for x in (model.E, model.F, model.G, model.H))
    a2, b2 = a + e @ w @ g, b + e @ w @ h
    c2, d2 = c + f @ w @ g, d + f @ w @ h
    eye = np.eye(a.shape[0])
    if a.shape[0] and not math.isfinite(np.linalg.cond(eye - a2)):
        raise ParameterError("the model has a pole at z = 1: no static gain")
    gain = d2 + (c2 @ np.linalg.solve(eye - a2, b2) if a.shape[0] else 0.0)
    return np.asarray(gain, dtype=np.float64)
