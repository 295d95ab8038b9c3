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

def thread_count() -> int:
    """Threads rayon uses for batch calls."""
