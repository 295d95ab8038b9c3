"""``piezohyst bench``: every benchmark of the source tree's bench/ (:mod:`piezohyst.papers.benchmarks`)."""

from __future__ import annotations

import argparse
import sys

from .common import _Parser


def _bench_parser(sub: argparse._SubParsersAction[_Parser]) -> None:
    b = sub.add_parser(
        "bench",
        help="run every benchmark in the source tree's bench/ and write one JSON + a "
        "Markdown table, each figure beside its same-run baseline",
    )
    b.add_argument("--only", nargs="+", metavar="NAME", help="run only these benchmarks")
    b.add_argument("--skip", nargs="+", metavar="NAME", help="skip these benchmarks")
    b.add_argument(
        "--quick", action="store_true", help="minimal repetitions and budgets (a smoke run, not figures to quote)"
    )
    b.add_argument("--report-only", action="store_true", help="do not run; summarize the JSON already in the results")
    b.add_argument(
        "--results",
        metavar="DIR",
        help="where the benchmarks write their JSON and the summary (default: bench/results)",
    )
    b.add_argument(
        "--readme",
        metavar="FILE",
        help="replace the section between <!-- bench:begin --> and <!-- bench:end --> of FILE with the table",
    )
    b.add_argument("--bench-dir", metavar="DIR", help="the bench/ directory (default: the source tree's)")


def _bench(args: argparse.Namespace) -> int:
    from ..papers.benchmarks import main as bench_main

    failed = bench_main(args)["failed"]
    if failed:
        print(
            f"piezohyst bench: {len(failed)} benchmark(s) did not produce results: {', '.join(failed)}",
            file=sys.stderr,
        )
        return 1
    return 0
