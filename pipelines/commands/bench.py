"""beambench bench: speed against error, one module per target.

``pipelines.bench_sim``, ``pipelines.bench_vision``, ``pipelines.bench_daq`` and
``pipelines.bench_process`` each provide ``run(quick: bool) -> int`` and print their
table on stdout.
"""

from __future__ import annotations

import argparse
import importlib

from pipelines.commands._common import not_available

HELP = "print speed against error for the simulator, vision, acquisition or processing"

ISSUES = {"sim": 3, "vision": 5, "daq": 4, "process": 6}


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("target", choices=tuple(ISSUES))
    p.add_argument("--quick", action="store_true", help="a short smoke run")


def run(args: argparse.Namespace) -> int:
    try:
        module = importlib.import_module(f"pipelines.bench_{args.target}")
    except ModuleNotFoundError as exc:
        if exc.name != f"pipelines.bench_{args.target}":
            raise
        return not_available(f"bench {args.target}", ISSUES[args.target])
    return int(module.run(quick=args.quick))
