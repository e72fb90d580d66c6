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


def test_an_exposure_is_sliced_by_its_fastest_point_not_its_tip(vt) -> None:
    """The hub turning one way and the beam's first mode the other so that the tip stands
    still: mid-beam still moves across the beam, and no point may move more than a step
    in a slice (one slice, as when the tip set the count, would render it unsmeared)."""
    pose = vt.bent(1.0, 0.05)
    radius = 0.008 + pose.stations_m + pose.longitudinal_m
    x = pose.stations_m / vt.L_M
    shape = x**2 * (6 - 4 * x + x**2) / 3  # 1 at the tip
    motion = BeamMotion(pose, 2.0, -2.0 * radius[-1] * shape)
    assert motion.tip_smear_m(0.01, 0.008) == pytest.approx(0.0, abs=1e-12)
    fastest = np.max(np.abs(2.0 * radius - 2.0 * radius[-1] * shape))
    assert motion.fastest_speed_m_s(0.008) == pytest.approx(fastest)
    poses = motion.exposure_poses(0.01, 0.008, max_step_m=1e-3)
    assert len(poses) == math.ceil(fastest * 0.01 / 1e-3) > 1
    lateral = [radius * p.hub_angle_rad + p.lateral_m for p in poses]  # small turns
    assert np.max(np.abs(np.diff(lateral, axis=0))) <= 1e-3 + 1e-12


def _linear_deflection(pose: BeamPose) -> tuple[np.ndarray, np.ndarray]:
    """The linear theory's deflection int theta of an inextensible pose, at its stations."""
    s = pose.stations_m
    th = np.arctan2(np.gradient(pose.lateral_m, s), np.gradient(s + pose.longitudinal_m, s))
    return s, np.concatenate([[0.0], np.cumsum(0.5 * (th[1:] + th[:-1]) * np.diff(s))])


def test_a_uniform_load_bends_the_beam_into_the_closed_form(vt) -> None:
    """Under a uniform load a clamped-free Euler-Bernoulli beam deflects as
    w = w_L x^2 (6 - 4 x + x^2) / 3 (x = s / L; Timoshenko's table): the integration
    from the free end gives it to the trapezoid rule's error (h^2, ~1e-7 here)."""
    pose = BeamPose.from_load(0.0, vt.L_M, lambda s: np.ones_like(s), 0.03)
    s, w = _linear_deflection(pose)
    x = s / vt.L_M
    np.testing.assert_allclose(w, 0.03 * x**2 * (6 - 4 * x + x**2) / 3, atol=3e-8)
    with pytest.raises(ValueError, match="load"):
        BeamPose.from_load(0.0, vt.L_M, lambda s: np.zeros_like(s), 0.03)


def test_a_modes_inertial_load_gives_the_mode_back(vt) -> None:
    """A vibrating cantilever's mode i carries the inertial load beta_i^4 phi_i: its
    static response is phi_i itself. The integration from the free end (the renderer)
    and the closed-form mode shapes (the measurement's basis) agree to 1e-6 of the
    shape's size: the two are written independently."""
    from vision.centreline import cantilever_eigenvalues, cantilever_modes_t

    L = vt.L_M
    for i, beta in enumerate(cantilever_eigenvalues(4)):
        pose = BeamPose.from_load(
            0.0, L, lambda s, i=i: cantilever_modes_t(s / L, i + 1)[i], 0.01, n=8001
        )
        s, w = _linear_deflection(pose)
        phi = cantilever_modes_t(s / L, i + 1)[i]
        phi *= 0.01 / phi[np.argmax(np.abs(phi))]
        assert np.max(np.abs(w - phi)) < 1e-8 * (1 + beta**2), (i, np.max(np.abs(w - phi)))
