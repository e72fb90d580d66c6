"""The campaign catalogue ``OUT/campaign.nc``: one xarray Dataset with a ``run``
dimension, one row per run (design.md, "A campaign writes ... a catalogue").

A row is a flat dict; :data:`COLUMNS` says each column's units and meaning. A run's
``status`` is one of :data:`STATUSES`: ``ok``; ``flagged``, processed and its results file
written, but a result is missing or may be wrong (no frame measured): its ``error`` says
why and the numbers that could be made are kept; ``failed``, its ``error`` text and NaN
numbers. The file is rewritten (atomically) after every
finished run, so a campaign that is killed keeps what it finished.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from pipelines.atomic import atomic_path
from pipelines.results.compare import ERROR_METRICS

CATALOGUE_NAME = "campaign.nc"
FORMAT_NAME = "beambench-campaign"
FORMAT_VERSION = 1

STATUSES = ("ok", "flagged", "failed")

# name: (units, long_name); "" units for text
TEXT_COLUMNS: dict[str, str] = {
    "status": "ok; flagged: processed, but a result is missing or may be wrong (see error); "
    "or failed (see error)",
    "error": "why the run failed or was flagged (empty when ok)",
    "warnings": "warnings the run logged, one a line",
    "run_id": "run id recorded in the log",
    "source_log": "the run's log file",
    "results_file": "the run's results file",
    "start_time_utc": "run start, UTC ISO-8601 (from the log)",
    "software_version": "beambench version that processed the run",
    "log_sha256": "sha256 of the log file",
    "rig_sha256": "sha256 of the rig (the --rig file, else the log's rig record)",
    "calibration_sha256": "sha256 of the calibration (the --calibration file, else the "
    "calibration detected from the frames)",
    "input_key": "log size and mtime, options and file hashes the run was made from (JSON)",
    "worker": "Dask worker that processed the run",
}
NUMBER_COLUMNS: dict[str, tuple[str, str]] = {
    "crank_frequency_hz": ("Hz", "crank frequency measured from the rocker angle"),
    "crank_frequency_sd_hz": ("Hz", "standard uncertainty of crank_frequency_hz"),
    "rocker_amplitude_rad": ("rad", "rocker angle, amplitude of the crank fundamental"),
    "rocker_amplitude_sd_rad": ("rad", "standard uncertainty of rocker_amplitude_rad"),
    "steady_from_s": ("s", "fits use the run from this time on (the simulation settled)"),
    "frames_total": ("1", "camera frames in the run"),
    "frames_failed": ("1", "frames that gave no measurement"),
    "process_wall_time_s": ("s", "wall time of the task on its worker"),
    "worker_peak_rss_bytes": ("byte", "peak resident memory of the worker process so far"),
    "log_size_bytes": ("byte", "size of the log file"),
    # process --fit-damping (NaN without it, or when the fit failed or a0 was held)
    "fitted_a1_s": ("s", "damping a1 fitted to the run (process --fit-damping)"),
    "fitted_a1_ci95_s": ("s", "half-width of the 95 % interval of fitted_a1_s"),
    "fitted_a0_per_s": ("1/s", "damping a0 of the fit (fitted, or held: see the results)"),
    "fitted_a0_ci95_per_s": ("1/s", "half-width of the 95 % interval of a0 (NaN: a0 held)"),
}
for _src, _what in (("image", "images"), ("strain", "strains"), ("sim", "simulation")):
    _p = f"tip_lateral_{_src}"
    NUMBER_COLUMNS[f"{_p}_amplitude_m"] = ("m", f"tip lateral from the {_what}, crank fundamental")
    NUMBER_COLUMNS[f"{_p}_amplitude_sd_m"] = ("m", f"standard uncertainty of {_p}_amplitude_m")
    NUMBER_COLUMNS[f"{_p}_phase_lag_rad"] = (
        "rad",
        f"tip lateral from the {_what}: phase lag of the crank fundamental behind the rocker "
        "angle's, in (-pi, pi]",
    )
    NUMBER_COLUMNS[f"{_p}_phase_lag_sd_rad"] = (
        "rad",
        f"standard uncertainty of {_p}_phase_lag_rad",
    )
for _m in ERROR_METRICS:
    NUMBER_COLUMNS[_m.key] = (_m.units, _m.label)
INT_COLUMNS = {"log_mtime_ns": ("ns", "log file modification time, ns since the epoch")}


def empty_row(name: str) -> dict[str, Any]:
    row: dict[str, Any] = {"run": name}
    row.update(dict.fromkeys(TEXT_COLUMNS, ""))
    row.update(dict.fromkeys(NUMBER_COLUMNS, math.nan))
    row.update(dict.fromkeys(INT_COLUMNS, 0))
    return row


def to_dataset(rows: Iterable[Mapping[str, Any]], attrs: Mapping[str, Any]) -> xr.Dataset:
    """The catalogue Dataset of ``rows`` (sorted by run name)."""
    ordered = sorted(rows, key=lambda r: str(r["run"]))
    runs = np.array([str(r["run"]) for r in ordered], dtype=object)
    data: dict[str, Any] = {}
    for name, long_name in TEXT_COLUMNS.items():
        values = np.array([str(r.get(name, "")) for r in ordered], dtype=object)
        data[name] = ("run", values, {"long_name": long_name})
    for name, (units, long_name) in NUMBER_COLUMNS.items():
        values = np.array([float(r.get(name, math.nan)) for r in ordered], dtype=np.float64)
        data[name] = ("run", values, {"units": units, "long_name": long_name})
    for name, (units, long_name) in INT_COLUMNS.items():
        values = np.array([int(r.get(name, 0)) for r in ordered], dtype=np.int64)
        data[name] = ("run", values, {"units": units, "long_name": long_name})
    ds = xr.Dataset(data, coords={"run": ("run", runs, {"long_name": "run (log file stem)"})})
    ds.attrs.update(attrs)
    ds.attrs["format"] = FORMAT_NAME
    ds.attrs["format_version"] = FORMAT_VERSION
    return ds


def rows_of(ds: xr.Dataset) -> dict[str, dict[str, Any]]:
    """The rows of a catalogue Dataset, by run name."""
    out: dict[str, dict[str, Any]] = {}
    for i, run in enumerate(ds["run"].values):
        row = empty_row(str(run))
        for name in (*TEXT_COLUMNS, *NUMBER_COLUMNS, *INT_COLUMNS):
            if name in ds:
                v = ds[name].values[i]
                row[name] = (
                    str(v) if name in TEXT_COLUMNS else int(v) if name in INT_COLUMNS else float(v)
                )
        out[str(run)] = row
    return out


def write_catalogue(ds: xr.Dataset, path: str | os.PathLike[str]) -> Path:
    out = Path(path)
    with atomic_path(out) as tmp:
        ds.to_netcdf(tmp, engine="h5netcdf")
    return out


def read_catalogue(path: str | os.PathLike[str]) -> xr.Dataset:
    """A catalogue written by :func:`write_catalogue`, in memory. Raises ``ValueError``
    naming the file when it is not one."""
    p = Path(path)
    try:
        with xr.open_dataset(p, engine="h5netcdf") as opened:
            ds = opened.load()
    except (OSError, ValueError, TypeError, KeyError) as exc:
        raise ValueError(f"{p}: not a beambench campaign catalogue ({exc})") from None
    if ds.attrs.get("format") != FORMAT_NAME:
        raise ValueError(f"{p}: not a beambench campaign catalogue (no format={FORMAT_NAME!r})")
    return ds
