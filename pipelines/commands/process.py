"""beambench process: a run log to a results file (and Rerun)."""

from __future__ import annotations

import argparse

from pipelines.commands._common import add_rig_argument, not_available
from pipelines.commands._viewer_args import add_viewer_arguments

HELP = "measure frames, reconstruct, simulate and compare a run; write RESULTS.nc"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("log", metavar="RUN.mcap")
    p.add_argument("--out", metavar="RESULTS.nc", required=True)
    add_rig_argument(p)
    p.add_argument("--calibration", metavar="CAL.json", default=None)
    add_viewer_arguments(p)


def run(args: argparse.Namespace) -> int:
    return not_available("process", 6)
