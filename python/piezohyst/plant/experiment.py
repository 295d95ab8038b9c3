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
    ``(command[:-1], reading[1:])``.

    Parameters
    ----------
    stage : Stage
        The stage to drive (e.g. :func:`virtual_stage`).
    command : array_like
        The amplifier command, V per sample.
    rng : numpy.random.Generator
        The sensor noise's source.

    Returns
    -------
    command, reading : ndarray
        The aligned pair (V, m), one sample shorter than ``command``.

    Examples
    --------
    >>> import numpy as np
    >>> import piezohyst as ph
    >>> from piezohyst.plant import excitation, measure
    >>> stage = ph.virtual_stage()
    >>> u, y = measure(stage, excitation(1 / stage.sample_time, seconds=0.2), np.random.default_rng(0))
    >>> u.size, y.size, bool(0 < y.max() < 25e-6)
    (1999, 1999, True)
    >>> bool(np.allclose(y / 1e-7, np.round(y / 1e-7)))       # the 0.1 um encoder's steps
    True
    """
    x = stage.simulate(command).position
    q = stage.sensor.quantization
    noisy = x + stage.sensor.noise_std * rng.standard_normal(x.size)
    y = np.round(noisy / q) * q if q > 0 else noisy
    return np.asarray(command)[:-1], y[1:]


def excitation(
    fs: float, seconds: float = 2.0, freq: float = 5.0, v_max: float = 150.0, hold: float = 0.4
) -> FloatArray:
    """Full-range sine from 0 V (``hold`` s of major loop), then a decaying envelope (nested
    minor loops) down to 20 %.

    Parameters
    ----------
    fs : float
        Sample rate, Hz.
    seconds : float
        Duration, s.
    freq : float
        Sine frequency, Hz.
    v_max : float
        The full range's top voltage, V (the sine spans 0 .. ``v_max``).
    hold : float
        Seconds of full-range cycles before the envelope decays.

    Returns
    -------
    ndarray
        Volts per sample.

    Examples
    --------
    >>> from piezohyst.plant import excitation
    >>> u = excitation(1000.0, seconds=1.0, freq=5.0, v_max=100.0)
    >>> u.size, float(u.min()), round(float(u.max()), 6)
    (1000, 0.0, 100.0)
    """
    t = np.arange(round(seconds * fs)) / fs
    env = np.clip(1 - 0.8 * (t - hold) / max(seconds - hold, 1e-9), 0.2, 1.0)
    return 0.5 * v_max * (1 - env * np.cos(2 * np.pi * freq * t))
