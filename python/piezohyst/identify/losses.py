"""Further fits of the linear families' parameters: sample-weighted least squares (and
weighted Huber) and the minimax (L-infinity) fit by linear programming
(:func:`scipy.optimize.linprog`, HiGHS)."""

from __future__ import annotations

import time
from typing import Any, cast

import numpy as np
import numpy.typing as npt

from .._validate import as_record
from ..errors import DataError, ParameterError
from ..models.preisach import Preisach
from .core import (
    DriftBasis,
    FitResult,
    FloatArray,
    LinearModel,
    _bvls,
    _condition,
    _design,
    _fit_metrics,
    _fit_preisach,
    _irls_huber,
    _what,
    check_samples,
    parameter_count,
)

__all__ = ["check_weights", "fit_linear_weighted"]


def check_weights(weights: npt.ArrayLike, n: int) -> FloatArray:
    """Sample weights checked: ``n`` finite values ``>= 0``, not all zero.

    Parameters
    ----------
    weights : array_like, shape (n,)
        The sample weights.
    n : int
        Number of samples of the training record.

    Returns
    -------
    ndarray, shape (n,)

    Raises
    ------
    ParameterError
        When the length differs, a weight is negative or all are zero.

    Examples
    --------
    >>> from piezohyst.identify.losses import check_weights
    >>> check_weights([1, 0, 2], 3).tolist()
    [1.0, 0.0, 2.0]
    >>> check_weights([1.0, -0.5], 2)
    Traceback (most recent call last):
    ...
    piezohyst.errors.ParameterError: weights[1] = -0.5 is negative; sample weights must be >= 0
    """
    w = as_record(weights, "weights", min_length=1)
    if w.size != n:
        raise ParameterError(f"weights has {w.size} samples, the training record has {n}; they must match")
    if np.any(w < 0):
        i = int(np.flatnonzero(w < 0)[0])
        raise ParameterError(f"weights[{i}] = {w[i]:g} is negative; sample weights must be >= 0")
    if not np.any(w > 0):
        raise ParameterError("weights are all zero: no sample would be fitted")
    return w


def fit_linear_weighted(
    model: LinearModel,
    v: FloatArray,
    y: FloatArray,
    loss: str,
    delta: float | None,
    weights: FloatArray | None,
    *,
    offset: bool = False,
    drift: DriftBasis | None = None,
    start: int = 0,
) -> FitResult:
    """The linear parameters of ``model`` (its structure kept) fitted to a validated record by
    ``loss`` (``"squared"``, ``"huber"`` or ``"linf"``) with optional sample ``weights``
    (``>= 0``; least squares minimizes ``sum w r^2``, the minimax fit ``max w |r|``), a
    ``drift`` basis fitted with it, the samples before ``start`` left out of the cost. A
    Preisach grid's least squares (and Huber) fit is :func:`piezohyst.identify.core._fit_preisach`'s
    with the sample weights: on its distinct relay patterns, with its smoothness prior.

    Parameters
    ----------
    model : PI, GeneralizedPI, RateDependentPI or Preisach
        The structure to fit (its thresholds, grid...); its parameter values are not used.
    v, y : ndarray, shape (N,)
        Validated input and output records.
    loss : {"squared", "huber", "linf"}
        The cost.
    delta : float or None
        Huber threshold, output units; ``None``: estimated from the residuals.
    weights : ndarray, shape (N,), optional
        Sample weights (:func:`check_weights`); ``None``: all 1.
    offset : bool, default False
        Fit a constant output offset with the parameters.
    drift : DriftBasis, optional
        Drift columns fitted with the parameters.
    start : int, default 0
        Samples before it are simulated but left out of the cost.

    Returns
    -------
    FitResult

    Examples
    --------
    A glitch given weight 0 does not move the fit:

    >>> import numpy as np
    >>> from piezohyst import PI
    >>> from piezohyst.identify.losses import fit_linear_weighted
    >>> truth = PI([0.1, 0.3, 0.6], [0.5, 0.2, 0.1])
    >>> v = np.sin(np.linspace(0, 12, 1200)) * np.linspace(1, 0.3, 1200)
    >>> y = truth.simulate(v)
    >>> y[600] += 5.0
    >>> w = np.ones(1200)
    >>> w[600] = 0.0
    >>> fit = fit_linear_weighted(PI([0.1, 0.3, 0.6], [1.0, 1.0, 1.0]), v, y, "squared", None, w)
    >>> np.round(fit.model.weights, 9).tolist()
    [0.5, 0.2, 0.1]
    >>> fit = fit_linear_weighted(PI([0.1, 0.3, 0.6], [1.0, 1.0, 1.0]), v, truth.simulate(v), "linf", None, None)
    >>> bool(fit.metrics["max_error"] < 1e-9)
    True
    """
    t0 = time.perf_counter()
    w = np.ones(v.size) if weights is None else np.array(weights, dtype=np.float64)
    w[:start] = 0.0
    if isinstance(model, Preisach) and loss != "linf":
        return _fit_preisach(model, v, y, loss, delta, t0, None, w, drift, start)
    A, lb, ub, build = _design(model, v, offset, drift)
    check_samples(v.size, parameter_count(model, A.shape[1]), _what(model), "fewer operators or levels")
    scale = np.maximum(np.sqrt(np.mean(A**2, axis=0)), 1e-300)
    A = A / scale
    bounds = (lb * scale, ub * scale)
    solves = 1
    if loss == "linf":
        z = _minimax(A, y, w, bounds)
    else:
        s = np.sqrt(w)
        z = np.clip(_bvls(A * s[:, None], y * s, bounds), *bounds)
        if loss == "huber":
            z, k = _irls_huber(A * s[:, None], y * s, bounds, z, delta, _bvls)
            solves += k
    fitted = build(z / scale)
    metrics = _fit_metrics(fitted.simulate(v), y)
    return FitResult(fitted, metrics, time.perf_counter() - t0, solves, condition=_condition(A))


def _minimax(A: FloatArray, y: FloatArray, w: FloatArray, bounds: tuple[FloatArray, FloatArray]) -> FloatArray:
    """``argmin_z max_i w_i |A_i z - y_i|`` within ``bounds``: the LP ``min t`` subject to
    ``-t <= w_i (A_i z - y_i) <= t``, solved by HiGHS."""
    from scipy import sparse
    from scipy.optimize import linprog

    keep = w > 0
    Aw = A[keep] * w[keep, None]
    yw = y[keep] * w[keep]
    m, p = Aw.shape
    one = sparse.csr_matrix(np.ones((m, 1)))
    A_ub = sparse.vstack([sparse.hstack([sparse.csr_matrix(Aw), -one]), sparse.hstack([sparse.csr_matrix(-Aw), -one])])
    b_ub = np.concatenate([yw, -yw])
    c = np.zeros(p + 1)
    c[-1] = 1.0
    lo, hi = bounds
    box = [
        (float(a) if np.isfinite(a) else None, float(b) if np.isfinite(b) else None)
        for a, b in zip(lo, hi, strict=True)
    ]
    res = linprog(c, A_ub=cast(Any, A_ub.tocsr()), b_ub=b_ub, bounds=[*box, (0.0, None)], method="highs")
    if res.status != 0 or res.x is None:
        raise DataError(f"the minimax (loss = 'linf') fit failed: {res.message}")
    z: FloatArray = np.asarray(res.x[:p], dtype=np.float64)
    return z
