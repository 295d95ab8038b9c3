"""Frequency responses from records and excitations (issue 19): the periodic estimate is exact
for a linear system, Welch's H1 is close, the result class plots, interpolates and converts."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
import pytest
import scipy.signal

from piezohyst.errors import ParameterError
from piezohyst.signals.frequency import FrequencyResponse, frf_from_record, multisine, swept_sine

FS = 1000.0
#: a discrete second-order system with a resonance at ~80 Hz
SYS = scipy.signal.cont2discrete(([1.0], [1 / (2 * np.pi * 80) ** 2, 0.1 / (2 * np.pi * 80), 1.0]), 1 / FS)
NUM, DEN = np.ravel(SYS[0]), SYS[1]


def truth(f):
    z = np.exp(2j * np.pi * np.asarray(f) / FS)
    return np.polyval(NUM, z) / np.polyval(DEN, z)


def test_a_periodic_multisine_gives_the_exact_response():
    u, freqs = multisine(FS, 1000, (2.0, 400.0), periods=5, rng=3)
    y = scipy.signal.lfilter(NUM, DEN, u)
    frf = frf_from_record(u, y, FS, period=1000, skip=1000)
    np.testing.assert_allclose(frf.frequency, freqs)
    np.testing.assert_allclose(frf.response, truth(freqs), rtol=1e-9)
    assert frf.coherence is not None and np.all(frf.coherence > 1 - 1e-9)
    f_pk, h_pk = frf.peak()
    assert 70 < f_pk < 90 and h_pk > 4  # the resonance (Q ~ 10)


def test_welch_h1_on_a_swept_sine_and_noise():
    rng = np.random.default_rng(1)
    sweep = swept_sine(FS, 1.0, 400.0, 4.0)
    u = np.tile(sweep, 5)  # repeated sweeps: every Welch segment holds a whole sweep's band
    y = scipy.signal.lfilter(NUM, DEN, u) + 0.01 * rng.standard_normal(u.size)
    f = np.array([5.0, 20.0, 60.0, 150.0, 300.0])
    frf = frf_from_record(u, y, FS, frequencies=f, nperseg=sweep.size, skip=sweep.size)
    np.testing.assert_allclose(np.abs(frf.response), np.abs(truth(f)), rtol=0.05)
    assert frf.method == "welch" and np.all(frf.coherence[:4] > 0.99)  # 0.85 at 300 Hz: |H| ~ 0.07 there


def test_frequency_response_tools():
    f = np.geomspace(1, 400, 50)
    h = FrequencyResponse(f, truth(f), input="u", output="y", unit="m/V", title="second order")
    assert abs(h.at([20.0])[0] - truth(20.0)) / abs(truth(20.0)) < 0.01
    frd = h.to_control()
    np.testing.assert_allclose(frd.omega, 2 * np.pi * f)
    for kind in ("bode", "nyquist"):
        fig = h.plot(kind=kind)
        assert fig.axes and fig.axes[0].lines
        plt.close(fig)
    assert "second order" in h._repr_html_()
    with pytest.raises(ParameterError, match="kind = 'polar'"):
        h.plot(kind="polar")
    with pytest.raises(ParameterError, match="must lie in the measured band"):
        h.at([500.0])
    with pytest.raises(ParameterError, match="response has 2 values, frequency has 3"):
        FrequencyResponse([1.0, 2.0, 3.0], [1.0, 2.0])
    with pytest.raises(ParameterError, match="frequency must be increasing"):
        FrequencyResponse([2.0, 1.0], [1.0, 2.0])
    with pytest.raises(ParameterError, match=r"response\[1\] = \(nan"):
        FrequencyResponse([1.0, 2.0], [1.0, np.nan])


def test_excitation_bad_input():
    with pytest.raises(ParameterError, match="band = \\(600.0, 700.0\\) must satisfy"):
        multisine(FS, 1000, (600.0, 700.0))
    with pytest.raises(ParameterError, match="f0 = 5.0, f1 = 1.0"):
        swept_sine(FS, 5.0, 1.0, 1.0)
    with pytest.raises(ParameterError, match="output has 5 samples, input has 6"):
        frf_from_record(np.ones(6), np.ones(5), FS)
    with pytest.raises(ParameterError, match="the input excites no frequency"):
        frf_from_record(np.ones(100), np.ones(100), FS, period=10)
