"""The catalogue's round trip, the skip rule and the report, without a cluster."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from pipelines.campaign.catalogue import (
    NUMBER_COLUMNS,
    empty_row,
    read_catalogue,
    rows_of,
    to_dataset,
    write_catalogue,
)
from pipelines.campaign.execute import is_done
from pipelines.campaign.inputs import Options, find_logs, plan_runs
from pipelines.campaign.report import write_campaign_report
from pipelines.errors import BeambenchError


def _row(name: str, f_hz: float) -> dict[str, object]:
    row = empty_row(name)
    row.update(status="ok", crank_frequency_hz=f_hz, crank_frequency_sd_hz=1e-5)
    for k, src in enumerate(("image", "strain", "sim")):
        row[f"tip_lateral_{src}_amplitude_m"] = 0.03 * f_hz + 1e-4 * k
        row[f"tip_lateral_{src}_amplitude_sd_m"] = 2e-5
        row[f"tip_lateral_{src}_phase_lag_rad"] = 0.5 * f_hz
        row[f"tip_lateral_{src}_phase_lag_sd_rad"] = 1e-3
    return row


def test_catalogue_round_trip_keeps_every_column_with_units(tmp_path: Path) -> None:
    failed = empty_row("b-run")
    failed.update(status="failed", error="b-run.mcap: truncated")
    ds = to_dataset([_row("c-run", 1.3), failed, _row("a-run", 0.8)], {"note": "x"})
    path = write_catalogue(ds, tmp_path / "campaign.nc")
    back = read_catalogue(path)
    assert list(back["run"].values) == ["a-run", "b-run", "c-run"]
    for name, (units, _) in NUMBER_COLUMNS.items():
        assert back[name].attrs["units"] == units
    rows = rows_of(back)
    assert rows["b-run"]["error"] == "b-run.mcap: truncated"
    assert math.isnan(rows["b-run"]["crank_frequency_hz"])
    assert rows["c-run"]["crank_frequency_hz"] == 1.3
    (tmp_path / "junk.nc").write_bytes(b"not netcdf")
    with pytest.raises(ValueError, match=r"junk\.nc: not a beambench campaign catalogue"):
        read_catalogue(tmp_path / "junk.nc")


def test_a_run_is_done_only_with_the_same_inputs_and_its_results(tmp_path: Path) -> None:
    log = tmp_path / "r1.mcap"
    log.write_bytes(b"x" * 10)
    (spec,) = plan_runs(find_logs([str(tmp_path)]), tmp_path, Options())
    row = {"status": "ok", "input_key": spec.input_key()}
    assert not is_done(spec, row)  # no results file yet
    Path(spec.results_path).write_bytes(b"")
    assert is_done(spec, row)
    (other,) = plan_runs([log], tmp_path, Options(damping_law="material"))
    assert not is_done(other, row)
    (fitted,) = plan_runs([log], tmp_path, Options(fit_damping=True))
    assert not is_done(fitted, row)  # a run processed without the fit is redone with it
    log.write_bytes(b"y" * 11)
    (changed,) = plan_runs([log], tmp_path, Options())
    assert not is_done(changed, row)
    assert not is_done(spec, {**row, "status": "failed"})


def test_two_logs_with_one_name_are_refused(tmp_path: Path) -> None:
    for d in ("a", "b"):
        (tmp_path / d).mkdir()
        (tmp_path / d / "run.mcap").write_bytes(b"x")
    logs = find_logs([str(tmp_path / "a"), str(tmp_path / "b")])
    with pytest.raises(BeambenchError, match="two logs named 'run'"):
        plan_runs(logs, tmp_path, Options())


def test_report_tabulates_every_run_and_draws_the_figure(tmp_path: Path) -> None:
    failed = empty_row("z-run")
    failed.update(status="failed", error="z-run.mcap: truncated")
    ds = to_dataset([_row("a-run", 0.8), _row("b-run", 1.2), failed], {})
    md = write_campaign_report(ds, tmp_path, title="t")
    text = md.read_text()
    assert text.count("\n| ") == 4  # header + 3 runs
    assert "failed: z-run.mcap: truncated" in text
    assert "| a-run | 0.80000 ± 1.0e-05 | 24.00 ± 0.02 |" in text
    png = (tmp_path / "campaign_response.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    assert np.isfinite(ds["crank_frequency_hz"].values[:2]).all()
    import xarray as xr

    f = np.linspace(0.7, 1.4, 4)
    sweep = xr.Dataset(
        {
            "tip_lateral_amplitude_m": (("crank_hz", "a1"), 0.03 * f[:, None]),
            "tip_lateral_phase_lag_rad": (("crank_hz", "a1"), 0.5 * f[:, None]),
        },
        coords={"crank_hz": f, "a1": [0.1]},
        attrs={"sim_model": "auto:modal", "damping_law": "paper"},
    )
    text = write_campaign_report(ds, tmp_path, sweep=sweep).read_text()
    assert "Curves: `beambench sweep`" in text and "auto:modal" in text


def test_sweep_ranges_and_lists_are_checked() -> None:
    from pipelines.campaign.sweep import parse_list, parse_range

    np.testing.assert_allclose(parse_range("0.5:2.5:5"), [0.5, 1.0, 1.5, 2.0, 2.5])
    np.testing.assert_allclose(parse_range("0.92"), [0.92])
    for bad in ("1:2", "a:b:3", "0:1:3", "1:2:0"):
        with pytest.raises(BeambenchError, match="--crank-hz"):
            parse_range(bad)
    np.testing.assert_allclose(parse_list("0.05,0.1", "--a1"), [0.05, 0.1])
    for bad in ("x", "-1", "0.1,0.1", ""):
        with pytest.raises(BeambenchError, match="--a1"):
            parse_list(bad, "--a1")


def test_report_plots_the_fitted_damping_against_crank_frequency(tmp_path: Path) -> None:
    rows = [_row("a-run", 0.8), _row("b-run", 1.2), _row("c-run", 1.0)]
    rows[0].update(fitted_a1_s=0.0512, fitted_a1_ci95_s=0.0004, fitted_a0_per_s=0.0512)
    rows[1].update(
        fitted_a1_s=0.0498, fitted_a1_ci95_s=0.0003, fitted_a0_per_s=0.07, fitted_a0_ci95_per_s=0.01
    )
    # c-run: processed without a fit (or the fit failed): not in the damping table
    ds = to_dataset(rows, {})
    back = read_catalogue(write_catalogue(ds, tmp_path / "catalogue.nc"))
    assert back["fitted_a1_ci95_s"].attrs["units"] == "s"
    text = write_campaign_report(back, tmp_path, title="t").read_text()
    assert "## Damping fitted to each run" in text
    assert "| a-run | 0.8000 | 0.0512 ± 0.0004 | 0.0512 (held) |" in text
    assert "| b-run | 1.2000 | 0.0498 ± 0.0003 | 0.07 ± 0.01 |" in text
    assert "| c-run | 1.0000 | " not in text
    png = (tmp_path / "campaign_damping.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
