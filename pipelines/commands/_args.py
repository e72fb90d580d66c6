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


# --max-tip-uncertainty: people give mm; at most this (a frame this uncertain measures
# nothing: the bench's tip swings about 45 mm)
MAX_TIP_UNCERTAINTY_LIMIT_MM = 10.0
DEFAULT_MAX_TIP_UNCERTAINTY_MM = 0.5


def add_max_tip_uncertainty_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--max-tip-uncertainty",
        type=float,
        default=None,
        metavar="MM",
        help="refuse a frame whose stated tip lateral standard uncertainty exceeds this, in "
        f"mm (default {DEFAULT_MAX_TIP_UNCERTAINTY_MM:g} mm); below it a frame is measured "
        "with its uncertainty stated",
    )


def max_tip_uncertainty_m(args: argparse.Namespace) -> float | None:
    """``--max-tip-uncertainty`` in metres (None: not given), checked."""
    from pipelines.errors import BeambenchError

    mm = args.max_tip_uncertainty
    if mm is None:
        return None
    if not 0.0 < mm <= MAX_TIP_UNCERTAINTY_LIMIT_MM:
        raise BeambenchError(
            f"--max-tip-uncertainty must be a number of mm in (0, "
            f"{MAX_TIP_UNCERTAINTY_LIMIT_MM:g}], got {mm}"
        )
    return float(mm) * 1e-3
