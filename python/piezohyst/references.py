"""Reference signals (SPEC §6). Each returns ``(t, x)`` as 1-D arrays."""
from __future__ import annotations

import numpy as np

from ._validate import as_scalar

__all__ = ["sine", "variable_amplitude_sine"]


def _time(duration, fs):
    duration = as_scalar(duration, "duration", positive=True)
    fs = as_scalar(fs, "fs", positive=True)
    n = int(round(duration * fs))
    if n < 2:
        raise ValueError(f"duration * fs = {duration * fs} gives fewer than 2 samples")
    return np.arange(n) / fs


def sine(freq, amplitude, duration, fs, offset=0.0, phase=-np.pi / 2):
    """``offset + amplitude sin(2 pi freq t + phase)``; the default phase starts at the bottom."""
    t = _time(duration, fs)
    f = as_scalar(freq, "freq", positive=True)
    a = as_scalar(amplitude, "amplitude", nonnegative=True)
    return t, as_scalar(offset, "offset") + a * np.sin(2 * np.pi * f * t + as_scalar(phase, "phase"))


def variable_amplitude_sine(freq, amplitude, duration, fs, offset=0.0, final_fraction=0.2):
    """A sine whose amplitude decays linearly to ``final_fraction`` of ``amplitude``: the
    nested minor loops of seed 2's variable-amplitude experiments. Starts at the offset."""
    t, _ = sine(freq, amplitude, duration, fs)
    ff = as_scalar(final_fraction, "final_fraction", nonnegative=True)
    env = 1.0 - (1.0 - ff) * t / t[-1]
    f = as_scalar(freq, "freq", positive=True)
    return t, as_scalar(offset, "offset") + as_scalar(amplitude, "amplitude") * env * np.sin(2 * np.pi * f * t)
