"""The hub as the frames show it beside the rig's hints: recorded, printed, and a warning
when the clamp is not where the rig's hub_offset_m (which the simulation uses) says."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from pipelines.process.hub import hub_attrs, hub_line, measured_hub, offset_warning
from pipelines.rig import load_rig
from vision import Calibration, FrameMeasurement
from vision.config import CameraConfig, CameraPoseConfig, RegistrationConfig
from vision.synthetic.scene import SceneSpec


@pytest.fixture(scope="module")
def calibration() -> Calibration:
    spec = SceneSpec.from_rig(
        CameraConfig(),
        CameraPoseConfig(),
        RegistrationConfig(),
        beam_length_m=0.835,
        beam_width_m=0.01905,
        hub_offset_m=0.008,
    )
    plane = spec.registration_points_m()
    return Calibration(spec.to_px(plane), plane, spec.camera_matrix, spec.distortion)


def _frame(cal: Calibration, angle: float, offset_m: float, length_m: float) -> FrameMeasurement:
    e = np.array([np.cos(angle), np.sin(angle)])
    clamp = offset_m * e
    back = clamp - length_m * e
    return FrameMeasurement(
        ok=True,
        hub_line_px=cal.to_px(np.vstack([back, clamp])),
        clamp_plane_m=clamp,
        hub_width_m=0.051,
    )


def test_the_measured_hub_is_the_frames_median(calibration: Calibration) -> None:
    frames = [_frame(calibration, np.radians(a), 0.0081, 0.068) for a in (250, 280, 310)]
    frames.append(FrameMeasurement(ok=False, reason="x"))
    hub = measured_hub(frames, calibration)
    assert hub["hub_length_measured_m"] == pytest.approx(0.068, abs=1e-9)
    assert hub["hub_width_measured_m"] == 0.051
    assert hub["hub_offset_measured_m"] == pytest.approx(0.0081, abs=1e-12)
    rig = load_rig()
    line = hub_line(hub_attrs(hub, rig), rig.beam.hub_offset_m)
    assert line == (
        "hub measured 68.0 x 51.0 mm, clamp 8.10 mm from the pivot (rig: hints 68 x 51 mm, "
        "hub_offset_m 8.00 mm)"
    )
    assert offset_warning(hub, rig) is None  # 0.1 mm: within what a face is found to
    assert measured_hub([FrameMeasurement(ok=False)], calibration) == {}
    assert hub_line(hub_attrs({}, rig), 0.008) is None


def test_a_clamp_elsewhere_than_the_rigs_offset_is_a_warning(calibration: Calibration) -> None:
    frames = [_frame(calibration, np.radians(a), 0.0125, 0.2) for a in (250, 280, 310)]
    hub = measured_hub(frames, calibration)
    rig = load_rig()
    note = offset_warning(hub, rig)
    assert note is not None and "12.50 mm from the pivot" in note and "8.00 mm" in note
    assert "--rig" in note
    moved = dataclasses.replace(rig, beam=dataclasses.replace(rig.beam, hub_offset_m=0.012))
    assert offset_warning(hub, moved) is None


def test_frames_that_did_not_measure_the_hubs_width_are_left_out_of_it_and_counted(
    calibration: Calibration,
) -> None:
    """A frame whose hub edges are no straight lines (a bar lying against one) reports
    the width NaN: the run's width is the median of the others, the line says how many,
    and none measuring it gives NaN, not a warning (pytest runs warnings as errors)."""
    frames = [_frame(calibration, np.radians(a), 0.0081, 0.068) for a in (250, 280, 310)]
    frames[1] = dataclasses.replace(frames[1], hub_width_m=float("nan"))
    frames[2] = dataclasses.replace(frames[2], hub_width_m=0.052)
    hub = measured_hub(frames, calibration)
    assert hub["hub_width_measured_m"] == pytest.approx(0.0515, abs=1e-12)
    assert (hub["hub_width_measured_frames"], hub["hub_measured_frames"]) == (2, 3)
    rig = load_rig()
    line = hub_line(hub_attrs(hub, rig), rig.beam.hub_offset_m)
    assert line is not None and "68.0 x 51.5 mm (the width on 2 of 3 frames)" in line
    none = [dataclasses.replace(f, hub_width_m=float("nan")) for f in frames]
    hub = measured_hub(none, calibration)
    assert np.isnan(hub["hub_width_measured_m"]) and hub["hub_width_measured_frames"] == 0
    line = hub_line(hub_attrs(hub, rig), rig.beam.hub_offset_m)
    assert line is not None and "68.0 mm long (its width on none of 3 frames)" in line
