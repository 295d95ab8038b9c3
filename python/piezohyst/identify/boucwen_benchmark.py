"""Identification of the Bouc–Wen benchmark system (:class:`piezohyst.models.boucwen_benchmark.BoucWenBenchmark`)
by free-run simulation error: a population search (DE by default), then trust-region least
squares from several starts, every candidate simulated in one Rust batch call per population.
The model and its simulation live in :mod:`piezohyst.models.boucwen_benchmark`; the
benchmark's dataset reader in :mod:`piezohyst.papers.boucwen_benchmark`.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from .. import _core
from .._validate import as_int, as_record, as_scalar
from ..errors import ParameterError, ParameterTypeError
from ..models.boucwen_benchmark import FS, INTERPOLATIONS, UPSAMPLE, BoucWenBenchmark
from ..models.boucwen_benchmark import upsample as _upsample  # the argument `upsample` shadows it
from .core import FloatArray, IdentificationResult, Metrics, _fit_metrics, check_fit_scale

if TYPE_CHECKING:  # pragma: no cover - typing only
    from .core import Callback, RngLike

__all__ = ["DEFAULT_BOUNDS", "IDENTIFY_PARAMETERS", "identify_boucwen_benchmark"]


# --------------------------------------------------------------------------------------------
# identification
# --------------------------------------------------------------------------------------------
#: What :func:`identify_boucwen_benchmark` searches, in this order. ``beta`` enters the
#: equations only through ``beta_gamma = beta * gamma`` and ``beta_delta = beta * delta``.
IDENTIFY_PARAMETERS = ("mass", "damping", "stiffness", "alpha", "beta_gamma", "beta_delta", "nu")

#: Default search box of :func:`identify_boucwen_benchmark` (a number fixes the parameter).
DEFAULT_BOUNDS: dict[str, tuple[float, float] | float] = {
    "mass": (0.5, 8.0),  # kg
    "damping": (0.0, 50.0),  # N s/m
    "stiffness": (1e4, 2e5),  # N/m
    "alpha": (1e4, 2e5),  # N/m
    "beta_gamma": (0.0, 2e4),  # 1/m for nu = 1: beta 1e2..1e4 times gamma 0..2
    "beta_delta": (-3e4, 1e4),  # 1/m for nu = 1: beta 1e2..1e4 times delta -3..1
    "nu": 1.0,  # fixed: the benchmark's structure
}

#: Samples at ``fs`` simulated past the scored range when the record has them, so that the
#: decimation filters' end reflection (about 5 samples deep at 750 Hz) stays outside it.
_TAIL = 8


def _search_box(
    bounds: Mapping[str, Any] | None,
) -> tuple[tuple[str, ...], FloatArray, FloatArray, dict[str, float]]:
    """``(names, lower, upper, fixed)`` of the free parameters from ``bounds`` (``None``, or a
    mapping of names in :data:`IDENTIFY_PARAMETERS` to ``(lower, upper)`` or a fixed number,
    overriding :data:`DEFAULT_BOUNDS`)."""
    box: dict[str, Any] = dict(DEFAULT_BOUNDS)
    if bounds is not None:
        if not hasattr(bounds, "items"):
            raise ParameterTypeError(
                f"bounds must be a mapping of parameter names to (lower, upper) pairs or fixed values, "
                f"got {type(bounds).__name__}"
            )
        for name, b in bounds.items():
            if name not in IDENTIFY_PARAMETERS:
                raise ParameterError(
                    f"bounds: unknown parameter {name!r}; expected names from {list(IDENTIFY_PARAMETERS)}"
                )
            box[name] = b
    names: list[str] = []
    lower: list[float] = []
    upper: list[float] = []
    fixed: dict[str, float] = {}
    minimum = {
        "mass": (0.0, False),
        "damping": (0.0, True),
        "stiffness": (0.0, True),
        "alpha": (0.0, True),
        "nu": (1.0, True),
    }
    for name in IDENTIFY_PARAMETERS:
        b = box[name]
        if isinstance(b, (tuple, list, np.ndarray)):
            if len(b) != 2:
                raise ParameterError(f"bounds[{name!r}] = {b!r} must be a (lower, upper) pair or a number")
            lo, hi = as_scalar(b[0], f"bounds[{name!r}] lower"), as_scalar(b[1], f"bounds[{name!r}] upper")
            if lo > hi:
                raise ParameterError(f"bounds[{name!r}] = ({lo}, {hi}): lower > upper")
        else:
            lo = hi = as_scalar(b, f"bounds[{name!r}]")
        if name in minimum:
            m, inclusive = minimum[name]
            if lo < m or (lo == m and not inclusive):
                rel = ">=" if inclusive else ">"
                raise ParameterError(f"bounds[{name!r}]: lower = {lo} must be {rel} {m}")
        if lo == hi:
            fixed[name] = lo
        else:
            names.append(name)
            lower.append(lo)
            upper.append(hi)
    if not names:
        raise ParameterError("bounds: every parameter is fixed; nothing to identify")
    return tuple(names), np.array(lower), np.array(upper), fixed


def _as_range(r: object, n: int, name: str, minimum: int) -> tuple[int, int]:
    """``(start, stop)`` sample indices inside a record of ``n`` samples."""
    if r is None:
        start, stop = 0, n
    else:
        try:
            start, stop = r  # type: ignore[misc]  # any pair: unpacking is the check
        except (TypeError, ValueError):
            raise ParameterTypeError(f"{name} must be a (start, stop) pair of sample indices, got {r!r}") from None
        start, stop = as_int(start, f"{name} start"), as_int(stop, f"{name} stop")
    if not start < stop <= n:
        raise ParameterError(f"{name} = ({start}, {stop}) must satisfy 0 <= start < stop <= {n} (the record's length)")
    if stop - start < minimum:
        raise ParameterError(f"{name} = ({start}, {stop}) holds {stop - start} samples, at least {minimum} needed")
    return start, stop


class _Problem:
    """The benchmark's simulation of one scored range of a record, for many parameter rows:
    the upsampled input of the range with ``warmup`` samples before it and up to ``_TAIL``
    after it, simulated from rest in one Rust batch call."""

    def __init__(self, fine: FloatArray, r: int, h: float, y: FloatArray, start: int, stop: int, warmup: int):
        w = min(warmup, start)
        tail = min(_TAIL, y.size - stop)
        self.input = np.ascontiguousarray(fine[(start - w) * r : (stop + tail) * r])
        self.target = np.ascontiguousarray(y[start:stop])
        self.skip, self.r, self.h = w, r, h

    def rmse(self, rows: FloatArray) -> FloatArray:
        return _core.boucwen_benchmark_batch_rmse(rows, self.input, self.h, self.r, self.target, self.skip, np.inf)

    def simulate(self, rows: FloatArray) -> FloatArray:
        return _core.boucwen_benchmark_batch_simulate(rows, self.input, self.h, self.r, self.skip, self.target.size)


def _least_squares_polish(
    problem: _Problem,
    to_rows: Callable[[FloatArray], FloatArray],
    x0: FloatArray,
    lower: FloatArray,
    upper: FloatArray,
    options: Mapping[str, Any],
) -> tuple[FloatArray, float, int, str]:
    """Trust-region least squares (SciPy ``least_squares``, ``trf``, within the bounds) on
    the residual of ``problem`` from ``x0``; Jacobian by central differences, all ``2 D``
    perturbed rows in one batch call. Returns ``(x, rmse, nfev, message)``: the better of
    ``x0`` and the result, its RMSE, the rows simulated and SciPy's message."""
    from scipy.optimize import least_squares  # imported on use: keeps imports quick

    D = x0.size
    span = upper - lower
    nfev = 0

    def fun(x: FloatArray) -> FloatArray:
        nonlocal nfev
        nfev += 1
        out: FloatArray = problem.simulate(to_rows(x[None, :]))[0]
        return out - problem.target  # NaN (a failed run) makes the trust region shrink

    def jac(x: FloatArray) -> FloatArray:
        nonlocal nfev
        step = 1e-6 * np.maximum(np.abs(x), 1e-3 * span)
        X = np.repeat(x[None, :], 2 * D, axis=0)
        idx = np.arange(D)
        X[idx, idx] = np.minimum(x + step, upper)
        X[D + idx, idx] = np.maximum(x - step, lower)
        out = problem.simulate(to_rows(X))
        nfev += 2 * D
        J = np.zeros((problem.target.size, D))
        f0 = None
        for d in range(D):
            hi_ok, lo_ok = np.all(np.isfinite(out[d])), np.all(np.isfinite(out[D + d]))
            if hi_ok and lo_ok and X[d, d] != X[D + d, d]:
                J[:, d] = (out[d] - out[D + d]) / (X[d, d] - X[D + d, d])
            elif hi_ok or lo_ok:  # one side failed or sits on a bound: one-sided difference
                if f0 is None:
                    f0 = problem.simulate(to_rows(x[None, :]))[0]
                    nfev += 1
                k = d if hi_ok else D + d
                if X[k, d] != x[d]:
                    J[:, d] = (out[k] - f0) / (X[k, d] - x[d])
        return J

    opts: dict[str, Any] = {"xtol": 1e-12, "ftol": 1e-12, "gtol": 1e-12, "max_nfev": 100}
    opts.update(options)
    x0 = np.clip(x0, lower, upper)
    f0 = float(problem.rmse(to_rows(x0[None, :]))[0])
    nfev += 1
    if not np.isfinite(f0):
        return x0, f0, nfev, "the simulation fails or diverges at the start"
    with np.errstate(over="ignore", invalid="ignore"):
        res = least_squares(fun, x0, jac=jac, bounds=(lower, upper), x_scale=span, method="trf", **opts)
    x1 = np.clip(res.x, lower, upper)
    f1 = float(problem.rmse(to_rows(x1[None, :]))[0])
    nfev += 1
    if not f1 < f0:
        return x0, f0, nfev, str(res.message)
    return x1, f1, nfev, str(res.message)


def _starts(X: FloatArray, f: FloatArray, lower: FloatArray, upper: FloatArray, count: int) -> list[FloatArray]:
    """Up to ``count`` of the evaluated candidates ``X`` (costs ``f``), best first, no two
    within 10 % of the box's span of each other in every coordinate."""
    span = upper - lower
    chosen: list[FloatArray] = []
    picked: list[FloatArray] = []
    for i in np.argsort(f, kind="stable"):
        if len(chosen) >= count or not np.isfinite(f[i]):
            break
        z = (X[i] - lower) / span
        if all(np.max(np.abs(z - c)) > 0.1 for c in picked):
            chosen.append(X[i])
            picked.append(z)
    return chosen


def _box_centre(lower: FloatArray, upper: FloatArray) -> FloatArray:
    """The box's centre: geometric for a positive range (a scale parameter), else arithmetic."""
    pos = lower > 0
    return np.where(pos, np.sqrt(np.where(pos, lower * upper, 1.0)), 0.5 * (lower + upper))


def _scored(
    model: BoucWenBenchmark,
    u: FloatArray,
    y: FloatArray,
    fs: float,
    r: int,
    interpolation: str,
    rng_: tuple[int, int],
) -> Metrics:
    """Free-run metrics of ``model`` on samples ``rng_`` of a validated record simulated whole."""
    start, stop = rng_
    out = np.asarray(model.simulate(u, fs=fs, upsample=r, interpolation=interpolation))
    return _fit_metrics(out[start:stop], y[start:stop])


def identify_boucwen_benchmark(
    u: npt.ArrayLike,
    y: npt.ArrayLike,
    fs: float = FS,
    *,
    upsample: int = UPSAMPLE,
    fit_range: tuple[int, int] | None = None,
    warmup: int = 1024,
    search_samples: int | None = 2048,
    beta: float = 1e3,
    bounds: Mapping[str, tuple[float, float] | float] | None = None,
    optimizer: str = "de",
    rng: RngLike = None,
    max_iterations: int = 30,
    population_size: int | None = None,
    polish: bool | dict[str, Any] = True,
    starts: int = 3,
    validate: Sequence[Any] | None = None,
    interpolation: str = "fft",
    progress: bool = False,
    callback: Callback | None = None,
) -> IdentificationResult:
    """Identify the benchmark's Bouc–Wen oscillator (mass, damping, stiffness, alpha, beta,
    gamma, delta, nu) from a force record ``u`` (N) and a displacement record ``y`` (m) by
    free-run simulation error, simulated exactly as :meth:`BoucWenBenchmark.simulate` does
    (``upsample`` x rate, Newmark + trapezoidal ``z``, FIR decimation).

    Three stages:

    1. **Global search**: a population optimizer (:func:`piezohyst.optimize.minimize`,
       ``optimizer`` in ``"de"``, ``"css"``, ``"pso"``, ``"mpso"``) over the box ``bounds``
       on the RMSE of the first ``search_samples`` samples of ``fit_range``; each population
       is simulated in one Rust batch call (rayon across rows, GIL released).
    2. **Screening** (with ``polish``): a short trust-region least-squares run (SciPy
       ``least_squares``, ``trf``, inside the bounds; 20 evaluations) on the search samples
       from each of the ``starts`` best distinct candidates the search evaluated and from the
       box's centre (geometric for positive ranges); the best result goes on.
    3. **Polish**: the same least squares on the residual over the whole ``fit_range`` to
       convergence. Jacobians are central differences, all ``2 D`` perturbed rows in one
       batch call.

    Why several starts: the least-squares basin around the true system is wide (from the
    default box's centre alone the polish converges on the benchmark's record), but a
    population search with a small budget is drawn to a broad spurious optimum in a corner
    of the box (``beta_gamma`` and ``damping`` at their upper bounds: the hysteresis
    degenerates into a friction-like force plus heavy viscous damping, RMSE ~2e-4 m against
    the noise's 7e-6 m). On six noise-free synthetic records (1024-sample multisines, default
    settings) the search's best sat in that corner in three; the best screened start was
    the box's centre in three and one of the search's candidates in the other three; all six
    ended at the true parameters.

    Parametrization: ``beta`` multiplies both ``gamma`` and ``delta`` and enters the
    equations nowhere else (``z' = alpha y' - (beta gamma) |y'| |z|^(nu-1) z - (beta delta)
    y' |z|^nu``), so ``(beta, gamma, delta)`` has a flat direction ``(s beta, gamma / s,
    delta / s)``. The search runs over ``beta_gamma = beta * gamma`` and ``beta_delta = beta
    * delta`` instead; the model is reported with the given ``beta`` (default 1e3, the
    benchmark's; not identified, any positive value describes the same system) and
    ``gamma = beta_gamma / beta``, ``delta = beta_delta / beta``.

    Default bounds (:data:`DEFAULT_BOUNDS`), chosen as physically sensible for a
    laboratory-scale oscillator driven by tens of N, not around the true values: mass
    0.5-8 kg, damping 0-50 N s/m (a damping ratio up to ~0.1 at the ~35 Hz resonance of such
    a system), stiffness and alpha 1e4-2e5 N/m each (natural frequencies from ~6 to ~100 Hz
    across the mass range), beta_gamma 0-2e4 and beta_delta -3e4..1e4 1/m (beta 1e2-1e4
    times gamma 0-2 and delta -3..1: loops that harden on loading, as the benchmark's, or
    soften, as the classical Bouc–Wen). ``nu`` is fixed at 1: it is the benchmark's
    structure, for ``nu = 1`` each implicit step is solved in closed form (1.6 times
    faster), and the core needs ``nu >= 1`` (the step's Jacobian holds ``|z|^(nu-1)``); pass
    ``bounds={"nu": (1.0, 2.0)}`` to fit it.

    Parameters
    ----------
    u, y : array_like
        Force (N) and displacement (m) records at ``fs``, equal lengths. With
        ``interpolation="fft"`` (the benchmark's) ``u`` must be a whole number of periods of
        a band-limited signal, as the benchmark's multisines are; it is upsampled whole.
    fs : float
        Sample rate, Hz (the benchmark's 750).
    upsample : int
        Integration steps per sample (the benchmark's 20).
    fit_range : (int, int), optional
        Samples ``start:stop`` whose error is minimized (default: the whole record). The
        simulation starts at rest ``warmup`` samples before ``start`` (or at the record's
        start), so the transient from rest stays out of the cost; e.g. ``(8192, 24576)``
        fits periods 2-3 of ``train_multisine.csv``.
    warmup : int
        Samples simulated before ``start`` and not scored (default 1024, 1.4 s: for the
        benchmark the response from rest meets the periodic one to 6e-15 m after 1024
        samples).
    search_samples : int or None
        Samples of ``fit_range`` (from its start) scored by the search and the screening
        (default 2048, 2.7 s); ``None`` scores all of it. The polish uses all of
        ``fit_range``.
    beta : float
        The value ``beta`` is reported with (> 0), see above.
    bounds : mapping, optional
        ``{name: (lower, upper) or fixed value}`` for names in :data:`IDENTIFY_PARAMETERS`,
        overriding :data:`DEFAULT_BOUNDS`.
    optimizer, rng, max_iterations, population_size, progress, callback
        Passed to :func:`piezohyst.optimize.minimize` (``rng``: same seed, same result,
        whatever the thread count).
    polish : bool or dict
        Run the screening and the polish; a dict gives ``least_squares`` options of the
        polish (defaults ``xtol = ftol = gtol = 1e-12``, ``max_nfev = 100``). The polished
        point replaces the search's best only if it lowers the RMSE over ``fit_range``.
    starts : int
        Distinct search candidates screened besides the box's centre (>= 0).
    validate : (u, y) or (u, y, (start, stop)), optional
        A record simulated whole from rest with the identified model and scored on
        ``start:stop`` (default all of it); it is not fitted.
    interpolation : {"fft", "linear", "zoh"}
        Input upsampling (see :func:`upsample`).

    Returns
    -------
    IdentificationResult
        ``model`` is a :class:`BoucWenBenchmark`; ``evaluations`` counts the rows simulated
        (search, screening and polish); ``train`` holds the metrics of the whole
        record ``u`` simulated from rest, on ``fit_range``; ``history`` the optimizer's
        per-iteration history plus ``"parameters"`` (the names searched) and, when
        polished, ``"polish"``: the screened RMSEs (``"screened"``, one per start, the
        centre last), the RMSE over ``fit_range`` before and after, the rows simulated
        (``"nfev"``) and SciPy's message.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.boucwen_benchmark import BoucWenBenchmark, identify_boucwen_benchmark
    >>> rng = np.random.default_rng(1)
    >>> n = 512                                       # one period of a 5-150 Hz multisine
    >>> lines = np.zeros(n // 2 + 1, complex)
    >>> lines[4:103] = np.exp(2j * np.pi * rng.random(99))
    >>> u = np.fft.irfft(lines, n)
    >>> u = np.tile(50 * u / u.std(), 2)               # 2 periods, 50 N RMS
    >>> y = BoucWenBenchmark().simulate(u)
    >>> res = identify_boucwen_benchmark(u, y, fit_range=(n, 2 * n), rng=0, max_iterations=10)
    >>> round(res.model.mass, 6), round(res.model.delta, 6), res.train["rmse"] < 1e-10
    (2.0, -1.1, True)
    """
    from ..optimize.core import minimize

    t0 = time.perf_counter()
    u_ = as_record(u, "u", min_length=2)
    y_ = as_record(y, "y", min_length=2)
    if y_.size != u_.size:
        raise ParameterError(f"y has {y_.size} samples, u has {u_.size}; they must match")
    if not np.ptp(u_) > 0:
        raise ParameterError("u is constant: the record does not excite the system")
    if not np.ptp(y_) > 0:
        raise ParameterError("y is constant: there is no response to identify")
    check_fit_scale(u_, "u")
    check_fit_scale(y_, "y")
    fs = as_scalar(fs, "fs", positive=True)
    r = as_int(upsample, "upsample", minimum=1)
    if interpolation not in INTERPOLATIONS:
        raise ParameterError(
            f"interpolation = {interpolation!r} is unknown; expected one of {', '.join(INTERPOLATIONS)}"
        )
    beta = as_scalar(beta, "beta", positive=True)
    names, lower, upper, fixed = _search_box(bounds)
    start, stop = _as_range(fit_range, u_.size, "fit_range", minimum=2 * len(names))
    warmup = as_int(warmup, "warmup")
    search = stop - start if search_samples is None else as_int(search_samples, "search_samples", minimum=1)
    search = min(max(search, 2 * len(names)), stop - start)
    starts = as_int(starts, "starts")
    if not isinstance(polish, (bool, dict)):
        raise ParameterTypeError(f"polish must be a bool or a dict of least_squares options, got {polish!r}")
    if validate is not None:
        if not isinstance(validate, (tuple, list)) or len(validate) not in (2, 3):
            raise ParameterTypeError("validate must be (u, y) or (u, y, (start, stop))")
        vu = as_record(validate[0], "validate u", min_length=2)
        vy = as_record(validate[1], "validate y", min_length=2)
        if vy.size != vu.size:
            raise ParameterError(f"validate y has {vy.size} samples, validate u has {vu.size}; they must match")
        v_range = _as_range(validate[2] if len(validate) == 3 else None, vu.size, "validate range", minimum=1)

    columns = [IDENTIFY_PARAMETERS.index(n) for n in names]
    template = np.array([fixed.get(n, 0.0) for n in IDENTIFY_PARAMETERS])

    def to_rows(X: FloatArray) -> FloatArray:
        """Search vectors (S, D) -> core rows [mass, damping, stiffness, alpha, beta, gamma, delta, nu]."""
        P = np.repeat(template[None, :], X.shape[0], axis=0)
        P[:, columns] = X
        rows = np.empty((X.shape[0], 8))
        rows[:, :4] = P[:, :4]
        rows[:, 4] = beta
        rows[:, 5] = P[:, 4] / beta
        rows[:, 6] = P[:, 5] / beta
        rows[:, 7] = P[:, 6]
        return rows

    fine = _upsample(u_, r, interpolation)
    h = 1.0 / (r * fs)
    search_problem = _Problem(fine, r, h, y_, start, start + search, warmup)
    full_problem = _Problem(fine, r, h, y_, start, stop, warmup)

    seen_x: list[FloatArray] = []
    seen_f: list[FloatArray] = []

    def cost(X: FloatArray) -> FloatArray:
        f = search_problem.rmse(to_rows(X))
        seen_x.append(np.array(X, dtype=np.float64))
        seen_f.append(f)
        return f

    res = minimize(
        cost,
        list(zip(lower, upper, strict=False)),
        method=optimizer,
        rng=rng,
        max_iterations=max_iterations,
        population_size=population_size,
        progress=progress,
        callback=callback,
    )
    if not np.isfinite(res.fun):
        raise ParameterError(
            "every simulated candidate failed or diverged: check the units of u (N) and y (m), fs and the bounds"
        )
    x = np.asarray(res.x, dtype=np.float64)
    history: dict[str, Any] = dict(res.history)
    history["parameters"] = names
    method = res.method or str(optimizer)
    evaluations = int(res.nfev)
    if polish is not False and res.message != "interrupted":
        candidates = _starts(np.concatenate(seen_x), np.concatenate(seen_f), lower, upper, starts)
        candidates.append(_box_centre(lower, upper))
        nfev = 0
        screened: list[float] = []
        best: tuple[FloatArray, float] | None = None
        for x0 in candidates:
            xs, fx, n, _ = _least_squares_polish(search_problem, to_rows, x0, lower, upper, {"max_nfev": 20})
            nfev += n
            screened.append(fx)
            if best is None or fx < best[1]:
                best = (xs, fx)
        assert best is not None  # candidates holds the box's centre at least
        before = float(full_problem.rmse(to_rows(x[None, :]))[0])
        x1, f1, n, message = _least_squares_polish(
            full_problem, to_rows, best[0], lower, upper, polish if isinstance(polish, dict) else {}
        )
        nfev += n + 1
        evaluations += nfev
        if f1 < before:
            x = x1
        history["polish"] = {
            "screened": np.array(screened),
            "rmse_before": before,
            "rmse_after": min(f1, before),
            "nfev": nfev,
            "message": message,
        }
        method += "+least_squares"
    model = BoucWenBenchmark(*to_rows(x[None, :])[0])
    train = _scored(model, u_, y_, fs, r, interpolation, (start, stop))
    val = None
    if validate is not None:
        val = _scored(model, vu, vy, fs, r, interpolation, v_range)
    return IdentificationResult(
        model,
        train,
        val,
        method,
        time.perf_counter() - t0,
        history,
        partial=res.interrupted,
        evaluations=evaluations,
    )
