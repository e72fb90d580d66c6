"""beambench reproduce: the paper's comparisons as a report."""

from __future__ import annotations

import argparse

from pipelines.commands._common import not_available

HELP = "reproduce the paper's comparisons as a report"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", metavar="DIR", default="reproduce-out")


def run(args: argparse.Namespace) -> int:
    return not_available("reproduce", 7)
