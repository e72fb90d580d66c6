"""beambench sweep: simulator sweeps as Dask tasks, one per point, into one NetCDF file."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from pipelines.commands._args import (
    add_damping_law_argument,
    add_rig_argument,
    damping_law_from_args,
    rig_from_args,
)
from pipelines.errors import BeambenchError
from sim.models.registry import MODELS

HELP = "simulate the reciprocating bench over crank frequencies (and a1) on a Dask cluster"

# as campaign: some points failed (their error is in the file's `error` variable)
EXIT_SOME_FAILED = 1


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("scene", choices=("reciprocating",))
    p.add_argument(
        "--crank-hz", metavar="START:STOP:N", required=True, help="crank frequencies, Hz"
    )
    p.add_argument(
        "--a1", metavar="LIST", default=None, help="a1 values, s, comma separated (default: rig's)"
    )
    add_damping_law_argument(p)
    add_rig_argument(p)
    p.add_argument("--model", choices=MODELS, default="auto")
    p.add_argument(
        "--sim-tol",
        type=float,
        default=2e-2,
        metavar="REL",
        help="relative tip error --model auto aims at (default 0.02, as process)",
    )
    p.add_argument("--scheduler", metavar="ADDRESS", default=None)
    p.add_argument("--workers", type=int, default=None, metavar="N")
    p.add_argument("--out", metavar="FILE.nc", required=True)


def run(args: argparse.Namespace) -> int:
    from pipelines.campaign.cluster import open_client
    from pipelines.campaign.sweep import failed_points, parse_list, parse_range, run_sweep
    from pipelines.results.sim_dataset import check_output_path, write_dataset

    rig = rig_from_args(args)
    crank = [float(v) for v in parse_range(args.crank_hz)]
    a1 = [float(v) for v in parse_list(args.a1, "--a1")] if args.a1 else [rig.damping.a1_s]
    if not (0.0 < args.sim_tol < 0.5):
        raise BeambenchError(f"--sim-tol must be in (0, 0.5), got {args.sim_tol}")
    try:
        out = check_output_path(args.out)
    except ValueError as exc:
        raise BeambenchError(f"--out {exc}") from None
    with open_client(args.scheduler, args.workers) as client:
        ds = run_sweep(
            rig,
            crank,
            a1,
            client,
            damping_law=damping_law_from_args(args, rig),
            model=args.model,
            sim_tol=args.sim_tol,
            report=lambda s: print(s, flush=True),
        )
    write_dataset(ds, Path(out))
    failed = failed_points(ds)
    print(f"wrote {out} ({ds.sizes['crank_hz']} x {ds.sizes['a1']} points, {len(failed)} failed)")
    for line in failed:
        print(f"failed: {line}", file=sys.stderr)
    return EXIT_SOME_FAILED if failed else 0
