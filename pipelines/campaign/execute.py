"""Running a campaign: skip what is already done, submit the rest as one Dask task per
run, record each run in the catalogue as it finishes.

A run is skipped when the catalogue holds it as ``ok`` with the same input key (log size
and mtime, options, rig and calibration contents, software version) and its results
file exists; ``force`` redoes it. A run that fails, or whose worker is lost more often
than the scheduler allows (``distributed.scheduler.allowed-failures``; a task on a worker
that dies is first moved to another), is recorded with its error and the others carry on.
A scheduler lost mid-way (:class:`~pipelines.campaign.cluster.SchedulerLost`) ends the
campaign with one error; what finished before is in the catalogue, so a rerun does the rest.
"""

from __future__ import annotations

import datetime as dt
import math
import uuid
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import dask

from pipelines import __version__
from pipelines.campaign.catalogue import (
    CATALOGUE_NAME,
    read_catalogue,
    rows_of,
    to_dataset,
    write_catalogue,
)
from pipelines.campaign.inputs import RunSpec
from pipelines.campaign.task import failed_row, process_task
from pipelines.errors import BeambenchError


@dataclass
class CampaignOutcome:
    catalogue_path: Path
    processed: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    failed: list[str] = field(default_factory=list)
    #: processed (and in ``processed``) but flagged: a result is missing or may be wrong
    flagged: list[str] = field(default_factory=list)
    rows: dict[str, dict[str, Any]] = field(default_factory=dict)


def load_rows(path: Path, force: bool) -> dict[str, dict[str, Any]]:
    """The rows of an existing catalogue (none if absent). A file there that is not a
    catalogue is refused unless ``force`` (then it is replaced)."""
    if not path.exists():
        return {}
    try:
        return rows_of(read_catalogue(path))
    except ValueError as exc:
        if force:
            return {}
        raise BeambenchError(f"{exc}; move it away or pass --force") from None


def is_done(spec: RunSpec, row: dict[str, Any] | None) -> bool:
    return (
        row is not None
        and row.get("status") == "ok"
        and row.get("input_key") == spec.input_key()
        and Path(spec.results_path).is_file()
    )


def describe(row: dict[str, Any]) -> str:
    """One line for a finished run."""
    first = str(row["error"]).splitlines()[0] if row["error"] else "unknown error"
    if row["status"] == "failed":
        return f"{row['run']}: FAILED: {first}"
    mm = 1e3
    f = row["crank_frequency_hz"]
    parts = [f"crank {f:.4f} Hz" if math.isfinite(f) else "crank frequency not found"]
    for src in ("image", "strain", "sim"):
        a = row[f"tip_lateral_{src}_amplitude_m"]
        parts.append(f"tip {src} {a * mm:.2f} mm")
    where = f" ({row['process_wall_time_s']:.1f} s on {row['worker']})"
    if row["status"] == "flagged":
        return f"{row['run']}: FLAGGED: {first}; " + ", ".join(parts) + where
    return f"{row['run']}: ok, " + ", ".join(parts) + where


def run_campaign(
    specs: Sequence[RunSpec],
    out_dir: Path,
    client: Any,
    *,
    force: bool = False,
    report: Callable[[str], None] = print,
    attrs: dict[str, Any] | None = None,
) -> CampaignOutcome:
    """Process ``specs`` on ``client``; the catalogue is ``out_dir/campaign.nc``."""
    path = out_dir / CATALOGUE_NAME
    rows = load_rows(path, force)
    outcome = CampaignOutcome(path, rows=rows)
    todo = []
    for spec in specs:
        if not force and is_done(spec, rows.get(spec.name)):
            outcome.skipped.append(spec.name)
        else:
            todo.append(spec)
    cat_attrs = {
        "title": "beambench campaign catalogue",
        "software_version": __version__,
        **(attrs or {}),
    }

    def save() -> None:
        cat_attrs["updated_utc"] = dt.datetime.now(dt.UTC).isoformat(timespec="seconds")
        # With the client current, xarray would write under a distributed lock held by the
        # scheduler: one round trip per write, and no catalogue at all once the scheduler
        # is gone (the very moment the finished runs must be kept). The file is written
        # here, by this process alone.
        with dask.config.set(scheduler="synchronous"):
            write_catalogue(to_dataset(outcome.rows.values(), cat_attrs), path)

    if outcome.skipped:
        report(
            f"{len(outcome.skipped)} of {len(specs)} runs already done (skipped; --force redoes)"
        )
    if not todo:
        save()
        return outcome
    with client.as_current():
        _gather(todo, client, outcome, save, report)
    return outcome


def _gather(
    todo: Sequence[RunSpec],
    client: Any,
    outcome: CampaignOutcome,
    save: Callable[[], None],
    report: Callable[[str], None],
) -> None:
    from pipelines.campaign.cluster import SchedulerLost, completed, outcome_of

    futures = {
        client.submit(process_task, spec, key=f"campaign-run-{spec.name}-{uuid.uuid4().hex}"): spec
        for spec in todo
    }
    try:
        for k, future in enumerate(completed(client, futures), start=1):
            spec = futures[future]
            result, exc = outcome_of(client, future)
            row = result if exc is None else failed_row(spec, f"{type(exc).__name__}: {exc}")
            future.release()
            outcome.rows[spec.name] = row
            (outcome.failed if row["status"] == "failed" else outcome.processed).append(spec.name)
            if row["status"] == "flagged":
                outcome.flagged.append(spec.name)
            save()
            report(f"[{k}/{len(todo)}] {describe(row)}")
    except SchedulerLost as exc:
        # every finished run is in the catalogue already (saved as it came in)
        raise SchedulerLost(
            f"{exc} after {len(outcome.processed) + len(outcome.failed)} of {len(todo)} runs; "
            f"those are kept in {outcome.catalogue_path}, a rerun does the rest"
        ) from None
