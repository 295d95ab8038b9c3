"""Creep: a bank of first-order lags with time constants spread over decades (docs/spec.md §2.4).

``w_j(k) = w_j(k-1) + (1 - exp(-Ts/tau_j)) (v(k) - w_j(k-1))``, output ``sum_j c_j w_j``.
Use it alone, or pass it as ``creep=`` to any PI-type model (Kuhnen's modified PI).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import numpy.typing as npt

from .._validate import as_scalar, as_vector
from ..errors import ParameterError, ParameterTypeError
from .model import FloatArray, HysteresisModel, JSONDict, _register

__all__ = ["Creep"]


@_register
class Creep(HysteresisModel):
    """Creep operator bank.

    Parameters
    ----------
    ts : float
        Sample time, s.
    taus : array_like
        Lag time constants, s (> 0), typically one per decade.
    weights : array_like
        Output weight of each lag.
    units : mapping, optional
        ``{"input": ..., "output": ...}`` unit names, kept in model files.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst import Creep
    >>> c = Creep(ts=1e-3, taus=[0.1, 1.0, 10.0], weights=[0.01, 0.01, 0.01])
    >>> y = c.simulate(np.ones(10_000))          # step response over 10 s
    >>> bool(y[99] < y[999] < y[-1] < 0.03)      # keeps creeping, bounded by sum(weights)
    True
    """

    kind = "creep"
    family = "creep"

    def __init__(
        self, ts: float, taus: npt.ArrayLike, weights: npt.ArrayLike, *, units: Mapping[str, str] | None = None
    ) -> None:
        self.ts = as_scalar(ts, "ts", positive=True)
        self.taus = as_vector(taus, "taus")
        self.weights = as_vector(weights, "weights", length=self.taus.size)
        bad = np.flatnonzero(~(self.taus > 0))
        if bad.size:
            raise ParameterError(f"taus[{bad[0]}] = {self.taus[bad[0]]} must be > 0")
        super().__init__([self.taus.size], self.tail(), units=units)

    @classmethod
    def log_spaced(cls, ts: float, tau_min: float, tau_max: float, terms: int, weight: float = 0.0) -> Creep:
        """Time constants log-spaced from ``tau_min`` to ``tau_max``, equal weights.

        Parameters
        ----------
        ts : float
            Sample time, s.
        tau_min, tau_max : float
            The shortest and longest time constants, s (> 0).
        terms : int
            Number of lags.
        weight : float
            The weight of each lag.

        Returns
        -------
        Creep

        Examples
        --------
        >>> from piezohyst import Creep
        >>> Creep.log_spaced(1e-3, 0.1, 10.0, 3, weight=0.01).taus.round(12).tolist()
        [0.1, 1.0, 10.0]
        """
        taus = np.geomspace(
            as_scalar(tau_min, "tau_min", positive=True), as_scalar(tau_max, "tau_max", positive=True), int(terms)
        )
        return cls(ts, taus, np.full(taus.size, float(weight)))

    def tail(self) -> FloatArray:
        """The creep part of a flat row: ``[ts, taus..., weights...]``.

        Returns
        -------
        ndarray

        Examples
        --------
        >>> from piezohyst import Creep
        >>> Creep(1e-3, [0.1, 1.0], [0.01, 0.02]).tail().tolist()
        [0.001, 0.1, 1.0, 0.01, 0.02]
        """
        return np.concatenate([[self.ts], self.taus, self.weights])

    @property
    def terms(self) -> int:
        """The number of lags."""
        return self.taus.size

    @property
    def parameters(self) -> JSONDict:
        """Named parameters (JSON-ready): ts, taus, weights."""
        return {"ts": self.ts, "taus": self.taus.tolist(), "weights": self.weights.tolist()}


def creep_parts(creep: object) -> tuple[int, FloatArray]:
    """``(terms, row tail)`` of an optional creep argument."""
    if creep is None:
        return 0, np.zeros(0)
    if not isinstance(creep, Creep):
        raise ParameterTypeError(f"creep must be a piezohyst.Creep or None, got {type(creep).__name__}")
    return creep.terms, creep.tail()


def creep_from(p: JSONDict | None) -> Creep | None:
    return None if p is None else Creep(**p)
