"""Report: files, valid PNGs, the table's numbers are summarise_errors', Fig. 10 geometry."""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from pipelines.results.compare import ERROR_METRICS, summarise_errors
from pipelines.results.dataset import make_results
from pipelines.review.report import PLOTS, REPORT_NAME, tip_positions_m, write_report
from pipelines.rig import Rig

FS_HZ = 400.0


def _results(failed: tuple[int, ...] = (2, 7)) -> Any:
    t = np.arange(0, 6.0, 1 / FS_HZ)
    omega = 2 * np.pi * 0.92
    rocker = 1.8 + 0.7669 * np.sin(omega * t)
    tip = 0.02 * np.sin(omega * t - 0.5)
    idx = np.arange(5, t.size, 27)
    ok = np.ones(idx.size, dtype=bool)
    ok[list(failed)] = False
    rng = np.random.default_rng(1)
    strain = 3e-4 * np.outer(np.sin(omega * t - 0.5), [1.0, 0.7, 0.45, 0.2])
    return make_results(
        time_s=t,
        rocker_angle_rad=rocker,
        strain=strain + rng.normal(0, 4e-6, strain.shape),
        gauge_m=[0.005, 0.204, 0.403, 0.603],
        frame_time_s=t[idx] + 0.001,
        hub_angle_image_rad=rocker[idx] + 0.05,
        tip_lateral_m=tip[idx] + rng.normal(0, 5e-4, idx.size),
        tip_longitudinal_m=-0.6 * tip[idx] ** 2 / 0.843,
        frame_ok=ok,
        tip_lateral_strain_m=tip * 1.03,
        sim_tip_lateral_m=tip,
        sim_strain=strain,
        sim_tip_longitudinal_m=-0.6 * tip**2 / 0.843,
        attrs={
            "source_log": "demo-out/run.mcap",
            "rig_json": Rig().to_json(),
            "software_version": "test",
            "sim_model": "modal",
            "sim_settings": {"modes": 3},
            "camera_to_daq_offset_s": -0.0042,
        },
    )


def _table(md: str) -> dict[str, tuple[str, str]]:
    rows = {}
    for line in md.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 3 and line.startswith("|") and not set(cells[1]) <= set("-:"):
            rows[cells[0]] = (cells[1], cells[2])
    return rows


def test_report_has_its_files_valid_pngs_and_the_error_numbers(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    ds = _results()
    with caplog.at_level(logging.WARNING):
        path = write_report(ds, tmp_path / "out", title="Synthetic run", notes=["made by a test"])
    assert not caplog.records, [r.getMessage() for r in caplog.records]  # e.g. matplotlib's
    assert path == tmp_path / "out" / REPORT_NAME
    names = sorted(p.name for p in path.parent.iterdir())
    assert names == sorted([REPORT_NAME, *PLOTS.values()])
    for name in PLOTS.values():
        img = cv2.imread(str(path.parent / name))
        assert img is not None and img.shape[0] > 200 and img.shape[1] > 300, name
        assert img.std() > 5, name  # something was drawn
    md = path.read_text("utf-8")
    assert md.startswith("# Synthetic run\n")
    assert "- made by a test" in md
    for name in PLOTS.values():
        assert f"]({name})" in md
    assert "-4.2 ms" in md
    table = _table(md)
    errors = summarise_errors(ds)
    for m in ERROR_METRICS:
        value, unit = table[m.label]
        assert unit == "mm"
        assert float(value) == pytest.approx(1e3 * errors[m.key], rel=5e-4), m.key
    for j in range(4):
        value, unit = table[f"strain g{j + 1}, measured - sim, RMS"]
        assert unit == "µε"
        assert float(value) == pytest.approx(1e6 * errors["strain_vs_sim_rms"][j], rel=5e-4)
        value, _ = table[f"strain g{j + 1}, measured - sim, max abs"]
        assert float(value) == pytest.approx(1e6 * errors["strain_vs_sim_max"][j], rel=5e-4)
    assert table["frames compared"][0] == str(errors["n_frames_compared"])
    assert "2 gave no measurement" in md
    # The noise put in is what comes out: RMS strain error ~ 4 microstrain.
    assert float(table["strain g1, measured - sim, RMS"][0]) == pytest.approx(4.0, rel=0.1)


def test_report_puts_the_simulation_error_beside_the_image_comparison(tmp_path: Path) -> None:
    ds = _results(failed=())
    md_old = write_report(ds, tmp_path / "old", title="old").read_text("utf-8")
    assert "simulation's own error" not in md_old  # a results file from before issue 15
    sd_m, est_m = 0.4e-3, 0.3e-3
    ds.attrs.update(
        sim_tol_rule="a fifth of the image's RMS tip uncertainty",
        sim_tol=4e-3,
        sim_tip_tol_m=0.08e-3,
        image_tip_lateral_sd_rms_m=sd_m,
        sim_tip_error_estimate_m=est_m,
        sim_resimulated=1,
        sim_drive_tip_uncertainty_m=0.12e-3,
        calibration_tip_lateral_sd_m=0.2e-3,
    )
    md = write_report(ds, tmp_path / "new", title="new").read_text("utf-8")
    rows = {}
    for line in md.split("simulation's own error", 1)[1].splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if line.startswith("|") and len(cells) == 2:
            rows[cells[0]] = cells[1]
    rms_m = summarise_errors(ds)["tip_lateral_image_vs_sim_rms_m"]  # ~0.5 mm of noise
    assert float(rows["image - sim, RMS"]) == pytest.approx(1e3 * rms_m, rel=5e-4)
    assert float(rows["simulation's estimated error (its model, max over the run)"]) == 0.3
    assert float(rows["image - sim, RMS, the simulation's error taken out"]) == pytest.approx(
        1e3 * np.sqrt(rms_m**2 - est_m**2), rel=5e-4
    )
    # sqrt(0.4^2 + 0.3^2 + 0.12^2 + 0.2^2) mm: noise, model, drive and calibration
    assert float(rows["expected image - sim RMS from these four alone"]) == pytest.approx(
        0.5517, abs=1e-4
    )
    assert (
        float(rows["simulation's uncertainty from the measured hub angle (fitted drive), RMS"])
        == 0.12
    )
    assert "simulated again after the frames" in md


def test_report_rewrites_a_folder_without_leaving_temp_files(tmp_path: Path) -> None:
    ds = _results(failed=())
    write_report(ds, tmp_path, title="one")
    path = write_report(ds, tmp_path, title="two")
    assert path.read_text("utf-8").startswith("# two\n")
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]
    with pytest.raises(TypeError, match="notes"):
        write_report(ds, tmp_path, title="x", notes="one string")
    with pytest.raises(ValueError, match="sim_strain"):
        write_report(ds.drop_vars("sim_strain"), tmp_path, title="x")


def test_tip_positions_against_closed_forms() -> None:
    r = 0.843
    a = np.radians([0.0, 90.0, 30.0, 150.0])
    flex, rigid = tip_positions_m(a, np.zeros(4), np.zeros(4), r)
    np.testing.assert_allclose(flex, rigid)
    np.testing.assert_allclose(np.hypot(*rigid.T), r)
    # Lateral is toward increasing angle, longitudinal along the beam.
    flex, _ = tip_positions_m(np.array([0.0, np.pi / 2]), [0.01, 0.01], [-0.002, 0.0], r)
    np.testing.assert_allclose(flex, [[r - 0.002, 0.01], [-0.01, r]], atol=1e-15)
    # A pure lateral deflection d puts the tip at radius sqrt(r^2 + d^2), angle + atan(d/r).
    d = 0.05
    flex, _ = tip_positions_m(np.array([0.7]), [d], [0.0], r)
    assert np.hypot(*flex[0]) == pytest.approx(np.hypot(r, d), rel=1e-12)
    assert np.arctan2(flex[0, 1], flex[0, 0]) == pytest.approx(0.7 + np.arctan(d / r), rel=1e-12)
    with pytest.raises(ValueError, match="pivot_to_tip_m"):
        tip_positions_m(a, np.zeros(4), np.zeros(4), -1.0)
    with pytest.raises(ValueError, match="lateral_m"):
        tip_positions_m(a, np.zeros(3), np.zeros(4), r)


@pytest.mark.parametrize("n_frames", [0, 6])
def test_a_run_without_usable_frames_still_gives_results_recording_and_report(
    tmp_path: Path, n_frames: int
) -> None:
    from pipelines.results.io import read_results, write_results
    from pipelines.review.viewer import open_viewer, rrd_entities

    t = np.arange(0, 5.0, 1 / FS_HZ)
    n = t.size
    ds = make_results(
        time_s=t,
        rocker_angle_rad=np.sin(t),
        strain=np.zeros((n, 4)),
        gauge_m=[0.005, 0.204, 0.403, 0.603],
        frame_time_s=0.1 * np.arange(n_frames),
        hub_angle_image_rad=np.zeros(n_frames),
        tip_lateral_m=np.zeros(n_frames),
        tip_longitudinal_m=np.zeros(n_frames),
        frame_ok=np.zeros(n_frames, dtype=bool),  # every frame failed
        tip_lateral_strain_m=np.full(n, np.nan),
        sim_tip_lateral_m=np.zeros(n),
        sim_strain=np.zeros((n, 4)),
        attrs={
            "source_log": "run.mcap",
            "rig_json": Rig().to_json(),
            "software_version": "test",
            "sim_model": "rigid",
            "sim_settings": {},
            "camera_to_daq_offset_s": float("nan"),  # alignment impossible without frames
        },
    )
    back = read_results(write_results(ds, tmp_path / "r.nc"))
    assert back.sizes["frame_time"] == n_frames
    assert back.attrs["frames_failed"] == n_frames
    errors = summarise_errors(back)
    assert errors["n_frames_compared"] == 0
    assert np.isnan(errors["tip_lateral_image_vs_sim_rms_m"])
    assert errors["strain_vs_sim_rms"] == [0.0] * 4
    with open_viewer("beambench-test", rrd_path=tmp_path / "r.rrd") as viewer:
        viewer.log_results(back)
    entities = rrd_entities(tmp_path / "r.rrd")
    assert entities["/daq/rocker_angle"].rows == n
    assert entities["/tip_lateral/image"].rows == 0
    md = write_report(back, tmp_path / "report", title="no frames").read_text("utf-8")
    assert "| tip lateral, image - sim, RMS | n/a | mm |" in md
    assert "camera-to-DAQ time offset: n/a ms" in md


def test_report_states_the_fitted_damping_with_its_intervals(tmp_path: Path) -> None:
    ds = _results()
    ds.attrs.update(
        {
            "fitted_damping_law": "material",
            "fitted_a0_per_s": 0.0501,
            "fitted_a1_s": 0.05012,
            "fitted_a1_ci95_s": 0.00031,
            "fitted_a0_note": "held equal to a1 (the paper's a0 = a1): the run does not "
            "determine a0",
            "fitted_residual_before_se": 812.0,
            "fitted_residual_after_se": 1.3,
            "fitted_strain_rms_before": 6.1e-6,
            "fitted_strain_rms_after": 0.9e-6,
            "fitted_tip_rms_before_m": 1.2e-3,
            "fitted_tip_rms_after_m": 0.06e-3,
            "fitted_birge_ratio": 1.4,
            "fitted_cycles": 11,
            "fitted_from_s": 1.6,
            "fitted_harmonics": "gauge 1 h1, image tip h1",
            "fitted_loop_model": "modal n_modes=4",
            "fitted_a1_loop_s": 0.05015,
            "fitted_exact_model": "auto:fe-corot",
        }
    )
    md = write_report(ds, tmp_path, title="fitted").read_text("utf-8")
    assert "## Damping fitted to the run" in md
    table = _table(md)
    assert table["a1"] == ("0.05012 s", "+-0.00031 s")
    assert table["a0"][1].startswith("held equal to a1")
    assert table["strains (RMS, microstrain)"] == ("6.10", "0.90")
    assert table["image tip (RMS, mm)"] == ("1.200", "0.060")
    ds.attrs = {k: v for k, v in ds.attrs.items() if not k.startswith("fitted_")}
    ds.attrs["fitted_damping_failed"] = "the least squares did not converge in 2 simulations"
    ds.attrs["fitted_damping_law"] = "paper"
    md = write_report(ds, tmp_path, title="unfitted").read_text("utf-8")
    assert "Not fitted (paper law): the least squares did not converge" in md
    assert "| a1 |" not in md
