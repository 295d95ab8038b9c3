"""``piezohyst simulate`` for multi-channel models (issue 15 item 4): U (N, nu) in, YHAT (N, ny)
out, the state set from Y0 through the model's estimator, shapes named in every error.

The plumbing is tested here with a small discrete state-space model standing in for the
library's MIMO class (an LTI ``x+ = A x + B u, y = C x + D u`` with a least-squares state
estimator): the numbers it must produce are known in closed form."""

from __future__ import annotations

import json
from typing import ClassVar

import numpy as np
import pytest

import piezohyst.cli.simulate as S
from piezohyst.cli.main import main
from piezohyst.signals import read_channels


class LtiDouble:
    """x+ = A x + B u, y = C x + D u; x0 estimated by least squares from (u, y)."""

    kind = "lti-double"
    units: ClassVar[dict[str, str]] = {"input": "V", "output": "m"}

    def __init__(self, seed: int = 0, nx: int = 4, nu: int = 3, ny: int = 2) -> None:
        rng = np.random.default_rng(seed)
        q, _ = np.linalg.qr(rng.standard_normal((nx, nx)))
        self.A = q @ np.diag(np.linspace(0.5, 0.9, nx)) @ q.T
        self.B = rng.standard_normal((nx, nu))
        self.C = 1e-6 * rng.standard_normal((ny, nx))
        self.D = 1e-7 * rng.standard_normal((ny, nu))
        self.calls: list[str] = []

    @property
    def nu(self) -> int:
        return self.B.shape[1]

    @property
    def ny(self) -> int:
        return self.C.shape[0]

    def simulate(self, u, *, init_output=None):
        x0 = None if init_output is None else self.estimate_initial_state(u[: init_output.shape[0]], init_output)
        return self.run(u, x0)

    def run(self, u, x0=None):
        self.calls.append("run")
        x = np.zeros(self.A.shape[0]) if x0 is None else np.asarray(x0, dtype=float)
        y = np.empty((u.shape[0], self.ny))
        for k in range(u.shape[0]):  # a test double: tiny records only
            y[k] = self.C @ x + self.D @ u[k]
            x = self.A @ x + self.B @ u[k]
        return y

    def estimate_initial_state(self, u, y):
        self.calls.append(f"estimate:{u.shape}:{y.shape}")
        free = self.run(u)  # the response from rest
        nx = self.A.shape[0]
        obs = np.zeros((y.shape[0] * self.ny, nx))
        ak = np.eye(nx)
        for k in range(y.shape[0]):
            obs[k * self.ny : (k + 1) * self.ny] = self.C @ ak
            ak = self.A @ ak
        x0, *_ = np.linalg.lstsq(obs, (y - free).ravel(), rcond=None)
        return x0


@pytest.fixture
def model(monkeypatch, tmp_path):
    m = LtiDouble()
    (tmp_path / "m.json").write_text("{}")
    monkeypatch.setattr(S, "_read_simulated", lambda path: m)
    return m


def _record(m: LtiDouble, n: int = 200, seed: int = 1):
    rng = np.random.default_rng(seed)
    u = 0.1 * rng.standard_normal((n, m.nu))
    x0 = rng.standard_normal(m.A.shape[0])
    return u, x0, m.run(u, x0)


def test_u_and_y0_give_the_measured_output_back(model, tmp_path, capsys):
    u, _x0, y = _record(model)
    np.save(tmp_path / "U.npy", u)
    np.save(tmp_path / "Y0.npy", y[:20])
    model.calls.clear()
    code = main(["simulate", str(tmp_path / "m.json"), str(tmp_path / "U.npy"), "--init-output",
                 str(tmp_path / "Y0.npy"), "--out", str(tmp_path / "YHAT.npy"), "--json"])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    yhat = np.load(tmp_path / "YHAT.npy")
    assert yhat.shape == (200, 2)
    # the state comes from Y0 alone: the whole record is reproduced (an exact model, no noise)
    np.testing.assert_allclose(yhat, y, rtol=0, atol=1e-12)
    assert model.calls[0] == "estimate:(20, 3):(20, 2)"
    summary = json.loads(capsys.readouterr().out)
    assert summary["shape"] == [200, 2] and summary["init_samples"] == 20 and summary["n_inputs"] == 3
    assert summary["units"] == {"input": "V", "output": "m"}
    # without Y0 the model starts at rest: a different output over the transient
    assert main(["simulate", str(tmp_path / "m.json"), str(tmp_path / "U.npy"), "--out", str(tmp_path / "r.npy")]) == 0
    rest = np.load(tmp_path / "r.npy")
    np.testing.assert_allclose(rest, model.run(u), atol=1e-15)
    assert np.max(np.abs(rest[:5] - y[:5])) > 1e-7


def test_csv_and_npz_inputs_and_outputs(model, tmp_path, capsys):
    u, _, y = _record(model, n=50)
    np.savetxt(tmp_path / "U.csv", u, delimiter=",", header="u0,u1,u2", comments="")
    np.savez(tmp_path / "Y0.npz", y0=y[:10])
    m = str(tmp_path / "m.json")
    assert main(["simulate", m, str(tmp_path / "U.csv"), "--init-output", str(tmp_path / "Y0.npz"),
                 "--out", str(tmp_path / "Y.csv")]) == 0  # fmt: skip
    back = read_channels(tmp_path / "Y.csv", "Y")
    np.testing.assert_allclose(back, y, atol=1e-12)  # repr text: read back bit for bit
    assert (tmp_path / "Y.csv").read_text().splitlines()[0] == "y0,y1"
    np.savez(tmp_path / "U.npz", u=u, other=np.ones(3))
    assert main(["simulate", m, str(tmp_path / "U.npz"), "--input", "u", "--out", str(tmp_path / "Y.npz")]) == 0
    assert np.load(tmp_path / "Y.npz")["y"].shape == (50, 2)
    assert main(["simulate", m, str(tmp_path / "U.npz"), "--out", "-"]) == 2
    assert "name the array to read" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("u_shape", "y0_shape", "message"),
    [
        ((100, 2), (10, 2), r"U has shape \(100, 2\), the model has 3 inputs: expected \(100, 3\)"),
        ((100, 3), (10, 3), r"Y0 has shape \(10, 3\), the model has 2 outputs: expected \(M, 2\)"),
        ((100, 3), (101, 2), r"Y0 has 101 samples, more than U's 100"),
        ((3, 100), (10, 2), r"U has shape \(3, 100\), the model has 3 inputs"),
        ((100, 3, 2), (10, 2), r"U has shape \(100, 3, 2\): expected \(samples, channels\)"),
    ],
)
def test_shape_mismatches_are_named(model, tmp_path, capsys, u_shape, y0_shape, message):
    np.save(tmp_path / "U.npy", np.zeros(u_shape))
    np.save(tmp_path / "Y0.npy", np.zeros(y0_shape))
    code = main(["simulate", str(tmp_path / "m.json"), str(tmp_path / "U.npy"), "--init-output",
                 str(tmp_path / "Y0.npy"), "--out", str(tmp_path / "Y.npy")])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    import re

    assert re.search(message, err), err
    assert not (tmp_path / "Y.npy").exists()


def test_bad_values_and_options(model, tmp_path, capsys):
    u = np.zeros((100, 3))
    u[7, 1] = np.nan
    np.save(tmp_path / "U.npy", u)
    m = str(tmp_path / "m.json")
    assert main(["simulate", m, str(tmp_path / "U.npy"), "--out", str(tmp_path / "Y.npy")]) == 2
    assert r"U[7, 1] = nan is not finite (sample 7, channel 1)" in capsys.readouterr().err
    np.save(tmp_path / "U.npy", np.zeros((100, 3)))
    assert main(["simulate", m, str(tmp_path / "U.npy"), "--out", str(tmp_path / "Y.txt")]) == 2
    assert "written as .npy .npz .csv, not '.txt'" in capsys.readouterr().err
    assert main(["simulate", m, str(tmp_path / "U.npy"), "--rows", "0:10", "--out", str(tmp_path / "Y.npy")]) == 2
    assert "--rows = '0:10' applies to single-channel models" in capsys.readouterr().err
    assert main(["simulate", m, str(tmp_path / "U.npy"), "--init-output", str(tmp_path / "no.npy"),
                 "--out", str(tmp_path / "Y.npy")]) == 2  # fmt: skip
    assert "--init-output" in capsys.readouterr().err and not (tmp_path / "Y.npy").exists()
    np.save(tmp_path / "Y.npy", np.ones(2))
    assert main(["simulate", m, str(tmp_path / "U.npy"), "--out", str(tmp_path / "Y.npy")]) == 2
    assert "--force" in capsys.readouterr().err


def test_init_output_refused_for_a_single_channel_model(tmp_path, capsys):
    from piezohyst import PI

    PI([0.0, 0.2], [1.0, 0.5]).save(tmp_path / "pi.json")
    np.savetxt(tmp_path / "v.csv", np.linspace(0, 1, 20), header="input", comments="")
    np.save(tmp_path / "Y0.npy", np.zeros((5, 1)))
    code = main(["simulate", str(tmp_path / "pi.json"), str(tmp_path / "v.csv"), "--init-output",
                 str(tmp_path / "Y0.npy"), "--out", str(tmp_path / "o.csv")])  # fmt: skip
    assert code == 2
    assert "sets the state of a multi-channel model" in capsys.readouterr().err


def test_a_saved_mimo_model_end_to_end(tmp_path):
    """The library's MimoModel through the installed command, as the acceptance check runs it:
    YHAT equals MimoModel.simulate(U, init_output=Y0) exactly."""
    import subprocess
    import sys

    from tests.export.test_export_c_mimo import lfr_model

    m = lfr_model()
    m.save(tmp_path / "fsm.json")
    rng = np.random.default_rng(0)
    u = 0.3 * rng.standard_normal((8192, 3))
    truth = m.simulate(u)
    np.save(tmp_path / "U.npy", u)
    np.save(tmp_path / "Y0.npy", truth[:100])
    args = ["simulate", "fsm.json", "U.npy", "--init-output", "Y0.npy", "--out", "YHAT.npy", "--json"]
    out = subprocess.run([sys.executable, "-m", "piezohyst", *args], cwd=tmp_path, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    summary = json.loads(out.stdout)
    assert summary["model"] == "mimo (lfr)" and summary["init_samples"] == 100
    yhat = np.load(tmp_path / "YHAT.npy")
    assert yhat.shape == (8192, 3)
    np.testing.assert_array_equal(yhat, m.simulate(u, init_output=truth[:100]))
    # the record is the model's own periodic output: Y0's state reproduces it
    assert np.max(np.abs(yhat - truth)) < 1e-3 * np.max(np.abs(truth))
    np.save(tmp_path / "Y0.npy", truth[:100, :2])
    out = subprocess.run(
        [sys.executable, "-m", "piezohyst", *args, "--force"], cwd=tmp_path, capture_output=True, text=True
    )
    assert out.returncode == 2 and "Y0 has shape (100, 2), the model has 3 outputs: expected (M, 3)" in out.stderr
