"""A controller written in C, run in the loop: a function of a shared library called through
ctypes from the Rust loop's slow path (the path of a Python :class:`~piezohyst.control.simulation.UserController`:
one call per sample, about a microsecond, for trying a law from a DAQ's firmware in the
simulated loop before it meets the stage).

The C side::

    double step(void *state, double reference, double measured, double velocity, double acceleration);
    void reset(void *state, double measured);            /* optional */

``state`` is a zeroed buffer of ``state_size`` bytes the controller owns for the run (reset to
zero, then ``reset`` called with the first reading, before every run).

Examples
--------
>>> from piezohyst.control.user import CController
>>> CController.from_library("/nonexistent/libpi.so", "pi_step")      # doctest: +ELLIPSIS
Traceback (most recent call last):
...
piezohyst.errors.ParameterError: library = '/nonexistent/libpi.so' cannot be loaded: ...
"""

from __future__ import annotations

import ctypes
import math
import os
from dataclasses import dataclass, field
from typing import Any

from .._validate import as_int
from ..errors import ComputationError, ParameterError

__all__ = ["RESET_SIGNATURE", "STEP_SIGNATURE", "CController"]

#: ``double step(void *state, double reference, double measured, double velocity, double acceleration)``
STEP_SIGNATURE = ctypes.CFUNCTYPE(
    ctypes.c_double, ctypes.c_void_p, ctypes.c_double, ctypes.c_double, ctypes.c_double, ctypes.c_double
)
#: ``void reset(void *state, double measured)``
RESET_SIGNATURE = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_double)

# ctypes function types take a docstring (and a module, so that doctest collects it here)
STEP_SIGNATURE.__doc__ = """The ctypes type of the C step,
``double step(void *state, double reference, double measured, double velocity, double acceleration)``:
wraps a Python callable (or casts a C function pointer) into a step for :class:`CController`.

Examples
--------
>>> from piezohyst.control.user import STEP_SIGNATURE, CController
>>> step = STEP_SIGNATURE(lambda state, r, y, v, a: 2.0 * (r - y) + 0.5 * v)
>>> CController(step).step(1.0, 0.25, velocity=1.0)
2.0
"""
STEP_SIGNATURE.__module__ = __name__
RESET_SIGNATURE.__doc__ = """The ctypes type of the optional C reset, ``void reset(void *state, double measured)``,
called with the first reading before each run (after the state is zeroed).

Examples
--------
>>> from piezohyst.control.user import RESET_SIGNATURE, STEP_SIGNATURE, CController
>>> seen = []
>>> c = CController(STEP_SIGNATURE(lambda *_: 0.0), RESET_SIGNATURE(lambda state, y: seen.append(y)))
>>> c.reset(0.125)
>>> seen
[0.125]
"""
RESET_SIGNATURE.__module__ = __name__


@dataclass
class CController:
    """A C function as a controller (the slow path of :func:`~piezohyst.closed_loop`,
    :func:`~piezohyst.track`); see the module's documentation for the C signatures.

    A C function here is a ``ctypes`` function pointer: one of a loaded library (see
    :meth:`from_library`) or a Python callable wrapped in ``STEP_SIGNATURE`` /
    ``RESET_SIGNATURE``, as in the example (no compiler needed).

    Parameters
    ----------
    step_function : ctypes function
        The step (``STEP_SIGNATURE``, or a ``ctypes.CDLL`` function: its types are set here).
    reset_function : ctypes function, optional
        Called with the first reading before each run.
    state_size : int
        Bytes of the state buffer handed to both.
    _library : ctypes.CDLL, optional
        Internal: the library the functions come from, kept loaded (set by
        :meth:`from_library`).

    Examples
    --------
    >>> import ctypes
    >>> from piezohyst.control.user import RESET_SIGNATURE, STEP_SIGNATURE, CController
    >>> def doubles(state):
    ...     return ctypes.cast(state, ctypes.POINTER(ctypes.c_double))
    >>> @STEP_SIGNATURE
    ... def step(state, reference, measured, velocity, acceleration):
    ...     doubles(state)[1] += reference - measured         # the error's sum
    ...     return doubles(state)[0] + 1e5 * doubles(state)[1]
    >>> @RESET_SIGNATURE
    ... def reset(state, measured):
    ...     doubles(state)[0] = 1e5 * measured                # an offset from the first reading
    >>> c = CController(step, reset, state_size=16)
    >>> c.reset(1e-6)
    >>> round(c.step(3e-6, 1e-6), 12), round(c.step(3e-6, 2e-6), 12)
    (0.3, 0.4)
    """

    step_function: Any
    reset_function: Any = None
    state_size: int = 256
    _state: Any = field(init=False, repr=False)
    _library: Any = field(default=None, repr=False)

    #: the step gets the reference's velocity and acceleration
    uses_reference_derivatives = True

    def __post_init__(self) -> None:
        n = as_int(self.state_size, "state_size", minimum=0)
        self._state = ctypes.create_string_buffer(max(n, 1))
        for name, fn, restype, argtypes in (
            ("step", self.step_function, ctypes.c_double, [ctypes.c_void_p] + [ctypes.c_double] * 4),
            ("reset", self.reset_function, None, [ctypes.c_void_p, ctypes.c_double]),
        ):
            if fn is None:
                if name == "step":
                    raise ParameterError("step_function is required")
                continue
            if not callable(fn):
                raise ParameterError(f"{name}_function = {fn!r} is not a C function")
            try:  # a function of a ctypes.CDLL: set its types (a CFUNCTYPE instance has them)
                fn.restype = restype
                fn.argtypes = argtypes
            except (AttributeError, TypeError):
                pass

    @classmethod
    def from_library(
        cls, library: str | os.PathLike[str], step: str, reset: str | None = None, state_size: int = 256
    ) -> CController:
        """Load ``step`` (and ``reset``) from the shared library at ``library``.

        Parameters
        ----------
        library : path
            A shared library (``.so``, ``.dylib``, ``.dll``).
        step, reset : str
            The functions' names.
        state_size : int
            Bytes of the state buffer.

        Returns
        -------
        CController

        Examples
        --------
        >>> import ctypes.util
        >>> from piezohyst.control.user import CController
        >>> libm = ctypes.util.find_library("m") or ctypes.util.find_library("msvcrt")
        >>> CController.from_library(libm, "no_such_step")     # doctest: +ELLIPSIS
        Traceback (most recent call last):
        ...
        piezohyst.errors.ParameterError: step = 'no_such_step': no such function in ...
        """
        try:
            lib = ctypes.CDLL(os.fspath(library))
        except OSError as exc:
            raise ParameterError(f"library = {os.fspath(library)!r} cannot be loaded: {exc}") from None
        fns: list[Any] = []
        for label, name in (("step", step), ("reset", reset)):
            if name is None:
                fns.append(None)
                continue
            try:
                fns.append(getattr(lib, name))
            except AttributeError:
                raise ParameterError(f"{label} = {name!r}: no such function in {os.fspath(library)!r}") from None
        c = cls(fns[0], fns[1], state_size)
        c._library = lib
        return c

    def reset(self, measured: float) -> None:
        """Zero the state and call the C ``reset`` (if any) with the first reading.

        Parameters
        ----------
        measured : float
            The first sensor reading, m.

        Examples
        --------
        >>> import ctypes
        >>> from piezohyst.control.user import RESET_SIGNATURE, STEP_SIGNATURE, CController
        >>> def doubles(state):
        ...     return ctypes.cast(state, ctypes.POINTER(ctypes.c_double))
        >>> @STEP_SIGNATURE
        ... def step(state, reference, measured, velocity, acceleration):
        ...     doubles(state)[1] += reference - measured         # the error's sum
        ...     return doubles(state)[0] + 1e5 * doubles(state)[1]
        >>> @RESET_SIGNATURE
        ... def reset(state, measured):
        ...     doubles(state)[0] = 1e5 * measured                # an offset from the first reading
        >>> c = CController(step, reset, state_size=16)
        >>> c.reset(0.0)
        >>> round(c.step(1e-6, 0.0), 12), round(c.step(1e-6, 0.0), 12)
        (0.1, 0.2)
        >>> c.reset(0.0)                                      # the sum starts again from zero
        >>> round(c.step(1e-6, 0.0), 12)
        0.1
        """
        ctypes.memset(self._state, 0, len(self._state))
        if self.reset_function is not None:
            self.reset_function(ctypes.cast(self._state, ctypes.c_void_p), float(measured))

    def step(self, reference: float, measured: float, velocity: float = 0.0, acceleration: float = 0.0) -> float:
        """One call of the C step: the command (V).

        Parameters
        ----------
        reference : float
            The reference position, m.
        measured : float
            The sensor reading, m.
        velocity, acceleration : float, optional
            The reference's derivatives, m/s and m/s^2.

        Returns
        -------
        float
            The command, V.

        Examples
        --------
        >>> import ctypes
        >>> from piezohyst.control.user import RESET_SIGNATURE, STEP_SIGNATURE, CController
        >>> def doubles(state):
        ...     return ctypes.cast(state, ctypes.POINTER(ctypes.c_double))
        >>> @STEP_SIGNATURE
        ... def step(state, reference, measured, velocity, acceleration):
        ...     doubles(state)[1] += reference - measured         # the error's sum
        ...     return doubles(state)[0] + 1e5 * doubles(state)[1]
        >>> @RESET_SIGNATURE
        ... def reset(state, measured):
        ...     doubles(state)[0] = 1e5 * measured                # an offset from the first reading
        >>> c = CController(step, reset, state_size=16)
        >>> c.reset(0.0)
        >>> round(c.step(2e-6, 1.5e-6), 12)                 # 1e5 V/m times the error's sum
        0.05
        """
        u = float(
            self.step_function(
                ctypes.cast(self._state, ctypes.c_void_p),
                float(reference),
                float(measured),
                float(velocity),
                float(acceleration),
            )
        )
        if not math.isfinite(u):
            raise ComputationError(f"the C controller returned {u} for reference {reference}, measured {measured}")
        return u
