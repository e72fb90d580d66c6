"""Pinhole camera with OpenCV lens distortion: projection, point undistortion and
checkerboard calibration.

Pixel coordinates are ``(x, y)`` = (column, row) with the centre of the top-left
pixel at ``(0, 0)``; point arrays are ``(N, 2)``.
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

_UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-14)


def camera_matrix(focal_length_px: float, width_px: int, height_px: int) -> NDArray[np.float64]:
    """The 3x3 intrinsic matrix of a camera with square pixels, principal point at the
    image centre ``((width_px - 1) / 2, (height_px - 1) / 2)``."""
    if not np.isfinite(focal_length_px) or focal_length_px <= 0:
        raise ValueError(f"focal_length_px must be positive, got {focal_length_px!r}")
    return np.array(
        [
            [focal_length_px, 0.0, (width_px - 1) / 2.0],
            [0.0, focal_length_px, (height_px - 1) / 2.0],
            [0.0, 0.0, 1.0],
        ]
    )


def as_points(points: ArrayLike, name: str) -> NDArray[np.float64]:
    """Validate an ``(N, 2)`` array of finite points, naming the parameter on error."""
    arr = np.asarray(points, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise ValueError(f"{name} must have shape (N, 2), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite")
    return arr


def check_intrinsics(
    matrix: ArrayLike | None, distortion: ArrayLike | None
) -> tuple[NDArray[np.float64] | None, NDArray[np.float64] | None]:
    """Validate a camera matrix (3, 3) and distortion (4, 5, 8, 12 or 14 coefficients)."""
    k = None
    if matrix is not None:
        k = np.asarray(matrix, dtype=np.float64)
        if k.shape != (3, 3) or not np.all(np.isfinite(k)):
            raise ValueError(f"camera matrix must be a finite 3x3 array, got shape {k.shape}")
        if k[0, 0] <= 0 or k[1, 1] <= 0 or abs(k[2, 2] - 1.0) > 1e-9 or np.any(k[2, :2] != 0):
            raise ValueError(
                "camera matrix must be [[fx, s, cx], [0, fy, cy], [0, 0, 1]], fx, fy > 0"
            )
    d = None
    if distortion is not None:
        d = np.asarray(distortion, dtype=np.float64).ravel()
        if d.size == 0:
            return k, None
        if d.size not in (4, 5, 8, 12, 14) or not np.all(np.isfinite(d)):
            raise ValueError(
                f"distortion must have 4, 5, 8, 12 or 14 finite OpenCV coefficients, got {d.size}"
            )
        if k is None and np.any(d != 0):
            raise ValueError("distortion needs a camera matrix")
    return k, d


def distort_normalized(
    xy: ArrayLike, matrix: NDArray[np.float64], distortion: NDArray[np.float64] | None
) -> NDArray[np.float64]:
    """Pixel coordinates ``(N, 2)`` of ideal normalized image points ``(N, 2)``
    (x/z, y/z in the camera frame) through ``matrix`` and ``distortion``."""
    pts = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    if pts.shape[0] == 0:
        return np.zeros((0, 2))
    obj = np.column_stack([pts, np.ones(len(pts))])
    dist = np.zeros(5) if distortion is None else distortion
    out, _ = cv2.projectPoints(obj, np.zeros(3), np.zeros(3), matrix, dist)
    return np.asarray(out, dtype=np.float64).reshape(-1, 2)


def undistort_points_px(
    points_px: ArrayLike,
    matrix: NDArray[np.float64] | None,
    distortion: NDArray[np.float64] | None,
) -> NDArray[np.float64]:
    """Remove lens distortion from pixel points ``(N, 2)``; the result is in pixels of
    the ideal (distortion-free) camera with the same matrix. Identity without distortion."""
    pts = np.asarray(points_px, dtype=np.float64).reshape(-1, 2)
    if matrix is None or distortion is None or not np.any(distortion) or len(pts) == 0:
        return pts.copy()
    out = cv2.undistortPoints(
        pts.reshape(-1, 1, 2), matrix, distortion, None, matrix, criteria=_UNDISTORT_CRITERIA
    )
    return np.asarray(out, dtype=np.float64).reshape(-1, 2)


def distort_points_px(
    points_px: ArrayLike,
    matrix: NDArray[np.float64] | None,
    distortion: NDArray[np.float64] | None,
) -> NDArray[np.float64]:
    """Inverse of :func:`undistort_points_px`: ideal pixels ``(N, 2)`` to observed pixels."""
    pts = np.asarray(points_px, dtype=np.float64).reshape(-1, 2)
    if matrix is None or distortion is None or not np.any(distortion) or len(pts) == 0:
        return pts.copy()
    kinv = np.linalg.inv(matrix)
    norm = pts @ kinv[:2, :2].T + kinv[:2, 2]
    return distort_normalized(norm, matrix, distortion)


def calibrate_checkerboard(
    images: Sequence[NDArray[np.uint8]],
    pattern_size: tuple[int, int],
    square_m: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """Intrinsics and distortion from checkerboard views.

    Parameters
    ----------
    images : sequence of uint8 [row, col] gray images, at least 3 views.
    pattern_size : (columns, rows) of inner corners.
    square_m : checker square side, m.

    Returns
    -------
    matrix : (3, 3), distortion : (5,) OpenCV order, rms_px : reprojection RMS, px.
    """
    if square_m <= 0:
        raise ValueError(f"square_m must be positive, got {square_m!r}")
    if len(images) < 3:
        raise ValueError(f"images must hold at least 3 views, got {len(images)}")
    cols, rows = pattern_size
    grid = np.zeros((cols * rows, 3), np.float32)
    grid[:, :2] = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2) * square_m
    obj, img = [], []
    shape: tuple[int, int] = (0, 0)
    for i, im in enumerate(images):
        if im.ndim != 2 or im.dtype != np.uint8:
            raise ValueError(f"images[{i}] must be a uint8 [row, col] gray image")
        shape = (im.shape[1], im.shape[0])
        found, corners = cv2.findChessboardCorners(im, (cols, rows))
        if not found:
            continue
        corners = cv2.cornerSubPix(
            im,
            corners,
            (5, 5),
            (-1, -1),
            (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-4),
        )
        obj.append(grid)
        img.append(corners)
    if len(obj) < 3:
        raise ValueError(f"the checkerboard was found in only {len(obj)} of {len(images)} images")
    rms, k, d, _, _ = cv2.calibrateCamera(obj, img, shape, None, None)
    return np.asarray(k, float), np.asarray(d, float).ravel(), float(rms)
