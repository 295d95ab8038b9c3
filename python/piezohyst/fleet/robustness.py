"""Monte-Carlo robustness of a controller over part-to-part variation of the stage.

The controller is designed (packed) for the nominal stage; each Monte-Carlo sample is a part:
the nominal stage with some physical parameters scaled by a random factor (``mass=±10%``: a
factor uniform in [0.9, 1.1]), run in closed loop on the same reference with its own
sensor-noise seed. The runs are batched in the Rust core
(:func:`piezohyst.control.simulation.closed_loop_batch_stages`: one rayon task per part), in
chunks of ``chunk`` samples, each chunk one Dask task.

Reproducibility: sample ``i``'s factors and noise seed come from its own generator,
``numpy.random.SeedSequence(seed, spawn_key=(i,))`` (the ``i``-th child of
``SeedSequence(seed).spawn``), and its run depends on nothing else; the chunks are fixed by
``chunk``, not by the workers. So the same ``seed`` gives the same result, to the bit, whatever
the number of workers, threads or the order the chunks finish in.

Examples
--------
>>> import numpy as np
>>> from piezohyst import PID, virtual_stage
>>> from piezohyst.fleet import RobustnessProblem, Runner, parse_perturbations, plan, robustness
>>> stage = virtual_stage()
>>> ref = 8e-6 + 5e-6 * np.sin(2 * np.pi * 25 * np.arange(400) * stage.sample_time)
>>> problem = RobustnessProblem(stage, PID(kp=2e6, ki=2e9), ref, 100, tuple(parse_perturbations("mass=±10%")), 0)
>>> res = robustness(problem, 12, Runner(plan("serial", env={})), chunk=5)
>>> res.samples, bool(res.percentiles()["rmse"]["p99"] < 1e-6)  # 99 % of the parts track within 1 µm RMSE
(12, True)
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ..control.simulation import ControllerLike, closed_loop_batch_stages, closed_loop_perturbed
from ..errors import ParameterError
from ..plant.stage import Stage, StageParameters
from ..progress import Progress
from ..signals.results import DataclassMatFile, html_table, require_pandas
from .cluster import Runner

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from ..control.simulation import ClosedLoopResult

__all__ = [
    "DISTRIBUTIONS",
    "PARAMETERS",
    "Perturbation",
    "RobustnessProblem",
    "RobustnessResult",
    "draw",
    "parse_perturbations",
    "robustness",
    "run_chunk",
]

FloatArray = npt.NDArray[np.float64]

#: The stage parameters a perturbation may scale: name -> columns of ``Stage.core_params()``
#: (``creep_weights`` scales every creep weight together). ``tests/fleet`` holds them equal to
#: the layout ``core_params`` writes.
PARAMETERS: dict[str, tuple[int, ...]] = {
    "mass": (0,),
    "damping": (1,),
    "stiffness": (2,),
    "tem": (3,),
    "capacitance": (4,),
    "hyst_alpha": (5,),
    "hyst_beta": (6,),
    "hyst_gamma": (7,),
    "electrostriction": (9,),
    "creep_weights": tuple(range(23, 31)),
}
_ALIASES = {"alpha": "hyst_alpha", "beta": "hyst_beta", "gamma": "hyst_gamma", "creep": "creep_weights"}

#: ``uniform``: the factor is uniform in ``[1 - p, 1 + p]``; ``normal``: normal with standard
#: deviation ``p`` around 1, truncated at ±3 standard deviations.
DISTRIBUTIONS = ("uniform", "normal")

#: Normal quantiles are drawn in [Phi(-3), Phi(3)] (truncation at 3 sigma).
_PHI_M3 = 0.5 * math.erfc(3 / math.sqrt(2))


@dataclass(frozen=True)
class Perturbation:
    """``name`` scaled by a random factor around 1 of relative spread ``percent`` / 100.

    Parameters
    ----------
    name : str
        A stage parameter of :data:`PARAMETERS` (``"mass"``, ``"stiffness"``, ...).
    percent : float
        The spread in percent: ``uniform`` factors lie in ``[1 - p, 1 + p]`` (``p`` < 100 %),
        ``normal`` ones have standard deviation ``p`` (< 33.3 %, truncated at ±3 sigma).
    distribution : {"uniform", "normal"}, optional
        The factor's distribution (default uniform).

    Examples
    --------
    >>> from piezohyst.fleet import Perturbation
    >>> str(Perturbation("mass", 10.0)), str(Perturbation("tem", 3.0, "normal"))
    ('mass=±10%', 'tem=±3%:normal')
    >>> try:
    ...     Perturbation("mass", 150.0)
    ... except ValueError as e:  # a ParameterError
    ...     print(str(e).split(":")[1].strip())
    the spread must be > 0 and < 100 % for a uniform factor (the parameter must keep its sign)
    """

    name: str
    percent: float
    distribution: str = "uniform"

    def __post_init__(self) -> None:
        if self.name not in PARAMETERS:
            raise ParameterError(
                f"--perturb: '{self.name}' is not a perturbable stage parameter; choose from "
                f"{', '.join(PARAMETERS)} (or alpha, beta, gamma, creep)"
            )
        if self.distribution not in DISTRIBUTIONS:
            raise ParameterError(f"--perturb {self.name}: distribution '{self.distribution}' must be uniform or normal")
        p = self.percent
        limit = 100.0 if self.distribution == "uniform" else 100.0 / 3.0
        if not (math.isfinite(p) and 0 < p < limit):
            raise ParameterError(
                f"--perturb {self.name}=±{p:g}%: the spread must be > 0 and < {limit:.4g} % for a {self.distribution} "
                "factor (the parameter must keep its sign)"
            )

    def __str__(self) -> str:
        tail = "" if self.distribution == "uniform" else ":normal"
        return f"{self.name}=±{self.percent:g}%{tail}"


_ITEM = re.compile(r"^\s*([A-Za-z_]+)\s*=\s*(?:±|\+-|\+/-)?\s*([0-9.eE+-]+)\s*%\s*(?::\s*([a-z]+))?\s*$")


def parse_perturbations(text: str) -> list[Perturbation]:
    """``"mass=±10%,stiffness=+-5%,tem=±3%:normal"`` as perturbations (``±``, ``+-`` or
    nothing before the percentage; ``:uniform`` (default) or ``:normal`` after it).

    Parameters
    ----------
    text : str
        Comma-separated ``NAME=±P%`` items (the CLI's ``--perturb``); ``alpha``, ``beta``,
        ``gamma`` and ``creep`` name ``hyst_alpha``, ``hyst_beta``, ``hyst_gamma`` and
        ``creep_weights``.

    Returns
    -------
    list of Perturbation

    Examples
    --------
    >>> [str(p) for p in parse_perturbations("mass=±10%, k=5%".replace("k", "stiffness"))]
    ['mass=±10%', 'stiffness=±5%']
    >>> parse_perturbations("gamma=+-20%:normal")[0]
    Perturbation(name='hyst_gamma', percent=20.0, distribution='normal')
    """
    out: list[Perturbation] = []
    for item in text.split(","):
        if not item.strip():
            continue
        m = _ITEM.match(item)
        if m is None:
            raise ParameterError(
                f"--perturb item '{item.strip()}' must read NAME=±P% (or NAME=+-P%, NAME=P%), optionally "
                "followed by :uniform or :normal"
            )
        name = _ALIASES.get(m.group(1), m.group(1))
        try:
            pct = float(m.group(2))
        except ValueError:
            raise ParameterError(f"--perturb item '{item.strip()}': '{m.group(2)}' is not a percentage") from None
        if any(p.name == name for p in out):
            raise ParameterError(f"--perturb names {name} twice")
        out.append(Perturbation(name, pct, m.group(3) or "uniform"))
    if not out:
        raise ParameterError(f"--perturb = '{text}' names no parameter; e.g. mass=±10%,stiffness=±5%")
    return out


def draw(perturbations: Sequence[Perturbation], seed: int, start: int, stop: int) -> tuple[FloatArray, np.ndarray]:
    """Samples ``start..stop``: their factors ``(n, P)`` and their sensor-noise seeds ``(n,)``
    (uint64). Sample ``i`` draws from ``SeedSequence(seed, spawn_key=(i,))`` only: ``P`` uniform
    numbers (mapped to each perturbation's distribution), then its noise seed.

    Parameters
    ----------
    perturbations : sequence of Perturbation
        The ``P`` perturbed parameters (the factors' columns).
    seed : int
        The run's seed.
    start, stop : int
        The samples ``start..stop`` (``stop`` excluded).

    Returns
    -------
    factors : numpy.ndarray
        ``(stop - start, P)`` factors around 1.
    seeds : numpy.ndarray
        ``(stop - start,)`` uint64 sensor-noise seeds.

    Examples
    --------
    >>> from piezohyst.fleet import draw, parse_perturbations
    >>> kinds = parse_perturbations("mass=±10%,stiffness=±10%")
    >>> factors, seeds = draw(kinds, 0, 0, 3)
    >>> factors.round(4).tolist(), seeds.dtype.name
    ([[1.0886, 0.9633], [1.0354, 0.9486], [1.0677, 0.9167]], 'uint64')
    >>> bool((draw(kinds, 0, 2, 3)[0] == factors[2]).all())  # a sample draws the same alone
    True
    """
    n, k = stop - start, len(perturbations)
    u = np.empty((n, k))
    seeds = np.empty(n, dtype=np.uint64)
    for j, i in enumerate(range(start, stop)):  # one generator per Monte-Carlo sample, not per time sample
        g = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(i,)))
        u[j] = g.random(k)
        seeds[j] = g.integers(0, 2**63 - 1)
    factors = np.empty((n, k))
    for c, p in enumerate(perturbations):
        spread = p.percent / 100.0
        if p.distribution == "uniform":
            factors[:, c] = 1.0 + spread * (2.0 * u[:, c] - 1.0)
        else:
            from scipy.special import ndtri

            factors[:, c] = 1.0 + spread * ndtri(_PHI_M3 + (1.0 - 2.0 * _PHI_M3) * u[:, c])
    return factors, seeds


@dataclass(frozen=True)
class RobustnessProblem:
    """Everything a chunk needs (pickled once per worker): the nominal stage, the controller
    packed for it, the reference, the samples left out of the metrics, the perturbations and the seed.

    Parameters
    ----------
    stage : Stage
        The nominal stage (each part scales some of its parameters).
    controller : controller
        The controller, designed for the nominal stage (PID, SMC, ...).
    reference : numpy.ndarray
        The position reference, m, one value per sample at the stage's rate.
    skip : int
        Leading samples left out of the metrics (the transient).
    perturbations : tuple of Perturbation
        The perturbed parameters.
    seed : int
        The seed of every sample's factors and sensor noise.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst import PID, virtual_stage
    >>> from piezohyst.fleet import RobustnessProblem, Runner, parse_perturbations, plan, robustness
    >>> stage = virtual_stage()
    >>> ref = 8e-6 + 5e-6 * np.sin(2 * np.pi * 25 * np.arange(400) * stage.sample_time)
    >>> kinds = tuple(parse_perturbations("mass=±10%,stiffness=±10%"))
    >>> problem = RobustnessProblem(stage, PID(kp=2e6, ki=2e9), ref, 100, kinds, 0)
    >>> problem.reference.size, [p.name for p in problem.perturbations]
    (400, ['mass', 'stiffness'])
    """

    stage: Stage
    controller: ControllerLike
    reference: FloatArray
    skip: int
    perturbations: tuple[Perturbation, ...]
    seed: int

    def rows(self, factors: FloatArray) -> FloatArray:
        """The stage parameter rows of parts with these factors.

        Parameters
        ----------
        factors : numpy.ndarray
            ``(n, P)`` factors, one column per perturbation.

        Returns
        -------
        numpy.ndarray
            ``(n, len(stage.core_params()))``: the Rust core's parameter row of each part.

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst import PID, virtual_stage
        >>> from piezohyst.fleet import RobustnessProblem, Runner, parse_perturbations, plan, robustness
        >>> stage = virtual_stage()
        >>> ref = 8e-6 + 5e-6 * np.sin(2 * np.pi * 25 * np.arange(400) * stage.sample_time)
        >>> kinds = tuple(parse_perturbations("mass=±10%,stiffness=±10%"))
        >>> problem = RobustnessProblem(stage, PID(kp=2e6, ki=2e9), ref, 100, kinds, 0)
        >>> rows = problem.rows(np.array([[1.1, 1.0], [1.0, 0.9]]))
        >>> rows.shape, float(rows[0, 0] / stage.core_params()[0]), float(rows[1, 2] / stage.core_params()[2])
        ((2, 31), 1.1, 0.9)
        """
        base = self.stage.core_params()
        rows = np.tile(base, (factors.shape[0], 1))
        for c, p in enumerate(self.perturbations):
            cols = list(PARAMETERS[p.name])
            rows[:, cols] *= factors[:, c : c + 1]
        return rows

    def part(self, factors: Sequence[float]) -> StageParameters:
        """The stage parameters of one part.

        Parameters
        ----------
        factors : sequence of float
            One factor per perturbation.

        Returns
        -------
        StageParameters

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst import PID, virtual_stage
        >>> from piezohyst.fleet import RobustnessProblem, Runner, parse_perturbations, plan, robustness
        >>> stage = virtual_stage()
        >>> ref = 8e-6 + 5e-6 * np.sin(2 * np.pi * 25 * np.arange(400) * stage.sample_time)
        >>> kinds = tuple(parse_perturbations("mass=±10%,stiffness=±10%"))
        >>> problem = RobustnessProblem(stage, PID(kp=2e6, ki=2e9), ref, 100, kinds, 0)
        >>> part = problem.part([1.1, 1.0])
        >>> round(part.mass / stage.params.mass, 12), part.stiffness == stage.params.stiffness
        (1.1, True)
        """
        changes: dict[str, Any] = {}
        sp = self.stage.params
        for p, f in zip(self.perturbations, factors, strict=True):
            value = getattr(sp, p.name)
            changes[p.name] = tuple(w * f for w in value) if isinstance(value, tuple) else value * f
        return dataclasses.replace(sp, **changes)


@dataclass(frozen=True)
class Chunk:
    """One task's samples ``start..start + n``: factors, noise seeds, ``[rmse, max_error,
    saturated_fraction]``."""

    start: int
    factors: FloatArray
    seeds: np.ndarray
    metrics: FloatArray


def run_chunk(problem: RobustnessProblem, start: int, stop: int) -> Chunk:
    """Samples ``start..stop`` of ``problem``: drawn, then run in one batched call of the Rust core.

    Parameters
    ----------
    problem : RobustnessProblem
        What to run.
    start, stop : int
        The samples ``start..stop`` (``stop`` excluded).

    Returns
    -------
    Chunk
        ``start``, the factors, noise seeds and ``[rmse, max_error, saturated_fraction]`` rows.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst import PID, virtual_stage
    >>> from piezohyst.fleet import RobustnessProblem, Runner, parse_perturbations, plan, robustness
    >>> stage = virtual_stage()
    >>> ref = 8e-6 + 5e-6 * np.sin(2 * np.pi * 25 * np.arange(400) * stage.sample_time)
    >>> kinds = tuple(parse_perturbations("mass=±10%,stiffness=±10%"))
    >>> problem = RobustnessProblem(stage, PID(kp=2e6, ki=2e9), ref, 100, kinds, 0)
    >>> from piezohyst.fleet import run_chunk
    >>> chunk = run_chunk(problem, 4, 8)
    >>> chunk.start, chunk.metrics.shape, bool(chunk.metrics[:, 0].max() < 1e-6)  # RMSE < 1 µm
    (4, (4, 3), True)
    """
    factors, seeds = draw(problem.perturbations, problem.seed, start, stop)
    m = closed_loop_batch_stages(
        problem.stage, problem.controller, problem.reference, problem.rows(factors), seeds, skip=problem.skip
    )
    return Chunk(start, factors, seeds, m)


_PERCENTILES = (50.0, 90.0, 95.0, 99.0, 99.9)


@dataclass(frozen=True)
class RobustnessResult(DataclassMatFile):
    """Every sample's factors, noise seed and ``[rmse, max_error, saturated_fraction]`` (sample
    order), the nominal stage's run, the problem, the wall time and the failed chunks (none in a
    complete result).

    As every result (:mod:`piezohyst.signals.results`): ``to_pandas()`` (one row per part),
    ``plot()``, the notebook display and ``.mat`` files (``to_mat``, ``from_mat``).

    Parameters
    ----------
    problem : RobustnessProblem
        What was run.
    factors : numpy.ndarray
        ``(samples, P)`` factors of each part.
    seeds : numpy.ndarray
        ``(samples,)`` sensor-noise seeds.
    metrics : numpy.ndarray
        ``(samples, 3)``: tracking RMSE and maximum error (m), saturated fraction of the run.
    nominal : numpy.ndarray
        The nominal stage's ``[rmse, max_error, saturated_fraction]``.
    wall_time : float
        Seconds the run took.
    errors : tuple of str, optional
        The chunks that failed, with their error (their samples are NaN).

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst import PID, virtual_stage
    >>> from piezohyst.fleet import RobustnessProblem, Runner, parse_perturbations, plan, robustness
    >>> stage = virtual_stage()
    >>> ref = 8e-6 + 5e-6 * np.sin(2 * np.pi * 25 * np.arange(400) * stage.sample_time)
    >>> kinds = tuple(parse_perturbations("mass=±10%,stiffness=±10%"))
    >>> problem = RobustnessProblem(stage, PID(kp=2e6, ki=2e9), ref, 100, kinds, 0)
    >>> res = robustness(problem, 16, Runner(plan("serial", env={})), chunk=8)
    >>> res.samples, res.names, res.errors
    (16, ['mass', 'stiffness'], ())
    """

    problem: RobustnessProblem
    factors: FloatArray
    seeds: np.ndarray
    metrics: FloatArray
    nominal: FloatArray
    wall_time: float
    errors: tuple[str, ...] = ()

    @property
    def samples(self) -> int:
        """The number of Monte-Carlo samples (parts)."""
        return int(self.metrics.shape[0])

    @property
    def names(self) -> list[str]:
        """The perturbed parameters' names, in the factors' column order."""
        return [p.name for p in self.problem.perturbations]

    def percentiles(self) -> dict[str, dict[str, float]]:
        """``{"rmse": {"p50": …, "p90": …, "p95": …, "p99": …, "p99.9": …, "max": …, "mean": …},
        "max_error": {…}}`` in m, over the samples that did not diverge.

        Returns
        -------
        dict

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst import PID, virtual_stage
        >>> from piezohyst.fleet import RobustnessProblem, Runner, parse_perturbations, plan, robustness
        >>> stage = virtual_stage()
        >>> ref = 8e-6 + 5e-6 * np.sin(2 * np.pi * 25 * np.arange(400) * stage.sample_time)
        >>> kinds = tuple(parse_perturbations("mass=±10%,stiffness=±10%"))
        >>> problem = RobustnessProblem(stage, PID(kp=2e6, ki=2e9), ref, 100, kinds, 0)
        >>> res = robustness(problem, 16, Runner(plan("serial", env={})), chunk=8)
        >>> {k: round(v * 1e6, 3) for k, v in res.percentiles()["rmse"].items()}  # µm
        {'p50': 0.341, 'p90': 0.443, 'p95': 0.452, 'p99': 0.456, 'p99.9': 0.457, 'max': 0.457, 'mean': 0.358}
        """
        out: dict[str, dict[str, float]] = {}
        for j, name in enumerate(("rmse", "max_error")):
            col = self.metrics[:, j]
            ok = col[np.isfinite(col)]
            if ok.size == 0:
                out[name] = {f"p{q:g}": math.inf for q in _PERCENTILES} | {"max": math.inf, "mean": math.inf}
                continue
            d = {f"p{q:g}": float(v) for q, v in zip(_PERCENTILES, np.percentile(ok, _PERCENTILES), strict=True)}
            out[name] = d | {"max": float(ok.max()), "mean": float(ok.mean())}
        return out

    def worst(self, k: int = 5) -> list[dict[str, Any]]:
        """The ``k`` samples of largest RMSE (diverged first): index, noise seed, metrics, each
        perturbed parameter's factor and value.

        Parameters
        ----------
        k : int, optional
            How many samples (default 5).

        Returns
        -------
        list of dict

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst import PID, virtual_stage
        >>> from piezohyst.fleet import RobustnessProblem, Runner, parse_perturbations, plan, robustness
        >>> stage = virtual_stage()
        >>> ref = 8e-6 + 5e-6 * np.sin(2 * np.pi * 25 * np.arange(400) * stage.sample_time)
        >>> kinds = tuple(parse_perturbations("mass=±10%,stiffness=±10%"))
        >>> problem = RobustnessProblem(stage, PID(kp=2e6, ki=2e9), ref, 100, kinds, 0)
        >>> res = robustness(problem, 16, Runner(plan("serial", env={})), chunk=8)
        >>> w = res.worst(1)[0]
        >>> w["sample"], round(w["rmse"] * 1e6, 3), round(w["parameters"]["stiffness"]["factor"], 3)
        (9, 0.457, 1.077)
        """
        order = np.lexsort((np.arange(self.samples), -np.nan_to_num(self.metrics[:, 0], posinf=np.inf)))[:k]
        sp = self.problem.stage.params
        out = []
        for i in order:
            params = {}
            for p, f in zip(self.problem.perturbations, self.factors[i], strict=True):
                nominal = getattr(sp, p.name)
                value = [w * f for w in nominal] if isinstance(nominal, tuple) else nominal * f
                params[p.name] = {"factor": float(f), "value": value, "nominal": nominal}
            out.append(
                {
                    "sample": int(i),
                    "noise_seed": int(self.seeds[i]),
                    "rmse": float(self.metrics[i, 0]),
                    "max_error": float(self.metrics[i, 1]),
                    "saturated_fraction": float(self.metrics[i, 2]),
                    "parameters": params,
                }
            )
        return out

    def sensitivity(self, *, deviation: bool = False) -> dict[str, float]:
        """Spearman rank correlation of each factor with the RMSE: which parameter drives the
        error, and which way (a feedback loop: a stiffer part lags more). ``deviation=True``: of
        ``|factor - 1|`` instead, for an error that grows both ways off nominal (a feedforward
        inverse: any gain mismatch), where the plain correlation is near 0.

        Parameters
        ----------
        deviation : bool, optional
            Correlate ``|factor - 1|`` instead of the factor (default False).

        Returns
        -------
        dict of str to float
            Each perturbed parameter's rank correlation (NaN with fewer than 3 finite runs).

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst import PID, virtual_stage
        >>> from piezohyst.fleet import RobustnessProblem, Runner, parse_perturbations, plan, robustness
        >>> stage = virtual_stage()
        >>> ref = 8e-6 + 5e-6 * np.sin(2 * np.pi * 25 * np.arange(400) * stage.sample_time)
        >>> kinds = tuple(parse_perturbations("mass=±10%,stiffness=±10%"))
        >>> problem = RobustnessProblem(stage, PID(kp=2e6, ki=2e9), ref, 100, kinds, 0)
        >>> res = robustness(problem, 16, Runner(plan("serial", env={})), chunk=8)
        >>> {k: round(v, 2) for k, v in res.sensitivity().items()}  # the stiffness drives the error
        {'mass': -0.08, 'stiffness': 0.99}
        """
        from scipy.stats import spearmanr

        rmse = self.metrics[:, 0]
        ok = np.isfinite(rmse)
        out = {}
        for c, name in enumerate(self.names):
            if ok.sum() < 3:
                out[name] = math.nan
                continue
            f = self.factors[ok, c]
            rho = spearmanr(np.abs(f - 1.0) if deviation else f, rmse[ok]).statistic
            out[name] = float(rho)
        return out

    def to_dict(self) -> dict[str, Any]:
        """The result as plain JSON-ready data (``piezohyst robustness --json``): the samples,
        seed, perturbations, nominal run, percentiles, diverged and saturated runs, sensitivities,
        worst cases, wall time and failed chunks.

        Returns
        -------
        dict

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst import PID, virtual_stage
        >>> from piezohyst.fleet import RobustnessProblem, Runner, parse_perturbations, plan, robustness
        >>> stage = virtual_stage()
        >>> ref = 8e-6 + 5e-6 * np.sin(2 * np.pi * 25 * np.arange(400) * stage.sample_time)
        >>> kinds = tuple(parse_perturbations("mass=±10%,stiffness=±10%"))
        >>> problem = RobustnessProblem(stage, PID(kp=2e6, ki=2e9), ref, 100, kinds, 0)
        >>> res = robustness(problem, 16, Runner(plan("serial", env={})), chunk=8)
        >>> d = res.to_dict()
        >>> d["samples"], d["diverged"], d["perturbations"]
        (16, 0, ['mass=±10%', 'stiffness=±10%'])
        """
        m = self.metrics
        return {
            "samples": self.samples,
            "seed": self.problem.seed,
            "perturbations": [str(p) for p in self.problem.perturbations],
            "skip_samples": self.problem.skip,
            "reference_samples": int(self.problem.reference.size),
            "nominal": {"rmse": float(self.nominal[0]), "max_error": float(self.nominal[1])},
            "percentiles": self.percentiles(),
            "diverged": int(np.count_nonzero(~np.isfinite(m[:, 0]))),
            "saturated_runs": int(np.count_nonzero(m[:, 2] > 0)),
            "sensitivity_spearman": self.sensitivity(),
            "sensitivity_spearman_deviation": self.sensitivity(deviation=True),
            "worst": self.worst(),
            "wall_time_s": self.wall_time,
            "errors": list(self.errors),
        }

    def to_pandas(self) -> Any:
        """One row per part: each perturbed parameter's factor, the noise seed, ``rmse`` and
        ``max_error`` (m) and ``saturated_fraction`` (needs pandas: without it an ``ImportError``
        says ``pip install pandas``).

        Returns
        -------
        pandas.DataFrame
            Indexed by ``sample``.

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst import PID, virtual_stage
        >>> from piezohyst.fleet import RobustnessProblem, Runner, parse_perturbations, plan, robustness
        >>> stage = virtual_stage()
        >>> ref = 8e-6 + 5e-6 * np.sin(2 * np.pi * 25 * np.arange(400) * stage.sample_time)
        >>> kinds = tuple(parse_perturbations("mass=±10%,stiffness=±10%"))
        >>> problem = RobustnessProblem(stage, PID(kp=2e6, ki=2e9), ref, 100, kinds, 0)
        >>> res = robustness(problem, 16, Runner(plan("serial", env={})), chunk=8)
        >>> try:
        ...     df = res.to_pandas()
        ... except ImportError:  # pandas is optional
        ...     df = None
        >>> df is None or list(df.columns) == [
        ...     "factor_mass", "factor_stiffness", "noise_seed", "rmse", "max_error", "saturated_fraction"
        ... ]
        True
        """
        pd = require_pandas(type(self).__name__)
        columns: dict[str, Any] = {f"factor_{n}": self.factors[:, j] for j, n in enumerate(self.names)}
        columns |= {
            "noise_seed": self.seeds,
            "rmse": self.metrics[:, 0],
            "max_error": self.metrics[:, 1],
            "saturated_fraction": self.metrics[:, 2],
        }
        return pd.DataFrame(columns, index=pd.RangeIndex(self.samples, name="sample"))

    def _repr_html_(self) -> str:
        pct = self.percentiles()
        rows = [
            ("parts", str(self.samples)),
            ("perturbations", ", ".join(str(p) for p in self.problem.perturbations)),
            ("nominal RMSE", f"{self.nominal[0] * 1e6:.4g} µm"),
        ]
        rows += [(f"RMSE {q}", f"{v * 1e6:.4g} µm") for q, v in pct["rmse"].items()]
        if self.errors:
            rows.append(("failed chunks", str(len(self.errors))))
        return html_table("RobustnessResult", rows)

    def replay(self, sample: int) -> ClosedLoopResult:
        """Sample ``sample`` run again with its signals (for a figure).

        Parameters
        ----------
        sample : int
            The sample's index.

        Returns
        -------
        ClosedLoopResult
            Its reference, command, voltage, position and error over time.

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst import PID, virtual_stage
        >>> from piezohyst.fleet import RobustnessProblem, Runner, parse_perturbations, plan, robustness
        >>> stage = virtual_stage()
        >>> ref = 8e-6 + 5e-6 * np.sin(2 * np.pi * 25 * np.arange(400) * stage.sample_time)
        >>> kinds = tuple(parse_perturbations("mass=±10%,stiffness=±10%"))
        >>> problem = RobustnessProblem(stage, PID(kp=2e6, ki=2e9), ref, 100, kinds, 0)
        >>> res = robustness(problem, 16, Runner(plan("serial", env={})), chunk=8)
        >>> run = res.replay(9)  # the same run: its RMSE after the skipped samples is the metric's
        >>> bool(np.isclose(np.sqrt(np.mean(run.error[100:] ** 2)), res.metrics[9, 0], rtol=1e-9))
        True
        """
        p = self.problem
        row = p.rows(self.factors[sample : sample + 1])[0]
        return closed_loop_perturbed(p.stage, p.controller, p.reference, row, int(self.seeds[sample]), skip=p.skip)

    def plot(self) -> Figure:
        """RMSE distribution with its percentiles, RMSE against each perturbed parameter, and the
        worst part's tracking error beside the nominal stage's.

        Returns
        -------
        matplotlib.figure.Figure

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst import PID, virtual_stage
        >>> from piezohyst.fleet import RobustnessProblem, Runner, parse_perturbations, plan, robustness
        >>> stage = virtual_stage()
        >>> ref = 8e-6 + 5e-6 * np.sin(2 * np.pi * 25 * np.arange(400) * stage.sample_time)
        >>> kinds = tuple(parse_perturbations("mass=±10%,stiffness=±10%"))
        >>> problem = RobustnessProblem(stage, PID(kp=2e6, ki=2e9), ref, 100, kinds, 0)
        >>> res = robustness(problem, 16, Runner(plan("serial", env={})), chunk=8)
        >>> import matplotlib
        >>> matplotlib.use("Agg")
        >>> fig = res.plot()
        >>> len(fig.axes)  # the distribution, the worst run, one panel per parameter
        4
        """
        import matplotlib.pyplot as plt

        k = len(self.names)
        fig = plt.figure(figsize=(11, 7))
        grid = fig.add_gridspec(2, max(k, 2))
        ax = fig.add_subplot(grid[0, : max(k, 2) // 2])
        rmse_um = self.metrics[:, 0] * 1e6
        finite = rmse_um[np.isfinite(rmse_um)]
        if finite.size:
            ax.hist(finite, bins=min(80, max(10, finite.size // 50)), color="tab:blue", alpha=0.8)
        pct = self.percentiles()["rmse"]
        for q, style in (("p50", "-"), ("p95", "--"), ("p99", ":")):
            if math.isfinite(pct[q]):
                ax.axvline(pct[q] * 1e6, color="k", ls=style, lw=1, label=f"{q} {pct[q] * 1e6:.3g} µm")
        ax.axvline(self.nominal[0] * 1e6, color="tab:green", lw=1.5, label=f"nominal {self.nominal[0] * 1e6:.3g} µm")
        ax.set_xlabel("tracking RMSE (µm)")
        ax.set_ylabel("parts")
        ax.legend(fontsize=7)
        ax.set_title(f"{self.samples} parts: {', '.join(str(p) for p in self.problem.perturbations)}", fontsize=8)
        ax2 = fig.add_subplot(grid[0, max(k, 2) // 2 :])
        worst = self.worst(1)[0]["sample"] if self.samples else None
        t = np.arange(self.problem.reference.size) * self.problem.stage.sample_time
        nominal_run = closed_loop_perturbed(
            self.problem.stage,
            self.problem.controller,
            self.problem.reference,
            self.problem.stage.core_params(),
            0,
            skip=self.problem.skip,
        )
        ax2.plot(t, nominal_run.error * 1e6, lw=0.8, color="tab:green", label="nominal")
        if worst is not None:
            ax2.plot(t, self.replay(worst).error * 1e6, lw=0.8, color="tab:red", label=f"worst (sample {worst})")
        ax2.axvline(self.problem.skip * self.problem.stage.sample_time, color="k", lw=0.5, ls=":")
        ax2.set_xlabel("time (s)")
        ax2.set_ylabel("tracking error (µm)")
        ax2.legend(fontsize=7)
        sens, dev = self.sensitivity(), self.sensitivity(deviation=True)
        for c, name in enumerate(self.names):
            a = fig.add_subplot(grid[1, c])
            ok = np.isfinite(rmse_um)
            a.plot(100 * (self.factors[ok, c] - 1), rmse_um[ok], ".", ms=1.5, alpha=0.4)
            a.set_xlabel(f"{name} (% off nominal)", fontsize=8)
            a.set_title(f"Spearman {sens[name]:+.2f}; with |off nominal| {dev[name]:+.2f}", fontsize=8)
            if c == 0:
                a.set_ylabel("RMSE (µm)")
            a.tick_params(labelsize=7)
        fig.tight_layout()
        return fig


def robustness(
    problem: RobustnessProblem,
    samples: int,
    runner: Runner,
    *,
    chunk: int = 500,
    progress: Progress | None = None,
) -> RobustnessResult:
    """Run ``samples`` parts of ``problem`` in chunks of ``chunk`` (each a task of ``runner``) and
    collect them in sample order. A chunk that fails is listed in ``errors`` and its samples are
    NaN; the others are kept.

    Parameters
    ----------
    problem : RobustnessProblem
        What to run.
    samples : int
        Monte-Carlo samples (parts).
    runner : Runner
        Where the chunks run (:func:`piezohyst.fleet.runner`).
    chunk : int, optional
        Samples per task (default 500): the result does not depend on it.
    progress : piezohyst.progress.Progress, optional
        The run's progress display.

    Returns
    -------
    RobustnessResult

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst import PID, virtual_stage
    >>> from piezohyst.fleet import RobustnessProblem, Runner, parse_perturbations, plan, robustness
    >>> stage = virtual_stage()
    >>> ref = 8e-6 + 5e-6 * np.sin(2 * np.pi * 25 * np.arange(400) * stage.sample_time)
    >>> kinds = tuple(parse_perturbations("mass=±10%,stiffness=±10%"))
    >>> problem = RobustnessProblem(stage, PID(kp=2e6, ki=2e9), ref, 100, kinds, 0)
    >>> res = robustness(problem, 16, Runner(plan("serial", env={})), chunk=8)
    >>> again = robustness(problem, 16, Runner(plan("serial", env={})), chunk=5)  # other chunks
    >>> bool(np.array_equal(res.metrics, again.metrics))
    True
    """
    import time

    if isinstance(samples, bool) or not isinstance(samples, int) or samples < 1:
        raise ParameterError(f"--samples = {samples!r} must be a whole number >= 1")
    if isinstance(chunk, bool) or not isinstance(chunk, int) or chunk < 1:
        raise ParameterError(f"chunk = {chunk!r} must be a whole number >= 1")
    t0 = time.perf_counter()
    k = len(problem.perturbations)
    factors = np.full((samples, k), np.nan)
    seeds = np.zeros(samples, dtype=np.uint64)
    metrics = np.full((samples, 3), np.nan)
    handle = runner.broadcast(problem)
    tasks = [(f"robustness-{a}", (handle, a, min(a + chunk, samples))) for a in range(0, samples, chunk)]
    errors = []
    for out in runner.run(run_chunk, tasks, progress):
        if out.error is not None:
            errors.append(f"{out.key}: {out.error}")
            continue
        c: Chunk = out.value
        n = c.metrics.shape[0]
        factors[c.start : c.start + n] = c.factors
        seeds[c.start : c.start + n] = c.seeds
        metrics[c.start : c.start + n] = c.metrics
    nominal = closed_loop_batch_stages(
        problem.stage,
        problem.controller,
        problem.reference,
        problem.stage.core_params()[None, :],
        np.zeros(1, dtype=np.uint64),
        skip=problem.skip,
    )[0]
    return RobustnessResult(problem, factors, seeds, metrics, nominal, time.perf_counter() - t0, tuple(sorted(errors)))
