"""Argument helpers shared by the subcommands."""

from __future__ import annotations

import argparse

from pipelines.rig import Rig, load_rig


def add_rig_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--rig",
        metavar="RIG.toml",
        default=None,
        help="rig configuration (default: the shipped paper bench)",
    )


def rig_from_args(args: argparse.Namespace) -> Rig:
    return load_rig(args.rig)
