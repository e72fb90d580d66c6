"""The Rerun destination options shared by process and replay."""

from __future__ import annotations

import argparse


def add_viewer_arguments(p: argparse.ArgumentParser) -> None:
    g = p.add_mutually_exclusive_group()
    g.add_argument("--rrd", metavar="FILE.rrd", help="save the Rerun recording to a file")
    g.add_argument("--spawn", action="store_true", help="open a Rerun viewer")
    g.add_argument("--connect", metavar="URL", help="stream to a running Rerun viewer")
