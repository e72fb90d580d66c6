"""Fuzz fixtures: one rendered frame of the synthetic bench with its true calibration,
made with beambench's renderer but a camera and pose that differ from the defaults."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:  # tests.fuzz.contract, however pytest was started
    sys.path.insert(0, str(ROOT))


@pytest.fixture(scope="session")
def frame_files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    from vision import Calibration
    from vision.codec import encode
    from vision.config import CameraConfig, CameraPoseConfig, RegistrationConfig
    from vision.synthetic.render import render_frame
    from vision.synthetic.scene import BeamPose, SceneSpec

    d = tmp_path_factory.mktemp("fuzz-frame")
    spec = SceneSpec.from_rig(
        CameraConfig(width_px=1280, height_px=960, focal_length_px=1300.0),
        CameraPoseConfig(tilt_rad=math.radians(20.0), roll_rad=math.radians(3.0)),
        RegistrationConfig(),
        beam_length_m=0.835,
        beam_width_m=0.01905,
        hub_offset_m=0.008,
        noise_dn=3.0,
    )
    pose = BeamPose.from_slope(math.radians(285), 0.835, lambda s: 0.04 * (2 * s / 0.835))
    frame = render_frame(spec, [pose])
    tr = frame.truth
    cal = Calibration(tr.corners_px, tr.plane_points_m, tr.camera_matrix, tr.distortion)
    (d / "cal.json").write_text(cal.to_json())
    (d / "frame.jpg").write_bytes(encode(frame.image, "jpeg", 92))
    (d / "frame.png").write_bytes(encode(frame.image, "png"))
    (d / "truth.json").write_text(json.dumps({"tip_lateral_m": tr.tip_lateral_m}))
    return {p.name: p for p in d.iterdir()}
