"""The nonparametric best linear approximation (BLA) of MIMO periodic multisine records
(Pintelon & Schoukens, *System Identification: A Frequency Domain Approach*, ch. 3–4).

Records are arrays ``(N, channels, R, P)``: one period of ``N`` samples, ``R`` realizations of
a random-phase multisine, ``P`` periods each, in steady state. Per realization the periods are
averaged (their spread is the noise); with ``nu`` inputs, each group of ``nu`` realizations
(realizations ``g*nu .. g*nu + nu - 1``) gives the ``ny x nu`` FRF at every bin,
``G = Y U^-1``; the BLA is the mean over groups, its *total* variance the spread over groups
(noise and nonlinear distortions), its *noise* variance the period-to-period noise
propagated through ``U^-1``. The nonlinear distortion variance is their difference.

Examples
--------
>>> import numpy as np
>>> from piezohyst.signals.frf import estimate_bla
>>> rng = np.random.default_rng(0)
>>> u = rng.standard_normal((64, 2, 4, 2)); u[..., 1] = u[..., 0]
>>> y = np.stack([2 * u[:, 0] - u[:, 1], u[:, 1]], axis=1)       # a static 2x2 system
>>> bla = estimate_bla(u, y, fs=64.0)
>>> np.round(bla.G[5].real, 6).tolist() == [[2.0, -1.0], [0.0, 1.0]]      # -0.0 == 0.0
True
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ParameterError
from .results import DataclassMatFile, html_table, require_pandas

__all__ = ["BestLinearApproximation", "estimate_bla", "multisine_records"]

FloatArray = NDArray[np.float64]


def multisine_records(u: ArrayLike, y: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """``u``, ``y`` as float arrays ``(N, nu, R, P)`` and ``(N, ny, R, P)`` (the
    nonlinear-benchmark layout: samples, channels, realizations, periods), checked: same
    ``N``, ``R``, ``P``; finite. A 3-D array is one period per realization.

    Parameters
    ----------
    u, y : array_like
        Inputs ``(N, nu, R, P)`` and outputs ``(N, ny, R, P)``, or ``(N, channels, R)``.

    Returns
    -------
    u, y : numpy.ndarray
        The checked 4-D float arrays.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.signals.frf import multisine_records
    >>> u, y = multisine_records(np.zeros((8, 2, 3)), np.zeros((8, 1, 3)))
    >>> u.shape, y.shape
    ((8, 2, 3, 1), (8, 1, 3, 1))
    """
    out = []
    for name, v in (("u", u), ("y", y)):
        a = np.asarray(v, dtype=np.float64)
        if a.ndim == 3:
            a = a[..., None]
        if a.ndim != 4:
            raise ParameterError(f"{name} has shape {a.shape}; expected (N, channels, realizations, periods)")
        if not np.isfinite(a).all():
            raise ParameterError(f"{name} holds a value that is not finite")
        out.append(a)
    if out[0].shape[0] != out[1].shape[0] or out[0].shape[2:] != out[1].shape[2:]:
        raise ParameterError(
            f"u has shape {out[0].shape} and y {out[1].shape}: samples, realizations and periods must match"
        )
    return out[0], out[1]


@dataclass(frozen=True, eq=False)
class BestLinearApproximation(DataclassMatFile):
    """The BLA of MIMO multisine records and its variances, at the excited bins.

    ``freqs`` (Hz, ``(K,)``), ``G_real`` / ``G_imag`` ``(K, ny, nu)`` (:attr:`G` the complex
    FRF), ``noise_var`` and ``total_var`` ``(K, ny, nu)`` (variances of the BLA estimate, the
    mean over groups), ``bins`` (DFT bin numbers), ``fs``, ``groups``, ``periods``.

    Parameters
    ----------
    freqs : numpy.ndarray
        Frequencies of the excited bins (Hz), ``(K,)``.
    bins : numpy.ndarray
        Their DFT bin numbers ``(K,)``.
    G_real, G_imag : numpy.ndarray
        Real and imaginary parts of the FRF ``(K, ny, nu)``.
    noise_var, total_var : numpy.ndarray
        Noise and total (noise and nonlinear distortion) variances of the BLA ``(K, ny, nu)``.
    fs : float
        Sample rate (Hz).
    groups : int
        Groups of ``nu`` realizations averaged.
    periods : int
        Periods per realization.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.signals.frf import estimate_bla
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal((64, 1, 4, 2)); u[..., 1] = u[..., 0]   # 4 realizations, 2 periods
    >>> y = u + 0.5 * np.roll(u, 1, axis=0)                           # y[t] = u[t] + 0.5 u[t-1]
    >>> y[..., 1] += 0.01 * rng.standard_normal((64, 1, 4))           # noise on the second period
    >>> bla = estimate_bla(u, y, fs=64.0)
    >>> bla.G.shape, bla.groups, bla.periods
    ((32, 1, 1), 4, 2)
    >>> bool(np.allclose(bla.G[:, 0, 0], 1 + 0.5 * np.exp(-2j * np.pi * bla.freqs / 64), atol=0.05))
    True
    """

    freqs: FloatArray
    bins: FloatArray
    G_real: FloatArray
    G_imag: FloatArray
    noise_var: FloatArray
    total_var: FloatArray
    fs: float
    groups: int
    periods: int

    @property
    def G(self) -> NDArray[np.complex128]:
        """The FRF ``(K, ny, nu)``."""
        return self.G_real + 1j * self.G_imag

    @property
    def distortion_var(self) -> FloatArray:
        """Variance of the nonlinear distortions (total minus noise, ≥ 0; needs 2 groups)."""
        return np.maximum(self.total_var - self.noise_var, 0.0)

    def to_pandas(self) -> Any:
        """One row per bin and (output, input) pair: frequency, |G| (dB), phase (deg), noise
        and distortion levels (dB, standard deviations); needs pandas.

        Returns
        -------
        pandas.DataFrame
            Columns ``freq_hz``, ``output``, ``input``, ``gain_db``, ``phase_deg``,
            ``noise_db``, ``distortion_db``.

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst.signals.frf import estimate_bla
        >>> rng = np.random.default_rng(0)
        >>> u = rng.standard_normal((64, 1, 4, 2)); u[..., 1] = u[..., 0]   # 4 realizations, 2 periods
        >>> y = u + 0.5 * np.roll(u, 1, axis=0)                           # y[t] = u[t] + 0.5 u[t-1]
        >>> y[..., 1] += 0.01 * rng.standard_normal((64, 1, 4))           # noise on the second period
        >>> bla = estimate_bla(u, y, fs=64.0)
        >>> bla.to_pandas().shape  # doctest: +SKIP
        (32, 7)
        """
        pd = require_pandas("BestLinearApproximation")
        k, ny, nu = self.G_real.shape
        g = self.G
        rows = {
            "freq_hz": np.repeat(self.freqs, ny * nu),
            "output": np.tile(np.repeat(np.arange(ny), nu), k),
            "input": np.tile(np.arange(nu), k * ny),
            "gain_db": 20 * np.log10(np.abs(g).ravel() + 1e-300),
            "phase_deg": np.degrees(np.angle(g)).ravel(),
            "noise_db": 10 * np.log10(self.noise_var.ravel() + 1e-300),
            "distortion_db": 10 * np.log10(self.distortion_var.ravel() + 1e-300),
        }
        return pd.DataFrame(rows)

    def plot(self, *, ax: Any = None) -> Any:
        """The Bode-magnitude matrix (one panel per output/input pair): |G|, and the noise and
        nonlinear-distortion levels (standard deviations of the BLA) in dB.

        Parameters
        ----------
        ax : matplotlib.axes.Axes or array of them, optional
            ``ny * nu`` axes to draw on; a new figure if ``None``.

        Returns
        -------
        matplotlib.figure.Figure
            The figure.

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst.signals.frf import estimate_bla
        >>> rng = np.random.default_rng(0)
        >>> u = rng.standard_normal((64, 1, 4, 2)); u[..., 1] = u[..., 0]   # 4 realizations, 2 periods
        >>> y = u + 0.5 * np.roll(u, 1, axis=0)                           # y[t] = u[t] + 0.5 u[t-1]
        >>> y[..., 1] += 0.01 * rng.standard_normal((64, 1, 4))           # noise on the second period
        >>> bla = estimate_bla(u, y, fs=64.0)
        >>> fig = bla.plot()
        >>> len(fig.axes)  # one panel per output/input pair
        1
        """
        import matplotlib.pyplot as plt

        _, ny, nu = self.G_real.shape
        if ax is None:
            fig, axes = plt.subplots(ny, nu, figsize=(3.2 * nu, 2.4 * ny), sharex=True, squeeze=False)
        else:
            axes = np.asarray(ax).reshape(ny, nu)
            fig = axes[0, 0].figure
        for i in range(ny):
            for j in range(nu):
                a = axes[i, j]
                a.semilogx(self.freqs, 20 * np.log10(np.abs(self.G[:, i, j]) + 1e-300), "k", lw=0.8, label="BLA")
                a.semilogx(self.freqs, 10 * np.log10(self.total_var[:, i, j] + 1e-300), "r.", ms=1, label="total")
                a.semilogx(self.freqs, 10 * np.log10(self.noise_var[:, i, j] + 1e-300), "g.", ms=1, label="noise")
                a.set_title(f"y{i + 1} / u{j + 1}", fontsize=8)
                if i == ny - 1:
                    a.set_xlabel("Hz")
                if j == 0:
                    a.set_ylabel("dB")
        axes[0, 0].legend(fontsize=6)
        fig.tight_layout()
        return fig

    def _repr_html_(self) -> str:
        k, ny, nu = self.G_real.shape
        snr = np.median(np.abs(self.G) ** 2 / np.maximum(self.noise_var, 1e-300))
        rows = [
            ("bins", str(k)),
            ("band", f"{self.freqs[0]:.4g} .. {self.freqs[-1]:.4g} Hz"),
            ("outputs x inputs", f"{ny} x {nu}"),
            ("groups x periods", f"{self.groups} x {self.periods}"),
            ("median SNR of G", f"{10 * np.log10(snr):.1f} dB"),
        ]
        return html_table("BestLinearApproximation", rows)


def estimate_bla(
    u: ArrayLike, y: ArrayLike, fs: float, *, excited: ArrayLike | None = None, threshold: float = 1e-3
) -> BestLinearApproximation:
    """The nonparametric BLA of records ``u`` ``(N, nu, R, P)``, ``y`` ``(N, ny, R, P)`` (see the
    module docstring). ``R`` must be a multiple of ``nu`` (groups of ``nu`` realizations).
    ``excited`` (bin numbers) defaults to the bins where every input's amplitude exceeds
    ``threshold`` times its largest (DC excluded).

    Parameters
    ----------
    u, y : array_like
        Inputs ``(N, nu, R, P)`` and outputs ``(N, ny, R, P)`` (:func:`multisine_records`).
    fs : float
        Sample rate (Hz).
    excited : array_like of int, optional
        The DFT bins to estimate at; default the excited ones.
    threshold : float
        Relative amplitude below which a bin counts as not excited.

    Returns
    -------
    BestLinearApproximation
        The BLA and its variances at the excited bins.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.signals.frf import estimate_bla
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal((64, 1, 4, 2)); u[..., 1] = u[..., 0]   # 4 realizations, 2 periods
    >>> y = u + 0.5 * np.roll(u, 1, axis=0)                           # y[t] = u[t] + 0.5 u[t-1]
    >>> y[..., 1] += 0.01 * rng.standard_normal((64, 1, 4))           # noise on the second period
    >>> bla = estimate_bla(u, y, fs=64.0)
    >>> bla.freqs[:3].tolist()
    [1.0, 2.0, 3.0]
    >>> exact = 1 + 0.5 * np.exp(-2j * np.pi * bla.freqs / 64)
    >>> bool(np.abs(bla.G[:, 0, 0] - exact).max() < 0.05)
    True
    >>> bool((bla.noise_var > 0).all()), estimate_bla(u, y, fs=64.0, excited=[4]).G.shape
    (True, (1, 1, 1))
    """
    uu, yy = multisine_records(u, y)
    n, nu, r, p = uu.shape
    if r < nu or r % nu:
        raise ParameterError(f"u has {r} realizations; the BLA of {nu} inputs needs a multiple of {nu}")
    if not (np.isfinite(fs) and fs > 0):
        raise ParameterError(f"fs = {fs} must be a sample rate > 0 (Hz)")
    uf = np.fft.rfft(uu, axis=0)
    yf = np.fft.rfft(yy, axis=0)
    um, ym = uf.mean(axis=3), yf.mean(axis=3)  # (K, ch, R)
    if excited is None:
        amp = np.abs(um).min(axis=2)  # (K, nu)
        ok = (amp > threshold * amp[1:].max(axis=0)).all(axis=1)
        ok[0] = False
        bins = np.nonzero(ok)[0]
    else:
        bins = np.asarray(excited, dtype=np.int64)
    if bins.size == 0:
        raise ParameterError("u excites no bin (no DFT bin has every input above the threshold)")
    # noise variance of the period mean of Y, per bin, output and realization
    var_y = (np.abs(yf - ym[..., None]) ** 2).sum(axis=3) / (p * (p - 1)) if p > 1 else np.zeros(ym.shape)
    ng = r // nu
    gs = []
    nvs = []
    for g in range(ng):
        ug = um[bins][:, :, g * nu : (g + 1) * nu]  # (K, nu, nu): input x realization
        yg = ym[bins][:, :, g * nu : (g + 1) * nu]
        inv = np.linalg.inv(ug)  # (K, realization, input)
        gs.append(yg @ inv)
        vy = var_y[bins][:, :, g * nu : (g + 1) * nu]  # (K, ny, realization)
        nvs.append(vy @ (np.abs(inv) ** 2))
    G = np.mean(gs, axis=0)
    noise = np.sum(nvs, axis=0) / ng**2
    spread = np.abs(np.array(gs) - G) ** 2
    total = spread.sum(axis=0) / (ng * (ng - 1)) if ng > 1 else noise.copy()
    freqs = bins * fs / n
    return BestLinearApproximation(
        freqs=freqs.astype(np.float64),
        bins=bins.astype(np.float64),
        G_real=np.ascontiguousarray(G.real),
        G_imag=np.ascontiguousarray(G.imag),
        noise_var=np.ascontiguousarray(noise),
        total_var=np.ascontiguousarray(total),
        fs=float(fs),
        groups=ng,
        periods=p,
    )
