from __future__ import annotations

import math

import numpy as np
import pytest

from vision.errors import BehindCameraError
from vision.synthetic.scene import BeamMotion, BeamPose


def test_truth_of_a_bent_beam(vt) -> None:
    pose = vt.bent(0.0, 0.1)
    lat, lon = pose.at(np.array([vt.L_M]))
    # Cubic shape of slope th_L(2 s/L - s^2/L^2): w(L) = 2/3 th_L L for small slopes.
    assert lat[0] == pytest.approx(2 / 3 * 0.1 * vt.L_M, rel=5e-3)
    assert -0.01 < lon[0] < 0  # pulled in, inextensible
    s = np.linspace(0, vt.L_M, 200)
    la, lo = pose.at(s)
    arc = np.sum(np.hypot(np.diff(s + lo), np.diff(la)))
    assert arc == pytest.approx(vt.L_M, rel=1e-6)


def test_bad_poses_and_scenes_are_refused(vt) -> None:
    with pytest.raises(ValueError, match="stations_m"):
        BeamPose(0.0, np.array([0.0]), np.zeros(1), np.zeros(1))
    with pytest.raises(ValueError, match="lateral_m"):
        BeamPose(0.0, np.array([0.0, 1.0]), np.zeros(3), np.zeros(2))
    with pytest.raises(ValueError, match="hub_width_m"):
        vt.make_spec(hub_width_m=vt.W_M / 2)


def test_the_exact_projection_refuses_points_behind_the_camera(clean_spec) -> None:
    """The camera is tilted about the plane's X axis: far enough along Y on one side,
    the plane lies behind it (beyond the horizon)."""
    near = clean_spec.to_px(np.array([[0.0, 0.0], [0.1, -0.2]]))
    assert near.shape == (2, 2) and np.all(np.isfinite(near))
    with pytest.raises(BehindCameraError):
        clean_spec.to_px(np.array([[0.0, 1e4], [0.0, -1e4]]))


def test_an_exposure_samples_the_motion_at_slice_midpoints(vt) -> None:
    """A hub turning at w for T moves the tip w (offset + L) T across the beam; the
    exposure's poses are the midpoints of equal slices, symmetric about mid-exposure, so
    their mean is the mid-exposure pose for a motion linear in time."""
    pose = vt.bent(1.0, 0.05)
    rate = np.full(pose.stations_m.shape, 0.3) * pose.stations_m / vt.L_M
    motion = BeamMotion(pose, 2.0, rate)
    assert motion.tip_smear_m(0.01, 0.008) == pytest.approx(
        (2.0 * (0.008 + vt.L_M + pose.longitudinal_m[-1]) + 0.3) * 0.01
    )
    poses = motion.exposure_poses(0.01, 0.008, max_step_m=1e-3)
    assert len(poses) == math.ceil(motion.tip_smear_m(0.01, 0.008) / 1e-3)
    assert np.mean([p.hub_angle_rad for p in poses]) == pytest.approx(1.0, abs=1e-12)
    span = poses[-1].hub_angle_rad - poses[0].hub_angle_rad
    assert span == pytest.approx(2.0 * 0.01 * (1 - 1 / len(poses)))
    np.testing.assert_allclose(np.mean([p.lateral_m for p in poses], axis=0), pose.lateral_m)
    assert len(BeamMotion(pose).exposure_poses(0.01, 0.008)) == 1  # a still beam
    with pytest.raises(ValueError, match="lateral_rate_m_s"):
        BeamMotion(pose, 0.0, np.zeros(3))
    with pytest.raises(ValueError, match="exposure_s"):
        motion.exposure_poses(-1.0, 0.008)
