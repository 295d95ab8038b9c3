"""Identification of MIMO stage models (:class:`~piezohyst.models.mimo.MimoModel`) from
periodic multisine records (issue 15: the Fine Steering Mirror benchmark's layout).

The path, every step measured on held-back realizations:

1. the nonparametric BLA (:func:`piezohyst.signals.frf.estimate_bla`) of all records;
2. its poles by the frequency-domain subspace method of McKelvey, Akçay & Ljung (1996)
   (:func:`subspace`), stabilized (a pole outside the unit circle reflected inside);
3. with the poles fixed, the residues (one ``ny x (nu + nw)`` matrix per pole) and the
   direct term by linear least squares on the records' spectra (:func:`fit_residues`) — for
   periodic steady-state records this is the output error of the simulation (Parseval);
4. the hysteresis: ``nw`` banks of play operators on the feedback signal ``z`` feed
   ``w`` back into the dynamics (``structure="lfr"``: ``z`` the model's own output, so
   the resonances move with amplitude) or act on the inputs (``"hammerstein"``). The first
   fit uses the measured output as ``z`` (equation error); each further iteration simulates
   the model and refits with its own ``z`` (toward output error);
5. the realization: per pole, the SVD of its residue matrix gives a minimal block
   (:func:`realize`).

:func:`identify_mimo` runs it for one kind or (``kind="auto"``) chooses among the kinds by
the benchmark protocol on held-back realizations (:func:`protocol_rmse`).

Examples
--------
>>> import numpy as np
>>> from piezohyst.identify.mimo import subspace
>>> a = np.diag([0.9, 0.5]); b = np.ones((2, 1)); c = np.ones((1, 2))
>>> k = np.arange(1, 64); z = np.exp(2j * np.pi * k / 128)
>>> g = np.array([c @ np.linalg.solve(zi * np.eye(2) - a, b) for zi in z])
>>> A, B, C, D = subspace(g, k / 128, order=2)
>>> np.round(np.sort(np.linalg.eigvals(A).real), 6).tolist()
[0.5, 0.9]
"""

from __future__ import annotations

import re
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import _core
from .._io import PathLike
from ..errors import DataError, ParameterError
from ..models.mimo import MimoModel, Structure
from ..signals.frf import estimate_bla, multisine_records
from ._sets import set_means
from .mimo_oe import refine_output_error, sliding_poles

__all__ = [
    "INIT_RIDGES",
    "MIMO_KINDS",
    "MimoIdentification",
    "MimoRecords",
    "MimoSettings",
    "choose_init_ridge",
    "fit_residues",
    "identify_mimo",
    "protocol_rmse",
    "read_multisine_folder",
    "realize",
    "set_means",
    "sliding_radius",
    "subspace",
]

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]

#: The MIMO model kinds of :func:`identify_mimo` (``auto`` chooses among them).
MIMO_KINDS = ("mimo-linear", "mimo-hammerstein", "mimo-lfr")
Kind = Literal["auto", "mimo-linear", "mimo-hammerstein", "mimo-lfr"]


# -- data -------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class MimoRecords:
    """Periodic multisine records: ``u`` ``(N, nu, R, P)``, ``y`` ``(N, ny, R, P)`` (samples,
    channels, realizations, periods), ``fs`` (Hz), ``labels`` (one per realization: its set,
    e.g. the excitation level) and ``group`` (one per realization: the index of its group of
    ``nu`` realizations within its set, which is what the held-out folds split on).

    Parameters
    ----------
    u, y : numpy.ndarray
        Inputs ``(N, nu, R, P)`` and outputs ``(N, ny, R, P)``.
    fs : float
        Sample rate (Hz).
    labels : tuple of str
        The set of each realization.
    group : tuple of int
        The group of each realization within its set.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.models.mimo import MimoModel
    >>> from piezohyst.identify.mimo import MimoRecords, MimoSettings, identify_mimo
    >>> true = MimoModel.linear(A=[[0.9, 0.0], [0.0, 0.5]], B=[[1.0], [1.0]], C=[[0.1, 0.2]], D=[[0.0]], fs=1000.0)
    >>> spec = np.zeros((4, 65), complex)
    >>> spec[:, 1:64] = np.exp(2j * np.pi * np.random.default_rng(0).random((4, 63)))
    >>> u = np.fft.irfft(spec, 128, axis=1)[:, :, None]  # 4 random-phase multisines (R, N, nu)
    >>> y = true.simulate(u)  # in periodic steady state (R, N, ny)
    >>> u4, y4 = (np.stack([np.moveaxis(a, 0, 2)] * 2, axis=3) for a in (u, y))  # (N, ch, R, P=2)
    >>> recs = MimoRecords.from_sets([("1V", u4, y4)], fs=1000.0)
    >>> recs.nu, recs.ny, recs.u.shape, recs.labels
    (1, 1, (128, 1, 4, 2), ('1V', '1V', '1V', '1V'))
    """

    u: FloatArray
    y: FloatArray
    fs: float
    labels: tuple[str, ...]
    group: tuple[int, ...]

    @classmethod
    def from_sets(cls, sets: Sequence[tuple[str, ArrayLike, ArrayLike]], fs: float) -> MimoRecords:
        """Records from ``(label, u, y)`` sets (e.g. one per level), concatenated along the
        realizations; within a set, realizations ``g*nu .. g*nu + nu - 1`` form group ``g``.

        Parameters
        ----------
        sets : sequence of (str, array_like, array_like)
            ``(label, u, y)`` with ``u`` ``(N, nu, R, P)`` and ``y`` ``(N, ny, R, P)``.
        fs : float
            Sample rate (Hz).

        Returns
        -------
        MimoRecords
            The sets' realizations, one after the other.

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst.models.mimo import MimoModel
        >>> from piezohyst.identify.mimo import MimoRecords, MimoSettings, identify_mimo
        >>> true = MimoModel.linear(A=[[0.9, 0.0], [0.0, 0.5]], B=[[1.0], [1.0]], C=[[0.1, 0.2]], D=[[0.0]], fs=1000.0)
        >>> spec = np.zeros((4, 65), complex)
        >>> spec[:, 1:64] = np.exp(2j * np.pi * np.random.default_rng(0).random((4, 63)))
        >>> u = np.fft.irfft(spec, 128, axis=1)[:, :, None]  # 4 random-phase multisines (R, N, nu)
        >>> y = true.simulate(u)  # in periodic steady state (R, N, ny)
        >>> u4, y4 = (np.stack([np.moveaxis(a, 0, 2)] * 2, axis=3) for a in (u, y))  # (N, ch, R, P=2)
        >>> recs = MimoRecords.from_sets([("1V", u4, y4)], fs=1000.0)
        >>> two = MimoRecords.from_sets([("1V", u4, y4), ("2V", 2 * u4, 2 * y4)], fs=1000.0)
        >>> two.u.shape, two.labels[3:5], two.group
        ((128, 1, 8, 2), ('1V', '2V'), (0, 1, 2, 3, 0, 1, 2, 3))
        """
        us, ys, labels, group = [], [], [], []
        for label, u, y in sets:
            uu, yy = multisine_records(u, y)
            us.append(uu)
            ys.append(yy)
            nu = uu.shape[1]
            labels += [label] * uu.shape[2]
            group += [r // nu for r in range(uu.shape[2])]
        if not us:
            raise ParameterError("no records given")
        shapes = {(a.shape[0], a.shape[1], a.shape[3]) for a in us} | set()
        if len(shapes) != 1 or len({(a.shape[0], a.shape[1]) for a in ys}) != 1:
            raise ParameterError(f"the sets' records differ in samples, channels or periods: {sorted(shapes)}")
        return cls(np.concatenate(us, axis=2), np.concatenate(ys, axis=2), float(fs), tuple(labels), tuple(group))

    @property
    def nu(self) -> int:
        """Inputs."""
        return int(self.u.shape[1])

    @property
    def ny(self) -> int:
        """Outputs."""
        return int(self.y.shape[1])

    def select(self, realizations: Sequence[int]) -> MimoRecords:
        """The records of the given realizations (indices into the concatenation).

        Parameters
        ----------
        realizations : sequence of int
            Indices of the realizations to keep.

        Returns
        -------
        MimoRecords
            Those realizations.

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst.models.mimo import MimoModel
        >>> from piezohyst.identify.mimo import MimoRecords, MimoSettings, identify_mimo
        >>> true = MimoModel.linear(A=[[0.9, 0.0], [0.0, 0.5]], B=[[1.0], [1.0]], C=[[0.1, 0.2]], D=[[0.0]], fs=1000.0)
        >>> spec = np.zeros((4, 65), complex)
        >>> spec[:, 1:64] = np.exp(2j * np.pi * np.random.default_rng(0).random((4, 63)))
        >>> u = np.fft.irfft(spec, 128, axis=1)[:, :, None]  # 4 random-phase multisines (R, N, nu)
        >>> y = true.simulate(u)  # in periodic steady state (R, N, ny)
        >>> u4, y4 = (np.stack([np.moveaxis(a, 0, 2)] * 2, axis=3) for a in (u, y))  # (N, ch, R, P=2)
        >>> recs = MimoRecords.from_sets([("1V", u4, y4)], fs=1000.0)
        >>> sub = recs.select([0, 2])
        >>> sub.u.shape, sub.group
        ((128, 1, 2, 2), (0, 2))
        """
        idx = list(realizations)
        return MimoRecords(
            self.u[:, :, idx],
            self.y[:, :, idx],
            self.fs,
            tuple(self.labels[i] for i in idx),
            tuple(self.group[i] for i in idx),
        )

    def folds(self) -> list[list[int]]:
        """Realization indices per fold: fold ``f`` holds every set's group ``f``.

        Returns
        -------
        list of list of int
            One list of realization indices per fold.

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst.models.mimo import MimoModel
        >>> from piezohyst.identify.mimo import MimoRecords, MimoSettings, identify_mimo
        >>> true = MimoModel.linear(A=[[0.9, 0.0], [0.0, 0.5]], B=[[1.0], [1.0]], C=[[0.1, 0.2]], D=[[0.0]], fs=1000.0)
        >>> spec = np.zeros((4, 65), complex)
        >>> spec[:, 1:64] = np.exp(2j * np.pi * np.random.default_rng(0).random((4, 63)))
        >>> u = np.fft.irfft(spec, 128, axis=1)[:, :, None]  # 4 random-phase multisines (R, N, nu)
        >>> y = true.simulate(u)  # in periodic steady state (R, N, ny)
        >>> u4, y4 = (np.stack([np.moveaxis(a, 0, 2)] * 2, axis=3) for a in (u, y))  # (N, ch, R, P=2)
        >>> recs = MimoRecords.from_sets([("1V", u4, y4)], fs=1000.0)
        >>> recs.folds()  # one input: every realization is a group
        [[0], [1], [2], [3]]
        """
        n = max(self.group) + 1
        return [[i for i, g in enumerate(self.group) if g == f] for f in range(n)]


def read_multisine_folder(path: PathLike, fs: float) -> MimoRecords:
    """Records from a folder of ``u_<name>.npy`` / ``y_<name>.npy`` pairs in the
    nonlinear-benchmark layout ``(N, channels, R, P)`` (one set per name, in name order).
    ``DataError`` naming the folder or the file when there is no pair or a file is not such
    an array.

    Parameters
    ----------
    path : str or os.PathLike
        The folder.
    fs : float
        Sample rate (Hz).

    Returns
    -------
    MimoRecords
        One set per ``u_<name>.npy`` / ``y_<name>.npy`` pair (label ``<name>`` without a
        trailing ``_train``).

    Examples
    --------
    >>> import pathlib, tempfile
    >>> import numpy as np
    >>> from piezohyst.identify.mimo import read_multisine_folder
    >>> u = np.random.default_rng(0).standard_normal((64, 2, 2, 1))
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     np.save(pathlib.Path(tmp) / "u_100mV_train.npy", u)
    ...     np.save(pathlib.Path(tmp) / "y_100mV_train.npy", 3 * u)
    ...     recs = read_multisine_folder(tmp, fs=1000.0)
    >>> recs.labels, recs.nu, recs.ny
    (('100mV', '100mV'), 2, 2)
    """
    folder = Path(path)
    if not folder.is_dir():
        raise DataError(f"data folder '{folder}' is not a folder")
    sets = []
    for uf in sorted(folder.glob("u_*.npy")):
        name = uf.name[2:-4]
        yf = folder / f"y_{name}.npy"
        if not yf.is_file():
            continue
        try:
            u = np.load(uf, allow_pickle=False)
            y = np.load(yf, allow_pickle=False)
        except (OSError, ValueError) as e:
            raise DataError(f"'{uf}' / '{yf}' are not numpy arrays: {e}") from None
        label = re.sub(r"_?train$", "", name) or name
        sets.append((label, u, y))
    if not sets:
        raise DataError(f"data folder '{folder}' holds no u_<name>.npy / y_<name>.npy pair")
    try:
        return MimoRecords.from_sets(sets, fs)
    except ParameterError as e:
        raise DataError(f"data folder '{folder}': {e}") from None


# -- subspace -------------------------------------------------------------------------------
def subspace(
    G: ArrayLike, freqs: ArrayLike, order: int, *, q: int | None = None, radius: float = 0.9999
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """``(A, B, C, D)`` of order ``order`` fitted to the FRF ``G`` ``(K, ny, nu)`` at the
    normalized frequencies ``freqs`` (cycles per sample, ``0 < f < 0.5``): McKelvey's
    frequency-domain subspace method (``q`` block rows, default ``2 * order``); poles
    outside ``radius`` reflected inside it; ``B``, ``D`` by linear least squares.

    Parameters
    ----------
    G : array_like
        The FRF ``(K, ny, nu)``.
    freqs : array_like
        Its normalized frequencies ``(K,)`` (cycles per sample).
    order : int
        States of the model.
    q : int, optional
        Block rows (default ``2 * order``).
    radius : float
        The largest pole radius kept; poles outside are reflected inside.

    Returns
    -------
    A, B, C, D : numpy.ndarray
        The state-space matrices.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.identify.mimo import subspace
    >>> a = np.diag([0.9, 0.5]); b = np.ones((2, 1)); c = np.array([[0.1, 0.2]])
    >>> f = np.arange(1, 64) / 128; z = np.exp(2j * np.pi * f)
    >>> g = np.array([c @ np.linalg.solve(zi * np.eye(2) - a, b) for zi in z])
    >>> A, B, C, D = subspace(g, f, order=2)
    >>> np.round(np.sort(np.linalg.eigvals(A).real), 6).tolist()
    [0.5, 0.9]
    >>> zi = z[10]; bool(np.allclose(C @ np.linalg.solve(zi * np.eye(2) - A, B) + D, g[10]))
    True
    """
    g = np.asarray(G, dtype=np.complex128)
    f = np.asarray(freqs, dtype=np.float64)
    if g.ndim != 3 or f.shape != (g.shape[0],):
        raise ParameterError(f"G has shape {g.shape} and freqs {f.shape}; expected (K, ny, nu) and (K,)")
    k, p, m = g.shape
    n = int(order)
    qq = 2 * n if q is None else int(q)
    if n < 1 or qq * p <= n or k * m < qq * m + n:
        raise ParameterError(f"order = {order} does not fit the data (q = {qq}, {k} frequencies, {p} outputs)")
    z = np.exp(2j * np.pi * f)
    wq = z[None, :] ** np.arange(qq)[:, None]  # (q, K)
    gb = np.einsum("qk,kij->qikj", wq, g).reshape(qq * p, k * m)
    wb = np.einsum("qk,ij->qikj", wq, np.eye(m)).reshape(qq * m, k * m)
    h = np.vstack([np.hstack([wb.real, wb.imag]), np.hstack([gb.real, gb.imag])])
    r = np.asarray(np.linalg.qr(h.T, mode="r")).T
    r22 = r[qq * m :, qq * m :]
    us = np.linalg.svd(r22, full_matrices=False)[0][:, :n]
    c = us[:p]
    a = np.linalg.lstsq(us[:-p], us[p:], rcond=None)[0]
    a = _stabilize(a, radius)
    b, d = _fit_bd(a, c, g, z)
    return a, b, c, d


def _inside(ev: ComplexArray, radius: float) -> ComplexArray:
    """Poles outside ``radius`` brought inside it: an unstable pole reflected (``1/conj``, times
    ``radius``), a stable one between ``radius`` and 1 moved onto ``radius`` (a reflection alone
    would leave it there: ``radius / |p| > radius`` when ``|p| < 1``)."""
    bad = np.abs(ev) > radius
    ev = ev.copy()
    mag = np.abs(ev[bad])
    ev[bad] = ev[bad] / mag * radius * np.minimum(1.0, 1.0 / mag)
    return ev


def _stabilize(a: FloatArray, radius: float) -> FloatArray:
    ev, v = np.linalg.eig(a)
    if not (np.abs(ev) > radius).any():
        return a
    ev = _inside(ev, radius)
    return np.asarray(np.real(v @ np.diag(ev) @ np.linalg.inv(v)), dtype=np.float64)


def _fit_bd(a: FloatArray, c: FloatArray, g: ComplexArray, z: ComplexArray) -> tuple[FloatArray, FloatArray]:
    n, p, m = a.shape[0], c.shape[0], g.shape[2]
    cr = c @ np.linalg.inv(z[:, None, None] * np.eye(n) - a)  # (K, p, n)
    phi = np.concatenate([cr, np.broadcast_to(np.eye(p), (z.size, p, p))], axis=2).reshape(z.size * p, n + p)
    phi_r = np.vstack([phi.real, phi.imag])
    rhs = g.reshape(z.size * p, m)
    th = np.linalg.lstsq(phi_r, np.vstack([rhs.real, rhs.imag]), rcond=None)[0]
    return np.ascontiguousarray(th[:n]), np.ascontiguousarray(th[n:])


def _split_poles(a: FloatArray) -> tuple[FloatArray, ComplexArray]:
    ev = np.linalg.eigvals(a)
    real = np.sort(ev[np.abs(ev.imag) < 1e-10].real)
    cplx = ev[ev.imag >= 1e-10]
    return real.astype(np.float64), cplx[np.argsort(np.angle(cplx))].astype(np.complex128)


# -- residues ---------------------------------------------------------------------------------
def _basis(n: int, real: FloatArray, cplx: ComplexArray) -> ComplexArray:
    """``(K, nb)`` basis functions at the rfft bins of ``n`` samples: per real pole
    ``1/(z-p)``, per complex pole ``1/(z-p) + 1/(z-p*)`` and ``i(1/(z-p) - 1/(z-p*))``."""
    z = np.exp(2j * np.pi * np.arange(n // 2 + 1) / n)[:, None]
    cols = [1.0 / (z - real[None, :])]
    a = 1.0 / (z - cplx[None, :])
    b = 1.0 / (z - np.conj(cplx)[None, :])
    cols += [a + b, 1j * (a - b)]
    return np.concatenate(cols, axis=1)


def play_features(z: FloatArray, thresholds: FloatArray) -> FloatArray:
    """Play operators of the periodic signals ``z`` ``(N, m, R)`` at ``thresholds``
    ``(m, nr)``, in periodic steady state (one period of warm-up): ``(N, m*nr, R)``,
    channel-major (Rust, records in parallel)."""
    n, _, r = z.shape
    zz = np.ascontiguousarray(np.moveaxis(np.concatenate([z, z], axis=0), 2, 0))
    th = np.ascontiguousarray(thresholds, dtype=np.float64)
    out, _ = _core.play_bank(zz, th, np.zeros((r, th.size)))
    return np.ascontiguousarray(np.moveaxis(out[:, n:], 0, 2))


@dataclass(frozen=True)
class _ResidueFit:
    real: FloatArray
    cplx: ComplexArray
    theta: FloatArray  # (ncols, ny)
    nu: int
    nw: int


def fit_residues(
    u: FloatArray,
    y: FloatArray,
    real: FloatArray,
    cplx: ComplexArray,
    w: FloatArray | None = None,
    *,
    ridge: float = 1e-10,
    record_weights: FloatArray | None = None,
) -> _ResidueFit:
    """The residues and direct term, poles fixed, by linear least squares on the spectra of
    the period-averaged records ``u`` ``(N, nu, R)``, ``y`` ``(N, ny, R)`` and the extra
    inputs ``w`` ``(N, nw, R)`` (strictly proper: no direct term). Normal equations
    accumulated per record (each weighted by ``record_weights``), columns scaled, ``ridge``
    relative to the largest diagonal.

    Parameters
    ----------
    u, y : numpy.ndarray
        Period-averaged inputs ``(N, nu, R)`` and outputs ``(N, ny, R)``.
    real : numpy.ndarray
        The real poles (z-domain).
    cplx : numpy.ndarray
        The complex poles, one of each conjugate pair (upper half plane).
    w : numpy.ndarray, optional
        Extra (feedback) inputs ``(N, nw, R)`` without a direct term.
    ridge : float
        Ridge weight relative to the largest diagonal of the scaled normal equations.
    record_weights : numpy.ndarray, optional
        One weight per record ``(R,)``.

    Returns
    -------
    object
        The residue fit (poles, parameters, ``nu``, ``nw``), for :func:`realize`.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.models.mimo import MimoModel
    >>> true = MimoModel.linear(A=[[0.9, 0.0], [0.0, 0.5]], B=[[1.0], [1.0]], C=[[0.1, 0.2]], D=[[0.0]], fs=1000.0)
    >>> spec = np.zeros((4, 65), complex)
    >>> spec[:, 1:64] = np.exp(2j * np.pi * np.random.default_rng(0).random((4, 63)))
    >>> u = np.fft.irfft(spec, 128, axis=1)[:, :, None]  # 4 random-phase multisines (R, N, nu)
    >>> y = true.simulate(u)  # in periodic steady state (R, N, ny)
    >>> u4, y4 = (np.stack([np.moveaxis(a, 0, 2)] * 2, axis=3) for a in (u, y))  # (N, ch, R, P=2)
    >>> from piezohyst.identify.mimo import fit_residues, realize
    >>> fit = fit_residues(u4.mean(axis=3), y4.mean(axis=3), np.array([0.9, 0.5]), np.zeros(0, complex))
    >>> A, B, E, C, D = realize(fit)
    >>> np.diag(A).tolist(), np.round((C * B.T).ravel(), 6).tolist()  # the residues C_i B_i
    ([0.9, 0.5], [0.1, 0.2])
    """
    n, nu, r = u.shape
    nw = 0 if w is None else w.shape[1]
    bz = _basis(n, real, cplx)
    nb = bz.shape[1]
    ncols = nu * (nb + 1) + nw * nb
    gram = np.zeros((ncols, ncols))
    rhs = np.zeros((ncols, y.shape[1]))
    uf = np.fft.rfft(u, axis=0)
    yf = np.fft.rfft(y, axis=0)
    wf = None if w is None else np.fft.rfft(w, axis=0)
    bu = np.concatenate([bz, np.ones((bz.shape[0], 1))], axis=1)
    for i in range(r):  # records (a handful), each a vectorized block
        phi = (uf[:, :, i, None] * bu[:, None, :]).reshape(bz.shape[0], nu * (nb + 1))
        if wf is not None:
            phi = np.concatenate([phi, (wf[:, :, i, None] * bz[:, None, :]).reshape(bz.shape[0], nw * nb)], axis=1)
        wt = 1.0 if record_weights is None else float(record_weights[i])
        # real and imaginary parts stacked: one real Gram product (numpy's syrk for a.T @ a)
        phr = np.concatenate([phi.real, phi.imag])
        gram += wt * (phr.T @ phr)
        rhs += wt * (phr.T @ np.concatenate([yf[:, :, i].real, yf[:, :, i].imag]))
    sc = np.sqrt(np.maximum(np.diag(gram), 1e-300))
    gs = gram / sc[:, None] / sc[None, :]
    gs[np.diag_indices_from(gs)] += ridge
    theta = np.linalg.solve(gs, rhs / sc[:, None]) / sc[:, None]
    return _ResidueFit(real, cplx, theta, nu, nw)


def relocate_poles(
    u: FloatArray,
    y: FloatArray,
    real: FloatArray,
    cplx: ComplexArray,
    w: FloatArray | None = None,
    *,
    iterations: int = 3,
    radius: float = 0.9999,
    ridge: float = 1e-10,
    record_weights: FloatArray | None = None,
) -> tuple[FloatArray, ComplexArray]:
    """Better poles by vector fitting's relocation (Gustavsen & Semlyen 1999) on the records'
    spectra (the data of :func:`fit_residues`): ``sigma(z) = 1 + sum c_b basis_b(z)`` and the
    residues solved together from ``sum R X = sigma Y`` (``sigma`` common to the outputs, the
    residues eliminated per output), the new poles the zeros of ``sigma``; poles outside
    ``radius`` reflected inside it."""
    n, nu, r = u.shape
    nw = 0 if w is None else w.shape[1]
    uf = np.fft.rfft(u, axis=0)
    yf = np.fft.rfft(y, axis=0)
    wf = None if w is None else np.fft.rfft(w, axis=0)
    for _ in range(iterations):
        bz = _basis(n, real, cplx)
        nb = bz.shape[1]
        bu = np.concatenate([bz, np.ones((bz.shape[0], 1))], axis=1)
        ncols = nu * (nb + 1) + nw * nb
        ny = y.shape[1]
        pp = np.zeros((ncols, ncols))
        ppsi = np.zeros((ny, ncols, nb))
        psipsi = np.zeros((ny, nb, nb))
        py = np.zeros((ny, ncols))
        psiy = np.zeros((ny, nb))
        for i in range(r):  # records (a handful), each a vectorized block
            phi = (uf[:, :, i, None] * bu[:, None, :]).reshape(bz.shape[0], nu * (nb + 1))
            if wf is not None:
                phi = np.concatenate([phi, (wf[:, :, i, None] * bz[:, None, :]).reshape(bz.shape[0], nw * nb)], axis=1)
            wt = 1.0 if record_weights is None else float(record_weights[i])
            ph = phi.conj().T
            pp += wt * (ph @ phi).real
            for o in range(ny):
                psi = yf[:, o, i, None] * bz
                ppsi[o] += wt * (ph @ psi).real
                psipsi[o] += wt * (psi.conj().T @ psi).real
                py[o] += wt * (ph @ yf[:, o, i]).real
                psiy[o] += wt * (psi.conj().T @ yf[:, o, i]).real
        sc = np.sqrt(np.maximum(np.diag(pp), 1e-300))
        pps = pp / sc[:, None] / sc[None, :]
        pps[np.diag_indices_from(pps)] += ridge
        lhs = np.zeros((nb, nb))
        rhs = np.zeros(nb)
        for o in range(ny):
            q = ppsi[o] / sc[:, None]
            lhs += psipsi[o] - q.T @ np.linalg.solve(pps, q)
            rhs += -psiy[o] + q.T @ np.linalg.solve(pps, py[o] / sc)
        c = np.linalg.solve(lhs + ridge * np.trace(lhs) / nb * np.eye(nb), rhs)
        nr_, nc = real.size, cplx.size
        poles = np.concatenate([real.astype(complex), cplx, np.conj(cplx)])
        ca, cb = c[nr_ : nr_ + nc], c[nr_ + nc :]
        res = np.concatenate([c[:nr_], ca + 1j * cb, ca - 1j * cb])
        zeros = np.linalg.eigvals(np.diag(poles) - np.outer(np.ones(poles.size), res))
        zeros = _inside(zeros, radius)
        real = np.sort(zeros[np.abs(zeros.imag) <= 1e-9].real).astype(np.float64)
        cplx = zeros[zeros.imag > 1e-9]
        cplx = cplx[np.argsort(np.angle(cplx))].astype(np.complex128)
    return real, cplx


def realize(
    fit: _ResidueFit, *, tol: float = 1e-9
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """``(A, B, E, C, D)`` of a residue fit: per pole, the SVD of its residue matrix
    ``[R_u R_w]`` (``ny x (nu + nw)``) gives one block per singular value above ``tol``
    times the largest (2 states for a complex pole, 1 for a real one).

    Parameters
    ----------
    fit : object
        A residue fit of :func:`fit_residues`.
    tol : float
        Singular values at or below ``tol`` times the largest are dropped.

    Returns
    -------
    A, B, E, C, D : numpy.ndarray
        The state-space matrices; ``E`` ``(nx, nw)`` the feedback inputs' matrix.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.models.mimo import MimoModel
    >>> true = MimoModel.linear(A=[[0.9, 0.0], [0.0, 0.5]], B=[[1.0], [1.0]], C=[[0.1, 0.2]], D=[[0.0]], fs=1000.0)
    >>> spec = np.zeros((4, 65), complex)
    >>> spec[:, 1:64] = np.exp(2j * np.pi * np.random.default_rng(0).random((4, 63)))
    >>> u = np.fft.irfft(spec, 128, axis=1)[:, :, None]  # 4 random-phase multisines (R, N, nu)
    >>> y = true.simulate(u)  # in periodic steady state (R, N, ny)
    >>> u4, y4 = (np.stack([np.moveaxis(a, 0, 2)] * 2, axis=3) for a in (u, y))  # (N, ch, R, P=2)
    >>> from piezohyst.identify.mimo import fit_residues, realize
    >>> fit = fit_residues(u4.mean(axis=3), y4.mean(axis=3), np.array([0.9, 0.5]), np.zeros(0, complex))
    >>> A, B, E, C, D = realize(fit)
    >>> A.shape, B.shape, E.shape, C.shape, round(float(abs(D[0, 0])), 9)
    ((2, 2), (2, 1), (2, 0), (1, 2), 0.0)
    """
    nr_, nc = fit.real.size, fit.cplx.size
    nb = nr_ + 2 * nc
    nu, nw = fit.nu, fit.nw
    th = fit.theta
    ny = th.shape[1]
    tu = th[: nu * (nb + 1)].reshape(nu, nb + 1, ny)
    tw = th[nu * (nb + 1) :].reshape(nw, nb, ny)
    d = tu[:, nb, :].T.copy()
    blocks_a: list[FloatArray] = []
    blocks_b: list[FloatArray] = []
    blocks_c: list[FloatArray] = []
    smax = 0.0
    parts = []
    for i, p in enumerate(fit.real):
        res = np.concatenate([tu[:, i, :].T, tw[:, i, :].T], axis=1)  # (ny, nu+nw)
        us, s, vt = np.linalg.svd(res, full_matrices=False)
        smax = max(smax, float(s[0]) if s.size else 0.0)
        parts.append(("r", complex(p), us, s, vt))
    for i, p in enumerate(fit.cplx):
        ia, ib = nr_ + i, nr_ + nc + i
        res = np.concatenate([tu[:, ia, :].T + 1j * tu[:, ib, :].T, tw[:, ia, :].T + 1j * tw[:, ib, :].T], axis=1)
        us, s, vh = np.linalg.svd(res, full_matrices=False)
        smax = max(smax, float(s[0]) if s.size else 0.0)
        parts.append(("c", complex(p), us, s, vh))
    for typ, p, us, s, vh in parts:
        for k in range(s.size):
            if s[k] <= tol * smax:
                continue
            if typ == "r":
                blocks_a.append(np.array([[p.real]]))
                blocks_b.append(vh[k : k + 1].real)
                blocks_c.append((us[:, k] * s[k]).real[:, None])
            else:
                cu = us[:, k] * s[k]
                be = vh[k]
                blocks_a.append(np.array([[p.real, -p.imag], [p.imag, p.real]]))
                blocks_b.append(np.vstack([be.real, be.imag]))
                blocks_c.append(np.column_stack([2 * cu.real, -2 * cu.imag]))
    from scipy.linalg import block_diag

    a = np.asarray(block_diag(*blocks_a), dtype=np.float64)
    bf = np.vstack(blocks_b)
    c = np.hstack(blocks_c)
    return a, np.ascontiguousarray(bf[:, :nu]), np.ascontiguousarray(bf[:, nu:]), np.ascontiguousarray(c), d


# -- protocol ---------------------------------------------------------------------------------
def protocol_rmse(
    model: MimoModel, u: ArrayLike, y: ArrayLike, *, skip: int = 100, use_output: bool = True
) -> FloatArray:
    """The benchmark's score of ``model`` on records ``u`` ``(N, nu, R, P)``, ``y``: each
    period of each realization simulated alone as a test record (its first ``skip`` measured
    outputs set the initial state when ``use_output``), the RMSE per output from sample
    ``skip`` on, averaged over outputs: ``(R, P)`` in the outputs' unit.

    Parameters
    ----------
    model : MimoModel
        The model scored.
    u, y : array_like
        Test records ``(N, nu, R, P)`` and ``(N, ny, R, P)``.
    skip : int
        Samples at the start of each period left out of the score (and used to set the
        initial state).
    use_output : bool
        Set the initial state from the first ``skip`` measured outputs.

    Returns
    -------
    numpy.ndarray
        The RMSE per realization and period ``(R, P)``.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.models.mimo import MimoModel
    >>> from piezohyst.identify.mimo import MimoRecords, MimoSettings, identify_mimo
    >>> true = MimoModel.linear(A=[[0.9, 0.0], [0.0, 0.5]], B=[[1.0], [1.0]], C=[[0.1, 0.2]], D=[[0.0]], fs=1000.0)
    >>> spec = np.zeros((4, 65), complex)
    >>> spec[:, 1:64] = np.exp(2j * np.pi * np.random.default_rng(0).random((4, 63)))
    >>> u = np.fft.irfft(spec, 128, axis=1)[:, :, None]  # 4 random-phase multisines (R, N, nu)
    >>> y = true.simulate(u)  # in periodic steady state (R, N, ny)
    >>> u4, y4 = (np.stack([np.moveaxis(a, 0, 2)] * 2, axis=3) for a in (u, y))  # (N, ch, R, P=2)
    >>> recs = MimoRecords.from_sets([("1V", u4, y4)], fs=1000.0)
    >>> from piezohyst.identify.mimo import protocol_rmse
    >>> protocol_rmse(true, u4, y4, skip=10).shape
    (4, 2)
    >>> bool(protocol_rmse(true, u4, y4, skip=10).max() < 1e-9)  # the true model scores 0
    True
    """
    uu, yy = multisine_records(u, y)
    n, nu, r, p = uu.shape
    recs = np.ascontiguousarray(np.moveaxis(uu, (2, 3), (0, 1)).reshape(r * p, n, nu))
    meas = np.moveaxis(yy, (2, 3), (0, 1)).reshape(r * p, n, yy.shape[1])
    st = model.periodic_state(recs)
    if use_output:
        st = np.vstack([model.estimate_state(recs[i], meas[i, :skip], state=st[i : i + 1]) for i in range(r * p)])
    yh, _, _ = model.run(recs, st)
    e = (yh - meas)[:, skip:]
    rmse = np.sqrt((e**2).mean(axis=1)).mean(axis=1)
    return np.asarray(rmse.reshape(r, p), dtype=np.float64)


#: The weights of the initial-state correction (``MimoModel.init["ridge"]``) that
#: :func:`choose_init_ridge` compares.
INIT_RIDGES = (1e-4, 1e-3, 1e-2, 1e-1, 1.0)


def choose_init_ridge(
    model: MimoModel, records: MimoRecords, *, ridges: Sequence[float] = INIT_RIDGES, skip: int = 100
) -> tuple[MimoModel, dict[str, float]]:
    """``model`` with the weight of its initial-state correction (``init["ridge"]``, see
    :meth:`~piezohyst.models.mimo.MimoModel.estimate_state`) that scores best by
    :func:`protocol_rmse` on ``records``, which the model must not have been fitted on.

    How far to trust the first measured outputs over the model's own periodic state depends
    on the model's error and the records' noise, which only records it did not fit show (on
    the ones it fitted its periodic state is too good). A ridge too small fits the noise of
    a few outputs with 100 states, whose error then lasts the record: FSM records, the
    refined LFR of each leave-one-realization-out fold scored on its held-out realization,
    µm at 300 mV: ridge 1e-4 0.172 to 0.197, 1e-3 0.1645 to 0.1782, 1e-2 0.1643 to 0.1747
    (the periodic state alone 0.1646 to 0.1746). The score of each ridge is the mean over
    sets of its RMSE relative to the first ridge's; the smallest wins, the first on a tie.

    Parameters
    ----------
    model : MimoModel
        The model.
    records : MimoRecords
        Records the model was not fitted on.
    ridges : sequence of float
        The weights compared (each ``> 0``).
    skip : int
        Measured outputs that set the state (the benchmark's 100).

    Returns
    -------
    model : MimoModel
        ``model`` with ``init["ridge"]`` the best ridge.
    scores : dict of str to float
        Each ridge's score.

    Examples
    --------
    A model that is right, records with noise: the periodic state beats any fit of the noise.

    >>> import numpy as np
    >>> from piezohyst.models.mimo import MimoModel
    >>> from piezohyst.identify.mimo import MimoRecords, choose_init_ridge
    >>> m = MimoModel.linear(A=[[0.95]], B=[[1.0]], C=[[0.1]], D=[[0.0]], fs=1000.0)
    >>> rng = np.random.default_rng(1)
    >>> u = rng.standard_normal((2, 256, 1))
    >>> y = m.simulate(u) + 0.05 * rng.standard_normal((2, 256, 1))
    >>> four = lambda a: np.stack([np.moveaxis(a, 0, 2)] * 2, axis=3)  # (N, ch, R, P=2)
    >>> recs = MimoRecords.from_sets([("1V", four(u), four(y))], fs=1000.0)
    >>> best, scores = choose_init_ridge(m, recs, skip=20)
    >>> best.init["ridge"], scores["0.0001"] > scores["1"]
    (1.0, True)
    """
    r = [float(v) for v in ridges]
    if not r or not all(np.isfinite(v) and v > 0 for v in r):
        raise ParameterError(f"ridges = {list(ridges)!r} must be numbers > 0 (at least one)")
    err = []
    for v in r:
        e = protocol_rmse(replace(model, init={**model.init, "ridge": v}), records.u, records.y, skip=skip)
        err.append(list(set_means(e, records.labels).values()))
    rel = np.asarray(err) / np.maximum(np.asarray(err[0]), 1e-300)
    score = rel.mean(axis=1)
    best = r[int(np.argmin(score))]
    return replace(model, init={**model.init, "ridge": best}), {
        f"{v:g}": float(sc) for v, sc in zip(r, score, strict=True)
    }


# -- identification ---------------------------------------------------------------------------
@dataclass(frozen=True)
class MimoSettings:
    """Settings of one MIMO kind: ``order`` (poles of the subspace fit), ``thresholds``
    (play thresholds as fractions of each output's RMS, the LFR's feedback; of each input's
    RMS for the Hammerstein and the LFR's input plays), ``iterations`` (output-error refits
    with the model's own feedback signal), ``relocations`` / ``oe_relocations`` (pole
    relocations before the first fit / at each refit; off: on the FSM records they raised
    the held-out error), ``input_plays`` (the LFR also has play operators on the inputs, a
    Hammerstein part), ``balance`` (record weights, below).

    Defaults chosen on the FSM records by held-out realizations (fit {1,2,3}, score {4,5,6}):
    order 40 over 28 and 56 (0.132/0.182/0.239 vs 0.151/0.205/0.268 and 0.130/0.180/0.237 µm
    at 100/200/300 mV), 4 thresholds over 7 (0.131/0.183/0.234), input plays
    (0.120/0.173/0.237), balance 0.5 (0.100/0.169/0.256; 1: 0.086/0.171/0.278). After the
    output-error refinement (same split, L-BFGS iterations fixed): static channels at 0.5, 1, 2
    output RMS beside the plays 0.072/0.152/0.229 µm against 0.077/0.155/0.246 without (300
    iterations), 0.069/0.146/0.221 at 800; static channels alone (no plays, scales 0.25-2)
    0.078/0.154/0.235 at 800. The refinement keeps improving past the budget (realization 6
    held out, the default kind with static channels: 0.073/0.145/0.213 µm at 400 iterations,
    0.065/0.124/0.188 at 1600, validation still falling), so its default stop is its time
    budget. Static channels are not on by default:
    on a known 2x2 play-LFR (tests/identify/test_mimo_oe.py) they start better but the
    refinement overfits them (training error down, held-back up, early-stopped at the start);
    ``auto`` fits the LFR with and without them and keeps the better by held-out realizations.

    Parameters
    ----------
    order : int
        Poles of the subspace fit.
    thresholds : tuple of float
        Play thresholds, fractions of the RMS of the signal each bank acts on.
    iterations : int
        Output-error refits of the LFR with its own feedback signal.
    relocations : int
        Pole relocations before the first fit.
    input_plays : bool
        The LFR also has play operators on the inputs.
    balance : float
        Records weighted by their output's mean square to the power ``-balance``.
    oe_relocations : int
        Pole relocations at each refit after the first.
    oe_iterations : int
        Iterations of the output-error refinement (LFR and Hammerstein; 0: off).
    oe_seconds : float
        Its time budget (seconds).
    oe_balance : float
        Its level weighting (records by their set's mean square output to the power
        ``-oe_balance``).
    static_scales : tuple of float
        Scales of the LFR's static feedback channels (fractions of each output's RMS); empty:
        none.
    oe_free : tuple of str
        What the output-error refinement fits beyond its default set (``"thresholds"``,
        ``"F"``; see :func:`~piezohyst.identify.mimo_oe.refine_output_error`'s ``free``).
    oe_watch : float
        The share (0 to 1) of the refinement's time and iterations early-stopped on held-back
        realizations before they join the fit (see :func:`identify_mimo`).
    oe_sliding_margin : float or None
        The LFR's sliding loop (its feedback at large amplitude) kept decaying at least this
        share (0 to 1] as fast as the start's slowest linear pole (:func:`sliding_radius`);
        ``None``: unbounded.

    Examples
    --------
    >>> from piezohyst.identify.mimo import MimoSettings
    >>> s = MimoSettings(order=2, thresholds=(0.5,))
    >>> s.order, s.thresholds, s.iterations, s.balance
    (2, (0.5,), 2, 0.5)
    """

    order: int = 40
    thresholds: tuple[float, ...] = (0.15, 0.45, 0.9, 1.5)
    iterations: int = 2
    relocations: int = 0
    input_plays: bool = True
    #: weight each record by its output's mean square to the power ``-balance``: 0 weighs all
    #: alike (the largest level dominates the squared error), 1 makes every level count alike
    #: (as the benchmark's mean of per-level RMSEs does), 0.5 between
    balance: float = 0.5
    #: pole relocations at each refit after the first (the feedback signal simulated)
    oe_relocations: int = 0
    #: L-BFGS iterations of the output-error refinement of the LFR / Hammerstein model
    #: (:func:`piezohyst.identify.mimo_oe.refine_output_error`, all sets jointly, watched on
    #: the last realization of each set, see ``oe_watch``); 0: off
    oe_iterations: int = 2000
    #: its time budget (seconds); :func:`identify_mimo`'s ``time_budget`` (the whole call's)
    #: binds first on the FSM records (the frequency-domain fits before it take about 40 s)
    oe_seconds: float = 600.0
    #: its level weighting: each record by its set's mean square output to the power
    #: ``-oe_balance`` (FSM records, realization 6 held out, 360 s: 0.5 gave 0.0754 / 0.149 /
    #: 0.218 µm, 1 gave 0.0689 / 0.148 / 0.227: the largest level, furthest from its target,
    #: gains what the smallest, well within its own, gives up; 400 iterations: 0.5 gave 0.0732 /
    #: 0.145 / 0.213, 0 gave 0.0815 / 0.149 / 0.207); at full length (static channels, 540 s,
    #: bench/fsm.py's six leave-one-out folds, µm at 100 / 200 / 300 mV) 0.25 gave 0.0737 /
    #: 0.1135 / 0.1651 against 0.5's 0.0714 / 0.1137 / 0.1675: 300 mV, the level nearest its
    #: target, gains in five folds of six (-0.5 to -2.8 %, +1 % in one), 100 mV (15 % inside its
    #: target) gives up 3 %; 0 of 50 new realizations per level failing at the level's amplitude.
    #: 0.1 (the same folds): 0.0758 / 0.1140 / 0.1649, 300 mV per fold 0.1661,
    #: 0.1624, 0.1715, 0.1576, 0.1614, 0.1704 (0.25: 0.1665, 0.1632, 0.1737, 0.1566, 0.1610,
    #: 0.1695), {1,2,3} -> {4,5,6} 0.1768 against 0.1752: no gain at 300 mV, 3 % lost at 100
    #: mV. Its fits are steadier (no fold stopped after probe alarms, none of 50 new
    #: realizations failing at 1.1 times any level; 0.25: fold 3 stopped, fold 1 7 of 50)
    oe_balance: float = 0.25
    #: the LFR's static (saturating) feedback channels ``r tanh(z / r)`` on each output, ``r``
    #: these fractions of the output's RMS (after the play channels); empty: none
    static_scales: tuple[float, ...] = ()
    #: the refinement also fits the play thresholds and the feedback's feedthrough ``F``
    #: (FSM records, realization 6 of each level held out, 200 iterations in runs of 20: 0.0796 /
    #: 0.169 / 0.259 µm with them free, 0.0811 / 0.170 / 0.261 without)
    oe_free: tuple[str, ...] = ("thresholds", "F")
    #: the share of the refinement's time and iterations fitted without the last realization of
    #: each set, early-stopped on it; unless the held-back error rose by then (overfitting), the
    #: rest is fitted on all realizations (1: early-stopped all the way; 0: all realizations
    #: from the start, no early stopping). FSM records, realization 6 held out, 480 s from the same start, µm at
    #: 100 / 200 / 300 mV: early-stopped all the way 0.0618 / 0.120 / 0.184 (1149 iterations,
    #: the budget binding: the held-back error was still falling); 0.5: 0.0610 / 0.120 / 0.179
    #: (588 watched, 505 on all); 0.25: 0.0607 / 0.119 / 0.179; all realizations from the
    #: start about 0.059 / 0.118 / 0.176 (its periodic steady state scored, 969 iterations).
    #: At the whole budget (realizations 1-5 fitted, 6 held out, 540 s, the protocol): 0 gave
    #: 0.0600 / 0.1222 / 0.1782 µm (1921 iterations; with the best initial-state ridge in
    #: hindsight 0.0588 / 0.1198 / 0.1752), 0.5 gave 0.0594 / 0.1185 / 0.1740 (2000).
    #: 0.5 keeps a watch long enough to stop a refinement that overfits
    oe_watch: float = 0.5
    #: the bound of the sliding loop's poles during the output-error refinement
    #: (:func:`sliding_radius`); off by default. 0.6 (0.9962 on the FSM records, where new
    #: realizations 10 % above 300 mV began to fail in the acceptance run's unbounded fit),
    #: bench/fsm.py's six leave-one-out folds: 0.0741 / 0.1139 / 0.1658 µm against 0.0737 /
    #: 0.1135 / 0.1651 unbounded (300 mV per fold 0.1691, 0.1641, 0.1718, 0.1584, 0.1623,
    #: 0.1690); fold 3 still stopped as unstable; {1,2,3} -> {4,5,6} 0.0621 / 0.1129 / 0.1743
    #: (0.1752 unbounded). No gain: kept as an option
    oe_sliding_margin: float | None = None

    def __post_init__(self) -> None:
        w = self.oe_watch
        if isinstance(w, bool) or not (isinstance(w, (int, float)) and 0.0 <= w <= 1.0):
            raise ParameterError(f"oe_watch = {self.oe_watch!r} must be a share in [0, 1]")
        m = self.oe_sliding_margin
        if m is not None and (isinstance(m, bool) or not (isinstance(m, (int, float)) and 0.0 < m <= 1.0)):
            raise ParameterError(f"oe_sliding_margin = {m!r} must be None or in (0, 1]")


@dataclass(frozen=True, eq=False)
class MimoIdentification:
    """A MIMO model and its report: ``kind``, ``settings``, ``holdout`` (per candidate: the
    protocol RMSE per set on held-back realizations), ``seconds``.

    Parameters
    ----------
    model : MimoModel
        The identified model (its ``fit`` holds :meth:`report`).
    kind : str
        Its kind, one of :data:`MIMO_KINDS`.
    settings : MimoSettings
        The settings it was fitted with.
    holdout : dict
        Per candidate of ``kind="auto"``: the held-out protocol RMSE per set.
    seconds : float
        Time taken.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.models.mimo import MimoModel
    >>> from piezohyst.identify.mimo import MimoRecords, MimoSettings, identify_mimo
    >>> true = MimoModel.linear(A=[[0.9, 0.0], [0.0, 0.5]], B=[[1.0], [1.0]], C=[[0.1, 0.2]], D=[[0.0]], fs=1000.0)
    >>> spec = np.zeros((4, 65), complex)
    >>> spec[:, 1:64] = np.exp(2j * np.pi * np.random.default_rng(0).random((4, 63)))
    >>> u = np.fft.irfft(spec, 128, axis=1)[:, :, None]  # 4 random-phase multisines (R, N, nu)
    >>> y = true.simulate(u)  # in periodic steady state (R, N, ny)
    >>> u4, y4 = (np.stack([np.moveaxis(a, 0, 2)] * 2, axis=3) for a in (u, y))  # (N, ch, R, P=2)
    >>> recs = MimoRecords.from_sets([("1V", u4, y4)], fs=1000.0)
    >>> res = identify_mimo(recs, "mimo-linear", settings=MimoSettings(order=2))
    >>> res.kind, res.model.nx, res.holdout
    ('mimo-linear', 2, {})
    """

    model: MimoModel
    kind: str
    settings: MimoSettings
    holdout: dict[str, dict[str, float]] = field(default_factory=dict)
    seconds: float = 0.0

    def report(self) -> dict[str, Any]:
        """The JSON report (also stored under the model file's ``fit``).

        Returns
        -------
        dict
            ``kind``, ``order``, ``thresholds``, ``iterations``, ``states``,
            ``feedback_channels``, ``holdout_rmse``, ``seconds``.

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst.models.mimo import MimoModel
        >>> from piezohyst.identify.mimo import MimoRecords, MimoSettings, identify_mimo
        >>> true = MimoModel.linear(A=[[0.9, 0.0], [0.0, 0.5]], B=[[1.0], [1.0]], C=[[0.1, 0.2]], D=[[0.0]], fs=1000.0)
        >>> spec = np.zeros((4, 65), complex)
        >>> spec[:, 1:64] = np.exp(2j * np.pi * np.random.default_rng(0).random((4, 63)))
        >>> u = np.fft.irfft(spec, 128, axis=1)[:, :, None]  # 4 random-phase multisines (R, N, nu)
        >>> y = true.simulate(u)  # in periodic steady state (R, N, ny)
        >>> u4, y4 = (np.stack([np.moveaxis(a, 0, 2)] * 2, axis=3) for a in (u, y))  # (N, ch, R, P=2)
        >>> recs = MimoRecords.from_sets([("1V", u4, y4)], fs=1000.0)
        >>> res = identify_mimo(recs, "mimo-linear", settings=MimoSettings(order=2))
        >>> r = res.report()
        >>> r["kind"], r["order"], r["states"], r["feedback_channels"], res.model.fit["states"]
        ('mimo-linear', 2, 2, 0, 2)
        """
        return {
            "kind": self.kind,
            "order": self.settings.order,
            "thresholds": list(self.settings.thresholds),
            "iterations": self.settings.iterations,
            "states": self.model.nx,
            "feedback_channels": self.model.nw,
            "holdout_rmse": self.holdout,
            "seconds": round(self.seconds, 2),
            **({"output_error": self.model.fit["output_error"]} if "output_error" in self.model.fit else {}),
        }


def _fit_kind(
    rec: MimoRecords,
    kind: str,
    settings: MimoSettings,
    log: Callable[[str], None] | None = None,
    deadline: float = np.inf,
) -> MimoModel:
    u = rec.u.mean(axis=3)
    y = rec.y.mean(axis=3)
    yscale = 1.0 / float(np.sqrt((y**2).mean()))
    ys = y * yscale
    rw = (ys**2).mean(axis=(0, 1)) ** (-settings.balance) if settings.balance else None
    bla = estimate_bla(rec.u, rec.y * yscale, rec.fs)
    a, _, _, _ = subspace(bla.G, bla.freqs / rec.fs, settings.order)
    real, cplx = _split_poles(a)
    structure: Structure = {"mimo-linear": "linear", "mimo-hammerstein": "hammerstein", "mimo-lfr": "lfr"}[kind]  # type: ignore[assignment]
    if structure == "linear":
        if settings.relocations:
            real, cplx = relocate_poles(u, ys, real, cplx, iterations=settings.relocations, record_weights=rw)
        f = fit_residues(u, ys, real, cplx, record_weights=rw)
        aa, b, _, c, d = realize(f)
        return MimoModel.linear(aa, b, c / yscale, d / yscale, rec.fs, fit={})
    rel = np.asarray(settings.thresholds, dtype=np.float64)
    src = u if structure == "hammerstein" else ys
    rms = np.sqrt((src**2).mean(axis=(0, 2)))
    th = rms[:, None] * rel[None, :]  # (m, nr)
    m, nr = th.shape
    z = src
    model: MimoModel | None = None
    both = structure == "lfr" and settings.input_plays  # plays of the inputs too (a Hammerstein part)
    th_u = np.sqrt((u**2).mean(axis=(0, 2)))[:, None] * rel[None, :]
    w_u = play_features(u, th_u) if both else None
    # static channels (LFR only): r tanh(z / r) of each output at each scale, channel-major
    scales = np.asarray(settings.static_scales if structure == "lfr" else (), dtype=np.float64)
    th_s = rms[:, None] * scales[None, :]  # (m, scales)
    ns, per = th_s.size, scales.size
    for it in range(settings.iterations + 1 if structure == "lfr" else 1):
        w = play_features(z, th)
        if w_u is not None:
            w = np.concatenate([w, w_u], axis=1)
        if ns:
            ths = th_s.reshape(1, ns, 1)
            w = np.concatenate([w, ths * np.tanh(np.repeat(z, per, axis=1) / ths)], axis=1)
        if it == 0 and settings.relocations:
            real, cplx = relocate_poles(u, ys, real, cplx, w, iterations=settings.relocations, record_weights=rw)
        if it > 0 and settings.oe_relocations:
            real, cplx = relocate_poles(u, ys, real, cplx, w, iterations=settings.oe_relocations, record_weights=rw)
        f = fit_residues(u, ys, real, cplx, w, record_weights=rw)
        aa, b, e, c, d = realize(f)
        nw = m * nr
        thr = th.reshape(nw, 1)
        if structure == "lfr":
            g = np.repeat(c, nr, axis=0)
            h = np.repeat(d, nr, axis=0)
        else:
            g = np.zeros((nw, aa.shape[0]))
            h = np.repeat(np.eye(m), nr, axis=0)
        if both:
            nwu = rec.nu * nr
            g = np.vstack([g, np.zeros((nwu, aa.shape[0]))])
            h = np.vstack([h, np.repeat(np.eye(rec.nu), nr, axis=0)])
            thr = np.vstack([thr, th_u.reshape(nwu, 1)])
            nw += nwu
        if ns:
            g = np.vstack([g, np.repeat(c, per, axis=0)])
            h = np.vstack([h, np.repeat(d, per, axis=0)])
            thr = np.vstack([thr, th_s.reshape(ns, 1)])
            nw += ns
        model = MimoModel(
            aa, b, c / yscale, d / yscale, e, np.zeros((c.shape[0], nw)), g, h,
            thr, np.ones((nw, 1)), rec.fs, structure, static_channels=ns,
        )  # fmt: skip
        if log is not None:
            log(f"{kind}: iteration {it}, {aa.shape[0]} states")
        if structure == "lfr" and it < settings.iterations:
            st = model.periodic_state(np.moveaxis(u, 2, 0))
            _, zs, _ = model.run(np.ascontiguousarray(np.moveaxis(u, 2, 0)), st)
            # the simulated outputs: the first channel of each output's group (plays, else static)
            first = slice(0, m * nr, nr) if nr else slice(nw - ns, nw, max(per, 1))
            z = np.ascontiguousarray(np.moveaxis(zs[:, :, first], 0, 2))
    assert model is not None
    if settings.oe_iterations > 0:
        model = _refine(rec, model, settings, log, deadline)
    return model


#: How far above its best score the held-back error of the watched refinement may end (the
#: lower of its last two stable checks, relative) for the held-back realizations to join the
#: fit (``_refine``): a plateau's scores differ by less (FSM records: 0.1 %), an overfit's
#: rise by more (from the true model of a test system: 14 times the best)
_JOIN_TOLERANCE = 0.01


def sliding_radius(model: MimoModel, margin: float | None) -> float | None:
    """The pole radius the output-error refinement keeps the sliding loop of an LFR inside
    (:func:`~piezohyst.identify.mimo_oe.sliding_poles`): the radius of ``model``'s slowest
    linear pole to the power ``margin``: those poles decay at least ``margin`` times as fast
    as the slowest pole of the linear part. ``MimoSettings.oe_sliding_margin``.

    Parameters
    ----------
    model : MimoModel
        The refinement's start (the frequency-domain fit).
    margin : float or None
        The share, in (0, 1]; ``None``: no bound.

    Returns
    -------
    float or None
        The radius; ``None`` without a margin or for a model that is not an LFR.

    Examples
    --------
    >>> from piezohyst.models.mimo import MimoModel
    >>> from piezohyst.identify.mimo import sliding_radius
    >>> m = MimoModel([[0.81]], [[1.0]], [[1.0]], [[0.0]], E=[[0.1]], F=[[0.0]], G=[[1.0]], H=[[0.0]],
    ...               thresholds=[[0.2]], weights=[[1.0]], fs=100.0, structure="lfr")
    >>> round(sliding_radius(m, 0.5), 6)
    0.9
    """
    if margin is None or model.structure != "lfr" or not model.nw:
        return None
    return float(np.abs(np.linalg.eigvals(model.A)).max() ** margin)


def _refine(
    rec: MimoRecords,
    model: MimoModel,
    settings: MimoSettings,
    log: Callable[[str], None] | None,
    deadline: float = np.inf,
) -> MimoModel:
    """The output-error refinement, within ``settings.oe_seconds`` and ``deadline``
    (``time.perf_counter()``), whichever is first, in two phases:

    1. *watched*: fitted on all but the last realization of each set and early-stopped on
       those, for the share ``settings.oe_watch`` of the time and iterations. If the held-back
       error rose (the lower of the last two stable checks' scores more than
       ``_JOIN_TOLERANCE`` above the best: overfitting), the phase's best model is the result.
    2. *all records*: otherwise the held-back error was still falling or had levelled off
       (the share ran out, the patience stopped a plateau, or the phase stopped as unstable):
       that is the budget or the data binding, not overfitting, and one more realization per
       set is worth more than a watch that has not fired: the held-back realizations join the
       fit, which goes on from the watched phase's best model, without early stopping, for
       the rest (with the same probes, restarts and final screen). A phase stopped as
       unstable says that the fit on those realizations kept reaching models that diverge or
       oscillate on new inputs, not that the held-back error rose: FSM records, all six
       realizations, the last held back (the acceptance run of ``identify --model auto``),
       the watched phase stopped as unstable at 900 iterations (four alarms; its best, 840,
       scored 0.7096, the check after it 0.7097) with 255 s of the 540-s budget left, and
       under the former rule the held-back realizations did not join. FSM records,
       realization 1 held out of the six, the others fitted (at 1.6 times the speed the
       budget was set on): the watch stopped a plateau by patience at 720 iterations (best
       620, the held-back score 0.7149 against 0.7143) and, no realization joining, scored
       0.0630 / 0.1197 / 0.1751 µm on the held-out one; on the slower machine the budget had
       ended the watch near the same point, the held-back realizations joined for 524 more
       iterations, and it scored 0.0625 / 0.1146 / 0.1654.

    Between them the weight of the initial-state correction is chosen on the held-back
    realizations (:func:`choose_init_ridge`).

    A set with one realization: no early stopping, all of it on all records."""
    t0 = time.perf_counter()
    budget = max(min(settings.oe_seconds, deadline - t0), 1.0)
    last = {lab: i for i, lab in enumerate(rec.labels)}
    hold = sorted(last.values()) if all(rec.labels.count(lab) > 1 for lab in last) else []
    fit = [i for i in range(len(rec.labels)) if i not in hold]
    common: dict[str, Any] = {
        "balance": settings.oe_balance, "free": settings.oe_free, "log": log,
        "sliding_radius": sliding_radius(model, settings.oe_sliding_margin),
    }  # fmt: skip
    summary: dict[str, Any] = {
        "validation_score": None, "best_validation_score": None, "watched_iterations": 0, "all_records_iterations": 0,
    }  # fmt: skip
    done, watching = 0, bool(hold) and settings.oe_watch > 0
    unstable = 0  # checks whose model diverged on the probes (refine_output_error)
    rejected = 0  # models the final screen of a phase refused
    join = True
    if watching:
        watch = refine_output_error(
            model, rec.select(fit), validation=rec.select(hold),
            maxiter=max(1, round(settings.oe_iterations * settings.oe_watch)),
            time_budget=max(budget * settings.oe_watch, 1.0), **common,
        )  # fmt: skip
        model, done, watched = watch.model, watch.best_iteration, watch.history[-1]["iteration"]
        unstable += sum(not h.get("stable", True) for h in watch.history)
        rejected += watch.screen_rejected
        summary.update(
            iterations=done,
            stopped=watch.stopped,
            validation_score=watch.history[-1]["validation_score"],
            # an unstable check has no score
            best_validation_score=min(
                h["validation_score"] for h in watch.history if h["validation_score"] is not None
            ),
            watched_iterations=watched,
        )
        # the watched model has not seen the held-back realizations: they choose how far the
        # model's state is corrected by measured outputs (the final model keeps that choice)
        model, ridges = choose_init_ridge(model, rec.select(hold))
        summary.update(init_ridge=model.init["ridge"], init_ridge_scores=ridges)
        # not overfitting: one of the last two stable checks within _JOIN_TOLERANCE of the best
        # score (the last one often comes a few iterations after the one before, when the
        # time ran out). The scores say so, not the model returned: the final screen may have
        # refused the best check for diverging on new inputs, which says nothing of the
        # held-back error's trend; an unstable check (a probe alarm, an excursion), or the
        # phase stopping as unstable, neither
        scores = [
            h["validation_score"] for h in watch.history if h.get("stable", True) and h["validation_score"] is not None
        ]
        join = min(scores[-2:]) <= (1 + _JOIN_TOLERANCE) * min(scores)
    left = budget - (time.perf_counter() - t0)
    if join and settings.oe_iterations - done > 0 and left > 1.0:
        if log is not None and watching:
            log("output error: the held-back error did not rise; the held-back realizations join the fit")
        res = refine_output_error(
            model, rec, maxiter=settings.oe_iterations - done, time_budget=left, **common
        )  # fmt: skip
        model = res.model
        unstable += sum(not h.get("stable", True) for h in res.history)
        rejected += res.screen_rejected
        summary.update(iterations=done + res.best_iteration, stopped=res.stopped)
        summary["all_records_iterations"] = res.best_iteration
    summary["unstable_checks"] = unstable
    summary["screen_rejected"] = rejected
    if common["sliding_radius"] is not None:
        summary["sliding_radius"] = common["sliding_radius"]
        summary["sliding_radius_reached"] = float(np.abs(sliding_poles(model)[1]).max())
    summary["seconds"] = round(time.perf_counter() - t0, 2)
    return model.with_fit({**dict(model.fit), "output_error": summary})


def _holdout(rec: MimoRecords, kind: str, settings: MimoSettings, folds: int) -> dict[str, float]:
    parts = rec.folds()
    errs: list[FloatArray] = []
    labels: list[str] = []
    for f in range(min(folds, len(parts))):
        test = parts[f]
        train = [i for i in range(len(rec.labels)) if i not in test]
        # the kinds are compared by their frequency-domain fits: the output-error step (minutes)
        # runs once, on the chosen kind, watched on its own held-back realizations
        model = _fit_kind(rec.select(train), kind, replace(settings, oe_iterations=0))
        t = rec.select(test)
        errs.append(protocol_rmse(model, t.u, t.y))
        labels += t.labels
    return set_means(np.concatenate(errs), labels)


def identify_mimo(
    records: MimoRecords,
    kind: Kind = "auto",
    *,
    settings: MimoSettings | None = None,
    candidates: Sequence[tuple[str, MimoSettings]] | None = None,
    folds: int = 1,
    time_budget: float = 540.0,
    log: Callable[[str], None] | None = None,
) -> MimoIdentification:
    """Identify a MIMO model of ``records`` (see the module docstring).

    ``kind``: one of :data:`MIMO_KINDS`, or ``"auto"``: each of ``candidates`` (default: the
    linear model and the LFR at their default settings, and with static channels) is fitted without one fold of
    realizations and scored on it by :func:`protocol_rmse` (``folds`` folds), and the best
    mean is refitted on all records. The held-out scores are in the result's ``holdout``. The
    candidates are compared by their frequency-domain fits; the output-error refinement
    (``MimoSettings.oe_iterations``, LFR and Hammerstein) runs on the chosen kind only, until
    ``MimoSettings.oe_seconds`` or the whole call's ``time_budget`` is spent: first watched
    (early-stopped on the last realization of each set, held back from the fit) for the share
    ``MimoSettings.oe_watch``, then, unless the held-back error rose (overfitting), on all
    realizations for the rest (its summary: the report's ``output_error``).

    Parameters
    ----------
    records : MimoRecords
        The training records.
    kind : {"auto", "mimo-linear", "mimo-hammerstein", "mimo-lfr"}
        The model kind, or ``"auto"`` to choose by held-out realizations.
    settings : MimoSettings, optional
        Settings of a single ``kind`` (default :class:`MimoSettings`).
    candidates : sequence of (str, MimoSettings), optional
        The kinds and settings ``"auto"`` chooses among.
    folds : int
        Held-out folds ``"auto"`` scores on.
    time_budget : float
        Seconds of the whole call: the output-error refinement gets what the steps before it
        left (at most ``MimoSettings.oe_seconds``, at least one second). The default keeps
        ``--model auto`` on the FSM records under 10 minutes with a minute to spare.
    log : callable, optional
        Called with one line of progress at a time.

    Returns
    -------
    MimoIdentification
        The model and its report.

    Examples
    --------
    A 2-state system identified from 4 short multisine realizations; ``auto`` picks the
    order that predicts the held-back realization.

    >>> import numpy as np
    >>> from piezohyst.models.mimo import MimoModel
    >>> from piezohyst.identify.mimo import MimoRecords, MimoSettings, identify_mimo
    >>> true = MimoModel.linear(A=[[0.9, 0.0], [0.0, 0.5]], B=[[1.0], [1.0]], C=[[0.1, 0.2]], D=[[0.0]], fs=1000.0)
    >>> spec = np.zeros((4, 65), complex)
    >>> spec[:, 1:64] = np.exp(2j * np.pi * np.random.default_rng(0).random((4, 63)))
    >>> u = np.fft.irfft(spec, 128, axis=1)[:, :, None]  # 4 random-phase multisines (R, N, nu)
    >>> y = true.simulate(u)  # in periodic steady state (R, N, ny)
    >>> u4, y4 = (np.stack([np.moveaxis(a, 0, 2)] * 2, axis=3) for a in (u, y))  # (N, ch, R, P=2)
    >>> recs = MimoRecords.from_sets([("1V", u4, y4)], fs=1000.0)
    >>> res = identify_mimo(recs, "mimo-linear", settings=MimoSettings(order=2))
    >>> from piezohyst.identify.mimo import protocol_rmse
    >>> np.round(np.sort(np.linalg.eigvals(res.model.A).real), 6).tolist()
    [0.5, 0.9]
    >>> bool(protocol_rmse(res.model, u4, y4, skip=10).max() < 1e-9)
    True
    >>> cands = [("mimo-linear", MimoSettings(order=1)), ("mimo-linear", MimoSettings(order=2))]
    >>> auto = identify_mimo(recs, "auto", candidates=cands)
    >>> auto.kind, auto.settings.order, len(auto.holdout)
    ('mimo-linear', 2, 2)
    """
    t0 = time.perf_counter()
    if kind != "auto" and kind not in MIMO_KINDS:
        raise ParameterError(f"kind = {kind!r} is not one of {['auto', *MIMO_KINDS]}")
    if not (isinstance(time_budget, (int, float)) and np.isfinite(time_budget) and time_budget > 0):
        raise ParameterError(f"time_budget = {time_budget!r} must be a number of seconds > 0")
    if records.u.shape[2] < records.nu:
        raise ParameterError(
            f"the records hold {records.u.shape[2]} realizations; {records.nu} inputs need at least {records.nu}"
        )
    holdout: dict[str, dict[str, float]] = {}
    if kind == "auto":
        cands = list(candidates) if candidates is not None else [
            ("mimo-linear", MimoSettings(order=40)),
            ("mimo-lfr", MimoSettings()),
            ("mimo-lfr", MimoSettings(static_scales=(0.5, 1.0, 2.0))),
        ]  # fmt: skip
        if len(records.folds()) < 2:
            raise ParameterError("--model auto needs two groups of realizations per set to hold one back")
        best = None
        for name, s in cands:
            h = _holdout(records, name, s, folds)
            static = f", static_scales={list(s.static_scales)}" if s.static_scales else ""
            key = f"{name}(order={s.order}, thresholds={list(s.thresholds) if name != 'mimo-linear' else []}{static})"
            holdout[key] = h
            mean = float(np.mean(list(h.values())))
            if log is not None:
                log(f"auto: {key} held-out RMSE {mean:.4g}")
            if best is None or mean < best[0]:
                best = (mean, name, s)
        assert best is not None
        _, chosen, st = best
    else:
        chosen, st = kind, settings or MimoSettings()
    model = _fit_kind(records, chosen, st, log, deadline=t0 + time_budget)
    res = MimoIdentification(model, chosen, st, holdout, time.perf_counter() - t0)
    return MimoIdentification(model.with_fit(res.report()), chosen, st, holdout, res.seconds)
