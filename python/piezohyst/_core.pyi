"""Type stub of the compiled core (``crates/python``). Checked against the module by
``tests/test_stub.py``: every public name here exists there and vice versa."""

from collections.abc import Callable, Sequence
from typing import Any, final

import numpy as np
import numpy.typing as npt

__all__ = [
    "MAX_TERMS",
    "STAGE_PARAM_LEN",
    "STAGE_STATE_LEN",
    "Controller",
    "Model",
    "MultiAxisPlant",
    "Scenario",
    "Stage",
    "__version__",
    "batch_rmse",
    "batch_simulate",
    "boucwen_benchmark_batch_rmse",
    "boucwen_benchmark_batch_simulate",
    "boucwen_benchmark_decimate",
    "boucwen_benchmark_integrate",
    "closed_loop",
    "closed_loop_batch",
    "closed_loop_batch_tracking",
    "controller_initial_state",
    "controller_layout",
    "controller_steps",
    "envelope_eval",
    "envelope_inverse",
    "family_layout",
    "family_sizes",
    "initial_state",
    "inverse",
    "layout_codes",
    "lfr_loss_grad",
    "lfr_simulate",
    "pi_analytic_inverse",
    "play_bank",
    "regressors",
    "simulate",
    "solve_cubic_increasing",
    "stage_batch_rmse",
    "stage_simulate",
    "thread_count",
    "validate",
    "virtual_stage_params",
]

__version__: str

_Array1 = npt.NDArray[np.float64]
_Array2 = npt.NDArray[np.float64]
_Array3 = npt.NDArray[np.float64]

def family_layout(name: str, dims: list[int]) -> dict[str, Any]:
    """The core's layout table for a family with these dims: ``family``, ``code`` (the C
    ``PhsFamily``), ``dim_names``, ``dims``, ``slots`` (slot names in row order, ``r[0]`` ...),
    ``groups`` (``(name, offset, length)`` per declared slot), ``linear`` (slot names of the
    regressor columns), ``nonnegative`` (the linear slots a fit keeps >= 0), ``param_len``,
    ``state_len``, ``scratch_len`` (what ``phs_model_sizes`` of the C library reports)."""

def controller_layout(kind: str) -> dict[str, Any]:
    """The core's layout table for a controller kind: ``kind``, ``code`` (the C
    ``PhsControllerKind``), ``slots`` (parameter names in order), ``param_len``."""

def layout_codes() -> tuple[dict[str, int], dict[str, int]]:
    """``({family: PhsFamily code}, {controller kind: PhsControllerKind code})``."""

def family_sizes(name: str, dims: list[int]) -> tuple[int, int]:
    """``(param_len, state_len)`` of a model family with these dims."""

def validate(name: str, dims: list[int], params: _Array1) -> None:
    """Raise ``ValueError`` naming the offending parameter if the row is not valid."""

def initial_state(name: str, dims: list[int], params: _Array1) -> _Array1:
    """The relaxed initial state."""

def simulate(name: str, dims: list[int], params: _Array1, input: _Array1, state: _Array1) -> _Array1:
    """Outputs for ``input`` from ``state`` (updated in place)."""

def inverse(name: str, dims: list[int], params: _Array1, desired: _Array1, state: _Array1, guess: float) -> _Array1:
    """Exact per-sample inverse from the forward ``state`` (updated in place)."""

def pi_analytic_inverse(p0: float, thresholds: _Array1, weights: _Array1) -> tuple[float, _Array1, _Array1]:
    """``(p0', thresholds', weights')`` of the inverse PI model."""

def envelope_inverse(kind: int, coefficients: list[float], values: _Array1) -> _Array1:
    """Element-wise ``g^{-1}`` of an envelope (0 identity, 1 polynomial, 2 tanh)."""

def envelope_eval(kind: int, coefficients: list[float], values: _Array1) -> _Array1:
    """Element-wise ``g`` of an envelope."""

def solve_cubic_increasing(coefficients: list[float], y: float, guess: float) -> float | None:
    """Root of an increasing cubic by the per-sample inverse's solver."""

def batch_simulate(name: str, dims: list[int], params: _Array2, input: _Array1) -> _Array2:
    """``(S, N)`` outputs of ``S`` parameter rows (GIL released, rayon)."""

def batch_rmse(
    name: str, dims: list[int], params: _Array2, input: _Array1, target: _Array1, invalid_cost: float | None = None
) -> _Array1:
    """``(S,)`` RMSE of ``S`` parameter rows against ``target`` (GIL released, rayon)."""

def regressors(name: str, dims: list[int], params: _Array1, input: _Array1) -> _Array2:
    """``(N, m)`` regressors of a row's linear parameters over ``input`` from rest."""

def thread_count() -> int:
    """Threads rayon uses for batch calls."""

def boucwen_benchmark_integrate(params: _Array1, input: _Array1, h: float, state: _Array1) -> tuple[_Array1, _Array1]:
    """Bouc–Wen benchmark by Newmark (average acceleration) + trapezoidal ``z``: ``(y, z)`` at
    ``t_0 + (i+1) h`` for ``input[i]``; ``params = [mass, damping, stiffness, alpha, beta, gamma,
    delta, nu]``, ``state = [y, dy, ddy, z]`` at ``t_0`` (updated in place)."""

def boucwen_benchmark_decimate(x: _Array1, factor: int) -> _Array1:
    """MATLAB ``decimate(x, p, 'fir')`` for each prime factor ``p`` of ``factor`` (increasing)."""

def boucwen_benchmark_batch_rmse(
    params: _Array2,
    input: _Array1,
    h: float,
    factor: int,
    target: _Array1,
    skip: int = 0,
    invalid_cost: float | None = None,
) -> _Array1:
    """``(S,)`` RMSE (m) of ``S`` rows ``[mass, damping, stiffness, alpha, beta, gamma, delta, nu]``
    against ``target``: each row simulates the high-rate force ``input`` (``input[i]`` at ``i h``)
    from rest and FIR-decimates by ``factor`` exactly as one simulation does, scored on the
    decimated samples ``skip .. skip + len(target)``. GIL released, rayon across rows, the same
    values for any thread count; invalid rows raise naming the row (or cost ``invalid_cost``),
    a run that fails or diverges costs +inf."""

def boucwen_benchmark_batch_simulate(
    params: _Array2, input: _Array1, h: float, factor: int, skip: int = 0, count: int | None = None
) -> _Array2:
    """``(S, count)`` decimated displacements (m) of ``S`` rows, simulated as in
    ``boucwen_benchmark_batch_rmse``: samples ``skip .. skip + count`` (``count`` defaults to the
    rest). Invalid rows raise naming the row; a run that fails or diverges is a NaN row."""

STAGE_PARAM_LEN: int
STAGE_STATE_LEN: int
MAX_TERMS: int

#: ``(kind, params, inverse, ilc)``: ``inverse`` is ``None`` or ``(family, dims, row, u_min,
#: u_max)``, ``ilc`` is ``None`` or ``(period, gain, forgetting, lead, delay)``; or a
#: :class:`Controller`.
_ControllerSpec = (
    tuple[str, _Array1, tuple[str, list[int], _Array1, float, float] | None, tuple[int, float, float, int, int] | None]
    | "Controller"
)
#: A :class:`Scenario` or ``(controller, reference, velocity, acceleration, seed)``.
_ScenarioSpec = "Scenario" | tuple[_ControllerSpec, _Array1, _Array1, _Array1, int]

@final
class Model:
    """A hysteresis model built once from family name, dims and parameter row (validated at
    construction; immutable). States are the caller's arrays."""

    def __new__(cls, family: str, dims: list[int], params: _Array1) -> Model: ...
    @property
    def family(self) -> str: ...
    @property
    def dims(self) -> list[int]: ...
    @property
    def params(self) -> _Array1: ...
    @property
    def param_len(self) -> int: ...
    @property
    def state_len(self) -> int: ...
    @property
    def layout(self) -> dict[str, Any]: ...
    def initial_state(self) -> _Array1:
        """The relaxed initial state."""
    def simulate(self, input: _Array1, state: _Array1 | None = None) -> _Array1:
        """Outputs for ``input`` from ``state`` (updated in place) or from rest."""
    def inverse(self, desired: _Array1, state: _Array1, guess: float = 0.0) -> _Array1:
        """Exact per-sample inverse from the forward ``state`` (updated in place)."""

@final
class Controller:
    """A controller validated once: kind and flat parameters (``controller_layout``),
    optionally behind the exact inverse of a model and/or with ILC."""

    def __new__(
        cls,
        kind: str,
        params: _Array1,
        inverse: tuple[Model, float, float] | None = None,
        ilc: tuple[int, float, float, int, int] | None = None,
    ) -> Controller: ...
    @property
    def kind(self) -> str: ...
    @property
    def params(self) -> _Array1: ...
    @property
    def state_len(self) -> int: ...
    @property
    def layout(self) -> dict[str, Any]: ...
    def initial_state(self, y0: float) -> _Array1:
        """The state before the first step, given the first measured position ``y0``."""
    def steps(
        self, reference: _Array1, velocity: _Array1, acceleration: _Array1, measured: _Array1, state: _Array1
    ) -> _Array1:
        """Commands stepped on given inputs from ``state`` (updated in place)."""

@final
class Scenario:
    """A closed-loop scenario: controller, reference (empty derivatives stand for zeros) and
    sensor noise seed."""

    def __new__(
        cls,
        controller: _ControllerSpec,
        reference: _Array1,
        velocity: _Array1 | None = None,
        acceleration: _Array1 | None = None,
        seed: int = 0,
    ) -> Scenario: ...
    def __len__(self) -> int: ...
    @property
    def seed(self) -> int: ...

@final
class Stage:
    """A stage and its sensor built once (parameters of ``STAGE_PARAM_LEN`` values, control
    period, integration settings, sensor)."""

    def __new__(
        cls,
        params: _Array1,
        ts: float,
        substeps: int,
        tolerance: float,
        sensor_quantization: float = 0.0,
        sensor_noise: float = 0.0,
        sensor_delay: int = 0,
        *,
        modes: Sequence[tuple[float, float, float]] | None = None,
        hysteresis: tuple[str, Sequence[int], _Array1] | None = None,
        dac_step: float = 0.0,
        drift: tuple[float, float, float] | None = None,
    ) -> Stage: ...
    @property
    def params(self) -> _Array1: ...
    @property
    def ts(self) -> float: ...
    @property
    def state_len(self) -> int:
        """Slots of the state: ``STAGE_STATE_LEN``, then the structure's."""
    @property
    def structured(self) -> bool:
        """Whether the stage has added modes, a voltage-driven law or a DAC."""
    def rest_state(self) -> _Array1:
        """The state at rest (the structure's modes still, its law relaxed)."""
    def closed_loop_python(
        self,
        step: Callable[[float, float, float, float], float],
        reference: _Array1,
        velocity: _Array1,
        acceleration: _Array1,
        seed: int,
        initial_state: _Array1,
    ) -> dict[str, Any]:
        """One closed loop with ``step(reference, velocity, acceleration, measured) ->
        command`` called from the Rust loop once per sample (slow: the GIL per sample)."""
    def simulate(self, command: _Array1, state: _Array1) -> tuple[_Array1, _Array1, _Array1]:
        """As ``stage_simulate``."""
    def closed_loop(self, scenario: _ScenarioSpec, initial_state: _Array1) -> dict[str, Any]:
        """As ``closed_loop``."""
    def closed_loop_batch(self, scenarios: Sequence[_ScenarioSpec], initial_state: _Array1) -> list[dict[str, Any]]:
        """As ``closed_loop_batch``."""
    def closed_loop_batch_tracking(
        self, scenarios: Sequence[_ScenarioSpec], initial_state: _Array1, skip: int
    ) -> _Array2:
        """As ``closed_loop_batch_tracking``."""
    def closed_loop_batch_stages(
        self, params: _Array2, scenario: _ScenarioSpec, seeds: npt.NDArray[np.uint64], initial_state: _Array1, skip: int
    ) -> _Array2:
        """``(S, 3)`` ``[rmse, max_error, saturated_fraction]`` of one scenario on ``S`` stages: row
        ``j`` of ``params`` (``(S, STAGE_PARAM_LEN)``) replaces this stage's parameters, ``seeds[j]``
        the scenario's noise seed (GIL released, rayon across rows)."""

@final
class MultiAxisPlant:
    """``N`` coupled axes with one sensor per output (issue 19): stages whose positions a static
    coupling matrix mixes, or an LFR model with a hysteresis law per actuator. Runs start at
    rest; one controller per axis, optionally behind a decoupling matrix."""

    @staticmethod
    def stages(stages: list[Stage], coupling: _Array2) -> MultiAxisPlant: ...
    @staticmethod
    def lfr(
        a: _Array2,
        b: _Array2,
        c: _Array2,
        d: _Array2,
        e: _Array2,
        f: _Array2,
        g: _Array2,
        h: _Array2,
        thresholds: _Array2,
        weights: _Array2,
        hysteresis: list[tuple[str, list[int], _Array1] | None],
        limits: list[tuple[float, float]],
        sensors: list[tuple[float, float, int]],
        ts: float,
        nt: int = 0,
    ) -> MultiAxisPlant: ...
    @property
    def axes(self) -> int: ...
    @property
    def ts(self) -> float: ...
    def closed_loop(
        self,
        controllers: list[_ControllerSpec],
        reference: _Array2,
        velocity: _Array2 | None,
        acceleration: _Array2 | None,
        seeds: list[int],
        decoupling: _Array2 | None = None,
    ) -> dict[str, Any]:
        """``command``, ``voltage``, ``position``, ``measured`` ``(n, N)``; ``terms`` (per axis
        ``(n, w_i)``) and ``term_names``."""
    def closed_loop_batch_tracking(
        self,
        candidates: list[list[_ControllerSpec]],
        reference: _Array2,
        velocity: _Array2 | None,
        acceleration: _Array2 | None,
        seeds: list[int],
        skip: int,
        decoupling: _Array2 | None = None,
    ) -> _Array3:
        """``(S, N, 3)`` ``[rmse, max_error, saturated_fraction]`` per candidate and axis (GIL
        released, rayon across candidates; a diverging run gives ``inf``)."""

def virtual_stage_params() -> _Array1:
    """The Rust core's copy of the packaged virtual stage's parameters (flat layout of
    ``StageParams::from_slice``), held equal to ``presets/virtual_stage.json`` by a test."""

def stage_simulate(
    params: _Array1, ts: float, substeps: int, tolerance: float, command: _Array1, state: _Array1
) -> tuple[_Array1, _Array1, _Array1]:
    """Open-loop stage under a held command per period: ``(position at each period start,
    amplifier voltage, CEMF voltage at each period end)``; ``state`` updated in place."""

def closed_loop(
    stage_params: _Array1,
    ts: float,
    substeps: int,
    tolerance: float,
    sensor_quantization: float,
    sensor_noise: float,
    sensor_delay: int,
    controller: _ControllerSpec,
    reference: _Array1,
    velocity: _Array1,
    acceleration: _Array1,
    initial_state: _Array1,
    seed: int,
) -> dict[str, Any]:
    """One closed-loop run: dict of ``command, voltage, position, measured, terms, term_names,
    final_state``."""

def closed_loop_batch(
    stage_params: _Array1,
    ts: float,
    substeps: int,
    tolerance: float,
    sensor_quantization: float,
    sensor_noise: float,
    sensor_delay: int,
    scenarios: Sequence[_ScenarioSpec],
    initial_state: _Array1,
) -> list[dict[str, Any]]:
    """Many scenarios ``(controller, reference, velocity, acceleration, seed)`` in parallel
    (GIL released, rayon)."""

def closed_loop_batch_tracking(
    stage_params: _Array1,
    ts: float,
    substeps: int,
    tolerance: float,
    sensor_quantization: float,
    sensor_noise: float,
    sensor_delay: int,
    scenarios: Sequence[_ScenarioSpec],
    initial_state: _Array1,
    skip: int,
) -> _Array2:
    """``(S, 3)`` ``[rmse, max_error, saturated_fraction]`` of many scenarios, recording no
    signals (GIL released, rayon)."""

def controller_initial_state(controller: _ControllerSpec, y0: float) -> _Array1:
    """The controller's state before its first step, given the first measured position ``y0``."""

def controller_steps(
    controller: _ControllerSpec,
    reference: _Array1,
    velocity: _Array1,
    acceleration: _Array1,
    measured: _Array1,
    state: _Array1,
) -> _Array1:
    """Commands of the controller stepped on given inputs without a plant (as a real-time loop
    or the C library runs it) from ``state`` (updated in place); empty ``velocity`` /
    ``acceleration`` stand for zeros."""

def stage_batch_rmse(
    params: _Array2,
    ts: float,
    substeps: int,
    tolerance: float,
    command: _Array1,
    target: _Array1,
    invalid_cost: float | None = None,
) -> _Array1:
    """``(S,)`` RMSE of the open-loop position of ``S`` stage rows against ``target``, from rest
    (GIL released, rayon)."""

def lfr_simulate(
    a: _Array2,
    b: _Array2,
    c: _Array2,
    d: _Array2,
    e: _Array2,
    f: _Array2,
    g: _Array2,
    h: _Array2,
    thresholds: _Array2,
    weights: _Array2,
    u: _Array3,
    state: _Array2,
    nt: int = 0,
) -> tuple[_Array3, _Array3, _Array2]:
    """MIMO LFR with play-operator feedback on ``R`` records ``u (R, N, nu)``: ``(y, z, final state)``;
    the last ``nt`` channels static saturations."""

def lfr_loss_grad(
    a: _Array2,
    b: _Array2,
    c: _Array2,
    d: _Array2,
    e: _Array2,
    f: _Array2,
    g: _Array2,
    h: _Array2,
    thresholds: _Array2,
    weights: _Array2,
    u: _Array3,
    y: _Array3,
    state: _Array2,
    skip: int,
    record_weights: _Array1,
    nt: int = 0,
) -> tuple[_Array1, _Array1]:
    """Squared output error of the LFR on ``R`` records (``u (R, N, nu)`` against ``y (R, N, ny)``
    from ``state``, the first ``skip`` samples not counted, each record weighted) and its gradient
    (reverse mode): ``(losses (R,), flat gradient in the order A, B, C, D, E, F, G, H, thresholds,
    weights)``; records in batches of 4 stepped in lockstep, a batch with a diverged simulation
    ``inf`` for each of its records."""

def play_bank(x: _Array3, thresholds: _Array2, state: _Array2) -> tuple[_Array3, _Array2]:
    """Play operators on every channel of ``x (R, N, m)``: ``(outputs (R, N, m*nr), final state)``."""
