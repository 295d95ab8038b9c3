"""Data loading (issue 4 item 4; docs/spec.md §8 data, §10 bad input): Record, load_record and the
real records of ../shared/data."""

import dataclasses
import os
import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest
import scipy.io
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import piezohyst as ph
from piezohyst.data import H5PY_HINT, Record, load_record, load_yan9a_model_record

try:
    import h5py
except ImportError:
    h5py = None

needs_h5py = pytest.mark.skipif(h5py is None, reason=H5PY_HINT)

DATA = Path(__file__).resolve().parents[2].parent / "shared" / "data"
YAN9A_MODEL = DATA / "piezo" / "yan9a_model_1hz.dat"
YAN9A_TEST = DATA / "piezo" / "yan9a_test.dat"
MULTISINE = DATA / "boucwen" / "train_multisine.csv"


def _skip_missing(path):
    return pytest.mark.skipif(not path.exists(), reason=f"{path} is not present (shared data lives outside the repo)")


def signals(n=50, fs=200.0):
    k = np.arange(n)
    t = k / fs
    u = 1.5 + np.sin(2 * np.pi * 3 * t)
    y = 0.7 * u + 0.1 * np.cos(2 * np.pi * 3 * t)
    return t, u, y


def write_csv(path, header, columns, delimiter=",", fmt="{!r}"):
    lines = [] if header is None else [delimiter.join(header)]
    for row in zip(*columns, strict=False):
        lines.append(delimiter.join(fmt.format(float(v)) for v in row))
    path.write_text("\n".join(lines) + "\n")
    return path


# ----------------------------------------------------------------------------- round trips


def test_csv_with_header_by_name(tmp_path):
    t, u, y = signals()
    f = write_csv(tmp_path / "run.csv", ["t", "u", "y"], [t, u, y])
    rec = load_record(f, input="u", output="y", time="t")
    np.testing.assert_array_equal(rec.input, u)
    np.testing.assert_array_equal(rec.output, y)
    np.testing.assert_array_equal(rec.time, t)
    assert rec.fs == pytest.approx(200.0, rel=1e-12)
    assert rec.n == len(rec) == 50
    assert rec.duration == pytest.approx(50 / 200.0)
    assert rec.columns == {"input": "u", "output": "y", "time": "t"}
    assert rec.source == str(f)
    # by index in the same file, fs given instead of time
    rec2 = load_record(f, input=1, output=2, fs=200)
    np.testing.assert_array_equal(rec2.input, u)
    assert rec2.time is None and rec2.fs == 200.0
    assert rec2.columns == {"input": "u", "output": "y"}


def test_tsv_without_header_by_index(tmp_path):
    _t, u, y = signals()
    other = np.full_like(u, 7.0)
    f = write_csv(tmp_path / "run.tsv", None, [u, other, other, other, y, other], delimiter="\t")
    rec = load_record(f, input=0, output=4, fs=200.0)
    np.testing.assert_array_equal(rec.input, u)
    np.testing.assert_array_equal(rec.output, y)
    assert rec.columns == {"input": "column 0", "output": "column 4"}
    # explicit delimiter and header=False give the same
    rec2 = load_record(f, input=0, output=4, fs=200.0, delimiter="\t", header=False)
    np.testing.assert_array_equal(rec2.output, y)


def test_whitespace_separated_with_comments_and_crlf(tmp_path):
    t, u, y = signals(20)
    body = "".join(f"  {a!r}   {b!r}  {c!r}  \r\n" for a, b, c in zip(t.tolist(), u.tolist(), y.tolist(), strict=False))
    f = tmp_path / "run.txt"
    f.write_bytes(("% exported by a scope\n# time voltage position\n" + body + "\n\n").encode())
    rec = load_record(f, input="voltage", output="position", time="time")  # names from the '#' line
    np.testing.assert_array_equal(rec.input, u)
    np.testing.assert_array_equal(rec.output, y)
    assert rec.fs == pytest.approx(200.0)
    rec2 = load_record(f, input=1, output=2, fs=200.0, delimiter=" ", header=False)
    np.testing.assert_array_equal(rec2.output, y)


def test_savetxt_round_trip_and_semicolons(tmp_path):
    t, u, y = signals()
    f = tmp_path / "a.dat"
    np.savetxt(f, np.column_stack([t, u, y]), header="t u y", fmt="%.17g")
    rec = load_record(f, input="u", output="y", time="t")
    np.testing.assert_array_equal(rec.output, y)
    g = write_csv(tmp_path / "b.csv", ['"u"', '"y"'], [u, y], delimiter=";")
    rec = load_record(g, fs=200)  # two columns: input and output inferred, quotes stripped
    assert rec.columns == {"input": "u", "output": "y"}
    np.testing.assert_array_equal(rec.input, u)


def test_default_columns(tmp_path):
    t, u, y = signals()
    f = write_csv(tmp_path / "a.csv", ["aux", "output", "input"], [t, y, u])
    rec = load_record(f, fs=200)  # named input/output
    np.testing.assert_array_equal(rec.input, u)
    np.testing.assert_array_equal(rec.output, y)
    g = write_csv(tmp_path / "b.csv", ["t", "v", "x"], [t, u, y])
    rec = load_record(g, time="t")  # the two columns besides time
    assert rec.columns == {"input": "v", "output": "x", "time": "t"}
    rec = load_record(g, input="x", time="t")  # output: the one column left
    assert rec.columns == {"input": "x", "output": "v", "time": "t"}
    with pytest.raises(ValueError, match=r"output not given and not inferable from the 3 columns \['t', 'v', 'x'\]"):
        load_record(g, input="x", fs=200)  # two candidates left for one role


def test_npz_by_key_and_matrix(tmp_path):
    t, u, y = signals()
    f = tmp_path / "a.npz"
    np.savez(f, voltage=u, position=y.reshape(-1, 1), t=t, data=np.column_stack([t, u, y]), fs=200.0)
    rec = load_record(f, input="voltage", output="position", time="t")
    np.testing.assert_array_equal(rec.input, u)
    np.testing.assert_array_equal(rec.output, y)
    assert rec.fs == pytest.approx(200.0)
    rec = load_record(f, dataset="data", input=1, output=2, time=0)
    np.testing.assert_array_equal(rec.output, y)
    assert rec.columns == {"input": "data[:, 1]", "output": "data[:, 2]", "time": "data[:, 0]"}
    # mixing a matrix column and a named array
    rec = load_record(f, dataset="data", input=1, output="position", fs=200)
    np.testing.assert_array_equal(rec.output, y)
    g = tmp_path / "b.npz"
    np.savez_compressed(g, input=u, output=y)
    rec = load_record(g, fs=200)  # default keys
    np.testing.assert_array_equal(rec.input, u)


def test_npy_matrix(tmp_path):
    _t, u, y = signals()
    f = tmp_path / "a.npy"
    np.save(f, np.column_stack([u, y]).astype(np.float32))
    rec = load_record(f, fs=200)
    np.testing.assert_array_equal(rec.input, u.astype(np.float32).astype(np.float64))
    assert rec.columns == {"input": "array[:, 0]", "output": "array[:, 1]"}


def test_mat_v5(tmp_path):
    t, u, y = signals()
    f = tmp_path / "a.mat"
    scipy.io.savemat(
        f,
        {
            "u": u,  # stored as a 1 x N row
            "y": y.reshape(-1, 1),  # N x 1 column
            "t": t,
            "data": np.column_stack([t, u, y]),  # N x 3 matrix
            "s": {"volts": u, "microns": y},  # struct
            "note": "a string",
        },
    )
    rec = load_record(f, input="u", output="y", time="t")
    np.testing.assert_array_equal(rec.input, u)
    np.testing.assert_array_equal(rec.output, y)
    assert rec.fs == pytest.approx(200.0)
    rec = load_record(f, dataset="data", input=1, output=2, fs=200.0)
    np.testing.assert_array_equal(rec.output, y)
    rec = load_record(f, input="s.volts", output="s/microns", fs=200.0)
    np.testing.assert_array_equal(rec.input, u)
    np.testing.assert_array_equal(rec.output, y)
    with pytest.raises(
        ValueError,
        match=r"input = 'v' is not in the file; the numeric MAT variables are \['data', "
        r"'s.microns', 's.volts', 't', 'u', 'y'\]",
    ):
        load_record(f, input="v", output="y", fs=1)
    # v4 files also load
    g = tmp_path / "b.mat"
    scipy.io.savemat(g, {"u": u, "y": y}, format="4")
    np.testing.assert_array_equal(load_record(g, input="u", output="y", fs=200).output, y)


def write_mat73(path, variables):
    """A MATLAB v7.3 file as MATLAB writes it: HDF5 with a 512-byte user block holding the
    MAT header, arrays stored column-major (transposed for h5py), structs as groups."""

    def put(group, name, value):
        if isinstance(value, dict):
            g = group.create_group(name)
            g.attrs["MATLAB_class"] = np.bytes_("struct")
            for k, v in value.items():
                put(g, k, v)
        elif isinstance(value, str):
            ds = group.create_dataset(name, data=np.frombuffer(value.encode("utf-16-le"), np.uint16).reshape(-1, 1))
            ds.attrs["MATLAB_class"] = np.bytes_("char")
        else:
            a = np.asarray(value, dtype=np.float64)
            a = a.reshape(1, -1) if a.ndim == 1 else a  # MATLAB vectors are 1 x N
            ds = group.create_dataset(name, data=a.T)
            ds.attrs["MATLAB_class"] = np.bytes_("double")

    with h5py.File(path, "w", userblock_size=512) as f:
        for k, v in variables.items():
            put(f, k, v)
    text = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Jan  1 00:00:00 2024 HDF5 schema 1.00 ."
    with open(path, "r+b") as fh:
        fh.write(text.ljust(116, b" ") + b"\x00" * 8 + b"\x00\x02IM")


@needs_h5py
def test_mat_v73(tmp_path):
    t, u, y = signals()
    f = tmp_path / "a.mat"
    write_mat73(f, {"u": u, "y": y, "t": t, "data": np.column_stack([t, u, y]), "s": {"volts": u}, "name": "run"})
    rec = load_record(f, input="u", output="y", time="t")
    np.testing.assert_array_equal(rec.input, u)
    np.testing.assert_array_equal(rec.output, y)
    assert rec.fs == pytest.approx(200.0)
    rec = load_record(f, dataset="data", input=1, output=2, fs=200.0)  # MATLAB's N x 3 orientation
    np.testing.assert_array_equal(rec.input, u)
    np.testing.assert_array_equal(rec.output, y)
    rec = load_record(f, input="s.volts", output="y", fs=200.0)
    np.testing.assert_array_equal(rec.input, u)
    with pytest.raises(
        ValueError,
        match=r"input = 'v' is not in the file; the numeric MATLAB v7.3 variables are "
        r"\['data', 's.volts', 't', 'u', 'y'\]",
    ):
        load_record(f, input="v", output="y", fs=200.0)
    with pytest.raises(TypeError, match=r"input = 'name' must hold real numbers"):
        load_record(f, input="name", output="y", fs=200.0)
    with pytest.raises(ValueError, match=r"input = 's' is not in the file"):  # a struct (group), not an array
        load_record(f, input="s", output="y", fs=200.0)


@needs_h5py
def test_hdf5_dataset_paths(tmp_path):
    t, u, y = signals()
    f = tmp_path / "a.h5"
    with h5py.File(f, "w") as h:
        h["run1/voltage"] = u
        h["run1/position"] = y
        h["run1/time"] = t
        h["matrix"] = np.column_stack([t, u, y])
        h["bad"] = np.array([1 + 1j, 2])
    rec = load_record(f, input="run1/voltage", output="run1/position", time="run1/time")
    np.testing.assert_array_equal(rec.input, u)
    np.testing.assert_array_equal(rec.output, y)
    rec = load_record(f, dataset="matrix", input=1, output=2, fs=200.0)
    np.testing.assert_array_equal(rec.output, y)
    with pytest.raises(
        ValueError,
        match=r"output = 'run1' is not in the file; the numeric HDF5 variables are "
        r"\['matrix', 'run1/position', 'run1/time', 'run1/voltage'\]",
    ):
        load_record(f, input="run1/voltage", output="run1", fs=1.0)
    with pytest.raises(TypeError, match=r"output = 'bad' must hold real numbers, got dtype complex128"):
        load_record(f, input="run1/voltage", output="bad", fs=1.0)
    g = tmp_path / "junk.hdf5"
    g.write_bytes(b"not an hdf5 file at all" * 10)
    with pytest.raises(ValueError, match="not a readable HDF5 file"):
        load_record(g, input="a", output="b", fs=1.0)


def test_hdf5_and_mat73_without_h5py(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "h5py", None)  # import h5py -> ImportError
    f = tmp_path / "a.h5"
    f.write_bytes(b"\x89HDF\r\n\x1a\n" + bytes(100))
    with pytest.raises(ImportError, match=r"reading HDF5 / MATLAB v7.3 needs h5py: pip install h5py"):
        load_record(f, input="u", output="y", fs=1.0)
    g = tmp_path / "b.mat"  # a v7.3 header is recognised before h5py is needed
    g.write_bytes(b"MATLAB 7.3 MAT-file".ljust(116, b" ") + bytes(8) + b"\x00\x02IM" + bytes(400))
    with pytest.raises(ImportError, match="needs h5py: pip install h5py"):
        load_record(g, input="u", output="y", fs=1.0)


# ----------------------------------------------------------------------------- time and fs


def test_time_column_gives_fs_and_fs_wins_when_they_agree(tmp_path):
    t, u, y = signals(100, fs=750.0)
    f = write_csv(tmp_path / "a.csv", ["t", "u", "y"], [t, u, y])
    assert load_record(f, input="u", output="y", time="t").fs == pytest.approx(750.0, rel=1e-12)
    rec = load_record(f, input="u", output="y", time="t", fs=750)
    assert rec.fs == 750.0
    np.testing.assert_array_equal(rec.time, t)


def test_non_uniform_time_names_index_and_steps(tmp_path):
    t, u, y = signals(10, fs=100.0)
    t = t.copy()
    t[6:] += 0.002  # a late sample: step 5 -> 6 is 0.012 s instead of 0.01 s
    f = write_csv(tmp_path / "a.csv", ["t", "u", "y"], [t, u, y])
    with pytest.raises(
        ValueError,
        match=r"a\.csv: time is not uniformly sampled: the step at index 5 \(time\[6\] - time\[5\] = 0\.012 s\) "
        r"differs from the median step 0\.01 s by 0\.2 relative \(time_rtol = 1e-06\); resample the record first",
    ):
        load_record(f, input="u", output="y", time="t")
    # and giving fs does not paper over it
    with pytest.raises(ValueError, match="not uniformly sampled"):
        load_record(f, input="u", output="y", time="t", fs=100.0)


def test_non_increasing_time(tmp_path):
    t, u, y = signals(10, fs=100.0)
    t = t.copy()
    t[4] = t[3]
    f = write_csv(tmp_path / "a.csv", ["t", "u", "y"], [t, u, y])
    with pytest.raises(
        ValueError, match=r"time is not strictly increasing: time\[4\] = 0\.03 follows time\[3\] = 0\.03"
    ):
        load_record(f, input="u", output="y", time="t")


def test_fs_and_time_disagree(tmp_path):
    t, u, y = signals(20, fs=200.0)
    f = write_csv(tmp_path / "a.csv", ["t", "u", "y"], [t, u, y])
    with pytest.raises(ValueError, match=r"fs = 100 Hz disagrees with the time column 't', which gives 200 Hz"):
        load_record(f, input="u", output="y", time="t", fs=100.0)
    with pytest.raises(ValueError, match=r"fs = 200\.01 Hz disagrees"):
        load_record(f, input="u", output="y", time="t", fs=200.01)


def test_rounded_time_stamps_need_a_looser_tolerance(tmp_path):
    t, u, y = signals(300, fs=750.0)
    f = tmp_path / "a.csv"
    f.write_text(
        "t,u,y\n"
        + "".join(f"{a:.7f},{b!r},{c!r}\n" for a, b, c in zip(t.tolist(), u.tolist(), y.tolist(), strict=False))
    )
    with pytest.raises(ValueError, match="not uniformly sampled"):
        load_record(f, input="u", output="y", time="t")
    rec = load_record(f, input="u", output="y", time="t", time_rtol=1e-3)
    assert rec.fs == pytest.approx(750.0, rel=1e-6)


# ----------------------------------------------------------------------------- bad input


@pytest.fixture
def files(tmp_path):
    t, u, y = signals(10)
    out = {"csv": write_csv(tmp_path / "good.csv", ["t", "u", "y"], [t, u, y])}

    def text(name, content):
        p = tmp_path / name
        p.write_text(content)
        return p

    out["bad_cell"] = text("bad_cell.csv", "t,u,y\n0,1,2\n1,2,3\n2,3,abc\n3,4,5\n")
    out["nan"] = text("nan.csv", "t,u,y\n0,1,2\n1,2,nan\n2,3,4\n")
    out["inf"] = text("inf.tsv", "0\t1\n1\t-inf\n2\t3\n")
    out["empty"] = text("empty.csv", "")
    out["blank"] = text("blank.csv", "\n  \n")
    out["comments"] = text("comments.csv", "# nothing\n% here\n")
    out["header_only"] = text("header_only.csv", "t,u,y\n")
    out["one_row"] = text("one_row.csv", "t,u,y\n0,1,2\n")
    out["ragged"] = text("ragged.csv", "t,u,y\n0,1,2\n1,2\n")
    out["xlsx"] = text("data.xlsx", "whatever")
    out["three"] = text("three.csv", "a,b,c\n0,1,2\n1,2,3\n")
    (tmp_path / "binary.csv").write_bytes(b"PK\x03\x04\x00\x00binary")
    out["binary"] = tmp_path / "binary.csv"
    np.savez(
        tmp_path / "a.npz",
        u=np.arange(10.0),
        y=np.arange(9.0),
        m=np.ones((5, 3)),
        z=np.ones(4) * 1j,
        s=np.float64(3.0),
        n=np.array([0, 1, 2, np.nan, 4]),
        v=np.arange(5.0),
    )
    out["npz"] = tmp_path / "a.npz"
    (tmp_path / "corrupt.npz").write_bytes(b"PK\x03\x04 this is not a zip archive")
    out["corrupt_npz"] = tmp_path / "corrupt.npz"
    (tmp_path / "corrupt.mat").write_bytes(b"MATLAB 5.0 MAT-file" + bytes(10))
    out["corrupt_mat"] = tmp_path / "corrupt.mat"
    out["dir"] = tmp_path
    return out


BAD = [
    # (file key, kwargs, exception, message regex)
    (
        "csv",
        dict(input="v", output="y", fs=1),
        ValueError,
        r"good\.csv: input = 'v' is not a column; the columns are \['t', 'u', 'y'\]",
    ),
    (
        "csv",
        dict(input="u", output=3, fs=1),
        ValueError,
        r"output = 3 is out of range: the file has 3 columns \(0-based indices 0\.\.2\)",
    ),
    ("csv", dict(input=-1, output=2, fs=1), ValueError, r"input = -1: column indices are 0-based and must be >= 0"),
    (
        "csv",
        dict(input=1.0, output=2, fs=1),
        TypeError,
        r"input must be a column name \(str\) or a 0-based column index \(int\), got 1\.0",
    ),
    ("csv", dict(input=True, output=2, fs=1), TypeError, r"input must be a column name"),
    ("csv", dict(input="", output=2, fs=1), ValueError, r"input = '': a column name may not be empty"),
    (
        "csv",
        dict(input="u", output="y"),
        ValueError,
        r"good\.csv: the sample rate is unknown: pass fs=<Hz> or time=<time column>",
    ),
    ("csv", dict(input="u", output="y", fs=0), ValueError, r"fs = 0\.0 must be > 0"),
    ("csv", dict(input="u", output="y", fs=-200.0), ValueError, r"fs = -200\.0 must be > 0"),
    ("csv", dict(input="u", output="y", fs=np.nan), ValueError, r"fs = nan is not finite"),
    ("csv", dict(input="u", output="y", fs="200"), TypeError, r"fs must be a real number, got '200'"),
    ("csv", dict(input="u", output="y", time="t", time_rtol=0), ValueError, r"time_rtol = 0\.0 must be > 0"),
    (
        "csv",
        dict(input="u", output="y", fs=1, header="yes"),
        ValueError,
        r"header = 'yes' must be 'auto', True or False",
    ),
    ("csv", dict(input="u", output="y", fs=1, header=1), TypeError, r"header must be 'auto', True or False, got 1"),
    (
        "csv",
        dict(input="u", output="y", fs=1, delimiter=""),
        ValueError,
        r"delimiter = '' must be a non-empty separator",
    ),
    ("csv", dict(input="u", output="y", fs=1, delimiter=44), TypeError, r"delimiter must be a str, got 44"),
    ("csv", dict(input="u", output="y", fs=1, dataset="m"), ValueError, r"dataset = 'm' applies to NPZ/MAT/HDF5 files"),
    ("csv", dict(input="u", output="y", fs=1, dataset=3), TypeError, r"dataset must be a str"),
    ("csv", dict(input="u", output="u", fs=1), ValueError, r"input and output are the same column 'u'"),
    ("csv", dict(input="u", output="y", time="u", fs=1), ValueError, r"input and time are the same column 'u'"),
    (
        "csv",
        dict(input=0, output=1, fs=1, header=False),
        ValueError,
        r"line 1 \(sample 0\), input column 'column 0' \(index 0\): 't' is not a number",
    ),
    ("three", dict(fs=1), ValueError, r"input not given and not inferable from the 3 columns \['a', 'b', 'c'\]"),
    ("three", dict(input="a", fs=1), ValueError, r"output not given and not inferable"),
    (
        "bad_cell",
        dict(input="u", output="y", fs=1),
        ValueError,
        r"bad_cell\.csv: line 4 \(sample 2\), output column 'y' \(index 2\): 'abc' is not a number",
    ),
    (
        "bad_cell",
        dict(input=1, output=0, fs=1, header=False),
        ValueError,
        r"line 1 \(sample 0\), input column 'column 1'",
    ),
    (
        "nan",
        dict(input="u", output="y", fs=1),
        ValueError,
        r"nan\.csv: output\[1\] = nan is not finite \(line 3, column 'y'\)",
    ),
    (
        "inf",
        dict(input=0, output=1, fs=1),
        ValueError,
        r"output\[1\] = -inf is not finite \(line 2, column 'column 1'\)",
    ),
    ("empty", dict(input=0, output=1, fs=1), ValueError, r"empty\.csv: is empty"),
    ("blank", dict(input=0, output=1, fs=1), ValueError, r"blank\.csv: is empty"),
    ("comments", dict(input=0, output=1, fs=1), ValueError, r"has no data lines \(only comments\)"),
    ("header_only", dict(input="u", output="y", fs=1), ValueError, r"header_only\.csv: has no data rows"),
    ("one_row", dict(input="u", output="y", fs=1), ValueError, r"one_row\.csv: input has 1 samples, at least 2 needed"),
    ("ragged", dict(input="u", output="y", fs=1), ValueError, r"line 3 has 2 fields, expected 3 as on the header"),
    (
        "xlsx",
        dict(input=0, output=1, fs=1),
        ValueError,
        r"data\.xlsx: unsupported file extension '\.xlsx'; supported: \.csv",
    ),
    ("binary", dict(input=0, output=1, fs=1), ValueError, r"contains NUL bytes: a binary file, not delimited text"),
    ("dir", dict(input=0, output=1, fs=1), ValueError, r"is a directory, not a data file"),
    (
        "npz",
        dict(input="u", output="y", fs=1),
        ValueError,
        r"output \('y'\) has 9 samples, input \('u'\) has 10: lengths must match",
    ),
    (
        "npz",
        dict(input="q", output="y", fs=1),
        ValueError,
        r"input = 'q' is not in the file; the numeric NPZ variables are \['m', 'n', 's', 'u', 'v', 'y'\]",
    ),
    (
        "npz",
        dict(input=0, output=1, fs=1),
        ValueError,
        r"input = 0 is a column index, which needs dataset = <name of a 2-D matrix>",
    ),
    (
        "npz",
        dict(input="m", output="u", fs=1),
        ValueError,
        r"input = 'm' has shape \(5, 3\), not a 1-D signal; for a matrix pass dataset='m'",
    ),
    ("npz", dict(input="z", output="u", fs=1), TypeError, r"input = 'z' must hold real numbers, got dtype complex128"),
    ("npz", dict(input="s", output="u", fs=1), ValueError, r"input = 's' is a scalar"),
    ("npz", dict(input="n", output="v", fs=1), ValueError, r"input\[3\] = nan is not finite \('n'\)"),
    (
        "npz",
        dict(dataset="u", input=0, output=1, fs=1),
        ValueError,
        r"dataset = 'u' has shape \(10,\), expected a 2-D matrix",
    ),
    (
        "npz",
        dict(dataset="m", input=0, output=3, fs=1),
        ValueError,
        r"output = 3 is out of range: dataset 'm' has shape \(5, 3\), 3 columns \(0-based indices 0\.\.2\)",
    ),
    ("npz", dict(input="u", output="y", fs=1, delimiter=","), ValueError, r"these apply to text files only"),
    ("corrupt_npz", dict(input="u", output="y", fs=1), ValueError, r"corrupt\.npz: not a readable NPZ archive"),
    ("corrupt_mat", dict(input="u", output="y", fs=1), ValueError, r"corrupt\.mat: not a"),
]


@pytest.mark.parametrize("key,kwargs,kind,message", BAD)
def test_bad_input_names_argument_and_value(files, key, kwargs, kind, message):
    with pytest.raises(kind, match=message):
        load_record(files[key], **kwargs)


def test_missing_file_and_bad_path(tmp_path):
    missing = tmp_path / "nope" / "run.csv"
    with pytest.raises(FileNotFoundError, match=r"nope/run\.csv: no such file"):
        load_record(missing, input=0, output=1, fs=1.0)
    with pytest.raises(TypeError, match="path must be a str or os.PathLike, got int"):
        load_record(3, input=0, output=1, fs=1.0)


def test_duplicate_column_names_are_never_guessed(tmp_path):
    """A header ``input,input``: asked by name, or left to the defaults, the ambiguity is an
    error naming the columns (issue 20); by index it loads."""
    t, u, y = signals()
    p = write_csv(tmp_path / "dup.csv", ["t", "input", "input"], [t, u, y])
    with pytest.raises(ph.DataError, match=r"input = 'input' names columns \[1, 2\]"):
        load_record(p, input="input", output=2, time="t")
    with pytest.raises(
        ph.DataError, match=r"input not given and the header names 2 columns 'input' \(columns 1, 2\): ambiguous"
    ):
        load_record(p, time="t")
    rec = load_record(p, input=1, output=2, time="t")
    np.testing.assert_array_equal(rec.output, y)
    # two columns of one name (not a role) are not assigned by position either
    p = write_csv(tmp_path / "dup2.csv", ["t", "v", "v"], [t, u, y])
    with pytest.raises(ph.DataError, match=r"2 columns are named 'v' \(columns 1, 2\): ambiguous"):
        load_record(p, time="t")
    # nor is a column named 'output' taken as the input
    p = write_csv(tmp_path / "swap.csv", ["t", "output", "y"], [t, u, y])
    with pytest.raises(ph.DataError, match=r"column 'output' would be taken as input \(columns 1\): ambiguous"):
        load_record(p, time="t", output="y")


def test_transposed_matrix_hint(tmp_path):
    f = tmp_path / "a.npz"
    np.savez(f, m=np.ones((3, 100)))
    with pytest.raises(
        ValueError, match=r"dataset = 'm' has shape \(3, 100\): fewer rows than columns, so it looks transposed"
    ):
        load_record(f, dataset="m", input=0, output=4, fs=1)


def test_mat_v5_errors(tmp_path):
    f = tmp_path / "a.mat"
    scipy.io.savemat(f, {"m": np.ones((4, 2)), "u": np.arange(4.0), "name": "x", "c": np.array([1 + 2j, 3])})
    with pytest.raises(
        ValueError, match=r"input = 'name' is not in the file; the numeric MAT variables are \['m', 'u'\]"
    ):
        load_record(f, input="name", output="u", fs=1)
    with pytest.raises(TypeError, match=r"input = 'c' must hold real numbers, got dtype complex128"):
        load_record(f, input="c", output="u", fs=1)
    with pytest.raises(ValueError, match=r"input = 'm' has shape \(4, 2\), not a 1-D signal"):
        load_record(f, input="m", output="u", fs=1)


# ----------------------------------------------------------------------------- Record


def make_record(n=10, with_time=True):
    k = np.arange(n, dtype=float)
    return Record(
        k, 10 * k, fs=10.0, time=k / 10 if with_time else None, source="src", columns={"input": "a", "output": "b"}
    )


def test_trim_is_half_open_and_zero_based():
    r = make_record()
    s = r.trim(2, 5)
    np.testing.assert_array_equal(s.input, [2, 3, 4])
    np.testing.assert_array_equal(s.output, [20, 30, 40])
    np.testing.assert_array_equal(s.time, [0.2, 0.3, 0.4])
    assert s.source == "src[2:5]" and s.fs == 10.0 and s.columns == r.columns
    np.testing.assert_array_equal(r.trim(7).input, [7, 8, 9])  # to the end
    assert r.trim(0, 10).n == 10
    assert r.trim().n == 10
    assert r.n == 10  # the original is untouched
    for args, kind, msg in [
        ((0, 11), ValueError, r"stop = 11 is beyond the end of the record \(10 samples\)"),
        ((5, 6), ValueError, r"start = 5, stop = 6 keep 1 samples, at least 2 needed"),
        ((6, 5), ValueError, r"start = 6, stop = 5 keep 0 samples"),
        ((-1,), ValueError, r"start = -1 must be >= 0"),
        ((1.5,), TypeError, r"start must be an integer, got 1\.5"),
        ((0, "5"), TypeError, r"stop must be an integer, got '5'"),
    ]:
        with pytest.raises(kind, match=msg):
            r.trim(*args)


def test_split():
    r = make_record()
    train, val = r.split(train=(0, 6), validate=(6, None))
    np.testing.assert_array_equal(train.input, np.arange(6.0))
    np.testing.assert_array_equal(val.input, [6, 7, 8, 9])
    assert (train.source, val.source) == ("src[0:6]", "src[6:10]")
    train, val = r.split()  # halves
    assert (train.n, val.n, val.input[0]) == (5, 5, 5.0)
    train, val = r.split(train=[5, 10], validate=[0, 3])  # any order, gaps allowed
    assert (train.input[0], val.n) == (5.0, 3)
    for kwargs, kind, msg in [
        (
            dict(train=(0, 6), validate=(5, 10)),
            ValueError,
            r"train = \(0, 6\) and validate = \(5, 10\) overlap \(samples 5 to 5\)",
        ),
        (dict(train=(0, 6)), ValueError, r"give both ranges, or neither"),
        (dict(train=(0, 6, 8), validate=(8, 10)), TypeError, r"train must be a \(start, stop\) pair of sample indices"),
        (dict(train="0:6", validate=(8, 10)), TypeError, r"train must be a \(start, stop\) pair"),
        (dict(train=(0, 6), validate=(8, 12)), ValueError, r"validate\[1\] = 12 is beyond the end of the record"),
        (dict(train=(0, 1), validate=(8, 10)), ValueError, r"train\[0\] = 0, train\[1\] = 1 keep 1 samples"),
    ]:
        with pytest.raises(kind, match=msg):
            r.split(**kwargs)


def test_record_validates_and_is_immutable():
    r = make_record()
    with pytest.raises(dataclasses.FrozenInstanceError):
        r.fs = 5.0
    with pytest.raises(ValueError, match="read-only"):
        r.input[0] = 1.0
    with pytest.raises(ValueError, match="read-only"):
        r.time[0] = 1.0
    k = np.arange(5.0)
    with pytest.raises(ValueError, match=r"output has 4 samples, input has 5"):
        Record(k, k[:4], fs=1.0)
    with pytest.raises(ValueError, match=r"input has 1 samples, at least 2 needed"):
        Record([1.0], [1.0], fs=1.0)
    with pytest.raises(ValueError, match=r"output\[2\] = nan is not finite"):
        Record(k, [0, 1, np.nan, 3, 4], fs=1.0)
    with pytest.raises(ValueError, match=r"fs = 0\.0 must be > 0"):
        Record(k, k, fs=0)
    with pytest.raises(ValueError, match=r"time is not strictly increasing: time\[3\] = 1\.0 follows time\[2\] = 2\.0"):
        Record(k, k, fs=1.0, time=[0, 1, 2, 1, 4])
    with pytest.raises(ValueError, match=r"time has 3 samples, input has 5"):
        Record(k, k, fs=1.0, time=[0, 1, 2])
    with pytest.raises(TypeError, match="source must be a str"):
        Record(k, k, fs=1.0, source=3)
    with pytest.raises(TypeError, match="columns must be a mapping"):
        Record(k, k, fs=1.0, columns=["a"])
    src = np.arange(5.0)
    rec = Record(src, src, fs=1.0)
    src[0] = 99.0  # the record holds its own copy
    assert rec.input[0] == 0.0
    assert "n=5" in repr(rec) and "fs=1 Hz" in repr(rec)


def test_to_pandas(monkeypatch):
    r = make_record(with_time=False)
    monkeypatch.setitem(sys.modules, "pandas", None)
    with pytest.raises(ImportError, match=r"Record\.to_pandas needs pandas: pip install pandas"):
        r.to_pandas()
    monkeypatch.delitem(sys.modules, "pandas")
    pd = pytest.importorskip("pandas", reason="pandas is optional and not installed")
    df = r.to_pandas()
    assert isinstance(df, pd.DataFrame) and list(df.columns) == ["time", "input", "output"]
    np.testing.assert_allclose(df["time"], np.arange(10) / 10.0)


# ----------------------------------------------------------------------------- real records


@_skip_missing(YAN9A_MODEL)
def test_yan9a_model_record():
    rec = load_yan9a_model_record(YAN9A_MODEL)
    assert rec.n == 8027 and rec.fs == 200.0
    assert rec.duration == pytest.approx(40.135)
    assert (rec.input.min(), rec.input.max()) == (0.0, 3.6)  # measured: exactly 0.000000 .. 3.600000 V
    assert (rec.output.min(), rec.output.max()) == (-123.059139, -73.635739)
    assert rec.columns == {"input": "column 0", "output": "column 4"}
    same = load_record(YAN9A_MODEL, input=0, output=4, fs=200)
    np.testing.assert_array_equal(same.input, rec.input)
    np.testing.assert_array_equal(same.output, rec.output)
    train, val = rec.split()
    assert (train.n, val.n) == (4013, 4014)
    with pytest.raises(
        ValueError, match=r"input = 7 is out of range: the file has 7 columns \(0-based indices 0\.\.6\)"
    ):
        load_record(YAN9A_MODEL, input=7, output=4, fs=200)


@_skip_missing(YAN9A_TEST)
def test_yan9a_test_record():
    rec = load_record(YAN9A_TEST, input=0, output=4, fs=200.0)
    assert rec.n == 14155
    desired = load_record(YAN9A_TEST, input=8, output=4, fs=200.0).input  # README's column 9
    assert -21 < desired.min() < -19 and 19 < desired.max() < 21


@_skip_missing(MULTISINE)
def test_train_multisine_record():
    from piezohyst.boucwen_benchmark import load_train_multisine

    rec = load_record(MULTISINE, fs=750)
    assert rec.n == 40960 and rec.fs == 750.0 and rec.columns == {"input": "u", "output": "y"}
    u, y, _fs = load_train_multisine(MULTISINE)
    np.testing.assert_array_equal(rec.input, u)
    np.testing.assert_array_equal(rec.output, y)
    _train, val = rec.split(train=(0, 4 * 8192), validate=(4 * 8192, None))  # last period held out
    assert val.n == 8192


# ----------------------------------------------------------------------------- fuzz

FUZZ_SUFFIXES = [".csv", ".tsv", ".txt", ".dat", ".npz", ".npy", ".mat"] + ([".h5"] if h5py is not None else [])
_t, _u, _y = signals(12, fs=100.0)
BASE_CSV = "t,u,y\n" + "".join(
    f"{a!r},{b!r},{c!r}\n" for a, b, c in zip(_t.tolist(), _u.tolist(), _y.tolist(), strict=False)
)
PIECES = [
    "",
    ",",
    "\t",
    "\n",
    "\r",
    " ",
    ";",
    "nan",
    "inf",
    "1e999",
    "-",
    ".",
    "e",
    "x",
    '"',
    "#",
    "%",
    "1",
    "0",
    "\x00",
    "é",
    "t",
    "u,y",
    "\ufeff",
]
LOAD_KWARGS = [
    dict(input="u", output="y", time="t"),
    dict(input=1, output=2, fs=100.0),
    dict(input="u", output="y", time="t", fs=100.0),
    dict(time="t"),
    dict(fs=50.0, header=False),
    dict(input=0, output=1, fs=1.0, delimiter=" "),
]


def _check_outcome(path, kwargs):
    try:
        rec = load_record(path, **kwargs)
    except ph.PiezohystError:  # the documented errors only (DataError, ParameterError, ...)
        return None
    assert rec.n >= 2 and rec.output.size == rec.n and rec.fs > 0
    assert np.all(np.isfinite(rec.input)) and np.all(np.isfinite(rec.output))
    return rec


@settings(
    max_examples=int(os.environ.get("PIEZOHYST_FUZZ_EXAMPLES", "100")),
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)
@given(content=st.binary(max_size=1500), suffix=st.sampled_from(FUZZ_SUFFIXES))
def test_fuzz_random_bytes_load_or_raise_value_or_type_error(content, suffix):
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / f"x{suffix}"
        p.write_bytes(content)
        _check_outcome(p, dict(input=0, output=1, fs=100.0))


@settings(
    max_examples=int(os.environ.get("PIEZOHYST_FUZZ_EXAMPLES", "100")),
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)
@given(
    edits=st.lists(st.tuples(st.integers(0, len(BASE_CSV)), st.sampled_from(PIECES), st.integers(0, 4)), max_size=6),
    kwargs=st.sampled_from(LOAD_KWARGS),
    encoding=st.sampled_from(["utf-8", "latin-1"]),
)
def test_fuzz_mutated_csv_load_or_raise_value_or_type_error(edits, kwargs, encoding):
    text = BASE_CSV
    for pos, piece, cut in edits:
        pos = min(pos, len(text))
        text = text[:pos] + piece + text[pos + cut :]
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "x.csv"
        p.write_bytes(text.encode(encoding, errors="replace"))
        rec = _check_outcome(p, kwargs)
        if not edits and rec is not None:
            np.testing.assert_array_equal(rec.output, _y)
