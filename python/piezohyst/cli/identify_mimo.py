"""``piezohyst identify`` on multi-channel data: a folder of ``u_*.npy`` / ``y_*.npy`` periodic
multisine records (the nonlinear-benchmark layout) → a MIMO model file
(:mod:`piezohyst.identify.mimo`). :func:`_identify` dispatches here when DATA is such data or
``--model`` names a MIMO kind."""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import PiezohystError
from ..identify.mimo import MIMO_KINDS, MimoRecords, identify_mimo, protocol_rmse, set_means
from ..outputs import write_atomic
from .common import _check_fs, _Fail, _writable


def _is_multichannel(data: str) -> bool:
    """Whether DATA is multi-channel records: a folder holding ``u_*.npy`` / ``y_*.npy`` files,
    one such file, or an NPZ whose ``u`` has a channel axis (:func:`piezohyst.signals.is_multichannel`)."""
    from ..signals.multichannel import is_multichannel

    return is_multichannel(data)


def _records(data: str, fs: float) -> MimoRecords:
    """The records of DATA, read and checked by :func:`piezohyst.signals.load_multichannel` (a u
    without its y, shapes, NaN, mixed lengths: one line naming the file), one set per record
    (``100mV_train`` -> ``100mV``)."""
    from ..signals.multichannel import load_multichannel

    try:
        recs = load_multichannel(data, fs=fs)
        return MimoRecords.from_sets([(re.sub(r"_?train$", "", r.name) or r.name, r.u, r.y) for r in recs], fs)
    except (PiezohystError, FileNotFoundError) as e:
        raise _Fail(f"DATA = {e}") from None


def _identify_mimo(args: argparse.Namespace) -> int:
    kind = args.model
    if kind != "auto" and kind not in MIMO_KINDS:
        raise _Fail(f"--model = {kind!r} does not fit multi-channel DATA; give auto or one of {list(MIMO_KINDS)}")
    fs = _check_fs(args.fs)
    if fs is None:
        raise _Fail("the sample rate is unknown: give --fs HZ")
    if not Path(args.data).exists():
        raise _Fail(f"DATA = '{args.data}' does not exist")
    out = _writable(args.out, "--out", args.force, {})
    rec = _records(args.data, fs)
    log = None if (args.json or getattr(args, "quiet", False)) else (lambda s: print(f"  {s}", file=sys.stderr))
    try:
        res = identify_mimo(rec, kind, log=log)
    except PiezohystError as e:
        raise _Fail(str(e)) from None
    train_rmse = set_means(protocol_rmse(res.model, rec.u, rec.y), rec.labels)
    rms_y = float(np.sqrt((rec.y**2).mean()))
    fit: dict[str, Any] = dict(res.report())
    fit["data"] = {
        "train": {
            "source": str(args.data),
            "samples": int(rec.u.shape[0] * rec.u.shape[2] * rec.u.shape[3]),
            "realizations": len(rec.labels),
            "periods": int(rec.u.shape[3]),
            "sets": sorted(set(rec.labels)),
        },
        "validation": None,
        "fs": fs,
    }
    fit["train"] = {"rmse": train_rmse, "rmse_percent": 100 * float(np.mean(list(train_rmse.values()))) / rms_y}
    if res.holdout:
        best = min(res.holdout.values(), key=lambda h: float(np.mean(list(h.values()))))
        fit["validation"] = {
            "rmse": best,
            "rmse_percent": 100 * float(np.mean(list(best.values()))) / rms_y,
            "protocol": "held-back realizations, init from the first 100 outputs, RMSE from sample 100",
            # the saved model is refitted on every record and then refined by output error: this
            # figure is the chosen kind's, fitted without the fold, before that refinement
            "model": "the chosen kind fitted without the held-back fold, before the output-error refinement",
        }
        fit["data"]["validation"] = {"source": "held-back realizations of DATA", "samples": int(rec.u.shape[0])}
    model = res.model.with_fit(fit)
    write_atomic(out, model.to_json(), overwrite=args.force, name="--out")
    if args.json:
        print(json.dumps({"out": str(out), "model": res.kind, "file_kind": "mimo", **fit}, indent=2))
    else:
        print(f"{res.kind} identified in {res.seconds:.3g} s -> {out} ({model.nx} states, {model.nw} feedback)")
        for lab, v in train_rmse.items():
            print(f"  train {lab}: RMSE {v:.4g} ({res.model.output_unit})")
        for key, h in res.holdout.items():
            print(f"  held out {key} (before refinement): " + ", ".join(f"{k} {v:.4g}" for k, v in h.items()))
        oe = res.model.fit.get("output_error")
        if oe:
            watched, joined = oe.get("watched_iterations", 0), oe.get("all_records_iterations", 0)
            how = f", {watched} watched on held-back realizations" if watched else ""
            how += f", {joined} on all realizations" if joined and watched else ""
            print(
                f"  output-error refinement: {oe['iterations']} iterations in {oe['seconds']} s{how} ({oe['stopped']})"
            )
    return 0
