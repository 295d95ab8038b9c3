"""A Preisach grid with a creep bank (issue 14: the 10 kHz records' creep on a Preisach loop):
the output is the grid's plus the bank's, the row carries the bank like the PI family's, a
row of two dims (written before the bank existed) still reads, the file round-trips and the
inverse covers the bank."""

import numpy as np
import pytest

import piezohyst as ph
from piezohyst import _core
from piezohyst.errors import ParameterTypeError


def grid(creep=None):
    w = np.linspace(0.1, 1.0, 10)
    return ph.Preisach(4, (0.0, 1.0), w, offset=0.2, slope=0.5, memory=16, creep=creep)


BANK = ph.Creep(1e-3, [0.01, 0.5], [0.3, 0.2])
V = 0.5 + 0.45 * np.sin(np.linspace(0, 20, 3000)) * np.linspace(1, 0.3, 3000)


def test_output_is_the_grid_plus_the_bank():
    y = grid(BANK).simulate(V)
    np.testing.assert_allclose(y, grid().simulate(V) + BANK.simulate(V), rtol=0, atol=1e-13)
    assert float(np.max(np.abs(y - grid().simulate(V)))) > 0.3  # the bank is not a no-op


def test_row_and_dims_carry_the_bank():
    m = grid(BANK)
    assert m.dims == (4, 16, 2)
    assert grid().dims == (4, 16, 0)
    row = m.to_row()
    # lo, hi, offset, slope, 10 cells, then creep_ts, the taus, the weights
    assert row.size == 4 + 10 + 1 + 2 + 2
    np.testing.assert_array_equal(row[-5:], [1e-3, 0.01, 0.5, 0.3, 0.2])
    layout = _core.family_layout("preisach", [4, 16, 2])
    assert layout["linear"][-1] == "creep_c" and "creep_c" in layout["nonnegative"]


def test_a_row_of_two_dims_still_reads():
    m = grid()
    old = _core.Model("preisach", [4, 16], m.to_row())  # a file or C code from before the bank
    assert np.array_equal(old.simulate(V), m.simulate(V))


def test_file_round_trip_and_inverse(tmp_path):
    m = grid(BANK).with_output_map(offset=0.1, gain=1.2)
    m.save(tmp_path / "p.json")
    back = ph.load_model(tmp_path / "p.json")
    assert isinstance(back, ph.Preisach) and back.creep is not None
    np.testing.assert_array_equal(back.creep.weights, BANK.weights)
    assert np.array_equal(back.simulate(V), m.simulate(V))
    y = m.simulate(V)
    assert float(np.max(np.abs(m.simulate(m.inverse().simulate(y)) - y))) < 1e-9


def test_folded_gain_scales_the_bank_and_extrapolation_keeps_it():
    m = grid(BANK).with_output_map(gain=2.0)
    assert np.allclose(m.simulate(V), 2.0 * grid(BANK).simulate(V), rtol=0, atol=1e-12)
    e = grid(BANK).extrapolated(2)
    assert e.creep is BANK
    np.testing.assert_allclose(e.simulate(V), grid(BANK).simulate(V), rtol=0, atol=1e-12)


def test_bad_creep_is_named():
    with pytest.raises(ParameterTypeError, match="creep"):
        ph.Preisach(2, (0.0, 1.0), [1.0, 1.0, 1.0], creep=[0.1])  # type: ignore[arg-type]
