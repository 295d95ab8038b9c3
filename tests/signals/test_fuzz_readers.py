"""Fuzz targets, one per record reader (issue 20): CSV and other delimited text, NPY, NPZ,
MAT (v4/v5 and v7.3), HDF5, Parquet. Each mutates a small *valid* seed file of its format —
bytes flipped, runs of bytes inserted, cut, duplicated or overwritten with interesting values
(0x00, 0xff, huge and negative sizes), the file truncated — and loads it.

The property: ``load_record`` returns a valid record (finite, at least 2 samples, a positive
rate) or raises a :class:`piezohyst.PiezohystError` (``DataError`` ...): never another
exception, never a crash, never a hang (a watchdog kills the run after 60 s on one file and
prints where it hung), never a ``RuntimeWarning`` (overflow in a reader's arithmetic), and never
an allocation past ``max_bytes`` (16 MB here).

Budget: ``PIEZOHYST_FUZZ_EXAMPLES`` examples per test (default 300 in ``make test``: 600
mutated files over the ten seeds, about 8 s); hypothesis runs derandomized (a fixed seed per
test) without its example database, so a run is reproducible. 5000 per test (10,000 files,
two minutes) ran clean after the fixes its first runs called for. A file that once broke the property is kept under
``tests/data/fuzz_regressions/`` and replayed by :func:`test_fuzz_regressions`.
"""

from __future__ import annotations

import faulthandler
import json
import os
import shutil
import tempfile
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import scipy.io
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import piezohyst as ph
from piezohyst.data import load_record

try:
    import h5py
except ImportError:
    h5py = None

try:
    import pyarrow as pa
    import pyarrow.parquet as pq
except ImportError:
    pa = pq = None

EXAMPLES = int(os.environ.get("PIEZOHYST_FUZZ_EXAMPLES", "300"))
FUZZ = settings(
    max_examples=EXAMPLES,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
#: The decompressed-size bound of every fuzzed load (the readers check it before allocating).
MAX_BYTES = 16 * 2**20
REGRESSIONS = Path(__file__).resolve().parents[1] / "data" / "fuzz_regressions"

N = 64
_t = np.arange(N) / 100.0
_u = 1.5 + np.sin(2 * np.pi * 3 * _t)
_y = 0.7 * _u + 0.1 * np.cos(2 * np.pi * 3 * _t)


def _to_bytes(write: Callable[[Path], None], suffix: str) -> bytes:
    d = Path(tempfile.mkdtemp())
    try:
        p = d / f"seed{suffix}"
        write(p)
        return p.read_bytes()
    finally:
        shutil.rmtree(d, ignore_errors=True)


def _csv(p: Path) -> None:
    rows = zip(_t.tolist(), _u.tolist(), _y.tolist(), strict=True)
    p.write_text("t,u,y\n" + "".join(f"{a!r},{b!r},{c!r}\n" for a, b, c in rows))


def _csv_comma(p: Path) -> None:  # decimal comma, semicolons, a comment, CRLF
    rows = "".join(f"{a:.6f};{b:.9f};{c:.9f}\r\n".replace(".", ",") for a, b, c in zip(_t, _u, _y, strict=True))
    p.write_text("# exported by a scope\r\nt [s];u [V];y [um]\r\n" + rows)


def _npy(p: Path) -> None:
    np.save(p, np.column_stack([_t, _u, _y]))


def _npz(p: Path) -> None:
    np.savez_compressed(p, t=_t, u=_u, y=_y)


def _npz_plain(p: Path) -> None:
    np.savez(p, t=_t, u=_u.astype(np.float32), y=_y)


def _mat5(p: Path) -> None:
    scipy.io.savemat(p, {"t": _t, "u": _u, "y": _y.reshape(-1, 1), "s": {"v": _u}})


def _mat4(p: Path) -> None:
    scipy.io.savemat(p, {"u": _u, "y": _y}, format="4")


def _mat73(p: Path) -> None:
    with h5py.File(p, "w", userblock_size=512) as f:
        for name, a in (("t", _t), ("u", _u), ("y", _y)):
            ds = f.create_dataset(name, data=a.reshape(1, -1).T)
            ds.attrs["MATLAB_class"] = np.bytes_("double")
    with open(p, "r+b") as fh:
        fh.write(b"MATLAB 7.3 MAT-file, HDF5 schema 1.00 .".ljust(116, b" ") + b"\x00" * 8 + b"\x00\x02IM")


def _hdf5(p: Path) -> None:
    with h5py.File(p, "w") as f:
        f["run1/voltage"] = _u
        f["run1/voltage"].attrs["units"] = "V"
        f.create_dataset("run1/position", data=_y, compression="gzip", chunks=(16,))
        f["run1/time"] = _t


def _parquet(p: Path) -> None:
    pq.write_table(pa.table({"t": _t, "u": _u, "y": _y}), p)


#: name -> (writer, suffix, load_record keywords, needs)
TARGETS: dict[str, tuple[Callable[[Path], None], str, dict[str, object], object]] = {
    "csv": (_csv, ".csv", dict(input="u", output="y", time="t"), True),
    "csv-decimal-comma": (_csv_comma, ".txt", dict(input=1, output=2, time=0), True),
    "npy": (_npy, ".npy", dict(input=1, output=2, fs=100.0), True),
    "npz": (_npz, ".npz", dict(input="u", output="y", time="t"), True),
    "npz-stored": (_npz_plain, ".npz", dict(input="u", output="y", fs=100.0), True),
    "mat-v5": (_mat5, ".mat", dict(input="s.v", output="y", time="t"), True),
    "mat-v4": (_mat4, ".mat", dict(input="u", output="y", fs=100.0), True),
    "mat-v7.3": (_mat73, ".mat", dict(input="u", output="y", time="t"), h5py),
    "hdf5": (_hdf5, ".h5", dict(input="run1/voltage", output="run1/position", time="run1/time"), h5py),
    "parquet": (_parquet, ".parquet", dict(input="u", output="y", time="t"), pq),
}
AVAILABLE = sorted(name for name, (*_, needs) in TARGETS.items() if needs is not None)
SEEDS = {name: _to_bytes(TARGETS[name][0], TARGETS[name][1]) for name in AVAILABLE}

#: Byte strings a mutation writes: zeros, 0xff runs, sizes that overflow or go negative as
#: little- and big-endian integers, text a parser may take for a number, a header or a delimiter.
PIECES = [
    b"\x00",
    b"\xff",
    b"\x00" * 8,
    b"\xff" * 8,
    b"\x7f\xff\xff\xff",
    b"\xff\xff\xff\x7f",
    b"\x80\x00\x00\x00\x00\x00\x00\x00",
    b"\x00\x00\x00\x00\x00\x00\xf0\x7f",  # +inf (little-endian double)
    b"\x00\x00\x00\x00\x00\x00\xf8\x7f",  # NaN
    b"\x01\x00\x00\x00",
    (2**40).to_bytes(8, "little"),
    b"(100000000000, 3)",
    b"'<c16'",
    b"nan",
    b"1e999",
    b",",
    b";",
    b"\t",
    b"\r\n",
    b'"',
    b"\xef\xbb\xbf",
]


def _mutate(seed: bytes, data: st.DataObject) -> bytes:
    raw = bytearray(seed)
    for _ in range(data.draw(st.integers(1, 8), label="edits")):
        # half the edits land in the first 600 bytes: the headers, where a reader decides sizes
        near = data.draw(st.booleans(), label="header")
        end = min(len(raw), 600) if near else len(raw)
        pos = data.draw(st.integers(0, max(end, 0)), label="pos")
        kind = data.draw(st.sampled_from(["flip", "byte", "insert", "overwrite", "cut", "dup", "truncate"]))
        if kind == "flip" and pos < len(raw):
            raw[pos] ^= 1 << data.draw(st.integers(0, 7), label="bit")
        elif kind == "byte" and pos < len(raw):
            raw[pos] = data.draw(st.integers(0, 255), label="value")
        elif kind == "insert":
            raw[pos:pos] = data.draw(st.sampled_from(PIECES), label="piece")
        elif kind == "overwrite":
            piece = data.draw(st.sampled_from(PIECES), label="piece")
            raw[pos : pos + len(piece)] = piece
        elif kind == "cut":
            del raw[pos : pos + data.draw(st.integers(1, 64), label="n")]
        elif kind == "dup":
            n = data.draw(st.integers(1, 64), label="n")
            raw[pos:pos] = raw[pos : pos + n]
        else:
            del raw[pos:]
    return bytes(raw)


def _outcome(content: bytes, suffix: str, kwargs: dict[str, object]) -> str:
    """Load ``content`` as a file: "loaded" (and checked) or the PiezohystError's class name."""
    d = Path(tempfile.mkdtemp())
    p = d / f"x{suffix}"
    p.write_bytes(content)
    faulthandler.dump_traceback_later(60, exit=True)  # a hang kills the run, with the stacks
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", RuntimeWarning)  # overflow in a reader: not a warning on stderr
            warnings.filterwarnings("error", message=".*may be corrupt")  # data read as it may not be
            rec = load_record(p, max_bytes=MAX_BYTES, **kwargs)
    except ph.PiezohystError as e:
        assert str(e).strip(), "an error without a message"
        return type(e).__name__
    finally:
        faulthandler.cancel_dump_traceback_later()
        shutil.rmtree(d, ignore_errors=True)
    assert rec.n >= 2 and rec.input.size == rec.output.size == rec.n
    assert np.all(np.isfinite(rec.input)) and np.all(np.isfinite(rec.output))
    assert np.isfinite(rec.fs) and rec.fs > 0
    return "loaded"


@pytest.mark.parametrize("name", AVAILABLE)
def test_seed_files_load(name):
    _writer, suffix, kwargs, _needs = TARGETS[name]
    assert _outcome(SEEDS[name], suffix, kwargs) == "loaded"
    rec = load_record(_seed_path(name), **kwargs)
    scale = 1e-6 if name == "csv-decimal-comma" else 1.0  # its header says y [um]: read in m
    np.testing.assert_allclose(rec.output, _y * scale, rtol=1e-6)  # decimal-comma text keeps 9 digits


def _seed_path(name: str) -> Path:
    d = Path(tempfile.mkdtemp())
    p = d / f"seed{TARGETS[name][1]}"
    p.write_bytes(SEEDS[name])
    return p


@FUZZ
@given(name=st.sampled_from(AVAILABLE), data=st.data())
def test_fuzz_mutated_records(name, data):
    _writer, suffix, kwargs, _needs = TARGETS[name]
    _outcome(_mutate(SEEDS[name], data), suffix, kwargs)


@FUZZ
@given(name=st.sampled_from(AVAILABLE), data=st.data())
def test_fuzz_mutated_records_by_index_and_default_columns(name, data):
    """The same mutations read with other column choices: the defaults, a dataset matrix by
    index, the text header off."""
    _writer, suffix, _kwargs, _needs = TARGETS[name]
    kwargs = data.draw(
        st.sampled_from([dict(fs=100.0), dict(input=0, output=1, fs=100.0), dict(fs=100.0, header=False)]),
        label="kwargs",
    )
    if suffix not in (".csv", ".txt") and "header" in kwargs:
        kwargs = dict(fs=100.0)
    _outcome(_mutate(SEEDS[name], data), suffix, kwargs)


def test_fuzz_regressions():
    """Files that once broke the property (found by the targets above), replayed."""
    manifest = json.loads((REGRESSIONS / "cases.json").read_text())
    assert manifest, "the regression manifest is empty"
    for case in manifest:
        content = (REGRESSIONS / case["file"]).read_bytes()
        suffix = Path(case["file"]).suffix
        got = _outcome(content, suffix, case["kwargs"])
        assert got == case["expect"], (case["file"], got, case.get("was"))


# -- multi-channel data (issue 15): a mutated u_*.npy beside a valid y_*.npy, a mutated NPZ with u/y
_UM = np.stack([_u, -_u, 0.5 * _u], axis=1).reshape(N, 3, 1, 1) * np.ones((1, 1, 2, 2))
MULTI_SEEDS = {
    "npy": _to_bytes(lambda p: np.save(p, _UM), ".npy"),
    "npz": _to_bytes(lambda p: np.savez(p, u=_UM[:, :, 0, 0], y=1e-6 * _UM[:, :, 0, 0], fs=100.0), ".npz"),
    "npz-compressed": _to_bytes(lambda p: np.savez_compressed(p, u=_UM, y=_UM), ".npz"),
}


def _outcome_multi(content: bytes, kind: str) -> str:
    """Load mutated multi-channel data: "loaded" (and checked) or the PiezohystError's class name."""
    from piezohyst.signals import load_multichannel

    d = Path(tempfile.mkdtemp())
    if kind == "npy":
        (d / "u_a.npy").write_bytes(content)
        np.save(d / "y_a.npy", _UM)
        target = d
    else:
        target = d / "a.npz"
        target.write_bytes(content)
    faulthandler.dump_traceback_later(60, exit=True)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", RuntimeWarning)
            recs = load_multichannel(target, fs=100.0, max_bytes=MAX_BYTES)
    except ph.PiezohystError as e:
        assert str(e).strip(), "an error without a message"
        return type(e).__name__
    finally:
        faulthandler.cancel_dump_traceback_later()
        shutil.rmtree(d, ignore_errors=True)
    for rec in recs:
        assert rec.u.ndim == rec.y.ndim == 4 and rec.samples >= 2
        assert np.all(np.isfinite(rec.u)) and np.all(np.isfinite(rec.y))
    return "loaded"


@pytest.mark.parametrize("kind", sorted(MULTI_SEEDS))
def test_multichannel_seeds_load(kind):
    assert _outcome_multi(MULTI_SEEDS[kind], kind) == "loaded"


@FUZZ
@given(kind=st.sampled_from(sorted(MULTI_SEEDS)), data=st.data())
def test_fuzz_mutated_multichannel(kind, data):
    _outcome_multi(_mutate(MULTI_SEEDS[kind], data), kind)
