"""Measured records: input/output signals with a sample rate, loaded from files.

A :class:`Record` holds one measured experiment — the actuator input (voltage, force, ...)
and the measured output (displacement, sensor reading, ...) sampled at ``fs`` Hz — and
knows how to trim itself and split into training and validation parts by sample ranges.
:func:`load_record` reads one from

- delimited text (``.csv``, ``.tsv``, ``.txt``, ``.dat``, ``.asc``): comma, tab, semicolon
  or whitespace separated, with or without a header line; columns by name or by 0-based
  index;
- NumPy ``.npz`` archives (arrays by key) and ``.npy`` matrices (columns by index);
- MATLAB ``.mat`` files, v4/v5/v7 (through :func:`scipy.io.loadmat`) and v7.3 (HDF5 based,
  through h5py when it is installed); variables by name, struct fields as ``"s.field"``;
- HDF5 files (``.h5``, ``.hdf5``, ``.he5``) through h5py when it is installed; datasets
  by path (``"run1/voltage"``).

The sample rate comes from a time column (strictly increasing and uniform; a non-uniform
time axis is an error, never a silent resample) or is given as ``fs``. Every problem —
missing file, unknown column, bad cell, NaN, short record, non-uniform time — is an error
that names the file, the argument and the value (docs/spec.md §10).

Examples
--------
>>> import tempfile, pathlib
>>> from piezohyst.data import load_record
>>> folder = pathlib.Path(tempfile.mkdtemp())
>>> text = "t,v,x\\n0.000,0.0,0.00\\n0.005,1.0,0.40\\n0.010,2.0,1.10\\n0.015,1.0,0.90\\n"
>>> _ = (folder / "run.csv").write_text(text)
>>> rec = load_record(folder / "run.csv", input="v", output="x", time="t")
>>> rec.n, rec.fs, rec.columns
(4, 200.0, {'input': 'v', 'output': 'x', 'time': 't'})
>>> rec.trim(1, 3).input
array([1., 2.])
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import os
import re
import warnings
from collections.abc import Callable, Hashable, Iterator, Mapping, Sequence
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING, Any, Protocol, TypeVar

import numpy as np
import numpy.typing as npt

from .._validate import as_int, as_record, as_scalar
from ..errors import DataError, ParameterError, ParameterTypeError
from .textio import PYARROW_HINT
from .textio import TextTable as TextTable
from .units import UnitConversion, conversion_for, parse_unit, split_annotation

if TYPE_CHECKING:  # pragma: no cover - typing only
    import pandas as pd

FloatArray = npt.NDArray[np.float64]
#: A column of a source: a name (str), a 0-based index (int), or not given.
ColumnSpec = str | int | None

__all__ = [
    "MAX_ARRAY_BYTES_ENV",
    "PYARROW_HINT",
    "TIME_RTOL",
    "Record",
    "UnitConversion",
    "load_record",
    "load_yan9a_model_record",
]

#: Default relative tolerance on the time steps of a time column (of the median step).
TIME_RTOL = 1e-6

TEXT_SUFFIXES = (".csv", ".tsv", ".txt", ".dat", ".asc")
NPZ_SUFFIXES = (".npz",)
NPY_SUFFIXES = (".npy",)
MAT_SUFFIXES = (".mat",)
HDF5_SUFFIXES = (".h5", ".hdf5", ".he5")
PARQUET_SUFFIXES = (".parquet", ".pq")
SUPPORTED_SUFFIXES = TEXT_SUFFIXES + NPZ_SUFFIXES + NPY_SUFFIXES + MAT_SUFFIXES + HDF5_SUFFIXES + PARQUET_SUFFIXES

#: The environment variable that raises (or lowers) the bound on the decompressed size of one
#: array read from an NPZ, MAT or HDF5 file, in bytes (also the ``max_bytes`` argument).
MAX_ARRAY_BYTES_ENV = "PIEZOHYST_MAX_ARRAY_BYTES"
#: The default bound: 1 GiB (134 million float64 samples).
MAX_ARRAY_BYTES = 1 << 30

#: A step at least this many median steps long is a gap (a missing stretch), not jitter.
GAP_STEPS = 1.5

H5PY_HINT = "reading HDF5 / MATLAB v7.3 needs h5py: pip install h5py"

_ROLES = ("input", "output", "time")


# --------------------------------------------------------------------------------------
# Record


@dataclasses.dataclass(frozen=True, eq=False, repr=False)
class Record:
    """One measured record: ``input`` and ``output`` sampled at ``fs`` Hz.

    Parameters
    ----------
    input, output : array_like
        1-D finite signals of equal length, at least 2 samples (stored as read-only
        float64 copies).
    fs : float
        Sample rate in Hz, > 0.
    time : array_like, optional
        The measured time axis in seconds (strictly increasing, same length), if the
        source had one. :func:`load_record` also checks that it is uniform and agrees
        with ``fs``.
    source : str
        Where the record came from (file path; ``[a:b]`` appended by :meth:`trim`).
    columns : dict
        The source columns used: ``{"input": ..., "output": ...[, "time": ...]}``.
    units : dict
        How each column was converted on loading, role -> :class:`UnitConversion`
        ``(source, si, scale, origin)``: e.g. ``{"time": ("ms", "s", 0.001, "header")}``; the
        arrays hold the converted (SI) values. Empty for a record built by hand.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.data import Record
    >>> rec = Record(np.arange(10.0), 2 * np.arange(10.0), fs=100.0)
    >>> rec.n, rec.duration
    (10, 0.1)
    >>> train, val = rec.split(train=(0, 6), validate=(6, 10))
    >>> train.n, val.n, float(val.input[0]), val.source
    (6, 4, 6.0, '[6:10]')
    """

    input: FloatArray
    output: FloatArray
    fs: float
    time: FloatArray | None = None
    source: str = ""
    columns: dict[str, str] = dataclasses.field(default_factory=dict)
    units: dict[str, UnitConversion] = dataclasses.field(default_factory=dict)

    def __post_init__(self) -> None:
        u = as_record(self.input, "input", min_length=2)
        y = as_record(self.output, "output", min_length=2)
        if y.size != u.size:
            raise ParameterError(f"output has {y.size} samples, input has {u.size}: lengths must match")
        fs = as_scalar(self.fs, "fs", positive=True)
        t = None
        if self.time is not None:
            t = as_record(self.time, "time", min_length=2)
            if t.size != u.size:
                raise ParameterError(f"time has {t.size} samples, input has {u.size}: lengths must match")
            _check_increasing(t, "time")
            t.flags.writeable = False
        if not isinstance(self.source, str):
            raise ParameterTypeError(f"source must be a str, got {type(self.source).__name__}")
        if not isinstance(self.columns, Mapping):
            raise ParameterTypeError(
                f"columns must be a mapping of role -> column name, got {type(self.columns).__name__}"
            )
        columns: dict[str, str] = {}
        for k, v in self.columns.items():
            if not isinstance(k, str) or not isinstance(v, str):
                raise ParameterTypeError(f"columns must map str to str, got {k!r}: {v!r}")
            columns[k] = v
        if not isinstance(self.units, Mapping):
            raise ParameterTypeError(
                f"units must be a mapping of role -> UnitConversion, got {type(self.units).__name__}"
            )
        units: dict[str, UnitConversion] = {}
        for k, c in self.units.items():
            if not isinstance(k, str) or not isinstance(c, tuple) or len(c) != 4:
                raise ParameterTypeError(f"units must map a role to a UnitConversion, got {k!r}: {c!r}")
            units[k] = UnitConversion(str(c[0]), str(c[1]), float(c[2]), str(c[3]))
        u.flags.writeable = False
        y.flags.writeable = False
        object.__setattr__(self, "input", u)
        object.__setattr__(self, "output", y)
        object.__setattr__(self, "fs", fs)
        object.__setattr__(self, "time", t)
        object.__setattr__(self, "columns", columns)
        object.__setattr__(self, "units", units)

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.input.size)

    @property
    def duration(self) -> float:
        """``n / fs`` in seconds (each sample spans one period ``1 / fs``)."""
        return self.n / self.fs

    def __len__(self) -> int:
        return self.n

    def si_units(self) -> dict[str, str]:
        """The unit of each signal as held (after conversion): ``{"input": "V", "output": "m"}``
        (``""`` where the source said nothing), the form a model's ``units`` takes.

        Returns
        -------
        dict

        Examples
        --------
        >>> import tempfile, pathlib
        >>> from piezohyst import load_record
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "run.csv"
        >>> _ = path.write_text("\\n".join(["t [ms],v (V),x (um)", "0,0,0", "1,1,2", "2,2,4"]))
        >>> rec = load_record(path, input="v (V)", output="x (um)", time="t [ms]")
        >>> rec.si_units(), rec.fs, rec.output.tolist()
        ({'input': 'V', 'output': 'm'}, 1000.0, [0.0, 2e-06, 4e-06])
        """
        return {role: self.units[role].si for role in ("input", "output") if role in self.units}

    def __repr__(self) -> str:
        return (
            f"Record(n={self.n}, fs={self.fs:g} Hz, duration={self.duration:g} s, "
            f"source={self.source!r}, columns={self.columns!r})"
        )

    def _span(self, start: object, stop: object, start_name: str, stop_name: str) -> tuple[int, int]:
        a = as_int(start, start_name, minimum=0)
        b = self.n if stop is None else as_int(stop, stop_name, minimum=0)
        if b > self.n:
            raise ParameterError(f"{stop_name} = {b} is beyond the end of the record ({self.n} samples)")
        if b - a < 2:
            raise ParameterError(
                f"{start_name} = {a}, {stop_name} = {b} keep {max(b - a, 0)} samples, at least 2 needed"
            )
        return a, b

    def _slice(self, a: int, b: int) -> Record:
        return Record(
            self.input[a:b],
            self.output[a:b],
            self.fs,
            None if self.time is None else self.time[a:b],
            f"{self.source}[{a}:{b}]",
            dict(self.columns),
            dict(self.units),
        )

    def trim(self, start: int = 0, stop: int | None = None) -> Record:
        """Samples ``start`` (inclusive) to ``stop`` (exclusive; ``None``: the end), as a
        new Record — the half-open range of Python slicing, 0-based sample indices.

        Indices beyond the record and ranges of fewer than 2 samples are errors, never
        silently clipped.

        Parameters
        ----------
        start : int
            First sample kept.
        stop : int, optional
            One past the last sample kept (default: the end).

        Returns
        -------
        Record

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst import Record
        >>> rec = Record(np.arange(10.0), 2 * np.arange(10.0), fs=100.0)
        >>> part = rec.trim(2, 5)
        >>> part.input.tolist(), part.source
        ([2.0, 3.0, 4.0], '[2:5]')
        >>> rec.trim(8, 12)
        Traceback (most recent call last):
        ...
        piezohyst.errors.ParameterError: stop = 12 is beyond the end of the record (10 samples)
        """
        a, b = self._span(start, stop, "start", "stop")
        return self._slice(a, b)

    def split(
        self, train: Sequence[int | None] | None = None, validate: Sequence[int | None] | None = None
    ) -> tuple[Record, Record]:
        """Training and validation records from two sample ranges ``(start, stop)``.

        Each range is half-open and 0-based like :meth:`trim` (``stop`` may be ``None``:
        the end). The ranges may not overlap. With neither given, the first half trains
        and the second half validates.

        Parameters
        ----------
        train, validate : (int, int or None), optional
            The two sample ranges ``(start, stop)``.

        Returns
        -------
        train, validate : Record

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst import Record
        >>> rec = Record(np.arange(10.0), 2 * np.arange(10.0), fs=100.0)
        >>> train, val = rec.split()
        >>> train.n, val.n
        (5, 5)
        >>> train, val = rec.split(train=(0, 8), validate=(8, None))
        >>> val.output.tolist()
        [16.0, 18.0]
        """
        if train is None and validate is None:
            h = self.n // 2
            train, validate = (0, h), (h, self.n)
        elif train is None or validate is None:
            raise ParameterError(f"train = {train!r}, validate = {validate!r}: give both ranges, or neither (halves)")
        spans: list[tuple[int, int]] = []
        for name, rng in (("train", train), ("validate", validate)):
            if isinstance(rng, (str, bytes)) or not isinstance(rng, (tuple, list)) or len(rng) != 2:
                raise ParameterTypeError(f"{name} must be a (start, stop) pair of sample indices, got {rng!r}")
            spans.append(self._span(rng[0], rng[1], f"{name}[0]", f"{name}[1]"))
        (a, b), (c, d) = spans
        if a < d and c < b:
            raise ParameterError(
                f"train = ({a}, {b}) and validate = ({c}, {d}) overlap "
                f"(samples {max(a, c)} to {min(b, d) - 1}); validation data must be held out"
            )
        return self._slice(a, b), self._slice(c, d)

    def to_mat(self, path: str | os.PathLike[str], *, overwrite: bool = False) -> Path:
        """Write the record to the MATLAB file ``path``, read back exactly by :meth:`from_mat`:
        the struct ``record`` with ``input``, ``output`` (N x 1 doubles, SI), ``fs`` (Hz),
        ``time`` (N x 1 s, or ``[]`` without a measured time axis), ``source``, ``columns``
        (role -> source column) and ``units`` (role -> ``source``, ``si``, ``scale``,
        ``origin``). :func:`load_record` reads it too: ``load_record(path,
        input="record.input", output="record.output", fs=...)``. Layout of the file:
        :mod:`piezohyst.signals.matfile`.

        Parameters
        ----------
        path : str or os.PathLike
            The file to write (``.mat``), atomically.
        overwrite : bool
            Replace an existing file (default ``False``: ``OutputExistsError``).

        Returns
        -------
        pathlib.Path
            The file written.

        Examples
        --------
        >>> import tempfile, pathlib
        >>> import numpy as np
        >>> from piezohyst.data import Record
        >>> rec = Record(np.sin(np.arange(5.0)), np.cos(np.arange(5.0)), fs=200.0, source="run 1")
        >>> path = rec.to_mat(pathlib.Path(tempfile.mkdtemp()) / "run.mat")
        >>> back = Record.from_mat(path)
        >>> np.array_equal(back.output, rec.output), back.fs, back.source
        (True, 200.0, 'run 1')
        """
        from .matfile import write_mat

        value: dict[str, object] = {
            "input": self.input.reshape(-1, 1),
            "output": self.output.reshape(-1, 1),
            "fs": self.fs,
            "time": None if self.time is None else self.time.reshape(-1, 1),
            "source": self.source,
            "columns": dict(self.columns),
            "units": {role: dict(c._asdict()) for role, c in self.units.items()},
        }
        return write_mat(path, "record", value, overwrite=overwrite)

    @classmethod
    def from_mat(cls, path: str | os.PathLike[str]) -> Record:
        """Read a record :meth:`to_mat` wrote, exactly (``DataError`` naming the file when it
        is not one).

        Parameters
        ----------
        path : str or os.PathLike
            The ``.mat`` file.

        Returns
        -------
        Record

        Examples
        --------
        >>> import tempfile, pathlib
        >>> from piezohyst.data import Record
        >>> path = Record([0.0, 1.0], [2.0, 3.0], fs=10.0).to_mat(pathlib.Path(tempfile.mkdtemp()) / "r.mat")
        >>> Record.from_mat(path).output.tolist()
        [2.0, 3.0]
        """
        from .matfile import load_mat_file

        def build(d: dict[str, Any]) -> Record:
            t = d["time"]
            return cls(
                np.asarray(d["input"], dtype=np.float64).ravel(),
                np.asarray(d["output"], dtype=np.float64).ravel(),
                d["fs"],
                None if t is None else np.asarray(t, dtype=np.float64).ravel(),
                d["source"],
                d["columns"],
                {role: UnitConversion(**c) for role, c in d["units"].items()},
            )

        return load_mat_file(path, "record", "record file", build)

    def to_pandas(self) -> pd.DataFrame:
        """A :class:`pandas.DataFrame` with columns ``time`` (the measured time, or
        ``arange(n) / fs``), ``input`` and ``output``. Needs pandas.

        Returns
        -------
        pandas.DataFrame

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst import Record
        >>> rec = Record(np.arange(4.0), 2 * np.arange(4.0), fs=100.0)
        >>> try:
        ...     df = rec.to_pandas()
        ... except ImportError:           # pandas is optional
        ...     df = None
        >>> df is None or list(df.columns) == ["time", "input", "output"]
        True
        """
        try:
            import pandas as pd
        except ImportError:
            raise ImportError("Record.to_pandas needs pandas: pip install pandas") from None
        t = self.time if self.time is not None else np.arange(self.n) / self.fs
        return pd.DataFrame({"time": np.array(t), "input": np.array(self.input), "output": np.array(self.output)})


def _check_increasing(t: FloatArray, name: str) -> FloatArray:
    d = np.diff(t)
    bad = np.flatnonzero(~(d > 0))
    if bad.size:
        k = int(bad[0])
        raise ParameterError(
            f"{name} is not strictly increasing: {name}[{k + 1}] = {float(t[k + 1])!r} follows "
            f"{name}[{k}] = {float(t[k])!r}"
        )
    return d


def fs_from_time(t: FloatArray, name: str, rtol: float) -> float:
    """The sample rate of a strictly increasing, uniform time axis (seconds).

    Robust to rounded and jittered time stamps within ``rtol``: every step must lie within
    ``rtol`` of the median step, a step of ``GAP_STEPS`` median steps or more is a gap (an error
    naming its row), and the rate is the slope of the least-squares line ``t = t0 + k / fs``
    over the sample index ``k``, each stamp within ``rtol`` steps of it."""
    d = _check_increasing(t, name)
    med = float(np.median(d))
    gaps = np.flatnonzero(d >= max(GAP_STEPS, 1.0 + 2.0 * rtol) * med)
    if gaps.size:
        k = int(gaps[0])
        raise ParameterError(
            f"{name} has a gap at row {k + 1}: {name}[{k + 1}] - {name}[{k}] = {d[k]:.9g} s is {d[k] / med:.3g} "
            f"median steps ({med:.9g} s), about {max(round(d[k] / med) - 1, 1)} samples missing; a record with "
            f"a missing stretch is not resampled silently: load the parts on either side of row {k + 1} "
            f"(trim), or fill the gap"
        )
    dev = np.abs(d - med)
    bad = np.flatnonzero(dev > rtol * med)
    if bad.size:
        k = int(bad[0])
        raise ParameterError(
            f"{name} is not uniformly sampled: the step at index {k} ({name}[{k + 1}] - {name}[{k}] = "
            f"{d[k]:.9g} s) differs from the median step {med:.9g} s by {dev[k] / med:.3g} relative "
            f"(time_rtol = {rtol:g}); resample the record first (it is not resampled silently), "
            f"or raise time_rtol if the time stamps are merely rounded"
        )
    idx = np.arange(t.size, dtype=np.float64)
    kc = idx - idx.mean()
    tc = t - t[0]
    step = float(np.dot(kc, tc - tc.mean()) / np.dot(kc, kc))
    resid = tc - tc.mean() - step * kc
    worst = int(np.argmax(np.abs(resid)))
    if abs(resid[worst]) > max(rtol, 1e-9) * step:
        raise ParameterError(
            f"{name} does not follow a uniform clock: {name}[{worst}] is {abs(resid[worst]) / step:.3g} steps off "
            f"the least-squares line t = t0 + k / fs (time_rtol = {rtol:g}); the sample rate drifts: resample "
            f"the record first, or raise time_rtol"
        )
    if abs(resid[worst]) <= 1e-6 * step:  # exact stamps: the span gives the rate to the last bit
        return (t.size - 1) / float(t[-1] - t[0])
    return 1.0 / step


# --------------------------------------------------------------------------------------
# Argument checks


def _check_path(path: object) -> Path:
    if isinstance(path, bytes) or not isinstance(path, (str, os.PathLike)):
        raise ParameterTypeError(f"path must be a str or os.PathLike, got {type(path).__name__}")
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such file")
    if p.is_dir():
        raise ParameterError(f"path = {str(p)!r} is a directory, not a data file")
    return p


def check_column_spec(spec: object, name: str) -> ColumnSpec:
    if spec is None:
        return None
    if isinstance(spec, str):
        if not spec.strip():
            raise ParameterError(f"{name} = {spec!r}: a column name may not be empty")
        return spec
    if isinstance(spec, bool) or not isinstance(spec, (int, np.integer)):
        raise ParameterTypeError(f"{name} must be a column name (str) or a 0-based column index (int), got {spec!r}")
    if spec < 0:
        raise ParameterError(f"{name} = {int(spec)}: column indices are 0-based and must be >= 0")
    return int(spec)


# --------------------------------------------------------------------------------------
# Sources: a text table or a container of arrays. Each resolves a column spec to a key
# (what identifies the column), a label (how to name it) and reads a 1-D float64 array.

_Key = TypeVar("_Key", bound=Hashable)


class ColumnSource(Protocol[_Key]):
    """What :func:`load_record` reads columns from: a :class:`TextTable` (keys are column
    indices) or a table of named arrays from :func:`open_npz`, :func:`open_npy`,
    :func:`open_mat`, :func:`open_hdf5` (keys are matrix column indices or array names)."""

    source: str

    def columns(self) -> list[tuple[_Key, str]]:
        """``(key, label)`` of every column that could be a signal."""
        ...

    def resolve(self, role: str, spec: str | int) -> tuple[_Key, str]:
        """``(key, label)`` of the column ``spec`` names for ``role``."""
        ...

    def read(self, role: str, key: _Key, label: str) -> FloatArray:
        """The column as a finite 1-D float64 array."""
        ...

    def close(self) -> None:
        """Release the file (a no-op for sources read into memory)."""
        ...


#: Any numeric array read from a container (float, int or unsigned dtype).
AnyArray = npt.NDArray[Any]


class _ContainerTable:
    """Named arrays (NPZ, MAT, HDF5) and optionally one 2-D matrix whose columns are
    addressed by index (``dataset``; rows are samples). A column's key is its index (int) in
    the matrix or the array's name (str)."""

    def __init__(
        self,
        source: str,
        kind: str,
        variables: dict[str, tuple[int, ...]],
        lookup: Callable[[str], AnyArray],
        matrix_name: str | None,
        close: Callable[[], None] | None = None,
        unit: Callable[[str], str | None] | None = None,
    ) -> None:
        self.source = source
        self.kind = kind
        self.variables = variables  # name -> shape, numeric arrays only (for listings)
        self._lookup = lookup  # name -> np.ndarray (raises KeyError)
        self._close = close
        self._unit = unit
        self.matrix: AnyArray | None = None
        self.matrix_name = matrix_name
        if matrix_name is not None:
            m = self._get(matrix_name, "dataset")
            if m.ndim != 2:
                hint = f"; name it directly, e.g. input={matrix_name!r}" if m.ndim == 1 else ""
                raise DataError(
                    f"{source}: dataset = {matrix_name!r} has shape {m.shape}, expected a 2-D matrix "
                    f"(samples x signals){hint}"
                )
            if m.shape[0] < m.shape[1]:
                raise DataError(
                    f"{source}: dataset = {matrix_name!r} has shape {m.shape}: fewer rows than columns, so it "
                    f"looks transposed; rows must be samples and columns signals (transpose it when saving)"
                )
            self.matrix = m

    def _available(self) -> str:
        names = sorted(self.variables)
        return f"the numeric {self.kind} variables are {names}" if names else "the file holds no numeric arrays"

    def close(self) -> None:
        """Close the file the arrays are read from (HDF5); a no-op for archives read whole."""
        if self._close is not None:
            self._close()

    def _get(self, name: str, role: str) -> AnyArray:
        try:
            a = self._lookup(name)
        except KeyError:
            raise DataError(f"{self.source}: {role} = {name!r} is not in the file; {self._available()}") from None
        if a.dtype.kind not in "fiu":
            raise ParameterTypeError(f"{self.source}: {role} = {name!r} must hold real numbers, got dtype {a.dtype}")
        return a

    def unit_of(self, key: int | str) -> str | None:
        """The unit stored with a named array (an HDF5 ``units`` attribute), if any."""
        if isinstance(key, int) or self._unit is None:
            return None
        return self._unit(key)

    def columns(self) -> list[tuple[int | str, str]]:
        if self.matrix is not None:
            return [(j, f"{self.matrix_name}[:, {j}]") for j in range(self.matrix.shape[1])]
        return [(n, n) for n, shape in self.variables.items() if sum(s > 1 for s in shape) == 1]

    def resolve(self, role: str, spec: str | int) -> tuple[int | str, str]:
        if isinstance(spec, int):
            if self.matrix is None:
                raise DataError(
                    f"{self.source}: {role} = {spec} is a column index, which needs dataset = <name of a "
                    f"2-D matrix>; or name the array ({self._available()})"
                )
            k = self.matrix.shape[1]
            if spec >= k:
                raise DataError(
                    f"{self.source}: {role} = {spec} is out of range: dataset {self.matrix_name!r} has shape "
                    f"{self.matrix.shape}, {k} columns (0-based indices 0..{k - 1})"
                )
            return spec, f"{self.matrix_name}[:, {spec}]"
        return spec, spec

    def read(self, role: str, key: int | str, label: str) -> FloatArray:
        if isinstance(key, int):
            assert self.matrix is not None  # resolve() gives column indices only with a matrix
            a = self.matrix[:, key]
        else:
            a = self._get(key, role)
            if a.ndim == 0 or a.size == 1:
                raise DataError(f"{self.source}: {role} = {label!r} is a scalar ({a.ravel()[:1]}), not a signal")
            if sum(s > 1 for s in a.shape) > 1:
                raise DataError(
                    f"{self.source}: {role} = {label!r} has shape {a.shape}, not a 1-D signal; for a matrix "
                    f"pass dataset={label!r} and {role}=<0-based column index>"
                )
            a = a.ravel()
        x = np.asarray(a, dtype=np.float64)
        bad = np.flatnonzero(~np.isfinite(x))
        if bad.size:
            i = int(bad[0])
            raise DataError(f"{self.source}: {role}[{i}] = {x[i]} is not finite ({label!r})")
        return x


def _numeric_shapes(arrays: Mapping[str, object]) -> dict[str, tuple[int, ...]]:
    return {
        k: tuple(v.shape)
        for k, v in arrays.items()
        if isinstance(v, np.ndarray) and v.dtype.kind in "fiu" and v.size > 0
    }


def _dict_lookup(arrays: Mapping[str, object]) -> Callable[[str], AnyArray]:
    def lookup(name: str) -> AnyArray:
        return np.asarray(arrays[name])

    return lookup


def _max_bytes(max_bytes: object) -> int:
    """The bound on one array's decompressed size: ``max_bytes``, else the environment
    variable ``PIEZOHYST_MAX_ARRAY_BYTES``, else 1 GiB."""
    if max_bytes is not None:
        return as_int(max_bytes, "max_bytes", minimum=1)
    env = os.environ.get(MAX_ARRAY_BYTES_ENV, "").strip()
    if not env:
        return MAX_ARRAY_BYTES
    try:
        value = int(float(env)) if re.fullmatch(r"\d+(?:\.\d*)?(?:[eE]\+?\d+)?", env) else -1
    except (ValueError, OverflowError):
        value = -1
    if value < 1:
        raise ParameterError(f"{MAX_ARRAY_BYTES_ENV} = {env!r} must be a number of bytes >= 1 (e.g. 4000000000)")
    return value


def _check_size(source: str, what: str, nbytes: int, limit: int) -> None:
    """A clear error, before reading, when an array would take more than ``limit`` bytes."""
    if nbytes > limit:
        raise DataError(
            f"{source}: {what} would take {nbytes:,} bytes when read (decompressed), over the limit of "
            f"{limit:,} bytes; if the file is trusted, raise the limit with the environment variable "
            f"{MAX_ARRAY_BYTES_ENV}=<bytes> or load_record(..., max_bytes=<bytes>)"
        )


def _npy_header(fp: Any) -> tuple[tuple[int, ...], np.dtype[Any]]:
    version = np.lib.format.read_magic(fp)
    if version == (1, 0):
        shape, _, dtype = np.lib.format.read_array_header_1_0(fp)
    else:  # 2.0 and 3.0 share the header layout (3.0 allows UTF-8 in field names)
        shape, _, dtype = np.lib.format.read_array_header_2_0(fp)
    return tuple(int(k) for k in shape), np.dtype(dtype)


def open_npz(path: Path, dataset: str | None, limit: int = MAX_ARRAY_BYTES) -> _ContainerTable:
    """An NPZ archive: member headers read to list the arrays; only the arrays named are
    decompressed, each after its size (from its header) is checked against ``limit``."""
    fh = open(path, "rb")  # ours, closed on every path (np.load leaks its own on a corrupt zip)
    try:
        z = np.load(fh, allow_pickle=False)
        if isinstance(z, np.ndarray):
            raise ParameterError("it holds a single array (.npy format), not an archive")
    except Exception as e:  # a corrupt archive raises from zipfile, zlib, numpy.lib.format ...
        fh.close()
        raise DataError(f"{path}: not a readable NPZ archive ({type(e).__name__}: {e})") from None

    def close() -> None:
        z.close()
        fh.close()

    headers: dict[str, tuple[tuple[int, ...], np.dtype[Any]]] = {}
    try:
        for member in z.zip.namelist():
            key = member[:-4] if member.endswith(".npy") else member
            if key not in z.files:
                continue
            with z.zip.open(member) as fp:
                headers[key] = _npy_header(fp)
    except Exception as e:
        close()
        raise DataError(f"{path}: not a readable NPZ archive ({type(e).__name__}: {e})") from None
    shapes = {k: sh for k, (sh, dt) in headers.items() if dt.kind in "fiu" and math.prod(sh) > 0}

    def lookup(name: str) -> AnyArray:
        if name not in headers:
            raise KeyError(name)
        shape, dtype = headers[name]
        if dtype.kind not in "fiu":
            return np.empty((0,), dtype=dtype if not dtype.hasobject else np.dtype("U1"))
        _check_size(
            str(path), f"NPZ member {name!r} of shape {shape} ({dtype})", math.prod(shape) * dtype.itemsize, limit
        )
        try:
            return np.asarray(z[name])
        except Exception as e:
            raise DataError(f"{path}: NPZ member {name!r} is not readable ({type(e).__name__}: {e})") from None

    try:
        return _ContainerTable(str(path), "NPZ", shapes, lookup, dataset, close=close)
    except BaseException:
        close()
        raise


def open_npy(path: Path, dataset: str | None, limit: int = MAX_ARRAY_BYTES) -> _ContainerTable:
    """A ``.npy`` matrix, after its header's size is checked against ``limit`` and against the
    bytes the file holds (numpy allocates the declared size before reading)."""
    if dataset is not None:
        raise ParameterError(f"dataset = {dataset!r} does not apply to a .npy file (one matrix; columns by index)")
    try:
        with open(path, "rb") as fp:
            shape, dtype = _npy_header(fp)
            have = os.fstat(fp.fileno()).st_size - fp.tell()
    except Exception as e:
        raise DataError(f"{path}: not a readable .npy array ({type(e).__name__}: {e})") from None
    if dtype.kind in "fiu":
        need = math.prod(shape) * dtype.itemsize
        _check_size(str(path), f"the array of shape {shape} ({dtype})", need, limit)
        if need > have:
            raise DataError(
                f"{path}: the array of shape {shape} ({dtype}) needs {need:,} bytes, the file holds {have:,}: "
                "truncated or damaged"
            )
    try:
        a = np.load(path, allow_pickle=False)
        if not isinstance(a, np.ndarray):
            raise ParameterError("it is an NPZ archive, not a single array")
    except Exception as e:
        raise DataError(f"{path}: not a readable .npy array ({type(e).__name__}: {e})") from None
    if a.dtype.kind not in "fiu":
        raise ParameterTypeError(f"{path}: the array must hold real numbers, got dtype {a.dtype}")
    arrays = {"array": a}
    return _ContainerTable(str(path), "npy", {"array": a.shape}, _dict_lookup(arrays), "array")


def _flatten_mat(d: Mapping[str, object], prefix: str, out: dict[str, AnyArray]) -> None:
    for k, v in d.items():
        if not prefix and k.startswith("__"):
            continue
        name = f"{prefix}{k}"
        if isinstance(v, Mapping):
            _flatten_mat(v, f"{name}.", out)
        elif isinstance(v, np.ndarray) or (isinstance(v, (int, float)) and not isinstance(v, bool)):
            out[name] = np.asarray(v)


_MAT_ITEMSIZE = {
    "double": 8, "single": 4, "int8": 1, "uint8": 1, "int16": 2, "uint16": 2,
    "int32": 4, "uint32": 4, "int64": 8, "uint64": 8, "logical": 1, "char": 2,
}  # fmt: skip


def open_mat(path: Path, dataset: str | None, limit: int = MAX_ARRAY_BYTES) -> _ContainerTable:
    """A MATLAB file: v7.3 through :func:`open_hdf5`; v4-v7 through scipy, one variable at a
    time and none before its size is checked against ``limit``.

    The variables are listed from their headers (:func:`scipy.io.whosmat`; v5-v7: each
    element's tag and array flags, :class:`_Mat5Index`); a numeric variable is read only when
    it is asked for (``loadmat(..., variable_names=[name])``), after its declared size and, in a
    v5-v7 file, the size its element decompresses to (counted by streaming zlib, stopped past
    the limit) are checked. Structs are read when the file is opened (their fields are the
    variables' names), each after the same check; a struct over the limit is listed by its
    name and refused when one of its fields is asked for. Cells, sparse matrices, strings and
    objects are never read."""
    from scipy.io import loadmat, whosmat
    from scipy.io.matlab import matfile_version

    source = str(path)
    try:
        major, _ = matfile_version(source)
    except Exception as e:
        raise DataError(f"{path}: not a MATLAB .mat file ({type(e).__name__}: {e})") from None
    if major == 2:
        return open_hdf5(path, dataset, matlab=True, limit=limit)
    version = 4 if major == 0 else 5

    def unreadable(e: Exception) -> DataError:
        return DataError(f"{path}: not a readable MATLAB v{version} file ({type(e).__name__}: {e})")

    try:
        with _mat_header_checks():
            listing = whosmat(source)
            index = _Mat5Index(path, len(listing)) if version == 5 else None
    except DataError:
        raise
    except Exception as e:
        raise unreadable(e) from None
    variables: dict[str, tuple[int, ...]] = {}
    where: dict[str, tuple[int, tuple[int, ...], str]] = {}  # numeric name -> (element, shape, class)
    too_big: dict[str, DataError] = {}  # structs over the limit, by name
    arrays: dict[str, AnyArray] = {}  # the structs' fields

    def check(i: int, name: str, shape: tuple[int, ...], cls: str) -> None:
        what = f"MATLAB variable {name!r} of shape {shape} ({cls})"
        if cls in _MAT_ITEMSIZE:
            _check_size(source, what, int(np.prod(shape)) * _MAT_ITEMSIZE[cls], limit)
        if index is not None:
            _check_size(source, what, index.decompressed_size(i, limit), limit)

    def read(name: str) -> AnyArray | Mapping[str, object]:
        try:
            with _mat_header_checks():
                d = loadmat(source, variable_names=[name], simplify_cells=True)
        except Exception as e:
            raise unreadable(e) from None
        value: AnyArray | Mapping[str, object] = d[name]
        return value

    for i, (name, dims, cls) in enumerate(listing):
        shape = tuple(int(k) for k in dims)
        if name.startswith("__"):
            continue
        if cls in _MAT_NUMERIC and not (index is not None and index.complex[i]):
            where[name] = (i, shape, cls)
            squeezed = tuple(k for k in shape if k != 1)  # as loadmat(simplify_cells=True) returns it
            if int(np.prod(shape)) > 0:
                variables[name] = squeezed
        elif cls in _MAT_NUMERIC:
            where[name] = (i, shape, cls)  # complex: read to say so when asked for
        elif cls == "struct":
            try:
                check(i, name, shape, cls)
            except DataError as e:
                too_big[name] = e
                continue
            _flatten_mat({name: read(name)}, "", arrays)
    variables.update(_numeric_shapes(arrays))

    def lookup(name: str) -> AnyArray:
        name = name.replace("/", ".")
        if name in arrays:
            return np.asarray(arrays[name])
        head = name.split(".", 1)[0]
        if head in too_big and head != name:
            raise too_big[head]
        if name not in where:
            raise KeyError(name)
        i, shape, cls = where[name]
        check(i, name, shape, cls)
        return np.asarray(read(name))

    return _ContainerTable(source, "MAT", variables, lookup, dataset)


@contextlib.contextmanager
def _mat_header_checks() -> Iterator[None]:
    """scipy's MATLAB reader on a damaged file: overflowing header arithmetic is left to the
    reader's own error (not a warning), and a v4 header of an unknown byte order, which scipy
    reads with a warning that the data "may be corrupt", is an error."""
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        warnings.filterwarnings("error", message=".*may be corrupt")
        yield


#: MATLAB classes read as numeric arrays.
_MAT_NUMERIC = ("double", "single", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64", "uint64")

#: miCOMPRESSED and miMATRIX, the data types of a MATLAB v5 file's top-level elements.
_MI_COMPRESSED, _MI_MATRIX = 15, 14


class _Mat5Index:
    """Where each top-level element of a MATLAB v5-v7 file lies, whether it is compressed,
    and its complex flag, read from the 8-byte tags and the array flags only (the layout
    scipy's reader walks, one element per variable :func:`scipy.io.whosmat` lists);
    :meth:`decompressed_size` counts what an element decompresses to without keeping it."""

    def __init__(self, path: Path, count: int) -> None:
        import zlib

        self.path = path
        self.elements: list[tuple[int, int, bool]] = []  # (payload offset, byte count, compressed)
        self.complex: list[bool] = []
        size = path.stat().st_size
        with open(path, "rb") as f:
            f.seek(126)
            self.order = "<" if f.read(2) == b"IM" else ">"
            pos = 128
            while pos + 8 <= size:
                f.seek(pos)
                mdtype, nbytes = np.frombuffer(f.read(8), dtype=f"{self.order}u4").tolist()
                if nbytes == 0 or pos + 8 + nbytes > size:
                    raise DataError(f"{path}: not a readable MATLAB v5 file (element at byte {pos} runs past the end)")
                head = f.read(min(nbytes, 4096))
                if mdtype == _MI_COMPRESSED:
                    try:
                        head = zlib.decompressobj().decompress(head, 24)
                    except zlib.error as e:
                        raise DataError(f"{path}: not a readable MATLAB v5 file (zlib: {e})") from None
                    inner = np.frombuffer(head[:4], dtype=f"{self.order}u4") if len(head) >= 4 else [0]
                    if int(inner[0]) != _MI_MATRIX:
                        raise DataError(f"{path}: not a readable MATLAB v5 file (a compressed element is not a matrix)")
                    flags = head[16:20]
                elif mdtype == _MI_MATRIX:
                    flags = head[8:12]
                else:
                    raise DataError(f"{path}: not a readable MATLAB v5 file (element of type {mdtype} at byte {pos})")
                word = int(np.frombuffer(flags, dtype=f"{self.order}u4")[0]) if len(flags) == 4 else 0
                self.complex.append(bool(word & 0x0800))
                self.elements.append((pos + 8, nbytes, mdtype == _MI_COMPRESSED))
                pos += 8 + nbytes
        if len(self.elements) != count:
            raise DataError(
                f"{path}: not a readable MATLAB v5 file ({len(self.elements)} elements for {count} variables)"
            )

    def decompressed_size(self, i: int, limit: int) -> int:
        """Bytes element ``i`` takes when read: its byte count, or for a compressed one the
        bytes its zlib stream decompresses to, counted in 1 MiB pieces and stopped once past
        ``limit`` (the count returned is then above ``limit``)."""
        import zlib

        offset, nbytes, compressed = self.elements[i]
        if not compressed:
            return nbytes
        d = zlib.decompressobj()
        total = 0
        chunk = 1 << 20
        with open(self.path, "rb") as f:
            f.seek(offset)
            left, data = nbytes, b""
            while total <= limit and not d.eof:
                if not data and left > 0:
                    data = f.read(min(chunk, left))
                    left -= len(data)
                try:
                    out = d.decompress(data, chunk)  # at most 1 MiB out; the rest of the input waits
                except zlib.error as e:
                    raise DataError(f"{self.path}: not a readable MATLAB v5 file (zlib: {e})") from None
                total += len(out)
                data = d.unconsumed_tail
                if not out and not data and left == 0:
                    break
        return total


def _import_h5py() -> ModuleType:
    try:
        import h5py
    except ImportError:
        raise ImportError(H5PY_HINT) from None
    module: ModuleType = h5py  # h5py ships no type information
    return module


class _Hdf5Source:
    """An open HDF5 file (closed by the caller) exposing numeric datasets by path."""

    def __init__(self, path: Path, matlab: bool, limit: int = MAX_ARRAY_BYTES) -> None:
        h5py = _import_h5py()
        self.limit = limit
        self.kind = "MATLAB v7.3" if matlab else "HDF5"
        try:
            self.file = h5py.File(path, "r")
        except Exception as e:
            raise DataError(f"{path}: not a readable {self.kind} file ({type(e).__name__}: {e})") from None
        self.matlab = matlab
        self.h5py = h5py
        shapes: dict[str, tuple[int, ...]] = {}

        def visit(name: str, obj: object) -> None:
            if any(part.startswith("#") for part in name.split("/")):
                return  # MATLAB's #refs# / #subsystem# internals
            if isinstance(obj, h5py.Dataset) and obj.dtype.kind in "fiu" and obj.size > 0:
                if matlab and obj.attrs.get("MATLAB_class", b"") in (b"char", "char"):
                    return
                shape = tuple(obj.shape)
                if matlab:  # MATLAB's view: struct fields as s.field, arrays transposed
                    shapes[name.replace("/", ".")] = shape[::-1]
                else:
                    shapes[name] = shape

        try:
            self.file.visititems(visit)
        except Exception as e:
            self.file.close()
            raise DataError(f"{path}: not a readable {self.kind} file ({type(e).__name__}: {e})") from None
        self.shapes = shapes

    def _check_links(self, key: str, name: str, depth: int = 0) -> None:
        """Refuse a path through an external link (a soft link is followed, within the file)."""
        h5py = self.h5py
        cur = ""
        for part in key.strip("/").split("/"):
            cur = f"{cur}/{part}"
            try:
                link = self.file.get(cur, getlink=True)
            except (KeyError, ValueError, TypeError):
                raise KeyError(name) from None
            if link is None:
                raise KeyError(name)
            if isinstance(link, h5py.ExternalLink):
                raise DataError(
                    f"{self.file.filename}: {name!r} goes through an external link ({cur!r} -> file "
                    f"{link.filename!r}, {link.path!r}); links to other files are not followed: only the "
                    f"file named is read"
                )
            if isinstance(link, h5py.SoftLink):
                if depth > 16:
                    raise DataError(f"{self.file.filename}: {name!r}: soft links nested more than 16 deep")
                self._check_links(str(link.path), name, depth + 1)

    def unit(self, name: str) -> str | None:
        """The ``units`` (or ``unit``) attribute of a dataset, if it has one."""
        key = name.replace(".", "/") if self.matlab else name
        try:
            self._check_links(key, name)
            value = self.file[key].attrs.get("units", self.file[key].attrs.get("unit"))
        except (KeyError, ValueError, TypeError, OSError, DataError):
            return None
        if isinstance(value, np.ndarray) and value.size == 1:
            value = value.ravel()[0]
        if isinstance(value, bytes):
            value = value.decode("utf-8", errors="replace")
        return value if isinstance(value, str) and value.isprintable() and len(value) <= 32 else None

    def lookup(self, name: str) -> AnyArray:
        key = name.replace(".", "/") if self.matlab else name
        self._check_links(key, name)
        try:
            obj = self.file[key]
        except (KeyError, ValueError):
            raise KeyError(name) from None
        if not isinstance(obj, self.h5py.Dataset):
            raise KeyError(name)
        src = self.file.filename
        if obj.external:
            raise DataError(
                f"{src}: dataset {name!r} keeps its data in external raw storage ({obj.external[0][0]!r}); "
                f"data outside the file named is not read"
            )
        if obj.is_virtual:
            raise DataError(
                f"{src}: dataset {name!r} is a virtual dataset (mapped from other datasets or files); "
                f"it is not read: only data stored in the file named is"
            )
        if obj.dtype.kind not in "fiu":
            return np.empty((0,), dtype=obj.dtype if obj.dtype.kind not in "OV" else np.dtype("U1"))
        _check_size(
            src, f"dataset {name!r} of shape {obj.shape} ({obj.dtype})", int(obj.size) * obj.dtype.itemsize, self.limit
        )
        try:
            a = np.asarray(obj[()])
        except Exception as e:
            raise DataError(f"{self.file.filename}: cannot read {name!r} ({type(e).__name__}: {e})") from None
        if self.matlab:
            cls = obj.attrs.get("MATLAB_class", b"")
            cls = cls.decode(errors="replace") if isinstance(cls, bytes) else str(cls)
            if cls == "char":
                return np.array([f"<MATLAB char array {name}>"])  # rejected as not numeric by the caller
            return a.T
        return a


def open_hdf5(path: Path, dataset: str | None, matlab: bool = False, limit: int = MAX_ARRAY_BYTES) -> _ContainerTable:
    """An HDF5 file (or MATLAB v7.3): datasets by path. Only what is named is read: external
    links, external raw storage and virtual datasets are refused, and a dataset's size is
    checked against ``limit`` before it is read."""
    src = _Hdf5Source(path, matlab, limit)
    try:
        return _ContainerTable(
            str(path), src.kind, src.shapes, src.lookup, dataset, close=src.file.close, unit=src.unit
        )
    except BaseException:
        src.file.close()
        raise


class ParquetTable:
    """A Parquet file (through pyarrow): its numeric columns by name or 0-based index; only the
    columns named are read, each after its uncompressed size is checked against ``limit``."""

    kind = "Parquet"

    def __init__(self, path: Path, limit: int = MAX_ARRAY_BYTES) -> None:
        try:
            import pyarrow.parquet as pq
        except ImportError:
            raise ImportError(PYARROW_HINT.replace("text records", "Parquet files")) from None
        self.source = str(path)
        self.limit = limit
        try:
            self.file = pq.ParquetFile(path)
            self.names: list[str] = [str(n) for n in self.file.schema_arrow.names]
            meta = self.file.metadata
            self.sizes = [
                sum(int(meta.row_group(g).column(j).total_uncompressed_size) for g in range(meta.num_row_groups))
                for j in range(meta.num_columns)
            ]
        except Exception as e:
            raise DataError(f"{path}: not a readable Parquet file ({type(e).__name__}: {e})") from None
        self.ncols = len(self.names)

    def columns(self) -> list[tuple[int, str]]:
        return list(enumerate(self.names))

    def unit_of(self, key: int) -> str | None:
        """A ``unit`` / ``units`` entry of the column's field metadata, if any."""
        meta = self.file.schema_arrow.field(key).metadata or {}
        value = meta.get(b"unit", meta.get(b"units"))
        if not isinstance(value, bytes):
            return None
        text = value.decode("utf-8", errors="replace")
        return text if text.isprintable() and len(text) <= 32 else None

    def resolve(self, role: str, spec: str | int) -> tuple[int, str]:
        if isinstance(spec, int):
            if spec >= self.ncols:
                raise DataError(
                    f"{self.source}: {role} = {spec} is out of range: the file has {self.ncols} columns "
                    f"(0-based indices 0..{self.ncols - 1})"
                )
            return spec, self.names[spec]
        hits = [j for j, n in enumerate(self.names) if n == spec]
        if not hits:
            hits = [j for j, n in enumerate(self.names) if split_annotation(n)[0] == spec]
        if not hits:
            raise DataError(f"{self.source}: {role} = {spec!r} is not a column; the columns are {self.names}")
        if len(hits) > 1:
            raise DataError(f"{self.source}: {role} = {spec!r} names columns {hits}; use a 0-based index")
        return hits[0], self.names[hits[0]]

    def read(self, role: str, key: int, label: str) -> FloatArray:
        import pyarrow as pa

        if key < len(self.sizes):
            _check_size(self.source, f"column {label!r}", self.sizes[key], self.limit)
        try:
            col = self.file.read(columns=[self.names[key]]).column(0)
        except Exception as e:
            raise DataError(f"{self.source}: column {label!r} is not readable ({type(e).__name__}: {e})") from None
        if not (pa.types.is_integer(col.type) or pa.types.is_floating(col.type)):
            raise ParameterTypeError(f"{self.source}: {role} = {label!r} must hold real numbers, got type {col.type}")
        if col.null_count:
            i = int(np.flatnonzero(np.asarray(col.is_null()))[0])
            raise DataError(f"{self.source}: {role}[{i}] is missing (null) in column {label!r}")
        x = np.asarray(col.to_numpy(), dtype=np.float64)
        bad = np.flatnonzero(~np.isfinite(x))
        if bad.size:
            i = int(bad[0])
            raise DataError(f"{self.source}: {role}[{i}] = {x[i]} is not finite ({label!r})")
        return x

    def close(self) -> None:
        """Release the file."""
        self.file = None


def open_parquet(path: Path, dataset: str | None, limit: int = MAX_ARRAY_BYTES) -> ParquetTable:
    if dataset is not None:
        raise ParameterError(f"dataset = {dataset!r} does not apply to a Parquet file (columns by name or index)")
    return ParquetTable(path, limit)


# --------------------------------------------------------------------------------------
# load_record


def load_record(
    path: str | os.PathLike[str],
    *,
    input: str | int | None = None,
    output: str | int | None = None,
    time: str | int | None = None,
    fs: float | None = None,
    delimiter: str | None = None,
    header: bool | str = "auto",
    dataset: str | None = None,
    time_rtol: float = TIME_RTOL,
    time_unit: str | None = None,
    input_unit: str | None = None,
    output_unit: str | None = None,
    max_bytes: int | None = None,
) -> Record:
    """Load a measured record (input, output, sample rate) from a file.

    Parameters
    ----------
    path : str or os.PathLike
        The file; its extension selects the reader: ``.csv .tsv .txt .dat .asc`` (delimited
        text, parsed by pyarrow), ``.npz``, ``.npy``, ``.mat`` (v4/v5/v7, or v7.3 with h5py),
        ``.h5 .hdf5 .he5`` (with h5py), ``.parquet .pq`` (pyarrow).
    input, output, time : str or int, optional
        The columns to use. A **str** names a column: a header name of a text file, a key
        of an NPZ archive, a MATLAB variable (struct fields as ``"s.field"``), an HDF5
        dataset path (``"run1/voltage"``). An **int** is a **0-based** column index: of a
        text file, of a ``.npy`` matrix, or of the 2-D matrix named by ``dataset``. (Data
        READMEs often number columns from 1: "column 5" is ``4`` here.) ``input`` and
        ``output`` default to the columns named ``"input"`` and ``"output"``, else — when
        the source has exactly two columns (besides ``time``) — to those two, in order.
        ``time`` (seconds) is only used when given.
    fs : float, optional
        Sample rate in Hz. Either ``fs`` or ``time`` is required; with both, they must
        agree to ``time_rtol`` (relative) and ``fs`` is used.
    delimiter : str, optional
        Text files: the field separator; by default sniffed from the first lines: tab,
        semicolon, comma or runs of whitespace (also ``delimiter=" "``), whichever splits
        them into the same number of fields. A decimal comma (``0,5;1,25``), a UTF-8 or UTF-16
        byte-order mark and quoted fields are recognised.
    header : {"auto", True, False}
        Text files: whether the first non-comment line holds column names. ``"auto"``:
        yes if any of its fields is neither a number nor empty (``,0,-1.6,0`` is data); a
        ``#`` comment line right above the data with one name per column (as
        ``numpy.savetxt(header=...)`` writes) also names the columns. Lines starting with
        ``#``, ``%`` or (unless ``;`` separates fields) ``;`` and blank lines are skipped.
    dataset : str, optional
        NPZ/MAT/HDF5: a 2-D matrix (rows are samples; MATLAB's orientation for ``.mat``
        files, also v7.3) whose columns integer ``input``/``output``/``time`` address.
    time_rtol : float
        Relative tolerance of the time stamps (default 1e-6; raise it for rounded or jittered
        stamps): every step within ``time_rtol`` of the median step, every stamp within
        ``time_rtol`` steps of the least-squares line ``t = t0 + k / fs`` whose slope gives the
        rate. A step of 1.5 median steps or more is a gap — an error naming its row.
    time_unit, input_unit, output_unit : str, optional
        The unit of a column (``"ms"``, ``"us"``; ``"mV"``, ``"kV"``; ``"um"``, ``"µm"``,
        ``"nm"``, ``"mm"``; ...). By default a unit annotating the column name is used —
        ``"t [ms]"``, ``"x (um)"``, ``"disp_um"`` — and a time column without one is in
        seconds. Values are converted to SI (s, V, m, N, A); ``Record.units`` says from what.
        A unit the loader does not know, annotated in a name, is recorded and not converted.
    max_bytes : int, optional
        NPZ/MAT/HDF5: the bound on the (decompressed) size of one array, checked before it
        is read; default the environment variable ``PIEZOHYST_MAX_ARRAY_BYTES``, else 1 GiB.

    Returns
    -------
    Record

    Raises
    ------
    FileNotFoundError
        No such file.
    ValueError, TypeError
        Anything wrong with the arguments or the data — unknown column (the available
        ones are listed), index out of range, a cell that is not a number (line and
        column named), NaN/Inf (sample named), fewer than 2 samples, mismatched lengths,
        non-increasing or non-uniform time (index and steps named), ``fs`` missing,
        ``fs <= 0`` or disagreeing with ``time``, unsupported extension, corrupt file.
    ImportError
        An HDF5 or MATLAB v7.3 file without h5py installed.

    Examples
    --------
    The piezo micromanipulator record of ``../shared/data/piezo`` (tab-separated, no
    header, 200 Hz; its README's "column 1" (voltage) and "column 5" (sensor) are 0 and 4):

    >>> rec = load_record("../shared/data/piezo/yan9a_model_1hz.dat",
    ...                   input=0, output=4, fs=200)  # doctest: +SKIP
    >>> rec.n, rec.fs  # doctest: +SKIP
    (8027, 200.0)

    A CSV file with a header and a time column:

    >>> import tempfile, pathlib
    >>> f = pathlib.Path(tempfile.mkdtemp()) / "a.csv"
    >>> _ = f.write_text("time,u,y\\n0.0,0,0\\n0.5,1,2\\n1.0,2,3\\n")
    >>> load_record(f, input="u", output="y", time="time").fs
    2.0
    >>> load_record(f, input="v", output="y", fs=2.0)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    piezohyst.errors.DataError: ...a.csv: input = 'v' is not a column; the columns are ['time', 'u', 'y']
    """
    p = _check_path(path)
    specs = {
        "input": check_column_spec(input, "input"),
        "output": check_column_spec(output, "output"),
        "time": check_column_spec(time, "time"),
    }
    fs_given = None if fs is None else as_scalar(fs, "fs", positive=True)
    rtol = as_scalar(time_rtol, "time_rtol", positive=True)
    given_units = {"input": input_unit, "output": output_unit, "time": time_unit}
    for role, unit in given_units.items():
        if unit is not None:
            parse_unit(unit, role)
    limit = _max_bytes(max_bytes)
    if delimiter is not None:
        if not isinstance(delimiter, str):
            raise ParameterTypeError(f"delimiter must be a str, got {delimiter!r}")
        if not delimiter or "\n" in delimiter or "\r" in delimiter:
            raise ParameterError(f"delimiter = {delimiter!r} must be a non-empty separator without line breaks")
    if not (header is True or header is False or header == "auto"):
        if isinstance(header, str):
            raise ParameterError(f"header = {header!r} must be 'auto', True or False")
        raise ParameterTypeError(f"header must be 'auto', True or False, got {header!r}")
    if dataset is not None:
        if not isinstance(dataset, str):
            raise ParameterTypeError(f"dataset must be a str (a variable / dataset name), got {dataset!r}")
        if not dataset.strip():
            raise ParameterError(f"dataset = {dataset!r} may not be empty")
    if specs["time"] is None and fs_given is None:
        raise DataError(f"{p}: the sample rate is unknown: pass fs=<Hz> or time=<time column>")

    suffix = p.suffix.lower()
    if suffix in TEXT_SUFFIXES:
        if dataset is not None:
            raise ParameterError(f"dataset = {dataset!r} applies to NPZ/MAT/HDF5 files; {p} is a text file")
        return _assemble(TextTable(p, delimiter, header), specs, fs_given, rtol, given_units)
    else:
        if suffix not in SUPPORTED_SUFFIXES:
            raise DataError(f"{p}: unsupported file extension {p.suffix!r}; supported: {' '.join(SUPPORTED_SUFFIXES)}")
        if delimiter is not None or header != "auto":
            raise ParameterError(
                f"delimiter = {delimiter!r}, header = {header!r}: these apply to text files only, not {p.suffix!r}"
            )
        table: ColumnSource[Any]  # keys: column indices or array names
        if suffix in NPZ_SUFFIXES:
            table = open_npz(p, dataset, limit)
        elif suffix in NPY_SUFFIXES:
            table = open_npy(p, dataset, limit)
        elif suffix in MAT_SUFFIXES:
            table = open_mat(p, dataset, limit)
        elif suffix in PARQUET_SUFFIXES:
            table = open_parquet(p, dataset, limit)
        else:
            table = open_hdf5(p, dataset, limit=limit)
    try:
        return _assemble(table, specs, fs_given, rtol, given_units)  # type: ignore[misc]
    finally:
        table.close()


def _keys(columns: Sequence[tuple[Hashable, str]]) -> str:
    """The keys of columns, for a message: ``columns 1, 2`` or ``'u', 'v'``."""
    keys = [k for k, _ in columns]
    return "columns " + ", ".join(str(k) for k in keys) if all(isinstance(k, int) for k in keys) else repr(keys)


def _assemble(
    table: ColumnSource[_Key],
    specs: Mapping[str, ColumnSpec],
    fs_given: float | None,
    rtol: float,
    given_units: Mapping[str, str | None] | None = None,
) -> Record:
    src = table.source
    resolved: dict[str, tuple[_Key, str]] = {}
    for role in _ROLES:
        spec = specs[role]
        if spec is not None:
            resolved[role] = table.resolve(role, spec)
    missing = [r for r in ("input", "output") if r not in resolved]
    if missing:
        cols = table.columns()
        labels = [lab for _, lab in cols]
        for r in list(missing):
            hit = [(k, lab) for k, lab in cols if lab == r]
            if len(hit) > 1:  # never guess which: the header is ambiguous
                raise DataError(
                    f"{src}: {r} not given and the header names {len(hit)} columns {r!r} ({_keys(hit)}): "
                    f"ambiguous; pass {r}= a 0-based column index"
                )
            if len(hit) == 1 and hit[0][0] not in {k for k, _ in resolved.values()}:
                resolved[r] = hit[0]
                missing.remove(r)
        if missing:
            used = {k for k, _ in resolved.values()}
            free = [(k, lab) for k, lab in cols if k not in used]
            if len(free) != len(missing):
                raise DataError(
                    f"{src}: {missing[0]} not given and not inferable from the {len(cols)} columns "
                    f"{labels}; pass {missing[0]}= a column name or 0-based index"
                )
            names = [lab for _, lab in free]
            for r, (_k, lab) in zip(missing, free, strict=True):
                if names.count(lab) > 1 or (lab in _ROLES and lab != r):
                    why = (
                        f"{names.count(lab)} columns are named {lab!r}"
                        if names.count(lab) > 1
                        else (f"column {lab!r} would be taken as {r}")
                    )
                    raise DataError(
                        f"{src}: {', '.join(missing)} not given and {why} ({_keys(free)}): ambiguous; pass "
                        f"{'= and '.join(missing)}= column names or 0-based indices"
                    )
            for r, c in zip(missing, free, strict=False):
                resolved[r] = c
    seen: dict[_Key, str] = {}
    for role in _ROLES:
        if role in resolved:
            key, label = resolved[role]
            if key in seen:
                raise DataError(f"{src}: {seen[key]} and {role} are the same column {label!r}")
            seen[key] = role
    prepare = getattr(table, "prepare", None)
    if prepare is not None:  # a text table parses every column asked for in one pass
        prepare([resolved[role][0] for role in _ROLES if role in resolved])
    arrays = {role: table.read(role, *resolved[role]) for role in _ROLES if role in resolved}
    given = given_units or {}
    unit_of = getattr(table, "unit_of", None)  # a unit stored with the column in the file, if any
    units = {
        role: conversion_for(
            role, resolved[role][1], given.get(role), None if unit_of is None else unit_of(resolved[role][0])
        )
        for role in _ROLES
        if role in resolved
    }
    for role, conv in units.items():
        if conv.scale != 1.0:
            arrays[role] = arrays[role] * conv.scale
    n = arrays["input"].size
    for role in ("output", "time"):
        if role in arrays and arrays[role].size != n:
            raise DataError(
                f"{src}: {role} ({resolved[role][1]!r}) has {arrays[role].size} samples, input "
                f"({resolved['input'][1]!r}) has {n}: lengths must match"
            )
    if n < 2:
        raise DataError(f"{src}: input has {n} samples, at least 2 needed")
    fs = fs_given
    if "time" in arrays:
        try:
            fs_time = fs_from_time(arrays["time"], "time", rtol)
        except ValueError as e:
            raise DataError(f"{src}: {e}") from None
        if fs_given is not None and abs(fs_time - fs_given) > rtol * fs_given:
            raise DataError(
                f"{src}: fs = {fs_given:g} Hz disagrees with the time column {resolved['time'][1]!r}, which gives "
                f"{fs_time:.9g} Hz (relative difference {abs(fs_time - fs_given) / fs_given:.3g} > time_rtol = "
                f"{rtol:g}); pass only one of them, or fix the other"
            )
        if fs is None:
            fs = fs_time
    if fs is None:  # load_record asks for fs or a time column first
        raise DataError(f"{src}: the sample rate is unknown: pass fs=<Hz> or time=<time column>")
    columns = {role: resolved[role][1] for role in _ROLES if role in resolved}
    try:
        return Record(arrays["input"], arrays["output"], fs, arrays.get("time"), src, columns, units)
    except (ValueError, TypeError) as e:
        raise type(e)(f"{src}: {e}") from None


def load_yan9a_model_record(path: str | os.PathLike[str]) -> Record:
    """The measured 1 Hz record of a piezoelectric micromanipulator, ``yan9a_model_1hz.dat``.

    Provenance (``../shared/data/README.md``): MIT License, (c) 2019 Yan Naing Aye; from the
    public repository yan9a/DiscreteBacklashOperator (MatLabCode/DiscreteBacklashModel/,
    originally ``Model_Vi_Do.dat``), data of Y. N. Aye and W. T. Ang, "A Discrete Backlash
    Operator for Identification and Compensation of Hysteresis and Non-linearity for
    Piezoelectric Micromanipulator", 2018. Tab-separated text without header, 8027 x 7,
    sampled at 200 Hz; the README's column 1 (actuator input voltage, 0 ... 3.6 V, 1 Hz
    sine) is ``input`` (index 0) and its column 5 (capacitive displacement sensor, raw
    units, -123 ... -74, lower = plates closer) is ``output`` (index 4); the other columns
    are constant. The original scripts identify on one cycle starting at row 3152.

    Parameters
    ----------
    path : str or os.PathLike
        The file, e.g. ``../shared/data/piezo/yan9a_model_1hz.dat``.

    Returns
    -------
    Record
        ``fs = 200`` Hz, input in V, output in raw sensor units.

    Examples
    --------
    >>> rec = load_yan9a_model_record("../shared/data/piezo/yan9a_model_1hz.dat")  # doctest: +SKIP
    >>> rec.n, rec.fs, float(rec.input.min()), float(rec.input.max())  # doctest: +SKIP
    (8027, 200.0, 0.0, 3.6)
    """
    return load_record(path, input=0, output=4, fs=200.0, delimiter="\t", header=False)
