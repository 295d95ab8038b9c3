"""MIMO feedforward: a per-actuator hysteresis inverse behind a model-based inversion of the
linear dynamics within a bandwidth, for stages with several actuators and sensors (issue 15).

The model is a Hammerstein chain per actuator: ``v_i -> H_i -> w_i`` (a hysteresis model per
input, V -> the linear part's input), then the linear MIMO dynamics ``w -> y`` (a discrete state
space ``A, B, C, D`` at ``fs``). For a periodic reference ``r`` (``N`` samples, ``ny`` outputs)
:class:`MimoFeedforward` computes

1. the linear part's regularized least-squares inverse over the reference, bin by bin of its
   spectrum: ``W(f) = (G^H G + lambda s^2 I)^{-1} G^H R(f)`` for ``f`` up to ``bandwidth`` (a
   raised-cosine taper over its last 20 %), zero above — a preview inversion over the whole
   period, stable whatever the zeros of ``G`` (non-minimum-phase included), with
   ``lambda`` bounding the gain where ``G`` is weaker than its static gain in every direction
   (``s`` is ``G(0)``'s smallest singular value);
2. each actuator's command through the exact inverse of its hysteresis model,
   ``v_i = H_i^{-1}(w_i)`` (the Rust per-sample inverse).

The helpers :func:`periodic_response` (the steady-state response of the linear part to a
periodic input, by FFT) and :func:`mirror_matrix` (tip/tilt/piston from three displacement
sensors) serve the virtual mirror of the examples.

Examples
--------
>>> import numpy as np
>>> from piezohyst.control.mimo import MimoFeedforward, periodic_response
>>> A = np.diag([0.9, 0.8]); B = np.eye(2); C = np.array([[0.1, 0.02], [0.0, 0.2]]); D = np.zeros((2, 2))
>>> ff = MimoFeedforward(A, B, C, D, fs=1000.0, bandwidth=200.0)
>>> t = np.arange(1000) / 1000.0
>>> r = np.column_stack([np.sin(2 * np.pi * 5 * t), np.cos(2 * np.pi * 7 * t)])
>>> w = ff.linear_command(r)
>>> y = periodic_response(A, B, C, D, w)
>>> bool(np.max(np.abs(y - r)) < 1e-3)
True
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from .._validate import as_int, as_scalar
from ..errors import ParameterError, ParameterTypeError

if TYPE_CHECKING:
    from ..models.model import HysteresisModel

FloatArray = npt.NDArray[np.float64]
ComplexArray = npt.NDArray[np.complex128]

__all__ = ["MimoFeedforward", "frequency_response", "mirror_matrix", "periodic_response"]


def _matrices(A: object, B: object, C: object, D: object) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    out = []
    for name, m in (("A", A), ("B", B), ("C", C), ("D", D)):
        try:
            kind = "U" if isinstance(m, (str, bytes)) else np.asarray(m).dtype.kind
            if kind in "cUS":
                raise TypeError(f"got dtype {np.asarray(m).dtype}")
            a = np.array(m, dtype=np.float64, copy=True)
        except (TypeError, ValueError) as e:
            raise ParameterTypeError(f"{name} must be a matrix of numbers: {e}") from None
        if a.ndim != 2:
            raise ParameterError(f"{name} must be 2-D, got shape {a.shape}")
        if not np.all(np.isfinite(a)):
            i, j = (int(k) for k in np.argwhere(~np.isfinite(a))[0])
            raise ParameterError(f"{name}[{i}, {j}] = {a[i, j]} is not finite")
        a.flags.writeable = False
        out.append(a)
    a_, b_, c_, d_ = out
    nx = a_.shape[0]
    if a_.shape != (nx, nx):
        raise ParameterError(f"A has shape {a_.shape}: it must be square")
    if b_.shape[0] != nx or c_.shape[1] != nx or d_.shape != (c_.shape[0], b_.shape[1]):
        raise ParameterError(
            f"A {a_.shape}, B {b_.shape}, C {c_.shape}, D {d_.shape} do not fit: expected A (nx, nx), "
            "B (nx, nu), C (ny, nx), D (ny, nu)"
        )
    return a_, b_, c_, d_


def frequency_response(
    A: npt.ArrayLike, B: npt.ArrayLike, C: npt.ArrayLike, D: npt.ArrayLike, f: npt.ArrayLike, fs: float
) -> ComplexArray:
    """The frequency response ``G(f) = C (z I - A)^{-1} B + D``, ``z = exp(2j pi f / fs)``, of a
    discrete state space, shape ``(len(f), ny, nu)``.

    Parameters
    ----------
    A, B, C, D : array_like
        The state-space matrices (``nx x nx``, ``nx x nu``, ``ny x nx``, ``ny x nu``).
    f : array_like
        Frequencies, Hz.
    fs : float
        Sample rate, Hz.

    Returns
    -------
    ndarray, complex, shape (F, ny, nu)

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.control.mimo import frequency_response
    >>> g = frequency_response([[0.5]], [[1.0]], [[0.5]], [[0.0]], [0.0], fs=1.0)
    >>> complex(g[0, 0, 0])   # 0.5 / (1 - 0.5)
    (1+0j)
    """
    a, b, c, d = _matrices(A, B, C, D)
    rate = as_scalar(fs, "fs", positive=True)
    freqs = np.atleast_1d(np.asarray(f, dtype=np.float64))
    z = np.exp(2j * np.pi * freqs / rate)
    nx = a.shape[0]
    if nx == 0:
        return np.broadcast_to(d.astype(np.complex128), (freqs.size, *d.shape)).copy()
    # diagonalize once when A is diagonalizable and well conditioned, else solve per frequency
    lam, v = np.linalg.eig(a)
    if np.linalg.cond(v) < 1e8:
        cb = c @ v
        vb = np.linalg.solve(v, b)
        g = (cb[None, :, :] * (1.0 / (z[:, None] - lam[None, :]))[:, None, :]) @ vb
    else:
        m = z[:, None, None] * np.eye(nx)[None] - a[None]
        g = c[None] @ np.linalg.solve(m, np.broadcast_to(b, (freqs.size, *b.shape)))
    return np.asarray(g + d[None], dtype=np.complex128)


def periodic_response(
    A: npt.ArrayLike, B: npt.ArrayLike, C: npt.ArrayLike, D: npt.ArrayLike, w: npt.ArrayLike
) -> FloatArray:
    """The periodic steady-state output ``(N, ny)`` of a discrete state space driven by the
    periodic input ``w`` ``(N, nu)`` (one period): ``irfft(G(f) W(f))``, exact for a stable
    system in steady state.

    Parameters
    ----------
    A, B, C, D : array_like
        The state-space matrices.
    w : array_like
        One period of the input, ``(N, nu)``.

    Returns
    -------
    ndarray, shape (N, ny)

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.control.mimo import periodic_response
    >>> y = periodic_response([[0.5]], [[1.0]], [[0.5]], [[0.0]], np.ones((8, 1)))
    >>> np.round(y.ravel(), 12).tolist()   # the DC gain, 1
    [1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0]
    """
    a, b, c, d = _matrices(A, B, C, D)
    x = _signal(w, "w", b.shape[1])
    n = x.shape[0]
    g = frequency_response(a, b, c, d, np.fft.rfftfreq(n), 1.0)
    spec = np.einsum("fij,fj->fi", g, np.fft.rfft(x, axis=0))
    return np.asarray(np.fft.irfft(spec, n=n, axis=0), dtype=np.float64)


def _signal(x: object, name: str, channels: int) -> FloatArray:
    try:
        kind = "U" if isinstance(x, (str, bytes)) else np.asarray(x).dtype.kind
        if kind in "cUS":
            raise TypeError(f"got dtype {np.asarray(x).dtype}")
        a = np.array(x, dtype=np.float64, copy=True)
    except (TypeError, ValueError) as e:
        raise ParameterTypeError(f"{name} must be an array of numbers: {e}") from None
    if a.ndim == 1 and channels == 1:
        a = a.reshape(-1, 1)
    if a.ndim != 2 or a.shape[1] != channels:
        raise ParameterError(f"{name} has shape {a.shape}, expected (N, {channels})")
    if a.shape[0] < 2:
        raise ParameterError(f"{name} has {a.shape[0]} samples, at least 2 needed")
    if not np.all(np.isfinite(a)):
        i, j = (int(k) for k in np.argwhere(~np.isfinite(a))[0])
        raise ParameterError(f"{name}[{i}, {j}] = {a[i, j]} is not finite")
    return a


def mirror_matrix(radius: float = 1.0, angles_deg: Sequence[float] = (90.0, 210.0, 330.0)) -> FloatArray:
    """The 3 x 3 map from a mirror's (piston, tip, tilt) to three displacement sensors at
    ``radius`` and ``angles_deg`` around its centre: ``y_i = piston + radius (tip sin a_i -
    tilt cos a_i)`` (tip about the x axis, tilt about the y axis, small angles in rad). Its
    inverse gives (piston, tip, tilt) from the sensors.

    Parameters
    ----------
    radius : float
        Sensor distance from the centre, m.
    angles_deg : sequence of 3 float
        The sensors' angular positions, degrees (distinct, not all on one line through the centre).

    Returns
    -------
    ndarray, shape (3, 3)

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.control.mimo import mirror_matrix
    >>> M = mirror_matrix(0.01)
    >>> ptt = np.linalg.solve(M, M @ [1e-6, 2e-4, -1e-4])   # piston m, tip rad, tilt rad
    >>> np.allclose(ptt, [1e-6, 2e-4, -1e-4])
    True
    """
    r = as_scalar(radius, "radius", positive=True)
    if not 1e-9 <= r <= 1e3:
        raise ParameterError(f"radius = {r:g} m is not a mirror's sensor radius (1e-9 .. 1e3 m)")
    ang = np.asarray(angles_deg, dtype=np.float64)
    if ang.shape != (3,) or not np.all(np.isfinite(ang)):
        raise ParameterError(f"angles_deg = {list(np.ravel(angles_deg))!r} must be 3 finite angles in degrees")
    a = np.deg2rad(ang)
    m = np.column_stack([np.ones(3), r * np.sin(a), -r * np.cos(a)])
    if np.linalg.cond(m) > 1e8:
        raise ParameterError(f"angles_deg = {ang.tolist()!r}: the sensors cannot tell tip from tilt (collinear)")
    return m


@dataclasses.dataclass(frozen=True, eq=False)
class MimoFeedforward:
    """Feedforward for a MIMO stage: the least-squares inverse of the linear dynamics within
    ``bandwidth`` over a periodic reference, then each actuator's hysteresis inverse.

    Parameters
    ----------
    A, B, C, D : array_like
        The linear part, a discrete state space at ``fs`` from the hysteresis outputs ``w``
        (``nu``) to the sensors (``ny``, m).
    fs : float
        Sample rate, Hz.
    hysteresis : sequence of HysteresisModel or None
        One invertible hysteresis model per actuator (V -> ``w``), or empty: the linear
        inverse alone (``v = w``).
    bandwidth : float, optional
        Inversion bandwidth, Hz (default ``fs / 4``); the reference's content above it is not
        followed (a raised-cosine taper over the last 20 % below it).
    regularization : float
        ``lambda``, relative to ``G(0)``'s smallest singular value squared (default 1e-4: a
        relative error of about 1e-4 in the static gain's weakest direction).

    Examples
    --------
    >>> import numpy as np
    >>> import piezohyst as ph
    >>> from piezohyst.control.mimo import MimoFeedforward, periodic_response
    >>> A = np.array([[0.95]]); B = np.array([[1.0]]); C = np.array([[0.05e-6]]); D = np.zeros((1, 1))
    >>> pi = ph.PI([0.0, 0.05, 0.1], [1.0, 0.3, 0.2])
    >>> ff = MimoFeedforward(A, B, C, D, fs=1e3, hysteresis=[pi], bandwidth=100.0)
    >>> t = np.arange(500) / 1e3
    >>> r = 0.2e-6 * (1 - np.cos(2 * np.pi * 4 * t))[:, None]     # m
    >>> v = ff.command(r, periods=2)                              # V, two periods
    >>> w = pi.simulate(v[:, 0])[500:, None]                      # the second period
    >>> bool(np.max(np.abs(periodic_response(A, B, C, D, w) - r)) < 0.01 * 0.4e-6)
    True
    """

    A: FloatArray
    B: FloatArray
    C: FloatArray
    D: FloatArray
    fs: float
    hysteresis: Sequence[HysteresisModel | None] = ()
    bandwidth: float | None = None
    regularization: float = 1e-4

    def __post_init__(self) -> None:
        a, b, c, d = _matrices(self.A, self.B, self.C, self.D)
        for name, m in (("A", a), ("B", b), ("C", c), ("D", d)):
            object.__setattr__(self, name, m)
        fs = as_scalar(self.fs, "fs", positive=True)
        object.__setattr__(self, "fs", fs)
        if np.max(np.abs(np.linalg.eigvals(a)), initial=0.0) >= 1.0:
            raise ParameterError("A has an eigenvalue on or outside the unit circle: the linear part is not stable")
        bw = fs / 4 if self.bandwidth is None else as_scalar(self.bandwidth, "bandwidth", positive=True)
        if bw > fs / 2:
            raise ParameterError(f"bandwidth = {bw:g} Hz is above the Nyquist frequency {fs / 2:g} Hz")
        object.__setattr__(self, "bandwidth", bw)
        object.__setattr__(self, "regularization", as_scalar(self.regularization, "regularization", positive=True))
        hyst: Any = self.hysteresis
        if isinstance(hyst, (str, bytes)) or not isinstance(hyst, Sequence):
            raise ParameterTypeError(f"hysteresis must be a sequence of models (one per input), got {hyst!r}")
        hyst = tuple(hyst)
        if hyst and len(hyst) != b.shape[1]:
            raise ParameterError(f"hysteresis has {len(hyst)} models, the linear part has {b.shape[1]} inputs")
        for i, h in enumerate(hyst):
            if h is not None and not callable(getattr(h, "inverse", None)):
                raise ParameterTypeError(f"hysteresis[{i}] must be an invertible hysteresis model, got {h!r}")
        object.__setattr__(self, "hysteresis", hyst)

    @classmethod
    def from_model(
        cls,
        model: Any,
        *,
        bandwidth: float | None = None,
        regularization: float = 1e-4,
        amplitude: npt.ArrayLike | None = None,
    ) -> MimoFeedforward:
        """The feedforward of a MIMO model with play operators in a feedback path
        (:class:`piezohyst.models.mimo.MimoModel`: ``z = G x + H u``, ``w = plays(z)``,
        ``y = C x + D u + F w``, ``x+ = A x + B u + E w``): its linear part with each feedback
        channel's plays replaced by their equivalent gain ``k_i = sum_j weights_ij (1 -
        r_ij / a_i)_+`` at the amplitude ``a_i`` of ``z_i`` (the large-signal slope ``sum_j
        weights_ij`` when ``amplitude`` is not given) — the loop closed through ``K``:
        ``A + E K G``, ``B + E K H``, ``C + F K G``, ``D + F K H``. :meth:`iterate` with the
        model's own simulation then inverts the hysteresis the gains leave out.

        A Hammerstein cascade — ``G = 0``, ``H = I``, ``[E; F] = [B; D] diag(c)`` (the plays of
        actuator ``i`` add ``c_i w_i`` to its input) — is split exactly instead: the linear
        part ``A, B, C, D`` and per actuator the PI model ``v -> v + c_i sum_j weights_ij
        play_{r_ij}(v)``, whose exact inverse :meth:`command` applies.

        Parameters
        ----------
        model : MimoModel
            The identified model (or any object with the matrices ``A..H``, ``thresholds``,
            ``weights`` and ``fs``).
        bandwidth : float, optional
            As the constructor.
        regularization : float
            As the constructor.
        amplitude : array_like, optional
            Amplitude of each feedback signal ``z_i`` (``nw`` values, the model's scale), for
            the equivalent gains.

        Returns
        -------
        MimoFeedforward

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst.models.mimo import MimoModel
        >>> from piezohyst.control.mimo import MimoFeedforward
        >>> kw = dict(A=[[0.5]], B=[[1.0]], C=[[1.0]], D=[[0.0]], F=[[0.0]], thresholds=[[0.0, 0.1]],
        ...           weights=[[0.2, 0.3]], fs=100.0)
        >>> lfr = MimoModel(E=[[-0.1]], G=[[1.0]], H=[[0.0]], structure="lfr", **kw)
        >>> MimoFeedforward.from_model(lfr).A.tolist()      # A + E (0.2 + 0.3) G
        [[0.45]]
        >>> cascade = MimoModel(E=[[1.0]], G=[[0.0]], H=[[1.0]], structure="hammerstein", **kw)
        >>> ff = MimoFeedforward.from_model(cascade)
        >>> ff.B.tolist(), ff.hysteresis[0]                 # the plays inverted per actuator
        ([[1.0]], PI(thresholds=[0.0, 0.1], weights=[0.2, 0.3], p0=1))
        """
        try:
            mats = {k: np.asarray(getattr(model, k), dtype=np.float64) for k in "ABCDEFGH"}
            th = np.asarray(model.thresholds, dtype=np.float64)
            wt = np.asarray(model.weights, dtype=np.float64)
            fs = float(model.fs)
        except (AttributeError, TypeError, ValueError) as e:
            raise ParameterTypeError(
                f"model must be a MIMO model with matrices A..H, thresholds, weights, fs: {e}"
            ) from None
        nw = mats["G"].shape[0]
        if amplitude is None:
            k = wt.sum(axis=1) if wt.size else np.zeros(nw)
        else:
            a = np.asarray(amplitude, dtype=np.float64).reshape(-1)
            if a.shape != (nw,) or not np.all(np.isfinite(a)) or np.any(a <= 0):
                raise ParameterError(
                    f"amplitude must be {nw} finite values > 0 (one per feedback channel), got {a.tolist()}"
                )
            k = (wt * np.clip(1.0 - th / a[:, None], 0.0, None)).sum(axis=1) if wt.size else np.zeros(nw)
        pis = _cascade(mats, th, wt)
        if pis is not None:  # plays per actuator ahead of the dynamics: invert them exactly
            return cls(mats["A"], mats["B"], mats["C"], mats["D"], fs, pis, bandwidth, regularization)
        ek, fk = mats["E"] * k[None, :], mats["F"] * k[None, :]
        return cls(
            mats["A"] + ek @ mats["G"],
            mats["B"] + ek @ mats["H"],
            mats["C"] + fk @ mats["G"],
            mats["D"] + fk @ mats["H"],
            fs,
            bandwidth=bandwidth,
            regularization=regularization,
        )

    @property
    def n_inputs(self) -> int:
        """Actuators, ``nu``."""
        return int(self.B.shape[1])

    @property
    def n_outputs(self) -> int:
        """Sensors, ``ny``."""
        return int(self.C.shape[0])

    def linear_command(self, reference: npt.ArrayLike) -> FloatArray:
        """The linear part's input ``w`` ``(N, nu)`` whose periodic steady-state output follows
        ``reference`` ``(N, ny)`` (one period) in least squares within the bandwidth.

        Parameters
        ----------
        reference : array_like, shape (N, ny)
            One period of the desired sensor outputs, m.

        Returns
        -------
        ndarray, shape (N, nu)

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst.control.mimo import MimoFeedforward
        >>> ff = MimoFeedforward([[0.5]], [[1.0]], [[0.5]], [[0.0]], fs=100.0)
        >>> np.round(ff.linear_command(np.full((4, 1), 2.0)).ravel(), 3).tolist()   # DC gain 1
        [2.0, 2.0, 2.0, 2.0]
        """
        r = _signal(reference, "reference", self.n_outputs)
        n = r.shape[0]
        f = np.fft.rfftfreq(n, 1.0 / self.fs)
        bw = float(self.bandwidth)  # type: ignore[arg-type]
        keep = f <= bw
        gh, lhs = self._normal_equations(n, np.asarray(f[keep], dtype=np.float64))
        rhs = gh @ np.fft.rfft(r, axis=0)[keep][:, :, None]
        w_spec = np.zeros((f.size, self.n_inputs), dtype=np.complex128)
        w_spec[keep] = np.linalg.solve(lhs, rhs)[:, :, 0]
        edge = 0.8 * bw
        taper = np.where(f <= edge, 1.0, 0.5 * (1 + np.cos(np.pi * np.clip((f - edge) / (bw - edge), 0, 1))))
        w_spec *= taper[:, None]
        return np.asarray(np.fft.irfft(w_spec, n=n, axis=0), dtype=np.float64)

    def _normal_equations(self, n: int, f: FloatArray) -> tuple[ComplexArray, ComplexArray]:
        """``G^H`` and ``G^H G + lambda s^2 I`` at the bins ``f`` of an ``n``-sample period,
        computed once per ``n`` (:meth:`iterate` calls :meth:`linear_command` repeatedly)."""
        cache: dict[int, tuple[ComplexArray, ComplexArray]] = self.__dict__.setdefault("_cache", {})
        if n not in cache:
            g = frequency_response(self.A, self.B, self.C, self.D, f, self.fs)
            g0 = frequency_response(self.A, self.B, self.C, self.D, [0.0], self.fs)[0]
            s2 = float(np.linalg.svd(g0, compute_uv=False)[-1]) ** 2
            gh = np.conj(np.swapaxes(g, 1, 2))
            cache[n] = (gh, gh @ g + self.regularization * s2 * np.eye(self.n_inputs)[None])
        return cache[n]

    def command(self, reference: npt.ArrayLike, periods: int = 2) -> FloatArray:
        """The actuator voltages ``(periods * N, nu)`` for ``periods`` repetitions of the periodic
        ``reference`` ``(N, ny)``: the linear inverse, then each actuator's hysteresis inverse run
        from its relaxed state over every period (the first period carries its transient).

        Parameters
        ----------
        reference : array_like, shape (N, ny)
            One period of the desired sensor outputs, m.
        periods : int
            Periods of the command, >= 1.

        Returns
        -------
        ndarray, shape (periods * N, nu)

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst.control.mimo import MimoFeedforward
        >>> ff = MimoFeedforward([[0.5]], [[1.0]], [[0.5]], [[0.0]], fs=100.0)
        >>> ff.command(np.full((4, 1), 2.0), periods=3).shape
        (12, 1)
        """
        p = as_int(periods, "periods", minimum=1)
        w = np.tile(self.linear_command(reference), (p, 1))
        if not self.hysteresis:
            return w
        v = np.empty_like(w)
        for i, h in enumerate(self.hysteresis):  # one Rust call per actuator
            v[:, i] = w[:, i] if h is None else h.inverse().simulate(w[:, i])
        return v

    def iterate(
        self,
        simulate: Callable[[FloatArray], FloatArray],
        reference: npt.ArrayLike,
        *,
        iterations: int = 5,
        periods: int = 2,
        gain: float = 1.0,
    ) -> tuple[FloatArray, FloatArray]:
        """Model-based inversion of a nonlinear MIMO model by iteration on its simulation: start
        from :meth:`command` and correct the command by the linear inverse of the remaining error
        of the model's periodic steady state, ``u += gain * linear_command(r - y_model(u))``.
        With hysteresis inside the dynamics (an LFR model), this inverts what the per-actuator
        inverse cannot.

        Parameters
        ----------
        simulate : callable
            The model: ``simulate(u)`` with ``u`` ``(periods * N, nu)`` returns ``(periods * N, ny)``
            (from the model's rest state; its last period is taken as the steady state).
        reference : array_like, shape (N, ny)
            One period of the desired outputs, m.
        iterations : int
            Corrections, >= 0.
        periods : int
            Periods simulated per evaluation, >= 2.
        gain : float
            Learning gain, in (0, 2).

        Returns
        -------
        command : ndarray, shape (N, nu)
            One period of the command (apply it periodically): the iterate with the smallest
            model error (an iteration that overshoots is not kept).
        errors : ndarray, shape (iterations + 1,)
            The RMS model error of the last period after each step, m.

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst.control.mimo import MimoFeedforward, periodic_response
        >>> A, B, C, D = [[0.5]], [[1.0]], [[0.5]], [[0.0]]
        >>> ff = MimoFeedforward(A, B, C, D, fs=100.0)
        >>> plant = lambda u: periodic_response(A, B, C, D, u) + 0.1 * np.tanh(u)   # unmodelled
        >>> r = np.sin(2 * np.pi * np.arange(50) / 50)[:, None]
        >>> u, err = ff.iterate(plant, r, iterations=6, periods=1)
        >>> bool(err[-1] < 1e-3 * err[0])
        True
        """
        r = _signal(reference, "reference", self.n_outputs)
        k = as_int(iterations, "iterations", minimum=0)
        p = as_int(periods, "periods", minimum=1)
        g = as_scalar(gain, "gain", positive=True)
        if g >= 2:
            raise ParameterError(f"gain = {g:g} must be in (0, 2)")
        if not callable(simulate):
            raise ParameterTypeError(f"simulate must be callable u -> y, got {simulate!r}")
        n = r.shape[0]
        u = self.command(r, periods=p)[-n:]
        errors: list[float] = []
        best = u
        for it in range(k + 1):  # a few whole-record model simulations, not a loop over samples
            y = np.asarray(simulate(np.tile(u, (p, 1))), dtype=np.float64)
            if y.shape != (p * n, self.n_outputs):
                raise ParameterError(f"simulate returned shape {y.shape}, expected ({p * n}, {self.n_outputs})")
            e = r - y[-n:]
            errors.append(float(np.sqrt(np.mean(e**2))))
            if errors[-1] <= min(errors):
                best = u
            if it < k:
                u = u + g * self.linear_command(e)
        return best, np.asarray(errors)


def _cascade(mats: dict[str, FloatArray], th: FloatArray, wt: FloatArray) -> tuple[HysteresisModel, ...] | None:
    """The per-actuator PI models when the model is a Hammerstein cascade (see :meth:`MimoFeedforward.from_model`)."""
    from ..models.pi import PI

    g, h = mats["G"], mats["H"]
    nu = mats["B"].shape[1]
    if g.shape[0] != nu or np.any(g != 0) or not np.array_equal(h, np.eye(nu)) or wt.size == 0:
        return None
    bd = np.vstack([mats["B"], mats["D"]])
    ef = np.vstack([mats["E"], mats["F"]])
    c = np.empty(nu)
    for i in range(nu):  # one least-squares scalar per actuator
        col = bd[:, i]
        den = float(col @ col)
        c[i] = float(col @ ef[:, i]) / den if den > 0 else 0.0
    scale = max(float(np.max(np.abs(ef))), 1e-300)
    if np.max(np.abs(ef - bd * c[None, :])) > 1e-9 * scale:
        return None
    pis = []
    for i in range(nu):
        order = np.argsort(th[i], kind="stable")
        r, w = th[i][order], c[i] * wt[i][order]
        if np.any(np.diff(r) <= 0):
            return None  # repeated thresholds: not a PI model of its own
        pis.append(PI(r, w, p0=1.0))
    return tuple(pis)
