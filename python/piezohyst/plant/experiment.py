"""Generic experiment helpers on a (virtual) stage: what a lab records when it drives the
stage (:func:`measure`), and an identification excitation with nested minor loops
(:func:`excitation`). The seeds' experiments built on them are in
:mod:`piezohyst.papers.experiments`.
"""

from __future__ import annotations

import numpy as np

__all__ = ["excitation", "measure"]


def measure(stage, command, rng):
    """What a lab records when it drives ``stage`` with ``command`` (V per sample): the
    command and the sensor reading (noise, quantization). The reading at ``k + 1`` shows the
    position the command at ``k`` produced, so the pair returned is aligned:
    ``(command[:-1], reading[1:])``."""
    x = stage.simulate(command).position
    q = stage.sensor.quantization
    noisy = x + stage.sensor.noise_std * rng.standard_normal(x.size)
    y = np.round(noisy / q) * q if q > 0 else noisy
    return np.asarray(command)[:-1], y[1:]


def excitation(fs, seconds=2.0, freq=5.0, v_max=150.0, hold=0.4):
    """Full-range sine from 0 V (``hold`` s of major loop), then a decaying envelope (nested
    minor loops) down to 20 %."""
    t = np.arange(round(seconds * fs)) / fs
    env = np.clip(1 - 0.8 * (t - hold) / max(seconds - hold, 1e-9), 0.2, 1.0)
    return 0.5 * v_max * (1 - env * np.cos(2 * np.pi * freq * t))
