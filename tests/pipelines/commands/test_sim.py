"""`beambench sim`: NetCDF per design.md, the linkage report, one-line errors."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import xarray as xr

from pipelines.cli import main
from sim.drives import SinusoidDrive
from sim.models.fe_ancf import AncfBeam


def test_reciprocating_writes_the_contract_variables(tmp_path: Path) -> None:
    out = tmp_path / "r.nc"
    rc = main(["sim", "reciprocating", "--model", "modal", "--duration", "1.5", "--out", str(out)])
    assert rc == 0
    with xr.open_dataset(out, engine="h5netcdf") as ds:
        for name, units in (
            ("time", "s"),
            ("gauge", "m"),
            ("hub_angle", "rad"),
            ("tip_lateral", "m"),
            ("tip_longitudinal", "m"),
            ("strain", "1"),
        ):
            assert ds[name].attrs["units"] == units
            assert ds[name].attrs["long_name"]
        assert ds["strain"].dims == ("time", "gauge")
        assert ds["gauge"].values.tolist() == [0.005, 0.204, 0.403, 0.603]
        assert ds.sizes["time"] == 601
        assert ds.attrs["model"] == "modal"
        for key in ("rtol", "atol", "wall_time_s"):
            assert math.isfinite(float(ds.attrs[key]))
        settings = json.loads(ds.attrs["settings"])
        assert settings["a0_per_s"] == 0.1 and settings["a1_s"] == 0.1  # the rig's
        assert 0.01 < float(abs(ds["tip_lateral"]).max()) < 0.05


def test_static_modal_matches_linear_theory(tmp_path: Path) -> None:
    out = tmp_path / "s.nc"
    assert main(["sim", "static", "--model", "modal", "--mass", "0.1", "--out", str(out)]) == 0
    with xr.open_dataset(out, engine="h5netcdf") as ds:
        p = 0.1 * 9.80665
        ei = 6.89e10 * 5.08095e-11
        linear = p * 0.835**3 / (3 * ei)
        assert float(-ds["tip_lateral"][0]) == pytest.approx(linear, rel=1e-4)
        assert (ds["strain"].values > 0).all()


def test_linkage_json_keys(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["sim", "linkage", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    for key in (
        "rocker_min_rad",
        "crank_at_min_rad",
        "rocker_max_rad",
        "crank_at_max_rad",
        "grashof",
        "transmission_angle_min_rad",
        "transmission_angle_max_rad",
    ):
        assert key in info
    assert info["grashof"] == "crank-rocker"
    assert math.degrees(info["rocker_min_rad"]) == pytest.approx(61.928, abs=1e-3)
    assert math.degrees(info["paper_rocker_min_rad"]) == pytest.approx(62.598)


@pytest.mark.parametrize(
    "argv",
    [
        ["sim", "static", "--mass", "-1"],
        ["sim", "reciprocating", "--drive", "foo"],
        ["sim", "static", "--out", "/nonexistent-folder/x.nc"],
    ],
)
def test_bad_input_is_one_error_line_and_exit_2(
    argv: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    try:
        rc = main(argv)
    except SystemExit as exc:  # argparse usage errors
        rc = int(exc.code or 0)
    assert rc == 2
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    assert "Traceback" not in err


def test_the_console_entry_point_reports_bad_input_in_one_line() -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "pipelines.cli", "sim", "static", "--mass", "-1"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == ["error: --mass must be non-negative, got -1.0 kg"]


def test_failed_run_does_not_clobber_an_existing_file(tmp_path: Path) -> None:
    out = tmp_path / "keep.nc"
    out.write_bytes(b"precious")
    rc = main(["sim", "static", "--mass", "-1", "--out", str(out)])
    assert rc == 2
    assert out.read_bytes() == b"precious"


def _one_error_line(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    assert "Traceback" not in err
    return lines[0]


def test_a_failing_fe_integration_is_one_error_line(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # the hub rate stops being finite at 20 ms: the integrator's own check refuses it
    def rate(self: SinusoidDrive, t_s: Any) -> np.ndarray:
        t = np.asarray(t_s, dtype=float)
        return np.where(t < 0.02, self.amplitude_rad * self.omega_rad_s, np.nan)

    monkeypatch.setattr(SinusoidDrive, "rate", rate)
    rc = main(["sim", "reciprocating", "--model", "fe", "--duration", "0.05"])
    assert rc == 2
    line = _one_error_line(capsys)
    assert "integration failed at t = " in line and "not finite" in line, line


def test_a_failing_static_fe_solve_is_one_error_line(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # a tangent 1000 times too stiff: Newton's steps are 1000 times too short and its 100
    # iterations do not reach the first load step's equilibrium
    exact_tangent = AncfBeam.tangent

    def stiff_tangent(self: AncfBeam, e_full: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        force, k = exact_tangent(self, e_full)
        return force, 1e3 * k

    monkeypatch.setattr(AncfBeam, "tangent", stiff_tangent)
    rc = main(["sim", "static", "--model", "fe", "--mass", "0.149"])
    assert rc == 2
    line = _one_error_line(capsys)
    assert line.startswith("error: static solve: Newton did not converge at load step 1/"), line
