"""MIMO identification (issue 15): the BLA recovers a known system's FRF, the subspace method
its poles, the residue fit its held-out outputs, and the LFR beats the linear model on held-out
realizations of a system with hysteresis in its feedback."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

from piezohyst.cli.main import main
from piezohyst.errors import ParameterError
from piezohyst.identify.mimo import (
    INIT_RIDGES,
    MimoRecords,
    MimoSettings,
    choose_init_ridge,
    identify_mimo,
    protocol_rmse,
    read_multisine_folder,
    subspace,
)
from piezohyst.models.mimo import MimoModel, load_mimo_model
from piezohyst.signals.frf import estimate_bla

N = 1024
FS = 1000.0


def _system(feedback: float = 0.0) -> MimoModel:
    """A 3x3 stage with three lightly damped modes; with ``feedback``, play operators on the
    outputs feed back (hysteresis that moves the resonances with amplitude)."""
    rng = np.random.default_rng(7)
    blocks = []
    for f, zeta in ((60.0, 0.03), (170.0, 0.02), (320.0, 0.04)):
        s = -zeta * 2 * np.pi * f + 1j * 2 * np.pi * f * np.sqrt(1 - zeta**2)
        p = np.exp(s / FS)
        blocks.append(np.array([[p.real, -p.imag], [p.imag, p.real]]))
    a = np.zeros((6, 6))
    for i, b in enumerate(blocks):
        a[2 * i : 2 * i + 2, 2 * i : 2 * i + 2] = b
    b = rng.standard_normal((6, 3)) * 0.3
    c = rng.standard_normal((3, 6))
    d = np.zeros((3, 3))
    if feedback == 0.0:
        return MimoModel.linear(a, b, c, d, fs=FS)
    nr = 2
    return MimoModel(
        a, b, c, d,
        E=-0.02 * feedback * np.repeat(b, nr, axis=1), F=np.zeros((3, 6)),
        G=np.repeat(c, nr, axis=0), H=np.zeros((6, 3)),
        thresholds=np.tile([[1.0], [4.0]], (3, 1)), weights=np.ones((6, 1)), fs=FS, structure="lfr",
    )  # fmt: skip


def _multisine(rng: np.random.Generator, realizations: int, rms: float) -> np.ndarray:
    k = np.arange(1, int(0.4 * N))
    spec = np.zeros((N // 2 + 1, 3, realizations), dtype=complex)
    spec[k] = np.exp(2j * np.pi * rng.random((k.size, 3, realizations)))
    u = np.fft.irfft(spec, n=N, axis=0)
    return u / u.std(axis=0, keepdims=True) * rms


def _records(m: MimoModel, rms: float, seed: int, noise: float = 1e-3, realizations: int = 6) -> np.ndarray:
    rng = np.random.default_rng(seed)
    u = _multisine(rng, realizations, rms)  # (N, 3, R)
    y = m.simulate(np.ascontiguousarray(np.moveaxis(u, 2, 0)), init="periodic")  # (R, N, 3) steady state
    y = np.moveaxis(y, 0, 2)
    uu = np.stack([u, u], axis=3)
    yy = np.stack([y, y], axis=3) + noise * rng.standard_normal((N, 3, realizations, 2))
    return uu, yy


def test_bla_recovers_a_known_frf_with_its_noise_level() -> None:
    m = _system()
    u, y = _records(m, 1.0, 0, noise=1e-3)
    bla = estimate_bla(u, y, FS)
    g_true = m.frequency_response(bla.freqs)
    err = np.abs(bla.G - g_true)
    assert np.median(err / np.abs(g_true)) < 5e-3
    # the noise variance predicts the actual error of the estimate (within a factor 3, median)
    ratio = np.median(err**2 / bla.noise_var)
    assert 1 / 3 < ratio < 3
    # a linear system: no nonlinear distortion beyond the noise (total ~ noise)
    assert np.median(bla.total_var / bla.noise_var) < 3
    if importlib.util.find_spec("pandas") is not None:
        assert len(bla.to_pandas()) == bla.freqs.size * 9


def test_subspace_recovers_the_poles() -> None:
    m = _system()
    k = np.arange(1, 400)
    g = m.frequency_response(k * FS / N)
    a, b, c, d = subspace(g, k / N, order=6)
    want = np.sort_complex(np.linalg.eigvals(m.A))
    got = np.sort_complex(np.linalg.eigvals(a))
    np.testing.assert_allclose(got, want, atol=1e-8)
    g2 = MimoModel.linear(a, b, c, d, fs=FS).frequency_response(k * FS / N)
    assert np.abs(g2 - g).max() < 1e-6 * np.abs(g).max()


@pytest.mark.parametrize(("pole", "want"), [(0.99995, 0.9999), (1.02, 0.9999 / 1.02), (0.5, 0.5)])
def test_subspace_keeps_every_pole_within_the_radius(pole: float, want: float) -> None:
    """A pole between ``radius`` and 1 goes onto ``radius`` (reflecting it would leave it at
    ``radius / |p| > radius``, which the output-error refinement refused); an unstable one is
    reflected; a pole inside is kept."""
    m = MimoModel.linear(A=[[pole]], B=[[1.0]], C=[[1.0]], D=[[0.0]], fs=FS)
    k = np.arange(1, 200)
    a, _, _, _ = subspace(m.frequency_response(k * FS / N), k / N, order=1, radius=0.9999)
    assert abs(abs(np.linalg.eigvals(a)[0]) - want) < 1e-6


def _two_levels(m: MimoModel) -> MimoRecords:
    sets = []
    for i, rms in enumerate((0.5, 1.5)):
        u, y = _records(m, rms, 10 + i, noise=1e-3)
        sets.append((f"level{i}", u, y))
    return MimoRecords.from_sets(sets, FS)


def test_linear_fit_predicts_held_out_realizations_to_the_noise() -> None:
    rec = _two_levels(_system())
    folds = rec.folds()
    res = identify_mimo(rec.select(folds[0]), "mimo-linear", settings=MimoSettings(order=6))
    t = rec.select(folds[1])
    err = protocol_rmse(res.model, t.u, t.y)
    assert err.mean() < 1.5e-3  # the noise is 1e-3
    # the realization repeats a pole per rank of its residue: every pole is a true one
    got = np.linalg.eigvals(res.model.A)
    want = np.linalg.eigvals(_system().A)
    assert np.abs(got[:, None] - want[None, :]).min(axis=1).max() < 1e-4  # from noisy data


def test_lfr_beats_linear_on_held_out_data_of_a_hysteretic_system() -> None:
    true = _system(feedback=1.0)
    rec = _two_levels(true)
    folds = rec.folds()
    t = rec.select(folds[1])
    fit = rec.select(folds[0])
    lin = identify_mimo(fit, "mimo-linear", settings=MimoSettings(order=6)).model
    lfr = identify_mimo(fit, "mimo-lfr", settings=MimoSettings(order=6, iterations=2)).model
    e_lin = protocol_rmse(lin, t.u, t.y).mean()
    e_lfr = protocol_rmse(lfr, t.u, t.y).mean()
    assert e_lfr < 0.5 * e_lin, (e_lfr, e_lin)
    assert lfr.structure == "lfr" and lfr.nw > 0


def _folder(tmp_path: Path, m: MimoModel) -> Path:
    d = tmp_path / "train"
    d.mkdir()
    for i, rms in enumerate((0.5, 1.5)):
        u, y = _records(m, rms, 20 + i)
        np.save(d / f"u_{i}_train.npy", u)
        np.save(d / f"y_{i}_train.npy", y)
    return d


def test_cli_identify_auto_on_a_folder(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    d = _folder(tmp_path, _system(feedback=1.0))
    rec = read_multisine_folder(d, FS)
    assert rec.labels[0] == "0" and rec.u.shape == (N, 3, 12, 2)
    out = tmp_path / "m.json"
    code = main(["identify", str(d), "--model", "mimo-linear", "--fs", "1000", "--out", str(out), "--json"])
    assert code == 0
    report = json.loads(capsys.readouterr().out)
    assert report["model"] == "mimo-linear" and report["data"]["train"]["realizations"] == 12
    m = load_mimo_model(out)
    assert m.fit["kind"] == "mimo-linear"
    assert main(["identify", str(d), "--model", "pi", "--fs", "1000", "--out", str(tmp_path / "x.json")]) == 2
    assert "does not fit multi-channel DATA" in capsys.readouterr().err
    assert main(["identify", str(d), "--model", "mimo-lfr", "--out", str(tmp_path / "y.json")]) == 2
    assert "--fs" in capsys.readouterr().err


def test_init_ridge_trusts_the_outputs_when_the_records_start_off_the_periodic_state() -> None:
    """Records that start in a transient (not the periodic steady state the model assumes):
    only the measured outputs tell the state, and the smallest ridge wins; the same records
    in steady state with noise: the periodic state wins, the largest ridge."""
    rng = np.random.default_rng(5)
    # two slow modes (radius 0.998: a state error lasts a third of the record)
    a = np.zeros((4, 4))
    for i, ang in enumerate((0.2, 0.5)):
        a[2 * i : 2 * i + 2, 2 * i : 2 * i + 2] = 0.998 * np.array(
            [[np.cos(ang), -np.sin(ang)], [np.sin(ang), np.cos(ang)]]
        )
    m = MimoModel.linear(a, 0.1 * rng.standard_normal((4, 3)), rng.standard_normal((3, 4)), np.zeros((3, 3)), fs=FS)
    u = _multisine(rng, 3, 1.0)  # (N, 3, R)
    ur = np.ascontiguousarray(np.moveaxis(u, 2, 0))
    st = m.periodic_state(ur) + 3.0 * rng.standard_normal((3, m.state_len))
    y_off, _, _ = m.run(ur, st)  # every record from a state away from the periodic one
    y_ss = m.simulate(ur, init="periodic") + 0.05 * rng.standard_normal((3, N, 3))

    def recs(y: np.ndarray) -> MimoRecords:
        four = lambda a: np.stack([np.moveaxis(a, 0, 2)] * 2, axis=3)  # noqa: E731
        return MimoRecords.from_sets([("1V", four(ur), four(y))], fs=FS)

    # few outputs per state (4 samples of 3 outputs, 4 states): their noise is easily fitted
    off, off_scores = choose_init_ridge(m, recs(y_off), skip=4)
    ss, ss_scores = choose_init_ridge(m, recs(y_ss), skip=4)
    assert off.init["ridge"] == INIT_RIDGES[0] and ss.init["ridge"] == INIT_RIDGES[-1], (off_scores, ss_scores)
    assert off_scores["1"] > 3 * off_scores["0.0001"], off_scores
    assert ss_scores["0.0001"] > 1.05 * ss_scores["1"], ss_scores
    assert m.init["ridge"] == 1e-3  # the model given is not changed
    with pytest.raises(ParameterError, match=r"ridges = \[0\.0\]"):
        choose_init_ridge(m, recs(y_ss), ridges=[0.0])


@pytest.mark.parametrize(("init", "match"), [
    ({"ridge": 0.0}, "init.ridge = 0.0 must be a finite number > 0"),
    ({"ridge": float("nan")}, "init.ridge = nan"),
    ({"ridge": "1e-3"}, "init.ridge = '1e-3'"),
    ({"periods": -1}, "init.periods = -1 must be an integer >= 0"),
    ({"periods": 1.5}, "init.periods = 1.5"),
])  # fmt: skip
def test_init_settings_are_checked(init: dict[str, object], match: str) -> None:
    m = _system()
    with pytest.raises(ParameterError, match=match):
        MimoModel.linear(m.A, m.B, m.C, m.D, fs=FS, init={"method": "periodic", **init})
