"""The stage plant (docs/spec.md §2.6, §3.1, §3.2, §10; issue 3): integration accuracy against an
independent solve_ivp reference, the drive amplifier, creep, the numbers the default virtual
stage must measure, stage files and bad input."""

import dataclasses
import itertools
import json
import math
from importlib import resources

import numpy as np
import pytest

import piezohyst as ph
from piezohyst import Amplifier, Sensor, Stage, StageParameters, virtual_stage
from tests.stage_reference import reference_positions

TS = 1e-4  # the virtual stage's controller period
N = 60  # 6 ms: six periods of the 1 kHz sine, the step's transient and its ringing
TARGET = 1e-6  # issue 3: <= 1e-6 relative to solve_ivp


def finite_bandwidth_stage():
    """The virtual stage with the amplifier the reference can integrate: 3 kHz, no slew limit."""
    return virtual_stage().with_(amplifier=Amplifier(-20, 150, 3000.0))


def sine_command(n=N):
    t = np.arange(n) * TS
    return 75 + 70 * np.sin(2 * np.pi * 1000 * t)  # 1 kHz, zero-order held at 10 kHz


def step_command(level=100.0, n=N, at=5):
    u = np.zeros(n)
    u[at:] = level
    return u


def rel_error(x, x_ref):
    return float(np.max(np.abs(x - x_ref)) / np.max(np.abs(x_ref)))


def linear_params(p):
    return dataclasses.replace(
        p, hyst_alpha=0.0, hyst_beta=0.0, hyst_gamma=0.0, electrostriction=0.0, creep_taus=(), creep_weights=()
    )


def voltage_drive_params(p):
    # input-driven CEMF: alpha in V/V, beta and gamma in 1/V (Vh saturates near 4 V)
    return dataclasses.replace(p, hyst_drive="voltage", hyst_alpha=0.12, hyst_beta=0.02, hyst_gamma=0.008)


_REFERENCES = {}


def reference(stage, command_name, command):
    """solve_ivp positions, cached per (stage, command) for the whole module."""
    key = (stage, command_name)
    if key not in _REFERENCES:
        _REFERENCES[key] = reference_positions(stage, command, stage.sample_time)
    return _REFERENCES[key]


COMMANDS = {"sine": sine_command(), "step": step_command()}


# --------------------------------------------------------------------------------------------
# integration accuracy against solve_ivp
# --------------------------------------------------------------------------------------------


def test_reference_itself_is_far_tighter_than_the_target():
    st = finite_bandwidth_stage()
    u = COMMANDS["sine"]
    loose = reference_positions(st, u, TS, rtol=1e-10, atol_scale=1e-12)
    assert rel_error(loose, reference(st, "sine", u)) < 1e-8


@pytest.mark.parametrize("name", ["sine", "step"])
def test_hysteresis_matters_in_the_comparison(name):
    # the reference with and without the CEMF differ by far more than the target, so
    # agreement below 1e-6 says the CEMF is integrated right, not that it is negligible
    st = finite_bandwidth_stage()
    u = COMMANDS[name]
    no_cemf = st.with_(params=dataclasses.replace(st.params, hyst_alpha=0.0, hyst_beta=0.0, hyst_gamma=0.0))
    assert rel_error(no_cemf.simulate(u, tolerance=1e-4).position, reference(st, name, u)) > 0.05


def test_1khz_sine_matches_reference():
    st = finite_bandwidth_stage()
    u = COMMANDS["sine"]
    x = st.simulate(u, substeps=1, tolerance=1e-4).position
    assert rel_error(x, reference(st, "sine", u)) <= TARGET  # measured 4.6e-8


def test_step_matches_reference_at_tight_tolerance():
    st = finite_bandwidth_stage()
    u = COMMANDS["step"]
    x = st.simulate(u, substeps=1, tolerance=1e-6).position
    assert rel_error(x, reference(st, "step", u)) <= TARGET  # measured 2.2e-7


@pytest.mark.parametrize("level", [20.0, 150.0])
def test_step_matches_reference_at_tolerance_1e_5(level):
    # the refinement also bounds the ringing inside a period (velocity plus distance from the
    # quasi-static position times the natural frequency), so every step size converges
    st = finite_bandwidth_stage()
    u = step_command(level)
    x = st.simulate(u, substeps=1, tolerance=1e-5).position
    assert rel_error(x, reference(st, f"step{level}", u)) <= TARGET  # measured 2.9e-7 / 1.9e-7


@pytest.mark.parametrize("name", ["sine", "step"])
def test_error_decreases_with_tolerance(name):
    st = finite_bandwidth_stage()
    u = COMMANDS[name]
    x_ref = reference(st, name, u)
    tolerances = [1.0, 1e-1, 1e-2, 1e-3, 1e-4]
    errors = [rel_error(st.simulate(u, substeps=1, tolerance=tol).position, x_ref) for tol in tolerances]
    assert errors[0] > 1e-3  # coarse refinement is visibly wrong ...
    for coarse, fine in itertools.pairwise(errors):
        assert fine < coarse or fine < 1e-7, errors  # ... every tenfold tighter tolerance is better, down to the floor
    assert errors[-1] < 1e-5


@pytest.mark.parametrize("name", ["sine", "step"])
def test_second_order_convergence_in_substeps_without_refinement(name):
    st = finite_bandwidth_stage()
    u = COMMANDS[name]
    x_ref = reference(st, name, u)
    errors = [rel_error(st.simulate(u, substeps=m, tolerance=math.inf).position, x_ref) for m in (2, 4, 8, 16, 32)]
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    assert np.all((ratios > 3.0) & (ratios < 6.0)), ratios  # O(h^2): ~4 per halving


@pytest.mark.parametrize("name", ["sine", "step"])
@pytest.mark.parametrize("substeps", [1, 7])
def test_linear_part_is_exact(name, substeps):
    st = finite_bandwidth_stage()
    st = st.with_(params=linear_params(st.params))
    u = COMMANDS[name]
    x = st.simulate(u, substeps=substeps, tolerance=math.inf).position
    assert rel_error(x, reference(st, name, u)) <= 1e-10  # measured 1.8e-11


@pytest.mark.parametrize("name", ["sine", "step"])
def test_voltage_driven_cemf_matches_reference(name):
    st = finite_bandwidth_stage()
    st = st.with_(params=voltage_drive_params(st.params))
    u = COMMANDS[name]
    x_ref = reference(st, name, u)
    assert rel_error(st.simulate(u, substeps=1, tolerance=1e-4).position, x_ref) <= TARGET  # 9e-9 / 3.6e-7
    # without refinement the CEMF increments are visibly off: the comparison is not vacuous
    assert rel_error(st.simulate(u, substeps=1, tolerance=math.inf).position, x_ref) > 1e-3


def test_tolerance_controls_electrostriction_without_cemf():
    st = finite_bandwidth_stage()
    p = st.params
    st = st.with_(params=dataclasses.replace(linear_params(p), electrostriction=p.electrostriction))
    u = COMMANDS["sine"]
    x_ref = reference(st, "sine", u)
    assert rel_error(st.simulate(u, substeps=1, tolerance=math.inf).position, x_ref) > 1e-3  # 4.2e-3
    assert rel_error(st.simulate(u, substeps=1, tolerance=1e-4).position, x_ref) <= TARGET


def test_creep_forcing_error_is_small_and_shrinks_with_substeps():
    # Known limitation: the creep voltage is first-order held over a sub-step and the
    # refinement does not look at it; its error is second order in the sub-step and small.
    st = finite_bandwidth_stage()
    p = st.params
    st = st.with_(params=dataclasses.replace(linear_params(p), creep_taus=p.creep_taus, creep_weights=p.creep_weights))
    u = COMMANDS["sine"]
    x_ref = reference(st, "sine", u)
    e1 = rel_error(st.simulate(u, substeps=1, tolerance=1e-4).position, x_ref)
    e16 = rel_error(st.simulate(u, substeps=16, tolerance=1e-4).position, x_ref)
    assert e1 < 5e-5 and e16 < e1 / 100


def test_simulation_continues_bit_for_bit_from_final_state():
    st = virtual_stage()
    u = np.concatenate([sine_command(200), step_command(40.0, 100)])
    whole = st.simulate(u)
    first = st.simulate(u[:137])
    state = first.final_state.copy()
    second = st.simulate(u[137:], initial_state=state)
    assert np.array_equal(state, first.final_state)  # the caller's state is not modified
    assert np.array_equal(np.concatenate([first.position, second.position]), whole.position)
    assert np.array_equal(np.concatenate([first.voltage, second.voltage]), whole.voltage)
    assert np.array_equal(np.concatenate([first.cemf, second.cemf]), whole.cemf)
    assert np.array_equal(second.final_state, whole.final_state)
    assert whole.position[0] == 0.0 and np.array_equal(whole.time, np.arange(u.size) * st.sample_time)


# --------------------------------------------------------------------------------------------
# amplifier
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("bandwidth", [3000.0, 800.0])
@pytest.mark.parametrize("tolerance", [0.05, 1e-6, math.inf])
@pytest.mark.parametrize("substeps", [1, 3])
def test_amplifier_first_order_response_is_exact(bandwidth, tolerance, substeps):
    st = virtual_stage().with_(amplifier=Amplifier(-20, 150, bandwidth))
    tau = 1 / (2 * math.pi * bandwidth)
    u = np.concatenate([np.zeros(3), np.full(20, 120.0), np.full(20, -15.0), np.full(5, 150.0)])
    va = st.simulate(u, substeps=substeps, tolerance=tolerance).voltage
    expected, v = [], 0.0
    for uk in u:
        v = uk + (v - uk) * math.exp(-TS / tau)  # end of each period
        expected.append(v)
    assert np.max(np.abs(va - expected)) <= 1e-12 * 165  # relative to the largest step


@pytest.mark.parametrize("substeps", [1, 5])
def test_slew_limited_ramp_then_exponential(substeps):
    slew, bw = 1.4e5, 3000.0  # the virtual stage's amplifier
    st = virtual_stage().with_(amplifier=Amplifier(-20, 150, bw, slew))
    tau = 1 / (2 * math.pi * bw)
    u = np.concatenate([np.zeros(2), np.full(20, 140.0)])
    va = st.simulate(u, substeps=substeps, tolerance=1e-3).voltage
    t = (np.arange(u.size) - 1) * TS  # end of period k, measured from the step at the start of period 2
    t_ramp = (140.0 - slew * tau) / slew  # the gap shrinks to slew*tau, where the exponential takes over
    ramp = (t > 0) & (t <= t_ramp)
    assert ramp.sum() == 9
    np.testing.assert_allclose(va[ramp], slew * t[ramp], rtol=1e-12)
    np.testing.assert_allclose(np.diff(va[ramp]) / TS, slew, rtol=1e-9)  # slope = slew rate
    tail = t > t_ramp
    np.testing.assert_allclose(va[tail], 140.0 - slew * tau * np.exp(-(t[tail] - t_ramp) / tau), rtol=1e-12)


def test_ideal_bandwidth_with_slew_limit_is_a_pure_ramp():
    st = virtual_stage().with_(amplifier=Amplifier(-20, 150, math.inf, 1e5))
    u = np.concatenate([np.zeros(2), np.full(16, 140.0), np.full(20, -20.0)])
    va = st.simulate(u).voltage
    np.testing.assert_allclose(va[2:16], 10.0 * np.arange(1, 15), rtol=1e-13)  # 10 V per 100 us
    assert np.all(va[15:18] == 140.0)
    np.testing.assert_allclose(va[18:34], 140.0 - 10.0 * np.arange(1, 17), rtol=1e-13, atol=1e-12)
    assert np.all(va[34:] == -20.0)


@pytest.mark.parametrize(
    "amplifier",
    [
        Amplifier(-20, 150, 3000.0, 1.4e5),
        Amplifier(-20, 150, 3000.0),
        Amplifier(-20, 150, math.inf, 1e5),
        Amplifier(-20, 150),
    ],
)
def test_amplifier_output_stays_within_its_limits(amplifier):
    st = virtual_stage().with_(amplifier=amplifier)
    square = np.where((np.arange(400) // 25) % 2 == 0, 150.0, -20.0)  # full-range square wave
    va = st.simulate(square).voltage
    assert va.min() >= -20.0 and va.max() <= 150.0
    assert va.max() == pytest.approx(150.0, abs=1e-9) and va.min() == pytest.approx(-20.0, abs=1e-9)


# --------------------------------------------------------------------------------------------
# the default virtual stage: creep, hysteresis, stroke, resonance (docs/spec.md §3.2)
# --------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def info():
    return virtual_stage().info()


def creep_probe(stage, level=75.0, probes=(0.01, 0.1, 1.0, 10.0, 100.0)):
    ts = 1e-3
    n = round(probes[-1] / ts) + 1
    u = np.full(n, level)
    u[:2] = [0.0, level / 2]
    x = stage.simulate(u, sample_time=ts, substeps=8).position
    return np.interp(probes, np.arange(n) * ts, x)


def test_creep_keeps_rising_log_linearly_at_the_designed_rate(info):
    st = virtual_stage()
    p = st.params
    xs = creep_probe(st)
    per_decade = np.diff(xs)
    # designed: each decade one more lag (weight c) completes: static_gain * c * V per decade,
    # reduced a little because the CEMF stiffens the stack against the creep force
    designed = p.static_gain * p.creep_weights[0] * 75.0
    assert np.all(per_decade > 0), per_decade
    assert np.all((per_decade / designed > 0.75) & (per_decade / designed < 1.05)), per_decade / designed
    slope = np.polyfit(np.log10([0.1, 1.0, 10.0, 100.0]), xs[1:], 1)[0]
    percent = 100 * slope / xs[1]
    assert 1.0 <= percent <= 2.0  # docs/spec.md §3.2: about 1-2 % per time decade
    assert info.creep_percent_per_decade == pytest.approx(percent, rel=0.1)
    # without the creep lags the position is flat after 10 ms
    flat = creep_probe(st.with_(params=dataclasses.replace(p, creep_taus=(), creep_weights=())))
    assert np.max(np.abs(np.diff(flat))) < 0.02 * designed


def loop(stage):
    """Third period of the 1 Hz, 0..v_max loop: (command, position after it) per branch."""
    t = np.arange(0, 3.0, TS)
    u = 75.0 * (1 - np.cos(2 * np.pi * t))
    x = stage.simulate(u).position
    last = t >= 2.0
    uu, xs = u[last][:-1], x[last][1:]  # position[k+1] is the response to command[k]
    up = np.diff(u[last]) > 0
    grid = np.linspace(5.0, 145.0, 141)

    def branch(mask):
        order = np.argsort(uu[mask])
        return np.interp(grid, uu[mask][order], xs[mask][order])

    return grid, branch(up), branch(~up), float(np.ptp(xs))


def test_hysteresis_loop_width_and_stroke(info):
    _grid, up, down, span = loop(virtual_stage())
    width = np.max(down - up) / span
    assert np.all(down >= up)  # the descending branch lies above the ascending one
    assert 0.10 <= width <= 0.15  # docs/spec.md §3.2: 10-15 % of stroke at 1 Hz full range
    assert 100 * width == pytest.approx(info.hysteresis_percent, abs=0.5)
    assert 15e-6 <= span <= 25e-6 and 15e-6 <= info.stroke <= 25e-6  # ~20 um at 150 V
    assert info.stroke == pytest.approx(span, rel=0.02)
    # asymmetric: a point-symmetric loop would have up(u) + down(150 - u) constant
    assert np.ptp(up + down[::-1]) / span > 0.01


def test_resonance_and_natural_frequency(info):
    p = virtual_stage().params
    assert 4500 <= info.resonance <= 6500
    assert p.natural_frequency == pytest.approx(5100, rel=0.01)
    assert info.natural_frequency == p.natural_frequency
    assert info.damping_ratio == pytest.approx(0.03, rel=1e-12)
    # small-signal, the charge-driven CEMF adds the stiffness Tem^2 alpha / (1 + Cz alpha)
    k_eff = p.stiffness + p.tem**2 * p.hyst_alpha / (1 + p.capacitance * p.hyst_alpha)
    assert info.resonance == pytest.approx(math.sqrt(k_eff / p.mass) / (2 * math.pi), rel=0.02)


def test_seed1_flexure_stage_agrees_with_virtual_stage():
    seed = ph.FlexureStage.seed1()
    p = virtual_stage().params
    assert p.mass == pytest.approx(seed.meq, rel=1e-12)
    assert p.stiffness == pytest.approx(seed.keq, rel=1e-4)  # 7.333e7 vs 6e7 + 1.3333e7
    assert p.natural_frequency == pytest.approx(seed.f_n, rel=1e-4)
    assert p.damping_ratio == pytest.approx(seed.zeta, rel=1e-12)


def test_virtual_stage_table():
    st = virtual_stage()
    assert (st.amplifier.v_min, st.amplifier.v_max) == (-20.0, 150.0)
    assert math.isfinite(st.amplifier.bandwidth) and math.isfinite(st.amplifier.slew_rate)
    assert st.sensor == Sensor(1e-7, st.sensor.noise_std, 1) and st.sensor.noise_std > 0
    assert st.sample_time == 1e-4
    assert st.params.hyst_drive == "charge" and st.params.capacitance == 1.8e-6


# --------------------------------------------------------------------------------------------
# stage files
# --------------------------------------------------------------------------------------------

STAGES = {
    "virtual": virtual_stage(),
    "ideal amplifier, voltage drive, no creep": virtual_stage().with_(
        amplifier=Amplifier(-10, 120),
        sensor=Sensor(),
        substeps=3,
        tolerance=math.inf,
        params=dataclasses.replace(voltage_drive_params(virtual_stage().params), creep_taus=(), creep_weights=()),
    ),
}


@pytest.mark.parametrize("name", list(STAGES))
def test_dict_round_trip_simulates_bit_identically(name):
    st = STAGES[name]
    d = json.loads(json.dumps(st.to_dict()))  # through JSON text, as a file would be
    back = Stage.from_dict(d)
    assert back == st
    u = np.concatenate([sine_command(300), step_command(30.0, 200)])
    u = np.clip(u, st.amplifier.v_min, st.amplifier.v_max)
    a, b = st.simulate(u), back.simulate(u)
    for field in ("position", "voltage", "cemf", "final_state"):
        assert np.array_equal(getattr(a, field), getattr(b, field)), field


def test_from_file_reads_a_written_file(tmp_path):
    st = virtual_stage().with_(amplifier=Amplifier(-15, 140, 2500.0, 1e5), name="bench rig")
    path = tmp_path / "stage.json"
    path.write_text(json.dumps(st.to_dict(), indent=2))
    back = Stage.from_file(path)
    assert back == st and back.name == "bench rig"
    u = np.linspace(0, 140, 500)
    assert np.array_equal(back.simulate(u).position, st.simulate(u).position)


def test_packaged_file_loads_and_overrides(tmp_path):
    d = json.loads(resources.files("piezohyst").joinpath("presets/virtual_stage.json").read_text())
    assert Stage.from_dict(d) == virtual_stage()
    d["mechanics"]["mass"] = 0.05
    d["amplifier"]["bandwidth"] = "inf"
    path = tmp_path / "mine.json"
    path.write_text(json.dumps(d))
    st = Stage.from_file(path)
    assert st.params.mass == 0.05 and st.amplifier.bandwidth == math.inf
    zeta = d["mechanics"]["damping_ratio"]
    assert st.params.damping == pytest.approx(2 * zeta * math.sqrt(0.05 * d["mechanics"]["stiffness"]), rel=1e-14)


def test_file_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="nope.json"):
        Stage.from_file(tmp_path / "nope.json")
    bad = tmp_path / "bad.json"
    bad.write_text('{"mechanics": {"mass": 0.07,')
    with pytest.raises(ValueError, match=r"bad\.json.*not valid JSON"):
        Stage.from_file(bad)
    arr = tmp_path / "array.json"
    arr.write_text("[1, 2, 3]")
    with pytest.raises(ValueError, match=r"array\.json.*JSON object"):
        Stage.from_file(arr)


def stage_dict():
    return json.loads(json.dumps(virtual_stage().to_dict()))


@pytest.mark.parametrize(
    "path",
    [
        ("mechanics",),
        ("cemf",),
        ("mechanics", "mass"),
        ("mechanics", "stiffness"),
        ("mechanics", "tem"),
        ("cemf", "alpha"),
        ("cemf", "beta"),
        ("cemf", "gamma"),
        ("creep", "weights"),
        ("creep", "taus"),
    ],
)
def test_missing_keys_are_named(path):
    d = stage_dict()
    parent = d
    for key in path[:-1]:
        parent = parent[key]
    del parent[path[-1]]
    with pytest.raises(ValueError, match=f"missing '{path[-1]}'"):
        Stage.from_dict(d)


def test_missing_damping_names_the_ratio():
    d = stage_dict()
    del d["mechanics"]["damping"]
    with pytest.raises(ValueError, match="missing 'damping_ratio'"):
        Stage.from_dict(d)


BAD_VALUES = [
    (("mechanics", "mass"), 0.0, r"mass = 0\.0 must be > 0"),
    (("mechanics", "mass"), -0.07, r"mass = -0\.07 must be > 0"),
    (("mechanics", "mass"), float("nan"), r"mass = nan is not finite"),
    (("mechanics", "stiffness"), -7.3e7, r"stiffness = -73000000\.0 must be > 0"),
    (("mechanics", "stiffness"), 0.0, r"stiffness = 0\.0 must be > 0"),
    (("mechanics", "damping"), -1.0, r"damping = -1\.0 must be >= 0"),
    (("mechanics", "tem"), 0.0, r"tem = 0\.0 must be > 0"),
    (("cemf", "capacitance"), -1e-6, r"capacitance = -1e-06 must be > 0"),
    (("cemf", "drive"), "current", r"hyst_drive = 'current' must be 'charge' or 'voltage'"),
    (("amplifier", "min"), 150.0, r"v_min = 150\.0 must be < v_max = 150\.0"),
    (("amplifier", "min"), 200.0, r"v_min = 200\.0 must be < v_max = 150\.0"),
    (("amplifier", "bandwidth"), 0.0, r"bandwidth = 0\.0 must be > 0"),
    (("amplifier", "slew_rate"), -1e5, r"slew_rate = -100000\.0 must be > 0"),
    (("sensor", "quantization"), -1e-7, r"quantization = -1e-07 must be >= 0"),
    (("sensor", "noise_std"), -1e-8, r"noise_std = -1e-08 must be >= 0"),
    (("sensor", "delay"), 17, r"delay = 17 must be <= 16"),
    (("loop", "sample_time"), 0.0, r"sample_time = 0\.0 must be > 0"),
    (("loop", "sample_time"), -1e-4, r"sample_time = -0\.0001 must be > 0"),
    (("loop", "substeps"), 0, r"substeps = 0 must be >= 1"),
    (("loop", "substeps"), 10_001, r"substeps = 10001 must be <= 10000"),
    (("loop", "tolerance"), 0.0, r"tolerance = 0\.0 must be > 0"),
    (("loop", "tolerance"), -0.01, r"tolerance = -0\.01 must be > 0"),
    (("creep", "taus"), [0.01, 0.0, 1.0, 10.0, 100.0], r"creep_taus\[1\] = 0\.0 must be > 0"),
    (("creep", "taus"), [0.01, 0.1, 1.0, -10.0, 100.0], r"creep_taus\[3\] = -10\.0 must be > 0"),
    (("creep", "weights"), [0.015], r"creep_weights has length 1, creep_taus has 5"),
]


@pytest.mark.parametrize("path, value, message", BAD_VALUES, ids=[f"{p[-1]}={v}" for p, v, _ in BAD_VALUES])
def test_non_physical_values_are_named(path, value, message):
    d = stage_dict()
    d[path[0]][path[1]] = value
    with pytest.raises(ValueError, match=message):
        Stage.from_dict(d)


def test_negative_damping_ratio_is_named():
    d = json.loads(resources.files("piezohyst").joinpath("presets/virtual_stage.json").read_text())
    d["mechanics"]["damping_ratio"] = -0.1
    with pytest.raises(ValueError, match=r"damping_ratio = -0\.1 must be >= 0"):
        Stage.from_dict(d)


def test_non_numeric_mass_is_named():
    d = stage_dict()
    d["mechanics"]["mass"] = "heavy"
    with pytest.raises(ValueError, match=r"mass.*heavy"):
        Stage.from_dict(d)


def test_constructors_validate_too():
    p = virtual_stage().params
    with pytest.raises(ValueError, match=r"mass = -1\.0 must be > 0"):
        dataclasses.replace(p, mass=-1.0)
    with pytest.raises(ValueError, match=r"damping = -5\.0 must be >= 0"):
        dataclasses.replace(p, damping=-5.0)
    with pytest.raises(ValueError, match=r"v_min = 150\.0 must be < v_max = -20\.0"):
        Amplifier(150.0, -20.0)
    with pytest.raises(ValueError, match=r"sample_time = 0\.0 must be > 0"):
        virtual_stage().with_(sample_time=0.0)
    with pytest.raises(ValueError, match=r"tolerance = nan is not finite"):
        virtual_stage().with_(tolerance=float("nan"))
    with pytest.raises(TypeError, match="params must be StageParameters"):
        Stage(params={"mass": 1.0})
    with pytest.raises(TypeError, match="substeps must be an integer"):
        virtual_stage().with_(substeps=1.5)
    assert isinstance(StageParameters(1.0, 0.0, 1.0, 1.0), StageParameters)


# --------------------------------------------------------------------------------------------
# bad commands and simulation arguments
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("index, value", [(7, 150.5), (0, -20.001), (99, 1e6)])
def test_commands_beyond_the_amplifier_range_are_named(index, value):
    u = np.full(100, 50.0)
    u[index] = value
    with pytest.raises(
        ValueError, match=rf"command\[{index}\] = {value} V is outside the amplifier range \[-20\.0, 150\.0\]"
    ):
        virtual_stage().simulate(u)


def test_commands_at_the_limits_are_accepted():
    r = virtual_stage().simulate(np.array([-20.0, 150.0, 150.0, -20.0]))
    assert np.all(np.isfinite(r.position))


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_non_finite_commands_are_named(bad):
    u = np.full(10, 50.0)
    u[4] = bad
    with pytest.raises(ValueError, match=rf"command\[4\] = {bad} is not finite"):
        virtual_stage().simulate(u)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"substeps": 0}, r"substeps = 0 must be >= 1"),
        ({"sample_time": 0.0}, r"sample_time = 0\.0 must be > 0"),
        ({"sample_time": -1e-4}, r"sample_time = -0\.0001 must be > 0"),
        ({"tolerance": 0.0}, r"tolerance = 0(\.0)? must be > 0"),
        ({"tolerance": -1.0}, r"tolerance = -1(\.0)? must be > 0"),
        ({"tolerance": float("nan")}, r"tolerance = (nan|NaN)"),
        ({"initial_state": np.zeros(5)}, r"state"),
    ],
)
def test_bad_simulation_arguments_are_named(kwargs, message):
    with pytest.raises(ValueError, match=message):
        virtual_stage().simulate(np.full(10, 50.0), **kwargs)


def test_rust_virtual_stage_matches_the_preset():
    """StageParams::virtual_stage() (Rust tests, soaks, examples) is the packaged preset."""
    from piezohyst import _core

    np.testing.assert_allclose(_core.virtual_stage_params(), virtual_stage().core_params(), rtol=1e-15, atol=0)
