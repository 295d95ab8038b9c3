"""MIMO stage models with hysteresis: a discrete state space with play operators in a feedback
path (a linear fractional representation, LFR), its simulation, initial state and file.

The model (sample rate ``fs``; matrices of a :class:`MimoModel`)::

    z[t]   = G x[t] + H u[t]                                 (nw feedback channels)
    w_i[t] = sum_j weights[i, j] * play(z_i[t]; thresholds[i, j])          (i < nw - nt)
    w_i[t] = sum_j weights[i, j] * r tanh(z_i[t] / r),  r = thresholds[i, j]  (the last nt)
    y[t]   = C x[t] + D u[t] + F w[t]
    x[t+1] = A x[t] + B u[t] + E w[t]

The last ``nt = static_channels`` feedback channels are static saturations (a smooth, odd,
saturating stiffness without memory; with ``G``, ``E``, ``F`` free they form a one-hidden-layer
network in the feedback path, the nonlinear LFR of the system-identification literature), the
others hysteretic (play operators).

``structure`` says which special case it is: ``"linear"`` (``nw = 0``), ``"hammerstein"``
(``z = u``: a bank of play operators per actuator ahead of the dynamics) or ``"lfr"`` (``z``
from the states: the hysteresis feeds back, so the resonances move with amplitude — the
counter-EMF idea of a single stage, generalized). Every loop over samples runs in Rust
(``_core.lfr_simulate``, records in parallel).

The model file is JSON (``kind: "mimo"``, :data:`MIMO_SCHEMA_VERSION`): dimensions, units,
the matrices as nested lists, the play thresholds and weights, how the initial state is set
(``init``) and the identification report (``fit``). :func:`load_mimo_model` reads it;
:func:`piezohyst.load_model` points to it.

Examples
--------
>>> import numpy as np
>>> from piezohyst.models.mimo import MimoModel
>>> m = MimoModel.linear(A=[[0.5]], B=[[1.0, 0.0]], C=[[1.0], [2.0]], D=np.zeros((2, 2)), fs=100.0)
>>> m.simulate(np.array([[1.0, 0.0], [0.0, 0.0], [0.0, 0.0]]), init="rest").tolist()
[[0.0, 0.0], [1.0, 2.0], [0.5, 1.0]]
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import _core
from .._io import PathLike, load_json_file
from ..errors import ParameterError
from ..outputs import write_atomic

__all__ = [
    "MIMO_KIND",
    "MIMO_SCHEMA_VERSION",
    "MimoModel",
    "is_mimo_description",
    "load_mimo_model",
    "mimo_from_dict",
]

FloatArray = NDArray[np.float64]

#: ``kind`` of a MIMO model file.
MIMO_KIND = "mimo"
#: The file format's version (``dims.nt``, the static channels, is optional: 0 when absent).
MIMO_SCHEMA_VERSION = 1

Structure = Literal["linear", "hammerstein", "lfr"]
InitMethod = Literal["periodic", "rest"]
_STRUCTURES = ("linear", "hammerstein", "lfr")
_MATRICES = ("A", "B", "C", "D", "E", "F", "G", "H")


def _matrix(v: ArrayLike, name: str, rows: int | None = None, cols: int | None = None) -> FloatArray:
    try:
        a = np.array(v, dtype=np.float64, copy=True)
    except (TypeError, ValueError) as e:
        raise ParameterError(f"{name} is not a matrix of numbers: {e}") from None
    if a.ndim != 2:
        if a.size == 0 and rows is not None and cols is not None:
            a = a.reshape(rows, cols)
        else:
            raise ParameterError(f"{name} must be a 2-D matrix, got shape {a.shape}")
    if (rows is not None and a.shape[0] != rows) or (cols is not None and a.shape[1] != cols):
        raise ParameterError(f"{name} has shape {a.shape}, expected ({rows}, {cols})")
    bad = np.argwhere(~np.isfinite(a))
    if bad.size:
        i, j = (int(k) for k in bad[0])
        raise ParameterError(f"{name}[{i}, {j}] = {a[i, j]} is not finite")
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class MimoModel:
    """A MIMO state space with play-operator feedback (see the module docstring).

    Build one with :meth:`linear`, :meth:`from_dict` or :func:`load_mimo_model`, or from
    :func:`piezohyst.identify.mimo.identify_mimo`. Units: inputs ``input_unit`` (V), outputs
    ``output_unit`` (m); the feedback signal ``z`` is in the model's own scale.

    Parameters
    ----------
    A, B, C, D : array_like
        The linear part: ``A`` ``(nx, nx)``, ``B`` ``(nx, nu)``, ``C`` ``(ny, nx)``, ``D`` ``(ny, nu)``.
    E, F : array_like
        How the feedback ``w`` enters the states ``(nx, nw)`` and the outputs ``(ny, nw)``.
    G, H : array_like
        The feedback signal ``z = G x + H u``: ``G`` ``(nw, nx)``, ``H`` ``(nw, nu)``.
    thresholds, weights : array_like
        The operators of each feedback channel, ``(nw, nr)``; thresholds ``>= 0`` (the scales
        ``r`` of a static channel: ``> 0``).
    fs : float
        Sample rate (Hz).
    structure : {"lfr", "hammerstein", "linear"}
        Which special case the model is (see the module docstring).
    static_channels : int
        The last ``static_channels`` feedback channels are static saturations (default 0).
    input_unit, output_unit : str
        Units of the inputs (default ``"V"``) and outputs (default ``"m"``).
    init : Mapping
        How :meth:`simulate` sets the initial state by default (``method``, ``periods``, ``ridge``).
    fit : Mapping
        The identification report.

    Examples
    --------
    A Hammerstein model: one input through two play operators into a first-order lag.

    >>> import numpy as np
    >>> from piezohyst.models.mimo import MimoModel
    >>> h = MimoModel(A=[[0.5]], B=[[1.0]], C=[[1.0]], D=[[0.0]], E=[[0.0]], F=[[1.0]], G=[[0.0]],
    ...               H=[[1.0]], thresholds=[[0.0, 0.5]], weights=[[1.0, 0.5]], fs=1000.0,
    ...               structure="hammerstein")
    >>> h
    MimoModel(structure='hammerstein', nx=1, nu=1, ny=1, nw=1, nr=2, fs=1000)
    >>> h.simulate(np.array([1.0, 2.0, 0.0]), init="rest").ravel().tolist()
    [1.25, 3.75, 2.75]
    """

    A: FloatArray
    B: FloatArray
    C: FloatArray
    D: FloatArray
    E: FloatArray
    F: FloatArray
    G: FloatArray
    H: FloatArray
    thresholds: FloatArray
    weights: FloatArray
    fs: float
    structure: Structure = "lfr"
    #: the last ``static_channels`` feedback channels are static saturations ``r tanh(z / r)``
    static_channels: int = 0
    input_unit: str = "V"
    output_unit: str = "m"
    #: How :meth:`simulate` sets the initial state by default: ``method`` (``periodic``: the
    #: input run ``periods`` times from rest first; ``rest``), and with measured outputs the
    #: least-squares correction of the linear states over them (``ridge``: its relative weight).
    init: Mapping[str, Any] = field(default_factory=lambda: {"method": "periodic", "periods": 2, "ridge": 1e-3})
    fit: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        a = _matrix(self.A, "A")
        nx = a.shape[0]
        if a.shape != (nx, nx):
            raise ParameterError(f"A must be square, got shape {a.shape}")
        b = _matrix(self.B, "B", nx)
        nu = b.shape[1]
        c = _matrix(self.C, "C", None, nx)
        ny = c.shape[0]
        g = _matrix(self.G, "G", None, nx)
        nw = g.shape[0]
        th = _matrix(self.thresholds, "thresholds", nw)
        nr = th.shape[1]
        mats = {
            "A": a,
            "B": b,
            "C": c,
            "D": _matrix(self.D, "D", ny, nu),
            "E": _matrix(self.E, "E", nx, nw),
            "F": _matrix(self.F, "F", ny, nw),
            "G": g,
            "H": _matrix(self.H, "H", nw, nu),
            "thresholds": th,
            "weights": _matrix(self.weights, "weights", nw, nr),
        }
        if (th < 0).any():
            i, j = (int(k) for k in np.argwhere(th < 0)[0])
            raise ParameterError(f"thresholds[{i}, {j}] = {th[i, j]} must be >= 0")
        nt = self.static_channels
        if type(nt) is not int or not 0 <= nt <= nw:
            raise ParameterError(f"static_channels = {nt!r} must be an integer in [0, nw = {nw}]")
        if nt and (th[nw - nt :] <= 0).any():
            i, j = (int(k) for k in np.argwhere(th[nw - nt :] <= 0)[0])
            raise ParameterError(
                f"thresholds[{nw - nt + i}, {j}] = {th[nw - nt + i, j]} (a static channel's scale) must be > 0"
            )
        for k, v in mats.items():
            object.__setattr__(self, k, v)
        fs = float(self.fs)
        if not (math.isfinite(fs) and fs > 0):
            raise ParameterError(f"fs = {self.fs} must be a finite sample rate > 0 (Hz)")
        object.__setattr__(self, "fs", fs)
        if self.structure not in _STRUCTURES:
            raise ParameterError(f"structure = {self.structure!r} is not one of {list(_STRUCTURES)}")
        method = self.init.get("method", "periodic")
        if method not in ("periodic", "rest"):
            raise ParameterError(f"init.method = {method!r} is not one of ['periodic', 'rest']")
        ridge = self.init.get("ridge", 1e-3)
        if isinstance(ridge, bool) or not (isinstance(ridge, (int, float)) and math.isfinite(ridge) and ridge > 0):
            raise ParameterError(f"init.ridge = {ridge!r} must be a finite number > 0")
        periods = self.init.get("periods", 2)
        if isinstance(periods, bool) or not (isinstance(periods, int) and periods >= 0):
            raise ParameterError(f"init.periods = {periods!r} must be an integer >= 0")

    # -- construction ---------------------------------------------------------------------
    @classmethod
    def linear(cls, A: ArrayLike, B: ArrayLike, C: ArrayLike, D: ArrayLike, fs: float, **kw: Any) -> MimoModel:
        """A linear model (no feedback channel): ``x+ = A x + B u``, ``y = C x + D u``.

        Parameters
        ----------
        A, B, C, D : array_like
            The state-space matrices ``(nx, nx)``, ``(nx, nu)``, ``(ny, nx)``, ``(ny, nu)``.
        fs : float
            Sample rate (Hz).
        **kw : Any
            Further fields of :class:`MimoModel` (``input_unit``, ``init``, ``fit``, ...).

        Returns
        -------
        MimoModel
            With ``structure="linear"`` and ``nw = 0``.

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst.models.mimo import MimoModel
        >>> m = MimoModel.linear(A=[[0.5]], B=[[1.0, 0.0]], C=[[1.0], [2.0]], D=np.zeros((2, 2)), fs=100.0)
        >>> (m.nx, m.nu, m.ny, m.nw, m.structure)
        (1, 2, 2, 0, 'linear')
        """
        a = _matrix(A, "A")
        b = _matrix(B, "B", a.shape[0])
        c = _matrix(C, "C", None, a.shape[0])
        nx, nu, ny = a.shape[0], b.shape[1], c.shape[0]
        z = np.zeros
        return cls(
            a, b, c, _matrix(D, "D", ny, nu), z((nx, 0)), z((ny, 0)), z((0, nx)), z((0, nu)), z((0, 0)), z((0, 0)),
            fs, "linear", **kw,
        )  # fmt: skip

    # -- dimensions -----------------------------------------------------------------------
    @property
    def nx(self) -> int:
        """States of the linear part."""
        return int(self.A.shape[0])

    @property
    def nu(self) -> int:
        """Inputs (actuators)."""
        return int(self.B.shape[1])

    @property
    def ny(self) -> int:
        """Outputs (sensors)."""
        return int(self.C.shape[0])

    @property
    def nw(self) -> int:
        """Feedback channels (each a bank of play operators)."""
        return int(self.G.shape[0])

    @property
    def state_len(self) -> int:
        """Length of the full state: ``nx`` linear states and ``nw * nr`` play outputs."""
        return self.nx + int(self.thresholds.size)

    # -- simulation -----------------------------------------------------------------------
    def _inputs(self, u: ArrayLike, name: str = "u") -> tuple[FloatArray, bool]:
        try:
            a = np.asarray(u, dtype=np.float64)
        except (TypeError, ValueError) as e:
            raise ParameterError(f"{name} is not an array of numbers: {e}") from None
        single = a.ndim == 2
        if a.ndim == 1 and self.nu == 1:
            a, single = a[:, None], True
        if single:
            a = a[None]
        if a.ndim != 3 or a.shape[2] != self.nu:
            raise ParameterError(
                f"{name} has shape {np.shape(u)}; expected (N, {self.nu}) (samples, inputs) or (R, N, {self.nu})"
            )
        if not np.isfinite(a).all():
            k = int(np.argmax(~np.isfinite(a.ravel())))
            raise ParameterError(f"{name} holds a value that is not finite (flat index {k})")
        return np.ascontiguousarray(a), single

    def run(self, u: ArrayLike, state: ArrayLike | None = None) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Simulate records ``u`` ``(R, N, nu)`` from ``state`` ``(R, state_len)`` (rest if
        ``None``): ``(y (R, N, ny), z (R, N, nw), final state (R, state_len))``.

        Parameters
        ----------
        u : array_like
            Inputs ``(R, N, nu)`` or one record ``(N, nu)``.
        state : array_like, optional
            The initial states ``(R, state_len)``; rest if ``None``.

        Returns
        -------
        y, z, state : numpy.ndarray
            Outputs ``(R, N, ny)``, feedback signals ``(R, N, nw)``, final states ``(R, state_len)``.

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst.models.mimo import MimoModel
        >>> m = MimoModel.linear(A=[[0.5]], B=[[1.0, 0.0]], C=[[1.0], [2.0]], D=np.zeros((2, 2)), fs=100.0)
        >>> y, z, st = m.run(np.array([[1.0, 0.0], [0.0, 0.0], [0.0, 0.0]]))
        >>> y.shape, z.shape, st.tolist()
        ((1, 3, 2), (1, 3, 0), [[0.25]])
        """
        uu, _ = self._inputs(u)
        r = uu.shape[0]
        s = np.zeros((r, self.state_len)) if state is None else np.array(state, dtype=np.float64, ndmin=2)
        if s.shape != (r, self.state_len):
            raise ParameterError(f"state has shape {s.shape}, expected ({r}, {self.state_len})")
        c = np.ascontiguousarray
        y, z, st = _core.lfr_simulate(
            c(self.A), c(self.B), c(self.C), c(self.D), c(self.E), c(self.F), c(self.G), c(self.H),
            c(self.thresholds), c(self.weights), uu, c(s), self.static_channels,
        )  # fmt: skip
        return y, z, st

    def periodic_state(self, u: ArrayLike, periods: int | None = None) -> FloatArray:
        """The state at the start of a period of the periodic input ``u`` ``(N, nu)`` or
        ``(R, N, nu)``: the input run ``periods`` times from rest (``init["periods"]``).

        Parameters
        ----------
        u : array_like
            One period of the input, ``(N, nu)`` or ``(R, N, nu)``.
        periods : int, optional
            How many periods to run from rest (default ``init["periods"]``).

        Returns
        -------
        numpy.ndarray
            The states ``(R, state_len)``.

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst.models.mimo import MimoModel
        >>> m = MimoModel.linear(A=[[0.5]], B=[[1.0, 0.0]], C=[[1.0], [2.0]], D=np.zeros((2, 2)), fs=100.0)
        >>> m.periodic_state(np.ones((4, 2)), periods=1).tolist()  # 1 + 0.5 + 0.25 + 0.125
        [[1.875]]
        """
        uu, _ = self._inputs(u)
        p = int(self.init.get("periods", 2)) if periods is None else int(periods)
        if p < 0:
            raise ParameterError(f"periods = {p} must be >= 0")
        st = np.zeros((uu.shape[0], self.state_len))
        for _ in range(p):
            _, _, st = self.run(uu, st)
        return st

    def estimate_state(self, u: ArrayLike, y0: ArrayLike, *, state: ArrayLike | None = None) -> FloatArray:
        """The initial state that best explains the measured outputs ``y0`` ``(M, ny)`` (the
        record's first ``M`` samples) given its input ``u`` ``(N, nu)``: starting from ``state``
        (default: :meth:`periodic_state` or rest, per ``init``), the linear states are corrected
        by least squares over ``y0`` (``C A^t dx`` for ``t < M``, the feedback held at its
        simulated value), ridge-regularized by ``init["ridge"]`` (relative to the norm of
        the observability rows).

        Parameters
        ----------
        u : array_like
            The record's input ``(N, nu)``.
        y0 : array_like
            Its first ``M`` measured outputs ``(M, ny)``, ``1 <= M <= N``.
        state : array_like, optional
            The state to correct ``(1, state_len)``; default per ``init``.

        Returns
        -------
        numpy.ndarray
            The corrected state ``(1, state_len)``.

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst.models.mimo import MimoModel
        >>> m = MimoModel.linear(A=[[0.5]], B=[[1.0, 0.0]], C=[[1.0], [2.0]], D=np.zeros((2, 2)), fs=100.0)
        >>> st = m.estimate_state(np.zeros((3, 2)), [[1.0, 2.0]], state=np.zeros((1, 1)))
        >>> round(float(st[0, 0]), 4)  # y = C x = [1, 2] for x = 1
        1.0
        """
        uu, single = self._inputs(u)
        if not single:
            raise ParameterError("estimate_state takes one record: u of shape (N, nu)")
        yy = np.asarray(y0, dtype=np.float64)
        if yy.ndim == 1 and self.ny == 1:
            yy = yy[:, None]
        if yy.ndim != 2 or yy.shape[1] != self.ny or yy.shape[0] < 1 or yy.shape[0] > uu.shape[1]:
            raise ParameterError(
                f"init output has shape {np.shape(y0)}; expected (M, {self.ny}) with 1 <= M <= {uu.shape[1]} "
                "(the record's first M measured outputs)"
            )
        if not np.isfinite(yy).all():
            raise ParameterError("init output holds a value that is not finite")
        if state is None:
            st = self.periodic_state(uu) if self.init.get("method", "periodic") == "periodic" else None
        else:
            st = np.array(state, dtype=np.float64, ndmin=2)
        if st is None:
            st = np.zeros((1, self.state_len))
        m = yy.shape[0]
        y_sim, _, _ = self.run(uu[:, :m], st)
        resid = (yy - y_sim[0]).ravel()
        # observability rows C A^t, t < m
        obs = np.empty((m, self.ny, self.nx))
        ca = self.C.copy()
        for t in range(m):  # m is the (short) stretch of outputs, not the record: a loop over ≤ m matrices
            obs[t] = ca
            ca = ca @ self.A
        o = obs.reshape(m * self.ny, self.nx)
        # ridge-regularized normal equations (a small solve: no SVD, whose threads stall a
        # loaded machine); the weight is relative to |O|_F^2, an upper bound of its largest
        # singular value squared
        ridge = float(self.init.get("ridge", 1e-3))
        gram = o.T @ o
        scale = float(np.trace(gram))
        if scale == 0:
            return st
        gram[np.diag_indices_from(gram)] += ridge**2 * scale
        dx = np.linalg.solve(gram, o.T @ resid)
        out = st.copy()
        out[0, : self.nx] += dx
        return out

    def simulate(
        self,
        u: ArrayLike,
        *,
        init: InitMethod | None = None,
        init_output: ArrayLike | None = None,
        state: ArrayLike | None = None,
    ) -> FloatArray:
        """The outputs ``(N, ny)`` for an input ``(N, nu)`` (or ``(R, N, ny)`` for ``(R, N, nu)``).

        The initial state: ``state`` if given; otherwise ``init`` (``"periodic"``: the input
        treated as one period of a periodic signal in steady state and run from rest
        ``init["periods"]`` times first; ``"rest"``; default the model's ``init["method"]``),
        corrected to fit ``init_output`` — the first measured outputs ``(M, ny)`` — if given
        (:meth:`estimate_state`; one record only).

        Parameters
        ----------
        u : array_like
            Inputs ``(N, nu)`` or ``(R, N, nu)``.
        init : {"periodic", "rest"}, optional
            How the initial state is set (default the model's ``init["method"]``).
        init_output : array_like, optional
            The first measured outputs ``(M, ny)`` the initial state is corrected to fit.
        state : array_like, optional
            The initial state itself ``(R, state_len)``.

        Returns
        -------
        numpy.ndarray
            Outputs ``(N, ny)`` (or ``(R, N, ny)``).

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst.models.mimo import MimoModel
        >>> m = MimoModel.linear(A=[[0.5]], B=[[1.0, 0.0]], C=[[1.0], [2.0]], D=np.zeros((2, 2)), fs=100.0)
        >>> m.simulate(np.array([[1.0, 0.0], [0.0, 0.0], [0.0, 0.0]]), init="rest").tolist()
        [[0.0, 0.0], [1.0, 2.0], [0.5, 1.0]]
        >>> m.simulate(np.zeros((3, 2)), init="rest", init_output=[[1.0, 2.0]]).round(3).tolist()
        [[1.0, 2.0], [0.5, 1.0], [0.25, 0.5]]
        """
        uu, single = self._inputs(u)
        method = init if init is not None else self.init.get("method", "periodic")
        if method not in ("periodic", "rest"):
            raise ParameterError(f"init = {method!r} is not one of ['periodic', 'rest']")
        if state is not None:
            st = np.array(state, dtype=np.float64, ndmin=2)
        elif method == "periodic":
            st = self.periodic_state(uu)
        else:
            st = np.zeros((uu.shape[0], self.state_len))
        if init_output is not None:
            if not single:
                raise ParameterError("init_output needs one record: u of shape (N, nu)")
            st = self.estimate_state(uu[0], init_output, state=st)
        y, _, _ = self.run(uu, st)
        return y[0] if single else y

    # -- linear part ----------------------------------------------------------------------
    def linear_part(self) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """``(A, B, C, D)`` of the dynamics with the feedback signal ``w`` held at zero.

        Returns
        -------
        tuple of numpy.ndarray
            ``(A, B, C, D)``.

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst.models.mimo import MimoModel
        >>> m = MimoModel.linear(A=[[0.5]], B=[[1.0, 0.0]], C=[[1.0], [2.0]], D=np.zeros((2, 2)), fs=100.0)
        >>> [a.shape for a in m.linear_part()]
        [(1, 1), (1, 2), (2, 1), (2, 2)]
        """
        return self.A, self.B, self.C, self.D

    def to_scipy(self) -> Any:
        """The linear part as :class:`scipy.signal.StateSpace` (discrete, ``dt = 1/fs``).

        Returns
        -------
        scipy.signal.StateSpace
            The discrete linear part.

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst.models.mimo import MimoModel
        >>> m = MimoModel.linear(A=[[0.5]], B=[[1.0, 0.0]], C=[[1.0], [2.0]], D=np.zeros((2, 2)), fs=100.0)
        >>> m.to_scipy().dt
        0.01
        """
        from scipy.signal import StateSpace

        return StateSpace(*self.linear_part(), dt=1.0 / self.fs)

    def to_control(self, *, continuous: bool = False) -> Any:
        """The linear part as a python-control ``StateSpace``: discrete (``dt = 1/fs``), or its
        zero-order-hold equivalent in continuous time (``continuous=True``, :meth:`continuous`).

        Parameters
        ----------
        continuous : bool
            Return the continuous-time equivalent instead of the discrete system.

        Returns
        -------
        control.StateSpace
            The linear part (needs the ``control`` package).

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst.models.mimo import MimoModel
        >>> m = MimoModel.linear(A=[[0.5]], B=[[1.0, 0.0]], C=[[1.0], [2.0]], D=np.zeros((2, 2)), fs=100.0)
        >>> sys = m.to_control()
        >>> (sys.nstates, sys.ninputs, sys.noutputs, sys.dt)
        (1, 2, 2, 0.01)
        """
        import control

        if continuous:
            return control.ss(*self.continuous())
        return control.ss(*self.linear_part(), 1.0 / self.fs)

    def continuous(self) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """``(Ac, Bc, C, D)``: the continuous system whose zero-order-hold discretization at
        ``1/fs`` is the linear part (matrix logarithm; refused for a pole on the negative real
        axis, which has no continuous equivalent).

        Returns
        -------
        tuple of numpy.ndarray
            ``(Ac, Bc, C, D)``.

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst.models.mimo import MimoModel
        >>> m = MimoModel.linear(A=[[0.5]], B=[[1.0, 0.0]], C=[[1.0], [2.0]], D=np.zeros((2, 2)), fs=100.0)
        >>> Ac, Bc, C, D = m.continuous()
        >>> round(float(Ac[0, 0]), 4)  # 100 Hz * ln(0.5)
        -69.3147
        """
        from scipy.linalg import logm

        ev = np.linalg.eigvals(self.A)
        if np.any((np.abs(ev.imag) < 1e-12) & (ev.real <= 0)):
            raise ParameterError("A has a pole on the negative real axis or at 0: no continuous equivalent")
        n, m = self.nx, self.nu
        big = np.zeros((n + m, n + m))
        big[:n, :n] = self.A
        big[:n, n:] = self.B
        big[n:, n:] = np.eye(m)
        lg = np.real(logm(big)) * self.fs
        return lg[:n, :n], lg[:n, n:], self.C.copy(), self.D.copy()

    def poles(self) -> FloatArray:
        """Frequencies (Hz) and damping ratios of the linear part's poles, ``(n, 2)``, by frequency.

        Returns
        -------
        numpy.ndarray
            One row ``(frequency, damping ratio)`` per pole (one of each complex pair).

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst.models.mimo import MimoModel
        >>> m = MimoModel.linear(A=[[0.5]], B=[[1.0, 0.0]], C=[[1.0], [2.0]], D=np.zeros((2, 2)), fs=100.0)
        >>> m.poles().round(3).tolist()  # a real pole: critically damped
        [[11.032, 1.0]]
        """
        ev = np.linalg.eigvals(self.A).astype(complex)
        s = np.log(ev) * self.fs
        f = np.abs(s) / (2 * np.pi)
        zeta = -s.real / np.maximum(np.abs(s), 1e-300)
        keep = ev.imag >= 0
        out = np.column_stack([f[keep], zeta[keep]])
        return np.asarray(out[np.argsort(out[:, 0])], dtype=np.float64)

    def frequency_response(self, freqs: ArrayLike) -> NDArray[np.complex128]:
        """The linear part's frequency response ``(K, ny, nu)`` at ``freqs`` (Hz).

        Parameters
        ----------
        freqs : array_like
            Frequencies (Hz), ``K`` of them.

        Returns
        -------
        numpy.ndarray
            Complex ``(K, ny, nu)``.

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst.models.mimo import MimoModel
        >>> m = MimoModel.linear(A=[[0.5]], B=[[1.0, 0.0]], C=[[1.0], [2.0]], D=np.zeros((2, 2)), fs=100.0)
        >>> m.frequency_response([0.0, 10.0]).shape
        (2, 2, 2)
        >>> m.frequency_response([0.0])[0].real.tolist()  # the static gain C (1 - A)^-1 B
        [[2.0, 0.0], [4.0, 0.0]]
        """
        f = np.asarray(freqs, dtype=np.float64)
        z = np.exp(2j * np.pi * f / self.fs)
        eye = np.eye(self.nx)
        res = np.linalg.solve(z[:, None, None] * eye - self.A, np.broadcast_to(self.B, (f.size, self.nx, self.nu)))
        return np.asarray(self.C @ res + self.D, dtype=np.complex128)

    # -- file -----------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """The model file's JSON object.

        Returns
        -------
        dict
            Read back by :func:`mimo_from_dict`.

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst.models.mimo import MimoModel
        >>> m = MimoModel.linear(A=[[0.5]], B=[[1.0, 0.0]], C=[[1.0], [2.0]], D=np.zeros((2, 2)), fs=100.0)
        >>> d = m.to_dict()
        >>> d["kind"], d["dims"]
        ('mimo', {'nx': 1, 'nu': 2, 'ny': 2, 'nw': 0, 'nr': 0, 'nt': 0})
        """
        return {
            "schema_version": MIMO_SCHEMA_VERSION,
            "kind": MIMO_KIND,
            "structure": self.structure,
            "fs": self.fs,
            "dims": {
                "nx": self.nx,
                "nu": self.nu,
                "ny": self.ny,
                "nw": self.nw,
                "nr": int(self.thresholds.shape[1]),
                "nt": self.static_channels,
            },
            "units": {"input": self.input_unit, "output": self.output_unit},
            "matrices": {k: getattr(self, k).tolist() for k in _MATRICES},
            "thresholds": self.thresholds.tolist(),
            "weights": self.weights.tolist(),
            "init": dict(self.init),
            "fit": dict(self.fit),
        }

    def to_json(self) -> str:
        """:meth:`to_dict` as JSON text.

        Returns
        -------
        str
            The JSON text, one line ending in a newline.

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst.models.mimo import MimoModel
        >>> m = MimoModel.linear(A=[[0.5]], B=[[1.0, 0.0]], C=[[1.0], [2.0]], D=np.zeros((2, 2)), fs=100.0)
        >>> import json
        >>> json.loads(m.to_json())["structure"]
        'linear'
        """
        return json.dumps(self.to_dict(), allow_nan=False) + "\n"

    def save(self, path: PathLike, *, overwrite: bool = False) -> Path:
        """Write the model file (JSON) atomically; an existing file is kept unless ``overwrite``.

        Parameters
        ----------
        path : str or os.PathLike
            The file to write.
        overwrite : bool
            Replace an existing file.

        Returns
        -------
        pathlib.Path
            The file written.

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst.models.mimo import MimoModel
        >>> m = MimoModel.linear(A=[[0.5]], B=[[1.0, 0.0]], C=[[1.0], [2.0]], D=np.zeros((2, 2)), fs=100.0)
        >>> import tempfile, pathlib
        >>> from piezohyst.models.mimo import load_mimo_model
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     path = m.save(pathlib.Path(tmp) / "mirror.json")
        ...     back = load_mimo_model(path)
        >>> bool(np.array_equal(back.C, m.C)), back.fs
        (True, 100.0)
        """
        return write_atomic(path, self.to_json(), overwrite=overwrite)

    def with_fit(self, fit: Mapping[str, Any]) -> MimoModel:
        """A copy with the identification report ``fit``.

        Parameters
        ----------
        fit : Mapping
            The identification report.

        Returns
        -------
        MimoModel
            The same model with ``fit`` replaced.

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst.models.mimo import MimoModel
        >>> m = MimoModel.linear(A=[[0.5]], B=[[1.0, 0.0]], C=[[1.0], [2.0]], D=np.zeros((2, 2)), fs=100.0)
        >>> dict(m.with_fit({"rmse": 0.1}).fit), dict(m.fit)
        ({'rmse': 0.1}, {})
        """
        return replace(self, fit=dict(fit))

    def __repr__(self) -> str:
        return (
            f"MimoModel(structure={self.structure!r}, nx={self.nx}, nu={self.nu}, ny={self.ny}, nw={self.nw}, "
            f"nr={self.thresholds.shape[1]}, "
            + (f"static_channels={self.static_channels}, " if self.static_channels else "")
            + f"fs={self.fs:g})"
        )


def _dims_of(nx: int, nu: int, ny: int, nw: int, nr: int) -> dict[str, tuple[int, int]]:
    return {
        "A": (nx, nx),
        "B": (nx, nu),
        "C": (ny, nx),
        "D": (ny, nu),
        "E": (nx, nw),
        "F": (ny, nw),
        "G": (nw, nx),
        "H": (nw, nu),
    }


def mimo_from_dict(d: Any) -> MimoModel:
    """Rebuild a :class:`MimoModel` from :meth:`MimoModel.to_dict` output (a model file's
    JSON object); ``ParameterError`` naming the field otherwise.

    Parameters
    ----------
    d : dict
        The model file's JSON object.

    Returns
    -------
    MimoModel
        The model.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.models.mimo import MimoModel, mimo_from_dict
    >>> m = MimoModel.linear(A=[[0.5]], B=[[1.0, 0.0]], C=[[1.0], [2.0]], D=np.zeros((2, 2)), fs=100.0)
    >>> back = mimo_from_dict(m.to_dict())
    >>> back.to_dict() == m.to_dict()
    True
    """
    if not isinstance(d, dict):
        raise ParameterError(f"a MIMO model description must be a JSON object, got {type(d).__name__}")
    if d.get("kind") != MIMO_KIND:
        raise ParameterError(f"kind = {d.get('kind')!r} is not a MIMO model (expected {MIMO_KIND!r})")
    v = d.get("schema_version")
    if type(v) is not int or v != MIMO_SCHEMA_VERSION:
        raise ParameterError(f"schema_version = {v!r} is not supported (this version reads {MIMO_SCHEMA_VERSION})")
    dims = d["dims"]
    nx, nu, ny, nw, nr = (int(dims[k]) for k in ("nx", "nu", "ny", "nw", "nr"))
    nt = dims.get("nt", 0)
    shapes = _dims_of(nx, nu, ny, nw, nr)
    mats = {k: _matrix(d["matrices"][k], f"matrices.{k}", *shapes[k]) for k in _MATRICES}
    units = d.get("units", {})
    return MimoModel(
        **mats,
        thresholds=_matrix(d["thresholds"], "thresholds", nw, nr),
        weights=_matrix(d["weights"], "weights", nw, nr),
        fs=float(d["fs"]),
        structure=d.get("structure", "lfr"),
        static_channels=nt,
        input_unit=str(units.get("input", "V")),
        output_unit=str(units.get("output", "m")),
        init=dict(d.get("init", {})),
        fit=dict(d.get("fit", {})),
    )


def load_mimo_model(path: PathLike) -> MimoModel:
    """Read a MIMO model file (written by :meth:`MimoModel.save` or ``piezohyst identify`` on
    multi-channel data); ``DataError`` naming the file if it is not one.

    Parameters
    ----------
    path : str or os.PathLike
        The model file.

    Returns
    -------
    MimoModel
        The model.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> import numpy as np
    >>> from piezohyst.models.mimo import MimoModel, load_mimo_model
    >>> m = MimoModel.linear(A=[[0.5]], B=[[1.0, 0.0]], C=[[1.0], [2.0]], D=np.zeros((2, 2)), fs=100.0)
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     back = load_mimo_model(m.save(pathlib.Path(tmp) / "m.json"))
    >>> back.simulate(np.ones((2, 2)), init="rest").tolist() == m.simulate(np.ones((2, 2)), init="rest").tolist()
    True
    """
    return load_json_file(path, "MIMO model file", mimo_from_dict)


def is_mimo_description(d: object) -> bool:
    """Whether a parsed model file is a MIMO model's (``kind: "mimo"``).

    Parameters
    ----------
    d : object
        A parsed model file (any JSON value).

    Returns
    -------
    bool
        ``True`` for a MIMO model's JSON object.

    Examples
    --------
    >>> from piezohyst.models.mimo import is_mimo_description
    >>> is_mimo_description({"kind": "mimo"}), is_mimo_description({"kind": "pi"}), is_mimo_description([])
    (True, False, False)
    """
    return isinstance(d, dict) and d.get("kind") == MIMO_KIND
