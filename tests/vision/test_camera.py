from __future__ import annotations

import numpy as np
import pytest

from vision.camera import (
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
