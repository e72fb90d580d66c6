"""beambench recover: salvage a log whose writer was killed."""

from __future__ import annotations

import argparse

from pipelines.commands._common import not_available

HELP = "restore every flushed message of a broken log into a new file"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("log", metavar="BROKEN.mcap")
    p.add_argument("--out", metavar="FIXED.mcap", required=True)


def run(args: argparse.Namespace) -> int:
    return not_available("recover", 4)
