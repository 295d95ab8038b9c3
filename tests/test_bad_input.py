"""docs/spec.md §10: bad input gets a clear error naming the argument and the value."""

import numpy as np
import pytest

import piezohyst as ph
from piezohyst import Envelope

CASES = [
    (lambda: ph.PI([0.2, 0.1], [1, 1]), ValueError, r"thresholds\[1\] = 0.1 is not greater than thresholds\[0\]"),
    (lambda: ph.PI([-0.1, 0.1], [1, 1]), ValueError, r"thresholds\[0\] = -0.1 must be >= 0"),
    (lambda: ph.PI([0.1, 0.2], [1, np.nan]), ValueError, r"weights\[1\] = nan is not finite"),
    (lambda: ph.PI([0.1, 0.2], [1]), ValueError, "weights has length 1, expected 2"),
    (lambda: ph.PI([0.1], [1], p0=np.inf), ValueError, "p0 = inf is not finite"),
    (lambda: ph.PI("0.1", [1]), TypeError, "thresholds must be a 1-D array of numbers, got str"),
    (lambda: ph.PI([0.1], [1], p0="1"), TypeError, "p0 must be a real number"),
    (lambda: ph.PI([[0.1]], [1]), ValueError, r"thresholds must be 1-D, got shape \(1, 1\)"),
    (
        lambda: ph.GeneralizedPI([0.1], [1], rising=Envelope.polynomial(0, 1, 0, -1), input_range=(-1, 1)),
        ValueError,
        "envelope rising is not increasing",
    ),
    (
        lambda: ph.GeneralizedPI([0.1], [1], falling=Envelope.tanh(1, 0)),
        ValueError,
        "envelope falling is not increasing",
    ),
    (
        lambda: ph.GeneralizedPI([0.1], [1], rising=Envelope.polynomial(0, 1, 1, 0)),
        ValueError,
        "envelope rising is not increasing at input -inf",
    ),  # a parabola is monotone on no infinite range
    (lambda: ph.GeneralizedPI([0.1], [1], input_range=(1, 0)), ValueError, r"input_range = \(1.0, 0.0\)"),
    (lambda: Envelope("cubic"), ValueError, "kind = 'cubic' is not an envelope"),
    (lambda: ph.RateDependentPI([0.1], [1], ts=0), ValueError, "ts = 0.0 must be > 0"),
    (lambda: ph.RateDependentPI([0.1], [1], ts=1e-3, beta=-1), ValueError, "beta = -1.0 must be >= 0"),
    (lambda: ph.Creep(1e-3, [0.1, -1], [1, 1]), ValueError, r"taus\[1\] = -1.0 must be > 0"),
    (lambda: ph.Preisach(3, (0, 1), [1, 1, -1, 1, 1, 1]), ValueError, r"weights\[2\] = -1 must be >= 0"),
    (lambda: ph.Preisach(3, (0, 1), np.ones(5)), ValueError, "weights has length 5, expected 6"),
    (lambda: ph.Preisach(0, (0, 1), []), ValueError, "levels = 0 must be >= 1"),
    (lambda: ph.Preisach(3, (0, 1), np.ones(6), memory=1), ValueError, "memory = 1 must be >= 2"),
    (lambda: ph.BoucWen(1, 1, 0, n=0.5), ValueError, "n = 0.5 must be >= 1"),
    (lambda: ph.Dahl(1, 0, 1), ValueError, "h_c = 0.0 must be > 0"),
    (lambda: ph.Duhem(-1, (0, 1, 0, 0), (0, 0, 0, 0)), ValueError, "alpha = -1.0 must be >= 0"),
]


@pytest.mark.parametrize("make,kind,message", CASES)
def test_constructor_errors_name_the_argument_and_value(make, kind, message):
    with pytest.raises(kind, match=message):
        make()


def test_non_monotone_cubic_envelope_detected():
    # c3 > 0 but a negative slope at the vertex: g' = 1 - 2v + 0.9 v^2, minimum at v = 1/0.9
    with pytest.raises(ValueError, match=r"envelope rising is not increasing at input 1.111.* \(slope -0.111"):
        ph.GeneralizedPI([0.1], [1], rising=Envelope.polynomial(0, 1, -1, 0.3), input_range=(-2, 2))


@pytest.mark.parametrize(
    "record,kind,message",
    [
        ([0.0, np.nan, 1.0], ValueError, r"input\[1\] = nan is not finite"),
        ([0.0, np.inf], ValueError, r"input\[1\] = inf is not finite"),
        ([], ValueError, "input has 0 samples"),
        ([[0.0, 1.0]], ValueError, "input must be 1-D"),
        ("abc", TypeError, "input must be a 1-D array of numbers"),
        ([1 + 1j], TypeError, "input must be real numbers, got dtype complex128"),
        ([True, False], TypeError, "got dtype bool"),
    ],
)
def test_bad_records(record, kind, message):
    with pytest.raises(kind, match=message):
        ph.papers.mpi_seed2().simulate(record)


def test_bad_state_and_step():
    m = ph.PI([0.1, 0.2], [1, 1])
    with pytest.raises(ValueError, match="state has length 3, expected 2"):
        m.state = [0, 0, 0]
    with pytest.raises(ValueError, match=r"initial_state\[0\] = nan"):
        m.simulate([1.0], initial_state=[np.nan, 0])
    with pytest.raises(ValueError, match="value = nan is not finite"):
        m.step(np.nan)
    with pytest.raises(TypeError, match="value must be a real number"):
        m.step([1.0])


def test_unreachable_desired_output_names_the_sample():
    g = Envelope.tanh(1.0, 1.0)
    m = ph.GeneralizedPI([0.0, 0.1], [1.0, 0.5], (0, 0, 0, 0), g, g)
    with pytest.raises(ValueError, match="desired output 5 at sample 2 is outside the range"):
        m.inverse().simulate([0.0, 0.5, 5.0])


def test_batch_bad_shapes():
    m = ph.PI([0.1], [1.0])
    with pytest.raises(ValueError, match="params has 4 columns, expected 3"):
        ph.batch_rmse(m, np.zeros((2, 4)), [0.0, 1.0], [0.0, 1.0])
    with pytest.raises(ValueError, match=r"params must be a 2-D \(S, P\) array"):
        ph.batch_rmse(m, np.zeros(3), [0.0, 1.0], [0.0, 1.0])
    with pytest.raises(ValueError, match="target has length 3, input has length 2"):
        ph.batch_rmse(m, np.array([m.to_row()]), [0.0, 1.0], [0.0, 1.0, 2.0])
    with pytest.raises(ValueError, match='family = "nope" is unknown'):
        ph.batch_rmse("nope", np.zeros((1, 3)), [0.0], [0.0], dims=[1, 0])


def test_huge_values_never_give_nan():
    m = ph.PI([0.1], [0.5])
    y = m.simulate([1e308, -1e308, 1e308])
    assert np.all(np.isfinite(y))
    with pytest.raises(ValueError, match="diverged at sample 0"):
        ph.PI([0.1], [2.0], p0=2.0).simulate([1e308])
