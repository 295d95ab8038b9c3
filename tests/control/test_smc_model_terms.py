"""Seed 1's SMC cancels the stage stiffness with K̂ x on the measured position; at the end of
the stroke that positive feedback can ask for more than the amplifier gives and the loop latches
at the limit. model_terms="desired" (K̂ x_d, the default since issue 19) cannot latch and tracks
as well."""

import numpy as np
import pytest

import piezohyst as ph
from piezohyst.control import SMC

STAGE = ph.virtual_stage()
FS = 1 / STAGE.sample_time
GAINS = dict(kp=1.38e6, kv=6.8e3, ks=13.3, phi=0.015, cemf=True)


def steps():
    ref = np.r_[np.full(3000, 5e-6), np.full(3000, 21e-6), np.full(3000, 8e-6)]
    return ref, np.zeros_like(ref)


def test_measured_model_terms_latch_at_the_stroke_end_and_desired_ones_do_not():
    ref, zero = steps()
    seed1 = ph.closed_loop(
        STAGE, SMC(STAGE.params, model_terms="measured", **GAINS), ref, velocity=zero, acceleration=zero, rng=1
    )
    fixed = ph.closed_loop(
        STAGE, SMC(STAGE.params, model_terms="desired", **GAINS), ref, velocity=zero, acceleration=zero, rng=1
    )
    # after the step back down to 8 um: seed 1's form is still stuck at the top (-14.8 um
    # measured), the command pinned near 150 V; the desired form is back within 0.1 um
    assert abs(ref[-1] - seed1.position[-1]) > 10e-6
    assert np.all(seed1.command[-1000:] > 149.0)
    assert abs(ref[-1] - fixed.position[-1]) < 0.1e-6
    assert abs(ref[5999] - fixed.position[5999]) < 0.1e-6


def test_desired_model_terms_track_like_the_seed_form():
    _, ref = ph.triangle(5, 5e-6, 1.0, FS, offset=7e-6)
    rmse = {
        mt: ph.track(SMC(STAGE.params, model_terms=mt, **GAINS), ref, stage=STAGE, rng=1, skip=0.2).metrics["rmse"]
        for mt in ("measured", "desired")
    }
    assert rmse["desired"] < 1.2 * rmse["measured"]  # measured 0.032 vs 0.034 um
    with pytest.raises(ValueError, match="model_terms = 'both' must be 'measured' or 'desired'"):
        ph.track(SMC(STAGE.params, model_terms="both"), ref, stage=STAGE)


def test_the_default_does_not_feed_the_measured_position_back():
    """Issue 19: no default feeds an estimate back positively."""
    assert SMC(STAGE.params).model_terms == "desired"
    ref, zero = steps()
    r = ph.closed_loop(STAGE, SMC(STAGE.params, **GAINS), ref, velocity=zero, acceleration=zero, rng=1)
    assert abs(ref[-1] - r.position[-1]) < 0.1e-6
