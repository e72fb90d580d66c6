"""The paper's measurement chain (seed 000 §4), the baseline ``method="paper"``.

The whole frame is rectified through the 4-point collineation (no lens-distortion
correction, as in the paper) onto a metric grid, smoothed with the 3x3 mean mask
(Eq. 41), differentiated with the Prewitt masks, the edge magnitude smoothed with a 5x1
boxcar along the strip, and each pixel column (or row) across the beam reduced to one
construction point: the first moment (centre of area) of its edge pixels. The hub angle is
the best-fit line through the hub's construction points, relative to the horizontal pixel
direction of the rectified image. Locating the strips reuses :func:`vision.locate.locate`.

:func:`measure_paper` needs only the :class:`~vision.calibration.Calibration` (its
homography, beam length and width, and its mapping for the image-space overlays), the
stations and the rectified grid's resolution; :class:`vision.measure.Measurer` with
``method="paper"`` calls it.
"""

from __future__ import annotations

import math
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from vision.calibration import Calibration
from vision.errors import FrameFailure
from vision.frame_measurement import FrameMeasurement
from vision.locate import locate

_PREWITT = np.array([[-1.0, 0.0, 1.0], [-1.0, 0.0, 1.0], [-1.0, 0.0, 1.0]], np.float32)


def _grid(beam_length_m: float, res: float) -> tuple[NDArray[np.float64], float, float, float, int]:
    """Rectified grid: plane point (X, Y) -> (col, row) = ((X - x0)/res, (y0 - Y)/res)."""
    reach = 1.08 * (beam_length_m + 0.05)
    n = math.ceil(2 * reach / res)
    x0, y0 = -reach, reach
    g = np.array([[1 / res, 0, -x0 / res], [0, -1 / res, y0 / res], [0, 0, 1.0]])
    return g, x0, y0, res, n


def _centres(mag: NDArray[Any], line_px: NDArray[np.float64], half: float) -> NDArray[np.float64]:
    """Construction points: centre of area of edge pixels on each column/row across."""
    d = line_px[-1] - line_px[0]
    cols = abs(d[0]) >= abs(d[1])
    img = mag if cols else mag.T
    pts = line_px if cols else line_px[:, ::-1]
    pts = pts[np.argsort(pts[:, 0])]
    lines = np.arange(int(np.ceil(pts[0, 0])), int(np.floor(pts[-1, 0])) + 1)
    h, w = img.shape
    lines = lines[(lines >= 0) & (lines < w)]
    yc = np.interp(lines, pts[:, 0], pts[:, 1])
    slope = np.gradient(yc, lines) if len(lines) > 2 else np.zeros_like(yc)
    reach = int(np.ceil(half * np.sqrt(1 + np.max(slope**2)))) + 4
    offs = np.arange(-reach, reach + 1)
    rows = np.round(yc).astype(np.intp)[:, None] + offs
    ok = (rows.min(axis=1) >= 0) & (rows.max(axis=1) < h)
    lines, rows = lines[ok], rows[ok]
    v = img[rows, lines[:, None]].astype(np.float64)
    # Edge pixels: the segmentation keeps magnitudes above half of the column's peak.
    v = np.where(v > 0.5 * v.max(axis=1, keepdims=True), v, 0.0)
    centre = (v * rows).sum(axis=1) / np.maximum(v.sum(axis=1), 1e-9)
    out = np.column_stack([lines.astype(np.float64), centre])
    return out if cols else out[:, ::-1]


def measure_paper(
    calibration: Calibration,
    image: NDArray[np.uint8],
    *,
    stations_m: NDArray[np.float64],
    resolution_m: float,
) -> FrameMeasurement:
    """Measure one frame by the paper's chain.

    Parameters
    ----------
    calibration : the camera placement (homography, beam length and width).
    image : uint8 gray [row, col] frame.
    stations_m : (S,) distances from the clamp (m) at which lateral deflection is reported.
    resolution_m : side of a pixel of the rectified grid, m (the Measurer uses the plane
        size of an image pixel at the pivot).

    Raises :class:`~vision.errors.FrameFailure` when the frame gives no measurement.
    """
    cal = calibration
    g, x0, y0, res, n = _grid(cal.beam_length_m, resolution_m)
    # Whole-frame rectification (the paper ignores lens distortion).
    warp = g @ cal.fit.matrix
    rect = cv2.warpPerspective(image, warp, (n, n), flags=cv2.INTER_LINEAR)
    mean = cv2.blur(rect.astype(np.float32), (3, 3))
    gx = cv2.filter2D(mean, cv2.CV_32F, _PREWITT)
    gy = cv2.filter2D(mean, cv2.CV_32F, _PREWITT.T)
    mag = cv2.magnitude(gx, gy)

    def to_grid(p: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.column_stack([(p[:, 0] - x0) / res, (y0 - p[:, 1]) / res])

    def to_plane(q: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.column_stack([q[:, 0] * res + x0, y0 - q[:, 1] * res])

    rough = locate(mean.astype(np.uint8), to_grid, cal.beam_length_m, cal.beam_width_m, res)
    # 5x1 boxcar along each strip's main pixel direction.
    d_beam = to_grid(rough.beam[-1:])[0] - to_grid(rough.beam[:1])[0]
    box = (5, 1) if abs(d_beam[0]) >= abs(d_beam[1]) else (1, 5)
    mag_beam = cv2.blur(mag, box)
    e0 = (rough.clamp - rough.hub_back) / np.linalg.norm(rough.clamp - rough.hub_back)
    hub_len = float(np.linalg.norm(rough.clamp - rough.hub_back))
    t = np.linspace(0.25 * hub_len, 0.75 * hub_len, 20)
    hub_line = to_grid(rough.hub_back + t[:, None] * e0)
    hub_pts = to_plane(_centres(mag, hub_line, 0.5 * rough.hub_width / res + 2))
    if len(hub_pts) < 5:
        raise FrameFailure("paper: hub not found")
    c = hub_pts.mean(axis=0)
    _, _, vt = np.linalg.svd(hub_pts - c)
    e = vt[0] if vt[0] @ e0 > 0 else -vt[0]
    nrm = np.array([-e[1], e[0]])
    clamp = c + ((rough.clamp - c) @ e) * e
    beam_line = to_grid(rough.beam)
    pts = to_plane(_centres(mag_beam, beam_line, 0.5 * cal.beam_width_m / res + 2))
    a = (pts - clamp) @ e
    b = (pts - clamp) @ nrm
    order = np.argsort(a)
    a, b = a[order], b[order]
    keep = (a > 0.5 * rough.hub_width) & (a < a.max() - cal.beam_width_m)
    if keep.sum() < 20:
        raise FrameFailure("paper: too few construction points on the beam")
    a, b = a[keep], b[keep]
    # Tip: the beam's end along the last construction points' direction.
    tip_a = float((rough.tip - clamp) @ e)
    prof_t = np.arange(tip_a - 3 * cal.beam_width_m, tip_a + 3 * cal.beam_width_m, res / 2)
    coef = np.polyfit(a[-60:], b[-60:], 1)
    pp = clamp + prof_t[:, None] * e + np.polyval(coef, prof_t)[:, None] * nrm
    q = to_grid(pp).astype(np.float32)
    prof = cv2.remap(mag_beam, q[:, 0:1], q[:, 1:2], cv2.INTER_LINEAR).ravel()
    a_tip = float(np.sum(prof * prof_t) / max(float(np.sum(prof)), 1e-9))
    b_tip = float(np.polyval(coef, a_tip))
    lat = np.interp(stations_m, a, b)
    line = clamp + a[:, None] * e + b[:, None] * nrm
    return FrameMeasurement(
        ok=True,
        hub_angle_rad=float(math.atan2(e[1], e[0]) % (2 * math.pi)),
        tip_lateral_m=b_tip,
        tip_longitudinal_m=a_tip - cal.beam_length_m,
        stations_m=stations_m.copy(),
        lateral_at_stations_m=lat,
        centreline_plane_m=line,
        centreline_px=cal.to_px(line),
        hub_line_px=cal.to_px(np.vstack([rough.hub_back, clamp])),
        clamp_plane_m=clamp,
        tip_plane_m=clamp + a_tip * e + b_tip * nrm,
        # the chain reads the hub's centre line only: its width is the locator's rough
        # one, where to look, not a measurement (as the default method's on a hub whose
        # edges are no straight lines)
        hub_width_located_m=rough.hub_width,
        method="paper",
    )
