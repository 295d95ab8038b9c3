"""What a Dask task carries (issue 16, item 3): models, controllers, stages and records survive a
pickle round trip and work the same after it, also when the pickle's buffers arrive at odd byte
offsets, as Dask's zero-copy messages deliver them (the Rust core reads aligned memory only)."""

import pickle

import numpy as np
import pytest

from piezohyst import closed_loop, virtual_stage
from piezohyst.cli.track import _CONTROLLERS, _build_controller
from piezohyst.signals.data import Record
from tests.models_zoo import drive, zoo

STAGE = virtual_stage()


def odd_roundtrip(obj):
    """Pickle protocol 5 with out-of-band buffers, each handed back at an odd address."""
    buffers = []
    data = pickle.dumps(obj, protocol=5, buffer_callback=buffers.append)
    odd = []
    for b in buffers:
        raw = b.raw()
        block = memoryview(bytearray(len(raw) + 1))[1:]
        block[:] = raw
        odd.append(block)
    return pickle.loads(data, buffers=odd)


@pytest.mark.parametrize("roundtrip", [lambda o: pickle.loads(pickle.dumps(o)), odd_roundtrip])
@pytest.mark.parametrize("name", sorted(zoo()))
def test_models_simulate_the_same_after_a_round_trip(name, roundtrip):
    m = zoo()[name]
    v = drive(400)
    assert np.array_equal(roundtrip(m).simulate(v), m.simulate(v))


@pytest.mark.parametrize("roundtrip", [lambda o: pickle.loads(pickle.dumps(o)), odd_roundtrip])
@pytest.mark.parametrize("kind", _CONTROLLERS)
def test_controllers_and_stages_run_the_same_closed_loop_after_a_round_trip(kind, roundtrip):
    c = _build_controller(kind, STAGE, None)
    t = np.arange(0, 0.03, STAGE.sample_time)
    ref = 8e-6 + 4e-6 * np.sin(2 * np.pi * 30 * t)
    a = closed_loop(STAGE, c, ref, rng=3)
    stage2, c2 = roundtrip((STAGE, c))
    b = closed_loop(stage2, c2, ref, rng=3)
    assert np.array_equal(a.position, b.position)
    assert stage2 == STAGE


def test_a_record_identifies_the_same_after_an_odd_round_trip():
    from piezohyst import identify

    v = drive(1500)
    y = zoo()["mpi"].simulate(v)
    rec = Record(v, y, fs=1000.0, source="drive")
    back = odd_roundtrip(rec)
    assert back.source == "drive" and back.fs == rec.fs
    a = identify(rec.input, rec.output, model="mpi", fs=rec.fs)
    b = identify(back.input, back.output, model="mpi", fs=back.fs)
    assert np.array_equal(a.model.to_row(), b.model.to_row())
