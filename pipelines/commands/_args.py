"""Arguments shared by the subcommands: the rig file and the Rerun destination."""

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


def add_viewer_arguments(p: argparse.ArgumentParser) -> None:
    """``--rrd FILE`` | ``--spawn`` | ``--connect URL``: where a Rerun recording goes."""
    g = p.add_mutually_exclusive_group()
    g.add_argument("--rrd", metavar="FILE.rrd", help="save the Rerun recording to a file")
    g.add_argument("--spawn", action="store_true", help="open a Rerun viewer")
    g.add_argument("--connect", metavar="URL", help="stream to a running Rerun viewer")
    p.add_argument(
        "--frame-reduction",
        type=int,
        choices=(1, 2, 4),
        default=2,
        metavar="N",
        help="camera frames in the recording at 1/N of their size (default 2, so a run loads "
        "in seconds; 1 keeps them at full resolution as logged)",
    )
