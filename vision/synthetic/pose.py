"""Camera placement relative to the beam plane (for the synthetic camera).

World frame = beam-plane frame (X, Y in the plane, Z = X x Y toward the camera side).
Camera frame: OpenCV (x right, y down, z along the optical axis).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from vision.config import CameraPoseConfig


def _axis_rotation(axis: NDArray[np.float64], angle_rad: float) -> NDArray[np.float64]:
    a = axis / np.linalg.norm(axis)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle_rad) * k + (1 - math.cos(angle_rad)) * (k @ k)


def camera_extrinsics(pose: CameraPoseConfig) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """World-to-camera rotation ``R`` (3, 3) and translation ``t`` (3,): ``x_cam = R X + t``.

    Untilted, the camera looks down the plane normal with image x along +X and image y
    along -Y (so the plane appears as seen from +Z, not mirrored).
    """
    az = pose.tilt_azimuth_rad
    tilt = _axis_rotation(np.array([math.cos(az), math.sin(az), 0.0]), pose.tilt_rad)
    axes0 = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]]).T  # columns
    cr, sr = math.cos(pose.roll_rad), math.sin(pose.roll_rad)
    roll = np.array([[cr, -sr, 0.0], [sr, cr, 0.0], [0.0, 0.0, 1.0]])
    axes = tilt @ axes0 @ roll
    target = np.array([pose.target_m[0], pose.target_m[1], 0.0])
    centre = target + tilt @ np.array([0.0, 0.0, pose.distance_m])
    r = axes.T
    return r, -r @ centre


def ideal_from_plane(
    matrix: NDArray[np.float64], rotation: NDArray[np.float64], translation: NDArray[np.float64]
) -> NDArray[np.float64]:
    """(3, 3) homography from beam-plane metres (X, Y, 1) to undistorted pixels."""
    h = matrix @ np.column_stack([rotation[:, 0], rotation[:, 1], translation])
    return h / h[2, 2]
