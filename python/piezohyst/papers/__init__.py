"""Paper reproduction and applications, built on the library (never imported by it): the two
seed papers' experiments (:mod:`.experiments`), the end-to-end demo and its report
(:mod:`.demo`, :mod:`.report`), the benchmark suite (:mod:`.benchmarks`) and the Bouc–Wen
benchmark workflow (:mod:`.boucwen_benchmark`).

The provenance names — values and presets taken from a paper — are public here:
``seed1_stage`` (seed 1's flexure stage), ``mpi_seed2`` and ``SEED2_TABLE1`` (seed 2's MPI
model). They are defined beside the classes they instantiate (:mod:`piezohyst.plant.flexure`,
:mod:`piezohyst.models.pi`), so that ``piezohyst.flexure`` and ``piezohyst.pi`` keep them.
"""

from ..models.pi import SEED2_TABLE1, mpi_seed2
from ..plant.flexure import seed1_stage

__all__ = ["SEED2_TABLE1", "mpi_seed2", "seed1_stage"]
