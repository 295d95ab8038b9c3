"""MimoModel: the Rust LFR simulation against a numpy reference, the periodic initial state,
the state estimate from measured outputs, the model file and the linear exports."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from piezohyst.errors import DataError, ParameterError
from piezohyst.models import load_model
from piezohyst.models.mimo import MimoModel, load_mimo_model, mimo_from_dict


def _modal(rng: np.random.Generator, pairs: int) -> np.ndarray:
    blocks = []
    for _ in range(pairs):
        r, th = rng.uniform(0.8, 0.97), rng.uniform(0.1, 2.5)
        blocks.append(r * np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]]))
    a = np.zeros((2 * pairs, 2 * pairs))
    for i, b in enumerate(blocks):
        a[2 * i : 2 * i + 2, 2 * i : 2 * i + 2] = b
    return a


def _lfr(seed: int = 0, dense: bool = False) -> MimoModel:
    rng = np.random.default_rng(seed)
    a = _modal(rng, 3)
    if dense:  # the same dynamics in a non-modal basis (the dense Rust path)
        t = rng.standard_normal((6, 6)) + 3 * np.eye(6)
        a = t @ a @ np.linalg.inv(t)
    nx, nu, ny, nw, nr = 6, 2, 3, 2, 3
    return MimoModel(
        A=a,
        B=rng.standard_normal((nx, nu)),
        C=rng.standard_normal((ny, nx)),
        D=0.1 * rng.standard_normal((ny, nu)),
        E=0.05 * rng.standard_normal((nx, nw)),
        F=0.05 * rng.standard_normal((ny, nw)),
        G=rng.standard_normal((nw, nx)),
        H=0.1 * rng.standard_normal((nw, nu)),
        thresholds=np.array([[0.0, 0.3, 0.8], [0.1, 0.5, 1.0]]),
        weights=rng.standard_normal((nw, nr)),
        fs=1000.0,
    )


def _reference(m: MimoModel, u: np.ndarray) -> np.ndarray:
    """The model's equations stepped in numpy (a test-only reference)."""
    x = np.zeros(m.nx)
    plays = np.zeros(m.thresholds.shape)
    out = np.empty((u.shape[0], m.ny))
    first_static = m.nw - m.static_channels
    for t in range(u.shape[0]):
        z = m.G @ x + m.H @ u[t]
        plays = np.minimum(np.maximum(plays, z[:, None] - m.thresholds), z[:, None] + m.thresholds)
        r = m.thresholds[first_static:]
        plays[first_static:] = r * np.tanh(z[first_static:, None] / r)
        w = (m.weights * plays).sum(axis=1)
        out[t] = m.C @ x + m.D @ u[t] + m.F @ w
        x = m.A @ x + m.B @ u[t] + m.E @ w
    return out


def _with_static(m: MimoModel) -> MimoModel:
    """The model with its last channel a static saturation (scales 0.2, 0.5, 1)."""
    th = m.thresholds.copy()
    th[-1] = [0.2, 0.5, 1.0]
    return replace(m, thresholds=th, static_channels=1)


@pytest.mark.parametrize(("dense", "static"), [(False, False), (True, False), (False, True), (True, True)])
def test_rust_simulation_equals_the_equations(dense: bool, static: bool) -> None:
    m = _lfr(dense=dense)
    if static:
        m = _with_static(m)
        assert m.static_channels == 1 and "static_channels=1" in repr(m)
    u = np.random.default_rng(1).standard_normal((300, 2))
    y = m.simulate(u, init="rest")
    np.testing.assert_allclose(y, _reference(m, u), rtol=1e-11, atol=1e-11)
    # a batch of records gives each record's own simulation
    yy = m.simulate(np.stack([u, -u]), init="rest")
    np.testing.assert_allclose(yy[1], _reference(m, -u), rtol=1e-11, atol=1e-11)


def test_periodic_state_is_the_steady_state() -> None:
    m = _lfr()
    rng = np.random.default_rng(2)
    u = rng.standard_normal((400, 2))
    # the steady state: many periods from rest; the last one is what a periodic start gives
    long = _reference(m, np.tile(u, (12, 1)))[-400:]
    y = m.simulate(u, init="periodic")
    assert np.abs(y - long).max() < 1e-6 * np.abs(long).max()
    y_rest = m.simulate(u, init="rest")
    assert np.abs(y_rest - long)[:20].max() > 1e-2 * np.abs(long).max()  # rest is not steady state


def test_state_from_measured_outputs_reproduces_a_record() -> None:
    m = MimoModel.linear(_lfr().A, _lfr().B, _lfr().C, _lfr().D, fs=1000.0, init={"method": "rest", "ridge": 1e-8})
    rng = np.random.default_rng(3)
    u = rng.standard_normal((500, 2))
    x0 = rng.standard_normal(m.nx)
    y_true, _, _ = m.run(u[None], np.array([x0]))
    y = m.simulate(u, init_output=y_true[0, :100])  # 100 outputs set the state
    assert np.abs(y - y_true[0]).max() < 1e-6 * np.abs(y_true).max()
    assert np.abs(m.simulate(u, init="rest") - y_true[0])[:10].max() > 0.1  # without them it is wrong


def test_file_round_trip(tmp_path: Path) -> None:
    m = _lfr()
    p = m.save(tmp_path / "m.json")
    back = load_mimo_model(p)
    u = np.random.default_rng(4).standard_normal((100, 2))
    np.testing.assert_array_equal(back.simulate(u), m.simulate(u))
    assert back.to_dict() == m.to_dict()
    # static channels are in the file; a file without dims.nt has none
    ms = _with_static(m)
    back = load_mimo_model(ms.save(tmp_path / "s.json"))
    assert back.static_channels == 1
    np.testing.assert_array_equal(back.simulate(u), ms.simulate(u))
    assert np.abs(ms.simulate(u) - m.simulate(u)).max() > 1e-3  # the channel is not a play
    d = m.to_dict()
    del d["dims"]["nt"]
    assert mimo_from_dict(d).static_channels == 0
    with pytest.raises(DataError, match="load_mimo_model"):  # load_model points to the MIMO loader
        load_model(p)
    (tmp_path / "bad.json").write_text('{"kind": "mimo", "schema_version": 1, "dims": {}}')
    with pytest.raises(DataError, match="bad.json"):
        load_mimo_model(tmp_path / "bad.json")


def test_bad_arguments_are_named() -> None:
    m = _lfr()
    with pytest.raises(ParameterError, match=r"u has shape \(10, 3\)"):
        m.simulate(np.zeros((10, 3)))
    with pytest.raises(ParameterError, match="not finite"):
        m.simulate(np.full((10, 2), np.nan))
    with pytest.raises(ParameterError, match=r"B has shape"):
        MimoModel.linear(np.eye(2), np.ones((3, 1)), np.ones((1, 2)), np.zeros((1, 1)), fs=1.0)
    with pytest.raises(ParameterError, match="thresholds"):
        MimoModel(**{**_parts(m), "thresholds": -np.ones((2, 3))})
    with pytest.raises(ParameterError, match="fs"):
        MimoModel(**{**_parts(m), "fs": 0.0})


def _parts(m: MimoModel) -> dict[str, object]:
    keys = ("A", "B", "C", "D", "E", "F", "G", "H", "thresholds", "weights", "fs")
    return {k: getattr(m, k) for k in keys}


def test_linear_exports_agree() -> None:
    m = _lfr()
    lin = MimoModel.linear(*m.linear_part(), fs=m.fs)
    f = np.array([5.0, 50.0, 200.0])
    g = lin.frequency_response(f)
    import control

    sys = lin.to_control()
    gc = np.array([sys(np.exp(2j * np.pi * fi / m.fs)) for fi in f])
    np.testing.assert_allclose(gc, g, rtol=1e-10)
    ac, bc, _, _ = lin.continuous()
    from scipy.signal import cont2discrete

    ad, bd, *_ = cont2discrete((ac, bc, lin.C, lin.D), 1 / m.fs, method="zoh")
    np.testing.assert_allclose(ad, lin.A, atol=1e-9)
    np.testing.assert_allclose(bd, lin.B, atol=1e-9)
    assert lin.to_scipy().dt == pytest.approx(1e-3)
    assert isinstance(control.ss(lin.A, lin.B, lin.C, lin.D, 1e-3), type(sys))


def test_static_channels_are_checked() -> None:
    m = _lfr()
    with pytest.raises(ParameterError, match=r"thresholds\[1, 0\] = 0.0 \(a static channel's scale\) must be > 0"):
        replace(m, thresholds=np.array([[0.0, 0.3, 0.8], [0.0, 0.5, 1.0]]), static_channels=1)
    with pytest.raises(ParameterError, match=r"static_channels = 3 must be an integer in \[0, nw = 2\]"):
        replace(m, static_channels=3)
    with pytest.raises(ParameterError, match="static_channels = 1.0"):
        replace(m, static_channels=1.0)  # type: ignore[arg-type]
