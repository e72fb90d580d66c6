"""Rerun recording of a campaign: one entity per run and the frequency response.

Read from the campaign catalogue (a Dataset with a ``run`` dimension, see
``pipelines.campaign.catalogue``) and, optionally, a sweep (dims ``crank_hz``, ``a1``).
The x axis is the timeline :data:`~pipelines.review.layout.CAMPAIGN_TIMELINE`, the crank
frequency in millihertz: each run sits at its measured crank frequency, a sweep's points
at theirs.

Entity paths::

    /summary                               the campaign's table (markdown)
    /runs/<run>                            the run's card: status, crank frequency,
                                           amplitudes and phase lags with their sd, the
                                           error of a failed run (markdown)
    /runs/<run>/amplitude/<source>         tip amplitude of the crank fundamental (mm):
                                           value, value - 2 sd, value + 2 sd
    /runs/<run>/phase_lag/<source>         tip phase lag behind the rocker (deg), likewise
    /sweep/amplitude/a1_<a1>, /sweep/phase_lag/a1_<a1>   a sweep's curve per a1

``<source>`` is ``image``, ``strain`` (both measured) or ``sim`` (the run's simulation).
A failed run has its card and no points.
"""

from __future__ import annotations

import math
import os
import uuid
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import rerun as rr
import xarray as xr

from pipelines.atomic import temp_path_beside
from pipelines.review.layout import (
    CAMPAIGN_SOURCES,
    CAMPAIGN_TIMELINE,
    COLOUR_AXES,
    COLOUR_BY_SOURCE,
    DEG_PER_RAD,
    MM_PER_M,
    build_campaign_blueprint,
    campaign_entity,
    run_entity,
)
from pipelines.review.viewer import RunViewer

APP_ID = "beambench-campaign"
# (quantity, catalogue variable suffix, sd suffix, display scale, display unit)
_QUANTITIES = (
    ("amplitude", "amplitude_m", "amplitude_sd_m", MM_PER_M, "mm"),
    ("phase_lag", "phase_lag_rad", "phase_lag_sd_rad", DEG_PER_RAD, "deg"),
)


def millihertz(f_hz: float) -> int:
    """A crank frequency's place on the campaign timeline."""
    return round(f_hz * 1e3)


def write_campaign_rrd(
    catalogue: xr.Dataset, path: str | os.PathLike[str], sweep: xr.Dataset | None = None
) -> Path:
    """Record ``catalogue`` (and ``sweep``) to the ``.rrd`` file ``path``, written under a
    temporary name beside it and renamed when complete. Raises BeambenchError (one
    line) when it cannot be written."""
    out = Path(path)
    runs = [str(r) for r in catalogue["run"].values]
    rec = rr.RecordingStream(APP_ID, recording_id=uuid.uuid4())
    tmp = temp_path_beside(out)
    rec.save(tmp, default_blueprint=build_campaign_blueprint(runs, sweep is not None))
    with RunViewer(rec, rrd_path=out, tmp_path=tmp):
        rec.log("/summary", rr.TextDocument(_summary(catalogue), media_type="text/markdown"))
        for i, run in enumerate(runs):
            _log_run(rec, catalogue.isel(run=i), run)
        if sweep is not None:
            _log_sweep(rec, sweep)
    return out


def _log_run(rec: rr.RecordingStream, row: xr.Dataset, run: str) -> None:
    rec.log(
        run_entity(run), rr.TextDocument(_card(row, run), media_type="text/markdown"), static=True
    )
    f_hz = float(row["crank_frequency_hz"])
    if str(row["status"].values) != "ok" or not math.isfinite(f_hz):
        return
    rec.set_time(CAMPAIGN_TIMELINE, sequence=millihertz(f_hz))
    for quantity, var, sd_var, scale, unit in _QUANTITIES:
        for src in CAMPAIGN_SOURCES:
            value = float(row[f"tip_lateral_{src}_{var}"]) * scale
            sd = float(row[f"tip_lateral_{src}_{sd_var}"]) * scale
            if not math.isfinite(value):
                continue
            entity = campaign_entity(run, quantity, src)
            colour = COLOUR_BY_SOURCE[src]
            rec.log(
                entity,
                rr.SeriesPoints(
                    colors=[colour, colour, colour],
                    markers=["circle", "down", "up"],
                    marker_sizes=[5.0, 3.0, 3.0],
                    names=[f"{run} {src} ({unit})", f"{src} - 2 sd", f"{src} + 2 sd"],
                ),
                static=True,
            )
            # an sd that is not known draws no bounds (NaN is no point), never zero-width ones
            rec.log(entity, rr.Scalars([value, value - 2 * sd, value + 2 * sd]))
    rec.reset_time()


def _log_sweep(rec: rr.RecordingStream, sweep: xr.Dataset) -> None:
    f = np.asarray(sweep["crank_hz"].values, float)
    times = rr.TimeColumn(CAMPAIGN_TIMELINE, sequence=[millihertz(v) for v in f])
    for a1 in sweep["a1"].values:
        pt = sweep.sel(a1=a1)
        for quantity, scale, unit, var in (
            ("amplitude", MM_PER_M, "mm", "tip_lateral_amplitude_m"),
            ("phase_lag", DEG_PER_RAD, "deg", "tip_lateral_phase_lag_rad"),
        ):
            entity = f"/sweep/{quantity}/{rr.escape_entity_path_part(f'a1_{float(a1):g}')}"
            rec.log(
                entity,
                rr.SeriesLines(
                    colors=[COLOUR_AXES], names=[f"sweep a1 = {float(a1):g} s ({unit})"]
                ),
                static=True,
            )
            values = np.asarray(pt[var].values, float) * scale  # a failed point: NaN, a gap
            rec.send_columns(entity, indexes=[times], columns=rr.Scalars.columns(scalars=values))


def _fmt(value: float, sd: float, scale: float, digits: int) -> str:
    if not math.isfinite(value):
        return "n/a"
    text = f"{value * scale:.{digits}f}"
    return text + (f" ± {sd * scale:.{digits}f}" if math.isfinite(sd) else " (sd unknown)")


def _card(row: xr.Dataset, run: str) -> str:
    def num(name: str) -> float:
        return float(row[name])

    lines = [f"# {run}", "", f"status: **{row['status'].values}**"]
    if str(row["error"].values):
        lines += ["", f"error: {row['error'].values}"]
    f = _fmt(num("crank_frequency_hz"), num("crank_frequency_sd_hz"), 1.0, 4)
    lines += ["", f"crank frequency: {f} Hz (sd)", ""]
    lines += ["| source | amplitude (mm) | phase lag (deg) |", "|---|---|---|"]
    for src in CAMPAIGN_SOURCES:
        p = f"tip_lateral_{src}"
        amp = _fmt(num(f"{p}_amplitude_m"), num(f"{p}_amplitude_sd_m"), MM_PER_M, 3)
        lag = _fmt(num(f"{p}_phase_lag_rad"), num(f"{p}_phase_lag_sd_rad"), DEG_PER_RAD, 2)
        lines.append(f"| {src} | {amp} | {lag} |")
    if str(row["results_file"].values):
        lines += ["", f"results: `{row['results_file'].values}`"]
    return "\n".join(lines) + "\n"


def _summary(catalogue: xr.Dataset) -> str:
    status = [str(s) for s in catalogue["status"].values]
    n_ok = sum(s == "ok" for s in status)
    lines = [
        "# Campaign",
        "",
        f"{len(status)} runs, {n_ok} ok, {len(status) - n_ok} failed. Points: value and "
        "its 2-sd bounds at each run's measured crank frequency (mHz on the time axis).",
        "",
        "| run | status | crank (Hz) | image (mm) | sim (mm) | image lag (deg) | sim lag (deg) |",
        "|---|---|---|---|---|---|---|",
    ]
    for i, run in enumerate(catalogue["run"].values):
        row = catalogue.isel(run=i)
        cells = [str(run), status[i]]
        cells.append(f"{float(row['crank_frequency_hz']):.4f}")
        for src in ("image", "sim"):
            cells.append(f"{float(row[f'tip_lateral_{src}_amplitude_m']) * MM_PER_M:.3f}")
        for src in ("image", "sim"):
            cells.append(f"{float(row[f'tip_lateral_{src}_phase_lag_rad']) * DEG_PER_RAD:.2f}")
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


__all__: Sequence[str] = ("APP_ID", "millihertz", "write_campaign_rrd")
