"""Population optimizers for identification and tuning (docs/spec.md §4): CSS, PSO, MPSO and DE.

Every optimizer is a public stepping object with an *ask/tell* interface: :meth:`Optimizer.ask`
returns the whole population as an ``(S, D)`` array, the caller evaluates it in one batch
(for a hysteresis model, one call of :func:`piezohyst.batch_rmse`, computed in Rust) and hands
the ``(S,)`` costs back with :meth:`Optimizer.tell`. :func:`minimize` runs that loop with
callbacks, a progress bar, a convergence test and an optional L-BFGS-B polish.

Conventions
-----------
* ``bounds`` is a sequence of ``(lower, upper)`` pairs, shape ``(D, 2)``, or a
  :class:`scipy.optimize.Bounds`. Every candidate returned by ``ask()`` lies inside them.
* ``rng`` is an int seed, a :class:`numpy.random.Generator` or ``None`` (fresh entropy); the
  global NumPy state is never used. The run depends only on ``rng`` and on the costs.
* A cost of ``+inf`` marks an invalid candidate and is accepted; a NaN cost is a bug upstream
  and raises ``ValueError`` naming its index.
* One *iteration* is one evaluated population (one ``ask``/``tell`` pair, one batch call);
  ``nfev`` counts evaluated candidates.

Examples
--------
>>> import numpy as np
>>> from piezohyst.optimize import minimize
>>> def sphere(X):                      # (S, D) -> (S,)
...     return np.sum((X - 0.3) ** 2, axis=1)
>>> res = minimize(sphere, [(-1, 1)] * 3, method="de", rng=1, max_iterations=150)
>>> bool(res.fun < 1e-8), res.message
(True, 'maximum number of iterations reached')

The same loop by hand, with the stepping object:

>>> from piezohyst.optimize import PSO
>>> opt = PSO([(-1, 1)] * 3, population_size=20, rng=1, max_iterations=100)
>>> while not opt.done:
...     X = opt.ask()
...     opt.tell(sphere(X))
>>> bool(opt.best_cost < 1e-8)
True
"""

from __future__ import annotations

import numbers
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any, TypeAlias

import numpy as np
import numpy.typing as npt

from .._validate import as_int, as_scalar
from ..errors import ComputationError, ParameterError, ParameterTypeError
from ..progress import Progress
from ..signals.results import DataclassMatFile, html_table, require_pandas
from .report import RunReport

#: Largest population an optimizer takes: each generation evaluates every member (a batch
#: call per generation), so a typo of a million members would hold the machine for hours.
MAX_POPULATION = 100_000

if TYPE_CHECKING:  # pragma: no cover - typing only
    import pandas as pd
    from matplotlib.figure import Figure
    from scipy.optimize import Bounds

__all__ = [
    "CSS",
    "DE",
    "METHODS",
    "MPSO",
    "PSO",
    "IntermediateResult",
    "OptimizeResult",
    "Optimizer",
    "css_charges",
    "css_forces",
    "minimize",
]


FloatArray: TypeAlias = npt.NDArray[np.float64]
BoundsLike: TypeAlias = "npt.ArrayLike | Bounds[Any, Any]"
"""``(D, 2)`` pairs of ``(lower, upper)`` or a :class:`scipy.optimize.Bounds`."""
RngLike: TypeAlias = int | np.integer[Any] | np.random.Generator | np.random.SeedSequence | None
"""An int seed, a NumPy ``Generator`` (or ``SeedSequence``), or ``None`` for fresh entropy."""
BatchObjective: TypeAlias = Callable[[FloatArray], npt.ArrayLike]
"""``fun_batch(X) -> costs``: ``(S, D)`` candidates to ``(S,)`` costs."""
Callback: TypeAlias = "Callable[[IntermediateResult], object]"
"""``callback(intermediate_result)``; a true return value stops the run."""


# --------------------------------------------------------------------------------------------
# argument helpers
# --------------------------------------------------------------------------------------------
def _as_bounds(bounds: BoundsLike) -> tuple[FloatArray, FloatArray]:
    """``(lower, upper)`` float arrays from ``(D, 2)`` pairs or a ``scipy.optimize.Bounds``."""
    if hasattr(bounds, "lb") and hasattr(bounds, "ub"):  # scipy.optimize.Bounds
        lo = np.atleast_1d(np.asarray(bounds.lb, dtype=np.float64))
        hi = np.atleast_1d(np.asarray(bounds.ub, dtype=np.float64))
        if lo.shape != hi.shape or lo.ndim != 1:
            raise ParameterError(f"bounds: lb and ub must be 1-D of equal length, got {lo.shape} and {hi.shape}")
    else:
        if isinstance(bounds, (str, bytes)) or bounds is None:
            raise ParameterTypeError(f"bounds must be a sequence of (lower, upper) pairs, got {bounds!r}")
        try:
            b = np.array(bounds, dtype=np.float64)
        except (TypeError, ValueError) as e:
            raise ParameterTypeError(f"bounds must be a sequence of (lower, upper) pairs of numbers: {e}") from None
        if b.ndim != 2 or b.shape[1] != 2 or b.shape[0] < 1:
            raise ParameterError(
                "bounds must have shape (D, 2) with D >= 1 (one (lower, upper) pair per parameter), "
                f"got shape {b.shape}"
            )
        lo, hi = b[:, 0].copy(), b[:, 1].copy()
    if lo.size < 1:
        raise ParameterError("bounds is empty: at least one parameter is needed")
    for name, arr in (("lower", lo), ("upper", hi)):
        bad = np.flatnonzero(~np.isfinite(arr))
        if bad.size:
            k = bad[0]
            raise ParameterError(f"bounds[{k}] = ({lo[k]}, {hi[k]}): the {name} bound is not finite")
    bad = np.flatnonzero(lo > hi)
    if bad.size:
        k = bad[0]
        raise ParameterError(f"bounds[{k}] = ({lo[k]}, {hi[k]}): lower > upper")
    if np.all(hi == lo):
        raise ParameterError("bounds: every parameter has lower == upper; nothing to optimize")
    return lo, hi


def _as_rng(rng: RngLike) -> np.random.Generator:
    if rng is None or isinstance(rng, (np.random.Generator, np.random.SeedSequence)):
        return np.random.default_rng(rng)
    if isinstance(rng, bool) or not isinstance(rng, (numbers.Integral, np.integer)):
        raise ParameterTypeError(f"rng must be None, an int seed or a numpy.random.Generator, got {rng!r}")
    if int(rng) < 0:
        raise ParameterError(f"rng = {int(rng)} must be a non-negative seed")
    return np.random.default_rng(int(rng))


def _as_fraction(x: object, name: str, *, low: float = 0.0, high: float = 1.0, open_low: bool = False) -> float:
    v = as_scalar(x, name)
    if v > high or v < low or (open_low and v == low):
        lo_br = "(" if open_low else "["
        raise ParameterError(f"{name} = {v} must be in {lo_br}{low}, {high}]")
    return v


def _readonly(a: npt.ArrayLike) -> FloatArray:
    out: FloatArray = np.array(a, copy=True)
    out.setflags(write=False)
    return out


# --------------------------------------------------------------------------------------------
# results
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class OptimizeResult(RunReport):
    """The outcome of a run (modelled on :class:`scipy.optimize.OptimizeResult`).

    As a :class:`~piezohyst.optimize.RunReport`: ``evaluations`` is ``nfev`` and ``partial``
    is ``True`` when the run was interrupted or stopped by the callback (``x`` is then the
    best point found before the stop).

    Parameters
    ----------
    x : ndarray, shape (D,)
        Best candidate found (``None`` only if no population was ever evaluated).
    fun : float
        Its cost (``inf`` if no candidate had a finite cost).
    nit : int
        Number of iterations (evaluated populations).
    nfev : int
        Number of evaluated candidates, including the polish.
    history : dict of ndarray
        Per iteration: ``"best_cost"`` (best so far, shape ``(nit,)``), ``"mean_cost"`` (mean
        of the finite costs of that population, ``inf`` if none was finite), ``"best_x"``
        (best so far, ``(nit, D)``), ``"n_finite"`` (number of finite costs) and ``"nfev"``
        (cumulative evaluations). Wrappers may add scalar annotations of the run (the Huber
        fit adds ``"huber_delta"``, a float).
    message : str
        Why the run stopped.
    success : bool
        ``True`` when the iteration budget was used up or the convergence test passed and a
        finite cost was found; ``False`` when stopped by the callback, interrupted, or when no
        candidate had a finite cost.
    wall_time : float
        Seconds of the run: the whole :func:`minimize` call (including the polish), or for
        :meth:`Optimizer.result` from the first ``ask()`` to the last ``tell()``.
    method : str
        The optimizer's name.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst import minimize
    >>> res = minimize(lambda X: ((X - 0.3) ** 2).sum(axis=1), [(-1, 1)] * 2, max_iterations=60, rng=0)
    >>> res.success, res.nit, res.evaluations == res.nfev, bool(res.fun < 1e-6)
    (True, 60, True, True)
    >>> res.history["best_cost"].shape
    (60,)
    """

    x: FloatArray | None
    fun: float
    nit: int
    nfev: int
    history: dict[str, Any] = field(repr=False)
    message: str
    success: bool
    wall_time: float
    method: str = ""

    @property
    def evaluations(self) -> int:
        """Evaluated candidates (``nfev``)."""
        return self.nfev

    @property
    def partial(self) -> bool:
        """Stopped before its end: interrupted (Ctrl-C) or stopped by the callback."""
        return self.interrupted or self.message.startswith("stopped by callback")

    def _headline(self) -> str:
        fun = "none" if self.x is None else f"{self.fun:.6g}"
        return f"{self.method or 'optimizer'}: fun {fun} after {self.nit} iterations ({self.message})"

    def _scores(self) -> dict[str, float]:
        return {"fun": float(self.fun)}

    @property
    def interrupted(self) -> bool:
        """The run was stopped by Ctrl-C (``KeyboardInterrupt``): ``x`` is the best point
        found before it, not a finished search."""
        return self.message == "interrupted"


@dataclass(frozen=True)
class IntermediateResult(DataclassMatFile):
    """What ``callback(intermediate_result)`` receives after each iteration.

    As every result (:mod:`piezohyst.signals.results`): ``to_pandas()`` (one row), ``plot()``
    (the best candidate so far, one bar per parameter), the notebook display and ``.mat``
    files (``to_mat``, ``from_mat``).

    Parameters
    ----------
    x : ndarray
        Best candidate so far.
    fun : float
        Its cost.
    nit : int
        Iterations done.
    nfev : int
        Candidates evaluated so far.
    mean_cost : float
        Mean of the finite costs of the last population (``inf`` if none was finite).

    Examples
    --------
    >>> from piezohyst import minimize
    >>> seen = []
    >>> res = minimize(lambda X: (X**2).sum(axis=1), [(-1, 1)], max_iterations=5, rng=0, callback=seen.append)
    >>> [r.nit for r in seen], seen[-1].fun == res.fun
    ([1, 2, 3, 4, 5], True)
    """

    x: FloatArray | None
    fun: float
    nit: int
    nfev: int
    mean_cost: float

    def _row(self) -> dict[str, float]:
        row = {"fun": float(self.fun), "nit": float(self.nit), "nfev": float(self.nfev), "mean_cost": self.mean_cost}
        if self.x is not None:
            row.update({f"x[{j}]": float(v) for j, v in enumerate(np.ravel(self.x))})
        return row

    def to_pandas(self) -> pd.DataFrame:
        """One row: ``fun``, ``nit``, ``nfev``, ``mean_cost`` and ``x[j]`` (needs pandas: without
        it an ``ImportError`` says ``pip install pandas``).

        Returns
        -------
        pandas.DataFrame
            Indexed by the iteration.

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst.optimize import IntermediateResult
        >>> r = IntermediateResult(np.array([0.1, 0.2]), 0.05, 3, 24, 0.4)
        >>> r.to_pandas().columns.tolist()  # doctest: +SKIP
        ['fun', 'nit', 'nfev', 'mean_cost', 'x[0]', 'x[1]']
        """
        pd = require_pandas(type(self).__name__)
        return pd.DataFrame([self._row()], index=pd.Index([self.nit], name="iteration"))

    def plot(self, *, ax: Any = None) -> Figure:
        """The best candidate so far, one bar per parameter.

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            The axes to draw on (default: a new figure).

        Returns
        -------
        matplotlib.figure.Figure

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst.optimize import IntermediateResult
        >>> fig = IntermediateResult(np.array([0.1, 0.2]), 0.05, 3, 24, 0.4).plot()
        >>> len(fig.axes[0].patches)
        2
        """
        import matplotlib.pyplot as plt

        if ax is None:
            fig, ax = plt.subplots(figsize=(6, 3.0))
        else:
            fig = ax.figure
        x = np.zeros(0) if self.x is None else np.ravel(self.x)
        ax.bar(np.arange(x.size), x)
        ax.set_xlabel("parameter")
        ax.set_ylabel("best x")
        ax.set_title(f"iteration {self.nit}: fun {self.fun:.6g}", fontsize="small")
        return fig

    def _repr_html_(self) -> str:
        rows = [(k, f"{v:.6g}") for k, v in self._row().items()]
        return html_table(f"IntermediateResult after {self.nit} iterations", rows)


# --------------------------------------------------------------------------------------------
# the common base
# --------------------------------------------------------------------------------------------
class Optimizer:
    """Base of the population optimizers: bounds, ``rng``, the ask/tell cycle and the history.

    Parameters
    ----------
    bounds : sequence of (float, float) or scipy.optimize.Bounds
        ``(lower, upper)`` per parameter; finite, ``lower <= upper`` (a parameter with
        ``lower == upper`` is held fixed).
    population_size : int, optional
        Candidates per iteration ``S`` (>= 4). Default ``max(20, 5 * D)``.
    rng : int, numpy.random.Generator or None
        Source of randomness; the only one used.
    max_iterations : int
        Iteration budget ``T`` (>= 1). Schedules that depend on ``it / T`` use it, and
        :meth:`ask` refuses to go beyond it.
    init : {"lhs", "random"} or array_like, shape (S, D)
        Initial population: a Latin hypercube sample (default), uniform random, or given
        (inside the bounds).

    Notes
    -----
    Subclasses implement ``_tell(X, f) -> X_next``: update their memory with the evaluated
    population ``X`` (costs ``f``, ``+inf`` allowed) and propose the next one; the base clips
    the proposal to the bounds (a no-op for the methods here, which handle bounds
    themselves) so that :meth:`ask` never leaves them.

    Examples
    --------
    The ask/tell cycle with any of the methods (here :class:`CSS`):

    >>> import numpy as np
    >>> from piezohyst.optimize import CSS
    >>> opt = CSS([(-1.0, 1.0), (-1.0, 1.0)], population_size=20, rng=0, max_iterations=50)
    >>> while not opt.done:
    ...     X = opt.ask()
    ...     opt.tell(((X - 0.5) ** 2).sum(axis=1))
    >>> opt.iteration, opt.nfev, bool(np.allclose(opt.best_x, 0.5, atol=1e-2))
    (50, 1000, True)
    """

    name = "optimizer"
    min_population = 4

    def __init__(
        self,
        bounds: BoundsLike,
        population_size: int | None = None,
        rng: RngLike = None,
        max_iterations: int = 200,
        *,
        init: str | npt.ArrayLike = "lhs",
    ) -> None:
        self._lower, self._upper = _as_bounds(bounds)
        self._range = self._upper - self._lower
        D = self._lower.size
        init_array = None
        if not isinstance(init, str):
            try:
                init_array = np.array(init, dtype=np.float64)
            except (TypeError, ValueError) as e:
                raise ParameterTypeError(f"init must be 'lhs', 'random' or an (S, D) array: {e}") from None
            if init_array.ndim != 2 or init_array.shape[1] != D:
                raise ParameterError(f"init has shape {init_array.shape}, expected (S, {D})")
            if population_size is None:
                population_size = init_array.shape[0]
        if population_size is None:
            population_size = max(20, 5 * D)
        self.population_size = as_int(
            population_size, "population_size", minimum=self.min_population, maximum=MAX_POPULATION
        )
        self.max_iterations = as_int(max_iterations, "max_iterations", minimum=1)
        self._rng = _as_rng(rng)
        S = self.population_size
        if init_array is not None:
            if init_array.shape[0] != S:
                raise ParameterError(f"init has {init_array.shape[0]} rows, population_size = {S}")
            bad = np.argwhere(~np.isfinite(init_array) | (init_array < self._lower) | (init_array > self._upper))
            if bad.size:
                i, d = bad[0]
                raise ParameterError(
                    f"init[{i}, {d}] = {init_array[i, d]} is outside bounds[{d}] = ({self._lower[d]}, {self._upper[d]})"
                )
            X0 = init_array
        elif init == "lhs":
            # one stratum per candidate in every dimension, strata shuffled independently
            u = (np.argsort(self._rng.random((D, S)), axis=1).T + self._rng.random((S, D))) / S
            X0 = self._lower + u * self._range
        elif init == "random":
            X0 = self._lower + self._rng.random((S, D)) * self._range
        else:
            raise ParameterError(f"init = {init!r} is not 'lhs', 'random' or an (S, D) array")
        self._pending = self._clip(X0)
        self._asked = False
        self._iteration = 0
        self._nfev = 0
        self._best_x: FloatArray | None = None
        self._best_cost = np.inf
        self._last_costs: FloatArray | None = None
        self._h_best: list[float] = []
        self._h_mean: list[float] = []
        self._h_x: list[FloatArray] = []
        self._h_finite: list[int] = []
        self._h_nfev: list[int] = []
        self._t_start: float | None = None
        self._elapsed = 0.0

    # -- properties ---------------------------------------------------------------------------
    @property
    def bounds(self) -> FloatArray:
        """``(D, 2)`` array of ``(lower, upper)``."""
        return np.stack([self._lower, self._upper], axis=1)

    @property
    def dimension(self) -> int:
        """Number of parameters ``D``."""
        return int(self._lower.size)

    @property
    def iteration(self) -> int:
        """Number of populations evaluated (``tell`` calls) so far."""
        return self._iteration

    @property
    def nfev(self) -> int:
        """Number of candidates evaluated so far."""
        return self._nfev

    @property
    def done(self) -> bool:
        """``True`` once ``max_iterations`` populations have been evaluated."""
        return self._iteration >= self.max_iterations

    @property
    def best_x(self) -> FloatArray | None:
        """Best candidate so far (a copy), ``None`` before the first :meth:`tell`."""
        return None if self._best_x is None else self._best_x.copy()

    @property
    def best_cost(self) -> float:
        """Cost of :attr:`best_x` (``inf`` before the first finite cost)."""
        return float(self._best_cost)

    @property
    def last_costs(self) -> FloatArray | None:
        """Costs of the last evaluated population (a copy)."""
        return None if self._last_costs is None else self._last_costs.copy()

    @property
    def history(self) -> dict[str, npt.NDArray[Any]]:
        """Per-iteration records as arrays (see :class:`OptimizeResult`)."""
        D = self.dimension
        return {
            "best_cost": np.array(self._h_best, dtype=np.float64),
            "mean_cost": np.array(self._h_mean, dtype=np.float64),
            "best_x": np.array(self._h_x, dtype=np.float64).reshape(-1, D),
            "n_finite": np.array(self._h_finite, dtype=np.int64),
            "nfev": np.array(self._h_nfev, dtype=np.int64),
        }

    # -- ask / tell ---------------------------------------------------------------------------
    def ask(self) -> FloatArray:
        """The population to evaluate next, shape ``(S, D)``, inside the bounds.

        Calling it again before :meth:`tell` returns the same population. Raises
        ``RuntimeError`` once ``max_iterations`` populations have been evaluated.

        Returns
        -------
        ndarray, shape (S, D)

        Examples
        --------
        >>> from piezohyst.optimize import PSO
        >>> opt = PSO([(0.0, 1.0)] * 3, population_size=8, rng=0)
        >>> X = opt.ask()
        >>> X.shape, bool((X >= 0).all() and (X <= 1).all()), bool((opt.ask() == X).all())
        ((8, 3), True, True)
        """
        if self.done:
            raise ComputationError(
                f"{self.name}: max_iterations = {self.max_iterations} populations have been evaluated; "
                "nothing more to ask"
            )
        if self._t_start is None:
            self._t_start = time.perf_counter()
        self._asked = True
        return self._pending.copy()

    def tell(self, costs: npt.ArrayLike) -> None:
        """Report the costs of the population returned by the last :meth:`ask`.

        Parameters
        ----------
        costs : array_like, shape (S,)
            One cost per row; ``+inf`` marks an invalid candidate. NaN and ``-inf`` raise
            ``ValueError``.

        Examples
        --------
        >>> from piezohyst.optimize import DE
        >>> opt = DE([(0.0, 1.0)], population_size=6, rng=0)
        >>> X = opt.ask()
        >>> opt.tell(X[:, 0])                 # cost = the parameter itself
        >>> bool(opt.best_cost == X[:, 0].min()), opt.iteration
        (True, 1)
        """
        if not self._asked:
            raise ComputationError(f"{self.name}: tell() without a pending ask()")
        f = self._check_costs(costs, "costs")
        X = self._pending
        self._asked = False
        self._iteration += 1
        self._nfev += f.size
        self._last_costs = f.copy()
        i = int(np.argmin(f))
        if self._best_x is None or f[i] < self._best_cost:
            self._best_x = X[i].copy()
            self._best_cost = float(f[i])
        finite = np.isfinite(f)
        n_finite = int(np.count_nonzero(finite))
        self._h_best.append(self._best_cost)
        self._h_mean.append(float(np.mean(f[finite])) if n_finite else np.inf)
        self._h_x.append(self._best_x.copy())
        self._h_finite.append(n_finite)
        self._h_nfev.append(self._nfev)
        self._pending = self._clip(self._tell(X, f))
        # ask() set the start before the first tell() (tell() needs a pending ask())
        self._elapsed = time.perf_counter() - (self._t_start or 0.0)

    def _check_costs(self, costs: npt.ArrayLike, name: str) -> FloatArray:
        try:
            f = np.array(costs, dtype=np.float64)
        except (TypeError, ValueError) as e:
            raise ParameterTypeError(f"{name} must be an array of numbers: {e}") from None
        S = self.population_size
        if f.shape != (S,):
            raise ParameterError(f"{name} has shape {f.shape}, expected ({S},): one cost per candidate")
        bad = np.flatnonzero(np.isnan(f))
        if bad.size:
            raise ParameterError(
                f"{name}[{bad[0]}] is NaN (candidate {self._pending[bad[0]].tolist()}); "
                "NaN marks a bug in the objective, return +inf for invalid candidates"
            )
        bad = np.flatnonzero(f == -np.inf)
        if bad.size:
            raise ParameterError(f"{name}[{bad[0]}] = -inf; costs must be finite or +inf")
        return f

    def converged(self, tol: float, atol: float = 0.0) -> bool:
        """Spread test on the last population (as in SciPy's DE):
        ``std(f) <= atol + tol * |mean(f)|``, all costs finite.

        Parameters
        ----------
        tol : float
            Relative tolerance on the spread of the costs.
        atol : float
            Absolute tolerance.

        Returns
        -------
        bool

        Examples
        --------
        >>> from piezohyst.optimize import PSO
        >>> opt = PSO([(0.0, 1.0)], population_size=4, rng=0)
        >>> _ = opt.ask()
        >>> opt.tell([1.0, 1.0, 1.0, 1.0])
        >>> opt.converged(tol=1e-9)
        True
        """
        f = self._last_costs
        if f is None or not np.all(np.isfinite(f)):
            return False
        return bool(np.std(f) <= atol + tol * abs(np.mean(f)))

    def intermediate_result(self) -> IntermediateResult:
        """The object handed to callbacks.

        Returns
        -------
        IntermediateResult

        Examples
        --------
        >>> from piezohyst.optimize import PSO
        >>> opt = PSO([(0.0, 1.0)], population_size=4, rng=0)
        >>> _ = opt.ask()
        >>> opt.tell([3.0, 1.0, 2.0, 4.0])
        >>> r = opt.intermediate_result()
        >>> r.fun, r.nit, r.nfev, r.mean_cost
        (1.0, 1, 4, 2.5)
        """
        return IntermediateResult(
            x=self.best_x,
            fun=self.best_cost,
            nit=self._iteration,
            nfev=self._nfev,
            mean_cost=self._h_mean[-1] if self._h_mean else np.inf,
        )

    def result(self, *, message: str | None = None, success: bool | None = None) -> OptimizeResult:
        """The run so far as an :class:`OptimizeResult`.

        ``message``/``success`` default to the budget outcome: ``"maximum number of iterations
        reached"`` (``success=True``) when done, ``"running"`` (``False``) otherwise, and
        ``"no finite cost found"`` (``False``) if every cost was ``inf``.

        Parameters
        ----------
        message : str, optional
            Why the run stopped.
        success : bool, optional
            Whether it succeeded.

        Returns
        -------
        OptimizeResult

        Examples
        --------
        >>> from piezohyst.optimize import PSO
        >>> opt = PSO([(0.0, 1.0)], population_size=4, rng=0, max_iterations=1)
        >>> _ = opt.ask()
        >>> opt.tell([3.0, 1.0, 2.0, 4.0])
        >>> res = opt.result()
        >>> res.fun, res.success, res.message
        (1.0, True, 'maximum number of iterations reached')
        """
        if message is None:
            message = "maximum number of iterations reached" if self.done else "running"
            if success is None:
                success = self.done
        if not np.isfinite(self._best_cost):
            if success and self._iteration:
                message = "no finite cost found"
            success = False
        return OptimizeResult(
            x=None if self._best_x is None else _readonly(self._best_x),
            fun=self.best_cost,
            nit=self._iteration,
            nfev=self._nfev,
            history={k: _readonly(v) for k, v in self.history.items()},
            message=message,
            success=bool(success),
            wall_time=float(self._elapsed),
            method=self.name,
        )

    # -- for subclasses -----------------------------------------------------------------------
    def _clip(self, X: FloatArray) -> FloatArray:
        return np.clip(X, self._lower, self._upper)

    def _tell(self, X: FloatArray, f: FloatArray) -> FloatArray:  # pragma: no cover - abstract
        raise NotImplementedError

    @property
    def _it_fraction(self) -> float:
        """``it / it_max`` with ``it`` the 0-based index of the population just evaluated."""
        return (self._iteration - 1) / self.max_iterations


# --------------------------------------------------------------------------------------------
# CSS
# --------------------------------------------------------------------------------------------
def css_charges(costs: npt.ArrayLike) -> FloatArray:
    """CSS charges ``q_i = (f_i - f_worst) / (f_best - f_worst)`` (Kaveh & Talatahari 2010).

    ``f_best`` and ``f_worst`` are the best and worst *finite* costs of the population.
    Candidates with infinite cost get ``q = 0``; if all finite costs are equal, the finite
    ones get ``q = 1``.

    Parameters
    ----------
    costs : array_like, shape (S,)
        The population's costs (``+inf`` allowed).

    Returns
    -------
    ndarray, shape (S,)

    Examples
    --------
    >>> from piezohyst.optimize import css_charges
    >>> css_charges([1.0, 2.0, 3.0, float("inf")]).tolist()
    [1.0, 0.5, 0.0, 0.0]
    """
    f = np.asarray(costs, dtype=np.float64)
    finite = np.isfinite(f)
    q = np.zeros(f.shape)
    if not finite.any():
        return q
    fb, fw = f[finite].min(), f[finite].max()
    if fw == fb:
        q[finite] = 1.0
    else:
        q[finite] = (fw - f[finite]) / (fw - fb)
    return q


def css_forces(
    positions: npt.ArrayLike, costs: npt.ArrayLike, *, a: float, eps: float, rand: npt.ArrayLike
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Charges, attraction matrix and resultant forces of one CSS step (docs/spec.md §4).

    With ``X_best`` the position of the best (finite) cost of the population:

    * ``q_i = (f_i - f_worst)/(f_best - f_worst)``  (:func:`css_charges`)
    * ``r_ij = ||X_i - X_j|| / (||(X_i + X_j)/2 - X_best|| + eps)``
    * ``p_ij = 1`` if ``f_i < f_j``, or if ``f_i > f_j`` and
      ``(f_j - f_best)/(f_i - f_j) > rand_ij``; else ``0`` (so ``p_ii = 0`` and equal costs
      do not attract)
    * ``F_j = sum_i p_ij [q_i/a^3 r_ij if r_ij < a else q_i/r_ij^2] (X_i - X_j)``

    ``F_j`` is Kaveh & Talatahari's force divided by the mass ``m_j = q_j``, the quantity the
    position update uses.

    Parameters
    ----------
    positions : array_like, shape (N, D)
    costs : array_like, shape (N,)
        ``+inf`` allowed (charge 0, attracted by every finite candidate).
    a : float
        Radius of the charged spheres.
    eps : float
        Guard against a zero denominator in ``r_ij``.
    rand : array_like, shape (N, N)
        Uniform draws ``rand_ij`` for the probabilistic attraction of ``j`` by worse ``i``.

    Returns
    -------
    q : ndarray, shape (N,)
    p : ndarray, shape (N, N)
        ``p[i, j] = p_ij`` (``i`` attracts ``j``).
    F : ndarray, shape (N, D)

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.optimize import css_forces
    >>> q, p, F = css_forces([[0.0], [1.0]], [0.0, 1.0], a=0.5, eps=0.0, rand=np.full((2, 2), 0.5))
    >>> F.ravel().tolist()       # r_01 = 1/0.5 = 2 >= a: F_1 = q_0/r^2 (X_0 - X_1)
    [0.0, -0.25]
    """
    X = np.asarray(positions, dtype=np.float64)
    f = np.asarray(costs, dtype=np.float64)
    u = np.asarray(rand, dtype=np.float64)
    N = f.size
    q = css_charges(f)
    finite = np.isfinite(f)
    if not finite.any():
        return q, np.zeros((N, N)), np.zeros_like(X)
    fb = f[finite].min()
    x_best = X[int(np.argmin(f))]
    fi, fj = f[:, None], f[None, :]
    better = fi < fj
    worse = fi > fj
    with np.errstate(divide="ignore", invalid="ignore"):
        # only evaluated where f_i > f_j (f_i may be inf: ratio 0; f_j is then finite)
        ratio = np.where(worse, (fj - fb) / np.where(worse, fi - fj, 1.0), 0.0)
    p = (better | (worse & (ratio > u))).astype(np.float64)
    diff = X[:, None, :] - X[None, :, :]  # diff[i, j] = X_i - X_j
    dist = np.linalg.norm(diff, axis=2)
    mid = np.linalg.norm(0.5 * (X[:, None, :] + X[None, :, :]) - x_best, axis=2)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(dist > 0, dist / (mid + eps), 0.0)  # r_ii = 0 (and p_ii = 0 anyway)
        far = np.where(r > 0, q[:, None] / (r * r), 0.0)
    coef = np.where(r < a, q[:, None] / a**3 * r, far) * p
    F = np.einsum("ij,ijd->jd", coef, diff)
    return q, p, F


class CSS(Optimizer):
    """Charged System Search (Kaveh & Talatahari 2010), as in docs/spec.md §4 — seed 1's optimizer.

    Each candidate (charged particle, CP) ``X_j`` with cost ``f_j`` carries the charge
    ``q_j = (f_j - f_worst)/(f_best - f_worst)`` (best and worst of the current population);
    the force on ``j`` is computed by :func:`css_forces`::

        r_ij = ||X_i - X_j|| / (||(X_i + X_j)/2 - X_best|| + eps)
        p_ij = 1  if f_i < f_j  or  (f_i > f_j and (f_j - f_best)/(f_i - f_j) > rand)
        F_j  = sum_i p_ij [q_i/a^3 r_ij if r_ij < a else q_i/r_ij^2] (X_i - X_j)
        a    = 0.1 max_d (upper_d - lower_d)

    and every CP moves (``it`` = 0-based index of the population just evaluated,
    ``it_max = max_iterations``)::

        k_a = 0.5 (1 + it/it_max),   k_v = 0.5 (1 - it/it_max)
        X_new = X + rand_1 k_a F + rand_2 k_v V,    V_new = X_new - X

    ``rand_1``, ``rand_2`` are one uniform draw per CP (as in the paper), ``V = 0`` at start,
    and ``rand_ij`` one draw per pair. ``F`` here is the paper's ``F_j / m_j`` with
    ``m_j = q_j`` and ``dt = 1``.

    **Charged memory (CM)**: the best ``max(1, N // 4)`` distinct candidates with finite cost
    seen so far (updated after every evaluation: new CPs better than the worst in the CM
    replace it).

    **Boundaries**, harmony-search style: every component of ``X_new`` that leaves its
    bounds is regenerated: with probability ``cmcr`` it is taken from the same component of
    a randomly chosen CM member and then, with probability ``par``, pitch-adjusted by
    ``bandwidth * (upper - lower) * U(-1, 1)`` (clipped to the bounds); otherwise (or while
    the CM is empty) it is drawn uniformly in the bounds. ``V_new`` is computed from the
    corrected position.

    A population whose costs are all ``+inf`` feels no force; it is redrawn uniformly in the
    bounds with ``V = 0`` (our choice: the paper assumes finite costs).

    Parameters
    ----------
    bounds, population_size, rng, max_iterations, init
        See :class:`Optimizer`.
    cmcr : float
        Charged-memory considering rate, default 0.95.
    par : float
        Pitch adjusting rate, default 0.1.
    bandwidth : float
        Pitch-adjust bandwidth as a fraction of each parameter's range, default 0.01.
    normalize : bool
        Compute separations, forces and velocities in the unit box (default). The spec's
        ``a = 0.1 * max range`` compares the unit-less ``r_ij`` with a length in parameter
        units; with parameters of different units (the CEMF model spans 1e-3..1e5) that
        keeps the population from contracting. ``False`` is the literal form.
    eps : float, optional
        Denominator guard of ``r_ij``; default ``1e-10 * max range``.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.optimize import CSS
    >>> opt = CSS([(-5, 5)] * 2, population_size=20, rng=0, max_iterations=200)
    >>> while not opt.done:
    ...     X = opt.ask()
    ...     opt.tell(np.sum((X - 1.0) ** 2, axis=1))
    >>> bool(opt.best_cost < 1e-6)
    True
    """

    name = "css"

    def __init__(
        self,
        bounds: BoundsLike,
        population_size: int | None = None,
        rng: RngLike = None,
        max_iterations: int = 200,
        *,
        cmcr: float = 0.95,
        par: float = 0.1,
        bandwidth: float = 0.01,
        eps: float | None = None,
        init: str | npt.ArrayLike = "lhs",
        normalize: bool = True,
    ) -> None:
        super().__init__(bounds, population_size, rng, max_iterations, init=init)
        self.cmcr = _as_fraction(cmcr, "cmcr")
        self.par = _as_fraction(par, "par")
        self.bandwidth = _as_fraction(bandwidth, "bandwidth")
        self.normalize = bool(normalize)
        # the forces mix the unit-less separation r_ij with the radius a: in the unit box
        # (normalize=True) both are on the same scale whatever the parameters' units
        scale = 1.0 if self.normalize else float(np.max(self._range))
        self.a = 0.1 * scale
        self.eps = 1e-10 * scale if eps is None else as_scalar(eps, "eps", positive=True)
        self.memory_size = max(1, self.population_size // 4)
        self._V = np.zeros((self.population_size, self.dimension))
        self._cm_x = np.empty((0, self.dimension))
        self._cm_f = np.empty(0)

    @property
    def charged_memory(self) -> tuple[FloatArray, FloatArray]:
        """``(positions (M, D), costs (M,))`` of the charged memory, best first."""
        return self._cm_x.copy(), self._cm_f.copy()

    def _update_memory(self, X: FloatArray, f: FloatArray) -> None:
        finite = np.isfinite(f)
        xs = np.concatenate([self._cm_x, X[finite]])
        fs = np.concatenate([self._cm_f, f[finite]])
        order = np.argsort(fs, kind="stable")  # best first; the memory before new CPs on ties
        xs, fs = xs[order], fs[order]
        _, first = np.unique(xs, axis=0, return_index=True)  # distinct positions, best copy
        keep = np.sort(first)[: self.memory_size]
        self._cm_x, self._cm_f = xs[keep], fs[keep]

    def _tell(self, X: FloatArray, f: FloatArray) -> FloatArray:
        N, D = X.shape
        rng = self._rng
        self._update_memory(X, f)
        if not np.isfinite(f).any():
            self._V = np.zeros((N, D))
            return self._lower + rng.random((N, D)) * self._range
        # a fixed parameter (zero range) stays put in either form
        scale = np.where(self._range > 0, self._range, 1.0) if self.normalize else 1.0
        U = (X - self._lower) / scale if self.normalize else X
        _, _, F = css_forces(U, f, a=self.a, eps=self.eps, rand=rng.random((N, N)))
        t = self._it_fraction
        ka, kv = 0.5 * (1.0 + t), 0.5 * (1.0 - t)
        r1 = rng.random((N, 1))
        r2 = rng.random((N, 1))
        Xn = X + scale * (r1 * ka * F + r2 * kv * self._V)
        Xn = self._harmony_bounds(Xn)
        self._V = (Xn - X) / scale
        return Xn

    def _harmony_bounds(self, Xn: FloatArray) -> FloatArray:
        out = ~((Xn >= self._lower) & (Xn <= self._upper))  # also catches non-finite
        j, d = np.nonzero(out)
        if j.size == 0:
            return Xn
        lo, hi = self._lower[d], self._upper[d]
        # five draws per out-of-bounds component, in row-major order:
        # use memory?, which member, pitch adjust?, adjustment, uniform value
        u = self._rng.random((j.size, 5))
        v = lo + u[:, 4] * (hi - lo)
        M = self._cm_f.size
        if M:
            from_cm = u[:, 0] < self.cmcr
            member = np.minimum((u[:, 1] * M).astype(np.int64), M - 1)
            mem = self._cm_x[member, d]
            adjust = u[:, 2] < self.par
            mem = np.where(adjust, np.clip(mem + self.bandwidth * (hi - lo) * (2.0 * u[:, 3] - 1.0), lo, hi), mem)
            v = np.where(from_cm, mem, v)
        Xn = Xn.copy()
        Xn[j, d] = v
        return Xn


# --------------------------------------------------------------------------------------------
# PSO and MPSO
# --------------------------------------------------------------------------------------------
class PSO(Optimizer):
    """Particle swarm optimization, global-best topology.

    After each evaluation the personal bests ``P_i`` and the global best ``G`` are updated
    (strict improvement), then::

        V = w V + c1 r1 (P_i - X) + c2 r2 (G - X),     |V_d| <= vmax (upper_d - lower_d)
        X = X + V

    with ``r1``, ``r2`` uniform per component. A component that leaves the bounds is put on
    the bound and its velocity set to zero (absorbing wall). Initial velocities are uniform
    in ``[-vmax, vmax]`` times the range.

    Parameters
    ----------
    bounds, population_size, rng, max_iterations, init
        See :class:`Optimizer`.
    w : float
        Inertia, default 0.7298 (Clerc & Kennedy's constriction, equivalently).
    c1, c2 : float
        Cognitive and social coefficients, default 1.49618 each.
    vmax : float
        Velocity clamp as a fraction of each parameter's range, default 0.2.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.optimize import PSO
    >>> opt = PSO([(-5, 5)] * 2, rng=0, max_iterations=100)
    >>> while not opt.done:
    ...     X = opt.ask()
    ...     opt.tell(np.sum(X ** 2, axis=1))
    >>> bool(opt.best_cost < 1e-10)
    True
    """

    name = "pso"

    def __init__(
        self,
        bounds: BoundsLike,
        population_size: int | None = None,
        rng: RngLike = None,
        max_iterations: int = 200,
        *,
        w: float = 0.7298,
        c1: float = 1.49618,
        c2: float = 1.49618,
        vmax: float = 0.2,
        init: str | npt.ArrayLike = "lhs",
    ) -> None:
        super().__init__(bounds, population_size, rng, max_iterations, init=init)
        self.w = as_scalar(w, "w", nonnegative=True)
        self.c1 = as_scalar(c1, "c1", nonnegative=True)
        self.c2 = as_scalar(c2, "c2", nonnegative=True)
        self.vmax = _as_fraction(vmax, "vmax", open_low=True)
        self._vlim = self.vmax * self._range
        self._V = (2.0 * self._rng.random((self.population_size, self.dimension)) - 1.0) * self._vlim
        self._P: FloatArray | None = None
        self._Pf: FloatArray | None = None

    @property
    def velocities(self) -> FloatArray:
        """Current velocities ``(S, D)`` (those that produced the pending population)."""
        return self._V.copy()

    def inertia(self, it: int) -> float:
        """Inertia weight used after evaluating population ``it`` (0-based): constant ``w``.

        Parameters
        ----------
        it : int
            The population's index.

        Returns
        -------
        float

        Examples
        --------
        >>> from piezohyst.optimize import PSO
        >>> PSO([(0.0, 1.0)], w=0.7, rng=0).inertia(10)
        0.7
        """
        return self.w

    def _update_bests(self, X: FloatArray, f: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Update the personal bests; returns them and the global best."""
        if self._P is None or self._Pf is None:
            self._P, self._Pf = X.copy(), f.copy()
        else:
            better = f < self._Pf
            self._P[better] = X[better]
            self._Pf[better] = f[better]
        g = int(np.argmin(self._Pf))
        return self._P, self._P[g]

    def _random_particle_term(self, X: FloatArray) -> FloatArray | float:
        return 0.0

    def _tell(self, X: FloatArray, f: FloatArray) -> FloatArray:
        P, G = self._update_bests(X, f)
        S, D = X.shape
        rng = self._rng
        r1 = rng.random((S, D))
        r2 = rng.random((S, D))
        V = (
            self.inertia(self._iteration - 1) * self._V
            + self.c1 * r1 * (P - X)
            + self.c2 * r2 * (G - X)
            + self._random_particle_term(X)
        )
        V = np.clip(V, -self._vlim, self._vlim)
        Xn = X + V
        low, high = Xn < self._lower, Xn > self._upper
        hit = low | high
        Xn = np.where(low, self._lower, np.where(high, self._upper, Xn))
        V[hit] = 0.0
        self._V = V
        return Xn


class MPSO(PSO):
    """Modified PSO of seed 2 (docs/spec.md §4, **[R]**): a random-particle term and a nonlinearly
    decreasing inertia::

        V = w(t) V + c1 r1 (P_i - X) + c2 r2 (G - X) + c3 r3 (P_k - X)
        w(t) = w_min + (w_max - w_min) (1 - t/T)^2

    ``P_k`` is the personal best of a particle ``k != i`` drawn uniformly for each ``i`` at
    each iteration; ``t`` is the 0-based index of the population just evaluated and
    ``T = max_iterations``. Velocity clamp and walls as in :class:`PSO`.

    Parameters
    ----------
    bounds, population_size, rng, max_iterations, init
        See :class:`Optimizer`.
    w_max, w_min : float
        Inertia at the start and the end, default 0.9 and 0.4.
    c1, c2, c3 : float
        Cognitive, social and random-particle coefficients, default 1.5, 1.5 and 0.5.
    vmax : float
        Velocity clamp as a fraction of each parameter's range, default 0.2.

    Examples
    --------
    >>> from piezohyst.optimize import MPSO
    >>> opt = MPSO([(0, 1)], rng=0, max_iterations=100, w_max=0.9, w_min=0.4)
    >>> opt.inertia(0), round(opt.inertia(50), 4), opt.inertia(100)
    (0.9, 0.525, 0.4)
    """

    name = "mpso"

    def __init__(
        self,
        bounds: BoundsLike,
        population_size: int | None = None,
        rng: RngLike = None,
        max_iterations: int = 200,
        *,
        w_max: float = 0.9,
        w_min: float = 0.4,
        c1: float = 1.5,
        c2: float = 1.5,
        c3: float = 0.5,
        vmax: float = 0.2,
        init: str | npt.ArrayLike = "lhs",
    ) -> None:
        super().__init__(bounds, population_size, rng, max_iterations, w=w_max, c1=c1, c2=c2, vmax=vmax, init=init)
        self.w_max = as_scalar(w_max, "w_max", nonnegative=True)
        self.w_min = as_scalar(w_min, "w_min", nonnegative=True)
        if self.w_min > self.w_max:
            raise ParameterError(f"w_min = {self.w_min} must be <= w_max = {self.w_max}")
        self.c3 = as_scalar(c3, "c3", nonnegative=True)

    def inertia(self, it: int) -> float:
        """``w(t) = w_min + (w_max - w_min) (1 - t/T)^2``, ``T = max_iterations``.

        Parameters
        ----------
        it : int
            The population's index ``t`` (0-based).

        Returns
        -------
        float

        Examples
        --------
        >>> from piezohyst.optimize import MPSO
        >>> opt = MPSO([(0.0, 1.0)], w_max=0.9, w_min=0.4, max_iterations=100, rng=0)
        >>> opt.inertia(0), opt.inertia(50), opt.inertia(100)
        (0.9, 0.525, 0.4)
        """
        return self.w_min + (self.w_max - self.w_min) * (1.0 - it / self.max_iterations) ** 2

    def _random_particle_term(self, X: FloatArray) -> FloatArray | float:
        if self._P is None:  # pragma: no cover - _update_bests runs first
            raise ComputationError("mpso: no personal bests yet")
        S, D = X.shape
        k = (np.arange(S) + self._rng.integers(1, S, size=S)) % S  # uniform over the others
        r3 = self._rng.random((S, D))
        term: FloatArray = self.c3 * r3 * (self._P[k] - X)
        return term


# --------------------------------------------------------------------------------------------
# DE
# --------------------------------------------------------------------------------------------
class DE(Optimizer):
    """Differential evolution, DE/rand/1/bin (Storn & Price 1997).

    The first ``ask()`` returns the initial population; afterwards each ``ask()`` returns
    one trial vector per target ``x_i``::

        v_i = x_r1 + F (x_r2 - x_r3)            r1, r2, r3 distinct, != i
        u_ij = v_ij if rand_ij < CR or j == j_rand else x_ij
        x_i <- u_i if f(u_i) <= f(x_i)

    A component of ``v_i`` outside the bounds is reflected at the violated bound; if still
    outside (a step longer than the range) it is drawn uniformly in the bounds.

    Parameters
    ----------
    bounds, population_size, rng, max_iterations, init
        See :class:`Optimizer`.
    F : float or (float, float)
        Mutation factor in ``(0, 2]``, default 0.7; a pair ``(lo, hi)`` draws ``F`` uniformly
        per iteration (dither).
    CR : float
        Crossover rate in ``[0, 1]``, default 0.9.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.optimize import DE
    >>> opt = DE([(-5, 5)] * 2, rng=0, max_iterations=100)
    >>> while not opt.done:
    ...     X = opt.ask()
    ...     opt.tell(np.sum(X ** 2, axis=1))
    >>> bool(opt.best_cost < 1e-10)
    True
    """

    name = "de"

    def __init__(
        self,
        bounds: BoundsLike,
        population_size: int | None = None,
        rng: RngLike = None,
        max_iterations: int = 200,
        *,
        F: float | tuple[float, float] | list[float] | npt.NDArray[np.float64] = 0.7,
        CR: float = 0.9,
        init: str | npt.ArrayLike = "lhs",
    ) -> None:
        super().__init__(bounds, population_size, rng, max_iterations, init=init)
        if isinstance(F, (tuple, list, np.ndarray)):
            if len(F) != 2:
                raise ParameterError(f"F = {F!r} must be a number or a (lo, hi) pair")
            lo = _as_fraction(F[0], "F[0]", high=2.0, open_low=True)
            hi = _as_fraction(F[1], "F[1]", high=2.0, open_low=True)
            if lo > hi:
                raise ParameterError(f"F = {tuple(F)}: lo > hi")
            self.F: float | tuple[float, float] = (lo, hi)
        else:
            self.F = _as_fraction(F, "F", high=2.0, open_low=True)
        self.CR = _as_fraction(CR, "CR")
        self._pop: FloatArray | None = None
        self._popf: FloatArray | None = None

    @property
    def population(self) -> tuple[FloatArray, FloatArray] | None:
        """``(targets (S, D), costs (S,))`` of the current generation, ``None`` before the first ``tell``."""
        if self._pop is None or self._popf is None:
            return None
        return self._pop.copy(), self._popf.copy()

    def _tell(self, X: FloatArray, f: FloatArray) -> FloatArray:
        rng = self._rng
        if self._pop is None or self._popf is None:
            self._pop, self._popf = X.copy(), f.copy()
        else:
            keep = f <= self._popf
            self._pop[keep] = X[keep]
            self._popf[keep] = f[keep]
        S, D = self._pop.shape
        keys = rng.random((S, S))
        np.fill_diagonal(keys, np.inf)
        r = np.argsort(keys, axis=1)[:, :3]
        Fm = self.F if not isinstance(self.F, tuple) else self.F[0] + rng.random() * (self.F[1] - self.F[0])
        P = self._pop
        V = P[r[:, 0]] + Fm * (P[r[:, 1]] - P[r[:, 2]])
        # reflection, then uniform resampling for what is still outside
        V = np.where(V < self._lower, 2.0 * self._lower - V, V)
        V = np.where(V > self._upper, 2.0 * self._upper - V, V)
        bad = (V < self._lower) | (V > self._upper)
        V = np.where(bad, self._lower + rng.random((S, D)) * self._range, V)
        cross = rng.random((S, D)) < self.CR
        cross[np.arange(S), rng.integers(D, size=S)] = True
        return np.where(cross, V, P)


METHODS: dict[str, type[Optimizer]] = {"css": CSS, "pso": PSO, "mpso": MPSO, "de": DE}
"""Method names accepted by :func:`minimize` and their classes."""


# --------------------------------------------------------------------------------------------
# minimize
# --------------------------------------------------------------------------------------------
def _method_class(method: str | type[Optimizer]) -> type[Optimizer]:
    if isinstance(method, type) and issubclass(method, Optimizer):
        return method
    if isinstance(method, str) and method.lower() in METHODS:
        return METHODS[method.lower()]
    raise ParameterError(f"method = {method!r} is not one of {sorted(METHODS)} (or an Optimizer subclass)")


def _evaluate(fun_batch: BatchObjective, X: FloatArray) -> FloatArray:
    out = fun_batch(X)
    try:
        f = np.array(out, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise ParameterTypeError(f"fun_batch must return an array of numbers, got {type(out).__name__}: {e}") from None
    if f.shape != (X.shape[0],):
        raise ParameterError(
            f"fun_batch returned shape {f.shape} for an input of shape {X.shape}; "
            f"expected ({X.shape[0]},): one cost per row"
        )
    bad = np.flatnonzero(np.isnan(f))
    if bad.size:
        raise ParameterError(
            f"fun_batch returned NaN at index {bad[0]} (x = {X[bad[0]].tolist()}); "
            "NaN marks a bug in the objective, return +inf for invalid candidates"
        )
    return f


def polish_lbfgsb(
    fun_batch: BatchObjective,
    x0: FloatArray,
    f0: float,
    lower: FloatArray,
    upper: FloatArray,
    options: Mapping[str, Any],
) -> tuple[FloatArray, float, int]:
    """L-BFGS-B from ``x0`` with central-difference gradients, each value+gradient one batch
    call of ``2 D + 1`` rows. Returns ``(x, f, nfev)``."""
    from scipy.optimize import minimize as sp_minimize

    D = x0.size
    rng_ = upper - lower
    free = rng_ > 0
    nfev = 0

    def fg(x: FloatArray) -> tuple[float, FloatArray]:
        nonlocal nfev
        x = np.clip(x, lower, upper)
        h = np.cbrt(np.finfo(float).eps) * np.maximum(np.abs(x), 0.01 * rng_)
        xp = np.minimum(x + h, upper)
        xm = np.maximum(x - h, lower)
        rows = np.empty((2 * D + 1, D))
        rows[0] = x
        rows[1 : D + 1] = x
        rows[D + 1 :] = x
        rows[1 + np.arange(D), np.arange(D)] = xp
        rows[D + 1 + np.arange(D), np.arange(D)] = xm
        f = _evaluate(fun_batch, rows)
        nfev += rows.shape[0]
        fx, fp, fm = f[0], f[1 : D + 1], f[D + 1 :]
        g = np.zeros(D)
        for d in np.flatnonzero(free):
            pts = [(xp[d], fp[d]), (x[d], fx), (xm[d], fm[d])]
            pts = [(a, b) for a, b in pts if np.isfinite(b)]
            (a1, b1), (a2, b2) = (pts[0], pts[-1]) if len(pts) >= 2 else ((0.0, 0.0), (1.0, 0.0))
            if a1 != a2:
                g[d] = (b1 - b2) / (a1 - a2)
        if not np.isfinite(fx):
            return 1e300, g
        return fx, g

    # the caller's L-BFGS-B options are free-form (SciPy checks them at run time)
    opts: Any = {"maxiter": 200, **options}
    res = sp_minimize(fg, x0, jac=True, method="L-BFGS-B", bounds=list(zip(lower, upper, strict=False)), options=opts)
    x1 = np.clip(res.x, lower, upper)
    f1 = _evaluate(fun_batch, x1[None, :])[0]
    nfev += 1
    if f1 < f0:
        return x1, float(f1), nfev
    return x0, f0, nfev


def minimize(
    fun_batch: BatchObjective,
    bounds: BoundsLike,
    method: str | type[Optimizer] = "css",
    *,
    population_size: int | None = None,
    max_iterations: int = 200,
    rng: RngLike = None,
    callback: Callback | None = None,
    progress: bool = False,
    polish: bool | Mapping[str, Any] = False,
    tol: float | None = None,
    atol: float = 0.0,
    **options: Any,
) -> OptimizeResult:
    """Minimize a batch objective over a box with a population method.

    Parameters
    ----------
    fun_batch : callable
        ``fun_batch(X) -> costs``: ``X`` of shape ``(S, D)`` (the whole population), costs of
        shape ``(S,)``; ``+inf`` for invalid candidates. Called once per iteration.
    bounds : sequence of (float, float) or scipy.optimize.Bounds
        Box of the search.
    method : {"css", "pso", "mpso", "de"} or Optimizer subclass
        :class:`CSS` (default), :class:`PSO`, :class:`MPSO`, :class:`DE`.
    population_size : int, optional
        Default ``max(20, 5 D)``.
    max_iterations : int
        Number of populations evaluated (default 200).
    rng : int, numpy.random.Generator or None
        Same seed, same result.
    callback : callable, optional
        ``callback(intermediate_result)`` after each iteration with an
        :class:`IntermediateResult` (``x``, ``fun``, ``nit``, ``nfev``, ``mean_cost``);
        returning ``True`` or raising ``StopIteration`` stops the run with
        ``message="stopped by callback"``, ``success=False``.
    progress : bool
        Show the progress on stderr (:mod:`piezohyst.progress`: a bar on a terminal, plain
        lines in a log, nothing inside :func:`piezohyst.progress.silenced`).
    polish : bool or dict
        Run L-BFGS-B (``scipy.optimize.minimize``, within the bounds) from the best point and
        keep the result if it is better; a dict gives L-BFGS-B options (default
        ``maxiter=200``). Gradients are central differences computed in one ``fun_batch``
        call of ``2 D + 1`` rows; all polish evaluations are counted in ``nfev``.
    tol, atol : float, optional
        Stop when the last population's costs are all finite and
        ``std(f) <= atol + tol * |mean(f)|`` (SciPy's DE test); off by default.
    **options
        Method options (e.g. ``cmcr``, ``par`` for CSS; ``w``, ``c1``, ``c2``, ``vmax`` for
        PSO; ``w_max``, ``w_min``, ``c3`` for MPSO; ``F``, ``CR`` for DE; ``init``).

    Returns
    -------
    OptimizeResult

    Notes
    -----
    ``KeyboardInterrupt`` during the run stops it cleanly: the best point so far is returned
    with ``success=False, message="interrupted"`` (no polish). The polish, when asked for,
    also follows a stop by the callback or by ``tol`` (as in SciPy's DE).

    Results depend only on ``rng`` and on the costs: with the same seed and a deterministic
    ``fun_batch`` (such as :func:`piezohyst.batch_rmse`, whose values do not depend on the
    thread count) two runs give identical histories.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.optimize import minimize
    >>> rosen = lambda X: np.sum(100 * (X[:, 1:] - X[:, :-1] ** 2) ** 2 + (1 - X[:, :-1]) ** 2, axis=1)
    >>> res = minimize(rosen, [(-2, 2)] * 2, method="mpso", rng=3, max_iterations=100, polish=True)
    >>> np.round(res.x, 4).tolist(), res.success
    ([1.0, 1.0], True)
    >>> res.history["best_cost"].shape
    (100,)
    """
    if not callable(fun_batch):
        raise ParameterTypeError(f"fun_batch must be callable, got {type(fun_batch).__name__}")
    if callback is not None and not callable(callback):
        raise ParameterTypeError(f"callback must be callable or None, got {type(callback).__name__}")
    cls = _method_class(method)
    if tol is not None:
        tol = as_scalar(tol, "tol", nonnegative=True)
    atol = as_scalar(atol, "atol", nonnegative=True)
    if not isinstance(polish, (bool, dict)):
        raise ParameterTypeError(f"polish must be a bool or a dict of L-BFGS-B options, got {polish!r}")
    try:
        opt = cls(bounds, population_size, rng, max_iterations, **options)
    except TypeError as e:
        if "unexpected keyword" in str(e):
            raise ParameterTypeError(f"method {cls.name!r}: {e}") from None
        raise
    bar = Progress(opt.max_iterations, opt.name) if progress else None
    t0 = time.perf_counter()
    message, success = "maximum number of iterations reached", True
    try:
        while not opt.done:
            X = opt.ask()
            opt.tell(_evaluate(fun_batch, X))
            if bar is not None:
                bar.update(opt.iteration, best=opt.best_cost)
            if callback is not None:
                try:
                    stop = callback(opt.intermediate_result())
                except StopIteration:
                    stop = True
                if stop is not None and bool(stop):
                    message, success = "stopped by callback", False
                    break
            if tol is not None and opt.converged(tol, atol):
                message = f"converged: population cost spread <= atol + tol*|mean| (tol={tol}, atol={atol})"
                break
    except KeyboardInterrupt:
        message, success = "interrupted", False
    finally:
        if bar is not None:
            bar.update(opt.iteration, best=opt.best_cost)
            bar.close()
    res = opt.result(message=message, success=success)
    x0 = res.x  # not None once a finite cost was found
    if (
        polish is not False
        and polish is not None
        and message != "interrupted"
        and np.isfinite(res.fun)
        and x0 is not None
    ):
        try:
            x, f, n = polish_lbfgsb(
                fun_batch, x0, res.fun, opt._lower, opt._upper, polish if isinstance(polish, Mapping) else {}
            )
        except KeyboardInterrupt:
            x, f, n = x0, res.fun, 0
        note = (
            f"; L-BFGS-B polish improved fun from {res.fun:.6g} to {f:.6g}"
            if f < res.fun
            else "; L-BFGS-B polish did not improve"
        )
        res = replace(res, x=_readonly(x), fun=f, nfev=res.nfev + n, message=res.message + note)
    return replace(res, wall_time=float(time.perf_counter() - t0))
