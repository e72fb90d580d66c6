"""beambench campaign: many runs, one Dask task each, into one folder with a catalogue."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import Any

from pipelines.commands._args import (
    add_damping_law_argument,
    add_max_tip_uncertainty_argument,
    add_rig_argument,
    max_tip_uncertainty_m,
)
from pipelines.errors import BeambenchError
from sim.models.registry import MODELS

EXIT_SOME_FAILED = 1


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("logs", nargs="+", metavar="RUN.mcap|DIR", help="logs, or folders of logs")
    p.add_argument("--out", metavar="DIR", required=True, help="output folder (created)")
    p.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        default=None,
        help="a running Dask scheduler (tcp://host:8786; start it with `dask scheduler` and "
        "workers with `dask worker tcp://host:8786`); default: an embedded cluster",
    )
    p.add_argument(
        "--workers",
        type=int,
        default=None,
        metavar="N",
        help="worker processes of the embedded cluster (default: one per core)",
    )
    p.add_argument("--force", action="store_true", help="redo runs that are already done")
    p.add_argument(
        "--sweep",
        metavar="FILE.nc",
        default=None,
        help="a `beambench sweep` whose curve the report draws over the runs",
    )
    p.add_argument(
        "--rrd",
        metavar="FILE.rrd",
        default=None,
        help="also record the campaign for Rerun (`beambench view FILE.rrd`): one entity per "
        "run and the frequency response, measured against simulated, the --sweep's curve",
    )
    add_rig_argument(p)
    p.add_argument("--calibration", metavar="CAL.json", default=None)
    p.add_argument("--model", choices=MODELS, default="auto")
    p.add_argument("--sim-tol", type=float, default=None, metavar="REL")
    add_damping_law_argument(p)
    add_max_tip_uncertainty_argument(p)
    p.add_argument(
        "--fit-damping",
        action="store_true",
        help="fit each run's damping (process --fit-damping); the catalogue and the report "
        "carry the fitted a1 with its interval",
    )


def run(args: argparse.Namespace) -> int:
    from pipelines.campaign.cluster import open_client
    from pipelines.campaign.execute import run_campaign
    from pipelines.campaign.inputs import Options, find_logs, plan_runs, sha256_file
    from pipelines.rig import load_rig

    logs = find_logs(args.logs)
    rrd = _check_rrd(args.rrd, logs, args.sweep) if args.rrd else None
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise BeambenchError(f"--out {out}: exists and is not a folder")
    if args.sim_tol is not None and not (0.0 < args.sim_tol < 0.5):
        raise BeambenchError(f"--sim-tol must be in (0, 0.5), got {args.sim_tol}")
    if args.rig:
        load_rig(args.rig)  # a bad rig file is one error now, not one per run
    if args.calibration and not Path(args.calibration).is_file():
        raise BeambenchError(f"--calibration {args.calibration}: no such file")
    options = Options(
        model=args.model,
        sim_tol=args.sim_tol,
        damping_law=args.damping_law,
        fit_damping=args.fit_damping,
        rig_path=str(Path(args.rig).resolve()) if args.rig else None,
        calibration_path=str(Path(args.calibration).resolve()) if args.calibration else None,
        rig_sha256=sha256_file(args.rig) if args.rig else "",
        calibration_sha256=sha256_file(args.calibration) if args.calibration else "",
        max_tip_uncertainty_m=max_tip_uncertainty_m(args),
    )
    out.mkdir(parents=True, exist_ok=True)
    if not os.access(out, os.W_OK):
        raise BeambenchError(f"--out {out}: folder is not writable")
    specs = plan_runs(logs, out, options)
    sweep = _read_sweep(args.sweep) if args.sweep else None
    with open_client(args.scheduler, args.workers) as client:
        n_workers = len(client.scheduler_info(n_workers=-1).get("workers", {}))
        where = args.scheduler or "an embedded cluster"
        print(f"campaign: {len(specs)} runs on {where} ({n_workers} workers)", flush=True)
        outcome = run_campaign(
            specs, out, client, force=args.force, report=lambda s: print(s, flush=True)
        )
    from pipelines.campaign.catalogue import read_catalogue
    from pipelines.campaign.report import write_campaign_report

    catalogue = read_catalogue(outcome.catalogue_path)
    report = write_campaign_report(catalogue, out, sweep=sweep)
    if rrd is not None:
        from pipelines.review.campaign_view import write_campaign_rrd

        print(f"recording {write_campaign_rrd(catalogue, rrd, sweep=sweep)}")
    print(
        f"{len(outcome.processed)} processed, {len(outcome.skipped)} skipped, "
        f"{len(outcome.failed)} failed (of the processed, {len(outcome.flagged)} flagged); "
        f"catalogue {outcome.catalogue_path}, report {report}"
    )
    for label, names in (("flagged", outcome.flagged), ("failed", outcome.failed)):
        for name in names:
            err = str(outcome.rows[name]["error"]).splitlines()[0]
            print(f"{label}: {name}: {err}", file=sys.stderr)
    return EXIT_SOME_FAILED if outcome.failed or outcome.flagged else 0


def _check_rrd(path: str, logs: list[Path], sweep: str | None) -> Path:
    from pipelines.paths import refuse_aliases

    rrd = Path(path)
    if rrd.suffix.lower() != ".rrd":
        raise BeambenchError(f"--rrd {rrd}: the recording file must end in .rrd")
    if not rrd.parent.is_dir():
        raise BeambenchError(f"--rrd {rrd}: folder {rrd.parent} does not exist")
    inputs: dict[str, str | Path | None] = {f"log {p.name}": p for p in logs}
    inputs["--sweep"] = sweep
    refuse_aliases({"--rrd": rrd}, inputs)
    return rrd


def _read_sweep(path: str) -> Any:
    import xarray as xr

    try:
        with xr.open_dataset(path, engine="h5netcdf") as opened:
            ds = opened.load()
    except (OSError, ValueError) as exc:
        raise BeambenchError(f"--sweep {path}: cannot read ({exc})") from None
    if "tip_lateral_amplitude_m" not in ds or "crank_hz" not in ds.dims:
        raise BeambenchError(f"--sweep {path}: not a beambench sweep file")
    return ds
