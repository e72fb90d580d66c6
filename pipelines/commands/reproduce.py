"""beambench reproduce: the paper's comparisons, recomputed, as a report.

Writes ``report.md``, its PNG plots, ``numbers.csv`` (the paper's values beside
beambench's) and one CSV per table into ``--out`` (default ``reproduce-out``). The folder's
parent must exist; an existing report is replaced only by a complete new one.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

from pipelines.errors import BeambenchError


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--out",
        metavar="DIR",
        default="reproduce-out",
        help="output folder (created if missing; its parent must exist)",
    )


def check_out_dir(path: str) -> Path:
    """Refuse an output folder that cannot be written, before any work is done."""
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise BeambenchError(f"--out {out}: exists and is not a folder")
    parent = out.absolute().parent
    if not parent.is_dir():
        raise BeambenchError(f"--out {out}: parent folder {parent} does not exist")
    if not os.access(parent, os.W_OK) or (out.exists() and not os.access(out, os.W_OK)):
        raise BeambenchError(f"--out {out}: folder is not writable")
    return out


def run(args: argparse.Namespace) -> int:
    out = check_out_dir(args.out)
    from pipelines.reproduce.report import run_reproduce

    start = time.perf_counter()
    report = run_reproduce(out)
    print(f"reproduce finished in {time.perf_counter() - start:.1f} s; report: {report}")
    return 0
