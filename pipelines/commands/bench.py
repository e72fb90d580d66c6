"""beambench bench: speed against error, one module per target.

``pipelines.bench.sim``, ``pipelines.bench.vision``, ``pipelines.bench.daq``,
``pipelines.bench.process`` and ``pipelines.bench.campaign`` each provide
``run(quick: bool) -> int`` and print their table on stdout.
"""

from __future__ import annotations

import argparse
import importlib

TARGETS = ("sim", "vision", "daq", "process", "campaign")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("target", choices=TARGETS)
    p.add_argument("--quick", action="store_true", help="a short smoke run")


def run(args: argparse.Namespace) -> int:
    module = importlib.import_module(f"pipelines.bench.{args.target}")
    return int(module.run(quick=args.quick))
