"""beambench replay: stream a raw log to Rerun."""

from __future__ import annotations

import argparse

from pipelines.commands._common import not_available
from pipelines.commands._viewer_args import add_viewer_arguments

HELP = "stream a raw run log to Rerun without processing"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("log", metavar="RUN.mcap")
    p.add_argument("--speed", default="max", help="replay speed factor, or 'max'")
    add_viewer_arguments(p)


def run(args: argparse.Namespace) -> int:
    return not_available("replay", 6)
