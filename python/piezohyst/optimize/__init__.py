"""Population optimizers over a box (CSS, PSO, MPSO, DE) and :func:`minimize`, in
:mod:`.core`; this package is the former module ``piezohyst.optimize``."""

from .core import (
    CSS,
    DE,
    METHODS,
    MPSO,
    PSO,
    IntermediateResult,
    Optimizer,
    OptimizeResult,
    css_charges,
    css_forces,
    minimize,
)

__all__ = [
    "CSS",
    "DE",
    "METHODS",
    "MPSO",
    "PSO",
    "IntermediateResult",
    "OptimizeResult",
    "Optimizer",
    "css_charges",
    "css_forces",
    "minimize",
]
