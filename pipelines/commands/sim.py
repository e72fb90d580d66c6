"""beambench sim: simulate one scene."""

from __future__ import annotations

import argparse

from pipelines.commands._common import add_rig_argument, not_available, rig_from_args

HELP = "simulate a scene (reciprocating, static, free-decay, spin-up, falling-body, modes, linkage)"

SCENES = ("reciprocating", "static", "free-decay", "spin-up", "falling-body", "modes", "linkage")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("scene", choices=SCENES)
    add_rig_argument(p)
    p.add_argument("--model", choices=("auto", "rigid", "modal", "fe"), default="auto")
    p.add_argument("--out", metavar="FILE.nc", default=None)


def run(args: argparse.Namespace) -> int:
    rig_from_args(args)
    return not_available("sim", 3)
