"""Rate-independent differential hysteresis models: Bouc–Wen, generalized Duhem, Dahl (docs/spec.md §2.5).

Each is integrated per sample in the driver's increment along a monotone path; closed forms
remove step-size error (Bouc–Wen n = 1, Duhem with cubic f and g, Dahl for any exponent).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy.typing as npt

from .._validate import as_scalar, as_vector
from ..errors import ParameterError
from .model import HysteresisModel, JSONDict, _register

__all__ = ["BoucWen", "Dahl", "Duhem"]


@_register
class BoucWen(HysteresisModel):
    """Bouc–Wen hysteresis driven by ``w``: ``y = d w - h`` with
    ``dh/dt = a dw/dt - beta |dw/dt| |h|^(n-1) h - gamma dw/dt |h|^n``.

    ``n = 1`` uses the exact integrator of docs/spec.md §2.5; other ``n >= 1`` use RK4 sub-steps in
    the driver increment. ``d = 0`` gives ``-h``.

    Parameters
    ----------
    a : float
        ``A``: the hysteretic variable's initial slope against the driver.
    beta, gamma : float
        Loop-shape parameters (``h`` saturates at ``a / (beta + gamma)`` for ``n = 1``).
    n : float
        Smoothness exponent (>= 1).
    d : float
        Direct gain of the driver in the output.
    units : mapping, optional
        ``{"input": ..., "output": ...}`` unit names, kept in model files.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst import BoucWen
    >>> m = BoucWen(a=1.0, beta=2.0, gamma=0.5, d=1.0)
    >>> y = m.simulate(np.sin(np.linspace(0, 4 * np.pi, 400)))
    >>> bool(abs(m.simulate([0.0, 10.0])[1] - (10 - 1 / 2.5)) < 1e-9)   # h saturates at a/(beta+gamma)
    True
    """

    kind = "boucwen"
    family = "boucwen"

    def __init__(
        self,
        a: float,
        beta: float,
        gamma: float,
        n: float = 1.0,
        d: float = 0.0,
        *,
        units: Mapping[str, str] | None = None,
    ) -> None:
        self.a = as_scalar(a, "a")
        self.beta = as_scalar(beta, "beta")
        self.gamma = as_scalar(gamma, "gamma")
        self.n = as_scalar(n, "n")
        if self.n < 1:
            raise ParameterError(f"n = {self.n} must be >= 1")
        self.d = as_scalar(d, "d")
        super().__init__([], [self.a, self.beta, self.gamma, self.n, self.d], units=units)

    def _fold_map(self, offset: float, gain: float, input_range: tuple[float, float] | None) -> HysteresisModel | None:
        # n = 1: h scales with a for a positive gain (beta, gamma act on |h| / h)
        if offset != 0.0 or not (gain > 0.0 and self.n == 1.0):
            return None
        return BoucWen(gain * self.a, self.beta, self.gamma, self.n, gain * self.d, units=self.units)

    @classmethod
    def from_benchmark(cls, alpha: float, beta: float, gamma: float, delta: float, nu: float = 1.0) -> BoucWen:
        """The Noël–Schoukens benchmark form ``z' = alpha y' - beta (gamma |y'| |z|^(nu-1) z
        + delta y' |z|^nu)``; the returned model outputs ``-z`` (``d = 0``).

        Parameters
        ----------
        alpha, beta, gamma, delta, nu : float
            The benchmark's hysteresis parameters (:class:`BoucWenBenchmark`).

        Returns
        -------
        BoucWen

        Examples
        --------
        >>> from piezohyst import BoucWen
        >>> m = BoucWen.from_benchmark(5e4, 1e3, 0.8, -1.1)
        >>> m.a, m.beta, m.gamma, m.n
        (50000.0, 800.0, -1100.0, 1.0)
        """
        return cls(alpha, beta * gamma, beta * delta, nu, 0.0)

    @property
    def parameters(self) -> JSONDict:
        """Named parameters (JSON-ready): a, beta, gamma, n, d."""
        return {"a": self.a, "beta": self.beta, "gamma": self.gamma, "n": self.n, "d": self.d}


@_register
class Duhem(HysteresisModel):
    """Generalized Duhem (Coleman–Hodgdon): ``dy/dt = alpha |du/dt| (f(u) - y) + g(u) du/dt``
    with cubic ``f`` and ``g`` (coefficients ``[c0, c1, c2, c3]``), integrated exactly.

    Parameters
    ----------
    alpha : float
        Rate of approach to ``f(u)`` per unit input change (>= 0).
    f, g : sequence of 4 floats
        Cubic coefficients ``[c0, c1, c2, c3]`` of ``f`` (the anhysteretic curve) and ``g``
        (the slope on reversal).
    units : mapping, optional
        ``{"input": ..., "output": ...}`` unit names, kept in model files.

    Examples
    --------
    >>> from piezohyst import Duhem
    >>> m = Duhem(alpha=1.0, f=[0.0, 1.0, 0.0, 0.0], g=[0.0, 0.0, 0.0, 0.0])
    >>> [round(y, 6) for y in m.simulate([0.0, 1.0, 2.0]).tolist()]   # y = u - 1 + exp(-u): lags f(u) = u
    [0.0, 0.367879, 1.135335]
    """

    kind = "duhem"
    family = "duhem"

    def __init__(
        self, alpha: float, f: npt.ArrayLike, g: npt.ArrayLike, *, units: Mapping[str, str] | None = None
    ) -> None:
        self.alpha = as_scalar(alpha, "alpha", nonnegative=True)
        self.f = tuple(float(x) for x in as_vector(f, "f", length=4))
        self.g = tuple(float(x) for x in as_vector(g, "g", length=4))
        super().__init__([], [self.alpha, *self.f, *self.g], units=units)

    @property
    def parameters(self) -> JSONDict:
        """Named parameters (JSON-ready): alpha, f, g."""
        return {"alpha": self.alpha, "f": list(self.f), "g": list(self.g)}


@_register
class Dahl(HysteresisModel):
    """Dahl: ``dh/dt = sigma du/dt (1 - (h/h_c) sign(du/dt))^a``; output ``h``.

    ``a = 1`` equals Bouc–Wen with ``n = 1``, ``gamma = 0``.

    Parameters
    ----------
    sigma : float
        Initial slope ``dh/du`` (> 0).
    h_c : float
        The level ``h`` saturates at (> 0).
    a : float
        Shape exponent (> 0).
    units : mapping, optional
        ``{"input": ..., "output": ...}`` unit names, kept in model files.

    Examples
    --------
    >>> from piezohyst import Dahl
    >>> m = Dahl(sigma=2.0, h_c=1.0)
    >>> round(float(m.simulate([0.0, 5.0])[-1]), 6)   # saturates towards h_c
    0.999955
    """

    kind = "dahl"
    family = "dahl"

    def __init__(self, sigma: float, h_c: float, a: float = 1.0, *, units: Mapping[str, str] | None = None) -> None:
        self.sigma = as_scalar(sigma, "sigma", positive=True)
        self.h_c = as_scalar(h_c, "h_c", positive=True)
        self.a = as_scalar(a, "a", positive=True)
        super().__init__([], [self.sigma, self.h_c, self.a], units=units)

    @property
    def parameters(self) -> JSONDict:
        """Named parameters (JSON-ready): sigma, h_c, a."""
        return {"sigma": self.sigma, "h_c": self.h_c, "a": self.a}
