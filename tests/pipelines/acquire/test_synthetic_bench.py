"""The built-in synthetic bench is the bench its rig describes (issue #20, "your renderer
learns the same variety"): the hub of ``[hub]`` with its clamp ``[beam] hub_offset_m``
from the pivot, motion blur over ``[camera] exposure_s`` from the beam's own velocity,
the contrast and lighting of ``[synthetic]``, and frames stamped
``[synthetic] stamp_latency_s`` late; processed end to end, the pipeline measures what was
drawn, within what it states."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from pipelines.acquire.synthetic import (
    CAMERA_CLOCK_OFFSET_S,
    SyntheticBench,
    SyntheticDevices,
    build_synthetic,
)
from pipelines.demo import capture_synthetic
from pipelines.process.frames import MeasuredFrame
from pipelines.process.run import Processed, process_run
from pipelines.rig import HubConfig, Rig, load_rig
from vision import Calibration

# A bench that differs from the default on purpose in every way the rig now says:
HUB_LENGTH_M, HUB_WIDTH_M, HUB_OFFSET_M = 0.060, 0.045, 0.012  # a short block, clamp 12 mm out
EXPOSURE_S = 2e-3  # 4x the default: the tip smears up to ~8 mm (8 px) a frame
BACKGROUND_DN, BEAM_DN = 60.0, 160.0  # 100 DN of contrast instead of 175
IMAGE_NOISE_DN = 3.0
LIGHTING_GRADIENT = -0.3  # the light falls 30 % from right to left
STAMP_LATENCY_S = 0.037  # frames stamped on arrival, 37 ms after mid-exposure
DURATION_S = 3.0


def other_rig() -> Rig:
    rig = load_rig()
    return dataclasses.replace(
        rig,
        hub=HubConfig(length_m=HUB_LENGTH_M, width_m=HUB_WIDTH_M),
        beam=dataclasses.replace(rig.beam, hub_offset_m=HUB_OFFSET_M),
        camera=dataclasses.replace(rig.camera, exposure_s=EXPOSURE_S),
        synthetic=dataclasses.replace(
            rig.synthetic,
            model="modal",
            warmup_s=2.0,
            seed=515,
            image_noise_dn=IMAGE_NOISE_DN,
            background_dn=BACKGROUND_DN,
            beam_dn=BEAM_DN,
            lighting_gradient=LIGHTING_GRADIENT,
            stamp_latency_s=STAMP_LATENCY_S,
            drawn_hub_length_m=0.0,  # draw [hub]'s block, not the shipped rig's bar
            drawn_hub_width_m=0.0,
        ),
    )


def _quick(rig: Rig) -> Rig:
    """``rig`` with a short modal warm-up (the scene does not depend on it)."""
    syn = dataclasses.replace(rig.synthetic, model="modal", warmup_s=0.1)
    return dataclasses.replace(rig, synthetic=syn)


def test_the_scene_is_the_rigs() -> None:
    rig = _quick(other_rig())
    bench = SyntheticBench(rig, 0.5)
    s = bench.scene
    assert (s.hub_length_m, s.hub_width_m, s.hub_offset_m) == (0.060, 0.045, 0.012)
    assert (s.background_dn, s.beam_dn, s.lighting_gradient) == (60.0, 160.0, -0.3)
    assert s.noise_dn == IMAGE_NOISE_DN
    # the hub at the default bench's share of the contrast (190 DN between 40 and 215)
    assert s.hub_dn == pytest.approx(60.0 + 100.0 * 150.0 / 175.0)
    default_scene = SyntheticBench(_quick(load_rig()), 0.5).scene
    assert default_scene.hub_dn == 190.0  # the default bench's picture is unchanged
    assert (default_scene.background_dn, default_scene.beam_dn) == (40.0, 215.0)
    assert default_scene.lighting_gradient == 0.0
    # the shipped rig's bench draws its own 200 x 40 mm bar, not [hub]'s paper block
    assert (default_scene.hub_length_m, default_scene.hub_width_m) == (0.2, 0.04)
    # motion blur: poses sampled at most a pixel of tip travel apart over the exposure
    default = SyntheticBench(dataclasses.replace(rig, camera=load_rig().camera), 0.5)
    assert bench.blur_samples >= 4 * default.blur_samples - 1 and bench.blur_samples > 4


def test_frames_are_stamped_the_latency_late() -> None:
    devices = build_synthetic(_quick(other_rig()), 0.5)
    cam = devices.camera
    for k in (0, 3, 7):
        true_mid = cam.true_exposure_start_s(k) + 0.5 * cam.exposure_s
        late_s = cam.stamp_ns(k) * 1e-9 - true_mid
        # the clock offset and the latency, to the 20 ppm drift and the 20 us jitter
        assert late_s == pytest.approx(CAMERA_CLOCK_OFFSET_S + STAMP_LATENCY_S, abs=1e-4)


@dataclasses.dataclass
class Captured:
    log_path: Path
    devices: SyntheticDevices

    def truth(self, ds: xr.Dataset, frames: list[MeasuredFrame]) -> tuple[np.ndarray, ...]:
        """Each frame's true mid-exposure time on the results' clock, its true tip lateral
        deflection and hub angle there (the time-average over 2 ms differs by ~1e-3 mm)."""
        cam, bench = self.devices.camera, self.devices.bench
        seq = np.array([f.sequence for f in frames])
        t_true = np.array([cam.true_exposure_start_s(int(k)) for k in seq]) + 0.5 * EXPOSURE_S
        t_zero_s = ds.attrs["t_zero_ns"] * 1e-9
        return (
            t_true - t_zero_s,
            bench.truth.tip_lateral_m(t_true),
            bench.truth.hub_angle_plane_rad(t_true),
        )


@pytest.fixture(scope="module")
def captured(tmp_path_factory: pytest.TempPathFactory) -> Captured:
    log_path = tmp_path_factory.mktemp("other-bench") / "other.mcap"
    return Captured(log_path, capture_synthetic(other_rig(), log_path, DURATION_S))


@pytest.fixture(scope="module")
def detected(captured: Captured) -> Processed:
    """Processed as a user would: the calibration from the registration plate in the frames."""
    return process_run(captured.log_path, workers=2)


def _errors(captured: Captured, processed: Processed) -> tuple[np.ndarray, ...]:
    """Tip lateral and hub angle errors of the measured frames, with their stated sds."""
    ds = processed.results
    ok = ds["frame_ok"].values.astype(bool)
    _, tip_true, hub_true = captured.truth(ds, processed.frames)
    tip_err = ds["tip_lateral"].values[ok] - tip_true[ok]
    hub_err = np.angle(np.exp(1j * (ds["hub_angle_image"].values[ok] - hub_true[ok])))
    tip_sd = ds["tip_lateral_sd"].values[ok]
    hub_sd = ds["hub_angle_image_sd"].values[ok]
    assert np.all(np.isfinite(tip_sd) & (tip_sd > 0) & np.isfinite(hub_sd) & (hub_sd > 0))
    return tip_err, tip_sd, hub_err, hub_sd


@pytest.mark.slow
def test_another_bench_is_processed_end_to_end(captured: Captured, detected: Processed) -> None:
    ds = detected.results
    ok = ds["frame_ok"].values.astype(bool)
    assert len(ok) == pytest.approx(DURATION_S * 15, abs=2)
    # a few frames state more than the 0.5 mm limit at this contrast and smear (3 to 4 of
    # 45 here): refused, not wrong
    assert ok.mean() >= 0.9, ds.attrs["frames_failed_by_reason"]
    # the hub the frames show is the one drawn (the foreign bench's tolerances)
    assert ds.attrs["hub_length_measured_m"] == pytest.approx(HUB_LENGTH_M, abs=0.5e-3)
    assert ds.attrs["hub_width_measured_m"] == pytest.approx(HUB_WIDTH_M, abs=0.5e-3)
    assert ds.attrs["hub_offset_measured_m"] == pytest.approx(HUB_OFFSET_M, abs=0.2e-3)
    # the latency is found in the data (issue #20: within 2 ms), and every frame lands on
    # its true mid-exposure
    offset = ds.attrs["camera_to_daq_offset_s"]
    assert offset == pytest.approx(-(CAMERA_CLOCK_OFFSET_S + STAMP_LATENCY_S), abs=2e-3)
    t_true, _, _ = captured.truth(ds, detected.frames)
    assert np.max(np.abs(ds["frame_time"].values - t_true)) < 2e-3


@pytest.mark.slow
def test_measured_within_the_stated_uncertainty_with_the_calibration_known(
    captured: Captured, tmp_path: Path
) -> None:
    # the stated uncertainties are the edge fits' (calibration left out, README): with
    # the true calibration every measured frame is within 3 of them
    spec = captured.devices.bench.scene
    plane = spec.registration_points_m()
    cal = Calibration(spec.to_px(plane), plane, spec.camera_matrix, spec.distortion)
    cal_path = tmp_path / "cal.json"
    cal_path.write_text(cal.to_json())
    processed = process_run(captured.log_path, calibration_path=cal_path, workers=2)
    assert processed.results["frame_ok"].values.mean() >= 0.9
    tip_err, tip_sd, hub_err, hub_sd = _errors(captured, processed)
    assert np.max(np.abs(tip_err) / tip_sd) <= 3.0, (tip_err, tip_sd)
    assert np.max(np.abs(hub_err) / hub_sd) <= 3.0, (np.degrees(hub_err), np.degrees(hub_sd))
    # and the stated uncertainty is not a blanket: the RMS error is of its size
    assert math.sqrt(np.mean(tip_err**2)) <= 1.5 * math.sqrt(np.mean(tip_sd**2))


@pytest.mark.slow
def test_measured_within_the_stated_uncertainty_with_the_registration_detected(
    captured: Captured, detected: Processed
) -> None:
    tip_err, tip_sd, hub_err, hub_sd = _errors(captured, detected)
    assert np.max(np.abs(tip_err) / tip_sd) <= 3.0
    assert np.max(np.abs(hub_err) / hub_sd) <= 3.0
