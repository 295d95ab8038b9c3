"""Discretized Preisach model (docs/spec.md §2.7).

The half-plane ``lo <= beta <= alpha <= hi`` is cut into an ``L x L`` triangular grid of
cells; cell ``(i, j)`` (alpha row ``i``, beta column ``j <= i``) holds the total weight of
its relays, spread uniformly. Output ``y = offset + slope v + mass of the relays that are
up``, computed exactly from the memory of dominant input extrema, so it is continuous in
``v`` and the per-sample inverse is exact. It starts from negative saturation.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, Self

import numpy as np
import numpy.typing as npt

from .._validate import as_int, as_interval, as_scalar, as_vector
from ..errors import ParameterError, ParameterTypeError
from .creep import Creep, creep_from, creep_parts
from .model import FloatArray, HysteresisModel, JSONDict, _register

__all__ = ["Preisach"]


@_register
class Preisach(HysteresisModel):
    """Discretized Preisach model.

    Parameters
    ----------
    levels : int
        Grid levels ``L`` per axis (``L (L + 1) / 2`` cells).
    input_range : (float, float)
        ``(lo, hi)`` edges of the grid; inputs beyond saturate every relay.
    weights : array_like
        Cell weights ``>= 0``: a flat vector in row order (cell ``(i, j)`` at
        ``i (i + 1) / 2 + j``) or an ``(L, L)`` array whose lower triangle is used.
    offset, slope : float
        Output ``offset + slope v + ...``; ``slope > 0`` makes the model strictly increasing.
    memory : int
        Dominant extrema remembered (2..256). Beyond, the adjacent pair of extrema closest in
        value (the smallest nested minor loop) is forgotten.
    creep : Creep, optional
        A creep bank added to the output (``y = ... + creep[v]``), as in the PI family
        (Kuhnen's modified PI): the slow response to the input's level that a
        rate-independent grid cannot hold. Its weights are linear parameters like the cells'.
    units : mapping, optional
        ``{"input": ..., "output": ...}`` unit names, kept in model files.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst import Preisach
    >>> m = Preisach(4, (0.0, 1.0), np.ones(10), slope=1.0)
    >>> y = m.simulate([0.0, 1.0, 0.0])
    >>> y.tolist()                       # all relays up at 1, all down again at 0
    [0.0, 11.0, 0.0]
    """

    kind = "preisach"
    family = "preisach"

    def __init__(
        self,
        levels: int,
        input_range: Sequence[float],
        weights: npt.ArrayLike,
        offset: float = 0.0,
        slope: float = 0.0,
        memory: int = 64,
        *,
        creep: Creep | None = None,
        units: Mapping[str, str] | None = None,
    ) -> None:
        self.levels = as_int(levels, "levels", minimum=1)
        lo, hi = as_interval(input_range, "input_range")
        if not (np.isfinite(lo) and np.isfinite(hi)):
            raise ParameterError(f"input_range = ({lo}, {hi}) must be finite")
        self.input_range = (lo, hi)
        cells = self.levels * (self.levels + 1) // 2
        try:
            raw = np.asarray(weights) if not isinstance(weights, (str, bytes)) else None
            w = np.asarray(weights, dtype=np.float64) if raw is not None and raw.dtype.kind not in "cb" else weights
        except (TypeError, ValueError) as e:
            raise ParameterTypeError(f"weights must be numbers (a vector or a triangular matrix): {e}") from None
        if raw is not None and raw.dtype.kind in "cb":  # no imaginary part dropped, no bool taken for 0/1
            raise ParameterTypeError(f"weights must be real numbers, got dtype {raw.dtype}")
        if isinstance(w, np.ndarray) and w.ndim == 2:
            if w.shape != (self.levels, self.levels):
                raise ParameterError(
                    f"weights has shape {w.shape}, expected ({self.levels}, {self.levels}) or ({cells},)"
                )
            w = w[np.tril_indices(self.levels)]
        self.weights = as_vector(w, "weights", length=cells)
        self.offset = as_scalar(offset, "offset")
        self.slope = as_scalar(slope, "slope", nonnegative=True)
        self.memory = as_int(memory, "memory", minimum=2)
        self.creep = creep
        m, tail = creep_parts(creep)
        row = np.concatenate([[lo, hi, self.offset, self.slope], self.weights, tail])
        super().__init__([self.levels, self.memory, m], row, units=units)

    @classmethod
    def _from_parameters(cls, p: JSONDict, units: Any) -> Self:
        return cls(**{**p, "creep": creep_from(p.get("creep"))}, units=units)

    def _fold_map(self, offset: float, gain: float, input_range: tuple[float, float] | None) -> HysteresisModel | None:
        return Preisach(
            self.levels,
            self.input_range,
            gain * self.weights,
            gain * self.offset + offset,
            gain * self.slope,
            self.memory,
            creep=None if self.creep is None else Creep(self.creep.ts, self.creep.taus, gain * self.creep.weights),
            units=self.units,
        )

    def extrapolated(self, cells: int) -> Preisach:
        """An equal model on ``input_range`` whose outermost cells continue beyond it.

        Beyond its grid a Preisach model has every relay saturated: its output continues with
        ``slope`` alone, a kink to a flatter line where the loop is steepest (a record's
        validation span whose input leaves the training range by a few percent missed by
        1.4 % of the range there). The copy's grid is ``cells`` cells (of the same width)
        wider at each end, so the output continues with the fitted outer slope for ``cells``
        cells, then with ``slope``:

        - above ``hi``, each new row is the old top row shifted along the diagonals (each
          relay keeps its loop width ``alpha - beta``, as the fit's smoothness prior and a PI
          model do): rising beyond ``hi`` goes on at the top row's rate, and falling back
          switches the relays off at their ``beta``, as a wider loop would (a 5 kHz lookalike
          record, 2.6 % of its validation inputs beyond the training range: 0.37 % of the
          range, 0.45 % with narrow relays there, 0.50 % with none);
        - below ``lo``, each new diagonal cell (narrow relays, both thresholds below ``lo``)
          weighs the old first column: falling beyond ``lo`` goes on at the falling branch's
          rate at ``lo``. (A copy of the column, its ``alpha`` inside the range, would
          switch up during the first rise of any record started at rest and change the model
          inside the range.)

        Inside the old range it is the same model: the new cells below ``lo`` are up from the
        first sample on (their mass taken off ``offset``), those above ``hi`` down until the
        input passes ``hi``. The output map, input delay, drift and units are kept.

        Parameters
        ----------
        cells : int
            Cells added at each end (``>= 0``; 0: ``self``).

        Returns
        -------
        Preisach
            ``levels + 2 cells`` levels over ``input_range`` widened by ``cells`` cells.

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst import Preisach
        >>> m = Preisach(4, (0.0, 1.0), np.ones(10), slope=1.0)
        >>> e = m.extrapolated(2)
        >>> e.levels, e.input_range
        (8, (-0.5, 1.5))
        >>> v = [0.2, 0.9, 0.4, 0.7]
        >>> bool(np.allclose(e.simulate(v), m.simulate(v)))
        True
        >>> m.simulate([0.75, 1.0, 1.25]).tolist()  # beyond 1: the slope alone
        [6.75, 11.0, 11.25]
        >>> e.simulate([0.75, 1.0, 1.25]).tolist()  # the top row's 4 per cell goes on
        [6.75, 11.0, 15.25]
        >>> v = [0.75, 1.0, 1.25, 0.6]  # back from beyond: the wider loop's relays fall too
        >>> round(float(e.simulate(v)[-1]), 2), round(float(m.simulate(v)[-1]), 2)
        (10.04, 8.64)
        """
        k = as_int(cells, "cells", minimum=0)
        if k == 0:
            return self
        n = self.levels
        lo, hi = self.input_range
        step = (hi - lo) / n
        w = self.weight_matrix()
        bottom = float(w[:, 0].sum())
        big = np.zeros((n + 2 * k, n + 2 * k))
        big[k : k + n, k : k + n] = w
        idx = np.arange(k)
        big[idx, idx] = bottom
        for i in range(k):
            big[k + n + i, k + i + 1 : k + n + i + 1] = w[-1]
        new = Preisach(
            n + 2 * k,
            (lo - k * step, hi + k * step),
            big,
            self.offset - k * bottom,
            self.slope,
            self.memory,
            creep=self.creep,
            units=self.units,
        )
        return new.with_output_map(self.output_map).with_input_delay(self.input_delay).with_drift(self.drift)

    def weight_matrix(self) -> FloatArray:
        """Weights as an ``(L, L)`` lower-triangular array (alpha rows, beta columns).

        Returns
        -------
        ndarray, shape (L, L)

        Examples
        --------
        >>> from piezohyst import Preisach
        >>> Preisach(2, (0.0, 1.0), [1.0, 2.0, 3.0]).weight_matrix().tolist()
        [[1.0, 0.0], [2.0, 3.0]]
        """
        m = np.zeros((self.levels, self.levels))
        m[np.tril_indices(self.levels)] = self.weights
        return m

    @property
    def parameters(self) -> JSONDict:
        """Named parameters (JSON-ready): levels, input range, weights, offset, slope, memory
        and creep (when set)."""
        d: JSONDict = {
            "levels": self.levels,
            "input_range": list(self.input_range),
            "weights": self.weights.tolist(),
            "offset": self.offset,
            "slope": self.slope,
            "memory": self.memory,
        }
        if self.creep is not None:
            d["creep"] = self.creep.parameters
        return d
