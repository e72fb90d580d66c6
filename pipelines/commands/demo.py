"""beambench demo: the synthetic bench end to end."""

from __future__ import annotations

import argparse

from pipelines.commands._common import add_rig_argument, not_available, rig_from_args

HELP = "synthetic bench end to end: capture, process, report"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", metavar="DIR", default="demo-out", help="output folder")
    add_rig_argument(p)


def run(args: argparse.Namespace) -> int:
    rig_from_args(args)
    return not_available("demo", 6)
