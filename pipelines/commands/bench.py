"""beambench bench: speed against error."""

from __future__ import annotations

import argparse

from pipelines.commands._common import not_available

HELP = "print speed against error for the simulator, vision or acquisition"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("target", choices=("sim", "vision", "daq"))
    p.add_argument("--quick", action="store_true", help="a short smoke run")


def run(args: argparse.Namespace) -> int:
    issue = {"sim": 3, "vision": 5, "daq": 4}[args.target]
    return not_available(f"bench {args.target}", issue)
