"""Multi-channel DATA for ``piezohyst identify`` (issue 15 item 5): a folder of u_*.npy / y_*.npy
records or an NPZ with u/y is read by piezohyst.signals.load_multichannel, so every bad input is
one line naming the file; a folder identifies and the model file simulates."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from piezohyst.control.mimo import periodic_response
from tests.control.test_mimo_feedforward import resonant_mimo


def run(*args, cwd):
    return subprocess.run([sys.executable, "-m", "piezohyst", *map(str, args)], cwd=cwd, capture_output=True, text=True)


def one_line(out) -> str:
    assert out.returncode == 2, out.stderr
    assert out.stderr.count("\n") == 1, out.stderr
    return out.stderr


@pytest.mark.parametrize(
    ("files", "message"),
    [
        ({"u_a": (64, 3, 6, 2), "y_a": (64, 3, 6, 2), "u_b": (64, 3, 6, 2)}, "u_b.npy has no output file y_b.npy"),
        ({"u_a": (64, 3, 6, 2), "y_a": (64, 3, 5, 2)}, r"y has shape (64, 3, 5, 2), u has shape (64, 3, 6, 2)"),
        ({"u_a": (64, 3, 6, 2), "y_a": (64, 3, 6, 2), "u_b": (32, 3, 6, 2), "y_b": (32, 3, 6, 2)}, "mixed shapes"),
        ({"u_a": (64,), "y_a": (64,)}, "1-D"),
    ],
)
def test_bad_folders_are_one_line_naming_the_file(tmp_path, files, message):
    for name, shape in files.items():
        np.save(tmp_path / f"{name}.npy", np.ones(shape))
    err = one_line(run("identify", ".", "--model", "auto", "--fs", "6400", "--out", "m.json", cwd=tmp_path))
    assert message in err and not (tmp_path / "m.json").exists()


def test_nan_in_a_record_is_named(tmp_path):
    y = np.ones((64, 3, 6, 2))
    y[10, 1, 4, 1] = np.nan
    np.save(tmp_path / "u_a.npy", np.ones((64, 3, 6, 2)))
    np.save(tmp_path / "y_a.npy", y)
    err = one_line(run("identify", ".", "--model", "mimo-linear", "--fs", "6400", "--out", "m.json", cwd=tmp_path))
    assert "y[10, 1, 4, 1] = nan is not finite" in err


def test_an_npz_with_channels_is_multichannel_data(tmp_path):
    np.savez(tmp_path / "run.npz", u=np.ones((256, 3)), y=np.ones((256, 3)))
    err = one_line(
        run("identify", "run.npz", "--model", "mimo-linear", "--fs", "6400", "--out", "m.json", cwd=tmp_path)
    )
    assert "realizations" in err  # routed to the MIMO identification, which needs nu realizations


def _write_folder(tmp_path):
    """A linear 3x3 system (modes at 640/790 Hz) measured with random-phase multisines at two
    levels, 6 realizations x 2 periods, written as u_/y_*.npy; returns the system, the
    multisine generator and the noise generator."""
    a, b, c, d = resonant_mimo()
    rng = np.random.default_rng(0)
    n = 512

    def multisine(level):
        spec = np.zeros((n // 2 + 1, 3), complex)
        spec[1:200] = np.exp(2j * np.pi * rng.random((199, 3)))
        u = np.fft.irfft(spec, n=n, axis=0)
        return u * level / u.std(axis=0)

    for level in (0.1, 0.2):
        u = np.empty((n, 3, 6, 2))
        y = np.empty((n, 3, 6, 2))
        for r in range(6):
            ur = multisine(level)
            u[:, :, r, :] = ur[:, :, None]
            y[:, :, r, :] = periodic_response(a, b, c, d, ur)[:, :, None] + 1e-9 * rng.standard_normal((n, 3, 2))
        np.save(tmp_path / f"u_{level * 1000:.0f}mV_train.npy", u)
        np.save(tmp_path / f"y_{level * 1000:.0f}mV_train.npy", y)
    return (a, b, c, d), multisine


def test_a_folder_identifies_and_its_model_simulates(tmp_path):
    """The identified model of :func:`_write_folder`'s records reproduces a new record."""
    (a, b, c, d), multisine = _write_folder(tmp_path)
    out = run("identify", ".", "--model", "mimo-linear", "--fs", "6400", "--out", "m.json", "--json", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    report = json.loads(out.stdout)
    assert report["data"]["train"]["sets"] == ["100mV", "200mV"] and report["data"]["train"]["realizations"] == 12
    test_u = multisine(0.15)
    truth = periodic_response(a, b, c, d, test_u)
    np.save(tmp_path / "U.npy", test_u)
    np.save(tmp_path / "Y0.npy", truth[:100])
    out = run("simulate", "m.json", "U.npy", "--init-output", "Y0.npy", "--out", "YHAT.npy", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    yhat = np.load(tmp_path / "YHAT.npy")
    rel = np.sqrt(np.mean((yhat[100:] - truth[100:]) ** 2)) / np.sqrt(np.mean(truth**2))
    assert rel < 0.01, rel  # a new record within 1 % (noise 1e-9 m on outputs of ~1e-6 m)


def test_the_summary_says_which_model_each_figure_is_of(tmp_path):
    """``auto``'s held-out figures are the candidates' before the output-error refinement, and a
    refined kind reports the refinement: neither passes for the saved model's validation."""
    _write_folder(tmp_path)
    out = run("identify", ".", "--model", "auto", "--fs", "6400", "--out", "a.json", "--json", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    report = json.loads(out.stdout)
    assert "before the output-error refinement" in report["validation"]["model"]
    out = run("identify", ".", "--model", "mimo-hammerstein", "--fs", "6400", "--out", "h.json", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert "output-error refinement:" in out.stdout and "iterations in" in out.stdout
    summary = json.loads((tmp_path / "h.json").read_text())["fit"]["output_error"]
    assert summary["stopped"] in out.stdout and summary["best_validation_score"] <= summary["validation_score"]
