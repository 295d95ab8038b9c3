"""docs/spec.md §10 audit of the public API (issue 8): every public entry point, called with a valid
recipe in which one argument at a time is replaced by a bad value of a catalogued kind.

Each call must either succeed with finite results (the value happened to be acceptable, e.g.
a negative offset) or raise a :class:`piezohyst.PiezohystError` whose message names the
argument — never a bare builtin error from deep inside, a NaN result or a crash. The catalogue
and the recipes give several hundred calls; the count per kind is printed with ``-s`` and is
part of the hardening report.
"""

from __future__ import annotations

import collections
import math

import numpy as np
import pytest

import piezohyst as ph

STAGE = ph.virtual_stage()
T = np.arange(400) / 1000.0
V = 0.5 + 0.4 * np.sin(2 * np.pi * 5 * T) * np.linspace(1, 0.3, T.size)
Y = ph.papers.mpi_seed2().simulate(V)
REF = 8e-6 + 4e-6 * np.sin(2 * np.pi * 20 * np.arange(600) * 1e-4)


def _with(a, index, value):
    a = np.array(a, dtype=float)
    a.flat[index] = value
    return a


ARRAY_BAD = {
    "nan inside": lambda a: _with(a, np.size(a) // 2, np.nan),
    "inf inside": lambda a: _with(a, 1, np.inf),
    "empty": lambda a: np.array([]),
    "one sample": lambda a: np.asarray(a)[:1],
    "2-D": lambda a: np.stack([a, a], axis=-1),
    "strings": lambda a: ["a", "b", "c"],
    "None": lambda a: None,
    "complex": lambda a: np.asarray(a) + 1j,
    "ragged": lambda a: [[1.0, 2.0], [3.0]],
}
SCALAR_BAD = {
    "nan": lambda x: math.nan,
    "inf": lambda x: math.inf,
    "-inf": lambda x: -math.inf,
    "negative": lambda x: -abs(x) - 1.0,
    "zero": lambda x: 0.0,
    "string": lambda x: "abc",
    "None": lambda x: None,
    "list": lambda x: [x, x],
    "huge": lambda x: 1e300,
}

# name -> (callable, positional args, keyword args, names of array arguments, names of scalar arguments)
RECIPES = {
    "identify": (ph.identify, (V, Y), dict(model="mpi", operators=5), ["input", "output"], ["operators"]),
    "identify_pi": (ph.identify_pi, (V, Y), dict(operators=5), ["input", "output"], ["operators"]),
    "identify_mpi": (ph.identify_mpi, (V, Y), dict(operators=5), ["input", "output"], ["operators"]),
    "identify_preisach": (ph.identify_preisach, (V, Y), dict(levels=5), ["input", "output"], ["levels", "memory"]),
    "fit_metrics": (ph.fit_metrics, (Y, Y + 0.01), {}, ["predicted", "measured"], []),
    "tracking_metrics": (ph.tracking_metrics, (REF, REF * 1.01), {}, ["reference", "output"], []),
    "linearity_error": (ph.linearity_error, (REF, REF * 1.01), {}, ["desired", "output"], []),
    "hysteresis_percent": (ph.hysteresis_percent, (V, Y), dict(levels=50), ["input", "output"], ["levels"]),
    "closed_loop": (ph.closed_loop, (STAGE, ph.PID(kp=1e6, ki=1e9), REF), dict(rng=1), ["reference"], []),
    "track": (ph.track, (ph.PID(kp=1e6, ki=1e9), REF), dict(stage=STAGE, rng=1, skip=0.01), ["reference"], ["skip"]),
    "sine": (ph.sine, (10.0, 1.0, 0.1, 1000.0), {}, [], ["freq", "amplitude", "duration", "fs", "offset"]),
    "triangle": (
        ph.triangle,
        (10.0, 1.0, 0.1, 1000.0),
        dict(rounding=0.1),
        [],
        ["freq", "amplitude", "duration", "fs", "rounding"],
    ),
    "chirp": (ph.chirp, (1.0, 50.0, 1.0, 0.5, 1000.0), {}, [], ["f_start", "f_end", "amplitude", "duration", "fs"]),
    "multisine": (
        ph.multisine,
        (1.0, 50.0, 1.0, 1.0, 1000.0),
        dict(rng=0),
        [],
        ["f_min", "f_max", "amplitude", "period", "fs", "periods"],
    ),
    "variable_amplitude_sine": (
        ph.variable_amplitude_sine,
        (10.0, 1.0, 0.5, 1000.0),
        {},
        [],
        ["freq", "amplitude", "duration", "fs", "final_fraction"],
    ),
    "staircase": (ph.staircase, ([0.0, 1.0, 2.0], 0.01, 1000.0), {}, ["levels"], ["dwell", "fs"]),
    "PI": (ph.PI, ([0.0, 0.1, 0.2], [1.0, 0.5, 0.2]), dict(p0=1.0), ["thresholds", "weights"], ["p0"]),
    "Preisach": (ph.Preisach, (3, (0.0, 1.0), np.ones(6)), dict(memory=16), ["weights"], ["levels", "memory"]),
    "BoucWen": (ph.BoucWen, (1.0, 0.5, 0.2), dict(n=1.0, d=1.0), [], ["a", "beta", "gamma", "n", "d"]),
    "Dahl": (ph.Dahl, (3.0, 0.7, 1.5), {}, [], []),
    "Creep": (ph.Creep, (1e-3, [0.01, 0.1], [0.01, 0.02]), {}, ["taus", "weights"], ["ts"]),
    "PID": (ph.PID, (), dict(kp=1e6, ki=1e9, kd=1.0, tau_d=1e-4), [], ["kp", "ki", "kd", "tau_d"]),
    "OpenLoop": (ph.OpenLoop, (), dict(gain=7e6, offset=0.0), [], ["gain", "offset"]),
    "VelocityObserver": (ph.VelocityObserver, (), dict(bandwidth=1000.0), [], ["bandwidth", "delay"]),
    "SMC": (ph.SMC, (STAGE.params,), dict(kp=1e6, kv=2e3, ks=20.0, phi=0.01), [], ["kp", "kv", "ks", "phi", "alpha"]),
    "Amplifier": (
        ph.Amplifier,
        (),
        dict(v_min=-20.0, v_max=150.0, bandwidth=3000.0, slew_rate=1e5),
        [],
        ["v_min", "v_max", "bandwidth", "slew_rate"],
    ),
    "Sensor": (
        ph.Sensor,
        (),
        dict(quantization=1e-7, noise_std=1e-8, delay=1),
        [],
        ["quantization", "noise_std", "delay"],
    ),
    "StageParameters": (
        ph.StageParameters,
        (0.07, 100.0, 7e7, 10.5),
        {},
        [],
        ["mass", "damping", "stiffness", "tem", "capacitance"],
    ),
    "Stage": (
        ph.Stage,
        (STAGE.params,),
        dict(sample_time=1e-4, substeps=1, tolerance=0.05),
        [],
        ["sample_time", "substeps", "tolerance"],
    ),
    "LeafSpring": (
        ph.LeafSpring,
        (7.17e10, 0.01, 0.002, 0.02),
        {},
        [],
        ["youngs_modulus", "width", "thickness", "length"],
    ),
    "FlexureStage": (
        ph.FlexureStage,
        (6e7, 1.3e7, 0.01, 0.06),
        {},
        [],
        ["actuator_stiffness", "flexure_stiffness", "actuator_mass", "stage_mass", "zeta"],
    ),
    "BoucWenBenchmark": (
        ph.BoucWenBenchmark,
        (),
        {},
        [],
        ["mass", "damping", "stiffness", "alpha", "beta", "gamma", "nu"],
    ),
    "batch_rmse": (
        ph.batch_rmse,
        (ph.papers.mpi_seed2(), np.tile(ph.papers.mpi_seed2()._row, (3, 1)), V, Y),
        {},
        ["params", "input", "target"],
        [],
    ),
    "batch_simulate": (
        ph.batch_simulate,
        (ph.papers.mpi_seed2(), np.tile(ph.papers.mpi_seed2()._row, (3, 1)), V),
        {},
        ["params", "input"],
        [],
    ),
    "GeneralizedPI": (
        ph.GeneralizedPI,
        ([0.0, 0.1], [1.0, 0.5], (0.0, 1.0, 0.0, 0.0)),
        dict(input_range=(0.0, 1.0)),
        ["thresholds", "weights", "polynomial"],
        [],
    ),
    "RateDependentPI": (
        ph.RateDependentPI,
        ([0.0, 0.1], [1.0, 0.5], 1e-3),
        dict(p0=1.0, beta=0.1, filter_tau=0.01),
        ["thresholds", "weights"],
        ["ts", "p0", "beta", "filter_tau"],
    ),
    "Duhem": (ph.Duhem, (1.0, [0.0, 1.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]), {}, ["f", "g"], ["alpha"]),
    "OutputMap": (ph.models.OutputMap, (), dict(offset=0.0, gain=1.0), [], ["offset", "gain"]),
    "PlayOperator": (ph.models.PlayOperator, (0.1,), {}, [], ["threshold"]),
    "ABSMC": (
        ph.ABSMC,
        (1.0, (1.0, 1.0)),
        dict(c1=2e3, lam=2e3, ks=1e3, phi=1e-3, gamma_theta=(1e12, 1e6), gamma_d=1e6, d0=0.0, theta_range=3.0),
        ["theta", "gamma_theta"],
        ["b", "c1", "lam", "ks", "phi", "gamma_d", "d0", "theta_range", "d_max"],
    ),
    "ILC": (
        ph.ILC,
        (ph.PID(kp=1e6), 100),
        dict(gain=0.5, forgetting=1.0, lead=3),
        [],
        ["period", "gain", "forgetting", "lead"],
    ),
    "InverseFeedforward": (ph.InverseFeedforward, (ph.papers.mpi_seed2(),), dict(c1=0.0, c2=0.0), [], ["c1", "c2"]),
    "CemfFeedforward": (ph.CemfFeedforward, (STAGE.params,), dict(u_min=-20.0, u_max=150.0), [], ["u_min", "u_max"]),
    "model.simulate": (ph.papers.mpi_seed2().simulate, (V,), {}, ["input"], []),
    "inverse.simulate": (ph.PI([0.0, 0.1, 0.2], [1.0, 0.5, 0.2]).inverse().simulate, (np.abs(V),), {}, ["desired"], []),
    "stage.simulate": (STAGE.simulate, (np.full(300, 50.0),), {}, ["command"], []),
    # issue 15: multi-channel records and the MIMO feedforward
    "MultiRecord": (
        ph.signals.MultiRecord,
        (np.ones((40, 3, 2, 2)), np.ones((40, 3, 2, 2))),
        dict(fs=6400.0),
        ["u", "y"],
        ["fs"],
    ),
    "MimoFeedforward": (
        ph.control.MimoFeedforward,
        (np.diag([0.5, 0.6]), np.eye(2), np.eye(2), np.zeros((2, 2))),
        dict(fs=1000.0, bandwidth=200.0),
        ["A", "B"],
        ["fs", "bandwidth", "regularization"],
    ),
    "MimoFeedforward.linear_command": (
        ph.control.MimoFeedforward(np.diag([0.5, 0.6]), np.eye(2), np.eye(2), np.zeros((2, 2)), fs=1e3).linear_command,
        (np.ones((50, 2)),),
        {},
        ["reference"],
        [],
    ),
    "mirror_matrix": (ph.control.mirror_matrix, (0.02,), {}, [], ["radius"]),
}


def _signature_names(fn):
    import inspect

    try:
        return list(inspect.signature(fn).parameters)
    except (TypeError, ValueError):
        return []


def _calls():
    """(recipe name, argument, bad kind, thunk) for every perturbation."""
    out = []
    for name, (fn, args, kwargs, arrays, scalars) in RECIPES.items():
        params = _signature_names(fn)
        for arg in arrays + scalars:
            catalogue = ARRAY_BAD if arg in arrays else SCALAR_BAD
            for kind, bad in catalogue.items():
                a, kw = list(args), dict(kwargs)
                if arg in kw:
                    kw[arg] = bad(kw[arg])
                else:
                    i = params.index(arg)
                    if i < len(a):
                        a[i] = bad(a[i])
                    else:
                        kw[arg] = bad(1.0)
                out.append((name, arg, kind, (lambda fn=fn, a=tuple(a), kw=kw: fn(*a, **kw))))
    return out


CALLS = _calls()
OUTCOMES = collections.Counter()


def _finite(result) -> bool:
    """Every number in a result (arrays, tuples, dicts, dataclass fields) is finite."""
    if result is None or isinstance(result, (str, bool)):
        return True
    if isinstance(result, (int, float, np.floating, np.integer)):
        return bool(np.isfinite(result))
    if isinstance(result, np.ndarray):
        return result.dtype.kind not in "fc" or bool(np.all(np.isfinite(result)))
    if isinstance(result, dict):
        return all(_finite(v) for v in result.values())
    if isinstance(result, (list, tuple)):
        return all(_finite(v) for v in result)
    for attr in ("position", "command", "output", "train", "params"):
        if hasattr(result, attr) and not callable(getattr(result, attr)):
            if not _finite(getattr(result, attr)):
                return False
    return True


@pytest.mark.parametrize("name,arg,kind,call", CALLS, ids=[f"{n}-{a}-{k}" for n, a, k, _ in CALLS])
def test_bad_argument_is_refused_by_name_or_harmless(name, arg, kind, call):
    try:
        result = call()
    except ph.PiezohystError as e:
        OUTCOMES["refused"] += 1
        msg = str(e)
        assert "\n" not in msg.strip() or len(msg) < 2000
        # the message names the argument (or, for a record's elements, the argument with an index)
        aliases = {arg, arg.replace("_", " ")}
        if kind in ("empty", "one sample", "2-D"):
            # a length/shape mismatch may be reported against the partner argument
            aliases |= set(RECIPES[name][3])
        if arg == "reference":
            aliases |= {"stroke"}
        assert any(a in msg for a in aliases), f"{name}({arg}={kind}): message does not name {arg!r}: {msg}"
        return
    OUTCOMES["accepted"] += 1
    assert _finite(result), f"{name}({arg}={kind}) returned non-finite values"


def test_zz_report_counts(capsys):
    """Prints the audit's counts (run last in this module)."""
    with capsys.disabled():
        print(f"\nbad-input audit: {len(CALLS)} calls over {len(RECIPES)} entry points; outcomes {dict(OUTCOMES)}")
    assert len(CALLS) >= 400


# -------------------------------------------------------------------------- constructors

#: Every public constructor of control/ and models/ (and the plant's), with a valid recipe.
CONSTRUCTORS = {
    name: RECIPES[name]
    for name in (
        "PI",
        "GeneralizedPI",
        "RateDependentPI",
        "Preisach",
        "BoucWen",
        "Dahl",
        "Duhem",
        "Creep",
        "OutputMap",
        "PlayOperator",
        "BoucWenBenchmark",
        "PID",
        "OpenLoop",
        "VelocityObserver",
        "SMC",
        "ABSMC",
        "ILC",
        "InverseFeedforward",
        "CemfFeedforward",
        "Amplifier",
        "Sensor",
        "StageParameters",
        "Stage",
    )
}
#: Arguments where infinity means something documented (an ideal amplifier, never refine).
INFINITE_OK = {("Amplifier", "bandwidth"), ("Amplifier", "slew_rate"), ("Stage", "tolerance")}
#: Arguments where None means "the default" (the stage's limits, the sensor's delay, ...).
NONE_OK = {
    ("ABSMC", "d_max"),
    ("CemfFeedforward", "u_min"),
    ("CemfFeedforward", "u_max"),
    ("OpenLoop", "gain"),  # the stage's 1 / static gain
    ("VelocityObserver", "delay"),  # the sensor's delay
}


def _constructor_calls():
    out = []
    for name, (cls, args, kwargs, _arrays, scalars) in CONSTRUCTORS.items():
        params = _signature_names(cls)
        for arg in scalars:
            for kind, bad in (
                ("nan", math.nan),
                ("inf", math.inf),
                ("-inf", -math.inf),
                ("string", "abc"),
                ("None", None),
                ("list", [1.0, 2.0]),
                ("bool", True),
            ):
                if (kind in ("inf",) and (name, arg) in INFINITE_OK) or (kind == "None" and (name, arg) in NONE_OK):
                    continue
                a, kw = list(args), dict(kwargs)
                i = params.index(arg)
                if arg in kw or i >= len(a):
                    kw[arg] = bad
                else:
                    a[i] = bad
                out.append((name, arg, kind, (lambda cls=cls, a=tuple(a), kw=kw: cls(*a, **kw))))
    return out


CONSTRUCTOR_CALLS = _constructor_calls()


@pytest.mark.parametrize(
    "name,arg,kind,build", CONSTRUCTOR_CALLS, ids=[f"{n}-{a}-{k}" for n, a, k, _ in CONSTRUCTOR_CALLS]
)
def test_constructors_refuse_what_is_not_a_number_when_built(name, arg, kind, build):
    """Issue 20: ``PID(kp=nan)`` built without a word and failed (or drove a rail) later. A
    constructor refuses NaN, an infinity, a string, None, a list or a bool for a number, at
    once, naming the argument."""
    with pytest.raises(ph.PiezohystError) as info:
        build()
    assert arg.split("_")[-1] in str(info.value), f"{name}({arg}={kind}): {info.value}"


@pytest.mark.parametrize(
    ("build", "message"),
    [
        (lambda: ph.PID(kp=math.nan), r"kp = nan is not finite"),
        (lambda: ph.PID(kp=-1.0), r"kp = -1\.0 must be >= 0"),
        (lambda: ph.PID(ki=-1.0), r"ki = -1\.0 must be >= 0"),
        (lambda: ph.PID(tau_d=0.0), r"tau_d = 0\.0 must be > 0"),
        (lambda: ph.PID(u_min=10.0, u_max=5.0), r"u_min = 10\.0 must be < u_max = 5\.0"),
        (lambda: ph.ILC(ph.PID(kp=1.0), period=0), r"period = 0 must be >= 2"),
        (lambda: ph.ILC(ph.PID(kp=1.0), period=10, lead=10), r"lead = 10 must be below the period 10"),
        (lambda: ph.ILC(ph.PID(kp=1.0), period=10, forgetting=1.5), r"forgetting = 1\.5 must lie in \(0, 1\]"),
        (lambda: ph.ILC("pid", period=10), r"inner must be a controller"),
        (lambda: ph.ILC(ph.ILC(ph.PID(), period=10), period=10), r"inner must not itself be an ILC"),
        (lambda: ph.VelocityObserver(bandwidth=-1.0), r"observer_bandwidth = -1\.0 must be > 0"),
        (lambda: ph.SMC(STAGE.params, kv=-10.0, alpha=5.0), r"kv \+ alpha = -5\.0 must be > 0"),
        (lambda: ph.SMC(STAGE.params, switching="bang"), r"switching = 'bang' must be"),
        (lambda: ph.SMC(STAGE.params, cemf="yes"), r"cemf must be True or False"),
        (lambda: ph.SMC(STAGE.params, observer=1000.0), r"observer must be a VelocityObserver"),
        (lambda: ph.SMC(ph.papers.mpi_seed2()), r"model must be StageParameters"),
        (lambda: ph.ABSMC(b=1.0, theta=(1.0, 1.0), theta_bounds=[[2.0, 0.0], [1.0, 1.0]]), r"theta_bounds\[0\]\[0\]"),
        (lambda: ph.ABSMC(b=1.0, theta=(1.0, 1.0), regressor="x"), r"regressor = 'x' must be"),
        (lambda: ph.InverseFeedforward(STAGE.params), r"model must be a hysteresis model"),
        (lambda: ph.Compensated(ph.PID(), "mpi"), r"model must be a hysteresis model"),
        (lambda: ph.Compensated(None, ph.papers.mpi_seed2()), r"inner must be a controller"),
        (lambda: ph.Stage(STAGE.params, amplifier=150.0), r"amplifier must be an Amplifier"),
        (lambda: ph.Stage(STAGE.params, sensor=None), r"sensor must be a Sensor"),
        (lambda: ph.Stage(STAGE.params, name="stage\x1b[2J"), r"name = .* holds a control character"),
        (lambda: ph.PI([0.1], [1.0], units={"output": "m\x1b[31m"}), r"units\['output'\] = .* control character"),
        (lambda: ph.batch_simulate(ph.papers.mpi_seed2(), np.tile(ph.papers.mpi_seed2()._row, (2, 1)) + 1j, V), "real"),
    ],
)
def test_documented_domains_are_checked_when_built(build, message):
    with pytest.raises(ph.PiezohystError, match=message):
        build()
