"""beambench info: what a run log holds."""

from __future__ import annotations

import argparse

from pipelines.commands._common import not_available

HELP = "channels, counts, rates, gaps and duration of a run log"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("log", metavar="RUN.mcap")


def run(args: argparse.Namespace) -> int:
    return not_available("info", 4)
