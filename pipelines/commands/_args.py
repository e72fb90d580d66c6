"""Arguments shared by the subcommands: the rig file, the damping law and the Rerun
destination."""

from __future__ import annotations

import argparse

from pipelines.rig import Rig, load_rig
from sim.config import DAMPING_LAWS


def add_rig_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--rig",
        metavar="RIG.toml",
        default=None,
        help="rig configuration (default: the shipped paper bench)",
    )


def rig_from_args(args: argparse.Namespace) -> Rig:
    return load_rig(args.rig)


def add_damping_law_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--damping-law",
        choices=DAMPING_LAWS,
        default=None,
        help="the a1 damping term: paper (Eq. 28, tangent stiffness) or material "
        "(Kelvin-Voigt, strain rates); default: the rig's [damping] law",
    )


def damping_law_from_args(args: argparse.Namespace, rig: Rig) -> str:
    """``--damping-law`` if given, else the rig's ``[damping] law``."""
    law: str = rig.damping.law if args.damping_law is None else args.damping_law
    return law


def add_viewer_arguments(p: argparse.ArgumentParser, frame_reduction_default: int = 2) -> None:
    """``--rrd FILE`` | ``--spawn`` | ``--connect URL``: where a Rerun recording goes."""
    g = p.add_mutually_exclusive_group()
    g.add_argument("--rrd", metavar="FILE.rrd", help="save the Rerun recording to a file")
    g.add_argument("--spawn", action="store_true", help="open a Rerun viewer")
    g.add_argument("--connect", metavar="URL", help="stream to a running Rerun viewer")
    p.add_argument(
        "--frame-reduction",
        type=int,
        choices=(1, 2, 4),
        default=frame_reduction_default,
        metavar="N",
        help=f"camera frames in the recording at 1/N of their size (default "
        f"{frame_reduction_default}, so a run loads in seconds; 1 keeps them at full "
        "resolution as logged)",
    )
