"""The common interface of every hysteresis model: simulate, step, state, inverse, files.

A model is a parameter set (immutable once built) plus an internal state used by
:meth:`HysteresisModel.step`. :meth:`HysteresisModel.simulate` never touches the internal
state: it runs a whole record from a given (default: relaxed) initial state. All loops over
samples run in the Rust core.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .. import _core
from .._io import load_json_file, malformed_as, write_atomic
from .._validate import as_record, as_scalar
from ..errors import ParameterError, ParameterTypeError

__all__ = ["SCHEMA_VERSION", "HysteresisModel", "Inverse", "load_model", "model_from_dict"]

#: Version of the model-file layout written by :meth:`HysteresisModel.save`.
SCHEMA_VERSION = 1

_REGISTRY: dict[str, type] = {}


def _register(cls):
    _REGISTRY[cls.kind] = cls
    return cls


class HysteresisModel:
    """Base class: a model family, its structure (``dims``) and one flat parameter row.

    Subclasses set ``kind`` (the name in model files), ``family`` (the core's name) and
    build ``dims`` and the row from their parameters.
    """

    kind: str = ""
    family: str = ""

    def __init__(self, dims, row, *, units=None):
        self.dims = tuple(int(d) for d in dims)
        self._row = np.ascontiguousarray(row, dtype=np.float64)
        _core.validate(self.family, list(self.dims), self._row)
        self._row.setflags(write=False)
        self.units = _units(units)
        self._state = self.initial_state()

    # -- parameters -----------------------------------------------------------------
    def to_row(self) -> np.ndarray:
        """The flat parameter row (a copy) in the core's layout for this family."""
        return self._row.copy()

    @property
    def parameters(self) -> dict:
        """Named parameters (JSON-ready)."""
        raise NotImplementedError

    # -- state ------------------------------------------------------------------------
    def initial_state(self) -> np.ndarray:
        """The relaxed initial state (input and memory at zero; Preisach: all relays down)."""
        return _core.initial_state(self.family, list(self.dims), self._row)

    @property
    def state(self) -> np.ndarray:
        """A copy of the internal state used by :meth:`step`."""
        return self._state.copy()

    @state.setter
    def state(self, value) -> None:
        self._state = self._checked_state(value, "state")

    def _checked_state(self, value, name) -> np.ndarray:
        s = as_record(value, name, min_length=0)
        if s.size != self._state.size:
            raise ParameterError(f"{name} has length {s.size}, expected {self._state.size} for this model")
        return s

    def reset(self) -> None:
        """Return the internal state to the relaxed initial state."""
        self._state = self.initial_state()

    # -- simulation -----------------------------------------------------------------
    def simulate(self, input, *, initial_state=None) -> np.ndarray:
        """Output for an input record, from ``initial_state`` (default: relaxed).

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
        """
        v = as_record(input, "input")
        st = self.initial_state() if initial_state is None else self._checked_state(initial_state, "initial_state")
        return _core.simulate(self.family, list(self.dims), self._row, v, st)

    def step(self, value: float) -> float:
        """Apply one input sample, advance the internal state, return the output."""
        v = np.array([as_scalar(value, "value")])
        st = self._state.copy()
        y = _core.simulate(self.family, list(self.dims), self._row, v, st)
        self._state = st
        return float(y[0])

    def inverse(self) -> Inverse:
        """The exact per-sample inverse of this model (docs/spec.md §2.1)."""
        return Inverse(self)

    # -- files ----------------------------------------------------------------------
    def to_dict(self, *, include_state: bool = False) -> dict:
        """JSON-ready description: ``schema_version``, ``kind``, ``parameters``, ``units``."""
        d = {
            "schema_version": SCHEMA_VERSION,
            "kind": self.kind,
            "parameters": self.parameters,
            "units": dict(self.units),
        }
        if include_state:
            d["state"] = self._state.tolist()
        return d

    def to_json(self, *, include_state: bool = False) -> str:
        """The model as a JSON string (floats round-trip exactly)."""
        return json.dumps(self.to_dict(include_state=include_state), indent=2, allow_nan=False)

    def save(self, path, *, overwrite: bool = False, include_state: bool = False) -> Path:
        """Write the model file atomically; an existing file is kept unless ``overwrite``."""
        text = self.to_json(include_state=include_state)
        return write_atomic(path, text, overwrite=overwrite)

    @classmethod
    def _from_parameters(cls, p: dict, units):
        return cls(**p, units=units)

    def __eq__(self, other):
        return type(self) is type(other) and self.dims == other.dims and np.array_equal(self._row, other._row)

    __hash__ = None

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={_short(v)}" for k, v in self.parameters.items())
        return f"{type(self).__name__}({args})"


def _short(v):
    if isinstance(v, list) and len(v) > 6:
        return f"[{', '.join(f'{x:.4g}' for x in v[:3])}, ... ({len(v)} values)]"
    if isinstance(v, float):
        return f"{v:.6g}"
    return repr(v)


def _units(units) -> dict:
    """A model's units: a mapping of names to strings (``None``: unitless)."""
    if not units:
        return {"input": "", "output": ""}
    if not isinstance(units, dict) or not all(isinstance(k, str) and isinstance(v, str) for k, v in units.items()):
        raise ParameterTypeError(f"units must be a mapping of names to unit strings, got {units!r}")
    return dict(units)


def model_from_dict(d: dict) -> HysteresisModel:
    """Rebuild a model from :meth:`HysteresisModel.to_dict` output."""
    with malformed_as("the model description"):
        return _model_from_dict(d)


def _model_from_dict(d: dict) -> HysteresisModel:
    if not isinstance(d, dict):
        raise ParameterTypeError(f"a model description must be a JSON object, got {type(d).__name__}")
    version = d.get("schema_version")
    if version != SCHEMA_VERSION:
        raise ParameterError(f"schema_version = {version!r} is not supported (this version reads {SCHEMA_VERSION})")
    kind = d.get("kind")
    if kind not in _REGISTRY:
        raise ParameterError(f"kind = {kind!r} is unknown; expected one of {sorted(_REGISTRY)}")
    p = d.get("parameters")
    if not isinstance(p, dict):
        raise ParameterError("parameters must be a JSON object")
    try:
        model = _REGISTRY[kind]._from_parameters(p, d.get("units"))
    except TypeError as e:
        raise ParameterError(f"parameters of kind {kind!r} are not valid: {e}") from None
    if "state" in d:
        model.state = d["state"]
    return model


def load_model(path) -> HysteresisModel:
    """Read a model file written by :meth:`HysteresisModel.save` (``DataError`` naming the
    file if it is not one)."""
    return load_json_file(path, "model file", model_from_dict)


class Inverse:
    """Exact per-sample inverse of a model (docs/spec.md §2.1).

    At each sample the forward model's state is frozen, the input that produces the desired
    output is found by bracketing and safeguarded Newton, and the forward state is advanced
    with it, so the inverse always stays consistent with the model it inverts.

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

    def __init__(self, model: HysteresisModel):
        self.model = model
        self._state = model.initial_state()
        self._last_input = 0.0

    @property
    def state(self) -> np.ndarray:
        """The forward model's state the inverse tracks (a copy)."""
        return self._state.copy()

    @state.setter
    def state(self, value) -> None:
        self._state = self.model._checked_state(value, "state")

    def reset(self) -> None:
        """Back to the relaxed state."""
        self._state = self.model.initial_state()
        self._last_input = 0.0

    def simulate(self, desired, *, initial_state=None) -> np.ndarray:
        """Inputs that make the model follow ``desired`` exactly, from ``initial_state``.

        Raises ``ValueError`` naming the sample if a desired value cannot be reached.
        """
        yd = as_record(desired, "desired")
        m = self.model
        st = m.initial_state() if initial_state is None else m._checked_state(initial_state, "initial_state")
        return _core.inverse(m.family, list(m.dims), m._row, yd, st, 0.0)

    def step(self, desired: float) -> float:
        """Input for one desired output; advances the tracked forward state."""
        m = self.model
        yd = np.array([as_scalar(desired, "desired")])
        st = self._state.copy()
        v = _core.inverse(m.family, list(m.dims), m._row, yd, st, self._last_input)
        self._state = st
        self._last_input = float(v[0])
        return self._last_input
