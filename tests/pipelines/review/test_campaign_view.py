"""The campaign's Rerun recording read back with rerun's own reader: one entity per run
(its card and its points), the frequency response against the crank frequency, a
sweep's curves, and the campaign layout."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from rerun.chunk import RrdReader

from pipelines.campaign.catalogue import empty_row, to_dataset
from pipelines.cli import main
from pipelines.review.campaign_view import write_campaign_rrd
from pipelines.review.layout import CAMPAIGN_TIMELINE
from pipelines.review.rrd import blueprint_views, rrd_entities

# Runs unlike any default: odd crank frequencies, a failed run, an unknown sd.
RUNS = {"slow run": 0.83, "run-2": 1.37, "run-3": 2.11}


def _catalogue() -> xr.Dataset:
    rows = []
    for k, (name, f) in enumerate(RUNS.items()):
        row = empty_row(name)
        row.update(status="ok", crank_frequency_hz=f, crank_frequency_sd_hz=1e-3 * (k + 1))
        for j, src in enumerate(("image", "strain", "sim")):
            p = f"tip_lateral_{src}"
            row[f"{p}_amplitude_m"] = 1e-3 * (3.1 + k + 0.2 * j)
            row[f"{p}_amplitude_sd_m"] = 1e-5 * (2 + j)
            row[f"{p}_phase_lag_rad"] = -0.1 * (k + 1) - 0.01 * j
            row[f"{p}_phase_lag_sd_rad"] = 2e-3 * (1 + j)
        rows.append(row)
    rows[1]["tip_lateral_strain_amplitude_sd_m"] = math.nan  # sd unknown: no bounds
    failed = empty_row("broken")
    failed.update(status="failed", error="broken.mcap: the log ends mid-chunk")
    rows.append(failed)
    return to_dataset(rows, {"title": "test"})


def _sweep() -> xr.Dataset:
    f = np.array([0.8, 1.4, 2.0, 2.6])
    amp = np.array([[2.0e-3, 1.5e-3], [4.0e-3, 3.0e-3], [np.nan, np.nan], [5.5e-3, 4.1e-3]])
    return xr.Dataset(
        {
            "tip_lateral_amplitude_m": (("crank_hz", "a1"), amp),
            "tip_lateral_phase_lag_rad": (("crank_hz", "a1"), -0.2 * amp / amp[0]),
        },
        coords={"crank_hz": f, "a1": [0.004, 0.012]},
    )


def _scalars(path: Path, entity: str) -> dict[int, list[float]]:
    """Timeline value -> the logged scalars of ``entity``."""
    out: dict[int, list[float]] = {}
    for chunk in RrdReader(path).stream():
        if chunk.entity_path != entity or chunk.is_static:
            continue
        rb = chunk.to_record_batch()
        if "Scalars:scalars" not in rb.schema.names:
            continue
        times = rb.column(CAMPAIGN_TIMELINE).to_pylist()
        for t, v in zip(times, rb.column("Scalars:scalars").to_pylist(), strict=True):
            out[int(t)] = [math.nan if x is None else float(x) for x in v]
    return out


def test_the_campaign_recording_holds_each_run_and_the_response(tmp_path: Path) -> None:
    cat = _catalogue()
    path = write_campaign_rrd(cat, tmp_path / "campaign.rrd", sweep=_sweep())
    entities = rrd_entities(path)
    assert "TextDocument:text" in entities["/summary"].components
    for name, f in RUNS.items():
        base = f"/runs/{name.replace(' ', chr(92) + ' ')}"
        assert "TextDocument:text" in entities[base].components
        assert list(_scalars(path, f"{base}/amplitude/sim")) == [round(f * 1e3)]
        for quantity in ("amplitude", "phase_lag"):
            for src in ("image", "strain", "sim"):
                e = entities[f"{base}/{quantity}/{src}"]
                assert e.rows == 1 and CAMPAIGN_TIMELINE in e.timelines
    # a failed run: its card, no points
    assert "/runs/broken" in entities
    assert not any(k.startswith("/runs/broken/") for k in entities)
    # values in display units at the run's crank frequency, with 2-sd bounds
    got = _scalars(path, "/runs/run-3/amplitude/image")
    assert list(got) == [2110]
    value, lo, hi = got[2110]
    assert value == pytest.approx(5.1) and lo == pytest.approx(5.1 - 0.04)
    assert hi == pytest.approx(5.1 + 0.04)
    lag = _scalars(path, "/runs/run-3/phase_lag/sim")[2110]
    assert lag[0] == pytest.approx(math.degrees(-0.32))
    assert lag[2] - lag[0] == pytest.approx(2 * math.degrees(6e-3))
    unknown = _scalars(path, "/runs/run-2/amplitude/strain")[1370]
    assert unknown[0] == pytest.approx(4.3) and math.isnan(unknown[1]) and math.isnan(unknown[2])
    # the sweep: one curve per a1, its failed point a gap
    curve = _scalars(path, "/sweep/amplitude/a1_0.012")
    assert sorted(curve) == [800, 1400, 2000, 2600]
    assert curve[1400] == [pytest.approx(3.0)] and math.isnan(curve[2000][0])
    # the layout: the response views show every run and the sweep, a card per run
    views = blueprint_views(path)
    series = [v for v in views if v.kind == "TimeSeries"]
    assert len(series) == 2
    for v in series:
        q = "amplitude" if v.shows("/runs/run-2/amplitude/sim") else "phase_lag"
        assert v.shows(f"/runs/run-2/{q}/image") and v.shows(f"/sweep/{q}/a1_0.004")
    docs = {v.origin for v in views if v.kind == "TextDocument"}
    assert {"/summary", "/runs/run-2", "/runs/broken"} <= docs


def test_a_bad_rrd_option_is_one_error_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    log = tmp_path / "run.mcap"
    log.write_bytes(b"not looked at: the option is refused first")
    args = ["campaign", str(log), "--out", str(tmp_path / "o")]
    assert main([*args, "--rrd", str(tmp_path / "c.nc")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --rrd ") and "must end in .rrd" in err
    assert err.count("\n") == 1
    assert main([*args, "--rrd", str(tmp_path / "nowhere" / "c.rrd")]) == 2
    err = capsys.readouterr().err
    assert "does not exist" in err and err.count("\n") == 1
