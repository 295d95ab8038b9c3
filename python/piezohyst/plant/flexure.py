"""Piezo flexure stage calculator (docs/spec.md §3.1, seed 1).

A stage guided by ``n`` identical leaf springs (thin beams clamped at both ends, guided:
the ends stay parallel) and pushed by a piezo stack. Stage and actuator move together, so
the lumped model is one mass-spring-damper::

    meq x'' + beq x' + keq x = F = Tem (Vin - Vh)

with ``meq = m_actuator + m_stage``, ``keq = k_actuator + k_flexure`` (springs in parallel)
and ``beq = 2 zeta sqrt(keq meq)``. All quantities are SI: metres, kilograms, pascals
(N/m²), N/m, N·s/m, hertz, N/V.

Examples
--------
>>> from piezohyst.flexure import FlexureStage, LeafSpring
>>> leaf = LeafSpring(youngs_modulus=7.2e10, width=10e-3, thickness=1e-3, length=6e-3)
>>> f"{leaf.stiffness:.4g}"
'1.333e+07'
>>> stage = FlexureStage.seed1()
>>> f"{stage.keq:.4g} N/m, {stage.meq:.4g} kg, {stage.f_n:.4g} Hz"
'7.333e+07 N/m, 0.0714 kg, 5101 Hz'
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, NamedTuple

from .._validate import as_int, as_scalar
from ..errors import ParameterError, ParameterTypeError
from ..signals.lti import state_space
from . import linear

__all__ = ["A7075_YOUNGS_MODULUS", "CemfCoefficients", "FlexureStage", "LeafSpring", "seed1_stage"]

#: Young's modulus of aluminium A7075 used by seed 1, in Pa (N/m²).
A7075_YOUNGS_MODULUS = 7.2e10


def _set(obj: object, name: str, value: object) -> None:
    object.__setattr__(obj, name, value)


@dataclass(frozen=True)
class LeafSpring:
    """``count`` identical leaf springs working in parallel (a guided-beam flexure).

    Each leaf is a rectangular beam of ``length`` L (along the leaf), ``width`` h (across the
    motion, the beam's depth out of the plane) and ``thickness`` d (along the motion),
    clamped at both ends with the ends kept parallel. Its stiffness in the direction of
    motion (seed 1, eq. for a guided beam)::

        I = h d^3 / 12                 second moment of area [m^4]
        k_leaf = 12 E I / L^3 = E h d^3 / L^3      [N/m]
        k = count * k_leaf             [N/m]

    Parameters
    ----------
    youngs_modulus : float
        E in Pa (N/m²), ``> 0``.
    width : float
        h in m, ``> 0``.
    thickness : float
        d in m, ``> 0`` (the stiffness scales with ``d^3``).
    length : float
        L in m, ``> 0`` (the stiffness scales with ``1 / L^3``).
    count : int, optional
        Number of leaves in parallel, ``>= 1`` (default 4, as in seed 1).

    Examples
    --------
    >>> leaf = LeafSpring(7.2e10, width=0.01, thickness=0.001, length=0.006, count=1)
    >>> f"{leaf.second_moment:.4g} m^4, {leaf.leaf_stiffness:.4g} N/m"
    '8.333e-13 m^4, 3.333e+06 N/m'
    """

    youngs_modulus: float
    width: float
    thickness: float
    length: float
    count: int = 4

    def __post_init__(self) -> None:
        for name in ("youngs_modulus", "width", "thickness", "length"):
            _set(self, name, as_scalar(getattr(self, name), name, positive=True))
        _set(self, "count", as_int(self.count, "count", minimum=1))

    @property
    def second_moment(self) -> float:
        """Second moment of area of one leaf, ``I = h d^3 / 12`` [m^4]."""
        return self.width * self.thickness**3 / 12.0

    @property
    def leaf_stiffness(self) -> float:
        """Stiffness of one leaf, ``12 E I / L^3`` [N/m]."""
        return 12.0 * self.youngs_modulus * self.second_moment / self.length**3

    @property
    def stiffness(self) -> float:
        """Stiffness of all ``count`` leaves in parallel, ``count * k_leaf`` [N/m]."""
        return self.count * self.leaf_stiffness

    @classmethod
    def seed1(cls) -> LeafSpring:
        """Seed 1's flexure: four A7075 leaves (E = 7.2e10 Pa), h = 10 mm, d = 1 mm, L = 6 mm,
        giving ``k_f = 1.333e7 N/m``.

        Returns
        -------
        LeafSpring

        Examples
        --------
        >>> f"{LeafSpring.seed1().stiffness:.4g}"
        '1.333e+07'
        """
        return cls(A7075_YOUNGS_MODULUS, width=10e-3, thickness=1e-3, length=6e-3, count=4)


class CemfCoefficients(NamedTuple):
    """Plant coefficients of the CEMF model normalized by the electromechanical transformation
    ratio: ``M x'' + B x' + K x = Vin - Vh`` (docs/spec.md §2.6).

    Parameters
    ----------
    M : float
        ``meq / Tem`` [V·s²/m].
    B : float
        ``beq / Tem`` [V·s/m].
    K : float
        ``keq / Tem`` [V/m].

    Examples
    --------
    >>> from piezohyst.plant import CemfCoefficients, FlexureStage
    >>> c = FlexureStage.seed1().cemf_coefficients(tem=10.0)
    >>> isinstance(c, CemfCoefficients), f"{c.K:.4g}"
    (True, '7.333e+06')
    """

    M: float
    B: float
    K: float

    def to_control(self) -> Any:
        """``1 / (M s^2 + B s + K)`` from the voltage ``Vin - Vh`` (V) to the position (m), a
        continuous python-control ``StateSpace``.

        Returns
        -------
        control.StateSpace
            States ``x`` (m), ``v`` (m/s).

        Examples
        --------
        >>> c = CemfCoefficients(M=0.00714, B=13.07, K=7.333e6)
        >>> bool(abs(c.to_control().dcgain() - 1 / 7.333e6) < 1e-20)
        True
        """
        part = linear.LinearPart(self.M, self.B, self.K, 1.0, 1.0, (), (), 0.0)
        sys = linear.linear_system(part)
        return state_space(
            sys.a, sys.b, sys.c, sys.d, inputs=["voltage"], outputs=["position"], states=sys.states, name="cemf_plant"
        )

    @classmethod
    def from_control(cls, sys: object) -> CemfCoefficients:
        """The coefficients whose plant :meth:`to_control` is ``sys``, a continuous
        ``b0 / (s^2 + a1 s + a0)`` without zeros: ``M = 1 / b0``, ``B = a1 / b0``, ``K = a0 / b0``.

        Parameters
        ----------
        sys : control.LTI or scipy.signal.lti
            The plant, input volts, output metres (``ParameterError`` for another form).

        Returns
        -------
        CemfCoefficients

        Examples
        --------
        >>> import control
        >>> CemfCoefficients.from_control(control.tf([1.0], [0.5, 2.0, 8.0]))
        CemfCoefficients(M=0.5, B=2.0, K=8.0)
        """
        return cls(*linear.second_order_from_control(sys, 1.0))


@dataclass(frozen=True)
class FlexureStage:
    """A piezo actuator driving a flexure-guided stage: lumped second-order plant.

    Parameters
    ----------
    actuator_stiffness : float
        Stack stiffness ``k_z`` [N/m], ``>= 0`` (datasheet value; 6e7 for a PSt 150/5x5/20).
    flexure_stiffness : float
        Flexure stiffness ``k_f`` [N/m], ``>= 0`` (e.g. ``LeafSpring.stiffness``).
    actuator_mass : float
        Moving mass of the actuator ``m_z`` [kg], ``> 0``.
    stage_mass : float
        Moving mass of the stage ``m_f`` [kg], ``> 0``.
    zeta : float, optional
        Damping ratio, ``>= 0`` (default 0.03; seed 1 calls the damping "almost zero",
        docs/spec.md §3.1 suggests 0.02-0.05).

    Notes
    -----
    Derived quantities are read-only properties:

    meq : float
        ``m_z + m_f`` [kg].
    keq : float
        ``k_z + k_f`` [N/m] (springs in parallel; must be > 0).
    beq : float
        ``2 zeta sqrt(keq meq)`` [N·s/m].
    omega_n : float
        ``sqrt(keq / meq)`` [rad/s].
    f_n : float
        ``omega_n / (2 pi)`` [Hz].

    Examples
    --------
    >>> stage = FlexureStage.from_leaf_spring(LeafSpring.seed1(), actuator_stiffness=6e7,
    ...                                       actuator_mass=0.0044, stage_mass=0.067)
    >>> f"{stage.keq:.4g}", f"{stage.f_n:.4g}", f"{stage.beq:.4g}"
    ('7.333e+07', '5101', '137.3')
    """

    actuator_stiffness: float
    flexure_stiffness: float
    actuator_mass: float
    stage_mass: float
    zeta: float = 0.03

    def __post_init__(self) -> None:
        for name in ("actuator_stiffness", "flexure_stiffness", "zeta"):
            _set(self, name, as_scalar(getattr(self, name), name, nonnegative=True))
        for name in ("actuator_mass", "stage_mass"):
            _set(self, name, as_scalar(getattr(self, name), name, positive=True))
        if not self.actuator_stiffness + self.flexure_stiffness > 0:
            raise ParameterError(
                f"actuator_stiffness + flexure_stiffness = {self.actuator_stiffness} + "
                f"{self.flexure_stiffness} must be > 0"
            )

    @classmethod
    def from_leaf_spring(
        cls, leaf: LeafSpring, actuator_stiffness: float, actuator_mass: float, stage_mass: float, zeta: float = 0.03
    ) -> FlexureStage:
        """Stage guided by ``leaf`` (a :class:`LeafSpring`); ``k_f = leaf.stiffness``.

        Parameters
        ----------
        leaf : LeafSpring
            The flexure.
        actuator_stiffness : float
            The stack's stiffness ``k_z``, N/m.
        actuator_mass, stage_mass : float
            ``m_z`` and ``m_f``, kg.
        zeta : float
            Damping ratio.

        Returns
        -------
        FlexureStage

        Examples
        --------
        >>> from piezohyst.plant import FlexureStage, LeafSpring
        >>> s = FlexureStage.from_leaf_spring(LeafSpring.seed1(), 6e7, 0.0044, 0.067)
        >>> f"{s.keq:.4g} N/m, {s.f_n:.4g} Hz"
        '7.333e+07 N/m, 5101 Hz'
        """
        if not isinstance(leaf, LeafSpring):
            raise ParameterTypeError(f"leaf must be a LeafSpring, got {leaf!r}")
        return cls(actuator_stiffness, leaf.stiffness, actuator_mass, stage_mass, zeta)

    @classmethod
    def seed1(cls, zeta: float = 0.03) -> FlexureStage:
        """Seed 1's stage: :meth:`LeafSpring.seed1` flexure (k_f = 1.333e7 N/m), PSt 150/5x5/20
        stack (k_z = 6e7 N/m), m_z = 0.0044 kg, m_f = 0.067 kg → keq = 7.333e7 N/m,
        meq = 0.0714 kg, f_n ≈ 5.1 kHz.

        Parameters
        ----------
        zeta : float
            Damping ratio (seed 1: "almost zero"; 0.02–0.05 is typical).

        Returns
        -------
        FlexureStage

        Examples
        --------
        >>> s = FlexureStage.seed1()
        >>> f"{s.flexure_stiffness:.4g} {s.keq:.4g} {s.meq:.4g} {s.f_n:.4g}"
        '1.333e+07 7.333e+07 0.0714 5101'
        """
        return cls.from_leaf_spring(
            LeafSpring.seed1(), actuator_stiffness=6e7, actuator_mass=0.0044, stage_mass=0.067, zeta=zeta
        )

    @property
    def meq(self) -> float:
        """Equivalent moving mass ``m_z + m_f`` [kg]."""
        return self.actuator_mass + self.stage_mass

    @property
    def keq(self) -> float:
        """Equivalent stiffness ``k_z + k_f`` [N/m]."""
        return self.actuator_stiffness + self.flexure_stiffness

    @property
    def beq(self) -> float:
        """Equivalent damping ``2 zeta sqrt(keq meq)`` [N·s/m]."""
        return 2.0 * self.zeta * math.sqrt(self.keq * self.meq)

    @property
    def omega_n(self) -> float:
        """Undamped natural angular frequency ``sqrt(keq / meq)`` [rad/s]."""
        return math.sqrt(self.keq / self.meq)

    @property
    def f_n(self) -> float:
        """Undamped natural frequency ``sqrt(keq / meq) / (2 pi)`` [Hz]."""
        return self.omega_n / (2.0 * math.pi)

    def to_control(self, tem: float | None = None) -> Any:
        """The lumped plant ``meq x'' + beq x' + keq x = F`` as a continuous python-control
        ``StateSpace`` from the force ``F`` (N) to the position (m); with ``tem`` (N/V) from the
        piezo voltage ``Vin - Vh`` (V) instead (``F = Tem (Vin - Vh)``).

        Parameters
        ----------
        tem : float, optional
            Electromechanical transformation ratio ``Tem`` (N/V, ``> 0``); ``None``: force input.

        Returns
        -------
        control.StateSpace
            States ``x`` (m), ``v`` (m/s).

        Examples
        --------
        >>> s = FlexureStage.seed1()
        >>> f"{s.to_control().dcgain():.4g} m/N"
        '1.364e-08 m/N'
        """
        gain = 1.0 if tem is None else as_scalar(tem, "tem", positive=True)
        part = linear.LinearPart(self.meq, self.beq, self.keq, gain, gain, (), (), 0.0)
        sys = linear.linear_system(part)
        return state_space(
            sys.a,
            sys.b,
            sys.c,
            sys.d,
            inputs=["force" if tem is None else "voltage"],
            outputs=["position"],
            states=sys.states,
            name="flexure_stage",
        )

    def cemf_coefficients(self, tem: float) -> CemfCoefficients:
        """CEMF-normalized plant ``M = meq/Tem, B = beq/Tem, K = keq/Tem`` (docs/spec.md §2.6).

        Parameters
        ----------
        tem : float
            Electromechanical transformation ratio ``Tem`` [N/V], ``> 0``.

        Returns
        -------
        CemfCoefficients
            ``(M, B, K)`` in V·s²/m, V·s/m and V/m.

        Examples
        --------
        >>> M, B, K = FlexureStage.seed1(zeta=0.0).cemf_coefficients(tem=10.0)
        >>> f"{M:.4g} {B:.4g} {K:.4g}"
        '0.00714 0 7.333e+06'
        """
        tem = as_scalar(tem, "tem", positive=True)
        return CemfCoefficients(self.meq / tem, self.beq / tem, self.keq / tem)


def seed1_stage(zeta: float = 0.03) -> FlexureStage:
    """Seed 1's flexure stage; same as :meth:`FlexureStage.seed1`.

    Parameters
    ----------
    zeta : float
        Damping ratio.

    Returns
    -------
    FlexureStage

    Examples
    --------
    >>> f"{seed1_stage().f_n:.4g} Hz"
    '5101 Hz'
    """
    return FlexureStage.seed1(zeta=zeta)
