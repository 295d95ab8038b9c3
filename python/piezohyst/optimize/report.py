"""The one shape of every fit, identification, tuning and optimization result.

Each such result says how long it took (``wall_time``, s), how many candidate evaluations it
spent (``evaluations``; a linear least-squares fit counts one), what happened per iteration
(``history``: a dict of arrays, one row per iteration, empty when the method does not iterate)
and whether it was stopped before its end (``partial``: Ctrl-C, a callback, a signal — the
result is then the best found before the stop). :class:`RunReport` gives all of them the same
``to_pandas()``, ``plot()``, notebook display and ``.mat`` files: the result protocol of
:mod:`piezohyst.signals.results`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ..signals.results import DataclassMatFile, html_table, require_pandas

if TYPE_CHECKING:  # pragma: no cover - typing only
    import pandas as pd
    from matplotlib.figure import Figure

__all__ = ["RunReport"]


class RunReport(DataclassMatFile):
    """Mixin of the result classes: subclasses provide ``wall_time``, ``evaluations``,
    ``history`` and ``partial`` (as fields or properties), a ``_headline()`` and their
    ``_scores()``. With :class:`~piezohyst.signals.results.DataclassMatFile` every run report
    is written to and read from MATLAB files (``to_mat``, ``from_mat``).

    :class:`OptimizeResult`, :class:`~piezohyst.identify.FitResult`,
    :class:`~piezohyst.identify.IdentificationResult` and
    :class:`~piezohyst.control.TuningResult` are ``RunReport``s: each has ``.to_pandas()``
    (the history per iteration), ``.plot()`` (convergence) and a notebook display.

    Examples
    --------
    >>> from piezohyst import minimize
    >>> from piezohyst.optimize import RunReport
    >>> res = minimize(lambda X: (X**2).sum(axis=1), [(-1, 1)], max_iterations=10, rng=0)
    >>> isinstance(res, RunReport), res.evaluations, res.partial
    (True, 200, False)
    >>> "<table>" in res._repr_html_()
    True
    """

    # Declared as read-only properties for the type checker only: a subclass provides each as a
    # dataclass field or as a property (a real property here would become a dataclass default).
    if TYPE_CHECKING:  # pragma: no cover - typing only

        @property
        def wall_time(self) -> float: ...

        @property
        def evaluations(self) -> int: ...

        @property
        def history(self) -> Mapping[str, Any] | None: ...

        @property
        def partial(self) -> bool: ...

    def _headline(self) -> str:
        return type(self).__name__

    def _history_columns(self) -> dict[str, npt.NDArray[Any]]:
        """Per-iteration columns of ``history``: 1-D arrays as they are, 2-D arrays (a
        candidate per iteration) split into ``name[j]`` columns."""
        cols: dict[str, npt.NDArray[Any]] = {}
        for name, values in (self.history or {}).items():
            a = np.asarray(values)
            if a.ndim == 1:
                cols[name] = a
            elif a.ndim == 2:
                for j in range(a.shape[1]):
                    cols[f"{name}[{j}]"] = a[:, j]
        lengths = {c.size for c in cols.values()}
        if len(lengths) > 1:
            # only the per-iteration series share a length; others (a final summary) are left out
            n = max(lengths, key=lambda k: sum(c.size == k for c in cols.values()))
            cols = {k: v for k, v in cols.items() if v.size == n}
        return cols

    def _scores(self) -> dict[str, float]:
        """The result's headline numbers by label (a fit's error in % of the range, a tuning's
        RMSE): what :meth:`plot` draws for a method without iterations and what the notebook
        display lists. Subclasses fill it."""
        return {}

    def to_pandas(self) -> pd.DataFrame:
        """The per-iteration history as a ``pandas.DataFrame`` indexed by iteration (needs
        pandas: without it an ``ImportError`` says ``pip install pandas``); for a method that
        does not iterate (a linear fit), one row of its headline numbers (what :meth:`plot`
        draws), in a row labelled ``"final"``.

        Returns
        -------
        pandas.DataFrame
            One column per history series (a candidate per iteration split into ``name[j]``),
            or one column per headline number.

        Examples
        --------
        >>> from piezohyst import minimize
        >>> res = minimize(lambda X: (X**2).sum(axis=1), [(-1, 1)], max_iterations=10, rng=0)
        >>> try:
        ...     df = res.to_pandas()
        ... except ImportError:           # pandas is optional
        ...     df = None
        >>> df is None or (len(df) == 10 and df.index.name == "iteration")
        True
        """
        pd = require_pandas(type(self).__name__)
        cols = self._history_columns()
        if not cols:
            return pd.DataFrame([self._scores()], index=pd.Index(["final"], name="result"))
        n = next(iter(cols.values())).size
        return pd.DataFrame(cols, index=pd.RangeIndex(1, n + 1, name="iteration"))

    def plot(self, *, ax: Any = None) -> Figure:
        """Convergence: the best cost so far against the iteration (log scale); for a method
        without iterations (a linear fit) its headline numbers as bars.

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            The axes to draw on (default: a new figure).

        Returns
        -------
        matplotlib.figure.Figure

        Examples
        --------
        >>> import matplotlib.pyplot as plt
        >>> from piezohyst import minimize
        >>> res = minimize(lambda X: (X**2).sum(axis=1) + 1e-3, [(-1, 1)], max_iterations=10, rng=0)
        >>> fig = res.plot()
        >>> fig.axes[0].get_ylabel()
        'best cost'
        >>> plt.close(fig)
        """
        import matplotlib.pyplot as plt

        cols = self._history_columns()
        if ax is None:
            fig, ax = plt.subplots(figsize=(6, 3.5))
        else:
            fig = ax.figure
        if "best_cost" in cols:
            best = cols["best_cost"]
            ax.semilogy(np.arange(1, best.size + 1), best, lw=1.2, label=self._headline())
            ax.set_xlabel("iteration")
            ax.set_ylabel("best cost")
            ax.legend(loc="upper right")
            return fig
        scores = self._scores()
        ax.barh(list(scores), list(scores.values()))
        ax.invert_yaxis()
        ax.set_title(self._headline(), fontsize="small")
        if not scores:
            ax.text(0.5, 0.5, "no per-iteration history", ha="center", va="center", transform=ax.transAxes)
        return fig

    def _repr_html_(self) -> str:
        rows = [(k, f"{v:.4g}") for k, v in self._scores().items()]
        rows += [
            ("wall time", f"{self.wall_time:.3g} s"),
            ("evaluations", str(self.evaluations)),
            ("iterations", str(len(next(iter(self._history_columns().values()), [])))),
            ("partial", "yes (stopped early: best so far)" if self.partial else "no"),
        ]
        return html_table(self._headline(), rows)
