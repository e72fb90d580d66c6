from __future__ import annotations

import numpy as np
import pytest

from vision.camera import (
    Lens,
    camera_matrix,
    check_intrinsics,
    distort_points_px,
    undistort_points_px,
)

K = camera_matrix(2100.0, 2048, 1536)


@pytest.mark.parametrize(
    "dist",
    [
        [-0.1, 0.0, 0.0, 0.0, 0.0],
        [0.1, -0.05, 0.001, -0.0005, 0.01],
        [0.05, 0.0, 0.0, 0.0],
    ],
)
def test_distortion_round_trip(dist: list[float]) -> None:
    d = np.array(dist)
    rng = np.random.default_rng(0)
    pts = rng.uniform([0, 0], [2047, 1535], size=(500, 2))
    ideal = undistort_points_px(pts, K, d)
    again = distort_points_px(ideal, K, d)
    np.testing.assert_allclose(again, pts, atol=1e-6)


def test_radial_distortion_moves_points_as_the_model_says() -> None:
    # k1 only: r_d = r (1 + k1 r^2) in normalized coordinates.
    k1 = -0.1
    x = np.array([[0.3, 0.2]])
    r2 = float(np.sum(x**2))
    ideal_px = x * 2100 + K[:2, 2]
    got = distort_points_px(ideal_px, K, np.array([k1, 0, 0, 0, 0.0]))
    np.testing.assert_allclose(got, x * (1 + k1 * r2) * 2100 + K[:2, 2], atol=1e-9)


@pytest.mark.parametrize(
    "dist",
    [
        [-0.1, 0.0, 0.0, 0.0, 0.0],
        [0.1, -0.05, 0.001, -0.0005, 0.01],
        [0.1, -0.05, 0.0, 0.0, 0.01, 0.02, -0.01, 0.005],
        [0.1, -0.05, 0.001, -0.0005, 0.01, 0.02, -0.01, 0.005, 0.001, -0.002, 0.003, 0.0005],
        [0.05, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.01, -0.02],  # tilt
    ],
)
def test_the_measurers_lens_is_opencvs_model(dist: list[float]) -> None:
    d = np.array(dist)
    rng = np.random.default_rng(1)
    # The image and a margin around it (points a measurement maps may lie outside).
    pts = rng.uniform([-200, -200], [2247, 1735], size=(3000, 2))
    lens = Lens(K, d)
    np.testing.assert_allclose(lens.distort(pts), distort_points_px(pts, K, d), atol=1e-9)
    np.testing.assert_allclose(lens.undistort(pts), undistort_points_px(pts, K, d), atol=1e-9)
    skewed = K.copy()
    skewed[0, 1] = 3.0  # OpenCV's own treatment of skew: handed to it
    np.testing.assert_array_equal(Lens(skewed, d).distort(pts), distort_points_px(pts, skewed, d))
    np.testing.assert_array_equal(Lens(K, np.zeros(5)).undistort(pts), pts)


def test_no_distortion_is_the_identity() -> None:
    pts = np.array([[1.0, 2.0], [1000.0, 700.0]])
    np.testing.assert_array_equal(undistort_points_px(pts, None, None), pts)
    np.testing.assert_array_equal(undistort_points_px(pts, K, np.zeros(5)), pts)


def test_bad_intrinsics_are_refused() -> None:
    with pytest.raises(ValueError, match="3x3"):
        check_intrinsics(np.eye(2), None)
    with pytest.raises(ValueError, match="coefficients"):
        check_intrinsics(K, np.zeros(3))
    with pytest.raises(ValueError, match="needs a camera matrix"):
        check_intrinsics(None, np.array([0.1, 0, 0, 0]))
    with pytest.raises(ValueError, match="focal_length_px"):
        camera_matrix(-1.0, 10, 10)


def test_checkerboard_calibration_recovers_the_focal_length() -> None:
    """Views of a flat 9x6 board through a known pinhole camera (homography warps)."""
    import math

    import cv2

    from vision.camera import calibrate_checkerboard
    from vision.config import CameraPoseConfig
    from vision.synthetic.pose import camera_extrinsics, ideal_from_plane

    sq_px, cols, rows = 40, 10, 7  # squares; 9 x 6 inner corners
    board = np.kron((np.indices((rows, cols)).sum(axis=0) % 2), np.ones((sq_px, sq_px)))
    board = np.pad(board * 200 + 30, sq_px, constant_values=230).astype(np.uint8)
    k = camera_matrix(900.0, 800, 600)
    sq_m = 0.03
    # board pixel (u, v) -> plane metres, centred
    to_m = np.array(
        [
            [sq_m / sq_px, 0, -sq_m * (cols / 2 + 1)],
            [0, -sq_m / sq_px, sq_m * (rows / 2 + 1)],
            [0, 0, 1],
        ]
    )
    views = []
    for tilt, az in ((0.3, 0.0), (0.4, 1.6), (0.35, 3.0), (0.45, 4.4), (0.25, 5.5)):
        pose = CameraPoseConfig(
            distance_m=0.9, target_m=(0.0, 0.0), tilt_rad=tilt, tilt_azimuth_rad=az
        )
        r, t = camera_extrinsics(pose)
        h = ideal_from_plane(k, r, t) @ to_m
        views.append(
            cv2.warpPerspective(board, h, (800, 600), flags=cv2.INTER_AREA, borderValue=230)
        )
    mat, dist, rms = calibrate_checkerboard(views, (cols - 1, rows - 1), sq_m)
    assert abs(dist[0]) < 0.1  # no lens distortion was applied (k2 is ill-determined here)
    assert rms < 0.5
    assert mat[0, 0] == pytest.approx(900.0, rel=0.02)
    assert mat[1, 1] == pytest.approx(900.0, rel=0.02)
    assert math.hypot(mat[0, 2] - 399.5, mat[1, 2] - 299.5) < 15
    with pytest.raises(ValueError, match="at least 3"):
        calibrate_checkerboard(views[:2], (cols - 1, rows - 1), sq_m)
