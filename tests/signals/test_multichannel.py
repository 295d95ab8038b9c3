"""Multi-channel records (issue 15 item 5): the nonlinear-benchmark folder layout, NPZ with u/y,
the typed record, and every bad input named clearly."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

import piezohyst as ph
from piezohyst.signals import MultiRecord, is_multichannel, load_multichannel

DATA = Path(__file__).resolve().parents[2].parent / "shared" / "data"
FSM = DATA / "fsm"
needs_fsm = pytest.mark.skipif(not FSM.exists(), reason=f"{FSM} is not present (shared data lives outside the repo)")

RNG = np.random.default_rng(7)


def _folder(tmp_path: Path, levels=(100, 200, 300), shape=(64, 3, 2, 2), ny=3) -> Path:
    for mv in levels:
        u = mv * 1e-3 * RNG.standard_normal(shape)
        y = 1e-6 * np.concatenate([u, u], axis=1)[:, :ny]
        np.save(tmp_path / f"u_{mv}mV_train.npy", u)
        np.save(tmp_path / f"y_{mv}mV_train.npy", y)
    return tmp_path


# ---------------------------------------------------------------- the benchmark's own folder


@needs_fsm
def test_fsm_folder_reads_as_three_levels_in_the_benchmark_layout(tmp_path):
    train = tmp_path / "train"
    shutil.copytree(FSM, train)  # the acceptance check copies the folder alone
    recs = load_multichannel(train, fs=6400)
    assert [r.name for r in recs] == ["100mV_train", "200mV_train", "300mV_train"]
    assert [r.level for r in recs] == pytest.approx([0.1, 0.2, 0.3])
    for r in recs:
        assert r.shape == (8192, 3, 3, 6, 2) and r.fs == 6400.0 and r.units == {"input": "V", "output": "m"}
        # the README: 100/200/300 mV RMS per input (within 2 %); outputs are metres (micrometres of travel)
        np.testing.assert_allclose(r.input_rms, r.level, rtol=0.02)
        assert 1e-6 < np.abs(r.y).max() < 1e-4
    raw = np.load(FSM / "y_200mV_train.npy")
    np.testing.assert_array_equal(recs[1].y, raw)  # unchanged, not a copy of another level
    assert is_multichannel(train) and is_multichannel(train / "u_100mV_train.npy")
    assert not recs[0].u.flags.writeable


@needs_fsm
def test_fsm_periods_repeat_and_time_series_concatenates_them():
    (rec,) = [r for r in load_multichannel(FSM, fs=6400) if r.name == "100mV_train"]
    u, y = rec.time_series(realization=3)
    assert u.shape == (16384, 3) and y.shape == (16384, 3)
    np.testing.assert_array_equal(u[:8192], rec.u[:, :, 3, 0])
    np.testing.assert_array_equal(y[8192:], rec.y[:, :, 3, 1])

    # steady state: period 2 repeats period 1 up to noise (4.7 % of the output RMS at 100 mV), the
    # inputs (measured too) to 0.04 %: two periods read from the array, not one period twice
    def rel(a):
        return np.sqrt(np.mean((a[..., 1] - a[..., 0]) ** 2)) / np.sqrt(np.mean(a**2))

    assert 0.01 < rel(rec.y) < 0.06
    assert 1e-5 < rel(rec.u) < 1e-3
    half = rec.select(realizations=[0, 1, 2])
    assert half.shape == (8192, 3, 3, 3, 2) and "r=[0, 1, 2]" in half.source


@needs_fsm
def test_single_u_file_reads_its_pair():
    (rec,) = load_multichannel(FSM / "y_300mV_train.npy", fs=6400)
    assert rec.name == "300mV_train" and rec.level == pytest.approx(0.3)


# ---------------------------------------------------------------- NPZ and generated folders


def test_npz_two_dimensional_is_one_realization_one_period(tmp_path):
    u = RNG.standard_normal((300, 3))
    y = RNG.standard_normal((300, 2))
    np.savez(tmp_path / "run.npz", u=u, y=y)
    (rec,) = load_multichannel(tmp_path / "run.npz", fs=1000)
    assert rec.shape == (300, 3, 2, 1, 1) and rec.name == "run"
    ut, yt = rec.time_series()
    np.testing.assert_array_equal(ut, u)
    np.testing.assert_array_equal(yt, y)
    assert is_multichannel(tmp_path / "run.npz")


def test_npz_four_dimensional_and_stored_fs(tmp_path):
    u = RNG.standard_normal((128, 3, 4, 2))
    np.savez_compressed(tmp_path / "b.npz", u=u, y=2 * u, fs=np.float64(6400.0))
    (rec,) = load_multichannel(tmp_path / "b.npz")
    assert rec.fs == 6400.0 and rec.shape == (128, 3, 3, 4, 2)
    np.testing.assert_array_equal(rec.y, 2 * u)
    with pytest.raises(ph.DataError, match=r"fs = 6400 Hz disagrees with fs = 5000 Hz given"):
        load_multichannel(tmp_path / "b.npz", fs=5000)


def test_single_channel_npz_is_not_multichannel(tmp_path):
    np.savez(tmp_path / "siso.npz", u=np.ones(50), y=np.ones(50))
    assert not is_multichannel(tmp_path / "siso.npz")
    assert not is_multichannel(tmp_path / "missing.npz")
    (tmp_path / "a.csv").write_text("u,y\n0,1\n")
    assert not is_multichannel(tmp_path / "a.csv") and not is_multichannel(tmp_path)


def test_three_axes_and_units_converted(tmp_path):
    u = RNG.standard_normal((64, 2, 5))  # mV, 5 realizations
    np.save(tmp_path / "u_a.npy", u)
    np.save(tmp_path / "y_a.npy", u)  # um
    (rec,) = load_multichannel(tmp_path, fs=100, input_unit="mV", output_unit="um")
    assert rec.shape == (64, 2, 2, 5, 1)
    np.testing.assert_allclose(rec.u[..., 0], 1e-3 * u)
    np.testing.assert_allclose(rec.y[..., 0], 1e-6 * u)
    with pytest.raises(ph.ParameterError, match=r"output_unit = 'mV' is a unit of 'V', the output is in m"):
        load_multichannel(tmp_path, fs=100, output_unit="mV")


def test_records_sorted_by_level_then_name(tmp_path):
    _folder(tmp_path, levels=(1000, 50, 300))
    np.save(tmp_path / "u_extra.npy", np.ones((64, 3, 2, 2)))
    np.save(tmp_path / "y_extra.npy", np.ones((64, 3, 2, 2)))
    (tmp_path / "README.md").write_text("other files are ignored")
    names = [r.name for r in load_multichannel(tmp_path, fs=1)]
    assert names == ["50mV_train", "300mV_train", "1000mV_train", "extra"]


# ---------------------------------------------------------------- bad input, named


def test_u_without_y_and_y_without_u(tmp_path):
    _folder(tmp_path, levels=(100,))
    np.save(tmp_path / "u_200mV_train.npy", np.ones((64, 3, 2, 2)))
    with pytest.raises(ph.DataError, match=r"u_200mV_train.npy has no output file y_200mV_train.npy beside it"):
        load_multichannel(tmp_path, fs=1)
    (tmp_path / "u_200mV_train.npy").rename(tmp_path / "y_200mV_train.npy")
    with pytest.raises(ph.DataError, match=r"y_200mV_train.npy has no input file u_200mV_train.npy"):
        load_multichannel(tmp_path, fs=1)


def test_empty_folder(tmp_path):
    with pytest.raises(ph.DataError, match=r"no u_<name>.npy / y_<name>.npy pairs in this folder.*no files"):
        load_multichannel(tmp_path, fs=1)
    (tmp_path / "notes.txt").write_text("x")
    with pytest.raises(ph.DataError, match=r"it holds \['notes.txt'\]"):
        load_multichannel(tmp_path, fs=1)


def test_mismatched_shapes_name_both(tmp_path):
    np.save(tmp_path / "u_a.npy", np.ones((64, 3, 2, 2)))
    np.save(tmp_path / "y_a.npy", np.ones((64, 3, 3, 2)))
    with pytest.raises(ph.DataError, match=r"y has shape \(64, 3, 3, 2\), u has shape \(64, 3, 2, 2\)"):
        load_multichannel(tmp_path, fs=1)


def test_nan_named_by_its_index(tmp_path):
    y = np.ones((64, 3, 2, 2))
    y[17, 2, 1, 0] = np.nan
    np.save(tmp_path / "u_a.npy", np.ones((64, 3, 2, 2)))
    np.save(tmp_path / "y_a.npy", y)
    with pytest.raises(ph.DataError, match=r"y_a.npy: y\[17, 2, 1, 0\] = nan is not finite"):
        load_multichannel(tmp_path, fs=1)


def test_one_dimensional_and_transposed_and_five_axes(tmp_path):
    np.savez(tmp_path / "a.npz", u=np.ones(64), y=np.ones((64, 3)))
    with pytest.raises(ph.DataError, match=r"u has shape \(64,\): 1-D.*reshape to \(64, 1\)"):
        load_multichannel(tmp_path / "a.npz", fs=1)
    np.savez(tmp_path / "a.npz", u=np.ones((3, 64)), y=np.ones((3, 64)))
    with pytest.raises(ph.DataError, match=r"u has shape \(3, 64\): more channels \(64\) than samples.*transposed"):
        load_multichannel(tmp_path / "a.npz", fs=1)
    np.savez(tmp_path / "a.npz", u=np.ones((8, 1, 1, 1, 1)), y=np.ones((8, 1)))
    with pytest.raises(ph.DataError, match=r"u has shape \(8, 1, 1, 1, 1\): expected"):
        load_multichannel(tmp_path / "a.npz", fs=1)
    np.savez(tmp_path / "a.npz", u=np.ones((8, 1, 0)), y=np.ones((8, 1)))
    with pytest.raises(ph.DataError, match=r"an empty axis"):
        load_multichannel(tmp_path / "a.npz", fs=1)


def test_mixed_lengths_and_channel_counts(tmp_path):
    _folder(tmp_path, levels=(100,))
    np.save(tmp_path / "u_b.npy", np.ones((32, 3, 2, 2)))
    np.save(tmp_path / "y_b.npy", np.ones((32, 3, 2, 2)))
    with pytest.raises(ph.DataError, match=r"records of mixed shapes: 'b' has 32 samples .* '100mV_train' has 64"):
        load_multichannel(tmp_path, fs=1)
    np.save(tmp_path / "u_b.npy", np.ones((64, 2, 2, 2)))
    np.save(tmp_path / "y_b.npy", np.ones((64, 3, 2, 2)))
    with pytest.raises(ph.DataError, match=r"'b' has 2 inputs"):
        load_multichannel(tmp_path, fs=1)


def test_fs_missing_or_bad(tmp_path):
    _folder(tmp_path, levels=(100,))
    with pytest.raises(ph.DataError, match=r"the sample rate is unknown: pass fs=<Hz>"):
        load_multichannel(tmp_path)
    with pytest.raises(ph.ParameterError, match=r"fs = -1.0 must be > 0"):
        load_multichannel(tmp_path, fs=-1)


def test_npz_without_y_and_other_files(tmp_path):
    np.savez(tmp_path / "a.npz", u=np.ones((64, 3)), x=np.ones(3))
    with pytest.raises(ph.DataError, match=r"no 'y' array.*it holds \['u', 'x'\]"):
        load_multichannel(tmp_path / "a.npz", fs=1)
    np.savez(tmp_path / "a.npz", u=np.ones((64, 3)), y=np.array(["a"] * 64))
    with pytest.raises(ph.ParameterTypeError, match=r"y must hold real numbers, got dtype <U1"):
        load_multichannel(tmp_path / "a.npz", fs=1)
    (tmp_path / "c.csv").write_text("1,2\n")
    with pytest.raises(ph.DataError, match=r"not a .csv file"):
        load_multichannel(tmp_path / "c.csv", fs=1)
    np.save(tmp_path / "plain.npy", np.ones((5, 2)))
    with pytest.raises(ph.DataError, match=r"named u_<name>.npy with y_<name>.npy"):
        load_multichannel(tmp_path / "plain.npy", fs=1)
    with pytest.raises(FileNotFoundError, match="no such file or folder"):
        load_multichannel(tmp_path / "nope", fs=1)
    with pytest.raises(ph.ParameterTypeError, match="path must be a str or os.PathLike"):
        load_multichannel(b"x", fs=1)  # type: ignore[arg-type]


def test_size_limit_truncation_and_corruption(tmp_path):
    _folder(tmp_path, levels=(100,))
    with pytest.raises(ph.DataError, match=r"would take 6,144 bytes .* over the limit of 1,000 bytes"):
        load_multichannel(tmp_path, fs=1, max_bytes=1000)
    raw = (tmp_path / "y_100mV_train.npy").read_bytes()
    (tmp_path / "y_100mV_train.npy").write_bytes(raw[:-100])
    with pytest.raises(ph.DataError, match=r"needs 6,144 bytes, the file holds 6,044: truncated"):
        load_multichannel(tmp_path, fs=1)
    (tmp_path / "z.npz").write_bytes(b"PK\x03\x04garbage")
    with pytest.raises(ph.DataError, match=r"z.npz: not a readable NPZ archive"):
        load_multichannel(tmp_path / "z.npz", fs=1)


def test_record_class_checks_its_arguments():
    u = np.ones((10, 2, 3, 2))
    rec = MultiRecord(u, u[:, :1], fs=100.0, name="x")
    assert rec.n_outputs == 1 and rec.level is None and "inputs=2" in repr(rec)
    with pytest.raises(ph.ParameterError, match=r"realizations = 3 must lie within \[0, 2\]"):
        rec.select(realizations=[3])
    with pytest.raises(ph.ParameterError, match=r"periods = \[\] keeps nothing"):
        rec.select(periods=[])
    with pytest.raises(ph.ParameterError, match=r"realization = 5 must lie within \[0, 2\]"):
        rec.time_series(5)
    with pytest.raises(ph.ParameterTypeError, match="name must be a str"):
        MultiRecord(u, u, fs=1.0, name=3)  # type: ignore[arg-type]
    with pytest.raises(ph.ParameterTypeError, match="u must hold real numbers, got dtype complex128"):
        MultiRecord(u + 1j, u, fs=1.0)
