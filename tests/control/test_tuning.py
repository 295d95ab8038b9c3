"""track(), tune() and `piezohyst track`: tracking metrics, gain tuning by simulation, the
command line and the tracking figure."""

import json

import matplotlib
import numpy as np
import pytest

import piezohyst as ph
from piezohyst.cli import main
from piezohyst.control import SMC, VelocityObserver

matplotlib.use("Agg")

STAGE = ph.virtual_stage()
FS = 1 / STAGE.sample_time


def triangle_5hz(seconds=0.5):
    return ph.triangle(5, 5e-6, seconds, FS, offset=7e-6)[1]


def test_track_metrics_leave_out_the_start_and_match_a_direct_computation():
    ref = triangle_5hz()
    res = ph.track(ph.PID(kp=2e6, ki=2e9), ref, stage=STAGE, rng=3, skip=0.2)
    k = round(0.2 * FS)
    e = ref[k:] - res.position[k:]
    m = res.metrics
    assert m["rmse"] == pytest.approx(np.sqrt(np.mean(e**2)), rel=1e-12)
    assert m["max_error"] == pytest.approx(np.abs(e).max(), rel=1e-12)
    assert m["normalized_max_error"] == pytest.approx(np.abs(e).max() / np.ptp(ref[k:]), rel=1e-12)
    # the start-up transient is excluded: the whole-record error is larger
    assert np.abs(ref - res.position).max() > m["max_error"]
    with pytest.raises(ValueError, match="skip = 1.0 s leaves fewer than 2"):
        ph.track(ph.PID(kp=2e6), ref, stage=STAGE, skip=1.0)


def test_tune_finds_better_gains_than_its_start_and_respects_the_constraints():
    model = STAGE.params
    ref = triangle_5hz(0.3)
    start = SMC(model, kp=2e5, kv=5e2, ks=3.0, phi=0.08, cemf=True, observer=VelocityObserver(300.0))
    before = ph.track(start, ref, stage=STAGE, rng=1, skip=0.1).metrics["rmse"]
    res = ph.tune(
        start,
        {"kp": (1e5, 1e7), "kv": (3e2, 5e3), "ks": (2.0, 40.0), "phi": (3e-3, 0.1)},
        ref,
        stage=STAGE,
        method="de",
        rng=2,
        max_iterations=6,
        population_size=12,
        skip=0.1,
    )
    assert set(res.gains) == {"kp", "kv", "ks", "phi"}
    for name, (lo, hi) in {"kp": (1e5, 1e7), "kv": (3e2, 5e3), "ks": (2.0, 40.0), "phi": (3e-3, 0.1)}.items():
        assert lo <= res.gains[name] <= hi
        assert getattr(res.controller, name) == res.gains[name]
    after = ph.track(res.controller, ref, stage=STAGE, rng=1, skip=0.1).metrics["rmse"]
    assert after < 0.5 * before  # measured ~0.04 um vs ~0.3 um
    assert res.rmse == pytest.approx(after, rel=0.3)  # same plant, different noise seed
    assert len(res.history["best_cost"]) == res.history["best_cost"].size
    assert np.all(np.diff(res.history["best_cost"]) <= 0)
    # same seed, same result
    again = ph.tune(
        start,
        {"kp": (1e5, 1e7), "kv": (3e2, 5e3), "ks": (2.0, 40.0), "phi": (3e-3, 0.1)},
        ref,
        stage=STAGE,
        method="de",
        rng=2,
        max_iterations=6,
        population_size=12,
        skip=0.1,
    )
    assert again.gains == res.gains


def test_tune_rejects_bad_requests():
    c = SMC(STAGE.params)
    ref = triangle_5hz(0.1)
    with pytest.raises(ValueError, match="has no field 'kq'"):
        ph.tune(c, {"kq": (1, 2)}, ref, stage=STAGE)
    with pytest.raises(ValueError, match=r"gains\['kp'\] = \(5.0, 1.0\): low must be < high"):
        ph.tune(c, {"kp": (5.0, 1.0)}, ref, stage=STAGE)
    with pytest.raises(ValueError, match=r"gains\['alpha'\] low = 0.0 must be > 0 with log_scale=True"):
        ph.tune(c, {"alpha": (0.0, 1.0)}, ref, stage=STAGE)
    with pytest.raises(TypeError, match="controller must be a piezohyst controller"):
        ph.tune(object(), {"kp": (1, 2)}, ref, stage=STAGE)


def test_unstable_candidates_cost_inf_not_an_error():
    # kv + alpha <= 0 for part of the box: those candidates are rejected, the others tuned
    c = SMC(STAGE.params, kp=1e6, kv=2e3, ks=20.0, phi=0.01, cemf=True, observer=VelocityObserver(300.0))
    res = ph.tune(
        c,
        {"kv": (-5e3, 5e3)},
        triangle_5hz(0.2),
        stage=STAGE,
        method="de",
        rng=1,
        max_iterations=3,
        population_size=8,
        log_scale=False,
        skip=0.05,
    )
    assert res.gains["kv"] > 0
    assert np.isfinite(res.rmse)


def test_plot_shows_tracking_zoom_and_error():
    ref = triangle_5hz(0.3)
    res = ph.track(ph.PID(kp=2e6, ki=2e9), ref, stage=STAGE, rng=1)
    fig = res.plot(zoom=(0.1, 0.15))
    ax_track, ax_err = fig.axes[:2]
    np.testing.assert_array_equal(ax_track.lines[1].get_ydata(), res.position * 1e6)
    np.testing.assert_array_equal(ax_err.lines[0].get_ydata(), res.error * 1e6)
    inset = ax_track.child_axes[0]
    assert inset.lines[0].get_xdata().min() >= 0.1 and inset.lines[0].get_xdata().max() <= 0.15


def test_cli_track_prints_metrics_and_json(capsys, tmp_path):
    assert (
        main(
            [
                "track",
                "--controller",
                "smc-cemf",
                "--reference",
                "triangle",
                "--freq",
                "5",
                "--amp",
                "5",
                "--offset",
                "7",
                "--duration",
                "0.4",
                "--json",
            ]
        )
        == 0
    )
    out = json.loads(capsys.readouterr().out)
    assert out["controller"] == "smc-cemf"
    # Case 2 on the stage's own parameters: far below the 0.75 um of open loop
    assert out["metrics"]["rmse"] < 0.1e-6
    plot = tmp_path / "t.png"
    assert main(["track", "--controller", "open-loop", "--duration", "0.3", "--plot", str(plot)]) == 0
    assert plot.stat().st_size > 1000
    assert "RMSE" in capsys.readouterr().out
    assert main(["track", "--controller", "open-loop", "--duration", "0.3", "--plot", str(plot)]) == 2
    assert "exists; pass --force" in capsys.readouterr().err
    assert main(["track", "--controller", "pid", "--amp", "50"]) == 2
    assert "beyond the stage's stroke" in capsys.readouterr().err
    assert main(["track", "--controller", "pid", "--freq", "0"]) == 2
    assert "--freq = 0.0 must be > 0" in capsys.readouterr().err
