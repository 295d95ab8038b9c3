"""Multi-channel (MIMO) records: several actuator inputs and several sensor outputs, often
periodic multisines measured over several realizations and periods.

A :class:`MultiRecord` holds one experiment (one excitation level) in the layout of the
nonlinear system-identification benchmarks (nonlinearbenchmark.org): ``u`` of shape
``(samples, inputs, realizations, periods)`` in volts and ``y`` of shape
``(samples, outputs, realizations, periods)`` in metres, sampled at ``fs`` Hz.
:func:`load_multichannel` reads

- a folder of ``u_<name>.npy`` / ``y_<name>.npy`` pairs, one record per pair named from the
  file stem (``u_100mV_train.npy`` -> ``"100mV_train"``), e.g. ``../shared/data/fsm``;
- an NPZ archive with ``u`` and ``y`` arrays — ``(N, nu)`` / ``(N, ny)``, or the 3-D or 4-D
  layout — and optionally a scalar ``fs``;
- a single ``u_<name>.npy`` file (its ``y_<name>.npy`` beside it).

Every record of a folder has the same number of samples, inputs and outputs; every problem
— a ``u`` without its ``y``, shapes that do not match, NaN, a 1-D array, an empty folder,
records of different lengths — is an error naming the file and the shapes.

Examples
--------
>>> import tempfile, pathlib
>>> import numpy as np
>>> from piezohyst.signals import load_multichannel
>>> folder = pathlib.Path(tempfile.mkdtemp())
>>> rng = np.random.default_rng(0)
>>> for level in (0.1, 0.2):
...     u = level * rng.standard_normal((256, 3, 2, 2))        # N, inputs, realizations, periods
...     np.save(folder / f"u_{level * 1000:.0f}mV_train.npy", u)
...     np.save(folder / f"y_{level * 1000:.0f}mV_train.npy", 1e-6 * u[:, :2])  # 2 outputs
>>> recs = load_multichannel(folder, fs=6400)
>>> [r.name for r in recs], recs[0].shape
(['100mV_train', '200mV_train'], (256, 3, 2, 2, 2))
>>> u, y = recs[1].time_series(realization=1)   # periods one after the other
>>> u.shape, y.shape
((512, 3), (512, 2))
"""

from __future__ import annotations

import dataclasses
import math
import os
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from .._validate import as_int, as_scalar
from ..errors import DataError, ParameterError, ParameterTypeError
from .data import _check_size, _max_bytes, _npy_header
from .units import parse_unit

FloatArray = npt.NDArray[np.float64]

__all__ = ["MultiRecord", "is_multichannel", "load_multichannel", "read_channels"]

#: The units a multi-channel record holds its signals in.
SI_UNITS = {"input": "V", "output": "m"}

_LEVEL = re.compile(r"^(?P<number>\d+(?:\.\d*)?|\.\d+)\s*(?P<unit>[munµμk]?V)(?![A-Za-z])")
_LEVEL_SCALE = {"V": 1.0, "mV": 1e-3, "uV": 1e-6, "µV": 1e-6, "μV": 1e-6, "nV": 1e-9, "kV": 1e3}


def _as_layout(x: object, role: str, source: str) -> FloatArray:
    """``x`` as a read-only float64 4-D array (samples, channels, realizations, periods)."""
    sym = "u" if role == "input" else "y"
    if isinstance(x, (str, bytes)):
        raise ParameterTypeError(f"{source}{sym} must be an array of numbers, got {type(x).__name__}")
    try:
        raw = x if isinstance(x, np.ndarray) else np.asarray(x)
    except (TypeError, ValueError) as e:
        raise ParameterTypeError(f"{source}{sym} must be an array of numbers: {e}") from None
    if raw.dtype.kind not in "fiu":
        raise ParameterTypeError(f"{source}{sym} must hold real numbers, got dtype {raw.dtype}")
    if raw.ndim == 1:
        raise DataError(
            f"{source}{sym} has shape {raw.shape}: 1-D, one channel without a channel axis; a multi-channel "
            f"record is (samples, channels[, realizations[, periods]]) — reshape to ({raw.shape[0]}, 1), "
            "or read a single-channel record with load_record"
        )
    if raw.ndim < 1 or raw.ndim > 4:
        raise DataError(
            f"{source}{sym} has shape {raw.shape}: expected (samples, channels[, realizations[, periods]]), 2 to 4 axes"
        )
    if 0 in raw.shape:
        raise DataError(f"{source}{sym} has shape {raw.shape}: an empty axis, no data")
    if raw.shape[0] < 2:
        raise DataError(f"{source}{sym} has shape {raw.shape}: {raw.shape[0]} sample(s), at least 2 needed")
    if raw.shape[1] > raw.shape[0]:
        raise DataError(
            f"{source}{sym} has shape {raw.shape}: more channels ({raw.shape[1]}) than samples ({raw.shape[0]}), "
            "so it looks transposed; the first axis is samples, the second channels"
        )
    a = np.array(raw, dtype=np.float64, copy=True).reshape(raw.shape + (1,) * (4 - raw.ndim))
    bad = np.argwhere(~np.isfinite(a))
    if bad.size:
        k, c, r, p = (int(i) for i in bad[0])
        raise DataError(
            f"{source}{sym}[{k}, {c}, {r}, {p}] = {a[k, c, r, p]} is not finite "
            f"(sample {k}, channel {c}, realization {r}, period {p}; {bad.shape[0]} such values)"
        )
    a.flags.writeable = False
    return a


@dataclasses.dataclass(frozen=True, eq=False, repr=False)
class MultiRecord:
    """A multi-channel record: inputs ``u`` (V) and outputs ``y`` (m) sampled at ``fs`` Hz,
    over realizations and periods.

    Parameters
    ----------
    u : array_like
        Inputs, shape ``(N, nu)``, ``(N, nu, R)`` or ``(N, nu, R, P)`` — samples (of one
        period), input channels, realizations, periods; held as a read-only float64
        ``(N, nu, R, P)`` array, in volts.
    y : array_like
        Outputs, ``(N, ny[, R[, P]])`` with the same ``N``, ``R`` and ``P``, in metres.
    fs : float
        Sample rate in Hz, > 0.
    name : str
        The record's name (a folder's records are named from their file stems:
        ``u_100mV_train.npy`` -> ``"100mV_train"``).
    source : str
        Where it was read from.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.signals import MultiRecord
    >>> u = np.zeros((100, 3, 6, 2)); y = np.zeros((100, 3, 6, 2))
    >>> rec = MultiRecord(u, y, fs=6400.0, name="100mV_train")
    >>> rec.samples, rec.n_inputs, rec.n_outputs, rec.realizations, rec.periods, rec.level
    (100, 3, 3, 6, 2, 0.1)
    >>> rec.select(realizations=[3, 4, 5]).realizations
    3
    >>> MultiRecord(u, y[:50], fs=6400.0)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    piezohyst.errors.DataError: y has shape (50, 3, 6, 2), u has shape (100, 3, 6, 2): ...
    """

    u: FloatArray
    y: FloatArray
    fs: float
    name: str = ""
    source: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str):
            raise ParameterTypeError(f"name must be a str, got {type(self.name).__name__}")
        if not isinstance(self.source, str):
            raise ParameterTypeError(f"source must be a str, got {type(self.source).__name__}")
        where = f"{self.source}: " if self.source else ""
        u = _as_layout(self.u, "input", where)
        y = _as_layout(self.y, "output", where)
        if (y.shape[0], y.shape[2], y.shape[3]) != (u.shape[0], u.shape[2], u.shape[3]):
            raise DataError(
                f"{where}y has shape {y.shape}, u has shape {u.shape}: samples, realizations and periods "
                "(axes 0, 2, 3) must match"
            )
        object.__setattr__(self, "u", u)
        object.__setattr__(self, "y", y)
        object.__setattr__(self, "fs", as_scalar(self.fs, "fs", positive=True))

    @property
    def samples(self) -> int:
        """Samples of one period, ``N``."""
        return int(self.u.shape[0])

    @property
    def n_inputs(self) -> int:
        """Input channels (actuators), ``nu``."""
        return int(self.u.shape[1])

    @property
    def n_outputs(self) -> int:
        """Output channels (sensors), ``ny``."""
        return int(self.y.shape[1])

    @property
    def realizations(self) -> int:
        """Realizations (independent excitations), ``R``."""
        return int(self.u.shape[2])

    @property
    def periods(self) -> int:
        """Periods of each realization, ``P``."""
        return int(self.u.shape[3])

    @property
    def shape(self) -> tuple[int, int, int, int, int]:
        """``(N, nu, ny, R, P)``."""
        return (self.samples, self.n_inputs, self.n_outputs, self.realizations, self.periods)

    @property
    def units(self) -> dict[str, str]:
        """The units the signals are held in: ``{"input": "V", "output": "m"}``."""
        return dict(SI_UNITS)

    @property
    def level(self) -> float | None:
        """The excitation level the name states, in V (``"100mV_train"`` -> 0.1), else ``None``."""
        m = _LEVEL.match(self.name)
        if m is None:
            return None
        return float(m.group("number")) * _LEVEL_SCALE[m.group("unit")]

    @property
    def input_rms(self) -> FloatArray:
        """RMS of each input channel over every sample, realization and period, V."""
        return np.asarray(np.sqrt(np.mean(self.u**2, axis=(0, 2, 3))), dtype=np.float64)

    def __repr__(self) -> str:
        n, nu, ny, r, p = self.shape
        return (
            f"MultiRecord(name={self.name!r}, samples={n}, inputs={nu}, outputs={ny}, realizations={r}, "
            f"periods={p}, fs={self.fs:g} Hz, source={self.source!r})"
        )

    def select(self, realizations: Sequence[int] | None = None, periods: Sequence[int] | None = None) -> MultiRecord:
        """The record restricted to some realizations and/or periods (0-based indices).

        Parameters
        ----------
        realizations : sequence of int, optional
            Realizations kept, in that order (default all).
        periods : sequence of int, optional
            Periods kept (default all).

        Returns
        -------
        MultiRecord

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst.signals import MultiRecord
        >>> rec = MultiRecord(np.ones((10, 2, 6, 2)), np.ones((10, 2, 6, 2)), fs=1e3)
        >>> rec.select(realizations=[0, 1, 2], periods=[1]).shape
        (10, 2, 2, 3, 1)
        """
        r = self._indices(realizations, "realizations", self.realizations)
        p = self._indices(periods, "periods", self.periods)
        tag = f"[r={list(r)}, p={list(p)}]"
        return MultiRecord(
            self.u[:, :, r][:, :, :, p], self.y[:, :, r][:, :, :, p], self.fs, self.name, self.source + tag
        )

    @staticmethod
    def _indices(idx: Sequence[int] | None, name: str, count: int) -> list[int]:
        if idx is None:
            return list(range(count))
        if isinstance(idx, (str, bytes)) or not isinstance(idx, Sequence):
            raise ParameterTypeError(f"{name} must be a sequence of 0-based indices, got {idx!r}")
        out = [as_int(i, name, minimum=0, maximum=count - 1) for i in idx]
        if not out:
            raise ParameterError(f"{name} = {list(idx)!r} keeps nothing; give at least one index")
        return out

    def time_series(self, realization: int = 0) -> tuple[FloatArray, FloatArray]:
        """One realization as time series, its periods one after the other.

        Parameters
        ----------
        realization : int
            0-based realization.

        Returns
        -------
        u : ndarray, shape (N * P, nu)
        y : ndarray, shape (N * P, ny)

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst.signals import MultiRecord
        >>> u = np.arange(8.0).reshape(2, 1, 1, 4)   # 2 samples, 4 periods
        >>> MultiRecord(u, u, fs=1.0).time_series()[0].ravel().tolist()
        [0.0, 4.0, 1.0, 5.0, 2.0, 6.0, 3.0, 7.0]
        """
        r = as_int(realization, "realization", minimum=0, maximum=self.realizations - 1)
        u = np.ascontiguousarray(self.u[:, :, r, :].transpose(2, 0, 1).reshape(-1, self.n_inputs))
        y = np.ascontiguousarray(self.y[:, :, r, :].transpose(2, 0, 1).reshape(-1, self.n_outputs))
        return u, y


# --------------------------------------------------------------------------------------
# Readers


def _read_npy(path: Path, limit: int) -> Any:
    """A ``.npy`` array, its header's size checked against ``limit`` and the file first."""
    try:
        with open(path, "rb") as fp:
            shape, dtype = _npy_header(fp)
            have = os.fstat(fp.fileno()).st_size - fp.tell()
    except Exception as e:
        raise DataError(f"{path}: not a readable .npy array ({type(e).__name__}: {e})") from None
    if dtype.kind not in "fiu":
        raise ParameterTypeError(f"{path}: the array must hold real numbers, got dtype {dtype}")
    need = math.prod(shape) * dtype.itemsize
    _check_size(str(path), f"the array of shape {shape} ({dtype})", need, limit)
    if need > have:
        raise DataError(
            f"{path}: the array of shape {shape} ({dtype}) needs {need:,} bytes, the file holds {have:,}: "
            "truncated or damaged"
        )
    try:
        return np.load(path, allow_pickle=False)
    except Exception as e:
        raise DataError(f"{path}: not a readable .npy array ({type(e).__name__}: {e})") from None


def _read_npz(path: Path, limit: int) -> dict[str, Any]:
    """``u``, ``y`` (and ``fs`` if present) of an NPZ archive, sizes checked before reading."""
    try:
        fh = open(path, "rb")
    except OSError as e:
        raise DataError(f"{path}: cannot be opened ({e})") from None
    try:
        z = np.load(fh, allow_pickle=False)
        if isinstance(z, np.ndarray):
            raise DataError(f"{path}: it holds a single array (.npy format), not an archive with u and y")
        headers: dict[str, tuple[tuple[int, ...], np.dtype[Any]]] = {}
        for member in z.zip.namelist():
            key = member[:-4] if member.endswith(".npy") else member
            if key in ("u", "y", "fs") and key in z.files:
                with z.zip.open(member) as fp:
                    headers[key] = _npy_header(fp)
        missing = [k for k in ("u", "y") if k not in headers]
        if missing:
            raise DataError(
                f"{path}: no {' and no '.join(repr(k) for k in missing)} array; a multi-channel NPZ holds "
                f"u (N, nu) and y (N, ny); it holds {sorted(z.files)}"
            )
        out: dict[str, Any] = {}
        for key, (shape, dtype) in headers.items():
            if dtype.kind not in "fiu":
                raise ParameterTypeError(f"{path}: {key} must hold real numbers, got dtype {dtype}")
            _check_size(str(path), f"NPZ member {key!r} of shape {shape} ({dtype})", math.prod(shape) * 8, limit)
            out[key] = np.asarray(z[key])
        z.close()
        return out
    except (DataError, ParameterTypeError):
        raise
    except Exception as e:  # a corrupt archive raises from zipfile, zlib, numpy.lib.format ...
        raise DataError(f"{path}: not a readable NPZ archive ({type(e).__name__}: {e})") from None
    finally:
        fh.close()


def _pairs(folder: Path) -> list[tuple[str, Path, Path]]:
    """The ``u_<name>.npy`` / ``y_<name>.npy`` pairs of a folder, by name."""
    files = {p.name: p for p in folder.iterdir() if p.is_file()}
    us = {n[2:-4]: p for n, p in files.items() if n.startswith("u_") and n.lower().endswith(".npy")}
    ys = {n[2:-4]: p for n, p in files.items() if n.startswith("y_") and n.lower().endswith(".npy")}
    if not us and not ys:
        listing = sorted(files)[:12]
        raise DataError(
            f"{folder}: no u_<name>.npy / y_<name>.npy pairs in this folder (multi-channel data); "
            f"it holds {listing if listing else 'no files'}"
        )
    alone_u = sorted(set(us) - set(ys))
    if alone_u:
        raise DataError(f"{folder}: {us[alone_u[0]].name} has no output file y_{alone_u[0]}.npy beside it")
    alone_y = sorted(set(ys) - set(us))
    if alone_y:
        raise DataError(f"{folder}: {ys[alone_y[0]].name} has no input file u_{alone_y[0]}.npy beside it")
    return [(name, us[name], ys[name]) for name in sorted(us)]


def _sort_key(rec: MultiRecord) -> tuple[float, str]:
    lv = rec.level
    return (math.inf if lv is None else lv, rec.name)


def _convert(a: Any, unit: str | None, role: str) -> Any:
    if unit is None:
        return a
    c = parse_unit(unit, role)
    if c.si != SI_UNITS[role]:
        raise ParameterError(f"{role}_unit = {unit!r} is a unit of {c.si!r}, the {role} is in {SI_UNITS[role]}")
    return np.asarray(a, dtype=np.float64) * c.scale


def load_multichannel(
    path: str | os.PathLike[str],
    *,
    fs: float | None = None,
    input_unit: str | None = None,
    output_unit: str | None = None,
    max_bytes: int | None = None,
) -> tuple[MultiRecord, ...]:
    """Read multi-channel records: a folder of ``u_*.npy`` / ``y_*.npy`` pairs, an NPZ with
    ``u`` and ``y``, or one ``u_<name>.npy`` (its ``y_<name>.npy`` beside it).

    Parameters
    ----------
    path : str or os.PathLike
        The folder or file.
    fs : float, optional
        Sample rate in Hz. Required unless an NPZ holds a scalar ``fs`` (with both they must
        agree to 1e-9 relative).
    input_unit, output_unit : str, optional
        The unit the files hold the inputs / outputs in (``"mV"``; ``"um"``, ``"nm"``);
        default V and m. Values are converted to V and m.
    max_bytes : int, optional
        The bound on one array's size, checked before it is read; default the environment
        variable ``PIEZOHYST_MAX_ARRAY_BYTES``, else 1 GiB.

    Returns
    -------
    tuple of MultiRecord
        One per ``u``/``y`` pair (one for an NPZ), by the level their names state
        (``100mV_train`` before ``200mV_train``), then by name. Every record has the same
        samples, inputs and outputs.

    Raises
    ------
    FileNotFoundError
        No such file or folder.
    DataError, ParameterError, ParameterTypeError
        An empty folder, a ``u`` without its ``y`` (or the reverse), shapes that do not match,
        a 1-D or transposed array, NaN/Inf (index named), records of different lengths or
        channel counts, ``fs`` missing or disagreeing, a corrupt or oversized file.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> import numpy as np
    >>> from piezohyst.signals import load_multichannel
    >>> f = pathlib.Path(tempfile.mkdtemp()) / "run.npz"
    >>> np.savez(f, u=np.ones((500, 3)), y=np.zeros((500, 3)), fs=1000.0)
    >>> (rec,) = load_multichannel(f)
    >>> rec.name, rec.shape, rec.fs
    ('run', (500, 3, 3, 1, 1), 1000.0)
    >>> np.savez(f, u=np.ones((500, 3)), y=np.zeros((400, 3)))
    >>> load_multichannel(f, fs=1000)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    piezohyst.errors.DataError: ...run.npz: y has shape (400, 3, 1, 1), u has shape (500, 3, 1, 1): ...
    """
    if isinstance(path, bytes) or not isinstance(path, (str, os.PathLike)):
        raise ParameterTypeError(f"path must be a str or os.PathLike, got {type(path).__name__}")
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such file or folder")
    fs_given = None if fs is None else as_scalar(fs, "fs", positive=True)
    limit = _max_bytes(max_bytes)
    found: list[tuple[str, str, str, Any, Any, float | None]] = []  # name, u file, y file, u, y, fs stored
    if p.is_dir():
        for name, pu, py in _pairs(p):
            found.append((name, str(pu), str(py), _read_npy(pu, limit), _read_npy(py, limit), None))
    elif p.suffix.lower() == ".npz":
        arrays = _read_npz(p, limit)
        stored = None
        if "fs" in arrays:
            f = np.asarray(arrays["fs"])
            if f.size != 1:
                raise DataError(f"{p}: fs has shape {f.shape}; it must be a scalar, the sample rate in Hz")
            stored = as_scalar(float(f.ravel()[0]), f"{p}: fs", positive=True)
        found.append((p.stem, str(p), str(p), arrays["u"], arrays["y"], stored))
    elif p.suffix.lower() == ".npy":
        stem = p.name[:-4]
        if not (stem.startswith("u_") or stem.startswith("y_")):
            raise DataError(
                f"{p}: a multi-channel .npy file is named u_<name>.npy with y_<name>.npy beside it "
                "(or give the folder, or an NPZ with u and y)"
            )
        name = stem[2:]
        pu, py = p.with_name(f"u_{name}.npy"), p.with_name(f"y_{name}.npy")
        for q, role in ((pu, "input"), (py, "output")):
            if not q.is_file():
                raise DataError(f"{p}: its {role} file {q.name} is not beside it")
        found.append((name, str(pu), str(py), _read_npy(pu, limit), _read_npy(py, limit), None))
    else:
        raise DataError(
            f"{p}: multi-channel data is a folder of u_*.npy / y_*.npy pairs or an NPZ with u and y, "
            f"not a {p.suffix or 'extension-less'} file"
        )
    records: list[MultiRecord] = []
    for name, source, ysource, u, y, stored in found:
        if stored is not None and fs_given is not None and abs(stored - fs_given) > 1e-9 * fs_given:
            raise DataError(f"{source}: the file's fs = {stored:g} Hz disagrees with fs = {fs_given:g} Hz given")
        rate = fs_given if fs_given is not None else stored
        if rate is None:
            raise DataError(f"{source}: the sample rate is unknown: pass fs=<Hz> (the CLI's --fs)")
        u = _convert(_as_layout(u, "input", f"{source}: "), input_unit, "input")
        y = _convert(_as_layout(y, "output", f"{ysource}: "), output_unit, "output")
        records.append(MultiRecord(u, y, rate, name, source))
    first = records[0]
    for rec in records[1:]:
        for what, a, b in (
            ("samples", rec.samples, first.samples),
            ("inputs", rec.n_inputs, first.n_inputs),
            ("outputs", rec.n_outputs, first.n_outputs),
        ):
            if a != b:
                raise DataError(
                    f"{p}: records of mixed shapes: {rec.name!r} has {a} {what} (u {rec.u.shape}, y {rec.y.shape}), "
                    f"{first.name!r} has {b} (u {first.u.shape}, y {first.y.shape})"
                )
    return tuple(sorted(records, key=_sort_key))


def is_multichannel(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` is multi-channel data for :func:`load_multichannel`: a folder holding
    ``u_*.npy`` or ``y_*.npy`` files, a ``u_/y_*.npy`` file, or an NPZ whose ``u`` array has
    two or more axes (read from its header only). A single-channel NPZ (1-D ``u``) is not.

    Parameters
    ----------
    path : str or os.PathLike
        A folder or file (need not exist: then ``False``).

    Returns
    -------
    bool

    Examples
    --------
    >>> import tempfile, pathlib
    >>> import numpy as np
    >>> from piezohyst.signals import is_multichannel
    >>> f = pathlib.Path(tempfile.mkdtemp()) / "a.npz"
    >>> np.savez(f, u=np.ones((50, 3)), y=np.ones((50, 3)))
    >>> is_multichannel(f), is_multichannel(f.parent), is_multichannel(f.parent / "b.npz")
    (True, False, False)
    """
    if isinstance(path, bytes) or not isinstance(path, (str, os.PathLike)):
        return False
    p = Path(path)
    try:
        if p.is_dir():
            return any(
                q.name[:2] in ("u_", "y_") and q.name.lower().endswith(".npy") and q.is_file() for q in p.iterdir()
            )
        if not p.is_file():
            return False
        if p.suffix.lower() == ".npy":
            return p.name[:2] in ("u_", "y_")
        if p.suffix.lower() != ".npz":
            return False
        with np.load(p, allow_pickle=False) as z:
            if isinstance(z, np.ndarray) or "u" not in z.files or "y" not in z.files:
                return False
            with z.zip.open("u.npy") as fp:
                shape, _ = _npy_header(fp)
        return len(shape) >= 2
    except Exception:  # unreadable: not ours to judge here; the reader that takes it says why
        return False


def read_channels(
    path: str | os.PathLike[str],
    name: str = "array",
    *,
    key: str | None = None,
    channels: int | None = None,
    max_bytes: int | None = None,
) -> FloatArray:
    """A matrix of signals, shape ``(samples, channels)``, from a ``.npy`` file, an NPZ archive
    (the array ``key``, by default its only array) or delimited text (one column per channel,
    header optional). A 1-D array is one channel.

    Parameters
    ----------
    path : str or os.PathLike
        The file (``.npy``, ``.npz``, ``.csv .tsv .txt .dat .asc``).
    name : str
        What the matrix is, for messages (``"U"``, ``"Y0"``).
    key : str, optional
        NPZ: the array to read; default the archive's only array.
    channels : int, optional
        The number of columns required (e.g. the model's inputs); a 1-D array is one channel.
    max_bytes : int, optional
        The bound on the array's size, checked before reading (default as :func:`load_multichannel`).

    Returns
    -------
    ndarray, shape (samples, channels)
        Finite float64.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> import numpy as np
    >>> from piezohyst.signals import read_channels
    >>> f = pathlib.Path(tempfile.mkdtemp()) / "u.csv"
    >>> _ = f.write_text("u0,u1,u2\\n0.1,0.2,0.3\\n0.4,0.5,0.6\\n")
    >>> read_channels(f, "U", channels=3).tolist()
    [[0.1, 0.2, 0.3], [0.4, 0.5, 0.6]]
    >>> read_channels(f, "U", channels=4)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    piezohyst.errors.DataError: ...u.csv: U has shape (2, 3): 3 channels, expected 4
    """
    if isinstance(path, bytes) or not isinstance(path, (str, os.PathLike)):
        raise ParameterTypeError(f"{name} must be a path (str or os.PathLike), got {type(path).__name__}")
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"{name} = '{p}': no such file")
    limit = _max_bytes(max_bytes)
    suffix = p.suffix.lower()
    a: Any
    if suffix == ".npy":
        a = _read_npy(p, limit)
    elif suffix == ".npz":
        a = _read_npz_member(p, key, name, limit)
    elif suffix in (".csv", ".tsv", ".txt", ".dat", ".asc"):
        from .textio import TextTable

        table = TextTable(p, None, "auto")
        try:
            cols = table.columns()
            a = np.column_stack([table.read(name, k, label) for k, label in cols])
        finally:
            table.close()
    else:
        raise DataError(f"{p}: {name} must be a .npy, .npz or delimited text file, not {p.suffix or 'extension-less'}")
    a = np.asarray(a)
    if a.dtype.kind not in "fiu":
        raise ParameterTypeError(f"{p}: {name} must hold real numbers, got dtype {a.dtype}")
    if a.ndim == 1:
        a = a.reshape(-1, 1)
    if a.ndim != 2:
        raise DataError(f"{p}: {name} has shape {a.shape}: expected (samples, channels)")
    if a.shape[0] < 1 or a.shape[1] < 1:
        raise DataError(f"{p}: {name} has shape {a.shape}: no data")
    if channels is not None and a.shape[1] != channels:
        hint = " (transposed? rows are samples, columns channels)" if a.shape[0] == channels else ""
        raise DataError(f"{p}: {name} has shape {a.shape}: {a.shape[1]} channels, expected {channels}{hint}")
    out = np.ascontiguousarray(a, dtype=np.float64)
    bad = np.argwhere(~np.isfinite(out))
    if bad.size:
        i, j = (int(k) for k in bad[0])
        raise DataError(f"{p}: {name}[{i}, {j}] = {out[i, j]} is not finite (sample {i}, channel {j})")
    return out


def _read_npz_member(path: Path, key: str | None, name: str, limit: int) -> Any:
    try:
        fh = open(path, "rb")
    except OSError as e:
        raise DataError(f"{path}: cannot be opened ({e})") from None
    try:
        z = np.load(fh, allow_pickle=False)
        if isinstance(z, np.ndarray):
            raise DataError(f"{path}: a single array in .npy format with an .npz name; rename it .npy")
        files = list(z.files)
        if key is None:
            if len(files) != 1:
                raise DataError(f"{path}: {name}: the archive holds {sorted(files)}; name the array to read")
            key = files[0]
        if key not in files:
            raise DataError(f"{path}: {name}: no array {key!r}; the archive holds {sorted(files)}")
        with z.zip.open(f"{key}.npy") as fp:
            shape, dtype = _npy_header(fp)
        _check_size(str(path), f"NPZ member {key!r} of shape {shape} ({dtype})", math.prod(shape) * 8, limit)
        out = np.asarray(z[key])
        z.close()
        return out
    except (DataError, ParameterTypeError):
        raise
    except Exception as e:
        raise DataError(f"{path}: not a readable NPZ archive ({type(e).__name__}: {e})") from None
    finally:
        fh.close()
