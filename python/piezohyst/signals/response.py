"""One result object for every time simulation: a hysteresis model run, an open-loop stage run
and a closed-loop run all return a :class:`Response` (python-control's ``TimeResponseData`` is
the model).

A response holds a time base, named signals of the same length (each with a unit and a role:
input or output), the state the run ended in, and a title. Signals are read by name
(``response.position`` or ``response["position"]``); ``inputs`` and ``outputs`` stack them as
``(n_signals, n_time)`` arrays, never squeezed.

Examples
--------
>>> import numpy as np
>>> from piezohyst.signals import Response
>>> r = Response(np.arange(3) * 1e-3, {"voltage": [0.0, 1.0, 2.0], "position": [0.0, 1e-6, 2e-6]},
...              inputs=["voltage"], units={"voltage": "V", "position": "m"})
>>> r.position
array([0.e+00, 1.e-06, 2.e-06])
>>> r.outputs.shape
(1, 3)
>>> r.to_pandas().columns.tolist()  # doctest: +SKIP
['voltage', 'position']
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple, Self

import numpy as np
import numpy.typing as npt

from ..errors import DataError, ParameterError
from .results import MatFile, html_table, require_pandas

if TYPE_CHECKING:  # pragma: no cover - typing only
    import pandas as pd
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

FloatArray = npt.NDArray[np.float64]

__all__ = ["MatSignals", "Response"]


class MatSignals(NamedTuple):
    """A response as :meth:`Response.to_mat` stores it, read back: what a subclass's
    ``_from_mat_fields`` builds itself from.

    Parameters
    ----------
    time : ndarray
        The time base, s.
    signals : dict of str to ndarray
        The signals by name.
    inputs : list of str
        The input signals' names.
    units : dict of str to str
        Each signal's unit.
    final_state : ndarray or None
        The state the run ended in.
    title : str
        What ran.
    extra : dict
        What the class stored besides (a closed loop's sample time, controller, ...).

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.signals.response import MatSignals
    >>> MatSignals(np.zeros(2), {"x": np.ones(2)}, [], {"x": "m"}, None, "run", {}).title
    'run'
    """

    time: FloatArray
    signals: dict[str, FloatArray]
    inputs: list[str]
    units: dict[str, str]
    final_state: FloatArray | None
    title: str
    extra: dict[str, Any]


class Response(MatFile):
    """Named signals of one time simulation, one value per sample.

    Parameters
    ----------
    time : array_like, shape (N,)
        Sample instants, s; finite and strictly increasing.
    signals : mapping of str to array_like, shape (N,)
        The signals in display order.
    inputs : sequence of str, optional
        Names of the signals that drove the run (the rest are outputs).
    units : mapping of str to str, optional
        Unit of each signal (``"m"``, ``"V"``, ``""`` for unitless); missing ones are ``""``.
    final_state : array_like, optional
        The state the run ended in; pass it as the next run's initial state to continue.
    title : str, optional
        What ran (a model family, a controller name, ...).

    Attributes
    ----------
    time : ndarray, shape (N,)
    signals : dict of str to ndarray, shape (N,)
    input_names, output_names : tuple of str
    units : dict of str to str
    final_state : ndarray or None
    title : str

    Examples
    --------
    >>> from piezohyst.signals import Response
    >>> r = Response([0.0, 0.1, 0.2], {"v": [0.0, 1.0, 2.0], "x": [0.0, 1e-6, 3e-6]},
    ...              inputs=["v"], units={"v": "V", "x": "m"}, title="demo")
    >>> r.x.tolist(), r.inputs.shape, r.outputs.shape, r.units["x"]
    ([0.0, 1e-06, 3e-06], (1, 3), (1, 3), 'm')
    >>> r
    Response(demo: 3 samples over 0.2 s; signals v, x)
    """

    time: FloatArray
    signals: dict[str, FloatArray]
    input_names: tuple[str, ...]
    output_names: tuple[str, ...]
    units: dict[str, str]
    final_state: FloatArray | None
    title: str

    def __init__(
        self,
        time: npt.ArrayLike,
        signals: Mapping[str, npt.ArrayLike],
        *,
        inputs: Iterable[str] = (),
        units: Mapping[str, str] | None = None,
        final_state: npt.ArrayLike | None = None,
        title: str = "",
    ) -> None:
        t = np.asarray(time, dtype=np.float64)
        if t.ndim != 1:
            raise ParameterError(f"time must be 1-D, got shape {t.shape}")
        bad = np.flatnonzero(~np.isfinite(t))
        if bad.size:
            raise ParameterError(f"time[{bad[0]}] = {t[bad[0]]} is not finite")
        if t.size > 1 and not np.all(np.diff(t) > 0):
            raise ParameterError("time must be strictly increasing")
        sig: dict[str, FloatArray] = {}
        for name, values in signals.items():
            a = np.asarray(values, dtype=np.float64)
            if a.shape != t.shape:
                raise ParameterError(f"signal {name!r} has shape {a.shape}, the time base {t.shape}")
            sig[name] = a
        input_names = tuple(inputs)
        for name in input_names:
            if name not in sig:
                raise ParameterError(f"inputs names {name!r}, which is not a signal (signals: {list(sig)})")
        unit_map = dict(units or {})
        for name in unit_map:
            if name not in sig:
                raise ParameterError(f"units names {name!r}, which is not a signal (signals: {list(sig)})")
        object.__setattr__(self, "time", t)
        object.__setattr__(self, "signals", sig)
        object.__setattr__(self, "input_names", input_names)
        object.__setattr__(self, "output_names", tuple(n for n in sig if n not in input_names))
        object.__setattr__(self, "units", {n: unit_map.get(n, "") for n in sig})
        object.__setattr__(
            self, "final_state", None if final_state is None else np.asarray(final_state, dtype=np.float64)
        )
        object.__setattr__(self, "title", str(title))

    # A response is a record of what happened: it is not edited after the run. Derived values
    # (metrics) are cached in ``__dict__`` by subclasses through functools.cached_property.
    def __setattr__(self, name: str, value: object) -> None:
        raise AttributeError(f"{type(self).__name__} is read-only (cannot set {name!r})")

    def __delattr__(self, name: str) -> None:
        raise AttributeError(f"{type(self).__name__} is read-only (cannot delete {name!r})")

    def __getattr__(self, name: str) -> FloatArray:
        # called only when normal lookup fails: signals read as attributes
        signals: dict[str, FloatArray] | None = self.__dict__.get("signals")
        if signals is not None and name in signals:
            return signals[name]
        raise AttributeError(f"{type(self).__name__} has no attribute or signal {name!r}")

    def __getitem__(self, name: str) -> FloatArray:
        try:
            return self.signals[name]
        except KeyError:
            raise KeyError(f"no signal {name!r} (signals: {list(self.signals)})") from None

    def __len__(self) -> int:
        return int(self.time.size)

    def __dir__(self) -> list[str]:
        return sorted(set(super().__dir__()) | set(self.signals))

    @property
    def n_time(self) -> int:
        """Number of samples."""
        return int(self.time.size)

    @property
    def inputs(self) -> FloatArray:
        """Input signals stacked, shape ``(n_inputs, N)``."""
        return self._stack(self.input_names)

    @property
    def outputs(self) -> FloatArray:
        """Output signals stacked, shape ``(n_outputs, N)``."""
        return self._stack(self.output_names)

    def _stack(self, names: Sequence[str]) -> FloatArray:
        if not names:
            return np.empty((0, self.time.size))
        return np.vstack([self.signals[n] for n in names])

    def to_pandas(self) -> pd.DataFrame:
        """The signals as a ``pandas.DataFrame`` indexed by time (needs pandas: without it an
        ``ImportError`` says ``pip install pandas``).

        Returns
        -------
        pandas.DataFrame
            One column per signal.

        Examples
        --------
        >>> from piezohyst.signals import Response
        >>> r = Response([0.0, 0.1], {"v": [0.0, 1.0], "x": [0.0, 2.0]}, inputs=["v"])
        >>> try:
        ...     df = r.to_pandas()
        ... except ImportError:           # pandas is optional
        ...     df = None
        >>> df is None or list(df.columns) == ["v", "x"]
        True
        """
        pd = require_pandas(type(self).__name__)
        return pd.DataFrame(dict(self.signals), index=pd.Index(self.time, name="time"))

    # -- .mat files (to_mat / from_mat: MatFile) ------------------------------------------
    def _mat_fields(self) -> dict[str, Any]:
        """What :meth:`to_mat` stores in ``extra`` besides the signals (subclasses add theirs)."""
        return {}

    @classmethod
    def _from_mat_fields(cls, f: MatSignals) -> Self:
        """The response :meth:`to_mat` wrote, built through the constructor (subclasses whose
        constructor differs override this)."""
        return cls(f.time, f.signals, inputs=f.inputs, units=f.units, final_state=f.final_state, title=f.title)

    def _mat_value(self) -> dict[str, Any]:
        """``time`` (N x 1 double, s); ``signals``, a struct of N x 1 doubles (signal names that
        are not MATLAB names: a struct of cells ``keys`` and ``values``); ``inputs``, the input
        signals' names; ``units``, signal -> unit; ``final_state`` (``[]`` when none);
        ``title``; ``extra``, what the class adds (a closed loop's ``sample_time``,
        ``controller``, ``skip_samples``, ``terms``)."""
        return {
            "time": self.time.reshape(-1, 1),
            "signals": {k: v.reshape(-1, 1) for k, v in self.signals.items()},
            "inputs": list(self.input_names),
            "units": dict(self.units),
            "final_state": self.final_state,
            "title": self.title,
            "extra": self._mat_fields(),
        }

    @classmethod
    def _from_mat_value(cls, d: dict[str, Any], path: Path) -> Self:
        try:
            fields = MatSignals(
                np.asarray(d["time"], dtype=np.float64).ravel(),
                {str(k): np.asarray(v, dtype=np.float64).ravel() for k, v in d["signals"].items()},
                [str(n) for n in d["inputs"]],
                {str(k): str(v) for k, v in d["units"].items()},
                None if d["final_state"] is None else np.asarray(d["final_state"], dtype=np.float64),
                str(d["title"]),
                dict(d.get("extra") or {}),
            )
            return cls._from_mat_fields(fields)
        except (KeyError, TypeError, AttributeError) as e:
            raise DataError(f"{path}: the response is malformed ({type(e).__name__}: {e})") from None

    def plot(self, signals: Sequence[str] | None = None, *, ax: Axes | Iterable[Axes] | None = None) -> Figure:
        """One panel per unit: the named ``signals`` (default all) against time.

        Parameters
        ----------
        signals : sequence of str, optional
            The signals to draw (default: all).
        ax : matplotlib.axes.Axes or sequence of them, optional
            The axes to draw on, one per unit (in the order the units first appear); by
            default a new figure.

        Returns
        -------
        matplotlib.figure.Figure

        Examples
        --------
        >>> import matplotlib.pyplot as plt
        >>> from piezohyst.signals import Response
        >>> r = Response([0.0, 0.1], {"v": [0.0, 1.0], "x": [0.0, 2e-6]}, inputs=["v"], units={"v": "V", "x": "m"})
        >>> fig = r.plot()
        >>> len(fig.axes), fig.axes[1].get_ylabel()    # one panel per unit
        (2, '(m)')
        >>> plt.close(fig)
        """
        import matplotlib.pyplot as plt
        from matplotlib.axes import Axes

        names = list(self.signals) if signals is None else list(signals)
        for n in names:
            self[n]
        groups: dict[str, list[str]] = {}
        for n in names:
            groups.setdefault(self.units[n], []).append(n)
        ax_list: list[Axes]
        if ax is None:
            fig, axes = plt.subplots(len(groups), 1, sharex=True, squeeze=False, figsize=(8, 2.4 * len(groups)))
            ax_list = list(axes[:, 0])
        else:
            ax_list = [ax] if isinstance(ax, Axes) else list(np.ravel(np.asarray(ax, dtype=object)))
            if len(ax_list) != len(groups):
                raise ParameterError(f"ax has {len(ax_list)} axes; this plot needs {len(groups)} (one per unit)")
            root = ax_list[0].get_figure(root=True)
            if root is None:
                raise ParameterError("ax is not part of a figure")
            fig = root
        for a, (unit, members) in zip(ax_list, groups.items(), strict=True):
            for n in members:
                a.plot(self.time, self.signals[n], lw=1, label=n)
            a.set_ylabel(f"({unit})" if unit else "")
            a.legend(loc="upper right")
        ax_list[-1].set_xlabel("time (s)")
        if self.title:
            ax_list[0].set_title(self.title)
        return fig

    def _summary_rows(self) -> list[tuple[str, str, str, str, str, str]]:
        rows = []
        for n, a in self.signals.items():
            role = "input" if n in self.input_names else "output"
            lo, hi = (float(a.min()), float(a.max())) if a.size else (float("nan"), float("nan"))
            rms = float(np.sqrt(np.mean(a * a))) if a.size else float("nan")
            rows.append((n, role, self.units[n], f"{lo:.4g}", f"{hi:.4g}", f"{rms:.4g}"))
        return rows

    def _duration(self) -> float:
        return float(self.time[-1] - self.time[0]) if self.time.size > 1 else 0.0

    def __repr__(self) -> str:
        title = f"{self.title}: " if self.title else ""
        names = ", ".join(self.signals)
        return f"{type(self).__name__}({title}{self.n_time} samples over {self._duration():.4g} s; signals {names})"

    def _repr_html_(self) -> str:
        return html_table(repr(self), self._summary_rows(), header=("signal", "role", "unit", "min", "max", "rms"))
