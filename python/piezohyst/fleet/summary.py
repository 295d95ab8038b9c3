"""Tables and figures of a fleet: robust outlier scores, the summary table (CSV and Parquet)
and the parameter-distribution report."""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from .._io import write_atomic

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["OUTLIER_Z", "flatten_parameters", "outliers", "robust_z", "write_table"]

#: |robust z| above which a value is an outlier (Iglewicz & Hoaglin's modified z-score cut-off).
OUTLIER_Z = 3.5


def robust_z(x: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """The modified z-score ``0.6745 (x - median) / MAD`` of each finite value (NaN elsewhere).

    The median absolute deviation (MAD) is 0 when more than half the values are equal; then a
    value off the median scores ``±inf`` and one on it 0.

    Parameters
    ----------
    x : array_like
        The values (NaN and infinities are left out of the median and the MAD).

    Returns
    -------
    numpy.ndarray
        The score of each value, NaN where the value is not finite.

    Examples
    --------
    >>> z = robust_z([1.0, 1.1, 0.9, 1.05, 0.95, 5.0])
    >>> [round(float(v), 2) for v in z]
    [-0.22, 0.67, -1.12, 0.22, -0.67, 35.75]
    """
    a = np.asarray(x, dtype=np.float64)
    out = np.full(a.shape, np.nan)
    ok = np.isfinite(a)
    if not ok.any():
        return out
    med = float(np.median(a[ok]))
    mad = float(np.median(np.abs(a[ok] - med)))
    dev = a[ok] - med
    if mad > 0:
        out[ok] = 0.6745 * dev / mad
    else:
        out[ok] = np.where(dev > 0, np.inf, np.where(dev < 0, -np.inf, 0.0))
    return out


def outliers(rows: Sequence[Mapping[str, Any]], columns: Sequence[str], cutoff: float = OUTLIER_Z) -> list[list[str]]:
    """For each row, the columns whose value is an outlier among the rows that have it
    (``|robust_z| > cutoff``), as ``"name (z = …)"`` strings. Needs 5 values of a column to judge it.

    Parameters
    ----------
    rows : sequence of mapping
        The records (a summary row each).
    columns : sequence of str
        The columns to judge (a row without a finite number there is not judged on it).
    cutoff : float, optional
        The ``|robust z|`` above which a value is an outlier (default :data:`OUTLIER_Z`, 3.5).

    Returns
    -------
    list of list of str
        Each row's flags, in the rows' order.

    Examples
    --------
    >>> from piezohyst.fleet import outliers
    >>> rows = [{"p.a": v} for v in (1.0, 1.1, 0.9, 1.05, 0.95, 5.0)]
    >>> outliers(rows, ["p.a"])
    [[], [], [], [], [], ['p.a (z = +35.7)']]
    """
    flags: list[list[str]] = [[] for _ in rows]
    for col in columns:
        idx = [i for i, r in enumerate(rows) if _finite(r.get(col))]
        if len(idx) < 5:
            continue
        z = robust_z([float(rows[i][col]) for i in idx])
        for i, zi in zip(idx, z, strict=True):
            if abs(zi) > cutoff:
                flags[i].append(f"{col} (z = {zi:+.3g})")
    return flags


def _finite(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def flatten_parameters(doc: Mapping[str, Any]) -> dict[str, float]:
    """A model file's numbers as flat columns ``p.<name>`` (``p.<name>[i]`` for lists): its
    ``parameters``, ``output_map``, and a stage file's ``mechanics`` and ``cemf``.

    Parameters
    ----------
    doc : mapping
        A model (or stage) file's JSON document.

    Returns
    -------
    dict of str to float
        Every number of those sections by its column name (booleans and strings are left out).

    Examples
    --------
    >>> from piezohyst.fleet import flatten_parameters
    >>> flatten_parameters({"kind": "boucwen", "parameters": {"a": 0.8, "n": 1, "weights": [0.5, 0.25]}})
    {'p.a': 0.8, 'p.n': 1.0, 'p.weights[0]': 0.5, 'p.weights[1]': 0.25}
    """
    out: dict[str, float] = {}

    def add(prefix: str, value: Any) -> None:
        if isinstance(value, bool):
            return
        if isinstance(value, (int, float)):
            out[prefix] = float(value)
        elif isinstance(value, Mapping):
            for k, v in value.items():
                add(f"{prefix}.{k}", v)
        elif isinstance(value, list):
            for i, v in enumerate(value):
                add(f"{prefix}[{i}]", v)

    for section in ("parameters", "output_map", "mechanics", "cemf"):
        if section in doc:
            add(f"p.{section}" if section != "parameters" else "p", doc[section])
    return out


def write_table(rows: Sequence[Mapping[str, Any]], columns: Sequence[str], csv_path: Path, parquet_path: Path) -> None:
    """The rows as CSV and as Parquet (pyarrow), both written atomically. Columns of numbers stay
    float64 (missing: empty in CSV, null in Parquet); the others are strings.

    Parameters
    ----------
    rows : sequence of mapping
        The rows (a missing key or None is a missing value).
    columns : sequence of str
        The columns, in order.
    csv_path : pathlib.Path
        Where the CSV goes.
    parquet_path : pathlib.Path
        Where the Parquet file goes.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> import pyarrow.parquet as pq
    >>> from piezohyst.fleet import write_table
    >>> rows = [{"record": "part00", "p.a": 0.8}, {"record": "part01", "p.a": None}]
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     write_table(rows, ["record", "p.a"], Path(tmp, "s.csv"), Path(tmp, "s.parquet"))
    ...     print(Path(tmp, "s.csv").read_text(), end="")
    ...     pq.read_table(Path(tmp, "s.parquet")).to_pydict()
    record,p.a
    part00,0.8
    part01,
    {'record': ['part00', 'part01'], 'p.a': [0.8, None]}
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    numeric = {c for c in columns if all(r.get(c) is None or _number(r.get(c)) for r in rows)}
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(columns)
    for r in rows:
        w.writerow(["" if r.get(c) is None else (repr(float(r[c])) if c in numeric else r[c]) for c in columns])
    write_atomic(csv_path, buf.getvalue(), name="summary.csv")
    arrays = {}
    for c in columns:
        vals = [r.get(c) for r in rows]
        if c in numeric:
            arrays[c] = pa.array([None if v is None else float(v) for v in vals], type=pa.float64())
        else:
            arrays[c] = pa.array([None if v is None else str(v) for v in vals], type=pa.string())
    table = pa.table(arrays)
    write_atomic(parquet_path, writer=lambda tmp: pq.write_table(table, tmp), name="summary.parquet")


def _number(v: Any) -> bool:
    return isinstance(v, (int, float, np.floating, np.integer)) and not isinstance(v, bool)


def distribution_figure(
    rows: Sequence[Mapping[str, Any]], columns: Sequence[str], title: str, cutoff: float = OUTLIER_Z
) -> Figure:
    """One panel per column: each row's value as a dot over a box plot (median, quartiles), the
    outliers (``|robust z| > cutoff``) in red and labelled with the row's ``record`` name."""
    import matplotlib.pyplot as plt

    # columns that vary (a parameter every record shares, such as Bouc-Wen's n = 1, says nothing)
    cols = [c for c in columns if len({float(r[c]) for r in rows if _finite(r.get(c))}) > 1]
    n = max(1, len(cols))
    ncol = min(4, n)
    nrow = math.ceil(n / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(3.2 * ncol, 2.6 * nrow + 0.6), squeeze=False)
    for ax in axes.flat[n:]:
        ax.set_visible(False)
    rng = np.random.default_rng(0)  # fixed horizontal jitter: the same figure for the same fleet
    for ax, col in zip(axes.flat, cols, strict=False):
        idx = [i for i, r in enumerate(rows) if _finite(r.get(col))]
        vals = np.array([float(rows[i][col]) for i in idx])
        z = robust_z(vals) if len(vals) >= 5 else np.zeros(len(vals))
        bad = np.abs(z) > cutoff
        ax.boxplot(vals, vert=True, widths=0.5, showfliers=False)
        x = 1 + 0.12 * rng.uniform(-1, 1, len(vals))
        ax.plot(x[~bad], vals[~bad], "o", ms=3, alpha=0.6, color="tab:blue")
        ax.plot(x[bad], vals[bad], "o", ms=5, color="tab:red")
        for xi, vi, i in zip(x[bad], vals[bad], np.asarray(idx)[bad], strict=True):
            ax.annotate(
                str(rows[i].get("record", i)),
                (xi, vi),
                fontsize=6,
                color="tab:red",
                xytext=(3, 0),
                textcoords="offset points",
            )
        ax.set_title(col, fontsize=8)
        ax.set_xticks([])
        ax.tick_params(labelsize=7)
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    return fig
