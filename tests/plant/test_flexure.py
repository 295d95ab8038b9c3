"""Flexure stage calculator (docs/spec.md §3.1): seed 1's numbers, scaling laws and bad input."""

import dataclasses
import math
import re

import numpy as np
import pytest

from piezohyst.flexure import A7075_YOUNGS_MODULUS, CemfCoefficients, FlexureStage, LeafSpring, seed1_stage


def sig4(x):
    return float(f"{x:.4g}")


def test_seed1_leaf_spring():
    leaf = LeafSpring.seed1()
    assert (leaf.youngs_modulus, leaf.width, leaf.thickness, leaf.length, leaf.count) == (7.2e10, 0.01, 0.001, 0.006, 4)
    assert leaf.youngs_modulus == A7075_YOUNGS_MODULUS
    assert sig4(leaf.second_moment) == 8.333e-13  # h d^3 / 12
    assert sig4(leaf.leaf_stiffness) == 3.333e6  # 12 E I / L^3
    assert sig4(leaf.stiffness) == 1.333e7  # four in parallel: seed 1's k_f
    assert leaf.stiffness == pytest.approx(4 * 7.2e10 * 0.01 * 0.001**3 / 0.006**3, rel=1e-14)


def test_seed1_stage():
    stage = FlexureStage.seed1()
    assert stage.actuator_stiffness == 6e7
    assert sig4(stage.flexure_stiffness) == 1.333e7
    assert sig4(stage.keq) == 7.333e7
    assert sig4(stage.meq) == 0.0714
    assert stage.meq == pytest.approx(0.0044 + 0.067, rel=1e-15)
    assert sig4(stage.f_n) == 5101  # "about 5.1 kHz"
    assert stage.f_n == pytest.approx(math.sqrt(stage.keq / stage.meq) / (2 * math.pi), rel=1e-15)
    assert stage.omega_n == pytest.approx(2 * math.pi * stage.f_n, rel=1e-15)
    assert stage.zeta == 0.03
    assert sig4(stage.beq) == 137.3  # 2 * 0.03 * sqrt(7.333e7 * 0.0714)
    assert FlexureStage.seed1(zeta=0.0).beq == 0.0
    assert seed1_stage() == stage


def test_from_leaf_spring_equals_direct_construction():
    leaf = LeafSpring(2e11, width=5e-3, thickness=0.5e-3, length=10e-3, count=2)
    a = FlexureStage.from_leaf_spring(leaf, actuator_stiffness=1e7, actuator_mass=0.002, stage_mass=0.05, zeta=0.05)
    b = FlexureStage(1e7, leaf.stiffness, 0.002, 0.05, zeta=0.05)
    assert a == b
    assert a.keq == pytest.approx(1e7 + 2 * 2e11 * 5e-3 * 0.5e-3**3 / 10e-3**3, rel=1e-14)


def test_leaf_spring_scaling_laws():
    base = LeafSpring(7e10, 0.01, 0.001, 0.006, count=1)
    assert LeafSpring(7e10, 0.01, 0.002, 0.006, count=1).stiffness == pytest.approx(8 * base.stiffness)
    assert LeafSpring(7e10, 0.01, 0.001, 0.012, count=1).stiffness == pytest.approx(base.stiffness / 8)
    assert LeafSpring(7e10, 0.02, 0.001, 0.006, count=1).stiffness == pytest.approx(2 * base.stiffness)
    assert LeafSpring(1.4e11, 0.01, 0.001, 0.006, count=1).stiffness == pytest.approx(2 * base.stiffness)
    assert LeafSpring(7e10, 0.01, 0.001, 0.006, count=6).stiffness == pytest.approx(6 * base.stiffness)


def test_plant_poles_match_natural_frequency_and_damping():
    stage = FlexureStage.seed1(zeta=0.04)
    a = np.array([[0.0, 1.0], [-stage.keq / stage.meq, -stage.beq / stage.meq]])
    poles = np.linalg.eigvals(a)
    assert np.abs(poles) == pytest.approx([stage.omega_n] * 2, rel=1e-12)
    assert -poles.real / np.abs(poles) == pytest.approx([0.04] * 2, rel=1e-12)


def test_cemf_coefficients():
    stage = FlexureStage.seed1()
    tem = 4.5
    c = stage.cemf_coefficients(tem)
    assert isinstance(c, CemfCoefficients)
    M, B, K = c
    assert (M, B, K) == (c.M, c.B, c.K)
    assert M == pytest.approx(stage.meq / tem, rel=1e-15)
    assert B == pytest.approx(stage.beq / tem, rel=1e-15)
    assert K == pytest.approx(stage.keq / tem, rel=1e-15)
    assert sig4(K) == sig4(7.333e7 / 4.5)
    # Normalizing does not move the resonance.
    assert math.sqrt(K / M) == pytest.approx(stage.omega_n, rel=1e-14)
    assert stage.cemf_coefficients(1).K == stage.keq


def test_frozen_and_float_fields():
    stage = FlexureStage(6e7, 1e7, 0.004, np.float64(0.06), zeta=np.float32(0.02))
    assert type(stage.stage_mass) is float and type(stage.zeta) is float
    with pytest.raises(dataclasses.FrozenInstanceError):
        stage.zeta = 0.1
    leaf = LeafSpring(7e10, 0.01, 0.001, 0.006, count=np.int64(3))
    assert type(leaf.count) is int
    with pytest.raises(dataclasses.FrozenInstanceError):
        leaf.count = 2


def _leaf(**kw):
    args = dict(youngs_modulus=7.2e10, width=0.01, thickness=0.001, length=0.006)
    args.update(kw)
    return LeafSpring(**args)


def _stage(**kw):
    args = dict(actuator_stiffness=6e7, flexure_stiffness=1.3e7, actuator_mass=0.0044, stage_mass=0.067)
    args.update(kw)
    return FlexureStage(**args)


BAD = [
    (lambda: _leaf(youngs_modulus=0.0), ValueError, "youngs_modulus = 0.0 must be > 0"),
    (lambda: _leaf(width=-0.01), ValueError, "width = -0.01 must be > 0"),
    (lambda: _leaf(thickness=0), ValueError, "thickness = 0.0 must be > 0"),
    (lambda: _leaf(length=float("nan")), ValueError, "length = nan is not finite"),
    (lambda: _leaf(length=float("inf")), ValueError, "length = inf"),
    (lambda: _leaf(width="1 cm"), TypeError, "width"),
    (lambda: _leaf(count=0), ValueError, "count = 0 must be >= 1"),
    (lambda: _leaf(count=2.5), TypeError, "count"),
    (lambda: _stage(actuator_stiffness=-1.0), ValueError, "actuator_stiffness = -1.0 must be >= 0"),
    (lambda: _stage(flexure_stiffness=-5), ValueError, "flexure_stiffness = -5.0 must be >= 0"),
    (lambda: _stage(actuator_stiffness=0, flexure_stiffness=0), ValueError, "actuator_stiffness + flexure_stiffness"),
    (lambda: _stage(actuator_mass=0), ValueError, "actuator_mass = 0.0 must be > 0"),
    (lambda: _stage(stage_mass=-0.1), ValueError, "stage_mass = -0.1 must be > 0"),
    (lambda: _stage(zeta=-0.01), ValueError, "zeta = -0.01 must be >= 0"),
    (lambda: _stage(zeta=float("nan")), ValueError, "zeta = nan"),
    (lambda: _stage(zeta=None), TypeError, "zeta"),
    (lambda: FlexureStage.seed1(zeta=-1), ValueError, "zeta = -1.0"),
    (lambda: FlexureStage.from_leaf_spring(1.3e7, 6e7, 0.0044, 0.067), TypeError, "leaf must be a LeafSpring"),
    (lambda: FlexureStage.seed1().cemf_coefficients(0.0), ValueError, "tem = 0.0 must be > 0"),
    (lambda: FlexureStage.seed1().cemf_coefficients(-2), ValueError, "tem = -2.0 must be > 0"),
    (lambda: FlexureStage.seed1().cemf_coefficients("4"), TypeError, "tem"),
]


@pytest.mark.parametrize("make,exc,msg", BAD, ids=[b[2] for b in BAD])
def test_bad_input(make, exc, msg):
    with pytest.raises(exc, match=re.escape(msg)):
        make()
