"""A campaign run in which no frame was measured is not ``ok``: ``process`` refuses it
(exit 2, its DAQ-only results written), so the campaign records it ``flagged`` with that
line as its error, keeps the numbers the DAQ gave, redoes it on a rerun, says so in its
summary and report, and exits 1 as for a failed run."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import pytest

from pipelines.campaign.catalogue import read_catalogue, rows_of
from pipelines.campaign.execute import describe, is_done
from pipelines.campaign.inputs import Options, plan_runs
from pipelines.cli import main
from pipelines.demo import capture_synthetic
from pipelines.rig import load_rig

pytestmark = pytest.mark.slow

DURATION_S = 3.0


@pytest.fixture(scope="module")
def log_path(tmp_path_factory: pytest.TempPathFactory) -> Path:
    rig = load_rig()
    rig = dataclasses.replace(
        rig,
        # 2 Hz: six crank periods in the 3 s, enough for the catalogue's fits
        linkage=dataclasses.replace(rig.linkage, crank_frequency_hz=2.0),
        synthetic=dataclasses.replace(rig.synthetic, model="modal", warmup_s=1.0),
    )
    path = tmp_path_factory.mktemp("flagged") / "blind.mcap"
    capture_synthetic(rig, path, DURATION_S)
    return path


def test_a_run_with_no_frame_measured_is_flagged(
    log_path: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "campaign"
    # a tip uncertainty limit of 0.1 um: every frame states more (or fails before), none is
    # measured
    argv = ["campaign", str(log_path), "--out", str(out), "--workers", "1"]
    argv += ["--max-tip-uncertainty", "0.0001", "--model", "modal"]
    assert main(argv) == 1
    captured = capsys.readouterr()
    assert "0 failed (of the processed, 1 flagged)" in captured.out
    assert "blind: FLAGGED: " in captured.out
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("flagged: blind: "), captured.err

    row = rows_of(read_catalogue(out / "campaign.nc"))["blind"]
    n = row["frames_total"]
    assert n == pytest.approx(DURATION_S * 15, abs=2) and row["frames_failed"] == n
    # process's line: the main reason and what may help
    assert f"none of the {n:.0f} frames was measured; the main reason is '" in err[0]
    assert "what may help: " in err[0] and "The DAQ-only results" in err[0]
    assert row["status"] == "flagged"
    assert row["error"] == err[0].removeprefix("flagged: blind: ")
    assert f" of {n:.0f} frames not measured: " in row["warnings"]
    assert Path(row["results_file"]).is_file()  # the DAQ-only results
    # what the DAQ gave is kept; the image gave nothing
    for key in (
        "crank_frequency_hz",
        "tip_lateral_strain_amplitude_m",
        "tip_lateral_sim_amplitude_m",
    ):
        assert math.isfinite(row[key]) and row[key] > 0, key
    assert row["crank_frequency_hz"] == pytest.approx(2.0, rel=1e-3)
    assert math.isnan(row["tip_lateral_image_amplitude_m"])
    assert describe(row).startswith("blind: FLAGGED: ")
    # not done: a rerun processes it again (as a failed run)
    options = Options(model="modal", max_tip_uncertainty_m=1e-7)
    (spec,) = plan_runs([log_path], out, options)
    assert not is_done(spec, row)

    report = (out / "campaign.md").read_text()
    assert "0 processed ok, 1 flagged" in report
    assert f"| flagged: {err[0].removeprefix('flagged: blind: ')[:80]} |" in report
