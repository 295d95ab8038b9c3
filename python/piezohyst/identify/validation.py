"""Honest validation of an identified model: the validation span simulated with the model's
state carried from the training span (or from rest, or from its periodic steady state), a
warm-up left out of the score, residual whiteness (autocorrelation, cross-correlation with the
input, a Ljung–Box statistic), a trust verdict and a diagnosis naming the likely cause of a
bad fit (offset, delay, swapped columns, wrong sample rate or time unit, drift).

Every loop over samples is a Rust simulation or a vectorized numpy/scipy call.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, TypeAlias

import numpy as np
import numpy.typing as npt

from .._validate import as_int, as_record
from ..errors import ParameterError
from .core import FloatArray, IdentificationResult, Metrics, _fit_metrics, _layout

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = [
    "RMSE_LIMIT_PERCENT",
    "VALIDATE_FROM",
    "ValidatedResult",
    "diagnose",
    "estimate_period",
    "league_table",
    "parameter_count",
    "residual_whiteness",
    "scored_metrics",
    "trust",
]

#: ``validate_from`` values: ``"carried"`` (the model runs from the training span's start through
#: the validation span, only the validation span scored) or ``"rest"`` (the validation span
#: simulated from the model's rest state, the former behaviour).
VALIDATE_FROM = ("carried", "rest")

#: Validation RMSE (% of the measured range) above which a fit is not trustworthy.
RMSE_LIMIT_PERCENT = 5.0

#: Residuals are "far from white" when more than this fraction of the autocorrelation lags
#: lies outside the 95 % band *and* the residual RMSE exceeds :data:`STRUCTURED_LIMIT_PERCENT`:
#: a hysteresis model's residual on measured data is never white (it holds the model's own
#: low-frequency error), so structure alone is no reason to distrust a fit that is within
#: 1 % of the range.
WHITENESS_LIMIT = 0.5
STRUCTURED_LIMIT_PERCENT = 1.0

#: ``simulate(input) -> output`` of a fitted model.
Simulate: TypeAlias = Callable[[FloatArray], FloatArray]
#: ``refit(input, output, fs) -> validation RMSE in % of range`` used by :func:`diagnose`.
Refit: TypeAlias = Callable[[FloatArray, FloatArray, "float | None"], float]


@dataclass(frozen=True, repr=False)
class ValidatedResult(IdentificationResult):
    """:class:`~piezohyst.identify.IdentificationResult` with the validation report:
    ``assessment`` holds how the spans were scored (``validate_from``, ``warmup``,
    ``periodic``), the residual whiteness of the training and validation spans
    (:func:`residual_whiteness`) and the trust verdict (:func:`trust`).

    Parameters
    ----------
    model : object
        The identified model.
    train : dict
        Free-run metrics on the training record (:func:`~piezohyst.identify.core.fit_metrics`).
    validation : dict or None
        The same on the validation span (state carried), when given.
    method : str
        How it was fitted (``"ls"``, ``"vp-de+polish"``, ...).
    wall_time : float
        Seconds the identification took.
    history : dict
        The optimizer's per-iteration history (empty for a linear fit).
    simulator : callable, optional
        How :meth:`simulate` predicts the output for models without a ``simulate(input)``.
    partial : bool
        Ctrl-C stopped the optimizer.
    evaluations : int
        Candidate evaluations the fit spent.
    assessment : dict
        ``validate_from``, ``warmup``, ``periodic``, the whiteness of the ``train`` and
        ``validation`` spans, ``trusted`` and its ``reasons``.

    Examples
    --------
    :func:`~piezohyst.identify` returns one when given validation data; built here by hand:

    >>> from piezohyst import PI
    >>> from piezohyst.identify import IdentificationResult
    >>> m = {"rmse": 0.01, "max_error": 0.03, "rmse_percent": 0.5, "max_error_percent": 1.5}
    >>> res = ValidatedResult(PI([0.2], [0.5]), m, m, "ls", 0.1, assessment={"trusted": True, "reasons": []})
    >>> isinstance(res, IdentificationResult), res.assessment["trusted"], res.metrics["validation"]["rmse"]
    (True, True, 0.01)
    """

    assessment: dict[str, Any] = field(default_factory=dict, compare=False)


def _check_warmup(warmup: object, n: int, name: str) -> int:
    w = as_int(warmup, "warmup", minimum=0)
    if w >= n - 1:
        raise ParameterError(f"warmup = {w} leaves fewer than 2 samples of the {name} span ({n} samples) to score")
    return w


def estimate_period(input: npt.ArrayLike) -> int:
    """The input's period in samples: the first peak of its autocorrelation (by FFT, unbiased)
    above 0.8 after the first zero crossing. Raises :class:`ParameterError` when the input is not periodic
    within the record (no repeat with correlation above 0.8).

    Parameters
    ----------
    input : array_like, shape (N,)
        The input record, N >= 4.

    Returns
    -------
    int
        The period, samples.

    Examples
    --------
    >>> import numpy as np
    >>> k = np.arange(1000)
    >>> estimate_period(np.sin(2 * np.pi * k / 125)), estimate_period(np.sign(np.sin(2 * np.pi * (k + 0.5) / 80)))
    (125, 80)
    """
    from scipy.signal import correlate

    v = as_record(input, "input", min_length=4)
    x = v - v.mean()
    if not np.any(x):
        raise ParameterError("input is constant: it has no period")
    acf = correlate(x, x, mode="full", method="fft")[x.size - 1 :]
    acf = acf / acf[0] * x.size / (x.size - np.arange(x.size))  # unbiased
    half = acf[: x.size // 2]
    neg = np.flatnonzero(half < 0)
    if neg.size == 0:
        raise ParameterError("input does not repeat within the record: give the period in samples")
    tail = half[neg[0] :]
    high = np.flatnonzero(tail >= 0.8)
    if high.size == 0:
        k = int(neg[0] + np.argmax(tail))
        raise ParameterError(
            f"input is not periodic (best repeat at {k} samples correlates {half[k]:.2f} < 0.8): "
            "give the period in samples"
        )
    # the first repeat: the peak of the first run of lags correlating >= 0.8
    breaks = np.flatnonzero(np.diff(high) > 1)
    run = neg[0] + (high[: breaks[0] + 1] if breaks.size else high)
    # within it, the lag at which the record best repeats itself
    mismatch = [float(np.mean((x[k:] - x[:-k]) ** 2)) for k in run]
    return int(run[int(np.argmin(mismatch))])


def scored_metrics(
    simulate: Simulate,
    input: FloatArray,
    output: FloatArray,
    *,
    start: int = 0,
    warmup: int = 0,
    periodic: int | None = None,
) -> tuple[Metrics, FloatArray]:
    """Metrics of ``output[start + warmup:]`` against the model's free run over the whole
    ``input`` (the state carried over ``input[:start]``); with ``periodic = P`` the input's
    first ``P`` samples are simulated first (one period before the record: the periodic
    steady state). Returns ``(metrics, residual)``, the residual over the scored samples.

    Parameters
    ----------
    simulate : callable
        ``simulate(input) -> output`` of the fitted model.
    input, output : ndarray, shape (N,)
        The simulated stretch and its measured output.
    start : int, default 0
        First sample of the scored span (the state carried over the samples before it).
    warmup : int, default 0
        Samples after ``start`` simulated but not scored.
    periodic : int, optional
        The input's period, samples: one period simulated before the record.

    Returns
    -------
    metrics : dict
        ``rmse``, ``max_error`` and both in % of the measured range.
    residual : ndarray, shape (N - start - warmup,)
        Predicted minus measured output over the scored samples.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst import PI
    >>> model = PI([0.2, 0.4], [0.5, 0.2], p0=0.8)
    >>> v = np.sin(2 * np.pi * np.arange(1000) / 250)
    >>> y = model.simulate(v)
    >>> metrics, residual = scored_metrics(model.simulate, v, y + 0.1, start=500, warmup=10)
    >>> round(metrics["rmse"], 12), residual.shape
    (0.1, (490,))
    """
    lead = 0 if periodic is None else periodic
    u = input if periodic is None else np.concatenate([input[:periodic], input])
    predicted = np.asarray(simulate(u), dtype=np.float64)[lead + start + warmup :]
    measured = output[start + warmup :]
    metrics = _fit_metrics(predicted, measured)
    return metrics, predicted - measured


def residual_whiteness(residual: npt.ArrayLike, input: npt.ArrayLike, max_lag: int | None = None) -> dict[str, Any]:
    """Whiteness of a residual: its autocorrelation at lags ``1..L`` and its cross-correlation
    with the (centred) input at lags ``-L..L`` against the 95 % band ``1.96 / sqrt(n)``.

    Returns ``lags`` (L: ``min(50, n // 5)`` by default), ``band``, ``autocorrelation_outside``
    and ``cross_correlation_outside`` (fractions of lags outside the band), ``ljung_box`` (the
    statistic ``n (n + 2) sum r_k^2 / (n - k)``) with its ``ljung_box_p`` (chi-squared, L
    degrees of freedom), ``cross_peak_lag`` (the lag of the largest ``|cross-correlation|``,
    positive when the residual follows the input) and ``cross_peak``, and the residual's
    ``mean`` and ``trend`` (the least-squares line's change over the span), in output units.

    Parameters
    ----------
    residual : array_like, shape (N,)
        Predicted minus measured output, N >= 4.
    input : array_like, shape (N,)
        The input over the same samples.
    max_lag : int, optional
        ``L``, the largest lag; default ``min(50, N // 5)``.

    Returns
    -------
    dict
        The statistics above, plus ``lag1`` (the lag-1 autocorrelation) and ``samples``.

    Examples
    --------
    >>> import numpy as np
    >>> v = np.sin(2 * np.pi * np.arange(1000) / 250)
    >>> white = residual_whiteness(np.random.default_rng(0).normal(size=1000), v)
    >>> white["lags"], white["autocorrelation_outside"] < 0.1
    (50, True)
    >>> residual_whiteness(np.sin(2 * np.pi * np.arange(1000) / 100), v)["autocorrelation_outside"]
    0.96
    """
    from scipy.signal import correlate
    from scipy.stats import chi2

    r = as_record(residual, "residual", min_length=4)
    v = as_record(input, "input", min_length=4)
    if v.size != r.size:
        raise ParameterError(f"input has {v.size} samples, residual has {r.size}; they must match")
    n = r.size
    lags = min(50, max(1, n // 5)) if max_lag is None else as_int(max_lag, "max_lag", minimum=1)
    # the correlations are scale-free: computed on the records scaled to a largest magnitude of 1
    # (a residual near 1e300 would overflow its squares, a subnormal one lose them)
    e = r / (float(np.max(np.abs(r))) or 1.0)
    x = v / (float(np.max(np.abs(v))) or 1.0)
    e = e - e.mean()
    x = x - x.mean()
    see, sxx = float(e @ e), float(x @ x)
    if see == 0.0:
        acf = np.zeros(lags)
        ccf = np.zeros(2 * lags + 1)
    else:
        acf = correlate(e, e, mode="full", method="fft")[n : n + lags] / see
        full = correlate(e, x, mode="full", method="fft")  # index n - 1 + k: sum e[i + k] x[i]
        ccf = full[n - 1 - lags : n + lags] / np.sqrt(see * sxx) if sxx > 0 else np.zeros(2 * lags + 1)
    band = 1.96 / np.sqrt(n)
    q = float(n * (n + 2) * np.sum(acf**2 / (n - np.arange(1, lags + 1))))
    peak = int(np.argmax(np.abs(ccf)))
    t = np.arange(n, dtype=np.float64)
    slope = float(np.polyfit(t, r, 1)[0]) if n > 2 else 0.0
    return {
        "lags": lags,
        "band": float(band),
        "autocorrelation_outside": float(np.mean(np.abs(acf) > band)),
        "cross_correlation_outside": float(np.mean(np.abs(ccf) > band)),
        "ljung_box": q,
        "ljung_box_p": float(chi2.sf(q, lags)),
        "cross_peak_lag": peak - lags,
        "cross_peak": float(ccf[peak]),
        "mean": float(r.mean()),
        "trend": slope * (n - 1),
        "lag1": float(acf[0]),
        "samples": n,
    }


def trust(metrics: Metrics, whiteness: dict[str, Any]) -> tuple[bool, list[str]]:
    """``(trusted, reasons)``: not trusted when the RMSE exceeds :data:`RMSE_LIMIT_PERCENT`
    of the range, or when the residual is far from white (more than :data:`WHITENESS_LIMIT`
    of its autocorrelation lags outside the 95 % band with an RMSE above
    :data:`STRUCTURED_LIMIT_PERCENT`).

    Parameters
    ----------
    metrics : dict
        The scored span's metrics (``rmse_percent`` is read).
    whiteness : dict
        Its :func:`residual_whiteness`.

    Returns
    -------
    trusted : bool
    reasons : list of str
        Why not (empty when trusted).

    Examples
    --------
    >>> import numpy as np
    >>> v = np.sin(2 * np.pi * np.arange(1000) / 250)
    >>> trust({"rmse_percent": 0.5}, residual_whiteness(np.random.default_rng(0).normal(size=1000), v))
    (True, [])
    >>> trust({"rmse_percent": 8.0}, residual_whiteness(np.random.default_rng(0).normal(size=1000), v))
    (False, ['RMSE 8 % of range > 5 %'])
    """
    reasons = []
    if metrics["rmse_percent"] > RMSE_LIMIT_PERCENT:
        reasons.append(f"RMSE {metrics['rmse_percent']:.3g} % of range > {RMSE_LIMIT_PERCENT:g} %")
    if whiteness["autocorrelation_outside"] > WHITENESS_LIMIT and metrics["rmse_percent"] > STRUCTURED_LIMIT_PERCENT:
        reasons.append(
            f"residual far from white ({100 * whiteness['autocorrelation_outside']:.0f} % of "
            f"{whiteness['lags']} autocorrelation lags outside the 95 % band, RMSE "
            f"{metrics['rmse_percent']:.3g} % > {STRUCTURED_LIMIT_PERCENT:g} %)"
        )
    return not reasons, reasons


def diagnose(
    refit: Refit,
    train: tuple[FloatArray, FloatArray],
    residual: FloatArray,
    whiteness: dict[str, Any],
    rmse_percent: float,
    fs: float | None,
    *,
    rate_refit: Callable[[float], float] | None = None,
    max_lag: int | None = None,
) -> list[dict[str, Any]]:
    """The likely causes of a bad fit, each ``{"cause", "evidence"}``, strongest first.

    ``refit(input, output, fs)`` fits the same kind again and returns its validation RMSE in %
    of range (same spans); ``train`` is the training ``(input, output)``, ``residual`` and
    ``whiteness`` (:func:`residual_whiteness`) those of the scored (validation) span and
    ``rmse_percent`` its RMSE. Checks, in order:

    - ``offset``: the residual's mean is most of its RMS (a constant shift of the output);
    - ``drift``: a straight line explains most of the residual (a trend over the span);
    - ``delay``: refitted with the output shifted by the lag of the residual/input
      cross-correlation peak (and by a search over small lags), the error falls by half;
    - ``swapped columns``: refitted with input and output exchanged, the error falls by half;
    - ``sample rate``: ``rate_refit(fs)`` fits a model whose dynamics have physical time
      constants (creep lags of 3 ms to 30 s) at a sample rate; when it fits at ``fs`` x 1000 or
      / 1000 (a time column in ms read as s, or the reverse) with half the error it has at the
      stated ``fs`` (and half the base error), the record's time scale contradicts ``fs``.

    Parameters
    ----------
    refit : callable
        ``refit(input, output, fs) -> validation RMSE in % of range``.
    train : tuple of ndarray
        The training ``(input, output)``.
    residual : ndarray
        The scored span's residual.
    whiteness : dict
        Its :func:`residual_whiteness`.
    rmse_percent : float
        Its RMSE, % of range.
    fs : float or None
        The stated sample rate, Hz.
    rate_refit : callable, optional
        ``rate_refit(fs) -> validation RMSE in %`` of a model with physical time constants.
    max_lag : int, optional
        Largest output lag tried; default a tenth of the training span.

    Returns
    -------
    list of dict
        ``{"cause", "evidence"}`` (and ``"lag"`` for a delay), strongest first.

    Examples
    --------
    A residual that is mostly a constant, and a fit that only works with the columns swapped:

    >>> import numpy as np
    >>> v = np.sin(np.linspace(0, 20, 400))
    >>> y = 2.0 * v
    >>> residual = 0.5 + 0.01 * np.sin(np.linspace(0, 50, 400))
    >>> refit = lambda u, out, fs: 1.0 if u is y else 9.0
    >>> causes = diagnose(refit, (v, y), residual, residual_whiteness(residual, v), 9.0, None)
    >>> [c["cause"] for c in causes]
    ['offset', 'swapped columns']
    """
    causes: list[dict[str, Any]] = []
    rms = float(np.sqrt(np.mean(residual**2))) or 1.0
    mean = whiteness["mean"]
    if abs(mean) > 0.6 * rms:
        causes.append(
            {"cause": "offset", "evidence": f"residual mean {mean:.4g} is {100 * abs(mean) / rms:.0f} % of its RMS"}
        )
    t = np.linspace(-1.0, 1.0, residual.size)
    line = np.polyval(np.polyfit(t, residual, 1), t)
    explained = 1.0 - float(np.sum((residual - line) ** 2)) / max(float(np.sum((residual - mean) ** 2)), 1e-300)
    if explained > 0.5 and abs(whiteness["trend"]) > 0.5 * rms:
        causes.append(
            {
                "cause": "drift",
                "evidence": f"a trend of {whiteness['trend']:.4g} over the span explains {100 * explained:.0f} % "
                "of the residual's variance",
            }
        )
    v, y = train
    better = 0.5 * rmse_percent
    n = v.size
    bound = max(1, n // 10) if max_lag is None else max_lag
    candidates = {int(whiteness["cross_peak_lag"])} | {
        int(k) for k in np.unique(np.geomspace(1, bound, 12).astype(int))
    }
    best: tuple[float, int] | None = None
    for k in sorted(c for c in candidates if 0 < c <= bound):
        e = refit(v[:-k], y[k:], fs)
        if best is None or e < best[0]:
            best = (e, k)
    if best is not None and best[0] < better:
        causes.append(
            {
                "cause": "delay",
                "evidence": f"the output lags the input by about {best[1]} samples: refitted with that lag, "
                f"validation RMSE {best[0]:.3g} % instead of {rmse_percent:.3g} %",
                "lag": best[1],
            }
        )
    e = refit(y, v, fs)
    if e < better:
        causes.append(
            {
                "cause": "swapped columns",
                "evidence": f"with input and output exchanged the fit gives {e:.3g} % instead of {rmse_percent:.3g} %",
            }
        )
    if rate_refit is not None and fs is not None:
        stated = rate_refit(fs)
        for factor, unit in ((1e3, "time in ms read as s"), (1e-3, "time in s read as ms")):
            e = rate_refit(fs * factor)
            if e < 0.5 * stated and e < better:
                causes.append(
                    {
                        "cause": "sample rate",
                        "evidence": f"a model with creep time constants in seconds fits the record at "
                        f"{fs * factor:.6g} Hz with {e:.3g} % RMSE, at the stated {fs:.6g} Hz with {stated:.3g} % "
                        f"({unit}?)",
                    }
                )
                break
    return causes


def plot_validation(
    simulate: Simulate,
    input: FloatArray,
    output: FloatArray,
    spans: dict[str, tuple[int, int]],
    *,
    periodic: int | None = None,
) -> Figure:
    """Figure of a validation: loop (measured and model), time series with the scored spans
    shaded, residual, and the residual's autocorrelation with the 95 % band. ``input`` and
    ``output`` are the simulated stretch (state carried), ``spans`` the scored ``(start, stop)``
    per name, in samples of the stretch."""
    import matplotlib.pyplot as plt

    lead = 0 if periodic is None else periodic
    u = input if periodic is None else np.concatenate([input[:periodic], input])
    yp = np.asarray(simulate(u), dtype=np.float64)[lead:]
    r = yp - output
    fig, axes = plt.subplots(2, 2, figsize=(12, 7))
    ax = axes[0, 0]
    ax.plot(input, output, lw=0.8, label="measured")
    ax.plot(input, yp, lw=0.8, label="model")
    ax.set(xlabel="input", ylabel="output", title="hysteresis loop")
    ax.legend()
    ax = axes[0, 1]
    ax.plot(output, lw=0.8, label="measured")
    ax.plot(yp, lw=0.8, label="model")
    for (name, (a, b)), colour in zip(spans.items(), ("tab:green", "tab:red"), strict=False):
        ax.axvspan(a, b, color=colour, alpha=0.08, label=name)
    ax.set(xlabel="sample", title="time series (state carried)")
    ax.legend()
    ax = axes[1, 0]
    ax.plot(r, lw=0.8)
    ax.set(xlabel="sample", ylabel="model - measured", title="residual")
    ax = axes[1, 1]
    name, (a, b) = list(spans.items())[-1]
    w = residual_whiteness(r[a:b], input[a:b])
    from scipy.signal import correlate

    e = r[a:b] - r[a:b].mean()
    acf = correlate(e, e, mode="full", method="fft")[e.size - 1 : e.size + w["lags"]] / max(float(e @ e), 1e-300)
    ax.stem(np.arange(acf.size), acf)
    ax.axhspan(-w["band"], w["band"], color="grey", alpha=0.2)
    ax.set(xlabel="lag (samples)", title=f"residual autocorrelation ({name})")
    fig.tight_layout()
    return fig


def parameter_count(model: object) -> int:
    """Parameters a fit adjusts: the linear families' regressor columns (their structure is
    fixed; a Preisach grid's offset, slope, creep lags and cells above 0: the cells
    :meth:`~piezohyst.Preisach.extrapolated` adds beyond the training range are fixed zeros or
    copies, and cells the record cannot tell apart share one weight), Bouc–Wen's four (``a``,
    ``beta``, ``gamma``, ``d``; ``n = 1``), else the model's row length; plus one for an input
    delay and one per drift term.

    Parameters
    ----------
    model : object
        The fitted model.

    Returns
    -------
    int

    Examples
    --------
    >>> from piezohyst import PI
    >>> from piezohyst.models.model import Drift
    >>> model = PI([0.2, 0.4], [0.5, 0.2], p0=0.8)
    >>> parameter_count(model), parameter_count(model.with_input_delay(3).with_drift(Drift(slope=0.1)))
    (3, 5)
    """
    from ..models.differential import BoucWen
    from ..models.pi import PI, GeneralizedPI, RateDependentPI
    from ..models.preisach import Preisach

    drift = getattr(model, "drift", None)
    extra = int(getattr(model, "input_delay", 0) > 0)
    if drift is not None:
        extra += len(drift.taus) + int(drift.slope != 0.0)
    if isinstance(model, Preisach):
        lags = 0 if model.creep is None else model.creep.terms
        return 2 + int(np.count_nonzero(model.weights)) + lags + extra
    if isinstance(model, (PI, GeneralizedPI, RateDependentPI)):
        return int(_layout(model)[0].size) + extra
    if isinstance(model, BoucWen):
        return 4 + extra
    row = getattr(model, "to_row", None)
    return int(np.size(row())) + extra if callable(row) else 0


def league_table(
    results: list[tuple[str, int, IdentificationResult | None, str | None]],
    n_train: int,
    *,
    labels: list[str] | None = None,
) -> tuple[list[dict[str, Any]], int]:
    """Rank fitted candidates ``(kind, creep, result or None, error)``: ``(rows, index of the
    chosen result)``; ``labels`` name them (default: ``kind+creepM``).

    With validation data: by validation RMSE (state carried, as :func:`identify` scores it),
    the chosen model being the one with the fewest parameters whose validation MSE is within
    one standard error of the best (the "one-standard-error rule" of hold-out model
    selection): the held-out error already charges a model for over-fitting, so the penalty
    only has to keep a larger model from winning by less than the hold-out estimate's own
    noise. The standard error of the best MSE is ``MSE sqrt(2 / n_eff)``, ``n_eff`` the
    validation samples discounted by the residual's lag-1 autocorrelation
    (``n (1 - r1) / (1 + r1)``). Without validation data: by BIC on the training record,
    ``n ln(MSE) + k ln(n)``.

    Parameters
    ----------
    results : list of tuple
        ``(kind, creep, result or None, error or None)`` per candidate.
    n_train : int
        Training samples (the BIC's ``n``; the validation samples when the results carry none).
    labels : list of str, optional
        Names of the candidates, one each.

    Returns
    -------
    rows : list of dict
        One per candidate, ranked: ``rank``, ``name``, ``parameters``, the RMSEs, ``score``,
        ``chosen``...; those that could not be fitted last, with their ``error``.
    chosen : int
        Index in ``results`` of the chosen candidate.

    Examples
    --------
    A larger model better by less than the hold-out's noise loses to the smaller one:

    >>> from piezohyst import PI
    >>> from piezohyst.identify import IdentificationResult
    >>> def result(model, rmse):
    ...     m = {"rmse": rmse, "rmse_percent": 10 * rmse}
    ...     return IdentificationResult(model, m, m, "ls", 0.0)
    >>> small = result(PI([0.2, 0.4], [0.5, 0.2]), 0.100)
    >>> large = result(PI([0.1, 0.2, 0.3, 0.4], [0.5, 0.2, 0.1, 0.1]), 0.099)
    >>> candidates = [("pi", 0, small, None), ("pi", 0, large, None), ("mpi", 0, None, "failed")]
    >>> rows, chosen = league_table(candidates, 1000, labels=["pi2", "pi4", "mpi"])
    >>> chosen, [(r["name"], r["rank"], r["chosen"]) for r in rows]
    (0, [('pi4', 1, False), ('pi2', 2, True), ('mpi', None, False)])
    """
    fitted = [(i, r) for i, (_, _, r, _) in enumerate(results) if r is not None]
    if not fitted:
        raise ParameterError("no candidate model could be fitted: " + "; ".join(str(e) for *_, e in results))
    has_val = all(r.validation is not None for _, r in fitted)
    score: dict[int, float] = {}
    k = {i: parameter_count(r.model) for i, r in fitted}
    chosen: int
    if has_val:
        for i, r in fitted:
            assert r.validation is not None
            score[i] = r.validation["rmse"] ** 2
        best = min(score, key=lambda i: score[i])
        w = getattr(fitted[[j for j, _ in fitted].index(best)][1], "assessment", {}).get("validation") or {}
        n = int(w.get("samples", n_train))
        r1 = min(max(float(w.get("lag1", 0.0)), 0.0), 0.999)
        n_eff = max(n * (1 - r1) / (1 + r1), 1.0)
        limit = score[best] * (1 + np.sqrt(2.0 / n_eff))
        within = [i for i in score if score[i] <= limit]
        chosen = min(within, key=lambda i: (k[i], score[i]))
        criterion = "validation RMSE"
    else:
        for i, r in fitted:
            mse = max(r.train["rmse"] ** 2, 1e-300)
            score[i] = n_train * float(np.log(mse)) + k[i] * float(np.log(n_train))
        chosen = min(score, key=lambda i: score[i])
        within = [chosen]
        limit = float("nan")
        criterion = "BIC (train)"
    order = sorted(score, key=lambda i: score[i])
    names = [k + (f"+creep{c}" if c else "") for k, c, _, _ in results] if labels is None else list(labels)
    if len(names) != len(results):
        raise ParameterError(f"labels has {len(names)} names for {len(results)} candidates")
    rows: list[dict[str, Any]] = []
    for rank, i in enumerate(order, 1):
        kind, creep, got, _ = results[i]
        assert got is not None
        r = got
        rows.append(
            {
                "rank": rank,
                "name": names[i],
                "kind": kind,
                "creep": creep,
                "parameters": k[i],
                "train_rmse_percent": r.train["rmse_percent"],
                "validation_rmse_percent": None if r.validation is None else r.validation["rmse_percent"],
                "score": score[i],
                "within_one_se": i in within if has_val else None,
                "criterion": criterion
                + (" (within 1 SE of the best, fewer parameters)" if i == chosen and i != order[0] else ""),
                "chosen": i == chosen,
            }
        )
    for j, (kind, creep, got, err) in enumerate(results):
        if got is None:
            rows.append(
                {
                    "rank": None,
                    "name": names[j],
                    "kind": kind,
                    "creep": creep,
                    "error": err,
                    "chosen": False,  # not fitted (too few samples for it, ...): never the winner
                }
            )
    return rows, chosen
