"""Bridges from piezohyst's linear objects to the field's LTI libraries: python-control
(``control.StateSpace`` / ``control.TransferFunction``) and :mod:`scipy.signal`.

The linear objects of the package build their matrices or polynomials themselves (a stage's
linear part in :mod:`piezohyst.plant.linear`, the PID and the open-loop feedforward in
:mod:`piezohyst.control.controllers`); this module turns them into the libraries' objects and
reads coefficients back from them (``from_control``) with the checks every reader shares:
single input and output, continuous or discrete with a known sample time, negligible
leading coefficients trimmed on the system's own frequency scale.

python-control is imported on first use (it is a dependency of the package; the message of a
broken install says how to get it).

Examples
--------
>>> from piezohyst.signals.lti import polynomial_tf, siso_polynomials
>>> sys = polynomial_tf([2.0, 0.0, 8.0], [1.0, 0.0])           # (2 s^2 + 8) / s
>>> num, den, dt = siso_polynomials(sys, "sys")
>>> num.tolist(), den.tolist(), dt
([2.0, 0.0, 8.0], [1.0, 0.0], None)
"""

from __future__ import annotations

from collections.abc import Sequence
from types import ModuleType
from typing import Any, TypeAlias

import numpy as np
import numpy.typing as npt

from .._validate import as_scalar
from ..errors import ParameterError, ParameterTypeError

FloatArray: TypeAlias = npt.NDArray[np.float64]

__all__ = [
    "CONTROL_HINT",
    "TRIM_RTOL",
    "polynomial_tf",
    "require_control",
    "scipy_state_space",
    "scipy_transfer_function",
    "siso_polynomials",
    "state_space",
]

#: What to do when python-control is missing (it is a dependency: a broken install).
CONTROL_HINT = "to_control()/from_control() need python-control: pip install control"

#: A leading polynomial coefficient smaller than this, relative to the largest one on the
#: system's own frequency scale, is a rounding residue of a conversion (``ss`` to ``tf``).
TRIM_RTOL = 1e-8


def require_control() -> ModuleType:
    """The ``control`` module (python-control), or ``ImportError`` saying how to install it.

    Returns
    -------
    module
        The imported ``control`` package.

    Examples
    --------
    >>> from piezohyst.signals.lti import require_control
    >>> require_control().__name__
    'control'
    """
    try:
        import control
    except ImportError:
        raise ImportError(CONTROL_HINT) from None
    module: ModuleType = control
    return module


def _sample_time(dt: float | None) -> float | None:
    if dt is None:
        return None
    return as_scalar(dt, "sample_time", positive=True)


def state_space(
    a: npt.ArrayLike,
    b: npt.ArrayLike,
    c: npt.ArrayLike,
    d: npt.ArrayLike,
    dt: float | None = None,
    *,
    inputs: Sequence[str] | None = None,
    outputs: Sequence[str] | None = None,
    states: Sequence[str] | None = None,
    name: str | None = None,
) -> Any:
    """A ``control.StateSpace`` (continuous for ``dt=None``, else discrete with sample time
    ``dt`` in s) with named signals.

    Parameters
    ----------
    a, b, c, d : array_like
        The state-space matrices ``x' = a x + b u``, ``y = c x + d u``.
    dt : float, optional
        Sample time in s (> 0) of a discrete system; ``None`` for a continuous one.
    inputs, outputs : sequence of str, optional
        Names of the input and output signals.
    states : sequence of str, optional
        Names of the states.
    name : str, optional
        Name of the system.

    Returns
    -------
    control.StateSpace

    Examples
    --------
    >>> import control
    >>> from piezohyst.signals.lti import state_space
    >>> g = state_space([[-2.0]], [[1.0]], [[3.0]], [[0.0]], inputs=["u"], outputs=["y"])
    >>> float(control.dcgain(g)), g.input_labels, g.output_labels
    (1.5, ['u'], ['y'])
    >>> state_space([[0.5]], [[1.0]], [[1.0]], [[0.0]], 0.01).dt
    0.01
    """
    ct = require_control()
    kw: dict[str, Any] = {k: list(v) for k, v in (("inputs", inputs), ("outputs", outputs), ("states", states)) if v}
    if name:
        kw["name"] = name
    args = [np.asarray(m, dtype=np.float64) for m in (a, b, c, d)]
    step = _sample_time(dt)
    return ct.ss(*args, 0 if step is None else step, **kw)


def polynomial_tf(
    num: npt.ArrayLike,
    den: npt.ArrayLike,
    dt: float | None = None,
    *,
    inputs: Sequence[str] | None = None,
    outputs: Sequence[str] | None = None,
    name: str | None = None,
) -> Any:
    """A SISO ``control.TransferFunction`` ``num(s) / den(s)`` (coefficients highest power
    first; ``z`` for a discrete one with sample time ``dt``).

    Parameters
    ----------
    num, den : array_like
        Numerator and denominator coefficients, highest power first.
    dt : float, optional
        Sample time in s (> 0) of a discrete system; ``None`` for a continuous one.
    inputs, outputs : sequence of str, optional
        Names of the input and output signals.
    name : str, optional
        Name of the system.

    Returns
    -------
    control.TransferFunction

    Examples
    --------
    >>> import control
    >>> from piezohyst.signals.lti import polynomial_tf
    >>> g = polynomial_tf([2.0], [1.0, 4.0])
    >>> float(control.dcgain(g)), g.ninputs, g.noutputs
    (0.5, 1, 1)
    """
    ct = require_control()
    kw: dict[str, Any] = {}
    if inputs is not None:
        kw["inputs"] = list(inputs)
    if outputs is not None:
        kw["outputs"] = list(outputs)
    if name:
        kw["name"] = name
    step = _sample_time(dt)
    n = np.asarray(num, dtype=np.float64)
    d = np.asarray(den, dtype=np.float64)
    return ct.tf(n, d, 0 if step is None else step, **kw)


def scipy_state_space(
    a: npt.ArrayLike, b: npt.ArrayLike, c: npt.ArrayLike, d: npt.ArrayLike, dt: float | None = None
) -> Any:
    """``scipy.signal.StateSpace`` (an ``lti``, or a ``dlti`` with ``dt``).

    Parameters
    ----------
    a, b, c, d : array_like
        The state-space matrices.
    dt : float, optional
        Sample time in s (> 0) of a discrete system; ``None`` for a continuous one.

    Returns
    -------
    scipy.signal.StateSpace

    Examples
    --------
    >>> from piezohyst.signals.lti import scipy_state_space
    >>> g = scipy_state_space([[-2.0]], [[1.0]], [[3.0]], [[0.0]])
    >>> g.A.tolist(), g.dt
    ([[-2.0]], None)
    >>> scipy_state_space([[0.5]], [[1.0]], [[1.0]], [[0.0]], dt=0.01).dt
    0.01
    """
    from scipy import signal

    args = [np.asarray(m, dtype=np.float64) for m in (a, b, c, d)]
    step = _sample_time(dt)
    return signal.StateSpace(*args) if step is None else signal.StateSpace(*args, dt=step)


def scipy_transfer_function(num: npt.ArrayLike, den: npt.ArrayLike, dt: float | None = None) -> Any:
    """``scipy.signal.TransferFunction`` (an ``lti``, or a ``dlti`` with ``dt``).

    Parameters
    ----------
    num, den : array_like
        Numerator and denominator coefficients, highest power first.
    dt : float, optional
        Sample time in s (> 0) of a discrete system; ``None`` for a continuous one.

    Returns
    -------
    scipy.signal.TransferFunction

    Examples
    --------
    >>> from piezohyst.signals.lti import scipy_transfer_function
    >>> g = scipy_transfer_function([1.0], [1.0, -0.5], dt=0.1)
    >>> g.den.tolist(), g.dt
    ([1.0, -0.5], 0.1)
    """
    from scipy import signal

    n = np.asarray(num, dtype=np.float64)
    d = np.asarray(den, dtype=np.float64)
    step = _sample_time(dt)
    return signal.TransferFunction(n, d) if step is None else signal.TransferFunction(n, d, dt=step)


def _frequency_scale(den: FloatArray, num: FloatArray, discrete: bool) -> float:
    """The scale on which the polynomial's coefficients are compared: the geometric mean of
    the non-zero root magnitudes of ``den`` (``s -> w s``), else of ``num`` (a polynomial
    transfer function, ``gain (c2 s^2 + c1 s + 1)``); 1 for a discrete system (its roots live
    near the unit circle) or without roots."""
    if discrete:
        return 1.0
    for p in (den, num):
        p = p[np.argmax(p != 0) :] if np.any(p) else p
        if p.size < 2:
            continue
        roots = np.abs(np.roots(p))
        roots = roots[(roots > 0) & np.isfinite(roots)]
        if roots.size:
            return float(np.exp(np.mean(np.log(roots))))
    return 1.0


def _trim(p: FloatArray, scale: float) -> FloatArray:
    """``p`` without leading coefficients that are rounding residues on the frequency scale."""
    powers = scale ** np.arange(p.size - 1, -1, -1, dtype=np.float64)
    weighted = np.abs(p) * powers
    top = float(weighted.max()) if weighted.size else 0.0
    if top == 0.0:
        return np.zeros(1)
    keep = np.flatnonzero(weighted > TRIM_RTOL * top)
    return p[keep[0] :].copy()


def siso_polynomials(sys: object, name: str) -> tuple[FloatArray, FloatArray, float | None]:
    """``(num, den, dt)`` of a single-input single-output LTI system: a python-control
    ``StateSpace`` / ``TransferFunction`` or a :mod:`scipy.signal` ``lti`` / ``dlti``.

    The polynomials have the highest power first, the denominator's leading coefficient is 1,
    and leading coefficients that are rounding residues of a conversion are trimmed
    (:data:`TRIM_RTOL`). ``dt`` is ``None`` for a continuous system, the sample time in s for
    a discrete one. A system with several inputs or outputs, a discrete system without a
    sample time (python-control's ``dt=True``) or anything else raises an error naming
    ``name``.

    Parameters
    ----------
    sys : object
        The system.
    name : str
        The argument's name, used in error messages.

    Returns
    -------
    num, den : ndarray
        Numerator and monic denominator, highest power first.
    dt : float or None
        Sample time in s, or ``None`` for a continuous system.

    Examples
    --------
    >>> from piezohyst.signals.lti import scipy_transfer_function, siso_polynomials, state_space
    >>> num, den, dt = siso_polynomials(state_space([[-2.0]], [[1.0]], [[3.0]], [[0.0]]), "plant")
    >>> num.tolist(), den.tolist(), dt
    ([3.0], [1.0, 2.0], None)
    >>> siso_polynomials(scipy_transfer_function([2.0], [2.0, -1.0], dt=0.1), "plant")[1].tolist()
    [1.0, -0.5]
    """
    num, den, dt = _raw_polynomials(sys, name)
    if not (np.all(np.isfinite(num)) and np.all(np.isfinite(den))):
        raise ParameterError(
            f"{name} has non-finite coefficients: numerator {num.tolist()}, denominator {den.tolist()}"
        )
    scale = _frequency_scale(den, num, dt is not None)
    den = _trim(den, scale)
    if den.size == 1 and den[0] == 0.0:
        raise ParameterError(f"{name} has a zero denominator")
    num = _trim(num, scale)
    lead = float(den[0])
    return num / lead, den / lead, dt


def _snap_origin(roots: npt.NDArray[Any]) -> npt.NDArray[np.complex128]:
    """Roots that are rounding residues of zero (below 1e-12 of the largest, e.g. an integrator
    from slycot's realization at -9e-16) put at zero."""
    if roots.size == 0:
        return roots
    big = float(np.max(np.abs(roots)))
    return np.where(np.abs(roots) < 1e-12 * big, 0.0, roots).astype(np.complex128)


def _state_space_polynomials(
    a: FloatArray, b: FloatArray, c: FloatArray, d: FloatArray
) -> tuple[FloatArray, FloatArray] | None:
    """``(num, den)`` of a SISO state space from its poles, its zeros (the finite eigenvalues
    of the Rosenbrock pencil) and its first non-zero Markov parameter: on a stiff system (a
    stage: ``k / m ~ 1e9``) this keeps the digits that ``ss2tf``'s ``poly(A - B C) - poly(A)``
    cancels. ``None`` when the result does not reproduce the system's response (then the
    caller converts the usual way)."""
    from scipy.linalg import eigvals

    n = a.shape[0]
    if n == 0:
        return d[0].copy(), np.ones(1)
    poles = _snap_origin(np.linalg.eigvals(a))
    den = np.real(np.poly(poles))
    pencil = np.block([[a, b], [c, d]])
    mass = np.zeros((n + 1, n + 1))
    mass[:n, :n] = np.eye(n)
    with np.errstate(divide="ignore", invalid="ignore"):
        zeros = eigvals(pencil, mass)
    zeros = _snap_origin(zeros[np.isfinite(zeros)])
    r = n - zeros.size
    if r < 0:
        return None
    gain = float(d[0, 0]) if r == 0 else float((c @ np.linalg.matrix_power(a, r - 1) @ b)[0, 0])
    num = gain * np.real(np.poly(zeros)) if zeros.size else np.array([gain])
    # check: the polynomials give the state space's response at the system's frequencies
    scale = float(np.max(np.abs(poles))) if poles.size else 0.0
    scale = scale if scale > 0 else 1.0
    probe = scale * (1j * np.array([0.1, 0.7, 3.0]) + 0.05)
    exact = np.array([(c @ np.linalg.solve(s * np.eye(n) - a, b) + d)[0, 0] for s in probe])
    fitted = np.polyval(num, probe) / np.polyval(den, probe)
    if not np.all(np.abs(fitted - exact) <= 1e-8 * np.maximum(np.abs(exact), 1e-300)):
        return None
    return num, den


def _raw_polynomials(sys: object, name: str) -> tuple[FloatArray, FloatArray, float | None]:
    from scipy import signal

    if isinstance(sys, (signal.lti, signal.dlti)):
        dt_raw = getattr(sys, "dt", None)
        step = None if dt_raw is None else float(dt_raw)
        if isinstance(sys, signal.StateSpace) and sys.B.shape[1] == 1 and sys.C.shape[0] == 1:
            exact = _state_space_polynomials(*(np.asarray(m, dtype=np.float64) for m in (sys.A, sys.B, sys.C, sys.D)))
            if exact is not None:
                return exact[0], exact[1], step
        tf = sys.to_tf()
        num = np.atleast_2d(np.asarray(tf.num, dtype=np.float64))
        if num.shape[0] != 1:
            raise ParameterError(f"{name} has {num.shape[0]} outputs; a single-input single-output system is needed")
        return num[0], np.asarray(tf.den, dtype=np.float64), step
    try:
        ct = require_control()
    except ImportError:
        ct = None
    if ct is None or not isinstance(sys, ct.LTI):
        raise ParameterTypeError(
            f"{name} must be a python-control StateSpace/TransferFunction or a scipy.signal lti/dlti, "
            f"got {type(sys).__name__}"
        )
    if sys.ninputs != 1 or sys.noutputs != 1:
        raise ParameterError(
            f"{name} has {sys.ninputs} inputs and {sys.noutputs} outputs; a single-input single-output system is needed"
        )
    dt = sys.dt
    if dt is True:
        raise ParameterError(f"{name} is discrete without a sample time (dt=True); give it one (dt > 0)")
    if dt is None:  # python-control's "either": taken as continuous
        dt = 0
    step = None if dt == 0 else float(dt)
    if isinstance(sys, ct.StateSpace):
        exact = _state_space_polynomials(*(np.asarray(m, dtype=np.float64) for m in (sys.A, sys.B, sys.C, sys.D)))
        if exact is not None:
            return exact[0], exact[1], step
    tf = sys if isinstance(sys, ct.TransferFunction) else ct.tf(sys)
    num = np.asarray(tf.num[0][0], dtype=np.float64)
    den = np.asarray(tf.den[0][0], dtype=np.float64)
    return num, den, step
