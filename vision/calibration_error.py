"""What the calibration's own error does to the plane and to each frame's measurement.

The calibration's homography ``H`` (plane from undistorted pixels) is fitted once per
camera placement, so its error is one error common to every frame of a run: a systematic
error, which the frames' own (noise) uncertainties leave out. Given the covariance of
``H``'s elements (:attr:`Calibration.plane_from_ideal_cov
<vision.calibration.Calibration.plane_from_ideal_cov>`, from the registration's fit), an
error ``dH`` moves the plane point seen at a fixed pixel by ``u(X) = P(X) dh``
(:func:`plane_jacobian`): the pivot (the plane's origin) and the beam's points move
against each other.

A frame's measurement (:mod:`vision.measure`) turns those moves into its results as a
linear map, which :func:`frame_sensitivity` writes down from the frame's own geometry:

- the hub axis passes through the pivot and is fitted jointly with the clamped beam
  (``w(0) = w'(0) = 0``) and the hub's edges: the beam's points move across the axis by
  ``u . n`` (less the slope times their move along it), the hub's by ``u . n`` (each
  hub edge at its own offset: they give only the direction), and the axis turn
  ``d theta`` is the least-squares one that the beam's shape (its clamped-free modes or
  the clamped polynomial, whichever the measurer took: the larger effect is stated)
  cannot absorb;
- the tip lateral is the tip's distance from the turned axis:
  ``u(T) . n - d theta (T . e)``;
- the tip longitudinal is the tip's distance from the clamp along the axis:
  ``(u(T) - u(C)) . e + d theta (T . n)``.

:func:`frame_calibration_sd` gives the three standard uncertainties; checked against the
measurer itself, re-measuring frames with another calibration, in
``tests/vision/test_calibration_error.py``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from vision.calibration import Calibration
from vision.centreline import cantilever_modes_t
from vision.frame_measurement import FrameMeasurement
from vision.homography import apply_homography

#: The measurer's clamped polynomial degree (``Measurer(poly_degree=8)``): what a turn of
#: the axis leaves in the beam's points that the shape cannot take up.
POLY_DEGREE = 8
SHAPE_MODES = 4
#: Hub points are counted clear of its end faces by this much (the measurer's margin is
#: 10 px; the plane's scale is a few tenths of a mm per px).
_HUB_MARGIN_M = 4e-3
_N_POINTS = 200


@dataclass(frozen=True)
class CalibrationSd:
    """Standard uncertainties of one frame's results from the calibration alone."""

    hub_angle_rad: float
    tip_lateral_m: float
    tip_longitudinal_m: float


NO_CALIBRATION_SD = CalibrationSd(0.0, 0.0, 0.0)


def plane_jacobian(cal: Calibration, points_m: ArrayLike) -> NDArray[np.float64]:
    """(N, 2, 9): how the plane points seen at the pixels of ``points_m`` (N, 2), m, move
    with the elements of the calibration's plane-from-ideal homography (row-major)."""
    pts = np.asarray(points_m, dtype=np.float64).reshape(-1, 2)
    h = cal.plane_from_ideal / cal.plane_from_ideal[2, 2]
    ideal = apply_homography(np.linalg.inv(h), pts)
    xt = np.column_stack([ideal, np.ones(len(pts))])  # (N, 3)
    w = xt @ h[2]
    out = np.zeros((len(pts), 2, 9))
    for i in range(2):
        out[:, i, 3 * i : 3 * i + 3] = xt / w[:, None]
        out[:, i, 6:9] = -(pts[:, i] / w)[:, None] * xt
    return out


def point_covariance(cal: Calibration, points_m: ArrayLike) -> NDArray[np.float64]:
    """(N, 2, 2) covariance (m^2) of the plane points seen at the pixels of ``points_m``
    from the calibration's error (zeros when it states none)."""
    p = plane_jacobian(cal, points_m)
    if cal.plane_from_ideal_cov is None:
        return np.zeros((len(p), 2, 2))
    return np.asarray(np.einsum("nik,kl,njl->nij", p, cal.plane_from_ideal_cov, p))


def frame_sensitivity(
    cal: Calibration, m: FrameMeasurement, shape: str = "modes"
) -> NDArray[np.float64] | None:
    """(3, 9): the changes of the frame's hub angle (rad), tip lateral and tip
    longitudinal (m) per change of the homography's elements, the beam's shape fitted as
    ``shape`` (one of :data:`SHAPES`), or None for a frame without a measurement."""
    if shape not in SHAPES:
        raise ValueError(f"shape must be one of {SHAPES}, got {shape!r}")
    geo = _frame_geometry(cal, m)
    return None if geo is None else _sensitivity(geo, shape)


@dataclass(frozen=True)
class _Geometry:
    """What :func:`frame_sensitivity` takes from a frame whatever the shape: the beam's
    points' axis coordinates ``a`` (m from the clamp), the axis turn's column of the beam
    and the hub rows, the points' moves per homography element across the axis, and
    the tip's and the clamp's sensitivity pieces."""

    a: NDArray[np.float64]
    a_tip: float
    length_m: float
    turn_beam: NDArray[np.float64]
    hub_s: NDArray[np.float64] | None
    jac: NDArray[np.float64]
    n: NDArray[np.float64]
    e: NDArray[np.float64]
    tip: NDArray[np.float64]
    p_tip: NDArray[np.float64]
    p_clamp: NDArray[np.float64]


def _frame_geometry(cal: Calibration, m: FrameMeasurement) -> _Geometry | None:
    if not m.ok or m.centreline_plane_m.shape[0] < 3:
        return None
    theta = float(m.hub_angle_rad)
    e = np.array([math.cos(theta), math.sin(theta)])
    n = np.array([-e[1], e[0]])
    line = np.asarray(m.centreline_plane_m, dtype=np.float64)
    clamp = np.asarray(m.clamp_plane_m, dtype=np.float64)
    tip = np.asarray(m.tip_plane_m, dtype=np.float64)
    d_clamp = float(clamp @ e)
    a_line = (line - clamp) @ e
    b_line = (line - clamp) @ n
    a_tip = float(a_line[-1])
    a = np.linspace(0.0, a_tip, _N_POINTS)
    b = np.interp(a, a_line, b_line)
    slope = np.gradient(b, a)
    beam = clamp + a[:, None] * e + b[:, None] * n
    across = n[None, :] - slope[:, None] * e[None, :]  # (K, 2)
    jac_beam = np.einsum("ki,kij->kj", across, plane_jacobian(cal, beam))
    jacs = [jac_beam]
    hub_s = None
    back = _hub_back_m(cal, m, e)
    if back is not None:
        s0, s1 = back + _HUB_MARGIN_M, d_clamp - _HUB_MARGIN_M
        if s1 > s0:
            k = max(2, round(_N_POINTS * (s1 - s0) / a_tip))
            hub_s = np.linspace(s0, s1, k)
            hub = hub_s[:, None] * e
            jacs.append(np.einsum("i,kij->kj", n, plane_jacobian(cal, hub)))
    p_tip, p_clamp = plane_jacobian(cal, np.vstack([tip, clamp]))
    return _Geometry(
        a, a_tip, cal.beam_length_m, d_clamp + a, hub_s, np.vstack(jacs), n, e, tip, p_tip, p_clamp
    )


def _sensitivity(geo: _Geometry, shape: str) -> NDArray[np.float64]:
    """:func:`frame_sensitivity` from the frame's geometry."""
    a = geo.a
    basis = _shape_basis(a, geo.a_tip, geo.length_m, shape)
    n_shape = basis.shape[1]
    rows = [np.column_stack([geo.turn_beam, np.zeros(len(a)), basis])]
    if geo.hub_s is not None:
        k = len(geo.hub_s)
        rows.append(np.column_stack([geo.hub_s, np.ones(k), np.zeros((k, n_shape))]))
    a_mat = np.vstack(rows)
    weights = np.linalg.pinv(a_mat)[0]  # the axis turn from the points' moves
    g_hub = weights @ geo.jac
    e, n, tip = geo.e, geo.n, geo.tip
    g_lat = n @ geo.p_tip - float(tip @ e) * g_hub
    g_lon = e @ (geo.p_tip - geo.p_clamp) + float(tip @ n) * g_hub
    return np.vstack([g_hub, g_lat, g_lon])


#: The shapes the measurer fits the beam with: its clamped-free modes when they pass its
#: tests, else the clamped polynomial. The frame does not say which.
SHAPES = ("modes", "polynomial")


def _shape_basis(
    a: NDArray[np.float64], a_tip: float, length_m: float, shape: str
) -> NDArray[np.float64]:
    """(K, S) the beam's shape space at ``a`` (m from the clamp)."""
    if shape == "modes":
        return np.asarray(cantilever_modes_t(a / length_m, SHAPE_MODES).T)
    return np.column_stack([(a / a_tip) ** k for k in range(2, POLY_DEGREE + 1)])


def _hub_back_m(cal: Calibration, m: FrameMeasurement, e: NDArray[np.float64]) -> float | None:
    """The hub's back face's distance from the pivot along the axis, m, or None."""
    if not np.all(np.isfinite(m.hub_line_px)):
        return None
    back = cal.to_plane(m.hub_line_px[:1])[0]
    return float(back @ e)


def frame_calibration_sd(cal: Calibration, m: FrameMeasurement) -> CalibrationSd:
    """The standard uncertainties the calibration's error gives the frame's hub angle,
    tip lateral and tip longitudinal (zero when the calibration states no covariance;
    NaN for a frame without a measurement)."""
    if not m.ok:
        return CalibrationSd(math.nan, math.nan, math.nan)
    if cal.plane_from_ideal_cov is None:
        return NO_CALIBRATION_SD
    geo = _frame_geometry(cal, m)  # the frame's, once for both shapes
    if geo is None:
        return CalibrationSd(math.nan, math.nan, math.nan)
    sd = np.zeros(3)
    for shape in SHAPES:  # whichever the measurer took: the larger
        g = _sensitivity(geo, shape)
        var = np.einsum("ik,kl,il->i", g, cal.plane_from_ideal_cov, g)
        sd = np.maximum(sd, np.sqrt(np.maximum(var, 0.0)))
    return CalibrationSd(float(sd[0]), float(sd[1]), float(sd[2]))


def frame_change(
    cal: Calibration, other: Calibration, m: FrameMeasurement, shape: str = "modes"
) -> NDArray[np.float64] | None:
    """(3,) the first-order change of the frame's hub angle (rad), tip lateral and
    longitudinal (m) when it is measured with ``other`` instead of ``cal`` (same
    intrinsics), the beam's shape fitted as ``shape``, or None for a frame without a
    measurement."""
    g = frame_sensitivity(cal, m, shape)
    if g is None:
        return None
    dh = (other.plane_from_ideal / other.plane_from_ideal[2, 2]).ravel()
    dh = dh - (cal.plane_from_ideal / cal.plane_from_ideal[2, 2]).ravel()
    return np.asarray(g @ dh)
