"""The common interface of every hysteresis model: simulate, step, state, inverse, files.

A model is a parameter set (immutable once built) plus an internal state used by
:meth:`HysteresisModel.step`. :meth:`HysteresisModel.simulate` never touches the internal
state: it runs a whole record from a given (default: relaxed) initial state. All loops over
samples run in the Rust core.

Around the family's core sits the measurement chain of the record the model was identified
on, each part a property of the model (identity by default) and of its file::

    y[k] = gain * h(v[k - input_delay]) + offset + drift(k)

- ``input_delay`` (:meth:`HysteresisModel.with_input_delay`): the input reaches the core
  ``input_delay`` samples late (a sensor's filter, a DAQ's latency); before a simulation's
  first sample the input is taken as held at its first value;
- the output map ``gain``, ``offset`` (:class:`OutputMap`): a sensor's gain and zero;
- ``drift`` (:class:`Drift`): a slow trend of the record (a sensor settling), a function of
  ``k``, the samples since the simulation's first sample (the training span's start, for an
  identified model).

The delay line and ``k`` are part of the model's state (after the core's slots), so a run
continued from a final state is the same run.
"""

from __future__ import annotations

import copy
import json
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Self, TypeVar

import numpy as np
import numpy.typing as npt

from .. import _core
from .._io import PathLike, check_parameter_tree, json_text, load_json_file, malformed_as, printable, write_atomic
from .._validate import as_int, as_record, as_scalar, as_vector
from ..errors import ParameterError, ParameterTypeError
from ..signals.matfile import load_mat_file, write_mat
from ..signals.response import Response
from .boucwen_benchmark import BoucWenBenchmark

__all__ = [
    "IDENTITY_MAP",
    "SCHEMA_VERSION",
    "AnyModel",
    "Drift",
    "HysteresisModel",
    "Inverse",
    "OutputMap",
    "load_model",
    "model_from_dict",
]

FloatArray = npt.NDArray[np.float64]
#: A JSON object: a model description as written to or parsed from a model file.
JSONDict = dict[str, Any]

#: Version of the model-file layout written by :meth:`HysteresisModel.save`.
SCHEMA_VERSION = 1

#: Largest input delay a model holds, in samples.
MAX_INPUT_DELAY = 100_000

_REGISTRY: dict[str, type[HysteresisModel]] = {}

_ModelType = TypeVar("_ModelType", bound="type[HysteresisModel]")


@dataclass(frozen=True)
class OutputMap:
    """The output map of every model: ``y = gain * h(v) + offset``, ``h`` the family's output.

    It models what sits between the actuator and the recorded output: a sensor offset (the
    zero of a displacement probe or an oscilloscope channel) and a gain (a calibration
    error, a unit factor). The family's parameter row, hence the core and the C ABI, is
    untouched: the map is applied to the core's output (and removed from a desired output
    before the core inverts it). The identity (``offset = 0``, ``gain = 1``) is the default;
    a model file stores the map only when it is not the identity.

    Parameters
    ----------
    offset : float
        Added to the output, in the output's unit.
    gain : float
        Multiplies the family's output: finite and non-zero.

    Examples
    --------
    >>> from piezohyst import PI
    >>> m = PI([0.5], [1.0], p0=1.0).with_output_map(offset=10.0, gain=2.0)
    >>> m.simulate([0.0, 1.0, 2.0]).tolist()
    [10.0, 13.0, 17.0]
    >>> m.inverse().simulate([10.0, 13.0, 17.0]).tolist()
    [0.0, 1.0, 2.0]
    """

    offset: float = 0.0
    gain: float = 1.0

    def __post_init__(self) -> None:
        offset = as_scalar(self.offset, "output_map.offset")
        gain = as_scalar(self.gain, "output_map.gain")
        if gain == 0.0:
            raise ParameterError("output_map.gain = 0.0 must be non-zero (the model would have no output)")
        object.__setattr__(self, "offset", offset)
        object.__setattr__(self, "gain", gain)

    @property
    def is_identity(self) -> bool:
        """``True`` for ``offset = 0``, ``gain = 1`` (the map changes nothing)."""
        return self.offset == 0.0 and self.gain == 1.0

    def apply(self, h: FloatArray) -> FloatArray:
        """``gain * h + offset`` (``h`` itself, not a copy, for the identity).

        Parameters
        ----------
        h : ndarray
            The family's output.

        Returns
        -------
        ndarray

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst.models import OutputMap
        >>> OutputMap(offset=1.0, gain=2.0).apply(np.array([0.0, 1.0])).tolist()
        [1.0, 3.0]
        """
        if self.is_identity:
            return h
        out: FloatArray = self.gain * h + self.offset
        return out

    def invert(self, y: FloatArray) -> FloatArray:
        """``(y - offset) / gain``: the family's output that gives ``y``.

        Parameters
        ----------
        y : ndarray
            Outputs after the map.

        Returns
        -------
        ndarray

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst.models import OutputMap
        >>> OutputMap(offset=1.0, gain=2.0).invert(np.array([1.0, 3.0])).tolist()
        [0.0, 1.0]
        """
        if self.is_identity:
            return y
        out: FloatArray = (y - self.offset) / self.gain
        return out

    def to_dict(self) -> JSONDict:
        """The map as a model file stores it.

        Returns
        -------
        dict
            ``{"offset": ..., "gain": ...}``.

        Examples
        --------
        >>> from piezohyst.models import OutputMap
        >>> OutputMap(offset=-96e-6).to_dict()
        {'offset': -9.6e-05, 'gain': 1.0}
        """
        return {"offset": self.offset, "gain": self.gain}

    @classmethod
    def from_any(cls, m: object) -> OutputMap:
        """An ``OutputMap`` from what a caller or a model file gives.

        Parameters
        ----------
        m : OutputMap, dict or None
            An ``OutputMap``; a model file's ``{"offset": ..., "gain": ...}`` (absent keys:
            the identity's values); or ``None`` (the identity).

        Returns
        -------
        OutputMap

        Examples
        --------
        >>> from piezohyst.models import OutputMap
        >>> OutputMap.from_any({"offset": 2.0})
        OutputMap(offset=2.0, gain=1.0)
        >>> OutputMap.from_any(None).is_identity
        True
        """
        if m is None:
            return IDENTITY_MAP
        if isinstance(m, OutputMap):
            return m
        if isinstance(m, dict):
            unknown = sorted(set(m) - {"offset", "gain"})
            if unknown:
                raise ParameterError(f"output_map has unknown keys {unknown}; expected 'offset' and 'gain'")
            return cls(m.get("offset", 0.0), m.get("gain", 1.0))
        raise ParameterTypeError(f"output_map must be an OutputMap or {{'offset': ..., 'gain': ...}}, got {m!r}")


#: The map that changes nothing: every model's default.
IDENTITY_MAP = OutputMap()


@dataclass(frozen=True)
class Drift:
    """A slow trend added to a model's output: ``drift(k) = slope k + sum_j weights_j
    (1 - exp(-k / taus_j))``, ``k`` the samples since the simulation's first sample.

    It models what a record's sensor adds over time whatever the input (a capacitive or
    optical sensor warming up, a DAQ's zero drifting): a linear trend and exponential settling
    terms. It is a property of the *record*, counted from the start of the simulation: an
    identified model's drift is counted from its training span's first sample, and predicts
    the trend only for runs that start there (``piezohyst identify`` reports it; the inverse
    and the exported C model leave it out, see :class:`Inverse`).

    Parameters
    ----------
    taus : sequence of float
        Settling time constants in samples (> 0, finite).
    weights : sequence of float
        The settled change of each term, output units (one per tau).
    slope : float
        Output units per sample.

    Examples
    --------
    >>> import numpy as np
    >>> d = Drift(taus=(100.0,), weights=(2.0,), slope=0.01)
    >>> d.evaluate(np.array([0.0, 100.0])).round(4).tolist()
    [0.0, 2.2642]
    """

    taus: tuple[float, ...] = ()
    weights: tuple[float, ...] = ()
    slope: float = 0.0

    def __post_init__(self) -> None:
        taus = as_vector(self.taus, "drift.taus")
        weights = as_vector(self.weights, "drift.weights", length=taus.size)
        bad = np.flatnonzero(~(taus > 0))
        if bad.size:
            raise ParameterError(f"drift.taus[{bad[0]}] = {taus[bad[0]]} must be > 0 (samples)")
        object.__setattr__(self, "taus", tuple(float(x) for x in taus))
        object.__setattr__(self, "weights", tuple(float(x) for x in weights))
        object.__setattr__(self, "slope", as_scalar(self.slope, "drift.slope"))

    def evaluate(self, k: FloatArray) -> FloatArray:
        """The drift at samples ``k`` (since the simulation's first sample).

        Parameters
        ----------
        k : ndarray of float
            Sample indices counted from the simulation's first sample.

        Returns
        -------
        ndarray of float
            The drift, output units, one value per ``k``.

        Examples
        --------
        >>> import numpy as np
        >>> Drift(slope=0.5).evaluate(np.array([0.0, 2.0, 4.0])).tolist()
        [0.0, 1.0, 2.0]
        >>> float(Drift(taus=(10.0,), weights=(3.0,)).evaluate(np.array([1e6]))[0])
        3.0
        """
        out: FloatArray = self.slope * k
        for tau, w in zip(self.taus, self.weights, strict=True):
            out = out - w * np.expm1(-k / tau)
        return out

    def to_dict(self) -> JSONDict:
        """JSON-ready description, the model file's ``drift`` (:meth:`from_any` reads it).

        Returns
        -------
        dict
            ``{"slope": ..., "taus": [...], "weights": [...]}``.

        Examples
        --------
        >>> d = Drift(taus=(100.0,), weights=(2.0,), slope=0.01)
        >>> d.to_dict()
        {'slope': 0.01, 'taus': [100.0], 'weights': [2.0]}
        >>> Drift.from_any(d.to_dict()) == d
        True
        """
        return {"slope": self.slope, "taus": list(self.taus), "weights": list(self.weights)}

    @classmethod
    def from_any(cls, d: object) -> Drift | None:
        """A ``Drift`` from what a caller or a model file gives.

        Parameters
        ----------
        d : Drift, dict or None
            A ``Drift`` (returned as is); a model file's ``{"slope", "taus", "weights"}``
            (absent keys: none); or ``None`` (no drift).

        Returns
        -------
        Drift or None

        Examples
        --------
        >>> from piezohyst.models.model import Drift
        >>> Drift.from_any({"slope": 0.1, "taus": [2.0], "weights": [0.5]})
        Drift(taus=(2.0,), weights=(0.5,), slope=0.1)
        >>> Drift.from_any(None) is None
        True
        >>> Drift.from_any({"offset": 1.0})
        Traceback (most recent call last):
        ...
        piezohyst.errors.ParameterError: drift has unknown keys ['offset']; expected 'slope', 'taus' and 'weights'
        """
        if d is None or isinstance(d, Drift):
            return d
        if isinstance(d, dict):
            unknown = sorted(set(d) - {"slope", "taus", "weights"})
            if unknown:
                raise ParameterError(f"drift has unknown keys {unknown}; expected 'slope', 'taus' and 'weights'")
            return cls(tuple(d.get("taus", ())), tuple(d.get("weights", ())), d.get("slope", 0.0))
        raise ParameterTypeError(f"drift must be a Drift or {{'slope': ..., 'taus': ..., 'weights': ...}}, got {d!r}")


def _register(cls: _ModelType) -> _ModelType:
    _REGISTRY[cls.kind] = cls
    return cls


class HysteresisModel:
    """Base class: a model family, its structure (``dims``) and one flat parameter row.

    Subclasses set ``kind`` (the name in model files), ``family`` (the core's name) and
    build ``dims`` and the row from their parameters; users build the subclasses
    (:class:`PI`, :class:`GeneralizedPI`, :class:`Preisach`, ...), not this class.

    Parameters
    ----------
    dims : iterable of int
        The family's structural sizes (the core's layout table).
    row : array_like
        The flat parameter row in the family's layout.
    units : mapping, optional
        ``{"input": ..., "output": ...}`` unit names, kept in model files.

    Examples
    --------
    >>> from piezohyst.models import PI, HysteresisModel
    >>> m = PI(thresholds=[0.5], weights=[1.0], p0=1.0)
    >>> isinstance(m, HysteresisModel), m.kind, m.dims
    (True, 'pi', (1, 0))
    """

    kind: str = ""
    family: str = ""

    def __init__(self, dims: Iterable[int], row: npt.ArrayLike, *, units: Mapping[str, str] | None = None) -> None:
        self.dims = tuple(int(d) for d in dims)
        self._row = np.ascontiguousarray(row, dtype=np.float64)
        # built and validated once; every simulation and inverse below runs on it
        self._compiled = _core.Model(self.family, list(self.dims), self._row)
        self._row.setflags(write=False)
        self.units = _units(units)
        self._map = IDENTITY_MAP
        self._delay = 0
        self._drift: Drift | None = None
        self._state = self.initial_state()

    # The compiled core model is not picklable: pickles carry the row, and it is rebuilt
    # (and validated again) on load.
    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        del state["_compiled"]
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        # a pickle's buffers may land unaligned (Dask's messages); the core reads aligned rows
        self._row = np.require(self._row, np.float64, ["C", "A"])
        self._row.setflags(write=False)
        self._state = np.require(self._state, np.float64, ["C", "A"])
        self._compiled = _core.Model(self.family, list(self.dims), self._row)

    # -- parameters -----------------------------------------------------------------
    def to_row(self) -> FloatArray:
        """The flat parameter row (a copy) in the core's layout for this family.

        Returns
        -------
        ndarray

        Examples
        --------
        >>> from piezohyst import PI
        >>> PI(thresholds=[0.1, 0.3], weights=[0.4, 0.2], p0=1.0).to_row().tolist()
        [1.0, 0.1, 0.3, 0.4, 0.2]
        """
        return self._row.copy()

    @property
    def parameters(self) -> JSONDict:
        """Named parameters (JSON-ready)."""
        raise NotImplementedError

    # -- output map -------------------------------------------------------------------
    @property
    def output_map(self) -> OutputMap:
        """The output map ``y = gain * h(v) + offset`` (:class:`OutputMap`; identity by default)."""
        return self._map

    def with_output_map(self, output_map: OutputMap | Mapping[str, float] | None = None, /, **kw: float) -> Self:
        """A copy of this model with the given output map. The parameter row is shared: the
        map is not part of it. The copy starts relaxed.

        Parameters
        ----------
        output_map : OutputMap, mapping or None, optional
            The map (``None``: the identity); or give the keywords instead.
        **kw : float
            ``offset=``, ``gain=``.

        Returns
        -------
        HysteresisModel
            A model of the same class.

        Examples
        --------
        >>> from piezohyst import PI
        >>> m = PI([0.5], [1.0], p0=1.0).with_output_map(offset=5.0)
        >>> m.simulate([0.0, 1.0]).tolist(), m.output_map.offset
        ([5.0, 6.5], 5.0)
        """
        if output_map is not None and kw:
            raise ParameterTypeError("give output_map or offset=/gain= keywords, not both")
        m = OutputMap.from_any(
            dict(kw) if kw else (dict(output_map) if isinstance(output_map, Mapping) else output_map)
        )
        new = copy.copy(self)
        new._map = m
        new.units = dict(self.units)
        new._state = self.initial_state()
        return new

    def mapped_row(self, input_range: tuple[float, float] | None = None) -> HysteresisModel:
        """An equal model (same outputs, same inverse) whose parameter row holds the output
        map, with the identity map: for consumers of the bare row (the compensated controllers
        of the core, the exported C controller). ``self`` when the map is the identity.

        The gain scales the parameters the output is linear in; the offset goes to the
        family's constant term (GPI polynomial ``c0``, Preisach ``offset``; a PI becomes the
        equal GPI with identity envelopes). ``ParameterError`` when the family cannot hold
        the map (an offset on RDPI or Bouc–Wen; a negative gain on non-negative weights).
        ``input_range``: the inputs the row will see (e.g. the amplifier's limits), the input
        range of the GPI a PI becomes (default: unbounded). The input delay and the drift are
        kept (they are not in the row: the core's compensated controllers, which invert the
        row, leave them out, as :class:`Inverse` does).


        Parameters
        ----------
        input_range : (float, float), optional
            The inputs the row will see.

        Returns
        -------
        HysteresisModel

        Examples
        --------
        >>> from piezohyst import PI
        >>> m = PI([0.5], [1.0], p0=1.0).with_output_map(offset=2.0)
        >>> bare = m.mapped_row()
        >>> bare.kind, bare.output_map.is_identity
        ('gpi', True)
        >>> bare.simulate([0.0, 1.0]).tolist() == m.simulate([0.0, 1.0]).tolist()
        True
        """
        if self._map.is_identity:
            return self
        why = ""
        try:
            folded = self._fold_map(self._map.offset, self._map.gain, input_range)
        except ParameterError as e:
            folded, why = None, f" ({e})"
        if folded is None:
            raise ParameterError(
                f"output_map = (offset={self._map.offset}, gain={self._map.gain}) cannot be held in the "
                f"parameter row of a {self.kind} model{why}; the core's compensated controllers invert the "
                "family's row: use a pi, gpi/mpi or preisach model, or one fitted with offset=False (--no-offset)"
            )
        return folded._copy_with(self._delay, self._drift)

    def _fold_map(self, offset: float, gain: float, input_range: tuple[float, float] | None) -> HysteresisModel | None:
        """The model with the map folded into its row, or ``None`` if the family cannot hold it."""
        return None

    # -- input delay and drift ----------------------------------------------------------
    @property
    def input_delay(self) -> int:
        """Samples by which the input reaches the family's core late (0 by default)."""
        return self._delay

    @property
    def drift(self) -> Drift | None:
        """The record's drift added to the output (:class:`Drift`), or ``None``."""
        return self._drift

    def with_input_delay(self, samples: int) -> Self:
        """A copy of this model whose input reaches the core ``samples`` samples late
        (``y[k] = gain * h(v[k - samples]) + offset``; before a simulation's first sample the
        input is held at its first value). The delay line is part of the state (after the
        core's slots, oldest first, then the samples since the start); the copy starts relaxed.

        Parameters
        ----------
        samples : int
            The delay in samples (``>= 0``; 0 removes it).

        Returns
        -------
        HysteresisModel
            A copy of the model with the delay.

        Examples
        --------
        >>> from piezohyst import PI
        >>> m = PI([0.5], [1.0], p0=1.0).with_input_delay(2)
        >>> m.simulate([1.0, 2.0, 3.0, 3.0]).tolist()
        [1.5, 1.5, 1.5, 3.5]
        """
        d = as_int(samples, "input_delay", minimum=0)
        if d > MAX_INPUT_DELAY:
            raise ParameterError(f"input_delay = {d} must be <= {MAX_INPUT_DELAY} samples")
        return self._copy_with(d, self._drift)

    def with_drift(self, drift: Drift | Mapping[str, Any] | None) -> Self:
        """A copy of this model with the given drift term (a :class:`Drift`, a model file's
        mapping, or ``None`` for none); the copy starts relaxed.

        Parameters
        ----------
        drift : Drift, mapping or None
            The trend added to the output, counted in samples from the start of a simulation.

        Returns
        -------
        HysteresisModel
            A copy of the model with the drift.

        Examples
        --------
        >>> from piezohyst import PI
        >>> from piezohyst.models.model import Drift
        >>> m = PI([0.5], [1.0], p0=1.0).with_drift(Drift(slope=0.5))
        >>> m.simulate([0.0, 0.0, 0.0]).tolist()
        [0.0, 0.5, 1.0]
        """
        return self._copy_with(self._delay, Drift.from_any(dict(drift) if isinstance(drift, Mapping) else drift))

    def _copy_with(self, delay: int, drift: Drift | None) -> Self:
        new = copy.copy(self)
        new._delay = delay
        new._drift = drift
        new.units = dict(self.units)
        new._state = new.initial_state()
        return new

    def _extra_state(self) -> int:
        """State slots after the core's: the delay line and the samples since the start."""
        return self._delay + 1 if (self._delay or self._drift is not None) else 0

    # -- state ------------------------------------------------------------------------
    def initial_state(self) -> FloatArray:
        """The relaxed initial state (input and memory at zero; Preisach: all relays down).
        With an input delay or a drift, the core's slots are followed by the delay line and the
        samples since the start (0: the delay line takes the next run's first input).

        Returns
        -------
        ndarray

        Examples
        --------
        >>> from piezohyst import PI
        >>> PI([0.5], [1.0], p0=1.0).initial_state().tolist()   # one play operator
        [0.0]
        """
        core = self._compiled.initial_state()
        extra = self._extra_state()
        return np.concatenate([core, np.zeros(extra)]) if extra else core

    @property
    def state(self) -> FloatArray:
        """A copy of the internal state used by :meth:`step`."""
        return self._state.copy()

    @state.setter
    def state(self, value: npt.ArrayLike) -> None:
        self._state = self._checked_state(value, "state")

    def _checked_state(self, value: object, name: str) -> FloatArray:
        s = as_record(value, name, min_length=0)
        if s.size != self._state.size:
            raise ParameterError(f"{name} has length {s.size}, expected {self._state.size} for this model")
        if self._extra_state() and not (s[-1] >= 0.0 and s[-1] == np.floor(s[-1])):
            raise ParameterError(
                f"{name}[{s.size - 1}] = {s[-1]} (samples since the start) must be a whole number >= 0"
            )
        return s

    def _run(self, v: FloatArray, st: FloatArray) -> FloatArray:
        """The output for input ``v`` from the full state ``st`` (updated in place): the delay
        line, the core, the output map, the drift."""
        extra = self._extra_state()
        if not extra:
            return self._map.apply(self._compiled.simulate(v, st))
        nc = st.size - extra
        d = self._delay
        age = float(st[-1])
        vin = v
        if d:
            line = np.full(d, v[0]) if age == 0.0 else st[nc : nc + d]
            w = np.concatenate([line, v])
            vin = w[: v.size]
            st[nc : nc + d] = w[v.size :]
        core = st[:nc].copy()
        y = self._map.apply(self._compiled.simulate(vin, core))
        st[:nc] = core
        if self._drift is not None:
            y = y + self._drift.evaluate(age + np.arange(v.size, dtype=np.float64))
        st[-1] = age + v.size
        return y

    def reset(self) -> None:
        """Return the internal state to the relaxed initial state.

        Examples
        --------
        >>> from piezohyst import PI
        >>> m = PI([0.5], [1.0], p0=1.0)
        >>> m.step(2.0)
        3.5
        >>> m.reset()
        >>> m.step(0.0)
        0.0
        """
        self._state = self.initial_state()

    # -- simulation -----------------------------------------------------------------
    def simulate(self, input: npt.ArrayLike, *, initial_state: npt.ArrayLike | None = None) -> FloatArray:
        """Output for an input record, from ``initial_state`` (default: relaxed).

        The fast path: it returns the output samples only. :meth:`response` runs the same
        simulation and returns the full :class:`~piezohyst.signals.Response` (time base, input
        and output with their units, final state).

        The internal state used by :meth:`step` is not changed.

        Parameters
        ----------
        input : array_like, shape (N,)
            Finite input samples.
        initial_state : array_like, optional
            State to start from, e.g. ``model.state``.

        Returns
        -------
        ndarray, shape (N,)

        Examples
        --------
        >>> from piezohyst import PI
        >>> m = PI(thresholds=[0.5], weights=[1.0], p0=1.0)
        >>> m.simulate([0.0, 1.0, 2.0, 1.0]).tolist()
        [0.0, 1.5, 3.5, 2.5]
        """
        v = as_record(input, "input")
        st = self.initial_state() if initial_state is None else self._checked_state(initial_state, "initial_state")
        return self._run(v, st)

    def response(
        self,
        input: npt.ArrayLike,
        *,
        fs: float | None = None,
        time: npt.ArrayLike | None = None,
        initial_state: npt.ArrayLike | None = None,
    ) -> Response:
        """Run the model over an input record and return the whole run as a :class:`~piezohyst.signals.Response`.

        The output is the one :meth:`simulate` returns, bit for bit; the internal state used
        by :meth:`step` is not changed.

        Parameters
        ----------
        input : array_like, shape (N,)
            Finite input samples.
        fs : float, optional
            Sampling rate, Hz (> 0): sample ``k`` is at ``k / fs``. Without ``fs`` and ``time``
            the time base is the sample index (``fs = 1``).
        time : array_like, shape (N,), optional
            Sample instants, s: finite and strictly increasing. Give ``fs`` or ``time``, not both.
        initial_state : array_like, optional
            State to start from (default: relaxed), e.g. ``model.state`` or the ``final_state``
            of a previous response to continue that run.

        Returns
        -------
        Response
            Signals ``input`` (role input) and ``output``, with the model's units (``""`` when
            it has none); ``final_state`` is the model state after the last sample; ``title``
            is the model family.

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst import PI
        >>> model = PI(thresholds=[0.5], weights=[1.0], p0=1.0, units={"input": "V", "output": "um"})
        >>> r = model.response([0.0, 1.0, 2.0, 1.0], fs=1000.0)
        >>> r.output.tolist(), r.time.tolist()
        ([0.0, 1.5, 3.5, 2.5], [0.0, 0.001, 0.002, 0.003])
        >>> r.units, r.title
        ({'input': 'V', 'output': 'um'}, 'pi')
        >>> rest = model.response([0.0], initial_state=r.final_state)   # continue the run
        >>> float(rest.output[0]) == float(model.simulate([0.0, 1.0, 2.0, 1.0, 0.0])[-1])
        True
        """
        v = as_record(input, "input")
        t = _time_base(v.size, fs, time)
        st = self.initial_state() if initial_state is None else self._checked_state(initial_state, "initial_state")
        y = self._run(v, st)
        return Response(
            t,
            {"input": v, "output": y},
            inputs=["input"],
            units={"input": self.units.get("input", ""), "output": self.units.get("output", "")},
            final_state=st,
            title=self.family,
        )

    def step(self, value: float) -> float:
        """Apply one input sample, advance the internal state, return the output.

        Parameters
        ----------
        value : float
            The input sample.

        Returns
        -------
        float

        Examples
        --------
        >>> from piezohyst import PI
        >>> m = PI(thresholds=[0.5], weights=[1.0], p0=1.0)
        >>> [m.step(v) for v in (0.0, 1.0, 2.0, 1.0)]
        [0.0, 1.5, 3.5, 2.5]
        """
        v = np.array([as_scalar(value, "value")])
        st = self._state.copy()
        y = self._run(v, st)
        self._state = st
        return float(y[0])

    def inverse(self) -> Inverse:
        """The exact per-sample inverse of this model (docs/spec.md §2.1), output map included;
        an input delay and a drift are left out (see :class:`Inverse`).


        Returns
        -------
        Inverse

        Examples
        --------
        >>> from piezohyst import PI
        >>> m = PI(thresholds=[0.5], weights=[1.0], p0=1.0)
        >>> m.inverse().simulate(m.simulate([0.0, 1.0, 2.0, 1.0])).tolist()
        [0.0, 1.0, 2.0, 1.0]
        """
        return Inverse(self)

    # -- files ----------------------------------------------------------------------
    def to_dict(self, *, include_state: bool = False) -> JSONDict:
        """JSON-ready description: ``schema_version``, ``kind``, ``parameters``, ``units``,
        ``output_map`` (``{"offset", "gain"}``) when the map is not the identity,
        ``input_delay`` (samples) when not 0 and ``drift`` (:meth:`Drift.to_dict`) when set.


        Parameters
        ----------
        include_state : bool
            Also store the internal state of :meth:`step` (key ``"state"``).

        Returns
        -------
        dict

        Examples
        --------
        >>> from piezohyst import PI
        >>> d = PI([0.5], [1.0], p0=1.0).to_dict()
        >>> d["kind"], d["parameters"]
        ('pi', {'thresholds': [0.5], 'weights': [1.0], 'p0': 1.0})
        """
        d: JSONDict = {
            "schema_version": SCHEMA_VERSION,
            "kind": self.kind,
            "parameters": self.parameters,
            "units": dict(self.units),
        }
        if not self._map.is_identity:
            d["output_map"] = self._map.to_dict()
        if self._delay:
            d["input_delay"] = self._delay
        if self._drift is not None:
            d["drift"] = self._drift.to_dict()
        if include_state:
            d["state"] = self._state.tolist()
        return d

    def to_json(self, *, include_state: bool = False) -> str:
        """The model as a JSON string (floats round-trip exactly).

        Parameters
        ----------
        include_state : bool
            Also store the internal state (see :meth:`to_dict`).

        Returns
        -------
        str

        Examples
        --------
        >>> from piezohyst import PI
        >>> from piezohyst.models import model_from_dict
        >>> import json
        >>> m = PI([0.1], [0.3], p0=1.0)
        >>> model_from_dict(json.loads(m.to_json())) == m
        True
        """
        return json.dumps(self.to_dict(include_state=include_state), indent=2, allow_nan=False)

    def save(self, path: PathLike, *, overwrite: bool = False, include_state: bool = False) -> Path:
        """Write the model file atomically; an existing file is kept unless ``overwrite``. A
        path ending in ``.mat`` writes the MATLAB file of :meth:`to_mat`, any other JSON.

        Parameters
        ----------
        path : str or os.PathLike
            The file to write (JSON, or MATLAB for ``.mat``).
        overwrite : bool
            Replace an existing file (otherwise :class:`~piezohyst.errors.OutputExistsError`).
        include_state : bool
            Also store the internal state (see :meth:`to_dict`).

        Returns
        -------
        pathlib.Path
            The written file.

        Examples
        --------
        >>> import tempfile, pathlib
        >>> from piezohyst import PI, load_model
        >>> m = PI([0.5], [1.0], p0=1.0)
        >>> path = m.save(pathlib.Path(tempfile.mkdtemp()) / "pi.json")
        >>> load_model(path) == m
        True
        """
        if Path(path).suffix.lower() == ".mat":
            return self.to_mat(path, overwrite=overwrite, include_state=include_state)
        text = self.to_json(include_state=include_state)
        return write_atomic(path, text, overwrite=overwrite)

    def to_mat(self, path: PathLike, *, overwrite: bool = False, include_state: bool = False) -> Path:
        """Write the model to the MATLAB file ``path`` (read back exactly by
        :func:`load_model`): the struct ``model`` with

        - ``schema_version`` (int), ``kind`` (the model-file name, ``"gpi"``), ``family`` (the
          core's family);
        - ``parameters``: a struct of the named parameters (vectors as 1 x N doubles; a GPI's
          unbounded ``input_range`` ends are NaN; envelopes and creep as structs);
        - ``output_map``: ``offset`` and ``gain`` (``y = gain * h(v) + offset``);
        - ``units``: a struct ``input``, ``output`` (``''`` for unitless);
        - ``state`` (with ``include_state``).

        The layout of the file: :mod:`piezohyst.signals.matfile`.

        Parameters
        ----------
        path : str or os.PathLike
            The file to write (``.mat``), atomically.
        overwrite : bool
            Replace an existing file (default ``False``: ``OutputExistsError``).
        include_state : bool
            Also store the internal state of :meth:`step` (default ``False``).

        Returns
        -------
        pathlib.Path
            The file written.

        Examples
        --------
        >>> import tempfile, pathlib
        >>> from piezohyst import PI, load_model
        >>> m = PI([0.0, 0.5], [1.0, 0.25], p0=0.1, units={"input": "V", "output": "m"})
        >>> path = m.to_mat(pathlib.Path(tempfile.mkdtemp()) / "pi.mat")
        >>> load_model(path) == m
        True
        """
        d = self.to_dict(include_state=include_state)
        d["family"] = self.family
        d["output_map"] = self._map.to_dict()
        return write_mat(path, "model", d, overwrite=overwrite)

    @classmethod
    def from_dict(cls, d: JSONDict) -> HysteresisModel:
        """The model of a :meth:`to_dict` description (:func:`model_from_dict`), which must be a
        ``cls`` (``ParameterError`` naming the kind otherwise).

        Parameters
        ----------
        d : dict
            A model description (``schema_version``, ``kind``, ``parameters``, ...).

        Returns
        -------
        HysteresisModel

        Examples
        --------
        >>> from piezohyst import PI
        >>> m = PI([0.5], [1.0], p0=1.0)
        >>> PI.from_dict(m.to_dict()) == m
        True
        """
        model = model_from_dict(d)
        if not isinstance(model, cls):
            raise ParameterError(f"kind = {d.get('kind')!r} is not a {cls.__name__}")
        return model

    @classmethod
    def _from_parameters(cls, p: JSONDict, units: Any) -> Self:
        return cls(**p, units=units)

    def __eq__(self, other: object) -> bool:
        return (
            isinstance(other, HysteresisModel)
            and type(self) is type(other)
            and self.dims == other.dims
            and np.array_equal(self._row, other._row)
            and self._map == other._map
            and self._delay == other._delay
            and self._drift == other._drift
        )

    # models compare by parameters and carry a mutable state: not hashable
    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={_short(v)}" for k, v in self.parameters.items())
        if not self._map.is_identity:
            args += f", output_map=(offset={self._map.offset:.6g}, gain={self._map.gain:.6g})"
        if self._delay:
            args += f", input_delay={self._delay}"
        if self._drift is not None:
            args += f", drift={self._drift}"
        return f"{type(self).__name__}({args})"


def _time_base(n: int, fs: object, time: object) -> FloatArray:
    """The time base of an ``n``-sample run: ``time`` as given (checked), else ``k / fs``
    (``fs`` defaults to 1: the sample index)."""
    if fs is not None and time is not None:
        raise ParameterError("fs and time are both given; pass one of them")
    if time is not None:
        t = as_record(time, "time")
        if t.size != n:
            raise ParameterError(f"time has {t.size} samples, the record {n}")
        bad = np.flatnonzero(~(np.diff(t) > 0))
        if bad.size:
            k = int(bad[0]) + 1
            raise ParameterError(
                f"time must be strictly increasing: time[{k}] = {t[k]} after time[{k - 1}] = {t[k - 1]}"
            )
        return t
    rate = 1.0 if fs is None else as_scalar(fs, "fs", positive=True)
    return np.arange(n, dtype=np.float64) / rate


def _short(v: object) -> str:
    if isinstance(v, list) and len(v) > 6:
        return f"[{', '.join(f'{x:.4g}' for x in v[:3])}, ... ({len(v)} values)]"
    if isinstance(v, float):
        return f"{v:.6g}"
    return repr(v)


def _units(units: object) -> dict[str, str]:
    """A model's units: a mapping of names to strings (``None``: unitless)."""
    if not units:
        return {"input": "", "output": ""}
    if not isinstance(units, dict) or not all(isinstance(k, str) and isinstance(v, str) for k, v in units.items()):
        raise ParameterTypeError(f"units must be a mapping of names to unit strings, got {units!r}")
    for k, v in units.items():  # units are printed: no terminal escapes, one line
        if printable(k) != k or printable(v) != v:
            raise ParameterError(
                f"units[{printable(repr(k))}] = {printable(repr(v))} holds a control character; a unit is plain text"
            )
    return dict(units)


#: What a model file holds: a hysteresis model, or the Bouc–Wen benchmark oscillator
#: (``kind = "boucwen-benchmark"``, simulated at its own ``fs``).
AnyModel = HysteresisModel | BoucWenBenchmark

#: Files that are not model files but that ``piezohyst`` commands write next to them: what
#: reads each instead.
_OTHER_FILES = {
    "stage": "a stage file (piezohyst identify --model cemf, the plant): read it with "
    "piezohyst.plant.Stage.from_file; 'piezohyst simulate' runs it open loop, "
    "'piezohyst stage info --stage' and 'piezohyst track --stage' read it",
    "mimo": "a MIMO model file (piezohyst identify on multi-channel data): read it with "
    "piezohyst.models.mimo.load_mimo_model; 'piezohyst simulate' runs it",
}


def model_from_dict(d: JSONDict) -> AnyModel:
    """Rebuild a model from :meth:`HysteresisModel.to_dict` output (or
    :meth:`BoucWenBenchmark.to_dict`'s).

    Parameters
    ----------
    d : dict
        A model description (a model file's JSON object).

    Returns
    -------
    HysteresisModel or BoucWenBenchmark

    Examples
    --------
    >>> from piezohyst import PI, model_from_dict
    >>> m = PI([0.5], [1.0], p0=1.0)
    >>> model_from_dict(m.to_dict()) == m
    True
    >>> model_from_dict({"schema_version": 2, "kind": "pi"})
    Traceback (most recent call last):
    ...
    piezohyst.errors.ParameterError: schema_version = 2 is not supported (this version reads the integer 1)
    """
    with malformed_as("the model description"):
        return _model_from_dict(d)


def _model_from_dict(d: object) -> AnyModel:
    if not isinstance(d, dict):
        raise ParameterTypeError(f"a model description must be a JSON object, got {type(d).__name__}")
    version = d.get("schema_version")
    if type(version) is not int or version != SCHEMA_VERSION:  # true is not 1, nor is 1.0
        raise ParameterError(
            f"schema_version = {json_text(version)} is not supported (this version reads the integer {SCHEMA_VERSION})"
        )
    kind = d.get("kind")
    if isinstance(d.get("parameters"), dict):
        check_parameter_tree(d["parameters"], "parameters")  # true is not a number: named by its path
    for part in ("output_map", "state"):
        if d.get(part) is not None:
            check_parameter_tree(d[part], part)
    if kind == BoucWenBenchmark.kind:
        return BoucWenBenchmark.from_dict(d)
    if isinstance(kind, str) and kind in _OTHER_FILES:
        raise ParameterError(f"kind = {kind!r} is not a hysteresis model but {_OTHER_FILES[kind]}")
    if kind not in _REGISTRY:
        raise ParameterError(
            f"kind = {kind!r} is unknown; expected one of {sorted([*_REGISTRY, BoucWenBenchmark.kind])}"
        )
    p = d.get("parameters")
    if not isinstance(p, dict):
        raise ParameterError("parameters must be a JSON object")
    try:
        model = _REGISTRY[kind]._from_parameters(p, d.get("units"))
    except TypeError as e:
        raise ParameterError(f"parameters of kind {kind!r} are not valid: {e}") from None
    if d.get("output_map") is not None:  # absent: the identity (files written before the map)
        model = model.with_output_map(OutputMap.from_any(d["output_map"]))
    if d.get("input_delay") is not None:  # absent: none (files written before the delay)
        if isinstance(d["input_delay"], bool) or not isinstance(d["input_delay"], int):
            raise ParameterError(f"input_delay = {d['input_delay']!r} must be a whole number of samples")
        model = model.with_input_delay(d["input_delay"])
    if d.get("drift") is not None:
        model = model.with_drift(Drift.from_any(d["drift"]))
    if "state" in d:
        model.state = d["state"]
    return model


def load_model(path: PathLike) -> AnyModel:
    """Read a model file written by :meth:`HysteresisModel.save` or ``piezohyst identify``
    (every ``--model`` kind but ``cemf``, whose stage file
    :meth:`piezohyst.plant.Stage.from_file` reads; ``DataError`` naming the file if it is not
    a model file). A ``boucwen-benchmark`` file gives a :class:`BoucWenBenchmark` that
    simulates at the file's ``fs``. A ``.mat`` file is read as the MATLAB file of
    :meth:`HysteresisModel.to_mat` (exactly), anything else as JSON.

    Parameters
    ----------
    path : str or os.PathLike
        The model file (JSON, or MATLAB for ``.mat``).

    Returns
    -------
    HysteresisModel or BoucWenBenchmark

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from piezohyst import PI, load_model
    >>> path = PI([0.5], [1.0], p0=1.0).save(pathlib.Path(tempfile.mkdtemp()) / "pi.json")
    >>> load_model(path).simulate([0.0, 2.0]).tolist()
    [0.0, 3.5]
    """
    if Path(path).suffix.lower() == ".mat":
        return load_mat_file(path, "model", "model file", _model_from_mat)
    return load_json_file(path, "model file", model_from_dict)


def _model_from_mat(d: JSONDict) -> AnyModel:
    """A model from the struct :meth:`HysteresisModel.to_mat` writes: its ``family`` must be
    the one its ``kind`` builds."""
    d = dict(d)
    family = d.pop("family", None)
    model = model_from_dict(d)
    expected = getattr(model, "family", None)
    if family is not None and expected is not None and family != expected:
        raise ParameterError(f"family = {family!r} does not match kind = {d.get('kind')!r} (family {expected!r})")
    return model


class Inverse:
    """Exact per-sample inverse of a model (docs/spec.md §2.1), output map included: the
    desired output ``y`` is mapped back to ``(y - offset) / gain`` and the family inverted.

    At each sample the forward model's state is frozen, the input that produces the desired
    output is found by bracketing and safeguarded Newton, and the forward state is advanced
    with it, so the inverse always stays consistent with the model it inverts.

    **Input delay and drift are not inverted.** A compensator cannot undo a delay: it would
    have to know the desired output ``input_delay`` samples ahead. The inverse inverts the
    undelayed model: driven by its inputs, a model with an input delay of ``d`` samples
    follows the desired output ``d`` samples late (``y[k] = desired[k - d]``); when the desired
    trajectory is known ahead (a planned scan), give it ``d`` samples early. The drift is a
    trend of the record's sensor, not a motion of the actuator: the inverse leaves it out (it
    does not drive the actuator to follow a sensor's drift). Its state is the family core's
    (without the delay line); a model state given to it is taken for its core part.

    Parameters
    ----------
    model : HysteresisModel
        The model to invert (:meth:`HysteresisModel.inverse` builds this).

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst import PI
    >>> model = PI(thresholds=[0.1, 0.3], weights=[0.5, 0.2], p0=1.0)
    >>> yd = np.sin(np.linspace(0, 6, 50))
    >>> v = model.inverse().simulate(yd)
    >>> bool(np.max(np.abs(model.simulate(v) - yd)) < 1e-12)
    True
    """

    def __init__(self, model: HysteresisModel) -> None:
        self.model = model
        self._state = model._compiled.initial_state()
        self._last_input = 0.0

    @property
    def state(self) -> FloatArray:
        """The forward model's core state the inverse tracks (a copy)."""
        return self._state.copy()

    @state.setter
    def state(self, value: npt.ArrayLike) -> None:
        self._state = self._checked(value, "state")

    def _checked(self, value: object, name: str) -> FloatArray:
        """The core part of a state: the core's state, or a whole model state (checked)."""
        m = self.model
        s = as_record(value, name, min_length=0)
        core = self._state.size
        if s.size != core:
            s = m._checked_state(s, name)[:core].copy()
        return s

    def reset(self) -> None:
        """Back to the relaxed state.

        Examples
        --------
        >>> from piezohyst import PI
        >>> inv = PI([0.5], [1.0], p0=1.0).inverse()
        >>> inv.step(3.5)
        2.0
        >>> inv.reset()
        >>> inv.state.tolist()
        [0.0]
        """
        self._state = self.model._compiled.initial_state()
        self._last_input = 0.0

    def simulate(self, desired: npt.ArrayLike, *, initial_state: npt.ArrayLike | None = None) -> FloatArray:
        """Inputs that make the model follow ``desired`` exactly, from ``initial_state``.

        The fast path: it returns the inputs only; :meth:`response` runs the same inversion
        and returns the full :class:`~piezohyst.signals.Response`.

        Raises ``ValueError`` naming the sample if a desired value cannot be reached.

        Parameters
        ----------
        desired : array_like, shape (N,)
            The desired outputs.
        initial_state : array_like, optional
            The forward model's state to start from (default: relaxed).

        Returns
        -------
        ndarray, shape (N,)
            The inputs.

        Examples
        --------
        >>> from piezohyst import PI
        >>> PI([0.5], [1.0], p0=1.0).inverse().simulate([0.0, 1.5, 3.5, 2.5]).tolist()
        [0.0, 1.0, 2.0, 1.0]
        """
        yd = as_record(desired, "desired")
        m = self.model
        st = m._compiled.initial_state() if initial_state is None else self._checked(initial_state, "initial_state")
        return m._compiled.inverse(m._map.invert(yd), st, 0.0)

    def response(
        self,
        desired: npt.ArrayLike,
        *,
        fs: float | None = None,
        time: npt.ArrayLike | None = None,
        initial_state: npt.ArrayLike | None = None,
    ) -> Response:
        """Invert a desired output record and return the whole run as a :class:`~piezohyst.signals.Response`.

        The inputs are the ones :meth:`simulate` returns, bit for bit; the tracked state used
        by :meth:`step` is not changed.

        Parameters
        ----------
        desired : array_like, shape (N,)
            Finite desired outputs of the model.
        fs : float, optional
            Sampling rate, Hz (> 0): sample ``k`` is at ``k / fs``. Without ``fs`` and ``time``
            the time base is the sample index (``fs = 1``).
        time : array_like, shape (N,), optional
            Sample instants, s: finite and strictly increasing. Give ``fs`` or ``time``, not both.
        initial_state : array_like, optional
            Forward model state to start from (default: relaxed), e.g. the ``final_state`` of a
            previous response.

        Returns
        -------
        Response
            Signals ``desired`` (role input, in the model's output unit) and ``input`` (the
            model input that produces it, in the model's input unit); ``final_state`` is the
            forward model's state after the last sample; ``title`` is the model family
            followed by ``" inverse"``.

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst import PI
        >>> model = PI(thresholds=[0.1, 0.3], weights=[0.5, 0.2], p0=1.0)
        >>> r = model.inverse().response(np.sin(np.linspace(0, 6, 50)), fs=100.0)
        >>> r.input_names, r.output_names, r.title
        (('desired',), ('input',), 'pi inverse')
        >>> bool(np.max(np.abs(model.simulate(r.input) - r.desired)) < 1e-12)
        True
        """
        yd = as_record(desired, "desired")
        t = _time_base(yd.size, fs, time)
        m = self.model
        st = m._compiled.initial_state() if initial_state is None else self._checked(initial_state, "initial_state")
        v = m._compiled.inverse(m._map.invert(yd), st, 0.0)
        return Response(
            t,
            {"desired": yd, "input": v},
            inputs=["desired"],
            units={"desired": m.units.get("output", ""), "input": m.units.get("input", "")},
            final_state=st,
            title=f"{m.family} inverse",
        )

    def step(self, desired: float) -> float:
        """Input for one desired output; advances the tracked forward state.

        Parameters
        ----------
        desired : float
            The desired output.

        Returns
        -------
        float
            The input.

        Examples
        --------
        >>> from piezohyst import PI
        >>> inv = PI([0.5], [1.0], p0=1.0).inverse()
        >>> [inv.step(y) for y in (0.0, 1.5, 3.5, 2.5)]
        [0.0, 1.0, 2.0, 1.0]
        """
        m = self.model
        yd = np.array([as_scalar(desired, "desired")])
        st = self._state.copy()
        v = m._compiled.inverse(m._map.invert(yd), st, self._last_input)
        self._state = st
        self._last_input = float(v[0])
        return self._last_input
