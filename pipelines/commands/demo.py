"""beambench demo: the synthetic bench end to end.

Captures 20 s from the built-in synthetic bench (fake DAQ and camera fed by the
simulator and the scene renderer), processes the log, streams it to a Rerun recording
and writes a short report. Everything lands in ``--out``.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

from pipelines.commands._args import add_rig_argument, rig_from_args
from pipelines.errors import BeambenchError
from pipelines.paths import refuse_inputs_among

DEMO_DURATION_S = 20.0


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", metavar="DIR", default="demo-out", help="output folder")
    p.add_argument(
        "--duration", metavar="S", type=float, default=None, help="seconds to capture (20)"
    )
    add_rig_argument(p)
    p.add_argument(
        "--campaign",
        action="store_true",
        help="a synthetic campaign instead: short runs at several crank frequencies "
        "processed on an embedded Dask cluster, a simulator sweep and a campaign report "
        "(--duration then is per run, default 8 s)",
    )


def run(args: argparse.Namespace) -> int:
    from pipelines.demo import OUTPUT_NAMES, run_demo

    out = Path(args.out)
    refuse_inputs_among(out, OUTPUT_NAMES, {"--rig": args.rig})
    rig = rig_from_args(args)
    if out.exists() and not out.is_dir():
        raise BeambenchError(f"--out {out}: exists and is not a folder")
    if args.duration is None:
        args.duration = 8.0 if args.campaign else DEMO_DURATION_S
    if not args.duration > 0:
        raise BeambenchError(f"--duration must be positive, got {args.duration}")
    out.mkdir(parents=True, exist_ok=True)
    if not os.access(out, os.W_OK):
        raise BeambenchError(f"--out {out}: folder is not writable")
    t0 = time.perf_counter()
    if args.campaign:
        from pipelines.campaign.synthetic import run_campaign_demo

        paths = run_campaign_demo(rig, out, duration_s=args.duration)
    else:
        paths = run_demo(rig, out, duration_s=args.duration)
    print(f"demo finished in {time.perf_counter() - t0:.1f} s; outputs in {out}/:")
    for label, path in paths.items():
        print(f"  {label:<10} {path}")
    return 0
