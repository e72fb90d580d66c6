"""beambench capture: record a run to an MCAP log."""

from __future__ import annotations

import argparse

from pipelines.commands._common import add_rig_argument, not_available, rig_from_args

HELP = "record a run (DAQ + camera) to a synchronized MCAP log"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--duration", metavar="S", type=float, required=True, help="seconds")
    p.add_argument("--out", metavar="RUN.mcap", required=True, help="log file to write")
    add_rig_argument(p)
    p.add_argument("--backend", choices=("fake", "hardware"), default="fake")
    p.add_argument("--realtime", action="store_true", help="pace the fake like the hardware")


def run(args: argparse.Namespace) -> int:
    rig_from_args(args)
    return not_available("capture", 4)
