"""One instance of every model kind, for tests that must cover them all."""

import numpy as np

import piezohyst as ph
from piezohyst import Envelope


def zoo():
    creep = ph.Creep(1e-3, [0.01, 0.1, 1.0], [0.01, 0.02, 0.03])
    r = np.linspace(0.05, 0.8, 6)
    w = np.array([0.4, 0.2, 0.1, 0.08, 0.05, 0.03])
    return {
        "pi": ph.PI(r, w, 0.9),
        "pi+creep": ph.PI(r, w, 0.9, creep=creep),
        "play": ph.PlayOperator(0.3),
        "gpi": ph.GeneralizedPI(
            r, w, (0, 0, 0, 0), Envelope.tanh(2.0, 0.8), Envelope.tanh(2.1, 0.75, 0.05, 0.02), input_range=(-1.5, 1.5)
        ),
        "mpi": ph.papers.mpi_seed2(),
        "mpi+creep": ph.GeneralizedPI(
            ph.papers.SEED2_TABLE1["thresholds"],
            ph.papers.SEED2_TABLE1["weights"],
            ph.papers.SEED2_TABLE1["polynomial"],
            Envelope.polynomial(0.0, 1.0, 0.0, 0.05),
            Envelope.polynomial(0.02, 0.9, 0.05, 0.07),
            input_range=(0, 1),
            creep=creep,
        ),
        "generalized_play": ph.GeneralizedPlay(
            0.2, Envelope.polynomial(0, 1.1), Envelope.identity(), input_range=(0, 1)
        ),
        "rdpi": ph.RateDependentPI(r, w, ts=1e-3, p0=0.8, beta=2e-4, rate_weights=np.full(6, 1e-4), filter_tau=2e-3),
        "creep": creep,
        "preisach": ph.Preisach(6, (-1.0, 1.0), np.linspace(0.1, 1.0, 21), offset=0.1, slope=0.3, memory=32),
        "boucwen": ph.BoucWen(1.0, 2.0, 0.5, n=1.0, d=1.2),
        "boucwen_n2": ph.BoucWen(1.0, 1.5, 0.5, n=2.0, d=1.0),
        "duhem": ph.Duhem(2.0, (0.0, 1.0, 0.0, 0.1), (0.3, 0.1, 0.0, 0.0)),
        "dahl": ph.Dahl(3.0, 0.7, 1.5),
    }


def drive(n=2000, seed=7):
    rng = np.random.default_rng(seed)
    return np.clip(0.5 + 0.45 * np.sin(np.linspace(0, 30, n)) * np.linspace(1, 0.2, n) + rng.normal(0, 0.01, n), 0, 1)
