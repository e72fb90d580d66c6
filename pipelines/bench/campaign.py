"""``beambench bench campaign``: runs per minute through a campaign on 1 and 2 workers.

Four 20 s runs of the built-in synthetic bench (two of 5 s with ``--quick``) are
captured first (not timed), then processed as ``beambench campaign --workers N --force``
does, on a fresh embedded cluster for each N. Printed per N: the cluster's start-up, the
campaign's wall time, runs per minute and bench seconds processed per wall second, and
each worker's peak resident memory (``VmHWM`` of the worker processes: the Dask
worker itself plus the largest task it ran).
"""

from __future__ import annotations

import dataclasses
import os
import tempfile
import time
from pathlib import Path
from typing import Any


def run(quick: bool) -> int:
    from pipelines.campaign.cluster import open_client
    from pipelines.campaign.execute import run_campaign
    from pipelines.campaign.inputs import Options, plan_runs
    from pipelines.campaign.task import peak_rss_bytes
    from pipelines.demo import capture_synthetic
    from pipelines.rig import load_rig

    n_runs, duration_s = (2, 5.0) if quick else (4, 20.0)
    rig = load_rig()
    with tempfile.TemporaryDirectory(prefix="beambench-bench-campaign-") as tmp:
        root = Path(tmp)
        logs = []
        t0 = time.perf_counter()
        for k in range(n_runs):
            hz = 0.8 + 0.2 * k
            run_rig = dataclasses.replace(
                rig, linkage=dataclasses.replace(rig.linkage, crank_frequency_hz=hz)
            )
            path = root / f"run-{k}.mcap"
            capture_synthetic(run_rig, path, duration_s)
            logs.append(path)
        capture_s = time.perf_counter() - t0
        size_mb = sum(p.stat().st_size for p in logs) / 1e6
        print(
            f"campaign of {n_runs} synthetic runs of {duration_s:g} s (logs {size_mb:.0f} MB in "
            f"all; capture, not counted: {capture_s:.1f} s) on {os.cpu_count()} cores"
        )
        print(
            f"{'workers':>7s} | {'start s':>7s} | {'wall s':>7s} | {'runs/min':>8s} | "
            f"{'bench s/s':>9s} | worker peak RSS MB"
        )
        print("-" * 72)
        for n_workers in (1, 2):
            out = root / f"out-{n_workers}"
            out.mkdir()
            specs = plan_runs(logs, out, Options())
            t0 = time.perf_counter()
            with open_client(None, n_workers) as client:
                t1 = time.perf_counter()
                outcome = run_campaign(specs, out, client, force=True, report=lambda s: None)
                t2 = time.perf_counter()
                rss: dict[str, Any] = client.run(peak_rss_bytes)
            wall = t2 - t1
            if outcome.failed:
                print(f"failed runs: {outcome.failed}")
                return 1
            peaks = ", ".join(f"{v / 1e6:.0f}" for v in sorted(rss.values()))
            print(
                f"{n_workers:7d} | {t1 - t0:7.1f} | {wall:7.1f} | {n_runs * 60 / wall:8.2f} | "
                f"{n_runs * duration_s / wall:9.2f} | {peaks}"
            )
    return 0
