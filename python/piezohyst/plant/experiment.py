"""Generic experiment helpers on a (virtual) stage: what a lab records when it drives the
stage (:func:`measure`), and an identification excitation with nested minor loops
(:func:`excitation`). The seeds' experiments built on them are in
:mod:`piezohyst.papers.experiments`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from .stage import Stage

FloatArray = npt.NDArray[np.float64]

__all__ = ["excitation", "measure"]


def measure(stage: Stage, command: npt.ArrayLike, rng: np.random.Generator) -> tuple[npt.NDArray[Any], FloatArray]:
    """What a lab records when it drives ``stage`` with ``command`` (V per sample): the
    command and the sensor reading (noise, quantization). The reading at ``k + 1`` shows the
    position the command at ``k`` produced, so the pair returned is aligned:
    ``(command[:-1], reading[1:])``."""
    x = stage.simulate(command).position
    q = stage.sensor.quantization
    noisy = x + stage.sensor.noise_std * rng.standard_normal(x.size)
    y = np.round(noisy / q) * q if q > 0 else noisy
    return np.asarray(command)[:-1], y[1:]


def excitation(
    fs: float, seconds: float = 2.0, freq: float = 5.0, v_max: float = 150.0, hold: float = 0.4
) -> FloatArray:
    """Full-range sine from 0 V (``hold`` s of major loop), then a decaying envelope (nested
    minor loops) down to 20 %."""
    t = np.arange(round(seconds * fs)) / fs
    env = np.clip(1 - 0.8 * (t - hold) / max(seconds - hold, 1e-9), 0.2, 1.0)
    return 0.5 * v_max * (1 - env * np.cos(2 * np.pi * freq * t))
