"""Processing says what failed: a line per failure reason with counts, a warning naming the
main reason and the option that would help when fewer than half the frames were measured,
and exit status 2 with one error line when none was (the DAQ-only results written)."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from pipelines.cli import main
from pipelines.process.failures import help_for, reason_kind, summarise_failures

ROOT = Path(__file__).resolve().parents[3]
SAMPLE = ROOT / "sample_data" / "run-6s.mcap"

NOISY = "too noisy: tip lateral uncertainty {:.2f} mm (edge scatter 0.20 mm; low contrast?)"


def test_reasons_are_counted_by_kind_whatever_their_numbers() -> None:
    reasons = [NOISY.format(0.5 + k / 100) for k in range(5)]
    reasons += ["motion blur: beam edges spread 7.1 px (12.0 mm of smear in the plane)"] * 2
    reasons += ["", "no hub found (too short)", ""]
    oks = [False] * 8 + [False, True]
    s = summarise_failures(oks, reasons)
    assert (s.total, s.measured, s.failed) == (10, 1, 9)
    assert [(k, n) for k, n, _ in s.kinds] == [
        ("too noisy", 5),
        ("motion blur", 2),
        ("no hub found (too short)", 1),
        ("no reason given", 1),
    ]
    lines = s.lines()
    assert lines[0] == f"5 of 10 frames not measured: too noisy (e.g. {NOISY.format(0.5)})"
    assert lines[2] == "1 of 10 frames not measured: no hub found (too short)"
    assert s.few_measured()
    assert s.advice().startswith("the main reason is 'too noisy' (5 frames); what may help: ")
    assert "--max-tip-uncertainty MM" in s.advice()


def test_each_kind_names_what_would_help() -> None:
    assert "--max-tip-uncertainty" in help_for(reason_kind(NOISY.format(0.7)))
    assert "[hub]" in help_for(reason_kind("no hub found (too short)"))
    assert "--rig" in help_for(reason_kind("beam width 25.0 mm in the image disagrees with x"))
    assert "exposure" in help_for(reason_kind("motion blur: beam edges spread 7.1 px"))
    assert "--calibration" in help_for("something new")


def test_half_measured_is_not_few() -> None:
    s = summarise_failures([True, False, True, False], ["", "x", "", "x"])
    assert not s.few_measured() and s.measured == 2
    assert summarise_failures([], []).kinds == []


@pytest.mark.slow
def test_no_frame_measured_is_exit_2_with_one_error_line_and_the_daq_results_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], caplog: pytest.LogCaptureFixture
) -> None:
    out = tmp_path / "r.nc"
    argv = ["process", str(SAMPLE), "--out", str(out), "--workers", "1"]
    # 0.1 um: no frame states a tip that certain
    with caplog.at_level(logging.WARNING):
        assert main([*argv, "--max-tip-uncertainty", "0.0001"]) == 2
    err = capsys.readouterr().err
    errors = [line for line in err.splitlines() if line.startswith("error: ")]
    assert len(errors) == 1 and "Traceback" not in err
    assert f"{SAMPLE}: none of the " in errors[0] and "'too noisy'" in errors[0]
    assert "--max-tip-uncertainty MM" in errors[0] and f"written to {out}" in errors[0]
    warned = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert any(" frames not measured: too noisy (e.g. too noisy: tip lateral" in m for m in warned)
    with xr.open_dataset(out, engine="h5netcdf") as ds:
        assert not ds["frame_ok"].values.any()
        assert np.isfinite(ds["sim_tip_lateral"].values).all()
        assert np.isfinite(ds["tip_lateral_strain"].values).all()
        assert '"too noisy"' in ds.attrs["frames_failed_by_reason"]


@pytest.mark.parametrize("mm", ["0", "-1", "nan", "11"])
def test_a_tip_uncertainty_limit_outside_its_range_is_one_error_line(
    mm: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["process", str(SAMPLE), "--out", str(tmp_path / "r.nc")]
    assert main([*argv, "--max-tip-uncertainty", mm]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --max-tip-uncertainty must be a number of mm") and (
        err.count("\n") == 1
    )
    assert not (tmp_path / "r.nc").exists()


def test_the_help_states_the_unit(capsys: pytest.CaptureFixture[str]) -> None:
    for command in ("process", "measure", "campaign"):
        with pytest.raises(SystemExit):
            main([command, "--help"])
        text = " ".join(capsys.readouterr().out.split())
        assert "--max-tip-uncertainty MM" in text and "in mm (default 0.5 mm)" in text
