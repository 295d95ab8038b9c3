"""Controller files and ``piezohyst export-c``: round trips, bad input, the generated C, and
the exported example compiled with ``cc`` against the C library, whose numbers must equal
Python's bit for bit."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import piezohyst as ph
from piezohyst import _core
from piezohyst.cli import main
from piezohyst.export_c import (
    CONTROLLER_PARAMS,
    LINK_LIBS,
    ExportedController,
    controller_from_dict,
    controller_to_dict,
    example_plan,
    load_controller,
    row_names,
    save_controller,
)

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def stage():
    return ph.virtual_stage()


@pytest.fixture(scope="module")
def mpi(stage):
    fs = 1.0 / stage.sample_time
    t = np.arange(int(1.0 * fs)) / fs
    u = 75 - 75 * np.clip(1 - 0.5 * t, 0.2, 1.0) * np.cos(2 * np.pi * 5 * t)
    x = stage.simulate(u).position
    return ph.identify_mpi(u[:-1], x[1:], operators=9).model


def controllers(stage, mpi):
    p = stage.params
    return {
        "open_loop": ph.OpenLoop(),
        "pid": ph.PID(kp=2e6, ki=2e9, kd=10.0),
        "smc": ph.SMC(p),
        "smc_cemf_super_twisting": ph.SMC(p, cemf=True, switching="super_twisting", k1=10.0, k2=1000.0),
        "absmc": ph.ABSMC.for_stage(p),
        "cemf_feedforward": ph.CemfFeedforward(p),
        "absmc_mpi": ph.Compensated(ph.ABSMC.linearized(2000.0, 0.7, c1=2e3, lam=2e3, ks=5e3, gamma_d=1e4), mpi),
        "inverse_ff": ph.InverseFeedforward(mpi, c1=1e-4),
        "pid_mpi_ilc": ph.ILC(ph.Compensated(ph.PID(kp=0.3, ki=1500.0), mpi), period=400, gain=0.3),
    }


def same_core(a, b):
    ka, pa, ia, la = a
    kb, pb, ib, lb = b
    assert ka == kb
    assert np.array_equal(np.asarray(pa), np.asarray(pb))
    assert (ia is None) == (ib is None)
    if ia is not None:
        assert ia[0] == ib[0] and list(ia[1]) == list(ib[1]) and np.array_equal(np.asarray(ia[2]), np.asarray(ib[2]))
        assert (ia[3], ia[4]) == (ib[3], ib[4])
    assert la == lb


# --------------------------------------------------------------------------------------------
# controller files


def test_controller_files_round_trip_exactly(tmp_path, stage, mpi):
    t = np.arange(600) * stage.sample_time
    ref = 8e-6 + 4e-6 * np.sin(2 * np.pi * 20 * t)
    for name, c in controllers(stage, mpi).items():
        path = save_controller(c, stage, tmp_path / f"{name}.json")
        d = json.loads(path.read_text())
        assert d["format"] == "piezohyst-controller" and d["schema_version"] == 1
        assert list(d["params"]) == list(CONTROLLER_PARAMS[d["kind"]])
        loaded = load_controller(path)
        assert isinstance(loaded, ExportedController)
        same_core(loaded.core(stage), c.core(stage))
        a = ph.closed_loop(stage, c, ref, rng=2)
        b = ph.closed_loop(stage, loaded, ref, rng=2)
        assert np.array_equal(a.command, b.command), name


def test_save_controller_keeps_existing_files(tmp_path, stage):
    path = save_controller(ph.PID(kp=1e6), stage, tmp_path / "c.json")
    with pytest.raises(FileExistsError, match="exists"):
        save_controller(ph.PID(kp=2e6), stage, path)
    assert load_controller(path).params[0] == 1e6
    save_controller(ph.PID(kp=2e6), stage, path, overwrite=True)
    assert load_controller(path).params[0] == 2e6
    assert not list(tmp_path.glob(".*tmp"))


def test_exported_controller_checks_the_sample_time(stage):
    c = controller_from_dict(controller_to_dict(ph.PID(kp=1e6), stage))
    other = ph.Stage(stage.params, stage.amplifier, stage.sensor, sample_time=5e-5)
    with pytest.raises(ValueError, match="sample_time"):
        c.core(other)


@pytest.mark.parametrize(
    "change, match",
    [
        (lambda d: d.update(format="nope"), "format"),
        (lambda d: d.update(schema_version=2), "schema_version"),
        (lambda d: d.update(kind="lqr"), "kind = 'lqr' is unknown"),
        (lambda d: d["params"].pop("kp"), "params of 'pid' must be an object with the keys"),
        (lambda d: d["params"].update(kp="big"), "params.kp = 'big' must be a number"),
        (lambda d: d["params"].update(kp=float("nan")), "params.kp = nan is not finite"),
        (lambda d: d["params"].update(kp=-1.0), "not valid: kp = -1 must be >= 0"),
        (lambda d: d["params"].update(u_min=200.0), "not valid"),
        (
            lambda d: d.update(ilc={"period": 0, "gain": 1.0, "forgetting": 1.0, "lead": 0, "delay": 0}),
            "ilc.period = 0",
        ),
        (lambda d: d.update(ilc={"period": 10}), "ilc must be null or an object"),
        (lambda d: d.update(inverse={"family": "xyz"}), "inverse.family = 'xyz' is unknown"),
        (lambda d: d.update(stage={}), "stage must be an object"),
        (lambda d: d["stage"].update(sample_time=-1.0), "stage.sample_time = -1.0 must be > 0"),
    ],
)
def test_bad_controller_files_are_named(stage, change, match):
    d = controller_to_dict(ph.PID(kp=1e6, ki=1e9), stage)
    change(d)
    with pytest.raises(ValueError, match=re.escape(match)):
        controller_from_dict(d)


def test_load_controller_bad_files(tmp_path):
    with pytest.raises(FileNotFoundError, match="does not exist"):
        load_controller(tmp_path / "none.json")
    (tmp_path / "x.json").write_text("{nope")
    with pytest.raises(ValueError, match="not valid JSON"):
        load_controller(tmp_path / "x.json")
    (tmp_path / "y.json").write_text("[1, 2]")
    with pytest.raises(ValueError, match="must be a JSON object"):
        load_controller(tmp_path / "y.json")


def test_parameter_names_match_the_core_and_the_c_library(c_library):
    """The flat layouts are defined three times (the Python binding, the C library, the names
    here): their lengths must agree for every kind."""
    import ctypes

    lib = ctypes.CDLL(str(c_library.with_suffix(".so")))
    codes = {"open_loop": 1, "pid": 2, "smc": 3, "absmc": 4, "cemf_feedforward": 5, "filtered_pid": 6}
    for kind, names in CONTROLLER_PARAMS.items():
        with pytest.raises(ValueError, match=r"takes (\d+) parameters") as e:
            _core.controller_initial_state((kind, np.zeros(0), None, None), 0.0)
        core_count = int(re.search(r"takes (\d+) parameters", str(e.value)).group(1))
        n = ctypes.c_size_t(0)
        assert lib.phs_controller_param_count(ctypes.c_uint32(codes[kind]), ctypes.byref(n)) == 0
        assert len(names) == core_count == n.value, kind


def test_row_names_cover_every_family():
    from tests.models_zoo import zoo

    for m in zoo().values():
        names = row_names(m.family, m.dims)
        assert len(names) == m.to_row().size and len(set(names)) == len(names)


# --------------------------------------------------------------------------------------------
# export-c: files and errors


def parse_c_array(text: str, name: str) -> np.ndarray:
    body = re.search(name + r"\[\d+\] = \{(.*?)\};", text, re.S).group(1)
    body = re.sub(r"/\*.*?\*/", "", body, flags=re.S)
    return np.array([float.fromhex(x) for x in body.replace(",", " ").split()])


def test_export_c_writes_exact_initializers(tmp_path, stage, mpi):
    mpath = tmp_path / "mpi.json"
    mpi.save(mpath)
    c = ph.Compensated(ph.ABSMC.linearized(2000.0, 0.7, c1=2e3, lam=2e3, ks=5e3, gamma_d=1e4), mpi)
    cpath = save_controller(c, stage, tmp_path / "absmc.json")
    out = tmp_path / "c"
    assert main(["export-c", str(mpath), str(cpath), "--out", str(out)]) == 0
    names = {p.name for p in out.iterdir()}
    assert {
        "piezohyst_model.h",
        "piezohyst_model.c",
        "piezohyst_controller.h",
        "piezohyst_controller.c",
        "example.c",
        "piezohyst.h",
    } <= names
    assert (out / "piezohyst.h").read_text() == (ROOT / "crates/capi/include/piezohyst.h").read_text()
    row = parse_c_array((out / "piezohyst_model.c").read_text(), "piezohyst_model_params")
    assert np.array_equal(row, mpi.to_row())
    params = parse_c_array((out / "piezohyst_controller.c").read_text(), "piezohyst_controller_params")
    assert np.array_equal(params, c.core(stage)[1])
    h = (out / "piezohyst_controller.h").read_text()
    n_state = _core.controller_initial_state(c.core(stage), 0.0).size
    assert f"#define PIEZOHYST_CONTROLLER_STATE_LEN {n_state}" in h
    assert "#define PIEZOHYST_CONTROLLER_HAS_INVERSE 1" in h


def run_cli(capsys, *argv):
    code = main(list(argv))
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def test_export_c_refuses_to_overwrite_and_bad_input(tmp_path, capsys, stage, mpi):
    mpath = tmp_path / "mpi.json"
    mpi.save(mpath)
    out = tmp_path / "c"
    assert run_cli(capsys, "export-c", str(mpath), "--out", str(out))[0] == 0
    before = (out / "piezohyst_model.c").read_text()
    code, _, err = run_cli(capsys, "export-c", str(mpath), "--out", str(out))
    assert code == 2 and "exists; pass --force" in err and err.count("\n") == 1
    assert run_cli(capsys, "export-c", str(mpath), "--out", str(out), "--force")[0] == 0
    assert (out / "piezohyst_model.c").read_text() == before
    # missing files, a file as --out, a controller on another model, bad options
    code, _, err = run_cli(capsys, "export-c", str(tmp_path / "none.json"), "--out", str(out))
    assert code == 2 and "no such file" in err
    code, _, err = run_cli(capsys, "export-c", str(mpath), "--out", str(mpath))
    assert code == 2 and "not a directory" in err
    other = ph.papers.mpi_seed2()
    cpath = save_controller(ph.InverseFeedforward(other), stage, tmp_path / "other.json")
    code, _, err = run_cli(capsys, "export-c", str(mpath), str(cpath), "--out", str(tmp_path / "d"))
    assert code == 2 and "export the model the controller was built on" in err
    assert not (tmp_path / "d").exists()
    code, _, err = run_cli(capsys, "export-c", str(mpath), str(mpath), "--out", str(tmp_path / "d"))
    assert code == 2 and "CONTROLLER" in err and "format" in err
    code, _, err = run_cli(capsys, "export-c", str(mpath), "--out", str(tmp_path / "d"), "--input-range", "2", "1")
    assert code == 2 and "--input-range" in err
    code, _, err = run_cli(capsys, "export-c", str(mpath), "--out", str(tmp_path / "d"), "--steps", "0")
    assert code == 2 and "--steps = 0" in err
    with pytest.raises(SystemExit) as e:  # usage errors: argparse, one line, exit 2
        main(["export-c", str(mpath)])
    assert e.value.code == 2 and "--out" in capsys.readouterr().err


# --------------------------------------------------------------------------------------------
# the exported example, compiled and run


@pytest.fixture(scope="module")
def c_library():
    if shutil.which("cc") is None:
        pytest.skip("no C compiler (cc)")
    if shutil.which("cargo") is not None:  # a no-op when the library is up to date
        subprocess.run(["cargo", "build", "--release", "-q", "-p", "piezohyst-capi"], cwd=ROOT, check=True)
    lib = ROOT / "target" / "release" / "libpiezohyst.a"
    if not lib.is_file():
        pytest.skip("the C library is not built (cargo build --release -p piezohyst-capi)")
    return lib


def build_example(out: Path, lib: Path, with_controller: bool) -> Path:
    sources = ["example.c", "piezohyst_model.c"] + (["piezohyst_controller.c"] if with_controller else [])
    exe = out / "example"
    cmd = [
        "cc",
        "-std=c99",
        "-O2",
        "-Wall",
        "-Wextra",
        "-Werror",
        "-pedantic",
        "-ffp-contract=off",
        f"-I{out}",
        *[str(out / s) for s in sources],
        str(lib),
        *LINK_LIBS.split(),
        "-o",
        str(exe),
    ]
    subprocess.run(cmd, check=True, capture_output=True, text=True)
    return exe


def with_map(model, mapped):
    """The model, or with an output map (a sensor offset of 2 um and a gain error of 5 %)."""
    return model.with_output_map(offset=2e-6, gain=1.05) if mapped else model


def pi_of(mpi):
    """A PI model (no constant term of its own) on MPI's thresholds."""
    return ph.PI(mpi.thresholds, np.abs(mpi.weights) + 1e-3, p0=0.05)


def preisach_creep():
    """A Preisach grid with a creep bank (issue 14): the row's creep tail in C too."""
    w = np.linspace(0.2e-6, 1e-6, 15) / 15
    return ph.Preisach(5, (0.0, 150.0), w, slope=2e-8, creep=ph.Creep(1e-4, [0.002, 0.05], [1e-9, 2e-9]))


@pytest.mark.parametrize(("family", "mapped"), [("mpi", False), ("mpi", True), ("pi", True), ("preisach+creep", True)])
def test_exported_model_example_runs(tmp_path, capsys, mpi, c_library, family, mapped):
    base = mpi if family == "mpi" else pi_of(mpi) if family == "pi" else preisach_creep()
    mpi = with_map(base, mapped)
    mpath = tmp_path / "mpi.json"
    mpi.save(mpath)
    out = tmp_path / "c"
    code, printed, _ = run_cli(capsys, "export-c", str(mpath), "--out", str(out))
    assert code == 0 and "cc -std=c99" in printed
    exe = build_example(out, c_library, False)
    r = subprocess.run([str(exe)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "max |model(inverse(y)) - y|" in r.stdout
    # the trace is Python's forward and inverse, bit for bit
    rows = np.array(
        [
            [float(x) for x in line.split()]
            for line in subprocess.run(
                [str(exe), "--trace"], capture_output=True, text=True, check=True
            ).stdout.splitlines()
        ]
    )
    plan = example_plan(mpi, None)
    k = np.arange(plan["steps"])
    phase = (k % plan["period"]) / float(plan["period"])
    lo, hi = plan["v_lo"], plan["v_hi"]
    v = np.where(phase < 0.5, lo + (hi - lo) * (2.0 * phase), lo + (hi - lo) * (2.0 - 2.0 * phase))
    assert np.array_equal(rows[:, 1], v)
    y = mpi.simulate(v)
    assert np.array_equal(rows[:, 2], y)
    assert np.array_equal(rows[:, 3], mpi.inverse().simulate(y))
    header = (out / "piezohyst_model.h").read_text()
    offset, gain = mpi.output_map.offset, mpi.output_map.gain
    assert f"#define PIEZOHYST_MODEL_OUTPUT_OFFSET {float(offset).hex()}" in header
    assert f"#define PIEZOHYST_MODEL_OUTPUT_GAIN {float(gain).hex()}" in header
    # the parameter row is the family's, map or not (the C ABI)
    assert np.array_equal(
        parse_c_array((out / "piezohyst_model.c").read_text(), "piezohyst_model_params"), mpi.to_row()
    )


@pytest.mark.parametrize(
    ("name", "mapped"),
    [
        ("smc_cemf_super_twisting", False),
        ("pid_mpi_ilc", False),
        ("absmc_mpi", False),
        ("pid_mpi_ilc", True),
        ("absmc_mpi", True),
    ],
)
def test_exported_controller_example_matches_python(tmp_path, stage, mpi, c_library, name, mapped):
    mpi = with_map(mpi, mapped)
    c = controllers(stage, mpi)[name]
    mpath = tmp_path / "mpi.json"
    mpi.save(mpath)
    cpath = save_controller(c, stage, tmp_path / "c.json")
    out = tmp_path / "c"
    assert main(["export-c", str(mpath), str(cpath), "--out", str(out), "--steps", "900"]) == 0
    exe = build_example(out, c_library, True)
    r = subprocess.run([str(exe)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "RMS error" in r.stdout
    trace = subprocess.run([str(exe), "--trace"], capture_output=True, text=True, check=True).stdout.splitlines()
    rows = np.array([[float(x) for x in line.split()] for line in trace])
    # the same loop in Python: the plant is the model, read one sample late
    loaded = load_controller(cpath)
    # behind an inverse the controller and the exported model use the row that holds the map
    plain = mpi.mapped_row()
    assert mapped == (plain is not mpi)
    plan = example_plan(plain, loaded, steps=900)
    spec = loaded.core(stage)
    fam, dims, row = plain.family, list(plain.dims), plain.to_row()
    plant = plain.initial_state()
    position = float(_core.simulate(fam, dims, row, np.zeros(1), plant)[0])
    state = _core.controller_initial_state(spec, position)
    period, lo, hi, ts = plan["period"], plan["x_lo"], plan["x_hi"], plan["ts"]
    expected = []
    for k in range(plan["steps"]):
        phase = float(k % period) / float(period)
        if phase < 0.5:
            rate, x = 2.0 * (hi - lo) / float(period), lo + (hi - lo) * (2.0 * phase)
        else:
            rate, x = -2.0 * (hi - lo) / float(period), lo + (hi - lo) * (2.0 - 2.0 * phase)
        y = position
        u = float(
            _core.controller_steps(spec, np.array([x]), np.array([rate / ts]), np.zeros(1), np.array([y]), state)[0]
        )
        position = float(_core.simulate(fam, dims, row, np.array([u]), plant)[0])
        expected.append((k, x, y, u))
    assert np.array_equal(rows, np.array(expected)), name


def test_exported_delayed_model_runs_its_delay_line(tmp_path, capsys, mpi, c_library):
    """A model with an input delay (issue 14): the C model step runs the delay line in its state
    (the trace is Python's simulate, bit for bit); the inverse inverts the undelayed model on the
    core state; the drift is not exported, and export-c says so."""
    drift = ph.models.model.Drift(taus=(50.0,), weights=(1e-7,), slope=1e-9)
    model = with_map(mpi, True).with_input_delay(3).with_drift(drift)
    mpath = tmp_path / "delayed.json"
    model.save(mpath)
    out = tmp_path / "c"
    code, _, err = run_cli(capsys, "export-c", str(mpath), "--out", str(out))
    assert code == 0 and "has a drift term" in err and "not exported" in err and err.count("\n") == 1
    header = (out / "piezohyst_model.h").read_text()
    n_core = _core.family_sizes(model.family, list(model.dims))[1]
    assert "#define PIEZOHYST_MODEL_INPUT_DELAY 3" in header
    assert f"#define PIEZOHYST_MODEL_CORE_STATE_LEN {n_core}" in header
    assert f"#define PIEZOHYST_MODEL_STATE_LEN {n_core + 4}" in header
    assert "drift" in header and "not exported" in header
    exe = build_example(out, c_library, False)
    r = subprocess.run([str(exe)], capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr  # the undelayed model reproduces the inverse's target
    trace = subprocess.run([str(exe), "--trace"], capture_output=True, text=True, check=True).stdout
    rows = np.array([[float(x) for x in line.split()] for line in trace.splitlines()])
    v = rows[:, 1]
    forward = model.with_drift(None)  # what C runs: delay line, core, output map
    assert np.array_equal(rows[:, 2], forward.simulate(v))
    assert np.array_equal(rows[:, 3], model.inverse().simulate(rows[:, 2]))
    assert model.state.size == n_core + 4  # Python's state has the same layout
