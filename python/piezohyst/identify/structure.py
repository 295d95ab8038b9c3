"""Structure decisions of an identification, taken on the training span only.

A measured record carries more than the actuator's hysteresis: the measurement chain delays
the output (a sensor's filter, a DAQ's latency), a sensor drifts, a quiet lead-in precedes the
excitation, and the actuator's memory at the record's first sample is unknown. What a careful
engineer decides before fitting, :func:`choose_structure` decides from the training span alone
(the held-out validation span is never looked at):

- **the fit's first sample** (:func:`fit_start`): a quiet lead-in (the input has not started to
  move: :func:`~piezohyst.signals.preprocess.find_excitation_start`) and the wiping-out of the
  unknown initial memory (a rate-independent hysteresis forgets its history once the input has
  reached the extremes of its range: until then the model, started at rest, and the actuator,
  started wherever its past left it, disagree for reasons no parameter can fix). The model is
  still simulated from the training span's first sample; the samples before the fit's start
  are left out of the fit's cost, not out of the simulation. Whether to skip the wiping-out
  too is weighed by the internal split below (on a span of one or two cycles the first sweep
  is data the fit cannot spare);
- **the input delay** (samples): the delay of the model's input (``HysteresisModel.input_delay``)
  whose fit has the smallest training error (one parameter: the in-sample error is a fair
  judge), searched on a grid from 0 to ``max_delay`` then refined to the sample;
- **a drift term** (:class:`DriftBasis`): fitted with the model when it predicts the later part
  of the training span better. An internal split: the model (with the chosen delay) is fitted
  on the first ``split`` of the training span (from the fit's start) and scored on the rest, as
  the validation is scored (the simulation carried on); a drift basis is kept only when it
  beats the model without drift by more than the standard error of that score (the
  one-standard-error rule, with the residual's autocorrelation discounting the samples).

For the linear families (fixed structure) all of this runs on one regressor matrix: their
output is linear in the parameters, a delay of ``d`` samples shifts the regressors' rows (the
first row held, as :meth:`HysteresisModel.simulate` holds the first input), so each candidate
delay and each split is a small Gram-matrix solve (:class:`_DelayedGram`), not a new
simulation. (Creep lags and rate terms are not exactly shifted by a held first input: the
choice is made on the shifted rows; the final fit at the chosen delay is exact.)

Every loop here is over candidate delays or drift bases, never over samples.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from .._validate import as_int, as_record, as_scalar
from ..errors import DataError, ParameterError
from ..models.preisach import Preisach
from .core import DriftBasis, FloatArray, LinearModel, _design, _mixed_nnls, delayed

__all__ = [
    "DRIFT_BASES",
    "DriftBasis",
    "StructureChoice",
    "choose_structure",
    "decide_structure",
    "default_max_delay",
    "delayed",
    "drift_bases",
    "fit_start",
    "residual_lag",
]


#: The drift bases :func:`decide_structure` offers by default, as multiples of the training
#: span's length ``T``: an exponential settling with ``tau = T`` or with ``tau = 3 T``, the
#: internal split choosing (or neither). A settling of ``tau = T`` has done 63 % of its change
#: within the training span and can add at most 37 % more, so a drift fitted to what was creep
#: or noise costs little; but a slow sensor drift (a long warm-up) it bends flat too early, and
#: over a validation span two or three times the training span the error grows. ``3 T``
#: follows such a drift (28 % done within the span) and still levels off, unlike a ramp, which
#: extrapolates the trend without end. Measured by the acceptance command (state carried) on
#: the 10 kHz lookalikes of ``tests/lookalike_records.py``: ``bench/identify_auto.py`` (seeds
#: 0-5) 14 of 18 runs within 0.5 % of the range against 13 with ``T`` alone, the worst 0.57 %
#: against 0.96 %; seeds 6-11, drawn after the choice, 16 of 18 against 15 (four runs worse,
#: within the target); yan9a and the 5 kHz lookalikes unchanged. A ramp as the second basis
#: instead: seed 4's first span 0.40 -> 0.73 %.
DRIFT_BASES: tuple[tuple[str, float | None], ...] = (("exp", 1.0), ("exp", 3.0))


def default_max_delay(fs: float | None, n: int) -> int:
    """The largest input delay searched by default: 20 ms of samples (at least 10), at most a
    fifth of the record; 10 samples (or a fifth of the record) without a sample rate.

    Parameters
    ----------
    fs : float or None
        Sample rate, Hz.
    n : int
        Samples of the training span.

    Returns
    -------
    int

    Examples
    --------
    >>> default_max_delay(10000.0, 5000), default_max_delay(None, 5000), default_max_delay(10000.0, 501)
    (200, 10, 100)
    """
    m = 10 if fs is None else max(10, round(0.02 * float(fs)))
    return int(max(0, min(m, (n - 1) // 5)))


def fit_start(
    input: npt.ArrayLike, fs: float | None = None, *, sweep: float = 0.8, cap: float = 0.3
) -> tuple[int, dict[str, Any]]:
    """The first sample of a training span the fit's cost should count, with the reasons.

    ``lead_in``: with ``fs``, the samples of a quiet lead-in
    (:func:`~piezohyst.signals.preprocess.find_excitation_start`, 0 when the span starts
    excited). ``wipe_out``: then the samples until the input has swept ``sweep`` of its range
    (the running maximum minus the running minimum): the model starts at rest, the actuator
    where its past left it (on a descending branch at a minimum, say), and they disagree until
    an excursion of the input has wiped that memory out (a play operator of threshold ``r`` is
    determined by a monotone excursion of ``2 r``; the default thresholds reach half the range:
    80 % leaves the widest few). At most ``cap`` of the excited span. Returns ``(start,
    report)``, ``start = lead_in + wipe_out``.

    Parameters
    ----------
    input : array_like, shape (N,)
        The training span's input, N >= 2.
    fs : float, optional
        Sample rate, Hz; ``None``: no lead-in is looked for.
    sweep : float, default 0.8
        Fraction of the input's range to sweep before the fit starts.
    cap : float, default 0.3
        Largest wipe-out, as a fraction of the excited span.

    Returns
    -------
    start : int
        The fit's first sample.
    report : dict
        ``{"lead_in": ..., "wipe_out": ..., "start": ...}``, samples.

    Examples
    --------
    >>> import numpy as np
    >>> v = np.concatenate([np.zeros(500), np.sin(np.linspace(0, 20 * np.pi, 4000))])
    >>> start, why = fit_start(v, fs=1000.0)
    >>> why["lead_in"], why["wipe_out"]
    (501, 240)
    """
    from ..signals.preprocess import find_excitation_start

    v = as_record(input, "input", min_length=2)
    frac = as_scalar(cap, "cap", positive=True)
    share = as_scalar(sweep, "sweep", positive=True)
    lead = 0
    if fs is not None:
        try:
            lead = find_excitation_start(v, as_scalar(fs, "fs", positive=True))
        except DataError:
            lead = 0
    rest = v[lead:]
    swept = np.maximum.accumulate(rest) - np.minimum.accumulate(rest)
    reached = np.flatnonzero(swept >= share * swept[-1])
    wipe = int(min(reached[0], frac * rest.size)) if swept[-1] > 0 else 0
    return lead + wipe, {"lead_in": lead, "wipe_out": wipe, "start": lead + wipe}


@dataclass(frozen=True)
class StructureChoice:
    """What :func:`choose_structure` decided, with the evidence (JSON-ready by :meth:`to_dict`).

    Parameters
    ----------
    delay : int
        The input delay, samples.
    drift : DriftBasis
        The drift basis kept (empty: no drift).
    start : int
        The fit's first sample.
    delay_rmse : dict of int to float
        Training RMSE (output units) of each delay tried.
    drift_rmse : dict of str to float
        Internal-split RMSE (output units) of each drift basis tried, ``"none"`` included.
    split : int, optional
        The internal split: the fit on ``[start, split)``, scored on ``[split, n)``.
    n_eff : float, optional
        Effective samples of the internal score (autocorrelation discounted).
    start_rmse : dict of int to float
        Internal-split RMSE (output units) of each fit start weighed.
    residual_lag : float, optional
        The check of the delay: the training residual's least-squares coefficient on the
        fitted output's slope (samples; :func:`residual_lag`). Near 0 when the delay is right
        (the residual carries no phase lag left); ``+k``: the fit runs ``k`` samples ahead of
        the data.
    drift_by : str, optional
        What chose ``drift``: ``"internal split"`` (:func:`choose_structure`, the default) or
        ``"validation"`` (``identify --model auto`` ranking its finalists' drift variants).

    Examples
    --------
    >>> c = StructureChoice(delay=3, drift=DriftBasis(), start=120, delay_rmse={0: 0.2, 3: 0.1})
    >>> c.to_dict()["delay_rmse"], c.to_dict()["fit_start"], c.drift.empty
    ({'0': 0.2, '3': 0.1}, 120, True)
    """

    delay: int
    drift: DriftBasis
    start: int
    #: Training RMSE (output units) of each delay tried.
    delay_rmse: dict[int, float] = field(default_factory=dict)
    #: Internal-split RMSE (output units) of each drift basis tried, ``"none"`` included.
    drift_rmse: dict[str, float] = field(default_factory=dict)
    #: The internal split: the fit on ``[start, split)``, scored on ``[split, n)``.
    split: int | None = None
    #: Effective samples of the internal score (autocorrelation discounted).
    n_eff: float | None = None
    #: Internal-split RMSE (output units) of each fit start weighed (the earliest and the wiped).
    start_rmse: dict[int, float] = field(default_factory=dict)
    #: The training residual's coefficient on the fitted output's slope, samples.
    residual_lag: float | None = None
    #: What chose the drift basis: ``"internal split"`` (this function), or ``"validation"``
    #: (``identify --model auto`` ranking the league's drift variants on the validation span).
    drift_by: str = "internal split"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: the decisions and their evidence (delays as string keys).

        Returns
        -------
        dict
            ``delay``, ``drift`` (:meth:`DriftBasis.to_dict`), ``fit_start``, ``delay_rmse``,
            ``drift_rmse``, ``split``, ``n_eff``, ``start_rmse``, ``residual_lag`` and
            ``drift_chosen_by``.

        Examples
        --------
        >>> d = StructureChoice(delay=2, drift=DriftBasis(linear=True), start=0).to_dict()
        >>> d["delay"], d["drift"]["name"], d["split"]
        (2, 'linear', None)
        """
        return {
            "delay": self.delay,
            "drift": self.drift.to_dict(),
            "fit_start": self.start,
            "delay_rmse": {str(k): v for k, v in sorted(self.delay_rmse.items())},
            "drift_rmse": dict(self.drift_rmse),
            "split": self.split,
            "n_eff": self.n_eff,
            "start_rmse": {str(k): v for k, v in sorted(self.start_rmse.items())},
            "residual_lag": self.residual_lag,
            "drift_chosen_by": self.drift_by,
        }


class _DelayedGram:
    """The normal equations of a linear model's fit with its input delayed by ``d`` samples,
    for any ``d`` and any span of rows, from one regressor matrix.

    ``A`` holds the regressors of the undelayed input (columns equilibrated, duplicates and
    all but one constant column removed), ``T`` the drift columns (not shifted: they are
    functions of time), ``y`` the output (centred and scaled). With the delay, row ``k`` of the
    regressors is ``A[max(k - d, 0)]`` (the first input held). Gram matrices of contiguous rows
    of ``A`` come from cumulative sums cached at the rows asked for."""

    def __init__(self, A: FloatArray, free: npt.NDArray[np.bool_], y: FloatArray) -> None:
        self.A = A
        self.free = free
        self.y = y
        self._cum: dict[int, FloatArray] = {0: np.zeros((A.shape[1], A.shape[1]))}

    def _gram_to(self, m: int) -> FloatArray:
        """``A[:m].T @ A[:m]`` from the nearest cached row count (the rows between added or
        removed: the delays tried are close, so is each new count to a cached one)."""
        if m not in self._cum:
            near = min(self._cum, key=lambda k: abs(k - m))
            part = self.A[min(near, m) : max(near, m)]
            g = part.T @ part
            self._cum[m] = self._cum[near] + g if near < m else self._cum[near] - g
        return self._cum[m]

    def normal(
        self, d: int, lo: int, hi: int, T: FloatArray
    ) -> tuple[FloatArray, FloatArray, float, npt.NDArray[np.bool_]]:
        """``(G, b, y'y, free)`` of rows ``[lo, hi)`` of ``[A_d | T]`` against ``y``."""
        A, y = self.A, self.y
        held = max(0, min(hi, d) - lo)  # rows k < d: the held first row
        k0 = min(max(lo, d), hi)
        j0, j1 = k0 - d, hi - d  # the shifted rows A[j0:j1] answer y[k0:hi]
        if j1 <= 0:  # a delay beyond the span: every row is the held first one
            j0 = j1 = 0
        a0 = A[0]
        G_aa = self._gram_to(j1) - self._gram_to(j0) + held * np.outer(a0, a0)
        b_a = A[j0:j1].T @ y[k0:hi] + a0 * float(np.sum(y[lo : lo + held]))
        if T.shape[1]:
            G_at = A[j0:j1].T @ T[k0:hi] + np.outer(a0, np.sum(T[lo : lo + held], axis=0))
            G_tt = T[lo:hi].T @ T[lo:hi]
            G = np.block([[G_aa, G_at], [G_at.T, G_tt]])
            b = np.concatenate([b_a, T[lo:hi].T @ y[lo:hi]])
            free = np.concatenate([self.free, np.ones(T.shape[1], dtype=bool)])
        else:
            G, b, free = G_aa, b_a, self.free
        return G, b, float(y[lo:hi] @ y[lo:hi]), free

    def rows(self, d: int, lo: int, hi: int) -> FloatArray:
        """Rows ``[lo, hi)`` of the delayed regressors."""
        idx = np.maximum(np.arange(lo, hi) - d, 0)
        out: FloatArray = self.A[idx]
        return out


def _solve(G: FloatArray, b: FloatArray, free: npt.NDArray[np.bool_]) -> FloatArray:
    """``argmin |X z - y|`` with ``z[~free] >= 0`` from the normal equations ``G = X'X``,
    ``b = X'y`` (Cholesky factor, the free columns projected out, NNLS on the rest); a ridge of
    ``1e-10`` of the mean diagonal when ``G`` is numerically singular."""
    from scipy.linalg import LinAlgError, cholesky, solve_triangular

    ridge = 0.0
    scale = float(np.mean(np.diag(G))) or 1.0
    for _ in range(8):
        try:
            R = cholesky(G + ridge * np.eye(G.shape[0]), lower=False, check_finite=False)
            break
        except LinAlgError:
            ridge = max(10 * ridge, 1e-10 * scale)
    else:
        raise ParameterError("the regressors are not finite: no least-squares solution")
    d = solve_triangular(R, b, trans="T", check_finite=False)
    return _mixed_nnls(R, d, free)


def _sse(G: FloatArray, b: FloatArray, yy: float, z: FloatArray) -> float:
    """The residual sum of squares ``|X z - y|^2`` from the normal equations."""
    return max(yy - 2.0 * float(z @ b) + float(z @ G @ z), 0.0)


def _reduced_design(template: LinearModel, v: FloatArray) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
    """The template's regressors on ``v`` with a free output offset, reduced to distinct
    non-constant columns plus one constant column, equilibrated: ``(A, free)``."""
    A, lb, _, _ = _design(template, v, True)
    if isinstance(template, Preisach):  # 0/1 relay columns: many cells switch together
        m = 0 if template.creep is None else template.creep.terms
        head = A.shape[1] - template.weights.size - m
        bits = np.packbits(A[:, head : A.shape[1] - m].T > 0.5, axis=1)
        _, first = np.unique(bits, axis=0, return_index=True)
        keep = np.concatenate([np.arange(head), head + np.sort(first), np.arange(A.shape[1] - m, A.shape[1])])
        A, lb = A[:, keep], lb[keep]
    constant = np.all(A == A[:1], axis=0)
    keep_cols = np.flatnonzero(~constant)
    A = np.column_stack([A[:, keep_cols], np.ones(v.size)])
    free = np.append(np.isneginf(lb[keep_cols]), True)
    scale = np.maximum(np.sqrt(np.mean(A * A, axis=0)), 1e-300)
    return A / scale, free


#: The delays tried first (then refined to the sample around the best).
_DELAY_GRID = (0, 1, 2, 3, 4, 5, 6, 7, 8, 10, 12, 14, 16, 20, 24, 28, 32, 40, 48, 56, 64, 80, 96, 112, 128, 160, 192)


def _delay_grid(max_delay: int) -> list[int]:
    grid = [d for d in _DELAY_GRID if d <= max_delay]
    k = grid[-1]
    while k < max_delay:  # beyond the table: every 25 %
        k = min(max_delay, max(k + 1, int(k * 1.25)))
        grid.append(k)
    return grid


def choose_structure(
    template: LinearModel,
    input: npt.ArrayLike,
    output: npt.ArrayLike,
    *,
    start: int = 0,
    max_delay: int = 0,
    delay: int | None = None,
    drifts: tuple[DriftBasis, ...] = (),
    split: float = 0.7,
    earliest: int | None = None,
) -> StructureChoice:
    """The input delay and drift basis of a linear model's fit to a training span (see the
    module's description), from ``template``'s structure (its linear parameters are ignored).

    Parameters
    ----------
    template : PI, GeneralizedPI, RateDependentPI or Preisach
        The structure fitted (an output offset is always fitted with it).
    input, output : array_like
        The training span, simulated from its first sample.
    start : int
        The fit's first sample (:func:`fit_start`): earlier samples are simulated, not scored.
    max_delay : int
        Largest input delay tried (samples); ``delay`` given: that delay, not searched.
    delay : int, optional
        A known input delay, samples: used as it is, not searched.
    drifts : tuple of DriftBasis
        The drift bases tried against none (empty: no drift).
    split : float
        The internal split: the fit on this fraction of ``[start, n)``, scored on the rest.
    earliest : int, optional
        An earlier fit start to weigh against ``start`` (the end of a quiet lead-in, when
        ``start`` also skips the wiping-out): the internal split keeps the one whose fit
        predicts the rest better (on a span of a cycle or two the first sweep is data the fit
        cannot spare; on a longer one, a transient it should not explain).

    Returns
    -------
    StructureChoice

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst import PI
    >>> v = np.sin(np.linspace(0, 40, 4000)) * np.linspace(1, 0.5, 4000)
    >>> y = PI([0.2, 0.5], [0.6, 0.3], p0=1.0).simulate(delayed(v, 3)) + 0.001 * np.arange(4000)
    >>> c = choose_structure(PI([0.2, 0.5], [0.0, 0.0]), v, y, max_delay=10, drifts=(DriftBasis(linear=True),))
    >>> c.delay, c.drift.name
    (3, 'linear')
    """
    v = as_record(input, "input", min_length=8)
    y = as_record(output, "output", min_length=8)
    n = v.size
    if y.size != n:
        raise ParameterError(f"output has {y.size} samples, input has {n}; they must match")
    s = as_int(start, "start", minimum=0)
    if n - s < 8:
        raise ParameterError(f"start = {s} leaves {n - s} samples of the {n}-sample training span to fit")
    frac = as_scalar(split, "split", positive=True)
    if not frac < 1:
        raise ParameterError(f"split = {frac} must be a fraction in (0, 1)")
    A, free = _reduced_design(template, v)
    mu = float(np.mean(y[s:]))
    unit = float(np.std(y[s:])) or 1.0
    gram = _DelayedGram(A, free, (y - mu) / unit)
    # the delay is searched with the first drift basis offered as a nuisance term, so a drift
    # does not pull the delay (a trend is no reason to shift the loop). Not every basis: two
    # settlings (tau = T and 3 T) together span a slow curve that takes loop shape on a short
    # span (yan9a, 200 samples, one cycle: the Preisach's delay went from 3 to 0 samples)
    nuisance = drifts[0].columns(n) if drifts else np.zeros((n, 0))

    def sse(d: int, lo: int, hi: int, T: FloatArray) -> float:
        G, b, yy, fr = gram.normal(d, lo, hi, T)
        return _sse(G, b, yy, _solve(G, b, fr))

    costs: dict[int, float] = {}
    if delay is not None:
        best = as_int(delay, "delay", minimum=0)
    else:
        top = min(as_int(max_delay, "max_delay", minimum=0), (n - s) // 4)
        for d in _delay_grid(top):
            costs[d] = sse(d, s, n, nuisance)
        best = min(costs, key=lambda k: costs[k])
        while True:  # refine to the sample
            near = [k for k in (best - 1, best + 1) if 0 <= k <= top and k not in costs]
            for k in near:
                costs[k] = sse(k, s, n, nuisance)
            nxt = min(costs, key=lambda k: costs[k])
            if nxt == best:
                break
            best = nxt
    rmse = {d: unit * math.sqrt(c / (n - s)) for d, c in costs.items()}
    G, b, _, fr = gram.normal(best, s, n, nuisance)
    fitted = np.concatenate([gram.rows(best, s, n), nuisance[s:]], axis=1) @ _solve(G, b, fr)
    lag = residual_lag(fitted, gram.y[s:])
    chosen = DriftBasis()
    drift_rmse: dict[str, float] = {}
    m = s + int(frac * (n - s))
    n_eff = None
    start_rmse: dict[int, float] = {}
    if earliest is not None and as_int(earliest, "earliest", minimum=0) < s and n - m >= 8 and m - s >= 8:
        none = np.zeros((n, 0))
        for lo in (int(earliest), s):
            G, b, _, fr = gram.normal(best, lo, m, none)
            r = gram.rows(best, m, n) @ _solve(G, b, fr) - gram.y[m:]
            start_rmse[lo] = unit * math.sqrt(float(np.mean(r * r)))
        if start_rmse[int(earliest)] < start_rmse[s]:
            s = int(earliest)
    if drifts and n - m >= 8 and m - s >= 8:
        scores: dict[str, tuple[float, DriftBasis]] = {}
        residual_none = None
        for basis in (DriftBasis(), *drifts):
            T = basis.columns(n)
            G, b, _, fr = gram.normal(best, s, m, T)
            z = _solve(G, b, fr)
            pred = np.concatenate([gram.rows(best, m, n), T[m:]], axis=1) @ z
            r = pred - gram.y[m:]
            scores[basis.name] = (float(np.mean(r * r)), basis)
            if basis.empty:
                residual_none = r
        assert residual_none is not None
        e = residual_none - residual_none.mean()
        r1 = float(e[:-1] @ e[1:]) / max(float(e @ e), 1e-300)
        r1 = min(max(r1, 0.0), 0.999)
        n_eff = max(residual_none.size * (1 - r1) / (1 + r1), 1.0)
        base = scores["none"][0]
        name = min(scores, key=lambda k: scores[k][0])
        if name != "none" and scores[name][0] * (1 + math.sqrt(2.0 / n_eff)) < base:
            chosen = scores[name][1]
        drift_rmse = {k: unit * math.sqrt(mse) for k, (mse, _) in scores.items()}
    return StructureChoice(
        best,
        chosen,
        s,
        rmse,
        drift_rmse,
        split=m if drift_rmse or start_rmse else None,
        n_eff=n_eff,
        start_rmse=start_rmse,
        residual_lag=lag,
    )


def residual_lag(fitted: npt.ArrayLike, output: npt.ArrayLike) -> float:
    """The phase lag a fit leaves in its residual, in samples: the least-squares coefficient
    ``k`` of ``fitted - output`` on the fitted output's slope (``fitted - output ~ k dfitted/dk``:
    the fit runs ``k`` samples ahead of the data). A check of a chosen input delay: near 0
    when the delay is right; a lag the model's hysteresis imitates (a delay of the measurement
    chain fitted as loop width) shows as a coefficient of the delay's sign.

    Parameters
    ----------
    fitted, output : array_like
        The fit's output and the measured output, equal lengths (at least 3 samples).

    Returns
    -------
    float
        Samples (0 when the fit is constant).

    Examples
    --------
    >>> import numpy as np
    >>> y = np.sin(np.linspace(0, 20, 2000))
    >>> round(residual_lag(np.roll(y, -3)[:-10], y[:-10]), 2)  # the fit 3 samples ahead
    3.0
    >>> residual_lag(y, y)
    0.0
    """
    f = as_record(fitted, "fitted", min_length=3)
    y = as_record(output, "output", min_length=3)
    if y.size != f.size:
        raise ParameterError(f"output has {y.size} samples, fitted has {f.size}; they must match")
    slope = np.gradient(f)
    ss = float(slope @ slope)
    return float((f - y) @ slope) / ss if ss > 0 else 0.0


def drift_bases(n: int, spec: tuple[tuple[str, float | None], ...] = DRIFT_BASES) -> tuple[DriftBasis, ...]:
    """The drift bases of ``spec`` (``("exp", multiple of the span)`` or ``("linear", None)``)
    for a training span of ``n`` samples.

    Parameters
    ----------
    n : int
        Samples of the training span.
    spec : tuple of (str, float or None)
        The bases, by default :data:`DRIFT_BASES`.

    Returns
    -------
    tuple of DriftBasis

    Examples
    --------
    >>> drift_bases(2000)
    (DriftBasis(taus=(2000.0,), linear=False), DriftBasis(taus=(6000.0,), linear=False))
    >>> [b.name for b in drift_bases(2000, (("exp", 0.5), ("linear", None)))]
    ['exp(1000)', 'linear']
    """
    out = []
    for kind, f in spec:
        if kind == "linear":
            out.append(DriftBasis(linear=True))
        else:
            assert f is not None
            out.append(DriftBasis(taus=(float(f) * n,)))
    return tuple(out)


#: Kinds whose structure decisions are taken on their own regressors; the others (``boucwen``,
#: and any kind fitted with ``structure="fit"``) take those of an MPI of the default structure.
_OWN_TEMPLATE = ("pi", "gpi", "mpi", "rdpi", "preisach")


def decide_structure(
    input: npt.ArrayLike,
    output: npt.ArrayLike,
    kind: str,
    *,
    fs: float | None = None,
    operators: int = 9,
    levels: int = 12,
    creep: int = 0,
    delay: int | str = "auto",
    max_delay: int | None = None,
    drift: str = "auto",
    start: int | str = "auto",
    creep_horizon: float = 1.0,
) -> StructureChoice:
    """What a careful engineer decides before fitting ``kind`` to a training span: the fit's
    first sample, the input delay and a drift term (:func:`choose_structure` on the kind's
    default structure; ``boucwen`` on an MPI's).

    Parameters
    ----------
    input, output : array_like
        The training span (nothing else is looked at).
    kind : str
        ``pi``, ``gpi``, ``mpi``, ``rdpi``, ``preisach`` or ``boucwen``.
    fs : float, optional
        Sample rate, Hz: the lead-in's length, the default ``max_delay`` (20 ms of samples).
    operators, levels, creep : int
        The kind's structure, as :func:`~piezohyst.identify` fits it (``creep_horizon`` too).
    delay : int or "auto"
        The input delay in samples, or ``"auto"``: searched from 0 to ``max_delay``.
    max_delay : int, optional
        Largest delay searched, samples; ``None``: :func:`default_max_delay`.
    drift : {"auto", "none"}
        ``"auto"``: the bases of :data:`DRIFT_BASES` tried by the internal split; ``"none"``.
    start : int or "auto"
        The fit's first sample, or ``"auto"``: :func:`fit_start`.
    creep_horizon : float, default 1.0
        The upper edge of the slowest creep band of an ``rdpi``, in record durations.

    Returns
    -------
    StructureChoice

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst import PI
    >>> v = np.sin(np.linspace(0, 40, 4000)) * np.linspace(1, 0.5, 4000)
    >>> y = PI([0.2, 0.5], [0.6, 0.3], p0=1.0).simulate(delayed(v, 3))
    >>> c = decide_structure(v, y, "pi", fs=1000.0, operators=4, drift="none")
    >>> c.delay, c.drift.name, c.start
    (3, 'none', 0)
    """
    from .dispatch import _linear_template

    v = as_record(input, "input", min_length=8)
    y = as_record(output, "output", min_length=8)
    if kind not in (*_OWN_TEMPLATE, "boucwen"):
        raise ParameterError(f"kind = {kind!r}: structure decisions apply to {[*_OWN_TEMPLATE, 'boucwen']}")
    if drift not in ("auto", "none"):
        raise ParameterError(f"drift = {drift!r} must be 'auto' or 'none'")
    earliest = None
    if start == "auto":
        s, why = fit_start(v, fs)
        earliest = why["lead_in"]
    elif isinstance(start, str):
        raise ParameterError(f"start = {start!r} must be 'auto' or a number of samples")
    else:
        s = as_int(start, "start", minimum=0)
    own = kind in _OWN_TEMPLATE
    template = _linear_template(
        kind if own else "mpi", v, fs, operators, levels, creep if own else 0, creep_horizon if own else 1.0
    )
    bases = drift_bases(v.size) if drift == "auto" else ()
    if delay == "auto":
        top = default_max_delay(fs, v.size) if max_delay is None else as_int(max_delay, "max_delay", minimum=0)
        return choose_structure(template, v, y, start=s, max_delay=top, drifts=bases, earliest=earliest)
    if isinstance(delay, str):
        raise ParameterError(f"delay = {delay!r} must be 'auto' or a number of samples")
    d = as_int(delay, "delay", minimum=0)
    return choose_structure(template, v, y, start=s, delay=d, drifts=bases, earliest=earliest)
