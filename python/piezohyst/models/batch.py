"""Batch evaluation: many parameter sets of one model family on one input record.

This is the engine identification runs on. Parameter sets are rows of an ``(S, P)`` array in
the family's flat layout (see :func:`piezohyst.models.HysteresisModel.to_row` and the table
in ``crates/core/src/spec.rs``). The work happens in Rust with the GIL released, spread over
parameter sets with rayon; results do not depend on the number of threads.

Examples
--------
>>> import numpy as np
>>> from piezohyst import PI, batch_rmse
>>> model = PI(thresholds=[0.2, 0.5], weights=[0.3, 0.1], p0=1.0)
>>> v = np.sin(np.linspace(0, 4 * np.pi, 200))
>>> rows = np.stack([model.to_row(), model.to_row() * 1.01])
>>> cost = batch_rmse(model, rows, v, model.simulate(v))
>>> float(cost[0])
0.0
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
import numpy.typing as npt

from .. import _core
from .._validate import as_int, as_record
from ..errors import ParameterError, ParameterTypeError
from .model import FloatArray, HysteresisModel

__all__ = ["batch_rmse", "batch_simulate"]


def _family(model_or_family: HysteresisModel | str, dims: Iterable[int] | None) -> tuple[str, list[int]]:
    if isinstance(model_or_family, str):
        if dims is None:
            raise ParameterTypeError("dims is required when the family is given by name")
        if isinstance(dims, (str, bytes)) or not isinstance(dims, Iterable):
            raise ParameterTypeError(f"dims must be a list of integers, got {dims!r}")
        return model_or_family, [as_int(d, f"dims[{i}]") for i, d in enumerate(dims)]
    return model_or_family.family, list(model_or_family.dims)


def _params(params: npt.ArrayLike, width: int) -> FloatArray:
    try:
        p = np.ascontiguousarray(params, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise ParameterTypeError(f"params must be a 2-D (S, P) array of numbers: {e}") from None
    if p.ndim != 2:
        raise ParameterError(f"params must be a 2-D (S, P) array, got shape {p.shape}")
    if p.shape[1] != width:
        raise ParameterError(f"params has {p.shape[1]} columns, expected {width} for this model family")
    return p


def batch_simulate(
    model: HysteresisModel | str,
    params: npt.ArrayLike,
    input: npt.ArrayLike,
    *,
    dims: Iterable[int] | None = None,
) -> FloatArray:
    """Outputs of ``S`` parameter sets driven by one input record.

    The rows are the family's parameter rows: a model's output map
    (:class:`~piezohyst.OutputMap`) is not part of them and is not applied.

    Parameters
    ----------
    model : HysteresisModel or str
        A model whose family and structure the rows follow, or a family name with ``dims``.
    params : array_like, shape (S, P)
        One parameter row per set.
    input : array_like, shape (N,)
        Input record, finite.
    dims : iterable of int, optional
        The family's structure when ``model`` is a family name.

    Returns
    -------
    ndarray, shape (S, N)

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst import PI, batch_simulate
    >>> pi = PI(thresholds=[0.5], weights=[1.0], p0=1.0)
    >>> rows = np.stack([pi.to_row(), 2 * pi.to_row()])     # p0 and the weight doubled (and r)
    >>> batch_simulate(pi, rows, [0.0, 1.0, 2.0]).tolist()
    [[0.0, 1.5, 3.5], [0.0, 2.0, 6.0]]
    >>> batch_simulate("pi", rows[:1], [0.0, 2.0], dims=[1, 0]).tolist()
    [[0.0, 3.5]]
    """
    family, d = _family(model, dims)
    width, _ = _core.family_sizes(family, d)
    v = as_record(input, "input", copy=False, finite=False)
    return _core.batch_simulate(family, d, _params(params, width), v)


def batch_rmse(
    model: HysteresisModel | str,
    params: npt.ArrayLike,
    input: npt.ArrayLike,
    target: npt.ArrayLike,
    *,
    dims: Iterable[int] | None = None,
    invalid_cost: float | None = None,
) -> FloatArray:
    """Root-mean-square error of ``S`` parameter sets against a target output.

    Parameters
    ----------
    model : HysteresisModel or str
        As in :func:`batch_simulate`.
    params : array_like, shape (S, P)
        One parameter row per set.
    input, target : array_like, shape (N,)
        The input record and the output to match.
    dims : iterable of int, optional
        The family's structure when ``model`` is a family name.
    invalid_cost : float, optional
        Cost given to rows that are not valid parameter sets (for optimizers that explore
        outside the feasible region). By default an invalid row raises ``ValueError``.
        A row whose simulation diverges costs ``inf``.

    Returns
    -------
    ndarray, shape (S,)

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst import PI, batch_rmse
    >>> pi = PI(thresholds=[0.5], weights=[1.0], p0=1.0)
    >>> v = np.linspace(0.0, 2.0, 5)
    >>> rows = np.stack([pi.to_row(), pi.to_row() + [0.1, 0, 0]])   # the true row, then p0 + 0.1
    >>> batch_rmse(pi, rows, v, pi.simulate(v)).round(6).tolist()
    [0.0, 0.122474]
    >>> batch_rmse(pi, np.array([[1.0, -0.5, 1.0]]), v, v, invalid_cost=np.inf).tolist()   # r < 0
    [inf]
    """
    family, d = _family(model, dims)
    width, _ = _core.family_sizes(family, d)
    v = as_record(input, "input", copy=False, finite=False)
    t = as_record(target, "target", copy=False, finite=False)
    if t.shape != v.shape:
        raise ParameterError(f"target has length {t.size}, input has length {v.size}; they must match")
    if invalid_cost is not None:
        invalid_cost = float(invalid_cost)
    return _core.batch_rmse(family, d, _params(params, width), v, t, invalid_cost)
