"""Play operators and the Prandtl–Ishlinskii family: PI, generalized PI / MPI, rate-dependent PI.

See docs/spec.md §2.1–§2.3. The classical play is
``z_r(k) = max(v(k) - r, min(v(k) + r, z_r(k-1)))``; the PI output is
``y = p0 v + sum_i w_i z_{r_i}``. The generalized play uses envelopes ``g_l`` (rising) and
``g_r`` (falling); the MPI of seed 2 adds a polynomial of the input.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Self

import numpy as np
import numpy.typing as npt

from .. import _core
from .._validate import as_interval, as_record, as_scalar, as_vector
from ..errors import ParameterError, ParameterTypeError
from .creep import Creep, creep_from, creep_parts
from .model import FloatArray, HysteresisModel, JSONDict, _register

__all__ = [
    "PI",
    "SEED2_TABLE1",
    "Envelope",
    "GeneralizedPI",
    "GeneralizedPlay",
    "ModifiedPI",
    "PlayOperator",
    "RateDependentPI",
    "mpi_seed2",
]


def _pi_vectors(thresholds: npt.ArrayLike, weights: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
    r = as_vector(thresholds, "thresholds")
    w = as_vector(weights, "weights", length=r.size)
    return r, w


def _with_creep(d: JSONDict, creep: Creep | None) -> JSONDict:
    if creep is not None:
        d["creep"] = creep.parameters
    return d


def _scaled(creep: Creep | None, gain: float) -> Creep | None:
    return None if creep is None else Creep(creep.ts, creep.taus, gain * creep.weights)


def _no_output_map(model: HysteresisModel) -> None:
    """The analytic inverses invert the family alone: refuse a model with an output map."""
    m = model.output_map
    if not m.is_identity:
        raise ParameterError(
            f"output_map = (offset={m.offset}, gain={m.gain}) is set: the analytic inverse does not cover it; "
            "use inverse()"
        )


@_register
class PI(HysteresisModel):
    """Prandtl–Ishlinskii model ``y = p0 v + sum_i w_i play_{r_i}[v]``.

    Parameters
    ----------
    thresholds : array_like
        Play thresholds ``0 <= r_1 < r_2 < ...`` (input units).
    weights : array_like
        One weight per threshold.
    p0 : float
        Weight of the linear term.
    creep : Creep, optional
        Creep added to the output.
    units : mapping, optional
        ``{"input": ..., "output": ...}`` unit names, kept in model files.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst import PI
    >>> m = PI(thresholds=[0.5], weights=[1.0], p0=1.0)
    >>> m.simulate([0.0, 1.0, 2.0, 1.0, 0.0]).tolist()
    [0.0, 1.5, 3.5, 2.5, 0.5]
    """

    kind = "pi"
    family = "pi"

    def __init__(
        self,
        thresholds: npt.ArrayLike,
        weights: npt.ArrayLike,
        p0: float = 1.0,
        *,
        creep: Creep | None = None,
        units: Mapping[str, str] | None = None,
    ) -> None:
        self.thresholds, self.weights = _pi_vectors(thresholds, weights)
        self.p0 = as_scalar(p0, "p0")
        self.creep = creep
        m, tail = creep_parts(creep)
        row = np.concatenate([[self.p0], self.thresholds, self.weights, tail])
        super().__init__([self.thresholds.size, m], row, units=units)

    @property
    def parameters(self) -> JSONDict:
        """Named parameters (JSON-ready): thresholds, weights, p0 and creep."""
        d: JSONDict = {"thresholds": self.thresholds.tolist(), "weights": self.weights.tolist(), "p0": self.p0}
        return _with_creep(d, self.creep)

    @classmethod
    def _from_parameters(cls, p: JSONDict, units: Any) -> Self:
        p = dict(p)
        return cls(**{**p, "creep": creep_from(p.get("creep"))}, units=units)

    def _fold_map(self, offset: float, gain: float, input_range: tuple[float, float] | None) -> HysteresisModel | None:
        # the equal GPI: identity envelopes, polynomial offset + p0 v
        return GeneralizedPI(
            self.thresholds,
            gain * self.weights,
            (offset, gain * self.p0, 0.0, 0.0),
            input_range=(-np.inf, np.inf) if input_range is None else input_range,
            creep=_scaled(self.creep, gain),
            units=self.units,
        )

    def loading_curve(self, s: npt.ArrayLike) -> FloatArray:
        """Initial loading curve ``phi(s) = p0 s + sum_i w_i max(s - r_i, 0)``, through the
        model's output map.

        Parameters
        ----------
        s : array_like
            Inputs (from the relaxed state, rising).

        Returns
        -------
        ndarray

        Examples
        --------
        >>> from piezohyst import PI
        >>> PI(thresholds=[0.5], weights=[1.0], p0=1.0).loading_curve([0.0, 1.0, 2.0]).tolist()
        [0.0, 1.5, 3.5]
        """
        x = as_record(np.atleast_1d(s), "s", min_length=0)
        played: FloatArray = np.maximum(x[:, None] - self.thresholds[None, :], 0.0) @ self.weights
        return self.output_map.apply(self.p0 * x + played)

    def analytic_inverse(self) -> PI:
        """The inverse PI model (docs/spec.md §2.1): driving it with ``y_d`` gives ``v``.

        Raises ``ValueError`` if a partial sum ``p0 + w_1 + ... + w_i`` is not positive.
        Creep is not part of the analytic inverse; use :meth:`inverse` then.

        Returns
        -------
        PI

        Examples
        --------
        >>> from piezohyst import PI
        >>> pi = PI(thresholds=[0.5], weights=[1.0], p0=1.0)
        >>> inv = pi.analytic_inverse()
        >>> inv.thresholds.tolist(), inv.weights.tolist(), inv.p0
        ([0.5], [-0.5], 1.0)
        >>> inv.simulate(pi.simulate([0.0, 1.0, 2.0, 1.0])).tolist()
        [0.0, 1.0, 2.0, 1.0]
        """
        if self.creep is not None:
            raise ParameterError("creep is set: the analytic PI inverse does not cover creep; use inverse()")
        _no_output_map(self)
        p0i, ri, wi = _core.pi_analytic_inverse(self.p0, self.thresholds, self.weights)
        return PI(ri, wi, p0i, units={"input": self.units.get("output", ""), "output": self.units.get("input", "")})


class PlayOperator(PI):
    """A single classical play (backlash) operator with threshold ``r``; output ``z_r``.

    Parameters
    ----------
    threshold : float
        ``r >= 0`` (input units).
    units : mapping, optional
        ``{"input": ..., "output": ...}`` unit names, kept in model files.

    Examples
    --------
    >>> from piezohyst import PlayOperator
    >>> PlayOperator(1.0).simulate([0.0, 3.0, 2.5, 0.5]).tolist()
    [0.0, 2.0, 2.0, 1.5]
    """

    kind = "play"

    def __init__(self, threshold: float, *, units: Mapping[str, str] | None = None) -> None:
        super().__init__([as_scalar(threshold, "threshold", nonnegative=True)], [1.0], 0.0, units=units)

    @property
    def threshold(self) -> float:
        """The threshold ``r``."""
        return float(self.thresholds[0])

    @property
    def parameters(self) -> JSONDict:
        """Named parameters (JSON-ready): the threshold."""
        return {"threshold": self.threshold}

    @classmethod
    def _from_parameters(cls, p: JSONDict, units: Any) -> Self:
        return cls(**p, units=units)


_register(PlayOperator)

_ENVELOPE_CODES = {"identity": 0, "polynomial": 1, "tanh": 2}


def _interval_from_json(x: object) -> object:
    """A model file's input_range: ``null`` ends are infinite."""
    if isinstance(x, (list, tuple)) and len(x) == 2:
        return (-np.inf if x[0] is None else x[0], np.inf if x[1] is None else x[1])
    return x  # as_interval names what is wrong with it


@dataclass(frozen=True)
class Envelope:
    """An increasing envelope of the generalized play.

    ``Envelope.identity()``, ``Envelope.polynomial(c0, c1, c2, c3)`` for
    ``c0 + c1 v + c2 v^2 + c3 v^3``, or ``Envelope.tanh(a0, a1, a2, a3)`` for
    ``a0 tanh(a1 v + a2) + a3``. Calling it evaluates ``g(v)``.

    Parameters
    ----------
    kind : {"identity", "polynomial", "tanh"}
        The envelope's form.
    coefficients : sequence of 4 floats
        Its coefficients, in the order above.

    Examples
    --------
    >>> from piezohyst import Envelope
    >>> g = Envelope.polynomial(0.0, 1.0, 0.5)
    >>> g([0.0, 1.0, 2.0]).tolist()
    [0.0, 1.5, 4.0]
    >>> round(float(g.inverse([1.5])[0]), 12)
    1.0
    """

    kind: str = "identity"
    coefficients: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        if self.kind not in _ENVELOPE_CODES:
            raise ParameterError(f"kind = {self.kind!r} is not an envelope; expected one of {list(_ENVELOPE_CODES)}")
        c = as_vector(self.coefficients, "coefficients", length=4)
        object.__setattr__(self, "coefficients", tuple(float(x) for x in c))

    @classmethod
    def identity(cls) -> Self:
        """``g(v) = v`` (the classical play).

        Returns
        -------
        Envelope

        Examples
        --------
        >>> from piezohyst import Envelope
        >>> Envelope.identity()([2.0]).tolist()
        [2.0]
        """
        return cls("identity")

    @classmethod
    def polynomial(cls, c0: float, c1: float, c2: float = 0.0, c3: float = 0.0) -> Self:
        """``g(v) = c0 + c1 v + c2 v^2 + c3 v^3`` (must increase on the model's input range).

        Parameters
        ----------
        c0, c1, c2, c3 : float
            The coefficients.

        Returns
        -------
        Envelope

        Examples
        --------
        >>> from piezohyst import Envelope
        >>> Envelope.polynomial(1.0, 2.0)([0.0, 1.0]).tolist()
        [1.0, 3.0]
        """
        return cls("polynomial", (c0, c1, c2, c3))

    @classmethod
    def tanh(cls, a0: float, a1: float, a2: float = 0.0, a3: float = 0.0) -> Self:
        """``g(v) = a0 tanh(a1 v + a2) + a3``.

        Parameters
        ----------
        a0, a1, a2, a3 : float
            The coefficients.

        Returns
        -------
        Envelope

        Examples
        --------
        >>> from piezohyst import Envelope
        >>> Envelope.tanh(2.0, 1.0)([0.0]).tolist()
        [0.0]
        """
        return cls("tanh", (a0, a1, a2, a3))

    @property
    def code(self) -> int:
        """The envelope kind's code in the core's parameter row (0 identity, 1 polynomial, 2 tanh)."""
        return _ENVELOPE_CODES[self.kind]

    def __call__(self, v: npt.ArrayLike) -> FloatArray:
        return _core.envelope_eval(self.code, list(self.coefficients), as_record(np.atleast_1d(v), "v", min_length=0))

    def inverse(self, y: npt.ArrayLike) -> FloatArray:
        """``g^{-1}(y)``; raises ``ValueError`` outside the envelope's range.

        Parameters
        ----------
        y : array_like
            Envelope values.

        Returns
        -------
        ndarray

        Examples
        --------
        >>> from piezohyst import Envelope
        >>> Envelope.polynomial(0.0, 2.0).inverse([1.0, 4.0]).tolist()
        [0.5, 2.0]
        """
        return _core.envelope_inverse(
            self.code, list(self.coefficients), as_record(np.atleast_1d(y), "y", min_length=0)
        )

    def to_dict(self) -> JSONDict:
        """The envelope as a model file stores it.

        Returns
        -------
        dict

        Examples
        --------
        >>> from piezohyst import Envelope
        >>> Envelope.tanh(1.0, 2.0).to_dict()
        {'kind': 'tanh', 'coefficients': [1.0, 2.0, 0.0, 0.0]}
        """
        return {"kind": self.kind, "coefficients": list(self.coefficients)}

    @classmethod
    def from_any(cls, e: object, name: str) -> Envelope:
        """An ``Envelope`` from an ``Envelope``, a model file's dict, or ``None`` (the identity).

        Parameters
        ----------
        e : Envelope, dict or None
            What the caller or the file gave.
        name : str
            The argument's name, for the error message.

        Returns
        -------
        Envelope

        Examples
        --------
        >>> from piezohyst import Envelope
        >>> Envelope.from_any({"kind": "polynomial", "coefficients": [0, 1, 0, 0]}, "rising")
        Envelope(kind='polynomial', coefficients=(0.0, 1.0, 0.0, 0.0))
        >>> Envelope.from_any(None, "rising").kind
        'identity'
        """
        if isinstance(e, Envelope):
            return e
        if isinstance(e, dict):
            return cls(**e)
        if e is None:
            return cls.identity()
        raise ParameterTypeError(f"{name} must be an Envelope, got {type(e).__name__}")


@_register
class GeneralizedPI(HysteresisModel):
    """Generalized (asymmetric) PI and the seed-2 modified PI (MPI), docs/spec.md §2.2.

    ``z_r(k) = max(g_l(v) - r, min(g_r(v) + r, z_r(k-1)))``,
    ``y = P(v) + sum_i b_i z_{r_i}``, ``P(v) = c0 + c1 v + c2 v^2 + c3 v^3``.

    Parameters
    ----------
    thresholds, weights : array_like
        Thresholds ``0 <= r_1 < ...`` (a zero threshold is allowed and carries a linear
        part through the envelope) and weights ``b_i``.
    polynomial : sequence of 4 floats
        Direct polynomial ``[c0, c1, c2, c3]``; zero for a pure GPI.
    rising, falling : Envelope
        ``g_l`` and ``g_r``; identity by default.
    input_range : (float, float)
        Inputs on which the envelopes must be increasing and must not cross; simulation
        does not restrict the input, the range only scopes these checks.
    creep : Creep, optional
        Creep added to the output.
    units : mapping, optional
        ``{"input": ..., "output": ...}`` unit names, kept in model files.

    Examples
    --------
    >>> from piezohyst.papers import mpi_seed2
    >>> m = mpi_seed2()
    >>> round(float(m.simulate([0.0, 0.5, 1.0])[-1]), 4)
    1.3833
    """

    kind = "gpi"
    family = "gpi"

    def __init__(
        self,
        thresholds: npt.ArrayLike,
        weights: npt.ArrayLike,
        polynomial: npt.ArrayLike = (0.0, 0.0, 0.0, 0.0),
        rising: Envelope | Mapping[str, Any] | None = None,
        falling: Envelope | Mapping[str, Any] | None = None,
        input_range: Sequence[float] = (-np.inf, np.inf),
        *,
        creep: Creep | None = None,
        units: Mapping[str, str] | None = None,
    ) -> None:
        self.thresholds, self.weights = _pi_vectors(thresholds, weights)
        self.polynomial = tuple(float(x) for x in as_vector(polynomial, "polynomial", length=4))
        self.rising = Envelope.from_any(rising, "rising")
        self.falling = Envelope.from_any(falling, "falling")
        lo, hi = as_interval(input_range, "input_range")
        self.input_range = (lo, hi)
        self.creep = creep
        m, tail = creep_parts(creep)
        row = np.concatenate(
            [
                [lo, hi],
                self.polynomial,
                self.rising.coefficients,
                self.falling.coefficients,
                self.thresholds,
                self.weights,
                tail,
            ]
        )
        super().__init__([self.thresholds.size, self.rising.code, self.falling.code, m], row, units=units)

    @property
    def parameters(self) -> JSONDict:
        """Named parameters (JSON-ready): thresholds, weights, polynomial, envelopes, input range, creep."""
        lo, hi = self.input_range
        d: JSONDict = {
            "thresholds": self.thresholds.tolist(),
            "weights": self.weights.tolist(),
            "polynomial": list(self.polynomial),
            "rising": self.rising.to_dict(),
            "falling": self.falling.to_dict(),
            "input_range": [lo if np.isfinite(lo) else None, hi if np.isfinite(hi) else None],
        }
        return _with_creep(d, self.creep)

    @classmethod
    def _from_parameters(cls, p: JSONDict, units: Any) -> Self:
        p = dict(p)
        p["input_range"] = _interval_from_json(p.pop("input_range", [None, None]))
        p["creep"] = creep_from(p.get("creep"))
        return cls(**p, units=units)

    def _fold_map(self, offset: float, gain: float, input_range: tuple[float, float] | None) -> HysteresisModel | None:
        poly = gain * np.asarray(self.polynomial) + np.array([offset, 0.0, 0.0, 0.0])
        return GeneralizedPI(
            self.thresholds,
            gain * self.weights,
            poly,
            self.rising,
            self.falling,
            self.input_range,
            creep=_scaled(self.creep, gain),
            units=self.units,
        )

    def analytic_inverse(self) -> EnvelopeInverse:
        """``v = g^{-1}(PI^{-1}[y])`` for equal envelopes, ``P = 0`` and a zero first
        threshold with positive weight (which plays the role of ``p0``).

        Returns
        -------
        EnvelopeInverse

        Examples
        --------
        >>> from piezohyst import Envelope, GeneralizedPI
        >>> g = Envelope.polynomial(0.0, 1.0, 0.2)
        >>> m = GeneralizedPI([0.0, 0.3], [1.0, 0.5], rising=g, falling=g, input_range=(0.0, 2.0))
        >>> v = [0.0, 1.0, 2.0, 1.0]
        >>> [round(x, 12) for x in m.analytic_inverse().simulate(m.simulate(v)).tolist()]
        [0.0, 1.0, 2.0, 1.0]
        """
        if self.rising != self.falling:
            raise ParameterError("rising and falling envelopes differ: no analytic inverse; use inverse()")
        if any(self.polynomial):
            raise ParameterError(
                f"polynomial = {list(self.polynomial)} is not zero: no analytic inverse; use inverse()"
            )
        if self.creep is not None:
            raise ParameterError("creep is set: no analytic inverse; use inverse()")
        _no_output_map(self)
        if self.thresholds.size == 0 or self.thresholds[0] != 0.0:
            raise ParameterError("thresholds[0] must be 0 (its weight is the linear term) for the analytic inverse")
        pi = PI(self.thresholds[1:], self.weights[1:], self.weights[0])
        return EnvelopeInverse(pi.analytic_inverse(), self.rising)


@_register
class ModifiedPI(GeneralizedPI):
    """A :class:`GeneralizedPI` fitted as the modified PI (MPI) of seed 2: the same model and
    parameters, named ``"mpi"`` in model files and reports (``identify(..., "mpi")``,
    ``piezohyst identify --model mpi``), so a file says which kind was fitted.

    Parameters
    ----------
    thresholds, weights : array_like
        Thresholds and weights, as :class:`GeneralizedPI`.
    polynomial : sequence of 4 floats
        Direct polynomial ``[c0, c1, c2, c3]``.
    rising, falling : Envelope
        ``g_l`` and ``g_r``; identity by default.
    input_range : (float, float)
        Inputs on which the envelopes are checked.
    creep : Creep, optional
        Creep added to the output.
    units : mapping, optional
        ``{"input": ..., "output": ...}`` unit names, kept in model files.

    Examples
    --------
    >>> from piezohyst.models import ModifiedPI
    >>> m = ModifiedPI([0.1, 0.2], [0.3, 0.2], (0.0, 0.5, 0.0, 0.1), input_range=(0.0, 1.0))
    >>> m.kind, round(float(m.simulate([0.0, 1.0])[-1]), 6)
    ('mpi', 1.03)
    """

    kind = "mpi"

    @classmethod
    def from_gpi(cls, model: GeneralizedPI) -> ModifiedPI:
        """The same parameters, units, creep, output map, input delay and drift as ``model``,
        named ``"mpi"``.

        Parameters
        ----------
        model : GeneralizedPI
            The model to rename.

        Returns
        -------
        ModifiedPI

        Examples
        --------
        >>> from piezohyst.models import ModifiedPI
        >>> from piezohyst.papers import mpi_seed2
        >>> m = ModifiedPI.from_gpi(mpi_seed2())
        >>> m.kind, m.simulate([0.0, 0.5]).tolist() == mpi_seed2().simulate([0.0, 0.5]).tolist()
        ('mpi', True)
        """
        return (
            cls(
                model.thresholds,
                model.weights,
                model.polynomial,
                model.rising,
                model.falling,
                model.input_range,
                creep=model.creep,
                units=model.units,
            )
            .with_output_map(model.output_map)
            ._copy_with(model.input_delay, model.drift)
        )


class EnvelopeInverse:
    """Analytic inverse of an equal-envelope GPI: an inverse PI followed by ``g^{-1}``
    (:meth:`GeneralizedPI.analytic_inverse` builds it).

    Parameters
    ----------
    pi_inverse : PI
        The inverse of the classical PI on the envelope's values.
    envelope : Envelope
        The common envelope ``g``.

    Examples
    --------
    >>> from piezohyst import PI, Envelope
    >>> from piezohyst.models import EnvelopeInverse
    >>> inv = EnvelopeInverse(PI([0.5], [1.0], p0=1.0).analytic_inverse(), Envelope.polynomial(0.0, 2.0))
    >>> inv.simulate([0.0, 1.5]).tolist()
    [0.0, 0.5]
    """

    def __init__(self, pi_inverse: PI, envelope: Envelope) -> None:
        self.pi_inverse = pi_inverse
        self.envelope = envelope

    def simulate(self, desired: npt.ArrayLike) -> FloatArray:
        """Inputs for a desired output record, from the relaxed state.

        Parameters
        ----------
        desired : array_like
            The desired outputs.

        Returns
        -------
        ndarray

        Examples
        --------
        >>> from piezohyst import PI, Envelope
        >>> from piezohyst.models import EnvelopeInverse
        >>> EnvelopeInverse(PI([0.5], [1.0], p0=1.0).analytic_inverse(), Envelope.identity()).simulate([3.5]).tolist()
        [2.0]
        """
        return self.envelope.inverse(self.pi_inverse.simulate(desired))


class GeneralizedPlay(GeneralizedPI):
    """A single generalized play operator; output ``z_r``.

    Parameters
    ----------
    threshold : float
        ``r >= 0``.
    rising, falling : Envelope
        ``g_l`` and ``g_r``; identity by default.
    input_range : (float, float)
        Inputs on which the envelopes are checked.
    units : mapping, optional
        ``{"input": ..., "output": ...}`` unit names, kept in model files.

    Examples
    --------
    >>> from piezohyst import Envelope, GeneralizedPlay
    >>> play = GeneralizedPlay(0.5, rising=Envelope.polynomial(0.0, 2.0), falling=Envelope.identity())
    >>> play.simulate([0.0, 1.0, 0.0]).tolist()
    [0.0, 1.5, 0.5]
    """

    kind = "generalized_play"

    def __init__(
        self,
        threshold: float,
        rising: Envelope | Mapping[str, Any] | None = None,
        falling: Envelope | Mapping[str, Any] | None = None,
        input_range: Sequence[float] = (-np.inf, np.inf),
        *,
        units: Mapping[str, str] | None = None,
    ) -> None:
        super().__init__(
            [as_scalar(threshold, "threshold", nonnegative=True)],
            [1.0],
            (0, 0, 0, 0),
            rising,
            falling,
            input_range,
            units=units,
        )

    @property
    def parameters(self) -> JSONDict:
        """Named parameters (JSON-ready): threshold, envelopes, input range."""
        d = super().parameters
        return {
            "threshold": d["thresholds"][0],
            "rising": d["rising"],
            "falling": d["falling"],
            "input_range": d["input_range"],
        }

    @classmethod
    def _from_parameters(cls, p: JSONDict, units: Any) -> Self:
        p = dict(p)
        p["input_range"] = _interval_from_json(p.pop("input_range", [None, None]))
        return cls(**p, units=units)


_register(GeneralizedPlay)

#: Seed 2, Table 1: identified MPI parameters on normalized input/output. The table gives
#: thresholds, weights and the polynomial; it does not list envelope constants, so the
#: reference set uses identity envelopes.
SEED2_TABLE1 = {
    "thresholds": [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9],
    "weights": [0.2054, 0.1985, 0.0237, 0.0148, 0.0456, 0.0645, 0.0051, 0.0014, 0.0033],
    "polynomial": [0.0, 0.2547, -0.00358, 0.7123],
}


def mpi_seed2(
    rising: Envelope | Mapping[str, Any] | None = None, falling: Envelope | Mapping[str, Any] | None = None
) -> GeneralizedPI:
    """The seed-2 Table 1 MPI model (normalized input in [0, 1]) as a reference set.

    ``P(v) = 0.2547 v - 0.00358 v^2 + 0.7123 v^3``; identity envelopes unless given.

    Parameters
    ----------
    rising, falling : Envelope, optional
        Envelopes (the paper does not list them; identity by default).

    Returns
    -------
    GeneralizedPI

    Examples
    --------
    >>> from piezohyst.papers import mpi_seed2
    >>> m = mpi_seed2()
    >>> m.thresholds.tolist()[:3], m.input_range
    ([0.1, 0.2, 0.3], (0.0, 1.0))
    """
    t = SEED2_TABLE1
    return GeneralizedPI(
        t["thresholds"],
        t["weights"],
        t["polynomial"],
        rising,
        falling,
        input_range=(0.0, 1.0),
        units={"input": "normalized", "output": "normalized"},
    )


@_register
class RateDependentPI(HysteresisModel):
    """Rate-dependent PI (docs/spec.md §2.3): dynamic thresholds and rate-dependent weights.

    ``r_i(k) = r_i + beta |dv/dt|``, ``w_i(k) = w_i + c_i |dv/dt|``, with ``|dv/dt|`` the
    backward difference ``|v(k) - v(k-1)| / ts``, low-passed with time constant
    ``filter_tau`` (0: unfiltered). The rate is 0 at the first sample after a reset.

    Parameters
    ----------
    thresholds, weights : array_like
        Static thresholds and weights.
    ts : float
        Sample time, s.
    p0 : float
        Linear weight.
    beta : float
        Threshold growth per unit input rate, s.
    rate_weights : array_like, optional
        ``c_i`` per threshold (default zeros).
    filter_tau : float
        Derivative low-pass time constant, s.
    creep : Creep, optional
        Creep added to the output.
    units : mapping, optional
        ``{"input": ..., "output": ...}`` unit names, kept in model files.

    Examples
    --------
    >>> from piezohyst import RateDependentPI
    >>> m = RateDependentPI([0.5], [1.0], ts=1e-3, p0=1.0, beta=1e-4)
    >>> m.simulate([0.0, 1.0, 2.0, 1.0]).tolist()   # the thresholds grow with the rate (1000 per s)
    [0.0, 1.4, 3.4, 2.4]
    """

    kind = "rdpi"
    family = "rdpi"

    def __init__(
        self,
        thresholds: npt.ArrayLike,
        weights: npt.ArrayLike,
        ts: float,
        p0: float = 1.0,
        beta: float = 0.0,
        rate_weights: npt.ArrayLike | None = None,
        filter_tau: float = 0.0,
        *,
        creep: Creep | None = None,
        units: Mapping[str, str] | None = None,
    ) -> None:
        self.thresholds, self.weights = _pi_vectors(thresholds, weights)
        self.ts = as_scalar(ts, "ts", positive=True)
        self.p0 = as_scalar(p0, "p0")
        self.beta = as_scalar(beta, "beta", nonnegative=True)
        n = self.thresholds.size
        self.rate_weights = np.zeros(n) if rate_weights is None else as_vector(rate_weights, "rate_weights", length=n)
        self.filter_tau = as_scalar(filter_tau, "filter_tau", nonnegative=True)
        self.creep = creep
        m, tail = creep_parts(creep)
        row = np.concatenate(
            [[self.ts, self.p0, self.beta, self.filter_tau], self.thresholds, self.weights, self.rate_weights, tail]
        )
        super().__init__([n, m], row, units=units)

    def _fold_map(self, offset: float, gain: float, input_range: tuple[float, float] | None) -> HysteresisModel | None:
        if offset != 0.0:
            return None  # no constant term
        return RateDependentPI(
            self.thresholds,
            gain * self.weights,
            self.ts,
            gain * self.p0,
            self.beta,
            gain * self.rate_weights,
            self.filter_tau,
            creep=_scaled(self.creep, gain),
            units=self.units,
        )

    @property
    def parameters(self) -> JSONDict:
        """Named parameters (JSON-ready): thresholds, weights, ts, p0, beta, rate weights, filter, creep."""
        d: JSONDict = {
            "thresholds": self.thresholds.tolist(),
            "weights": self.weights.tolist(),
            "ts": self.ts,
            "p0": self.p0,
            "beta": self.beta,
            "rate_weights": self.rate_weights.tolist(),
            "filter_tau": self.filter_tau,
        }
        return _with_creep(d, self.creep)

    @classmethod
    def _from_parameters(cls, p: JSONDict, units: Any) -> Self:
        p = dict(p)
        p["creep"] = creep_from(p.get("creep"))
        return cls(**p, units=units)
