"""``piezohyst stage info``: stroke, hysteresis, resonance and creep of a stage by simulation."""

from __future__ import annotations

import argparse
import json

from .common import _Parser


def _stage_parser(sub: argparse._SubParsersAction[_Parser]) -> None:
    st = sub.add_parser("stage", help="stage utilities")
    st_sub = st.add_subparsers(dest="stage_command", required=True)
    info = st_sub.add_parser("info", help="measure stroke, hysteresis, resonance and creep of a stage by simulation")
    info.add_argument("--stage", metavar="FILE", help="stage file (JSON; default: the built-in virtual stage)")
    info.add_argument("--json", action="store_true", help="print the numbers as JSON")


def _stage_info(args: argparse.Namespace) -> None:
    from ..plant.stage import Stage, virtual_stage

    stage = Stage.from_file(args.stage) if args.stage else virtual_stage()
    info = stage.info().to_dict()
    if args.json:
        print(json.dumps(info, indent=2))
        return
    name = stage.name or (args.stage or "virtual stage")
    print(f"{name}")
    print(f"  stroke (0..{info['full_range_V'][1]:g} V, 1 Hz)      {info['stroke_um']:8.2f} um")
    print(f"  hysteresis (1 Hz, full range)   {info['hysteresis_percent_1hz_full_range']:8.2f} % of output range")
    print(f"  first resonance (measured)      {info['first_resonance_hz']:8.0f} Hz")
    print(
        f"  mechanical natural frequency    {info['natural_frequency_hz']:8.0f} Hz "
        f"(damping ratio {info['damping_ratio']:.3f})"
    )
    print(f"  creep                           {info['creep_percent_per_decade']:8.2f} % per time decade (0.1..100 s)")
