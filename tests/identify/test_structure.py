"""Structure decisions on the training span (issue 14): the fit's start (lead-in, wiping-out),
the input delay by training error on shifted regressors, a drift term by an internal split,
and identify() holding them in the model so its file reproduces the validation figure."""

from __future__ import annotations

import numpy as np
import pytest

import piezohyst as ph
from piezohyst import _core
from piezohyst.errors import ParameterError
from piezohyst.identify.core import DriftBasis, delayed
from piezohyst.identify.dispatch import identify
from piezohyst.identify.structure import choose_structure, decide_structure, drift_bases, fit_start

FS = 1000.0


def excitation(n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS
    f = rng.uniform(0.8, 1.5, 3)
    phases = rng.uniform(0, 6, 3)
    return 2.0 + sum(a * np.sin(2 * np.pi * fi * t + p) for a, fi, p in zip((1.0, 0.5, 0.3), f, phases, strict=True))


def truth_output(v: np.ndarray, delay: int, noise: float, seed: int = 1) -> np.ndarray:
    """A PI loop on the thresholds ``identify`` fits with (9 over half the input range) read
    ``delay`` samples late, with noise: the fitted family holds the truth, the delay is the
    question."""
    r = np.arange(9) * np.ptp(v) / 2 / 9
    y = 3.0 * ph.PI(r, np.linspace(0.5, 0.05, 9), p0=0.4).simulate(delayed(v, delay))
    return y + noise * np.ptp(y) * np.random.default_rng(seed).standard_normal(v.size)


def test_delayed_holds_the_first_sample():
    assert delayed([1.0, 2.0, 3.0], 0).tolist() == [1.0, 2.0, 3.0]
    assert delayed([1.0, 2.0, 3.0], 1).tolist() == [1.0, 1.0, 2.0]
    assert delayed([1.0, 2.0, 3.0], 5).tolist() == [1.0, 1.0, 1.0]


def test_fit_start_skips_a_quiet_lead_in_and_the_first_unwiped_stretch():
    t = np.arange(6000) / FS
    v = 2.0 + np.sin(2 * np.pi * t) * np.exp(-t / 3.0)
    quiet = np.concatenate([np.full(700, 2.0), v])
    start, why = fit_start(quiet, FS)
    assert abs(why["lead_in"] - 700) <= 2 and start == why["lead_in"] + why["wipe_out"]
    # after the lead-in: until the input has swept 80 % of its range (from its first maximum,
    # 0.25 s in, down past the middle of the first descent)
    rest = quiet[why["lead_in"] :]
    swept = np.maximum.accumulate(rest) - np.minimum.accumulate(rest)
    k = why["wipe_out"]
    assert swept[k] >= 0.8 * np.ptp(rest) > swept[k - 1]
    assert 250 < k < 750
    # without fs no lead-in is looked for; a growing excitation sweeps its range only at the end:
    # at most 30 % of the span is skipped
    assert fit_start(quiet)[1]["lead_in"] == 0
    t = np.arange(3000) / FS
    _, growing = fit_start(np.sin(2 * np.pi * 2 * t) * t, FS)
    assert growing["wipe_out"] == int(0.3 * (3000 - growing["lead_in"]))


@pytest.mark.parametrize("delay", [0, 2, 7])
def test_choose_structure_finds_the_delay_of_a_record(delay):
    v = excitation(6000)
    y = truth_output(v, delay, 0.001)
    # the family that holds the truth finds the delay exactly; a 12-level Preisach, which
    # approximates the loop, within a sample (its misfit leans on the delay)
    for kind, tolerance in (("pi", 0), ("preisach", 1)):
        choice = decide_structure(v, y, kind, fs=FS, drift="none")
        assert abs(choice.delay - delay) <= tolerance, (kind, choice.delay_rmse)
        assert choice.drift.empty and choice.drift_rmse == {}


def test_a_drift_is_kept_only_when_the_split_says_so():
    v = excitation(8000)
    y = truth_output(v, 3, 0.001)
    clean = decide_structure(v, y, "pi", fs=FS)
    assert clean.delay == 3 and clean.drift.empty  # no drift: none is kept
    assert set(clean.drift_rmse) == {"none", *(b.name for b in drift_bases(v.size))}
    drifting = y + 0.05 * np.ptp(y) * np.arange(v.size) / v.size
    chosen = decide_structure(v, drifting, "pi", fs=FS)
    assert chosen.delay == 3 and not chosen.drift.empty
    assert chosen.drift_rmse[chosen.drift.name] < 0.5 * chosen.drift_rmse["none"]


def test_choose_structure_checks_its_arguments():
    v = excitation(200)
    y = truth_output(v, 0, 0.0)
    tmpl = ph.PI([0.5, 1.0], [0.0, 0.0])
    with pytest.raises(ParameterError, match="start = 195 leaves 5 samples"):
        choose_structure(tmpl, v, y, start=195)
    with pytest.raises(ParameterError, match="split = 1.0"):
        choose_structure(tmpl, v, y, split=1.0)
    with pytest.raises(ParameterError, match="kind = 'cemf'"):
        decide_structure(v, y, "cemf")


@pytest.mark.parametrize(
    ("kind", "creep"), [("pi", 0), ("gpi", 2), ("mpi", 0), ("rdpi", 2), ("preisach", 0), ("boucwen", 0)]
)
def test_identify_holds_delay_and_drift_and_its_model_reproduces_the_validation(kind, creep):
    v = excitation(5000)
    y = truth_output(v, 4, 0.002) + 0.03 * np.arange(v.size) / v.size
    a, b = 0, 3000
    basis = DriftBasis(taus=(float(b - a),))
    kw = {"max_iterations": 15, "rng": 0} if kind == "boucwen" else {}
    res = identify(
        v[a:b], y[a:b], kind, fs=FS, creep=creep, validate=(v[b:], y[b:]), gap=v[b:b], input_delay=4, drift=basis,
        fit_start=300, diagnosis=False, **kw,
    )  # fmt: skip
    model = res.model
    assert model.input_delay == 4 and model.drift is not None and model.drift.taus == (3000.0,)
    assert res.assessment["fit_start"] == 300
    back = ph.models.model.model_from_dict(model.to_dict())
    sim = back.simulate(v)
    assert ph.fit_metrics(sim[b:], y[b:])["rmse_percent"] == pytest.approx(res.validation["rmse_percent"], abs=1e-9)
    assert ph.fit_metrics(sim[300:b], y[300:b])["rmse_percent"] == pytest.approx(res.train["rmse_percent"], abs=1e-9)


def test_identify_refuses_drift_where_it_does_not_apply():
    v = excitation(1000)
    y = truth_output(v, 0, 0.0)
    with pytest.raises(ParameterError, match="drift / fit_start apply"):
        identify(v, y, "mpi", structure="fit", drift=DriftBasis(linear=True))
    with pytest.raises(ParameterError, match="input_delay applies to models with an output map"):
        identify(v, y, "cemf", fs=FS, input_delay=2)
    with pytest.raises(ParameterError, match="input_delay = -1"):
        identify(v, y, "pi", input_delay=-1)


def test_the_delayed_gram_is_the_normal_equations_of_the_shifted_rows():
    from piezohyst.identify.structure import _DelayedGram, _reduced_design

    v = excitation(600)
    y = truth_output(v, 2, 0.01)
    A, free = _reduced_design(ph.PI([0.3, 0.6], [0.0, 0.0], creep=ph.Creep(1 / FS, [0.05], [0.0])), v)
    gram = _DelayedGram(A, free, y)
    T = DriftBasis(taus=(300.0,), linear=True).columns(v.size)
    for d in (0, 1, 7, 150, 599, 700):  # a delay beyond the rows: every row is the held first one
        for lo, hi in ((0, 600), (40, 420), (300, 310)):
            G, b, yy, fr = gram.normal(d, lo, hi, T)
            X = np.column_stack([gram.rows(d, lo, hi), T[lo:hi]])
            assert np.allclose(G, X.T @ X, rtol=1e-10, atol=1e-9) and np.allclose(b, X.T @ y[lo:hi])
            assert yy == pytest.approx(float(y[lo:hi] @ y[lo:hi])) and fr.size == X.shape[1]
    # the rows are the regressors of the held, delayed input (exact for a rate-independent core)
    pi = ph.PI([0.3, 0.6], [0.0, 0.0])
    raw = _core.regressors(pi.family, list(pi.dims), pi.to_row(), v)
    shifted = _DelayedGram(raw, np.zeros(raw.shape[1], dtype=bool), y).rows(5, 0, v.size)
    assert np.array_equal(shifted, _core.regressors(pi.family, list(pi.dims), pi.to_row(), delayed(v, 5)))


def test_residual_lag_checks_the_chosen_delay():
    """The training residual's coefficient on the fitted slope: ~0 at the chosen delay, the
    delay's sign and a good part of its size when the delay is withheld (the loop width takes
    the rest); and the function itself on a known shift."""
    from piezohyst.identify.structure import decide_structure, residual_lag

    v = np.sin(np.linspace(0, 60, 6000)) * np.linspace(1, 0.4, 6000)
    r = np.arange(1, 6) * np.ptp(v) / 12  # the template's thresholds: the fit can be exact
    y = ph.PI(r, [0.6, 0.3, 0.2, 0.1, 0.1], p0=1.0).simulate(np.concatenate([np.full(6, v[0]), v[:-6]]))
    chosen = decide_structure(v, y, "pi", fs=1000.0, operators=5, drift="none")
    withheld = decide_structure(v, y, "pi", fs=1000.0, operators=5, drift="none", delay=0)
    assert chosen.delay == 6 and abs(chosen.residual_lag) < 0.05, chosen.residual_lag
    assert withheld.residual_lag > 1.0, withheld.residual_lag  # 1.09: the loop width takes the rest
    assert chosen.to_dict()["residual_lag"] == chosen.residual_lag
    s = np.sin(np.linspace(0, 20, 2000))
    assert residual_lag(s[5:], s[:-5]) == pytest.approx(5.0, rel=0.02)  # fit 5 samples ahead
    with pytest.raises(ParameterError, match="fitted has 3"):
        residual_lag([1.0, 2.0, 3.0], [1.0, 2.0, 3.0, 4.0])
