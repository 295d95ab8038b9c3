"""The Bouc–Wen hysteretic benchmark (Noël & Schoukens 2016) as a workflow: its training
record's reader, with the model (:mod:`piezohyst.models.boucwen_benchmark`) and its
identification (:mod:`piezohyst.identify.boucwen_benchmark`) re-exported, so this module
holds everything the former ``piezohyst.boucwen_benchmark`` did (that path is an alias of
this module).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import numpy.typing as npt

from ..errors import DataError
from ..identify.boucwen_benchmark import DEFAULT_BOUNDS, IDENTIFY_PARAMETERS, identify_boucwen_benchmark
from ..models.boucwen_benchmark import FS, INTERPOLATIONS, UPSAMPLE, BoucWenBenchmark, decimate, upsample

__all__ = [
    "DEFAULT_BOUNDS",
    "FS",
    "IDENTIFY_PARAMETERS",
    "INTERPOLATIONS",
    "UPSAMPLE",
    "BoucWenBenchmark",
    "decimate",
    "identify_boucwen_benchmark",
    "load_train_multisine",
    "upsample",
]


def load_train_multisine(path: str | Path) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], float]:
    """The benchmark's training record (``train_multisine.csv`` of forgi86/dynonet,
    header ``u,y``: 5 periods x 8192 samples, u in N, y in m).

    Parameters
    ----------
    path : str or pathlib.Path
        The CSV file (a header ``u,y``, then one sample per line).

    Returns
    -------
    u, y : numpy.ndarray
        Force (N) and displacement (m).
    fs : float
        750.0 Hz.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from piezohyst import load_train_multisine
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "train_multisine.csv"
    >>> _ = path.write_text("u,y\\n1.5,2e-6\\n-3.0,1e-6\\n")
    >>> u, y, fs = load_train_multisine(path)
    >>> u.tolist(), y.tolist(), fs
    ([1.5, -3.0], [2e-06, 1e-06], 750.0)
    """
    path = Path(path)
    with path.open() as fh:
        header = fh.readline().strip().replace(" ", "").lower()
        if header != "u,y":
            raise DataError(f"{path}: header = {header!r}, expected 'u,y'")
        data = np.loadtxt(fh, delimiter=",", dtype=np.float64, ndmin=2)
    if data.shape[1] != 2 or data.shape[0] == 0:
        raise DataError(f"{path}: data has shape {data.shape}, expected (N, 2) with N > 0")
    u = np.ascontiguousarray(data[:, 0])
    y = np.ascontiguousarray(data[:, 1])
    for name, a in (("u", u), ("y", y)):
        bad = np.flatnonzero(~np.isfinite(a))
        if bad.size:
            raise DataError(f"{path}: {name}[{bad[0]}] = {a[bad[0]]} is not finite")
    return u, y, FS
