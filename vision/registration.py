"""Automatic detection of the registration object (paper §4.3): a light plate in the
beam plane with two orthogonal dark grooves crossing in a square of known side.

The grooves cut the plate into four light quadrants; their inner corners are the
crossing square's corners. Each groove edge is refined to sub-pixel accuracy along its
whole visible length and fitted as a straight line in undistorted pixels; the corners are
the intersections of those lines. The plate's eight straight edges then fix the plane's
mapping (:mod:`vision.plane_pose`): the camera's pose when its intrinsics are known, a
free homography otherwise, with the fit's covariance.

Corner order: the symmetric object does not say which corner is which. The plate is
taken to be seen from its front (+Z) side, and the registration object's first-groove
direction (``RegistrationConfig.angle_rad`` from +X) to appear in the image within 45
degrees of ``x_axis_image_rad - angle_rad`` (image angle, from +x toward +y down); the
default 0 means the plane's +X axis points roughly to the image's right.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from itertools import combinations

import cv2
import numpy as np
from numpy.typing import NDArray

from vision.calibration import Calibration
from vision.camera import check_intrinsics, distort_points_px, undistort_points_px
from vision.config import RegistrationConfig
from vision.edges import edge_moment, erf_edge
from vision.errors import ParameterError, RegistrationError
from vision.homography import (
    LineHomographyFit,
    apply_homography,
    collineation_4pt,
    homography_from_lines,
)
from vision.plane_pose import PlaneFit, fit_lines
from vision.sampling import bilinear

log = logging.getLogger(__name__)


def registration_plane_points_m(registration: RegistrationConfig) -> NDArray[np.float64]:
    """(4, 2) corners of the crossing square in the beam plane, CCW, starting at the corner
    at (-s/2, -s/2) of the object's own frame (first groove along its x axis)."""
    h = registration.square_side_m / 2.0
    local = np.array([[-h, -h], [h, -h], [h, h], [-h, h]])
    c, s = math.cos(registration.angle_rad), math.sin(registration.angle_rad)
    return local @ np.array([[c, s], [-s, c]]) + np.asarray(registration.center_m)


def _quads(image: NDArray[np.uint8]) -> list[NDArray[np.float64]]:
    blur = cv2.GaussianBlur(image, (5, 5), 1.0)
    _, binary = cv2.threshold(blur, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    contours, _ = cv2.findContours(binary, cv2.RETR_LIST, cv2.CHAIN_APPROX_SIMPLE)
    out = []
    for c in contours:
        area = cv2.contourArea(c)
        if area < 150:
            continue
        approx = cv2.approxPolyDP(c, 0.04 * cv2.arcLength(c, True), True)
        if len(approx) != 4 or not cv2.isContourConvex(approx):
            continue
        q = approx.reshape(4, 2).astype(np.float64)
        sides = np.linalg.norm(q - np.roll(q, 1, axis=0), axis=1)
        if sides.min() < 0.3 * sides.max():
            continue
        out.append(q)
    return out


def _group(quads: list[NDArray[np.float64]], ratio: float) -> list[NDArray[np.float64]] | None:
    """Four quads of similar size whose nearest corners close a small square."""
    best, best_score = None, math.inf
    areas = [cv2.contourArea(q.astype(np.float32)) for q in quads]
    for idx in combinations(range(len(quads)), 4):
        a = np.array([areas[i] for i in idx])
        if a.max() > 2.5 * a.min():
            continue
        centre = np.mean([quads[i].mean(axis=0) for i in idx], axis=0)
        inner = np.array(
            [quads[i][np.argmin(np.linalg.norm(quads[i] - centre, axis=1))] for i in idx]
        )
        side = np.sqrt(abs(cv2.contourArea(_ccw(inner).astype(np.float32))))
        quad_side = np.sqrt(a.mean())
        if side < 4 or not 0.4 < (quad_side / side) / ratio < 2.5:
            continue
        score = float(np.std(a) / a.mean() + abs(np.log((quad_side / side) / ratio)))
        if score < best_score:
            best, best_score = [quads[i] for i in idx], score
    return best


def _ccw(p: NDArray[np.float64]) -> NDArray[np.float64]:
    c = p.mean(axis=0)
    return p[np.argsort(np.arctan2(p[:, 1] - c[1], p[:, 0] - c[0]))]


def _side_points(
    image: NDArray[np.uint8], a: NDArray[np.float64], b: NDArray[np.float64], inside: NDArray
) -> NDArray[np.float64]:
    """Sub-pixel edge points along the quad side a-b (light inside toward ``inside``)."""
    d = b - a
    length = float(np.linalg.norm(d))
    t = d / length
    nrm = np.array([-t[1], t[0]])
    if (inside - a) @ nrm < 0:
        nrm = -nrm  # nrm points into the light quadrant
    ts = np.arange(0.15 * length, 0.85 * length, 1.0)
    step = 0.25
    offs = np.arange(-8.0, 8.0 + step / 2, step)
    pts = a[None, None, :] + ts[:, None, None] * t + offs[None, :, None] * nrm
    v = bilinear(image, pts.reshape(-1, 2)).reshape(len(ts), len(offs))
    ok = np.all(np.isfinite(v), axis=1)
    diff = np.diff(v[ok], axis=1)  # dark -> light along nrm: positive steps
    if diff.shape[0] == 0:
        return np.zeros((0, 2))
    peak = np.argmax(diff, axis=1)
    c, k, _ = edge_moment(diff, peak, round(4.0 / step))
    off = offs[0] + c * step
    good = np.isfinite(off) & (k > 15)
    base = a + ts[ok][good, None] * t
    return base + off[good, None] * nrm


def _detect_inner(
    image_gray: NDArray[np.uint8],
    registration: RegistrationConfig,
    camera_matrix: NDArray[np.float64] | None = None,
    distortion: NDArray[np.float64] | None = None,
    x_axis_image_rad: float = 0.0,
) -> NDArray[np.float64]:
    """Raw-pixel corners (4, 2) of the crossing square from the quadrants' inner corners."""
    if not isinstance(image_gray, np.ndarray) or image_gray.dtype != np.uint8:
        raise TypeError("image_gray must be a uint8 numpy array")
    if image_gray.ndim != 2:
        raise ParameterError("image_gray", f"must be [row, col], got shape {image_gray.shape}")
    k, d = check_intrinsics(camera_matrix, distortion)
    if float(image_gray.std()) < 2.0:
        raise RegistrationError("blank image", found=False)
    ratio = (
        (registration.plate_side_m - registration.square_side_m) / 2 / registration.square_side_m
    )
    quads = _quads(image_gray)
    group = _group(quads, ratio)
    if group is None:
        raise RegistrationError(
            f"no four light quadrants around a dark cross "
            f"({len(quads)} light quadrilaterals in the image)",
            found=False,
        )
    centre = np.mean([q.mean(axis=0) for q in group], axis=0)
    sides = []  # (ideal-pixel points, direction) of each quadrant side along a groove
    for q in group:
        i = int(np.argmin(np.linalg.norm(q - centre, axis=1)))
        for j in (i - 1, (i + 1) % 4):
            raw = _side_points(image_gray, q[i], q[j], q.mean(axis=0))
            if len(raw) < 5:
                raise RegistrationError("groove edges not visible", found=False)
            sides.append(undistort_points_px(raw, k, d))
    lines = _lines_from_sides(sides)
    corners = []
    for la in lines[0]:
        for lb in lines[1]:
            corners.append(_intersect(la, lb))
    ideal = np.array(corners)
    raw_corners = distort_points_px(ideal, k, d)
    h, w = image_gray.shape
    if (
        np.any(raw_corners < 0)
        or np.any(raw_corners[:, 0] > w - 1)
        or np.any(raw_corners[:, 1] > h - 1)
    ):
        raise RegistrationError("a corner lies off the image", found=True)
    return _order(raw_corners, registration.angle_rad, x_axis_image_rad)


def _fit_line(p: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    c = p.mean(axis=0)
    _, _, vt = np.linalg.svd(p - c, full_matrices=False)
    return c, vt[0]


def _lines_from_sides(sides: list[NDArray[np.float64]]) -> list[list[tuple]]:
    """Merge the 8 side point sets into 4 groove-edge lines, split into 2 directions."""
    fits = [_fit_line(s) for s in sides]
    used: set[int] = set()
    merged = []
    for i in range(len(sides)):
        if i in used:
            continue
        ci, di = fits[i]
        nrm = np.array([-di[1], di[0]])
        best, best_d = None, math.inf
        for j in range(len(sides)):
            if j == i or j in used:
                continue
            cj, dj = fits[j]
            if abs(di[0] * dj[1] - di[1] * dj[0]) > 0.1:
                continue
            dist = abs((cj - ci) @ nrm)
            if dist < best_d:
                best, best_d = j, dist
        if best is None or best_d > 3.0:
            raise RegistrationError("groove edges are not straight lines", found=False)
        used.update((i, best))
        merged.append(_fit_line(np.vstack([sides[i], sides[best]])))
    if len(merged) != 4:
        raise RegistrationError("expected four groove edges", found=False)
    ref = merged[0][1]
    group_a = [m for m in merged if abs(m[1] @ ref) > 0.7]
    group_b = [m for m in merged if abs(m[1] @ ref) <= 0.7]
    if len(group_a) != 2 or len(group_b) != 2:
        raise RegistrationError("grooves are not two crossing pairs", found=False)
    return [group_a, group_b]


def _intersect(la: tuple, lb: tuple) -> NDArray[np.float64]:
    (pa, da), (pb, db) = la, lb
    m = np.column_stack([da, -db])
    t = np.linalg.solve(m, pb - pa)
    return pa + t[0] * da


def _order(corners: NDArray[np.float64], angle_rad: float, x_axis_image_rad: float) -> NDArray:
    c = corners.mean(axis=0)
    # Image y points down: decreasing image angle is CCW in the plane seen from +Z.
    cyc = corners[np.argsort(-np.arctan2(corners[:, 1] - c[1], corners[:, 0] - c[0]))]
    expect = x_axis_image_rad - angle_rad
    want = np.array([math.cos(expect), math.sin(expect)])
    best, best_dot = cyc, -math.inf
    for r in range(4):
        p = np.roll(cyc, -r, axis=0)
        # local +x: from the (-,-),(-,+) side to the (+,-),(+,+) side
        v = 0.5 * (p[1] + p[2]) - 0.5 * (p[0] + p[3])
        dot = float(v @ want / np.linalg.norm(v))
        if dot > best_dot:
            best, best_dot = p, dot
    return best


def _local_to_plane(registration: RegistrationConfig, local: NDArray[np.float64]) -> NDArray:
    c, s = math.cos(registration.angle_rad), math.sin(registration.angle_rad)
    return local @ np.array([[c, s], [-s, c]]) + np.asarray(registration.center_m)


@dataclass(frozen=True)
class Registration:
    """The registration object found in a frame: the 16 corners of its four light
    quadrants in raw pixels (16, 2) and in the beam plane (16, 2), m, and the plane's
    fitted mapping with its covariance (:class:`~vision.plane_pose.PlaneFit`)."""

    image_points_px: NDArray[np.float64]
    plane_points_m: NDArray[np.float64]
    fit: PlaneFit


def detect_registration(
    image_gray: NDArray[np.uint8],
    registration: RegistrationConfig,
    camera_matrix: NDArray[np.float64] | None = None,
    distortion: NDArray[np.float64] | None = None,
    x_axis_image_rad: float = 0.0,
) -> Registration:
    """Find the registration object and fit the plane to its eight straight edges (two
    per groove, four plate borders), each refined along its whole length, which pins the
    mapping over the whole plate rather than only at the crossing square. With the
    camera's intrinsics the plane's pose is fitted (6 degrees of freedom), else a free
    homography (8); a pose the edges reject (wrong intrinsics) falls back to the free
    fit with a warning (:func:`vision.plane_pose.fit_lines`). Raises
    :class:`~vision.errors.RegistrationError` (a ``ValueError``) with the reason."""
    k, d = check_intrinsics(camera_matrix, distortion)
    inner = _detect_inner(image_gray, registration, k, d, x_axis_image_rad)
    hs, hp = registration.square_side_m / 2, registration.plate_side_m / 2
    local_inner = np.array([[-hs, -hs], [hs, -hs], [hs, hs], [-hs, hs]])
    ideal_inner = undistort_points_px(inner, k, d)
    h0 = collineation_4pt(local_inner, ideal_inner).matrix
    levels = (-hp, -hs, hs, hp)
    light_dir = (1.0, -1.0, 1.0, -1.0)  # light side of each level (toward the quadrants)
    segments = ((-hp, -hs), (hs, hp))
    # Dense edge points (about one per pixel) along each of the eight straight edges.
    px_per_m = float(np.linalg.norm(ideal_inner[1] - ideal_inner[0])) / (2 * hs)
    lines_px, plane_lines = [], []
    for axis in (0, 1):
        for level, sign in zip(levels, light_dir, strict=True):
            pts = []
            for lo, hi in segments:
                n_pts = int(np.clip(0.8 * (hi - lo) * px_per_m, 20, 600))
                t = np.linspace(lo + 0.1 * (hi - lo), hi - 0.1 * (hi - lo), n_pts)
                local = np.zeros((len(t), 2))
                local[:, axis] = level
                local[:, 1 - axis] = t
                step = np.zeros(2)
                step[axis] = sign * 0.2 * hs
                pts.append(_refine_line(image_gray, h0, k, d, local, step))
            ideal = undistort_points_px(np.vstack(pts), k, d)
            if len(ideal) < 20:
                raise RegistrationError("plate edges not visible", found=True)
            lines_px.append(ideal)
            line = np.zeros(3)
            line[axis], line[2] = 1.0, -level
            plane_lines.append(line)
    h0_inv = np.asarray(np.linalg.inv(h0), dtype=np.float64)
    fit = homography_from_lines(lines_px, np.array(plane_lines), h0_inv)
    _check_fit(fit, k)
    keep = np.concatenate(fit.inliers)
    index = np.concatenate([np.full(len(p), j) for j, p in enumerate(lines_px)])
    plane = fit_lines(
        np.vstack(lines_px)[keep],
        index[keep],
        np.array(plane_lines),
        fit.matrix,
        k,
        _plane_from_local(registration),
    )
    if plane.note:
        log.warning("registration object: %s", plane.note)
    local16 = np.array([(u, v) for u in levels for v in levels])
    plane16 = _local_to_plane(registration, local16)
    ideal16 = apply_homography(np.linalg.inv(plane.matrix), plane16)
    raw = distort_points_px(ideal16, k, d)
    # The refined inner corners must agree with the quadrants' own corners.
    moved = float(np.max(np.linalg.norm(raw[[5, 9, 10, 6]] - inner, axis=1)))
    if moved > MAX_CORNER_SHIFT_PX:
        raise RegistrationError(
            f"the fitted plate disagrees with its crossing square by "
            f"{moved:.2f} px (not the registration object, or partly hidden)",
            found=True,
        )
    h, w = image_gray.shape
    if np.any(raw < 0) or np.any(raw[:, 0] > w - 1) or np.any(raw[:, 1] > h - 1):
        raise RegistrationError("a plate corner lies off the image", found=True)
    return Registration(raw, plane16, plane)


def detect_registration_points(
    image_gray: NDArray[np.uint8],
    registration: RegistrationConfig,
    camera_matrix: NDArray[np.float64] | None = None,
    distortion: NDArray[np.float64] | None = None,
    x_axis_image_rad: float = 0.0,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """All 16 corners of the plate's four light quadrants: raw pixels (16, 2) and beam-plane
    metres (16, 2), from :func:`detect_registration`. Raises
    :class:`~vision.errors.RegistrationError` (a ``ValueError``) with the reason."""
    found = detect_registration(
        image_gray, registration, camera_matrix, distortion, x_axis_image_rad
    )
    return found.image_points_px, found.plane_points_m


def _plane_from_local(registration: RegistrationConfig) -> NDArray[np.float64]:
    """(3, 3) the similarity from the object's own frame to the beam plane's."""
    c, s = math.cos(registration.angle_rad), math.sin(registration.angle_rad)
    cx, cy = registration.center_m
    return np.array([[c, -s, cx], [s, c, cy], [0.0, 0.0, 1.0]])


#: Refuse the registration when a straight edge keeps less than this share of its points.
MIN_INLIER_SHARE = 0.6
#: ... or its points scatter more than this (px RMS) about the fitted object.
MAX_EDGE_RMS_PX = 0.5
#: ... or the fitted inner corners move this far from the first detection (px).
MAX_CORNER_SHIFT_PX = 1.0
#: ... or, with known intrinsics, the plane's axes seen through the camera matrix are
#: unequal or non-orthogonal by more than this (a square imaged by a pinhole camera).
MAX_SHAPE_ERROR = 0.05


def _check_fit(fit: LineHomographyFit, k: NDArray[np.float64] | None) -> None:
    """Refuse (:class:`~vision.errors.RegistrationError`) a registration the edges do not
    support."""
    for j, keep in enumerate(fit.inliers):
        share = float(np.mean(keep))
        if share < MIN_INLIER_SHARE:
            raise RegistrationError(
                f"edge {j} is not straight (only {100 * share:.0f} % of its points on a "
                "line: hidden by something, or not the registration object)",
                found=True,
            )
    if not fit.rms_px <= MAX_EDGE_RMS_PX:
        raise RegistrationError(
            f"its edges scatter {fit.rms_px:.2f} px about the fitted "
            f"object (more than {MAX_EDGE_RMS_PX} px: too noisy or not the object)",
            found=True,
        )
    if k is None:
        return
    # Plane (object) axes through the camera: columns of K^-1 G are r1 s, r2 s, t s.
    m = np.linalg.inv(k) @ np.linalg.inv(fit.matrix)
    r1, r2 = m[:, 0], m[:, 1]
    n1, n2 = float(np.linalg.norm(r1)), float(np.linalg.norm(r2))
    skew = abs(float(r1 @ r2)) / (n1 * n2)
    if abs(n1 / n2 - 1.0) > MAX_SHAPE_ERROR or skew > MAX_SHAPE_ERROR:
        raise RegistrationError(
            "the fitted plate is not a square seen through the camera "
            f"matrix (axis ratio {n1 / n2:.3f}, skew {skew:.3f}): wrong intrinsics or a "
            "misdetected object",
            found=True,
        )


def _refine_line(
    image: NDArray[np.uint8],
    h0: NDArray[np.float64],
    k: NDArray[np.float64] | None,
    d: NDArray[np.float64] | None,
    local: NDArray[np.float64],
    toward_light: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Sub-pixel dark-to-light edge points (raw px) near predicted local edge points.

    The edge is scanned along raw pixel rows or columns (whichever crosses it more
    squarely), one scan line per pixel, and located by the least-squares blurred-step fit
    of :func:`vision.edges.erf_edge`: no interpolation, whose bias follows the edge's
    phase on the pixel grid and does not average out along an edge that is nearly
    parallel to the grid."""
    a = distort_points_px(apply_homography(h0, local), k, d)
    b = distort_points_px(apply_homography(h0, local + toward_light), k, d)
    nrm = b - a
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    axis = 1 if np.median(np.abs(nrm[:, 1])) >= np.median(np.abs(nrm[:, 0])) else 0
    sign = 1.0 if np.median(nrm[:, axis]) > 0 else -1.0
    # One scan line per integer coordinate across the scan direction.
    across = a[:, 1 - axis]
    order = np.argsort(across)
    lines = np.arange(math.ceil(across[order][0]), math.floor(across[order][-1]) + 1)
    if lines.size < 2:
        return np.zeros((0, 2))
    pos = np.interp(lines, across[order], a[order, axis])
    reach = 7
    offs = np.arange(-reach, reach + 1) * int(sign)
    idx = np.round(pos).astype(np.intp)[:, None] + offs[None, :]
    h, w = image.shape
    size_along, size_across = (h, w) if axis == 1 else (w, h)
    ok = (idx.min(axis=1) >= 0) & (idx.max(axis=1) < size_along)
    ok &= (lines >= 0) & (lines < size_across)
    if not ok.any():
        return np.zeros((0, 2))
    idx, lines = idx[ok], lines[ok]
    cols = np.broadcast_to(lines[:, None], idx.shape)
    prof = (image[idx, cols] if axis == 1 else image[cols, idx]).astype(np.float64)
    lo = prof[:, :2].mean(axis=1)
    hi = prof[:, -2:].mean(axis=1)
    frac = (prof - lo[:, None]) / np.maximum(hi - lo, 1e-6)[:, None]
    start = len(offs) - 0.5 - frac.sum(axis=1)  # equal-area step (sample units)
    c = erf_edge(prof, start, lo, hi, np.full(len(lo), 0.8), rising=True)
    good = np.isfinite(c) & (hi - lo > 15.0) & (c > 2.0) & (c < len(offs) - 3.0)
    along = idx[:, 0] + sign * c
    out = np.zeros((int(good.sum()), 2))
    out[:, axis] = along[good]
    out[:, 1 - axis] = lines[good]
    return out


def detect_registration_corners(
    image_gray: NDArray[np.uint8],
    registration: RegistrationConfig,
    camera_matrix: NDArray[np.float64] | None = None,
    distortion: NDArray[np.float64] | None = None,
    x_axis_image_rad: float = 0.0,
) -> NDArray[np.float64]:
    """Raw-pixel corners (4, 2) of the crossing square, in the order of
    :func:`registration_plane_points_m`. Raises
    :class:`~vision.errors.RegistrationError` (a ``ValueError``) with the reason."""
    raw, _ = detect_registration_points(
        image_gray, registration, camera_matrix, distortion, x_axis_image_rad
    )
    # Grid order: index 4 * i + j for levels (-P/2, -s/2, s/2, P/2); inner corners:
    return raw[[5, 9, 10, 6]]


def calibration_from_registration(
    image_gray: NDArray[np.uint8],
    registration: RegistrationConfig,
    camera_matrix: NDArray[np.float64] | None = None,
    distortion: NDArray[np.float64] | None = None,
    *,
    beam_length_m: float = 0.835,
    beam_width_m: float = 0.01905,
    x_axis_image_rad: float = 0.0,
) -> Calibration:
    """Detect the registration object in a frame and build the :class:`Calibration`
    from the 16 plate-quadrant corners of the fitted plane (:func:`detect_registration`),
    with the fit's covariance. Raises
    :class:`~vision.errors.RegistrationError` (a ``ValueError``) with the reason when the
    object cannot be found."""
    if not isinstance(image_gray, np.ndarray) or image_gray.dtype != np.uint8:
        raise TypeError("image_gray must be a uint8 numpy array")
    found = detect_registration(
        image_gray, registration, camera_matrix, distortion, x_axis_image_rad
    )
    return Calibration(
        found.image_points_px,
        found.plane_points_m,
        camera_matrix,
        distortion,
        beam_length_m=beam_length_m,
        beam_width_m=beam_width_m,
        plane_from_ideal_cov=found.fit.covariance,
    )
