"""The Bouc–Wen hysteretic benchmark system (Noël & Schoukens 2016), docs/spec.md §3.3.

::

    mL y'' + cL y' + kL y + z = u
    z' = alpha y' - beta (gamma |y'| |z|^(nu-1) z + delta y' |z|^nu)

with ``mL = 2 kg, cL = 10 N s/m, kL = 5e4 N/m, alpha = 5e4 N/m, beta = 1e3 1/m,
gamma = 0.8, delta = -1.1, nu = 1``. Input ``u`` is a force in N, output ``y`` a
displacement in m, ``z`` the hysteretic force in N. The benchmark's records are at
``fs = 750 Hz``.

How the records are reproduced
------------------------------
The official generator (MATLAB ``BoucWen_ExampleIntegration.m`` with the p-coded
``BoucWen_NewmarkIntegration``; the dynoNet training record was made with the same script)
builds its multisine *at the integration rate* ``20 fs = 15 kHz`` and keeps every 20th
sample as the input record. Its lines (5–150 Hz) lie far below 375 Hz, so the record at
``fs`` determines the integrated input exactly. This module reproduces each stage:

1. **Input upsampling** (``interpolation="fft"``, the default): periodic band-limited
   interpolation (zero padding of the record's DFT; an even record's Nyquist bin is split
   evenly). For a whole number of periods of a multisine this *is* the official
   high-rate input, to round-off: on ``train_multisine.csv`` the simulated output misses
   the measured one by an RMSE of 7.37e-6 m, which is the record's noise (the residual
   is uncorrelated from one period to the next and has the same power on and off the
   periodic response's frequency lines). Linear interpolation (``"linear"``) gives
   1.04e-5 m and a zero-order hold (``"zoh"``) 1.03e-4 m, so neither was used. For a
   record that is not periodic, ``"fft"`` wraps its end onto its start; use
   ``"linear"`` there or pass the high-rate input to :meth:`BoucWenBenchmark.integrate`.
2. **Integration** at ``h = 1 / (upsample fs)``: Newmark's average-acceleration rule for
   the mechanical part and the trapezoidal rule for ``z``, one implicit step per sample
   solved to round-off (in closed form for ``nu = 1``, by Newton's method otherwise; Rust
   core, ``piezohyst_core::boucwen_benchmark``). The initial acceleration satisfies the
   equation of motion at the first sample; the first output sample is the initial
   displacement.
3. **Decimation**: MATLAB ``decimate(y, p, 'fir')`` for each prime factor ``p`` of
   ``upsample`` in increasing order (2, 2, 5 for 20): the 31-tap Hamming low-pass
   ``fir1(30, 1/p)``, applied as a zero-phase filter over the record extended by odd
   reflection about its end samples, then every ``p``-th sample from the first. (Plain
   subsampling gives 7.368e-6 m on the training record, SciPy's ``decimate`` 7.67e-6 m.)

Identification
--------------
:func:`piezohyst.identify.boucwen_benchmark.identify_boucwen_benchmark` fits all parameters
to a record by free-run simulation error: a population search (DE by default), then
trust-region least squares from several starts. Every candidate is simulated as above (the
input upsampled once and shared) in one Rust batch call per population
(``_core.boucwen_benchmark_batch_rmse``, rayon across rows). On ``train_multisine.csv``,
fitted on periods 2-3, it predicts periods 4-5 with an RMSE of 7.389e-6 m (the true model:
7.387e-6 m) in about 7 s on 2 cores.

The official script simulates one extra period and drops it so that the decimation
filter's end effect falls outside the record; here the reflection at the end changes the
last few samples of a multisine response by far less than the noise (the RMSE above is
for the plain 5-period record).

Examples
--------
>>> import numpy as np
>>> from piezohyst.boucwen_benchmark import BoucWenBenchmark
>>> fs, n = 750.0, 1500                       # 2 s at the benchmark rate
>>> t = np.arange(n) / fs
>>> u = 50 * np.sin(2 * np.pi * 10 * t)       # N
>>> y = BoucWenBenchmark().simulate(u, fs=fs)  # m
>>> y.shape, bool(2e-4 < np.abs(y[750:]).max() < 1e-3)
((1500,), True)
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Literal, overload

import numpy as np
import numpy.typing as npt

from .. import _core
from .._io import PathLike, write_atomic
from .._validate import as_int, as_record, as_scalar, as_vector
from ..errors import ParameterError
from ..signals.matfile import write_mat
from ..signals.response import Response

FloatArray = npt.NDArray[np.float64]

#: Version of the model-file layout (that of :data:`piezohyst.models.model.SCHEMA_VERSION`).
SCHEMA_VERSION = 1

__all__ = ["FS", "INTERPOLATIONS", "UPSAMPLE", "BoucWenBenchmark", "decimate", "upsample"]

#: Sampling rate of the benchmark's records, Hz.
FS = 750.0
#: Upsampling factor of the official generator.
UPSAMPLE = 20
INTERPOLATIONS = ("fft", "linear", "zoh")


def upsample(u: npt.ArrayLike, factor: int, interpolation: str = "fft") -> FloatArray:
    """The record ``u`` at ``factor`` times its rate, ``len(u) * factor`` samples.

    Sample ``factor * k`` of the result is ``u[k]``.

    Parameters
    ----------
    u : array_like
        Finite 1-D record.
    factor : int
        Upsampling factor, >= 1.
    interpolation : {"fft", "linear", "zoh"}
        ``"fft"``: periodic band-limited interpolation (exact for a whole number of
        periods of a signal without content at or above half the record's rate);
        ``"linear"``: straight lines between samples, the last sample held;
        ``"zoh"``: each sample held for ``factor`` samples.

    Returns
    -------
    numpy.ndarray

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.boucwen_benchmark import upsample
    >>> k = np.arange(16)
    >>> fine = upsample(np.sin(2 * np.pi * k / 16), 4)
    >>> bool(np.allclose(fine, np.sin(2 * np.pi * np.arange(64) / 64)))
    True
    """
    x = as_record(u, "u")
    r = as_int(factor, "factor", minimum=1)
    if interpolation not in INTERPOLATIONS:
        raise ParameterError(
            f"interpolation = {interpolation!r} is unknown; expected one of {', '.join(INTERPOLATIONS)}"
        )
    if r == 1:
        return x
    n = x.size
    if interpolation == "zoh":
        return np.repeat(x, r)
    if interpolation == "linear":
        return np.interp(np.arange(n * r) / r, np.arange(n), x)
    spec = np.fft.rfft(x)
    padded = np.zeros(n * r // 2 + 1, dtype=complex)
    padded[: spec.size] = spec
    if n % 2 == 0 and n > 0:
        padded[n // 2] *= 0.5  # the Nyquist line splits evenly between +-fs/2
    fine: FloatArray = np.fft.irfft(padded, n * r) * r
    return fine


_upsample = upsample  # BoucWenBenchmark.simulate's argument `upsample` shadows it


def decimate(y: npt.ArrayLike, factor: int) -> FloatArray:
    """MATLAB ``decimate(y, p, 'fir')`` for each prime factor ``p`` of ``factor``
    (increasing), as the official benchmark generator; ``ceil(len(y) / factor)`` samples.

    Parameters
    ----------
    y : array_like, shape (N,)
        The record to decimate.
    factor : int
        Decimation factor (>= 1).

    Returns
    -------
    ndarray, shape (ceil(N / factor),)

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.boucwen_benchmark import decimate
    >>> t = np.arange(2000) / 15000.0
    >>> slow = decimate(np.sin(2 * np.pi * 50 * t), 20)
    >>> bool(np.allclose(slow, np.sin(2 * np.pi * 50 * t[::20]), atol=1e-3))
    True
    """
    x = as_record(y, "y", copy=False)
    r = as_int(factor, "factor", minimum=1)
    return _core.boucwen_benchmark_decimate(x, r)


_PARAMETER_NAMES = ("mass", "damping", "stiffness", "alpha", "beta", "gamma", "delta", "nu")


class BoucWenBenchmark:
    """The benchmark system with overridable parameters (defaults: the true system).

    Parameters
    ----------
    mass : float
        ``mL``, kg (> 0).
    damping : float
        ``cL``, N s/m (>= 0).
    stiffness : float
        ``kL``, N/m (>= 0).
    alpha : float
        Hysteretic stiffness, N/m (>= 0).
    beta : float
        Hysteresis amplitude (>= 0), 1/m for ``nu = 1``.
    gamma, delta : float
        Loop-shape parameters.
    nu : float
        Smoothness exponent (>= 1).
    fs, upsample : float, int
        The record's sampling rate (Hz) and the integration steps per sample that
        :meth:`simulate` and :meth:`response` use when not given (defaults: the benchmark's
        750 Hz and 20); a model file (:meth:`save`, ``piezohyst identify --model
        boucwen-benchmark``) keeps them, so ``load_model(file).simulate(u)`` runs at the
        rate the model was identified at.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.boucwen_benchmark import BoucWenBenchmark
    >>> bw = BoucWenBenchmark()
    >>> u = 50 * np.sin(2 * np.pi * 5 * np.arange(750) / 750.0)
    >>> y, z = bw.simulate(u, return_z=True)
    >>> bool(np.all(np.isfinite(y)) and 10 < np.abs(z).max() < 100)
    True
    >>> BoucWenBenchmark(mass=0)
    Traceback (most recent call last):
    ...
    piezohyst.errors.ParameterError: mass = 0.0 must be > 0
    """

    #: The name in model files.
    kind = "boucwen-benchmark"
    #: Units of the input (force) and output (displacement).
    units: Mapping[str, str] = {"input": "N", "output": "m"}

    def __init__(
        self,
        mass: float = 2.0,
        damping: float = 10.0,
        stiffness: float = 5e4,
        alpha: float = 5e4,
        beta: float = 1e3,
        gamma: float = 0.8,
        delta: float = -1.1,
        nu: float = 1.0,
        *,
        fs: float = FS,
        upsample: int = UPSAMPLE,
    ) -> None:
        self.fs = as_scalar(fs, "fs", positive=True)
        self.upsample = as_int(upsample, "upsample", minimum=1)
        self.mass = as_scalar(mass, "mass", positive=True)
        self.damping = as_scalar(damping, "damping", nonnegative=True)
        self.stiffness = as_scalar(stiffness, "stiffness", nonnegative=True)
        self.alpha = as_scalar(alpha, "alpha", nonnegative=True)
        self.beta = as_scalar(beta, "beta", nonnegative=True)
        self.gamma = as_scalar(gamma, "gamma")
        self.delta = as_scalar(delta, "delta")
        self.nu = as_scalar(nu, "nu")
        if not self.nu >= 1.0:
            raise ParameterError(f"nu = {self.nu} must be >= 1")

    @property
    def parameters(self) -> dict[str, float]:
        """The parameters by name."""
        return {
            "mass": self.mass,
            "damping": self.damping,
            "stiffness": self.stiffness,
            "alpha": self.alpha,
            "beta": self.beta,
            "gamma": self.gamma,
            "delta": self.delta,
            "nu": self.nu,
        }

    def params(self) -> FloatArray:
        """``[mass, damping, stiffness, alpha, beta, gamma, delta, nu]`` for the core.

        Returns
        -------
        ndarray, shape (8,)

        Examples
        --------
        >>> from piezohyst import BoucWenBenchmark
        >>> BoucWenBenchmark().params().tolist()
        [2.0, 10.0, 50000.0, 50000.0, 1000.0, 0.8, -1.1, 1.0]
        """
        return np.array(list(self.parameters.values()), dtype=np.float64)

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self.parameters.items())
        return f"BoucWenBenchmark({args})"

    def __eq__(self, other: object) -> bool:
        return (
            isinstance(other, BoucWenBenchmark)
            and self.parameters == other.parameters
            and (self.fs, self.upsample) == (other.fs, other.upsample)
        )

    __hash__ = None  # type: ignore[assignment]

    # -- files ------------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """The model-file layout (what ``piezohyst identify --model boucwen-benchmark`` writes):
        ``schema_version``, ``kind``, the eight ``parameters``, ``fs``, ``upsample``, ``units``.

        Returns
        -------
        dict

        Examples
        --------
        >>> from piezohyst import BoucWenBenchmark
        >>> d = BoucWenBenchmark(mass=2.5).to_dict()
        >>> d["kind"], d["parameters"]["mass"], d["fs"]
        ('boucwen-benchmark', 2.5, 750.0)
        """
        return {
            "schema_version": SCHEMA_VERSION,
            "kind": self.kind,
            "parameters": self.parameters,
            "fs": self.fs,
            "upsample": self.upsample,
            "units": dict(self.units),
        }

    def save(self, path: PathLike, *, overwrite: bool = False) -> Path:
        """Write the model file atomically (read back by :func:`piezohyst.load_model`); a path
        ending in ``.mat`` writes the MATLAB file of :meth:`to_mat`.

        Parameters
        ----------
        path : str or os.PathLike
            The file to write (JSON, or MATLAB for ``.mat``).
        overwrite : bool
            Replace an existing file (otherwise :class:`~piezohyst.errors.OutputExistsError`).

        Returns
        -------
        pathlib.Path

        Examples
        --------
        >>> import tempfile, pathlib
        >>> from piezohyst import BoucWenBenchmark, load_model
        >>> path = BoucWenBenchmark(damping=12.0).save(pathlib.Path(tempfile.mkdtemp()) / "bw.json")
        >>> load_model(path) == BoucWenBenchmark(damping=12.0)
        True
        """
        if Path(path).suffix.lower() == ".mat":
            return self.to_mat(path, overwrite=overwrite)
        return write_atomic(path, json.dumps(self.to_dict(), indent=2, allow_nan=False), overwrite=overwrite)

    def to_mat(self, path: PathLike, *, overwrite: bool = False) -> Path:
        """Write the model to the MATLAB file ``path`` (read back exactly by
        :func:`piezohyst.load_model`): the struct ``model`` with ``schema_version``, ``kind``,
        ``family`` (``"boucwen-benchmark"``), the eight ``parameters``, ``fs``, ``upsample``,
        ``units`` (layout: :mod:`piezohyst.signals.matfile`).

        Parameters
        ----------
        path : str or os.PathLike
            The file to write (``.mat``), atomically.
        overwrite : bool
            Replace an existing file (default ``False``: ``OutputExistsError``).

        Returns
        -------
        pathlib.Path
            The file written.

        Examples
        --------
        >>> import tempfile, pathlib
        >>> from piezohyst import load_model
        >>> from piezohyst.models import BoucWenBenchmark
        >>> path = BoucWenBenchmark().to_mat(pathlib.Path(tempfile.mkdtemp()) / "bw.mat")
        >>> load_model(path).parameters == BoucWenBenchmark().parameters
        True
        """
        return write_mat(path, "model", {**self.to_dict(), "family": self.kind}, overwrite=overwrite)

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> BoucWenBenchmark:
        """The model of a :meth:`to_dict` description (``fs`` and ``upsample`` default to the
        benchmark's when absent); unknown parameter names are a ``ParameterError``.

        Parameters
        ----------
        d : mapping
            A model file's JSON object.

        Returns
        -------
        BoucWenBenchmark

        Examples
        --------
        >>> from piezohyst import BoucWenBenchmark
        >>> BoucWenBenchmark.from_dict({"parameters": {"mass": 3.0}}).mass
        3.0
        """
        p = d.get("parameters")
        if not isinstance(p, dict):
            raise ParameterError("parameters must be a JSON object")
        unknown = sorted(set(p) - set(_PARAMETER_NAMES))
        if unknown:
            raise ParameterError(
                f"parameters of kind 'boucwen-benchmark' has unknown names {unknown}; expected {list(_PARAMETER_NAMES)}"
            )
        return cls(**p, fs=d.get("fs", FS), upsample=d.get("upsample", UPSAMPLE))

    def initial_state(self, initial_state: npt.ArrayLike | None = None, u0: float = 0.0) -> FloatArray:
        """The core's state ``[y, y', y'', z]`` from ``initial_state = (y0, dy0, z0)``
        (m, m/s, N; default at rest) under the input ``u0`` (N).

        Parameters
        ----------
        initial_state : array_like of 3 floats, optional
            Displacement, velocity and hysteretic force ``(y0, dy0, z0)``.
        u0 : float
            The input force at the start, N (sets the acceleration).

        Returns
        -------
        ndarray, shape (4,)

        Examples
        --------
        >>> from piezohyst import BoucWenBenchmark
        >>> BoucWenBenchmark().initial_state(u0=4.0).tolist()   # y'' = u0 / mL
        [0.0, 0.0, 2.0, 0.0]
        """
        if initial_state is None:
            y0 = dy0 = z0 = 0.0
        else:
            y0, dy0, z0 = as_vector(initial_state, "initial_state", length=3)
        a0 = (u0 - self.damping * dy0 - self.stiffness * y0 - z0) / self.mass
        return np.array([y0, dy0, a0, z0], dtype=np.float64)

    @overload
    def integrate(
        self,
        u: npt.ArrayLike,
        h: float,
        initial_state: npt.ArrayLike | None = None,
        *,
        return_z: Literal[False] = False,
    ) -> FloatArray: ...
    @overload
    def integrate(
        self, u: npt.ArrayLike, h: float, initial_state: npt.ArrayLike | None = None, *, return_z: Literal[True]
    ) -> tuple[FloatArray, FloatArray]: ...
    @overload
    def integrate(
        self, u: npt.ArrayLike, h: float, initial_state: npt.ArrayLike | None = None, *, return_z: bool
    ) -> FloatArray | tuple[FloatArray, FloatArray]: ...
    def integrate(
        self, u: npt.ArrayLike, h: float, initial_state: npt.ArrayLike | None = None, *, return_z: bool = False
    ) -> FloatArray | tuple[FloatArray, FloatArray]:
        """Integrate at the step ``h`` with no resampling: ``u[k]`` is the force (N) at
        ``t = k h`` and ``y[k]`` (m) the displacement there; ``y[0]`` is the initial one.

        Parameters
        ----------
        u : array_like
            Force record at the integration rate, N.
        h : float
            Time step, s (> 0).
        initial_state : array_like of 3 floats, optional
            ``(y0, dy0, z0)`` in m, m/s, N at ``t = 0``; at rest by default.
        return_z : bool
            Also return the hysteretic force ``z`` (N).

        Returns
        -------
        y : numpy.ndarray
            or ``(y, z)`` with ``return_z``.

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst.boucwen_benchmark import BoucWenBenchmark
        >>> y, z = BoucWenBenchmark().integrate(np.full(30000, 10.0), h=1 / 15000, return_z=True)
        >>> bool(abs(5e4 * y[-1] + z[-1] - 10.0) < 0.01)   # at rest again: kL y + z = u
        True
        """
        y, z, _ = self._integrate(as_record(u, "u"), as_scalar(h, "h", positive=True), initial_state)
        if return_z:
            return y, z
        return y

    def _integrate(
        self, u: FloatArray, h: float, initial_state: npt.ArrayLike | None
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """``(y, z, state)``: the integrated displacement and hysteretic force at ``t = k h`` and
        the core's state ``[y, y', y'', z]`` at the last sample."""
        state = self.initial_state(initial_state, float(u[0]))
        y0, z0 = state[0], state[3]
        y, z = _core.boucwen_benchmark_integrate(self.params(), u[1:], h, state)
        return np.concatenate([[y0], y]), np.concatenate([[z0], z]), state

    @overload
    def simulate(
        self,
        u: npt.ArrayLike,
        fs: float | None = None,
        upsample: int | None = None,
        initial_state: npt.ArrayLike | None = None,
        *,
        interpolation: str = "fft",
        return_z: Literal[False] = False,
    ) -> FloatArray: ...
    @overload
    def simulate(
        self,
        u: npt.ArrayLike,
        fs: float | None = None,
        upsample: int | None = None,
        initial_state: npt.ArrayLike | None = None,
        *,
        interpolation: str = "fft",
        return_z: Literal[True],
    ) -> tuple[FloatArray, FloatArray]: ...
    @overload
    def simulate(
        self,
        u: npt.ArrayLike,
        fs: float | None = None,
        upsample: int | None = None,
        initial_state: npt.ArrayLike | None = None,
        *,
        interpolation: str = "fft",
        return_z: bool,
    ) -> FloatArray | tuple[FloatArray, FloatArray]: ...
    def simulate(
        self,
        u: npt.ArrayLike,
        fs: float | None = None,
        upsample: int | None = None,
        initial_state: npt.ArrayLike | None = None,
        *,
        interpolation: str = "fft",
        return_z: bool = False,
    ) -> FloatArray | tuple[FloatArray, FloatArray]:
        """Output of the benchmark system for the force record ``u`` sampled at ``fs``, as
        the official generator: upsample by ``upsample``, integrate, FIR-decimate back.

        The fast path: it returns the arrays only. :meth:`response` runs the same simulation
        and returns the full :class:`~piezohyst.signals.Response` (time base, ``u``, ``y`` and
        ``z`` with their units, final state).

        Parameters
        ----------
        u : array_like
            Force record, N, at ``fs``.
        fs : float, optional
            Sampling rate of ``u`` and of the output, Hz (> 0); default: the model's ``fs``.
        upsample : int, optional
            Integration steps per sample (>= 1); default: the model's ``upsample`` (the
            benchmark uses 20).
        initial_state : array_like of 3 floats, optional
            ``(y0, dy0, z0)`` in m, m/s, N at the first sample; at rest by default.
        interpolation : {"fft", "linear", "zoh"}
            How the input is upsampled (see :func:`upsample`); ``"fft"`` reproduces the
            benchmark's periodic multisines exactly.
        return_z : bool
            Also return the hysteretic force ``z`` (N), decimated the same way.

        Returns
        -------
        y : numpy.ndarray
            Displacement, m, ``len(u)`` samples at ``fs``; or ``(y, z)``.

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst.boucwen_benchmark import BoucWenBenchmark
        >>> rng = np.random.default_rng(0)
        >>> n = 1024                                   # one period of a 5-150 Hz multisine
        >>> lines = np.zeros(n // 2 + 1, complex)
        >>> k = np.arange(7, 205)
        >>> lines[k] = np.exp(2j * np.pi * rng.random(k.size))
        >>> u = np.fft.irfft(lines, n)
        >>> u = np.tile(50 * u / u.std(), 3)             # 3 periods, 50 N RMS
        >>> y = BoucWenBenchmark().simulate(u)
        >>> bool(np.abs(y[2 * n:] - y[n:2 * n]).max() < 1e-3 * np.abs(y).max())   # steady state
        True
        """
        _, y, z, _ = self._run(u, fs, upsample, initial_state, interpolation, with_z=return_z)
        if return_z:
            assert z is not None
            return y, z
        return y

    def response(
        self,
        u: npt.ArrayLike,
        fs: float | None = None,
        upsample: int | None = None,
        initial_state: npt.ArrayLike | None = None,
        *,
        interpolation: str = "fft",
    ) -> Response:
        """The run of :meth:`simulate` as a :class:`~piezohyst.signals.Response`: the force, the
        displacement and the hysteretic force on one time base.

        Parameters
        ----------
        u, fs, upsample, initial_state, interpolation
            As in :meth:`simulate`.

        Returns
        -------
        Response
            Signals ``u`` (force, N, role input), ``y`` (displacement, m) and ``z`` (hysteretic
            force, N), ``len(u)`` samples at ``k / fs`` s; ``y`` and ``z`` are the arrays
            ``simulate(..., return_z=True)`` returns, bit for bit. ``final_state`` is
            ``(y, y', z)`` (m, m/s, N, the layout ``initial_state`` takes) at the last
            integration step, ``t = (len(u) upsample - 1) / (upsample fs)``; a run started from
            it continues this one closely but not bit for bit, since the upsampling and the
            zero-phase decimation each look at the whole record.

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst.models import BoucWenBenchmark
        >>> u = 50 * np.sin(2 * np.pi * 5 * np.arange(750) / 750.0)
        >>> r = BoucWenBenchmark().response(u)
        >>> r.input_names, r.output_names, r.units
        (('u',), ('y', 'z'), {'u': 'N', 'y': 'm', 'z': 'N'})
        >>> r.outputs.shape, float(r.time[-1])
        ((2, 750), 0.9986666666666667)
        >>> y, z = BoucWenBenchmark().simulate(u, return_z=True)
        >>> bool(np.array_equal(r.y, y) and np.array_equal(r.z, z))
        True
        """
        x, y, z, state = self._run(u, fs, upsample, initial_state, interpolation, with_z=True)
        assert z is not None
        rate = self.fs if fs is None else as_scalar(fs, "fs", positive=True)
        return Response(
            np.arange(x.size, dtype=np.float64) / rate,
            {"u": x, "y": y, "z": z},
            inputs=["u"],
            units={"u": "N", "y": "m", "z": "N"},
            final_state=state[[0, 1, 3]],
            title="Bouc–Wen benchmark",
        )

    def _run(
        self,
        u: npt.ArrayLike,
        fs: float | None,
        upsample: int | None,
        initial_state: npt.ArrayLike | None,
        interpolation: str,
        *,
        with_z: bool,
    ) -> tuple[FloatArray, FloatArray, FloatArray | None, FloatArray]:
        """``(u, y, z, state)`` of :meth:`simulate`: the checked input, the decimated outputs
        (``z`` only ``with_z``) and the core's state at the last integration step."""
        x = as_record(u, "u")
        rate = self.fs if fs is None else as_scalar(fs, "fs", positive=True)
        r = self.upsample if upsample is None else as_int(upsample, "upsample", minimum=1)
        if interpolation not in INTERPOLATIONS:
            raise ParameterError(
                f"interpolation = {interpolation!r} is unknown; expected one of {', '.join(INTERPOLATIONS)}"
            )
        fine = _upsample(x, r, interpolation)
        # the checks integrate() makes on the high-rate record and the step
        y, z, state = self._integrate(
            as_record(fine, "u"), as_scalar(1.0 / (r * rate), "h", positive=True), initial_state
        )
        y = _core.boucwen_benchmark_decimate(y, r)
        return x, y, _core.boucwen_benchmark_decimate(z, r) if with_z else None, state
