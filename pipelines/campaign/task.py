"""One run of a campaign as one Dask task: the per-run pipeline of ``beambench process``
(frames measured in the task's own process, one at a time, so a worker never starts a
pool of its own), the results file, and the run's catalogue row.

A run that fails on its input (a truncated log, no registration object, ...) returns a
row with its error instead of raising: the campaign records it and carries on. What
raises is a bug or a lost worker, which the client records the same way.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import logging
import time
from pathlib import Path
from typing import Any

import dask

from daq.errors import DaqError
from pipelines import __version__
from pipelines.campaign.catalogue import empty_row
from pipelines.campaign.inputs import RunSpec, sha256_file
from pipelines.campaign.summary import summarise_run
from pipelines.errors import BeambenchError
from sim.errors import SimError
from vision.errors import VisionError

KNOWN_ERRORS = (BeambenchError, SimError, VisionError, DaqError)


class _Collect(logging.Handler):
    def __init__(self) -> None:
        super().__init__(level=logging.WARNING)
        self.lines: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.lines.append(f"{record.name}: {record.getMessage()}")


def base_row(spec: RunSpec) -> dict[str, Any]:
    row = empty_row(spec.name)
    row.update(
        source_log=spec.log_path,
        software_version=__version__,
        input_key=spec.input_key(),
        log_size_bytes=float(spec.log_size_bytes),
        log_mtime_ns=spec.log_mtime_ns,
    )
    return row


def failed_row(spec: RunSpec, error: str) -> dict[str, Any]:
    row = base_row(spec)
    row.update(status="failed", error=error)
    return row


def process_task(spec: RunSpec) -> dict[str, Any]:
    """Process ``spec``'s log, write its results file, return its catalogue row."""
    from pipelines.blas_threads import limit_blas_threads
    from pipelines.process.run import MAX_TIP_UNCERTAINTY_M, process_run, write_processed
    from pipelines.rig import load_rig

    limit_blas_threads()
    t0 = time.perf_counter()
    opts = spec.options
    collect = _Collect()
    root = logging.getLogger()
    root.addHandler(collect)
    # No progress bar inside a task: a worker's stderr may be the campaign's terminal.
    try:
        # Inside a Dask worker xarray would write NetCDF under a distributed lock named after
        # the file (here an in-memory buffer, which no scheduler knows): the run is one task
        # and computes locally, so Dask's scheduler inside it is the synchronous one.
        with contextlib.redirect_stderr(io.StringIO()), dask.config.set(scheduler="synchronous"):
            rig = load_rig(opts.rig_path) if opts.rig_path else None
            processed = process_run(
                Path(spec.log_path),
                rig=rig,
                calibration_path=Path(opts.calibration_path) if opts.calibration_path else None,
                model=opts.model,
                sim_tol=opts.sim_tol,
                workers=1,
                damping_law=opts.damping_law,
                max_tip_uncertainty_m=MAX_TIP_UNCERTAINTY_M
                if opts.max_tip_uncertainty_m is None
                else opts.max_tip_uncertainty_m,
                fit_damping=opts.fit_damping,
            )
            write_processed(processed, Path(spec.results_path))
    except KNOWN_ERRORS as exc:
        return failed_row(spec, str(exc))
    finally:
        root.removeHandler(collect)
    ds = processed.results
    row = base_row(spec)
    row.update(summarise_run(ds))
    flag = flag_reason(processed, spec)
    row.update(
        status="ok" if flag is None else "flagged",
        error=flag or "",
        warnings="\n".join(collect.lines),
        results_file=spec.results_path,
        log_sha256=sha256_file(spec.log_path),
        rig_sha256=_sha256_text(str(ds.attrs["rig_json"])),
        calibration_sha256=opts.calibration_sha256
        or _sha256_text(str(ds.attrs.get("calibration", ""))),
        process_wall_time_s=time.perf_counter() - t0,
        worker_peak_rss_bytes=float(peak_rss_bytes()),
        worker=_worker_name(),
        **_run_info(ds),
    )
    return row


def flag_reason(processed: Any, spec: RunSpec) -> str | None:
    """Why a processed run's results may not be taken as they are (``None``: they may):
    no frame was measured (``process`` exits 2 with this line; its DAQ-only results are
    written all the same)."""
    failures = processed.failures
    if failures.total and not failures.measured:
        return (
            f"{spec.log_path}: none of the {failures.total} frames was measured; "
            f"{failures.advice()}. The DAQ-only results (strains, potentiometer, simulation) "
            f"were written to {spec.results_path}"
        )
    return None


def peak_rss_bytes() -> int:
    """This process's peak resident memory: ``VmHWM`` (reset by exec, unlike
    ``ru_maxrss``, which a process started by fork + exec inherits from its parent)."""
    try:
        with open("/proc/self/status", encoding="ascii") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    import resource

    return int(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss) * 1024


def _sha256_text(text: str) -> str:
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def _run_info(ds: Any) -> dict[str, str]:
    import json

    try:
        info = json.loads(str(ds.attrs.get("run_info", "{}")))
    except json.JSONDecodeError:
        info = {}
    if not isinstance(info, dict):
        info = {}
    return {
        "run_id": str(info.get("run_id", "")),
        "start_time_utc": str(info.get("start_utc", "")),
    }


def _worker_name() -> str:
    try:
        from distributed import get_worker

        return str(get_worker().address)
    except ValueError:  # not inside a Dask worker (run in-process)
        return "local"
