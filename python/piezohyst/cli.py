"""The ``piezohyst`` command line."""
from __future__ import annotations

import argparse
import json
import sys

__all__ = ["main"]


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="piezohyst", description="Piezo hysteresis modelling, identification and compensation.")
    p.add_argument("--debug", action="store_true", help="show a traceback on errors")
    sub = p.add_subparsers(dest="command", required=True)
    d = sub.add_parser("demo", help="forward and exact inverse of the seed-2 MPI model; writes a loop figure")
    d.add_argument("--out", default="piezohyst-report", help="output directory (default: ./piezohyst-report)")
    d.add_argument("--force", action="store_true", help="overwrite existing output files")
    d.add_argument("--json", action="store_true", help="print the numbers as JSON")
    st = sub.add_parser("stage", help="stage utilities")
    st_sub = st.add_subparsers(dest="stage_command", required=True)
    info = st_sub.add_parser("info", help="measure stroke, hysteresis, resonance and creep of a stage by simulation")
    info.add_argument("--stage", metavar="FILE", help="stage file (JSON; default: the built-in virtual stage)")
    info.add_argument("--json", action="store_true", help="print the numbers as JSON")
    return p


def _stage_info(args) -> None:
    from .stage import Stage, virtual_stage

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
    print(f"  mechanical natural frequency    {info['natural_frequency_hz']:8.0f} Hz (damping ratio {info['damping_ratio']:.3f})")
    print(f"  creep                           {info['creep_percent_per_decade']:8.2f} % per time decade (0.1..100 s)")


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    try:
        if args.command == "stage":
            _stage_info(args)
        elif args.command == "demo":
            from .demo import run_demo

            quiet = (lambda *a, **k: None) if args.json else print
            numbers = run_demo(args.out, force=args.force, print_fn=quiet)
            if args.json:
                print(json.dumps(numbers, indent=2))
        return 0
    except (ValueError, TypeError, OSError) as e:
        if args.debug:
            raise
        print(f"piezohyst: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
