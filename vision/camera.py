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

from vision.errors import CalibrationError, ParameterError

_UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-14)


def camera_matrix(focal_length_px: float, width_px: int, height_px: int) -> NDArray[np.float64]:
    """The 3x3 intrinsic matrix of a camera with square pixels, principal point at the
    image centre ``((width_px - 1) / 2, (height_px - 1) / 2)``."""
    if not np.isfinite(focal_length_px) or focal_length_px <= 0:
        raise ParameterError("focal_length_px", f"must be positive, got {focal_length_px!r}")
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
        raise ParameterError(name, f"must have shape (N, 2), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ParameterError(name, "must be finite")
    return arr


def check_intrinsics(
    matrix: ArrayLike | None, distortion: ArrayLike | None
) -> tuple[NDArray[np.float64] | None, NDArray[np.float64] | None]:
    """Validate a camera matrix (3, 3) and distortion (4, 5, 8, 12 or 14 coefficients)."""
    k = None
    if matrix is not None:
        k = np.asarray(matrix, dtype=np.float64)
        if k.shape != (3, 3) or not np.all(np.isfinite(k)):
            raise ParameterError(
                "camera matrix", f"must be a finite 3x3 array, got shape {k.shape}"
            )
        if k[0, 0] <= 0 or k[1, 1] <= 0 or abs(k[2, 2] - 1.0) > 1e-9 or np.any(k[2, :2] != 0):
            raise ParameterError(
                "camera matrix", "must be [[fx, s, cx], [0, fy, cy], [0, 0, 1]], fx, fy > 0"
            )
    d = None
    if distortion is not None:
        d = np.asarray(distortion, dtype=np.float64).ravel()
        if d.size == 0:
            return k, None
        if d.size not in (4, 5, 8, 12, 14) or not np.all(np.isfinite(d)):
            raise ParameterError(
                "distortion",
                f"must have 4, 5, 8, 12 or 14 finite OpenCV coefficients, got {d.size}",
            )
        if k is None and np.any(d != 0):
            raise ParameterError("distortion", "needs a camera matrix")
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
        raise ParameterError("square_m", f"must be positive, got {square_m!r}")
    if len(images) < 3:
        raise ParameterError("images", f"must hold at least 3 views, got {len(images)}")
    cols, rows = pattern_size
    grid = np.zeros((cols * rows, 3), np.float32)
    grid[:, :2] = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2) * square_m
    obj, img = [], []
    shape: tuple[int, int] = (0, 0)
    for i, im in enumerate(images):
        if im.ndim != 2 or im.dtype != np.uint8:
            raise ParameterError(f"images[{i}]", "must be a uint8 [row, col] gray image")
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
        raise CalibrationError(
            f"the checkerboard was found in only {len(obj)} of {len(images)} images"
        )
    rms, k, d, _, _ = cv2.calibrateCamera(obj, img, shape, None, None)
    return np.asarray(k, float), np.asarray(d, float).ravel(), float(rms)


class Lens:
    """One camera's lens distortion for the per-frame measurement: the same OpenCV model
    as :func:`distort_points_px` / :func:`undistort_points_px`, evaluated in numpy.

    A frame's measurement maps a few thousand points through the lens in a dozen small
    batches. ``cv2.projectPoints`` also computes its (N, 15) Jacobian on every call
    (about half a microsecond a point) and ``cv2.undistortPoints`` iterates point by
    point to 1e-14 (about 4 us a point): together they were a third of a distorted
    frame's time. Here the forward model (radial k1..k6, tangential p1 p2, thin prism
    s1..s4) is closed form and its inverse is Newton's method from a first-order start
    (quadratic convergence: four steps take an image point to rounding level). Points
    that do not converge (far outside the image, where the model folds over), sensor
    tilt (tau x, tau y) and a skewed camera matrix go to OpenCV, so the result is that
    of the functions above everywhere.
    """

    #: Newton steps of the inverse (at most; it stops once the steps are at rounding
    #: level); a point still off by more than ``_TOL`` (normalized units, ~1e-9 px) after
    #: them is handed to OpenCV.
    _STEPS = 6
    _TOL = 1e-12

    def __init__(
        self, matrix: NDArray[np.float64] | None, distortion: NDArray[np.float64] | None
    ) -> None:
        self.matrix = matrix
        self.distortion = distortion
        self.identity = matrix is None or distortion is None or not np.any(distortion)
        c = np.zeros(14)
        if distortion is not None:
            c[: len(distortion)] = distortion
        self._numpy = not self.identity and matrix is not None and matrix[0, 1] == 0.0
        self._numpy = self._numpy and c[12] == 0.0 and c[13] == 0.0
        self._c = c
        # Radial terms only (no tangential or thin-prism terms): a cheaper inverse.
        self._radial = not np.any(c[[2, 3, 8, 9, 10, 11]])
        if matrix is not None:
            self._f = np.array([matrix[0, 0], matrix[1, 1]])
            self._pp = np.array([matrix[0, 2], matrix[1, 2]])

    @property
    def distorts_pointwise(self) -> bool:
        """Whether :meth:`distort` maps each point by its own arithmetic (no lens, or its
        formula here), so one call for many points gives, bit for bit, what a call for
        each few would; through OpenCV (a matrix product over the call) it is not promised."""
        return self.identity or self._numpy

    def distort(self, ideal_px: NDArray[np.float64]) -> NDArray[np.float64]:
        """Ideal (undistorted) pixels (N, 2) -> observed pixels (N, 2)."""
        pts = np.asarray(ideal_px, dtype=np.float64).reshape(-1, 2)
        if self.identity or len(pts) == 0:
            return pts.copy()
        if not self._numpy:
            return distort_points_px(pts, self.matrix, self.distortion)
        (fx, fy), (cx, cy) = self._f, self._pp
        # x and y apart: operations on (N, 2) arrays loop over rows of two.
        x, y = (pts[:, 0] - cx) / fx, (pts[:, 1] - cy) / fy
        out = np.empty_like(pts)
        if self._radial:
            rad = self._radial_factor(x * x + y * y)
            out[:, 0], out[:, 1] = x * rad * fx + cx, y * rad * fy + cy
        else:
            xy = self._model(x, y)[0]
            out[:, 0], out[:, 1] = xy[:, 0] * fx + cx, xy[:, 1] * fy + cy
        return out

    def undistort(self, points_px: NDArray[np.float64]) -> NDArray[np.float64]:
        """Observed pixels (N, 2) -> ideal pixels (N, 2)."""
        pts = np.asarray(points_px, dtype=np.float64).reshape(-1, 2)
        if self.identity or len(pts) == 0:
            return pts.copy()
        if not self._numpy:
            return undistort_points_px(pts, self.matrix, self.distortion)
        (fx, fy), (cx, cy) = self._f, self._pp
        tx, ty = (pts[:, 0] - cx) / fx, (pts[:, 1] - cy) / fy
        if self._radial:
            x, y, err = self._undistort_radial(tx, ty)
        else:
            x, y, err = self._undistort_general(tx, ty)
        out = np.empty_like(pts)
        out[:, 0], out[:, 1] = x * fx + cx, y * fy + cy
        bad = ~(err < self._TOL)
        if bad.any():
            out[bad] = undistort_points_px(pts[bad], self.matrix, self.distortion)
        return np.asarray(out)

    def _radial_factor(self, r2: NDArray[np.float64]) -> NDArray[np.float64]:
        """The radial factor at squared normalized radius ``r2``."""
        k1, k2, _p1, _p2, k3, k4, k5, k6 = self._c[:8]
        rad = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        if k4 or k5 or k6:
            rad = rad / (1.0 + r2 * (k4 + r2 * (k5 + r2 * k6)))
        return rad

    def _undistort_radial(
        self, tx: NDArray[np.float64], ty: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Radial terms only: the ideal point is the distorted one scaled by ``s`` with
        ``s rad(s^2 rd^2) = 1``, a scalar equation per point."""
        k1, k2, _p1, _p2, k3, k4, k5, k6 = self._c[:8]
        rational = bool(k4 or k5 or k6)
        rd2 = tx * tx + ty * ty
        s = np.ones_like(rd2)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            for _ in range(self._STEPS):
                r2 = s * s * rd2
                rad = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
                drad = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2)
                if rational:
                    den = 1.0 + r2 * (k4 + r2 * (k5 + r2 * k6))
                    rad = rad / den
                    drad = (drad - rad * (k4 + r2 * (2.0 * k5 + 3.0 * k6 * r2))) / den
                # h(s) = s rad - 1, h'(s) = rad + 2 r2 drad / dr2.
                step = (s * rad - 1.0) / (rad + 2.0 * r2 * drad)
                s = s - step
                if not np.any(np.abs(step) > 1e-15):
                    break
            err = np.abs(s * self._radial_factor(s * s * rd2) - 1.0) * np.sqrt(rd2)
        return tx * s, ty * s, err

    def _undistort_general(
        self, tx: NDArray[np.float64], ty: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """All terms: 2-D Newton from the point divided by its radial factor."""
        rad = self._radial_factor(tx * tx + ty * ty)
        x, y = tx / rad, ty / rad
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            for _ in range(self._STEPS):
                (fxy, _r, jac) = self._model(x, y, jacobian=True)
                ex, ey = fxy[:, 0] - tx, fxy[:, 1] - ty
                a, b, c, d = jac
                det = a * d - b * c
                dx, dy = (d * ex - b * ey) / det, (a * ey - c * ex) / det
                x, y = x - dx, y - dy
                if not (np.any(np.abs(dx) > 1e-15) or np.any(np.abs(dy) > 1e-15)):
                    break
        fxy = self._model(x, y)[0]
        err = np.abs(fxy[:, 0] - tx) + np.abs(fxy[:, 1] - ty)
        return x, y, err

    def _model(
        self, x: NDArray[np.float64], y: NDArray[np.float64], jacobian: bool = False
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], tuple[NDArray[np.float64], ...]]:
        """Distorted normalized points (N, 2), the radial factor and, with ``jacobian``,
        the four partial derivatives (dxd/dx, dxd/dy, dyd/dx, dyd/dy)."""
        k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4 = self._c[:12]
        r2 = x * x + y * y
        num = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        den = 1.0 + r2 * (k4 + r2 * (k5 + r2 * k6))
        rad = num / den
        xy2 = 2.0 * x * y
        xd = x * rad + p1 * xy2 + p2 * (r2 + 2.0 * x * x) + r2 * (s1 + s2 * r2)
        yd = y * rad + p1 * (r2 + 2.0 * y * y) + p2 * xy2 + r2 * (s3 + s4 * r2)
        out = np.column_stack([xd, yd])
        if not jacobian:
            return out, rad, ()
        # d rad / d r2, then the chain rule through r2 = x^2 + y^2.
        dnum = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2)
        dden = k4 + r2 * (2.0 * k5 + 3.0 * k6 * r2)
        drad2 = 2.0 * (dnum - rad * dden) / den  # 2 d rad / d r2
        px_ = 2.0 * (s1 + 2.0 * s2 * r2)  # d(thin prism x) / d r2, doubled
        py_ = 2.0 * (s3 + 2.0 * s4 * r2)
        a = rad + x * x * drad2 + 2.0 * p1 * y + 6.0 * p2 * x + px_ * x
        b = x * y * drad2 + 2.0 * p1 * x + 2.0 * p2 * y + px_ * y
        c = x * y * drad2 + 2.0 * p1 * x + 2.0 * p2 * y + py_ * x
        d = rad + y * y * drad2 + 6.0 * p1 * y + 2.0 * p2 * x + py_ * y
        return out, rad, (a, b, c, d)
