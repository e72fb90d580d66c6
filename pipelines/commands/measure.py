"""beambench measure: hub angle and tip deflection from photographs."""

from __future__ import annotations

import argparse

from pipelines.commands._common import not_available

HELP = "measure hub angle and tip deflection in still images"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("images", metavar="IMAGE", nargs="+")
    p.add_argument("--calibration", metavar="CAL.json", required=True)
    p.add_argument("--json", action="store_true", help="one JSON object per image")


def run(args: argparse.Namespace) -> int:
    return not_available("measure", 5)
