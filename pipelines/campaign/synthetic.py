"""``beambench demo --campaign``: a synthetic campaign with nothing started by hand.

Records a handful of short runs on the built-in synthetic bench at different crank
frequencies (the rig's ``linkage.crank_frequency_hz`` set per run), processes them on an
embedded Dask cluster, sweeps the simulator over the same range, and writes the campaign
report.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from pipelines.campaign.catalogue import CATALOGUE_NAME, read_catalogue
from pipelines.campaign.cluster import open_client
from pipelines.campaign.execute import run_campaign
from pipelines.campaign.inputs import Options, plan_runs
from pipelines.campaign.report import write_campaign_report
from pipelines.campaign.sweep import run_sweep
from pipelines.demo import capture_synthetic
from pipelines.process.run import SIM_TOL
from pipelines.rig import Rig

DEMO_CRANK_HZ = (0.7, 0.92, 1.2, 1.5)
DEMO_RUN_S = 8.0
SWEEP_POINTS = 9


def run_campaign_demo(
    rig: Rig,
    out: Path,
    *,
    crank_hz: Sequence[float] = DEMO_CRANK_HZ,
    duration_s: float = DEMO_RUN_S,
    workers: int | None = None,
    report: Callable[[str], None] = print,
) -> dict[str, Path]:
    """Record, process, sweep and report; return the outputs by label."""
    logs_dir = out / "logs"
    logs_dir.mkdir(parents=True, exist_ok=True)
    logs = []
    for hz in crank_hz:
        path = logs_dir / f"crank-{hz:.3f}hz.mcap"
        if not path.exists():  # a rerun reuses the recordings (and the campaign skips)
            run_rig = dataclasses.replace(
                rig, linkage=dataclasses.replace(rig.linkage, crank_frequency_hz=float(hz))
            )
            capture_synthetic(run_rig, path, duration_s)
            report(f"recorded {path.name} ({duration_s:g} s at {hz:g} Hz)")
        logs.append(path)
    results = out / "results"
    results.mkdir(exist_ok=True)
    specs = plan_runs(logs, results, Options())
    with open_client(None, workers) as client:
        outcome = run_campaign(specs, results, client, report=report)
        f = np.linspace(min(crank_hz), max(crank_hz), SWEEP_POINTS)
        sweep = run_sweep(
            rig,
            [float(v) for v in f],
            [rig.damping.a1_s],
            client,
            damping_law=rig.damping.law,
            model="auto",
            sim_tol=SIM_TOL,
            report=report,
        )
    sweep_path = out / "sweep.nc"
    from pipelines.results.sim_dataset import write_dataset

    write_dataset(sweep, sweep_path)
    catalogue = read_catalogue(results / CATALOGUE_NAME)
    md = write_campaign_report(
        catalogue,
        out,
        sweep=sweep,
        title=f"beambench demo campaign: {len(logs)} synthetic runs of {duration_s:g} s",
    )
    if outcome.flagged:
        report(f"{len(outcome.flagged)} runs flagged: {', '.join(outcome.flagged)}")
    if outcome.failed:
        report(f"{len(outcome.failed)} runs failed: {', '.join(outcome.failed)}")
    return {
        "logs": logs_dir,
        "catalogue": results / CATALOGUE_NAME,
        "sweep": sweep_path,
        "report": md,
    }
