"""Loading real lab exports (issue 14 item 1; issue 20 readers): generated records that each carry
one defect — empty first field, time in ms, rounded / jittered time, a gap, decimal comma, BOM,
comment lines, quoted fields, units in the header — Parquet, MAT v5 / v7.3, and readers that read
only what was named (HDF5 links, external storage and virtual datasets refused; sizes bounded)."""

from pathlib import Path

import numpy as np
import pytest
import scipy.io

from piezohyst.data import Record, load_record
from piezohyst.errors import DataError, ParameterError
from piezohyst.signals.units import UnitConversion, parse_unit, split_annotation

try:
    import h5py
except ImportError:
    h5py = None

needs_h5py = pytest.mark.skipif(h5py is None, reason="h5py is not installed")

DATA = Path(__file__).resolve().parents[2].parent / "shared" / "data"
YAN9A = [DATA / "piezo" / "yan9a_model_1hz.dat", DATA / "piezo" / "yan9a_test.dat"]


def signals(n=400, fs=1000.0):
    k = np.arange(n)
    t = k / fs
    u = 2.0 + 1.5 * np.sin(2 * np.pi * 7 * t)
    y = 0.7 * u + 0.2 * np.cos(2 * np.pi * 7 * t)
    return t, u, y


def rows(*cols, fmt="{!r}", sep=","):
    return "".join(sep.join(fmt.format(float(v)) for v in r) + "\n" for r in zip(*cols, strict=True))


# ----------------------------------------------------------------------------- header or data


def test_first_row_with_an_empty_field_is_data_not_a_header(tmp_path):
    t, u, y = signals(50)
    f = tmp_path / "scope.csv"
    body = rows(t, u, y)
    # the first row's first field is empty (a scope that leaves the first time stamp blank)
    first, rest = body.split("\n", 1)
    f.write_text("," + first.split(",", 1)[1] + "\n" + rest)
    rec = load_record(f, input=1, output=2, fs=1000.0)
    assert rec.n == 50  # the first row kept, not taken for a header
    np.testing.assert_array_equal(rec.input, u)
    np.testing.assert_array_equal(rec.output, y)
    assert rec.columns == {"input": "column 1", "output": "column 2"}
    # the brief's own row: all four fields numbers or empty
    g = tmp_path / "b.csv"
    g.write_text(",0,-1.617,0\n,1,-1.5,0\n,2,-1.4,0\n")
    rec = load_record(g, input=1, output=2, fs=10.0)
    np.testing.assert_array_equal(rec.output, [-1.617, -1.5, -1.4])
    # reading the empty column names the line and the empty cell
    with pytest.raises(
        DataError, match=r"line 1 \(sample 0\), input column 'column 0' \(index 0\): '' is not a number"
    ):
        load_record(g, input=0, output=2, fs=10.0)


def test_empty_cell_deep_in_a_large_file_is_named(tmp_path):
    t, u, y = signals(120_000, fs=10_000.0)
    lines = rows(t, u, y).splitlines()
    lines[100_000] = lines[100_000].rsplit(",", 1)[0] + ","  # empty output cell, many Arrow blocks in
    f = tmp_path / "big.csv"
    f.write_text("t,u,y\n" + "\n".join(lines) + "\n")
    with pytest.raises(DataError, match=r"big\.csv: line 100002 \(sample 100000\), output column 'y' \(index 2\): ''"):
        load_record(f, input="u", output="y", time="t")
    lines[100_000] = lines[100_000] + "abc"
    f.write_text("t,u,y\n" + "\n".join(lines) + "\n")
    with pytest.raises(DataError, match=r"line 100002 \(sample 100000\), output column 'y' \(index 2\): 'abc'"):
        load_record(f, input="u", output="y", time="t")


def test_large_file_equals_numpy_loadtxt(tmp_path):
    t, u, y = signals(150_000, fs=10_000.0)
    f = tmp_path / "big.csv"
    np.savetxt(f, np.column_stack([t, u, y, -u]), delimiter=",", header="t,u,y,aux", comments="", fmt="%.17g")
    rec = load_record(f, input="u", output="y", time="t")
    ref = np.loadtxt(f, delimiter=",", skiprows=1)
    np.testing.assert_array_equal(rec.time, ref[:, 0])
    np.testing.assert_array_equal(rec.input, ref[:, 1])
    np.testing.assert_array_equal(rec.output, ref[:, 2])
    assert rec.fs == pytest.approx(10_000.0, rel=1e-9)


# ----------------------------------------------------------------------------- sniffing


@pytest.mark.parametrize("sep", [";", "\t", " "])
def test_decimal_comma(tmp_path, sep):
    t, u, y = signals(60)
    text = "t;u;y\n".replace(";", sep) + "".join(
        sep.join(f"{v:.6f}".replace(".", ",") for v in r) + "\n" for r in zip(t, u, y, strict=True)
    )
    f = tmp_path / "eu.csv"
    f.write_text(text)
    rec = load_record(f, input="u", output="y", time="t")
    np.testing.assert_allclose(rec.input, u, atol=5e-7)
    np.testing.assert_allclose(rec.output, y, atol=5e-7)
    assert rec.fs == pytest.approx(1000.0, rel=1e-9)


def test_decimal_comma_without_header(tmp_path):
    f = tmp_path / "eu.txt"
    f.write_text("0,5;1,25;-3\n1,5;2,25;-4\n2,5;3,25;-5\n")
    rec = load_record(f, input=1, output=2, fs=1.0)
    np.testing.assert_array_equal(rec.input, [1.25, 2.25, 3.25])
    np.testing.assert_array_equal(rec.output, [-3, -4, -5])


@pytest.mark.parametrize("encoding", ["utf-8-sig", "utf-16"])
def test_byte_order_mark(tmp_path, encoding):
    t, u, y = signals(30)
    f = tmp_path / "bom.csv"
    f.write_bytes(("time,volts,microns\n" + rows(t, u, y)).encode(encoding))
    rec = load_record(f, input="volts", output="microns", time="time")  # the BOM is not part of 'time'
    np.testing.assert_array_equal(rec.output, y)


def test_comment_lines_everywhere(tmp_path):
    t, u, y = signals(40)
    body = rows(t, u, y).splitlines()
    body.insert(10, "# paused here")
    body.insert(20, "% a MATLAB comment")
    body.insert(25, "   ")
    body.insert(30, "# a,comment,with commas")  # as many fields as the data: Arrow parses it
    f = tmp_path / "c.csv"
    f.write_text("; logger v2.1\n# channel A: u\n\n" + "t,u,y\n" + "\n".join(body) + "\n; end of file\n")
    rec = load_record(f, input="u", output="y", time="t")
    np.testing.assert_array_equal(rec.input, u)
    np.testing.assert_array_equal(rec.output, y)
    # a bad cell after the comments is named by its line in the file
    body[35] = body[35].rsplit(",", 1)[0] + ",oops"
    f.write_text("; logger v2.1\n# channel A: u\n\n" + "t,u,y\n" + "\n".join(body) + "\n")
    with pytest.raises(DataError, match=r"line 40 \(sample 31\), output column 'y' \(index 2\): 'oops'"):
        load_record(f, input="u", output="y", time="t")


def test_semicolon_rows_with_empty_first_field_are_data(tmp_path):
    f = tmp_path / "s.csv"
    f.write_text(";1;2\n;2;4\n;3;6\n")
    rec = load_record(f, input=1, output=2, fs=1.0)
    np.testing.assert_array_equal(rec.output, [2, 4, 6])


def test_quoted_fields(tmp_path):
    f = tmp_path / "q.csv"
    f.write_text('"time, s","u","y"\n"0.0","1.5","2"\n"0.5","2.5","3"\n"1.0","3.5","4"\n')
    rec = load_record(f, input="u", output="y", time="time, s")
    np.testing.assert_array_equal(rec.input, [1.5, 2.5, 3.5])
    assert rec.fs == 2.0


# ----------------------------------------------------------------------------- units


def test_split_annotation_and_parse_unit():
    assert split_annotation("t [ms]") == ("t", "ms")
    assert split_annotation("x (um)") == ("x", "um")
    assert split_annotation("u(V)") == ("u", "V")
    assert split_annotation("disp_um") == ("disp", "um")
    assert split_annotation("time_s") == ("time", "s")
    assert split_annotation("run_a") == ("run_a", None)  # 'a' is not a unit
    assert split_annotation("sensor (counts)") == ("sensor", "counts")
    assert parse_unit("µm", "output") == UnitConversion("µm", "m", 1e-6, "argument")
    assert parse_unit("kV", "input").scale == 1e3
    assert parse_unit("us", "time").scale == 1e-6
    with pytest.raises(ParameterError, match=r"output_unit = 'furlong' is not a known unit"):
        parse_unit("furlong", "output")
    with pytest.raises(ParameterError, match=r"time_unit = 'mV' is not a unit of time"):
        parse_unit("mV", "time")


def test_time_in_ms_from_the_header_is_not_read_as_seconds(tmp_path):
    t, u, y = signals(200, fs=5000.0)
    f = tmp_path / "ms.csv"
    f.write_text("t [ms],u (V),x (um)\n" + rows(t * 1e3, u, y * 10))
    rec = load_record(f, input="u", output="x", time="t")  # names without the annotation match
    assert rec.fs == pytest.approx(5000.0, rel=1e-9)  # not 5 Hz
    np.testing.assert_allclose(rec.time, t, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(rec.output, y * 10e-6, rtol=1e-12)  # um -> m
    np.testing.assert_array_equal(rec.input, u)
    assert rec.units["time"] == UnitConversion("ms", "s", 1e-3, "header")
    assert rec.units["output"] == UnitConversion("um", "m", 1e-6, "header")
    assert rec.units["input"] == UnitConversion("V", "V", 1.0, "header")
    assert rec.si_units() == {"input": "V", "output": "m"}
    assert rec.columns == {"input": "u (V)", "output": "x (um)", "time": "t [ms]"}
    # the full annotated name matches too; an argument overrides the header
    rec2 = load_record(f, input="u (V)", output="x (um)", time="t [ms]", output_unit="nm")
    np.testing.assert_allclose(rec2.output, y * 10e-9, rtol=1e-12)
    assert rec2.units["output"].origin == "argument"
    # the units survive trim / split
    assert rec.trim(5, 50).units == rec.units


def test_time_unit_argument_and_suffix_names(tmp_path):
    t, u, y = signals(100, fs=250.0)
    f = tmp_path / "a.csv"
    f.write_text("time,volts_mV,disp_um\n" + rows(t * 1e3, u * 1e3, y))
    rec = load_record(f, input="volts", output="disp", time="time", time_unit="ms")
    assert rec.fs == pytest.approx(250.0, rel=1e-9)
    np.testing.assert_allclose(rec.input, u, rtol=1e-12)
    np.testing.assert_allclose(rec.output, y * 1e-6, rtol=1e-12)
    # without the unit, the time column is seconds (as today) and the record says it assumed so
    rec = load_record(f, input="volts", output="disp", time="time")
    assert rec.fs == pytest.approx(0.25, rel=1e-9)
    assert rec.units["time"] == UnitConversion("s", "s", 1.0, "assumed")
    with pytest.raises(ParameterError, match=r"input_unit = 'parsec' is not a known unit"):
        load_record(f, input="volts", output="disp", time="time", input_unit="parsec")


def test_unknown_annotation_is_kept_not_converted(tmp_path):
    f = tmp_path / "a.csv"
    f.write_text("u [V],y [counts]\n0,10\n1,20\n2,30\n")
    rec = load_record(f, fs=100.0)
    np.testing.assert_array_equal(rec.output, [10, 20, 30])
    assert rec.units["output"] == UnitConversion("counts", "counts", 1.0, "header")


def test_record_units_validated():
    k = np.arange(5.0)
    with pytest.raises(TypeError, match="units must map a role to a UnitConversion"):
        Record(k, k, fs=1.0, units={"input": "V"})


# ----------------------------------------------------------------------------- time axis


def test_rounded_and_jittered_time_stamps_within_tolerance(tmp_path):
    t, u, y = signals(3000, fs=750.0)
    f = tmp_path / "r.csv"
    f.write_text("t,u,y\n" + rows(np.round(t, 5), u, y))  # 10 us resolution on a 1.33 ms step
    with pytest.raises(DataError, match="not uniformly sampled"):
        load_record(f, input="u", output="y", time="t")  # the default 1e-6 is strict
    rec = load_record(f, input="u", output="y", time="t", time_rtol=0.05)
    assert rec.fs == pytest.approx(750.0, rel=1e-6)  # the least-squares slope, not one step
    rng = np.random.default_rng(3)
    tj = t + rng.uniform(-0.1, 0.1, t.size) / 750.0  # +-10 % of a step of jitter
    g = tmp_path / "j.csv"
    g.write_text("t,u,y\n" + rows(tj, u, y))
    rec = load_record(g, input="u", output="y", time="t", time_rtol=0.25)
    assert rec.fs == pytest.approx(750.0, rel=1e-5)
    # (n - 1) / (t[-1] - t[0]), yesterday's estimate, is worse than the fit on jittered stamps
    naive = (t.size - 1) / (tj[-1] - tj[0])
    assert abs(rec.fs - 750.0) < abs(naive - 750.0)


def test_a_gap_is_an_error_naming_its_row(tmp_path):
    t, u, y = signals(300, fs=1000.0)
    keep = np.r_[0:120, 130:300]  # ten samples missing after row 119
    f = tmp_path / "gap.csv"
    f.write_text("t,u,y\n" + rows(t[keep], u[keep], y[keep]))
    with pytest.raises(DataError, match=r"gap\.csv: time has a gap at row 120: time\[120\] - time\[119\] = 0\.011 s"):
        load_record(f, input="u", output="y", time="t", time_rtol=0.05)
    with pytest.raises(DataError, match=r"about 10 samples missing"):
        load_record(f, input="u", output="y", time="t", time_rtol=0.05)


def test_non_monotonic_time_names_its_row(tmp_path):
    t, u, y = signals(50)
    t = t.copy()
    t[[20, 21]] = t[[21, 20]]
    f = tmp_path / "nm.csv"
    f.write_text("t,u,y\n" + rows(t, u, y))
    with pytest.raises(
        DataError, match=r"time is not strictly increasing: time\[21\] = 0\.02 follows time\[20\] = 0\.021"
    ):
        load_record(f, input="u", output="y", time="t", time_rtol=0.05)


def test_drifting_clock_is_refused(tmp_path):
    n = 2000
    steps = np.linspace(0.99e-3, 1.01e-3, n - 1)  # every step within 1 % of the median, the rate drifts
    t = np.r_[0.0, np.cumsum(steps)]
    u = np.sin(np.arange(n) / 50)
    f = tmp_path / "drift.csv"
    f.write_text("t,u,y\n" + rows(t, u, u))
    with pytest.raises(DataError, match=r"does not follow a uniform clock"):
        load_record(f, input="u", output="y", time="t", time_rtol=0.02)


# ----------------------------------------------------------------------------- other formats


def test_parquet(tmp_path):
    pa = pytest.importorskip("pyarrow")
    import pyarrow.parquet as pq

    t, u, y = signals(500)
    f = tmp_path / "a.parquet"
    pq.write_table(pa.table({"t [ms]": t * 1e3, "u": u, "x (um)": y, "note": ["a"] * 500}), f)
    rec = load_record(f, input="u", output="x", time="t")
    assert rec.fs == pytest.approx(1000.0, rel=1e-9)
    np.testing.assert_allclose(rec.output, y * 1e-6, rtol=1e-12)
    rec = load_record(f, input=1, output=2, fs=1000.0)
    np.testing.assert_array_equal(rec.input, u)
    with pytest.raises(TypeError, match=r"input = 'note' must hold real numbers"):
        load_record(f, input="note", output="u", fs=1.0)
    with pytest.raises(DataError, match=r"input = 'v' is not a column; the columns are \['t \[ms\]', 'u'"):
        load_record(f, input="v", output="u", fs=1.0)
    g = tmp_path / "null.pq"
    pq.write_table(pa.table({"u": [1.0, None, 3.0], "y": [1.0, 2.0, 3.0]}), g)
    with pytest.raises(DataError, match=r"input\[1\] is missing \(null\) in column 'u'"):
        load_record(g, fs=1.0)
    with pytest.raises(DataError, match=r"not a readable Parquet file"):
        (tmp_path / "junk.parquet").write_bytes(b"PAR1 nonsense")
        load_record(tmp_path / "junk.parquet", fs=1.0)


def test_mat_v5_with_units(tmp_path):
    t, u, y = signals(100)
    f = tmp_path / "a.mat"
    scipy.io.savemat(f, {"t_ms": t * 1e3, "u": u, "y": y})
    rec = load_record(f, input="u", output="y", time="t_ms", output_unit="um")
    assert rec.fs == pytest.approx(1000.0, rel=1e-9)
    np.testing.assert_allclose(rec.output, y * 1e-6, rtol=1e-12)


@needs_h5py
def test_mat_v73_loads(tmp_path):
    from tests.signals.test_data import write_mat73

    t, u, y = signals(100)
    f = tmp_path / "a.mat"
    write_mat73(f, {"u": u, "y": y, "t": t * 1e3})
    rec = load_record(f, input="u", output="y", time="t", time_unit="ms")
    assert rec.fs == pytest.approx(1000.0, rel=1e-9)
    np.testing.assert_array_equal(rec.output, y)


@pytest.mark.parametrize("path", YAN9A, ids=lambda p: p.name)
def test_yan9a_loads_exactly_as_numpy_reads_it(path):
    if not path.exists():
        pytest.skip(f"{path} is not present")
    ref = np.loadtxt(path)
    rec = load_record(path, input=0, output=4, fs=200.0)
    np.testing.assert_array_equal(rec.input, ref[:, 0])
    np.testing.assert_array_equal(rec.output, ref[:, 4])
    assert rec.n == ref.shape[0]
    assert rec.units == {
        "input": UnitConversion("", "", 1.0, "assumed"),
        "output": UnitConversion("", "", 1.0, "assumed"),
    }


# ----------------------------------------------------------------------------- read only what was named


def test_npz_decompressed_size_is_bounded_before_reading(tmp_path, monkeypatch):
    f = tmp_path / "bomb.npz"
    np.savez_compressed(f, u=np.zeros(2_000_000), y=np.arange(10.0), v=np.arange(10.0))
    assert f.stat().st_size < 100_000  # 16 MB of zeros compress to a few kB
    with pytest.raises(
        DataError, match=r"NPZ member 'u' of shape \(2000000,\) \(float64\) would take 16,000,000 bytes"
    ):
        load_record(f, input="u", output="y", fs=1.0, max_bytes=1_000_000)
    monkeypatch.setenv("PIEZOHYST_MAX_ARRAY_BYTES", "1000000")
    with pytest.raises(DataError, match=r"over the limit of 1,000,000 bytes; .*PIEZOHYST_MAX_ARRAY_BYTES=<bytes>"):
        load_record(f, input="u", output="y", fs=1.0)
    rec = load_record(f, input="v", output="y", fs=1.0)  # 'u' is never decompressed
    np.testing.assert_array_equal(rec.input, np.arange(10.0))
    monkeypatch.setenv("PIEZOHYST_MAX_ARRAY_BYTES", "lots")
    with pytest.raises(ParameterError, match=r"PIEZOHYST_MAX_ARRAY_BYTES = 'lots' must be a number of bytes"):
        load_record(f, input="v", output="y", fs=1.0)
    monkeypatch.delenv("PIEZOHYST_MAX_ARRAY_BYTES")
    with pytest.raises(ValueError, match=r"max_bytes = 0 must be >= 1"):
        load_record(f, input="v", output="y", fs=1.0, max_bytes=0)


def test_mat_v5_size_is_bounded(tmp_path):
    f = tmp_path / "big.mat"
    scipy.io.savemat(f, {"u": np.zeros(500_000), "y": np.zeros(10)}, do_compression=True)
    with pytest.raises(
        DataError, match=r"MATLAB variable 'u' of shape \(500000, 1\)|MATLAB variable 'u' of shape \(1, 500000\)"
    ):
        load_record(f, input="u", output="y", fs=1.0, max_bytes=1_000_000)


def test_mat_v5_reads_only_what_was_named(tmp_path, monkeypatch):
    # a numeric variable over the limit that nobody asks for is never read (it used to stop
    # the whole file); a struct whose fields decompress past the limit is listed by name and
    # refused when a field is asked for, never decompressed past the limit
    f = tmp_path / "mixed.mat"
    big = np.zeros(2_000_000)  # 16 MB of zeros: a few kB compressed
    scipy.io.savemat(
        f, {"big": big, "s": {"wave": big, "gain": 2.0}, "u": np.arange(10.0), "y": np.ones(10)}, do_compression=True
    )
    assert f.stat().st_size < 100_000
    read: list[object] = []
    real = scipy.io.loadmat
    monkeypatch.setattr(scipy.io, "loadmat", lambda *a, **k: read.append(k.get("variable_names")) or real(*a, **k))
    rec = load_record(f, input="u", output="y", fs=1.0, max_bytes=1_000_000)
    np.testing.assert_array_equal(rec.input, np.arange(10.0))
    assert read and all(names in (["u"], ["y"]) for names in read)  # 'big' and 's' never read
    with pytest.raises(
        DataError, match=r"MATLAB variable 'big' of shape \(1, 2000000\) \(double\) would take 16,000,000"
    ):
        load_record(f, input="big", output="y", fs=1.0, max_bytes=1_000_000)
    with pytest.raises(DataError, match=r"MATLAB variable 's' of shape \(1, 1\) \(struct\) would take [0-9,]+ bytes"):
        load_record(f, input="s.wave", output="y", fs=1.0, max_bytes=1_000_000)
    # under a limit that holds it, the struct's fields are variables like any other
    rec = load_record(f, input="s.wave", output="big", fs=1.0)
    assert rec.n == 2_000_000


def test_mat_v5_decompressed_size_is_counted_not_held(tmp_path):
    from piezohyst.signals.data import _Mat5Index

    f = tmp_path / "z.mat"
    scipy.io.savemat(f, {"a": np.zeros(3_000_000), "b": np.arange(4.0)}, do_compression=True)
    index = _Mat5Index(f, 2)
    assert [c for *_, c in index.elements] == [True, True] and index.complex == [False, False]
    # the element: tags and headers, then 24,000,000 bytes of data
    assert 24_000_000 < index.decompressed_size(0, 10**9) < 24_000_100
    # stopped just past the limit: at most one 1 MiB piece beyond it
    assert 1_000_000 < index.decompressed_size(0, 1_000_000) <= 1_000_000 + (1 << 20)
    assert index.decompressed_size(1, 10**9) < 200


@needs_h5py
def test_hdf5_external_links_storage_and_virtual_datasets_are_refused(tmp_path):
    secret = tmp_path / "secret.bin"
    secret.write_bytes(np.arange(16.0).tobytes())
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as h:
        h["x"] = np.arange(16.0)
    f = tmp_path / "evil.h5"
    with h5py.File(f, "w") as h:
        h["y"] = np.arange(16.0)
        h.create_dataset("raw", shape=(16,), dtype="f8", external=[(str(secret), 0, 128)])
        h["link"] = h5py.ExternalLink(str(other), "/x")
        h["soft"] = h5py.SoftLink("/link")
        layout = h5py.VirtualLayout(shape=(16,), dtype="f8")
        layout[:] = h5py.VirtualSource(str(other), "x", shape=(16,))
        h.create_virtual_dataset("virtual", layout)
        h["big"] = np.zeros(300_000)
    with pytest.raises(DataError, match=r"evil\.h5: dataset 'raw' keeps its data in external raw storage"):
        load_record(f, input="raw", output="y", fs=1.0)
    with pytest.raises(DataError, match=r"'link' goes through an external link .*only the file named is read"):
        load_record(f, input="link", output="y", fs=1.0)
    with pytest.raises(DataError, match=r"'soft' goes through an external link"):
        load_record(f, input="soft", output="y", fs=1.0)
    with pytest.raises(DataError, match=r"dataset 'virtual' is a virtual dataset"):
        load_record(f, input="virtual", output="y", fs=1.0)
    with pytest.raises(DataError, match=r"dataset 'big' of shape \(300000,\) \(float64\) would take 2,400,000 bytes"):
        load_record(f, input="big", output="y", fs=1.0, max_bytes=1_000_000)
    g = tmp_path / "good.h5"
    with h5py.File(g, "w") as h:
        h["u"] = np.arange(16.0)
        h["y"] = 2 * np.arange(16.0)
        h["alias"] = h5py.SoftLink("/u")  # a link inside the file is followed
    rec = load_record(g, input="alias", output="y", fs=1.0)
    np.testing.assert_array_equal(rec.input, np.arange(16.0))


def test_a_line_of_units_under_the_names(tmp_path):
    t, u, y = signals(80, fs=2000.0)
    f = tmp_path / "scope.csv"
    f.write_text("Time,Channel A,Channel B\n(ms),(V),(mV)\n\n" + rows(t * 1e3, u, y * 1e3))
    rec = load_record(f, input="Channel A", output="Channel B", time="Time")
    assert rec.fs == pytest.approx(2000.0, rel=1e-9)
    np.testing.assert_allclose(rec.output, y, rtol=1e-12)
    assert rec.columns == {"input": "Channel A [V]", "output": "Channel B [mV]", "time": "Time [ms]"}
    assert rec.units["output"] == UnitConversion("mV", "V", 1e-3, "header")
    lines = f.read_text().splitlines()
    lines[10] = lines[10].rsplit(",", 1)[0] + ",x"
    f.write_text("\n".join(lines) + "\n")
    with pytest.raises(DataError, match=r"line 11 \(sample 7\), output column 'Channel B \[mV\]'"):
        load_record(f, input="Channel A", output="Channel B", time="Time")


@needs_h5py
def test_hdf5_units_attribute(tmp_path):
    t, u, y = signals(100, fs=500.0)
    f = tmp_path / "a.h5"
    with h5py.File(f, "w") as h:
        h["t"] = t * 1e3
        h["t"].attrs["units"] = "ms"
        h["u"] = u
        h["u"].attrs["units"] = np.bytes_("V")
        h["x"] = y
        h["x"].attrs["unit"] = "nm"
    rec = load_record(f, input="u", output="x", time="t")
    assert rec.fs == pytest.approx(500.0, rel=1e-9)
    np.testing.assert_allclose(rec.output, y * 1e-9, rtol=1e-12)
    assert rec.units["output"] == UnitConversion("nm", "m", 1e-9, "file")
    rec = load_record(f, input="u", output="x", time="t", output_unit="um")  # an argument wins
    np.testing.assert_allclose(rec.output, y * 1e-6, rtol=1e-12)


def test_parquet_field_metadata_unit(tmp_path):
    pa = pytest.importorskip("pyarrow")
    import pyarrow.parquet as pq

    t, u, y = signals(100)
    schema = pa.schema(
        [
            pa.field("t", pa.float64(), metadata={"unit": "us"}),
            pa.field("u", pa.float64()),
            pa.field("y", pa.float64(), metadata={"units": "mm"}),
        ]
    )
    f = tmp_path / "a.parquet"
    pq.write_table(pa.table({"t": t * 1e6, "u": u, "y": y}, schema=schema), f)
    rec = load_record(f, input="u", output="y", time="t")
    assert rec.fs == pytest.approx(1000.0, rel=1e-9)
    np.testing.assert_allclose(rec.output, y * 1e-3, rtol=1e-12)
    assert rec.units["time"] == UnitConversion("us", "s", 1e-6, "file")


def test_whitespace_with_decimal_comma_and_no_header(tmp_path):
    f = tmp_path / "ws.txt"
    f.write_text("0,5  1,25  -3\n1,5  2,25  -4\n2,5  3,25  -5\n")  # ',' splits every line alike, but into non-numbers
    rec = load_record(f, input=1, output=2, fs=1.0)
    np.testing.assert_array_equal(rec.input, [1.25, 2.25, 3.25])
    np.testing.assert_array_equal(rec.output, [-3, -4, -5])
