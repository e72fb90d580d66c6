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
from pipelines.commands.sim import MAX_DAMPING, MAX_DURATION_S, SOLVE_S_PER_S, human_s
from pipelines.errors import BeambenchError
from sim.models.registry import MODELS

# as campaign: some points failed (their error is in the file's `error` variable)
EXIT_SOME_FAILED = 1

# Work is bounded before a cluster starts, as `sim` bounds a run (the error names the
# cost): each point at most `sim`'s MAX_DURATION_S of simulated time, and the sweep at most
# this much in all: about an hour of solving on one core with the FE beam that auto picks
# at its slowest (`sim`'s SOLVE_S_PER_S), e.g. 2,000 points of 12 s.
MAX_SWEEP_SIMULATED_S = 20 * MAX_DURATION_S


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("scene", choices=("reciprocating",))
    p.add_argument(
        "--crank-hz",
        metavar="START:STOP:N",
        required=True,
        help="crank frequencies, Hz (a point simulates 3 s and 4 crank periods: at most "
        f"{MAX_DURATION_S:g} s a point, {MAX_SWEEP_SIMULATED_S:g} s a sweep)",
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
    check_sweep_cost(crank, a1, args.model)
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


def check_sweep_cost(crank_hz: list[float], a1_s: list[float], model: str) -> None:
    """Refuse a sweep beyond the limits (one error naming the value, its cost and the
    limit): a crank frequency so low that one point simulates hours, a1 beyond what the
    rig accepts, or more points than an hour of solving."""
    from pipelines.campaign.sweep import PERIODS, SETTLE_S, point_duration_s

    rate = SOLVE_S_PER_S.get(model, SOLVE_S_PER_S["fe"])
    slowest = min(crank_hz)
    point_s = point_duration_s(slowest)
    if point_s > MAX_DURATION_S:
        lowest = PERIODS / (MAX_DURATION_S - SETTLE_S)
        raise BeambenchError(
            f"--crank-hz {slowest:g} Hz: one point would simulate {human_s(point_s)} "
            f"({SETTLE_S:g} s to settle and {PERIODS} crank periods), about "
            f"{human_s(point_s * rate)} of solving with --model {model}; at most "
            f"{MAX_DURATION_S:g} s a point, i.e. crank frequencies from {lowest:.3g} Hz"
        )
    if max(a1_s) > MAX_DAMPING[1]:
        raise BeambenchError(
            f"--a1 {max(a1_s):g} s: at most {MAX_DAMPING[1]:g} s (the rig's limit)"
        )
    total_s = sum(point_duration_s(f) for f in crank_hz) * len(a1_s)
    if total_s > MAX_SWEEP_SIMULATED_S:
        n = len(crank_hz) * len(a1_s)
        raise BeambenchError(
            f"--crank-hz and --a1: {n} points would simulate {human_s(total_s)} in all, "
            f"about {human_s(total_s * rate)} of solving with --model {model}; at most "
            f"{human_s(MAX_SWEEP_SIMULATED_S)} of simulated time a sweep (fewer points, "
            "or several sweeps)"
        )
