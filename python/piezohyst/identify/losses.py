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
    """Sample weights checked: ``n`` finite values ``>= 0``, not all zero."""
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
    with the sample weights: on its distinct relay patterns, with its smoothness prior."""
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
