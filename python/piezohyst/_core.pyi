"""Type stub of the compiled core (``crates/python``). Checked against the module by
``tests/test_stub.py``: every public name here exists there and vice versa."""

import numpy as np
import numpy.typing as npt

__version__: str

Array1 = npt.NDArray[np.float64]
Array2 = npt.NDArray[np.float64]

def family_sizes(name: str, dims: list[int]) -> tuple[int, int]:
    """``(param_len, state_len)`` of a model family with these dims."""

def validate(name: str, dims: list[int], params: Array1) -> None:
    """Raise ``ValueError`` naming the offending parameter if the row is not valid."""

def initial_state(name: str, dims: list[int], params: Array1) -> Array1:
    """The relaxed initial state."""

def simulate(name: str, dims: list[int], params: Array1, input: Array1, state: Array1) -> Array1:
    """Outputs for ``input`` from ``state`` (updated in place)."""

def inverse(name: str, dims: list[int], params: Array1, desired: Array1, state: Array1, guess: float) -> Array1:
    """Exact per-sample inverse from the forward ``state`` (updated in place)."""

def pi_analytic_inverse(p0: float, thresholds: Array1, weights: Array1) -> tuple[float, Array1, Array1]:
    """``(p0', thresholds', weights')`` of the inverse PI model."""

def envelope_inverse(kind: int, coefficients: list[float], values: Array1) -> Array1:
    """Element-wise ``g^{-1}`` of an envelope (0 identity, 1 polynomial, 2 tanh)."""

def envelope_eval(kind: int, coefficients: list[float], values: Array1) -> Array1:
    """Element-wise ``g`` of an envelope."""

def solve_cubic_increasing(coefficients: list[float], y: float, guess: float) -> float | None:
    """Root of an increasing cubic by the per-sample inverse's solver."""

def batch_simulate(name: str, dims: list[int], params: Array2, input: Array1) -> Array2:
    """``(S, N)`` outputs of ``S`` parameter rows (GIL released, rayon)."""

def batch_rmse(
    name: str, dims: list[int], params: Array2, input: Array1, target: Array1, invalid_cost: float | None = None
) -> Array1:
    """``(S,)`` RMSE of ``S`` parameter rows against ``target`` (GIL released, rayon)."""

def regressors(name: str, dims: list[int], params: Array1, input: Array1) -> Array2:
    """``(N, m)`` regressors of a row's linear parameters over ``input`` from rest."""

def thread_count() -> int:
    """Threads rayon uses for batch calls."""

def boucwen_benchmark_integrate(params: Array1, input: Array1, h: float, state: Array1) -> tuple[Array1, Array1]:
    """Bouc–Wen benchmark by Newmark (average acceleration) + trapezoidal ``z``: ``(y, z)`` at
    ``t_0 + (i+1) h`` for ``input[i]``; ``params = [mass, damping, stiffness, alpha, beta, gamma,
    delta, nu]``, ``state = [y, dy, ddy, z]`` at ``t_0`` (updated in place)."""

def boucwen_benchmark_decimate(x: Array1, factor: int) -> Array1:
    """MATLAB ``decimate(x, p, 'fir')`` for each prime factor ``p`` of ``factor`` (increasing)."""

def boucwen_benchmark_batch_rmse(
    params: Array2,
    input: Array1,
    h: float,
    factor: int,
    target: Array1,
    skip: int = 0,
    invalid_cost: float | None = None,
) -> Array1:
    """``(S,)`` RMSE (m) of ``S`` rows ``[mass, damping, stiffness, alpha, beta, gamma, delta, nu]``
    against ``target``: each row simulates the high-rate force ``input`` (``input[i]`` at ``i h``)
    from rest and FIR-decimates by ``factor`` exactly as one simulation does, scored on the
    decimated samples ``skip .. skip + len(target)``. GIL released, rayon across rows, the same
    values for any thread count; invalid rows raise naming the row (or cost ``invalid_cost``),
    a run that fails or diverges costs +inf."""

def boucwen_benchmark_batch_simulate(
    params: Array2, input: Array1, h: float, factor: int, skip: int = 0, count: int | None = None
) -> Array2:
    """``(S, count)`` decimated displacements (m) of ``S`` rows, simulated as in
    ``boucwen_benchmark_batch_rmse``: samples ``skip .. skip + count`` (``count`` defaults to the
    rest). Invalid rows raise naming the row; a run that fails or diverges is a NaN row."""

STAGE_PARAM_LEN: int
STAGE_STATE_LEN: int
MAX_TERMS: int

#: ``(kind, params, inverse, ilc)``: ``inverse`` is ``None`` or ``(family, dims, row, u_min,
#: u_max)``, ``ilc`` is ``None`` or ``(period, gain, forgetting, lead, delay)``.
ControllerSpec = tuple[
    str, Array1, tuple[str, list[int], Array1, float, float] | None, tuple[int, float, float, int, int] | None
]

def virtual_stage_params() -> Array1:
    """The Rust core's copy of the packaged virtual stage's parameters (flat layout of
    ``StageParams::from_slice``), held equal to ``presets/virtual_stage.json`` by a test."""

def stage_simulate(
    params: Array1, ts: float, substeps: int, tolerance: float, command: Array1, state: Array1
) -> tuple[Array1, Array1, Array1]:
    """Open-loop stage under a held command per period: ``(position at each period start,
    amplifier voltage, CEMF voltage at each period end)``; ``state`` updated in place."""

def closed_loop(
    stage_params: Array1,
    ts: float,
    substeps: int,
    tolerance: float,
    sensor_quantization: float,
    sensor_noise: float,
    sensor_delay: int,
    controller: ControllerSpec,
    reference: Array1,
    velocity: Array1,
    acceleration: Array1,
    initial_state: Array1,
    seed: int,
) -> dict:
    """One closed-loop run: dict of ``command, voltage, position, measured, terms, term_names,
    final_state``."""

def closed_loop_batch(
    stage_params: Array1,
    ts: float,
    substeps: int,
    tolerance: float,
    sensor_quantization: float,
    sensor_noise: float,
    sensor_delay: int,
    scenarios: list[tuple[ControllerSpec, Array1, Array1, Array1, int]],
    initial_state: Array1,
) -> list[dict]:
    """Many scenarios ``(controller, reference, velocity, acceleration, seed)`` in parallel
    (GIL released, rayon)."""

def closed_loop_batch_tracking(
    stage_params: Array1,
    ts: float,
    substeps: int,
    tolerance: float,
    sensor_quantization: float,
    sensor_noise: float,
    sensor_delay: int,
    scenarios: list[tuple[ControllerSpec, Array1, Array1, Array1, int]],
    initial_state: Array1,
    skip: int,
) -> Array2:
    """``(S, 3)`` ``[rmse, max_error, saturated_fraction]`` of many scenarios, recording no
    signals (GIL released, rayon)."""

def controller_initial_state(controller: ControllerSpec, y0: float) -> Array1:
    """The controller's state before its first step, given the first measured position ``y0``."""

def controller_steps(
    controller: ControllerSpec,
    reference: Array1,
    velocity: Array1,
    acceleration: Array1,
    measured: Array1,
    state: Array1,
) -> Array1:
    """Commands of the controller stepped on given inputs without a plant (as a real-time loop
    or the C library runs it) from ``state`` (updated in place); empty ``velocity`` /
    ``acceleration`` stand for zeros."""

def stage_batch_rmse(
    params: Array2,
    ts: float,
    substeps: int,
    tolerance: float,
    command: Array1,
    target: Array1,
    invalid_cost: float | None = None,
) -> Array1:
    """``(S,)`` RMSE of the open-loop position of ``S`` stage rows against ``target``, from rest
    (GIL released, rayon)."""
