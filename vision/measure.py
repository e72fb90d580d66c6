"""Per-frame measurement: hub angle, tip deflection and the beam's centre line.

Methods
-------
``"default"``
    Locate the beam and hub around the pivot (:mod:`vision.locate`), take sub-pixel
    edges along raw pixel rows/columns (:mod:`vision.edges`), map the edge points through
    undistortion and the homography into the plane, fit the hub's two edges as parallel
    lines (hub axis and angle), find the clamp (where the hub ends) and the tip (where
    the strip ends) by 1-D edge moments along the axis, and fit each beam edge with a
    polynomial in the hub frame; the centre line is their mean.
``"paper"``
    The paper's chain (seed 000 §4): whole-frame rectification with the homography,
    3x3 mean filter, Prewitt edges, 5x1 boxcar, first moments (:mod:`vision.paper`).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.polynomial import legendre
from numpy.typing import NDArray

from vision.calibration import Calibration
from vision.camera import distort_points_px, undistort_points_px
from vision.edges import strip_edges
from vision.homography import apply_homography
from vision.locate import FrameFailure, Rough, locate
from vision.sampling import bilinear, edge_moment

log = logging.getLogger(__name__)

METHODS = ("default", "paper")
_NAN2 = np.full(2, np.nan)


@dataclass(frozen=True, eq=False)
class FrameMeasurement:
    """What one frame shows. Numbers are NaN when ``ok`` is False.

    Attributes
    ----------
    ok, reason : whether the frame gave a measurement, and why not.
    hub_angle_rad : hub axis direction (pivot toward beam), CCW from +X, in [0, 2 pi).
    tip_lateral_m, tip_longitudinal_m : tip deflection relative to the rigid beam (the hub
        axis extended from the clamp).
    stations_m, lateral_at_stations_m : (S,) lateral deflection at those distances from
        the clamp along the beam.
    centreline_plane_m, centreline_px : (K, 2) centre line, plane (m) and raw image (px).
    hub_line_px : (2, 2) two raw-image points on the hub axis (back end, clamp).
    clamp_plane_m, tip_plane_m : (2,) where the free beam begins / the tip's end centre.
    hub_width_m, beam_width_m : widths measured in the frame.
    edge_rms_m : RMS residual of the beam edge fits.
    hub_angle_std_rad, tip_lateral_std_m : standard uncertainties predicted from the edge
        fits' residuals (noise only; calibration errors are not included).
    blur_px : median ramp width of the beam's edges along the scan lines, px (motion blur
        widens it; frames beyond ``max_blur_px`` are flagged).
    """

    ok: bool
    reason: str = ""
    hub_angle_rad: float = math.nan
    tip_lateral_m: float = math.nan
    tip_longitudinal_m: float = math.nan
    stations_m: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    lateral_at_stations_m: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    centreline_plane_m: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 2)))
    centreline_px: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 2)))
    hub_line_px: NDArray[np.float64] = field(default_factory=lambda: np.full((2, 2), np.nan))
    clamp_plane_m: NDArray[np.float64] = field(default_factory=lambda: _NAN2.copy())
    tip_plane_m: NDArray[np.float64] = field(default_factory=lambda: _NAN2.copy())
    hub_width_m: float = math.nan
    beam_width_m: float = math.nan
    edge_rms_m: float = math.nan
    blur_px: float = math.nan
    hub_angle_std_rad: float = math.nan
    tip_lateral_std_m: float = math.nan
    method: str = "default"

    def to_dict(self) -> dict[str, object]:
        """The JSON-able summary (what ``beambench measure --json`` prints)."""

        def num(x: float) -> float | None:
            return None if not math.isfinite(x) else float(x)

        return {
            "ok": self.ok,
            "reason": self.reason,
            "hub_angle_rad": num(self.hub_angle_rad),
            "tip_lateral_m": num(self.tip_lateral_m),
            "tip_longitudinal_m": num(self.tip_longitudinal_m),
            "stations_m": [float(s) for s in self.stations_m],
            "lateral_at_stations_m": [num(float(v)) for v in self.lateral_at_stations_m],
        }


class Measurer:
    """Measures frames of one camera placement. Build once, call :meth:`measure` per frame;
    picklable (plain arrays), so it can be sent to worker processes.

    Parameters
    ----------
    calibration : the camera placement's :class:`~vision.calibration.Calibration`.
    stations_m : distances from the clamp (m) at which lateral deflection is reported.
    method : ``"default"`` or ``"paper"``.
    """

    def __init__(
        self,
        calibration: Calibration,
        *,
        stations_m: Sequence[float] = (0.005, 0.204, 0.403, 0.603),
        method: str = "default",
        poly_degree: int = 7,
        max_blur_px: float = 9.0,
        edge_estimator: str = "area",
        max_root_slope_rad: float = 0.01,
        max_tip_std_m: float = 0.3e-3,
    ) -> None:
        if not isinstance(calibration, Calibration):
            raise TypeError(f"calibration must be a Calibration, got {type(calibration).__name__}")
        if method not in METHODS:
            raise ValueError(f"method must be one of {METHODS}, got {method!r}")
        st = np.asarray(stations_m, dtype=np.float64).ravel()
        if not np.all(np.isfinite(st)) or np.any(st < 0) or np.any(st > calibration.beam_length_m):
            raise ValueError("stations_m must lie on the beam (0 .. beam_length_m)")
        self.calibration = calibration
        self.stations_m = st
        self.method = method
        self.poly_degree = int(poly_degree)
        self.max_blur_px = float(max_blur_px)
        self.edge_estimator = edge_estimator
        self.max_root_slope_rad = float(max_root_slope_rad)
        self.max_tip_std_m = float(max_tip_std_m)
        self._h = calibration.fit.matrix
        self._h_inv = np.linalg.inv(self._h)
        self._k = calibration.camera_matrix
        self._d = calibration.distortion
        # Plane size of a pixel about the pivot (search step sizes are set from it).
        pivot_px = self.to_px(np.zeros((1, 2)))[0]
        nb = self.to_plane(pivot_px[None, :] + np.array([[1.0, 0.0], [0.0, 1.0]]))
        self.px_m = float(np.mean(np.linalg.norm(nb - 0.0, axis=1)))
        if not math.isfinite(self.px_m) or self.px_m <= 0:
            raise ValueError("calibration: the pivot does not map into the image plane")

    # -- mappings ---------------------------------------------------------------------
    def to_px(self, points_m: NDArray[np.float64]) -> NDArray[np.float64]:
        """Plane points (N, 2) m -> raw pixels (N, 2)."""
        return distort_points_px(apply_homography(self._h_inv, points_m), self._k, self._d)

    def to_plane(self, points_px: NDArray[np.float64]) -> NDArray[np.float64]:
        """Raw pixels (N, 2) -> plane points (N, 2) m."""
        return apply_homography(self._h, undistort_points_px(points_px, self._k, self._d))

    # -- entry point --------------------------------------------------------------------
    def measure(self, image_gray: NDArray[np.uint8]) -> FrameMeasurement:
        """Measure one uint8 gray [row, col] frame; never raises for a bad frame."""
        if not isinstance(image_gray, np.ndarray):
            raise TypeError(f"image_gray must be a numpy array, got {type(image_gray).__name__}")
        if image_gray.ndim != 2 or image_gray.dtype != np.uint8 or min(image_gray.shape) < 16:
            return self._fail(f"not a uint8 gray [row, col] image (shape {image_gray.shape})")
        if float(image_gray[::8, ::8].std()) < 2.0:
            return self._fail("blank frame (no contrast)")
        try:
            if self.method == "paper":
                from vision.paper import measure_paper

                return measure_paper(self, image_gray)
            return self._measure_default(image_gray)
        except FrameFailure as exc:
            return self._fail(str(exc))
        except (ValueError, np.linalg.LinAlgError, IndexError, FloatingPointError) as exc:
            log.warning("frame measurement failed unexpectedly: %s", exc)
            return self._fail(f"measurement failed ({exc})")

    def _fail(self, reason: str) -> FrameMeasurement:
        n = len(self.stations_m)
        return FrameMeasurement(
            ok=False,
            reason=reason,
            stations_m=self.stations_m.copy(),
            lateral_at_stations_m=np.full(n, np.nan),
            method=self.method,
        )

    # -- the default method ---------------------------------------------------------------
    def _measure_default(self, image: NDArray[np.uint8]) -> FrameMeasurement:
        cal = self.calibration
        w_beam, length = cal.beam_width_m, cal.beam_length_m
        rough = locate(image, self.to_px, length, w_beam, self.px_m)
        e, n, back_a, axis_b, hub_w, sd_hub = self._hub_axis(image, rough)
        # Clamp: the hub's end face, on its shoulders either side of the beam.
        origin0 = rough.clamp - ((rough.clamp @ n) - axis_b) * n
        a_clamp = self._end_face(image, origin0, e, n, hub_w, w_beam)
        clamp = origin0 + a_clamp * e
        # Beam edges in the hub frame (a from the clamp along e, b along n).
        la, lb, blur = self._beam_edges(image, rough, clamp, e, n, w_beam, length, hub_w)
        la, lb, rms, width = self._fit_edges(la, lb)
        if abs(width - w_beam) > 0.15 * w_beam:
            raise FrameFailure(
                f"beam width {width * 1e3:.1f} mm in the image disagrees with the "
                f"calibration's {w_beam * 1e3:.1f} mm"
            )
        if blur > self.max_blur_px:
            raise FrameFailure(f"motion blur: beam edges spread {blur:.1f} px")
        amax = float(max(la[:, 0].max(), lb[:, 0].max()))
        centre = _centre_poly(la, lb, self.poly_degree, amax)
        tip = self._tip(image, clamp, e, n, centre, amax, w_beam)
        a_tip, b_tip = tip
        arc = _arc_length(centre, a_tip)
        if abs(arc - length) > 0.02 * length:
            raise FrameFailure(
                f"beam length {arc * 1e3:.0f} mm along the centre line disagrees with "
                f"{length * 1e3:.0f} mm (occluded or out of view?)"
            )
        # Predicted noise of the tip's lateral deflection: hub direction carried to the
        # tip, and the end value of a degree-d polynomial fit (leverage ~ (d+1)^2 / N).
        n_pts = len(la) + len(lb)
        sd_fit = rms * (self.poly_degree + 1) / math.sqrt(n_pts)
        sd_tip = math.hypot(sd_hub * length, sd_fit)
        if sd_tip > self.max_tip_std_m:
            raise FrameFailure(
                f"too noisy: tip lateral uncertainty {sd_tip * 1e3:.2f} mm "
                f"(edge scatter {rms * 1e3:.2f} mm; low contrast?)"
            )
        root_slope = float(centre.deriv(np.array([0.0]))[0])
        if abs(root_slope) > self.max_root_slope_rad:
            raise FrameFailure(
                f"the beam leaves the clamp at {math.degrees(root_slope):.2f} deg to the hub "
                "axis (a clamped beam leaves along it): hub or beam mis-measured"
            )
        a_st = _stations_to_a(centre, self.stations_m, a_tip)
        lat_st = centre(a_st)
        k = 200
        a_line = np.linspace(0.0, a_tip, k)
        b_line = centre(a_line)
        b_line[-1] = b_tip
        line_m = clamp[None, :] + a_line[:, None] * e[None, :] + b_line[:, None] * n[None, :]
        back = clamp + back_a * e
        hub_px = self.to_px(np.vstack([back, clamp]))
        return FrameMeasurement(
            ok=True,
            hub_angle_rad=float(math.atan2(e[1], e[0]) % (2 * math.pi)),
            tip_lateral_m=float(b_tip),
            tip_longitudinal_m=float(a_tip - length),
            stations_m=self.stations_m.copy(),
            lateral_at_stations_m=np.asarray(lat_st, dtype=np.float64),
            centreline_plane_m=line_m,
            centreline_px=self.to_px(line_m),
            hub_line_px=hub_px,
            clamp_plane_m=clamp,
            tip_plane_m=line_m[-1].copy(),
            hub_width_m=hub_w,
            hub_angle_std_rad=sd_hub,
            tip_lateral_std_m=sd_tip,
            beam_width_m=width,
            edge_rms_m=rms,
            blur_px=blur,
            method="default",
        )

    def _strip_points(
        self,
        image: NDArray[np.uint8],
        line_m: NDArray[np.float64],
        half_width_m: float,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        px = self.to_px(line_m)
        # Half width in pixels across the strip, point by point (perspective foreshortens
        # across and along differently).
        t = np.gradient(line_m, axis=0)
        t /= np.linalg.norm(t, axis=1, keepdims=True)
        nrm = np.column_stack([-t[:, 1], t[:, 0]])
        across = np.linalg.norm(self.to_px(line_m + half_width_m * nrm) - px, axis=1)
        edges = strip_edges(image, px, across, estimator=self.edge_estimator)
        if len(edges.side_a) < 5:
            raise FrameFailure("too few edge points (strip not visible)")
        keep = edges.contrast > 0.35 * np.median(edges.contrast)
        return (
            self.to_plane(edges.side_a[keep]),
            self.to_plane(edges.side_b[keep]),
            edges.spread[keep],
        )

    def _hub_axis(
        self, image: NDArray[np.uint8], rough: Rough
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], float, float, float, float]:
        """Hub axis from its two edges fitted as parallel lines in the plane; the last
        value is the standard uncertainty of its direction (rad)."""
        d = rough.clamp - rough.hub_back
        length = float(np.linalg.norm(d))
        if length < max(20 * self.px_m, 2.0 * rough.hub_width):
            raise FrameFailure("hub too short in view to fit its axis")
        e = d / length
        margin = min(0.5 * rough.hub_width, 0.3 * length)
        t = np.linspace(margin, length - margin, max(8, int(length / self.px_m / 3)))
        line = rough.hub_back[None, :] + t[:, None] * e[None, :]
        pa, pb, _ = self._strip_points(image, line, rough.hub_width / 2)
        for _ in range(2):
            n = np.array([-e[1], e[0]])
            ca, cb = pa.mean(axis=0), pb.mean(axis=0)
            stack = np.vstack([pa - ca, pb - cb])
            _, _, vt = np.linalg.svd(stack, full_matrices=False)
            e2 = vt[0] if vt[0] @ e > 0 else -vt[0]
            n2 = np.array([-e2[1], e2[0]])
            res = np.concatenate([(pa - ca) @ n2, (pb - cb) @ n2])
            sig = 1.4826 * np.median(np.abs(res)) + 1e-9
            ka = np.abs((pa - ca) @ n2) < 4 * sig
            kb = np.abs((pb - cb) @ n2) < 4 * sig
            if ka.sum() < 3 or kb.sum() < 3:
                raise FrameFailure("hub edges not straight")
            pa, pb = pa[ka], pb[kb]
            e = e2
        n = np.array([-e[1], e[0]])
        ba, bb = float(pa.mean(axis=0) @ n), float(pb.mean(axis=0) @ n)
        axis_b = 0.5 * (ba + bb)
        back_a = float((rough.hub_back - rough.clamp) @ e)
        # Direction uncertainty of the common-direction fit: residual / spread along it.
        ca, cb = pa.mean(axis=0), pb.mean(axis=0)
        res = np.concatenate([(pa - ca) @ n, (pb - cb) @ n])
        spread = float(np.sum(((pa - ca) @ e) ** 2) + np.sum(((pb - cb) @ e) ** 2))
        dof = max(len(res) - 3, 1)
        sd = math.sqrt(float(np.sum(res**2)) / dof / max(spread, 1e-18))
        return e, n, back_a, axis_b, abs(ba - bb), sd

    def _end_face(
        self,
        image: NDArray[np.uint8],
        origin: NDArray[np.float64],
        e: NDArray[np.float64],
        n: NDArray[np.float64],
        hub_w: float,
        w_beam: float,
    ) -> float:
        """Position along the axis (from ``origin``) where the hub's shoulders end."""
        inner, outer = w_beam / 2, hub_w / 2
        if outer - inner < 3 * self.px_m:
            raise FrameFailure("hub not wider than the beam by enough to find the clamp")
        lat = np.linspace(inner + 0.3 * (outer - inner), outer - 0.3 * (outer - inner), 3)
        return self._along_edge(image, origin, e, n, np.concatenate([lat, -lat]), 0.0, hub_w)

    def _along_edge(
        self,
        image: NDArray[np.uint8],
        origin: NDArray[np.float64],
        e: NDArray[np.float64],
        n: NDArray[np.float64],
        lateral: NDArray[np.float64],
        guess: float,
        reach: float,
    ) -> float:
        """Bright-to-dark edge along ``e`` near ``guess`` on lines offset by ``lateral``."""
        step = 0.25 * self.px_m
        t = np.arange(guess - reach, guess + reach, step)
        pts = (
            origin[None, None, :]
            + t[None, :, None] * e[None, None, :]
            + lateral[:, None, None] * n[None, None, :]
        )
        v = bilinear(image, self.to_px(pts.reshape(-1, 2))).reshape(len(lateral), len(t))
        if not np.all(np.isfinite(v)):
            raise FrameFailure("clamp or tip outside the image")
        prof = v.mean(axis=0)
        diff = -np.diff(prof)[None, :]
        peak = np.array([int(np.argmax(diff[0]))])
        half = round(3.0 / 0.25)
        c, k, _ = edge_moment(diff, peak, half)
        if not np.isfinite(c[0]) or k[0] < 8.0:
            raise FrameFailure("no clear end edge (clamp or tip)")
        return float(t[0] + c[0] * step)

    def _beam_edges(
        self,
        image: NDArray[np.uint8],
        rough: Rough,
        clamp: NDArray[np.float64],
        e: NDArray[np.float64],
        n: NDArray[np.float64],
        w_beam: float,
        length: float,
        hub_w: float,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
        # Rough centre line in the plane, from past the clamp to short of the tip.
        rel = rough.beam - clamp
        a, b = rel @ e, rel @ n
        order = np.argsort(a)
        a, b = a[order], b[order]
        a_end = float((rough.tip - clamp) @ e)
        # Scan lines near the ends cross the hub's shoulders or the end face.
        a0 = 0.5 * hub_w + 4 * self.px_m
        a1 = a_end - 0.6 * w_beam - 4 * self.px_m
        if a1 - a0 < 0.3 * length:
            raise FrameFailure("beam too short in view")
        aq = np.linspace(a0, a1, max(20, int((a1 - a0) / (2 * self.px_m))))
        bq = np.interp(aq, a, b)
        line = clamp[None, :] + aq[:, None] * e[None, :] + bq[:, None] * n[None, :]
        pa, pb, spread = self._strip_points(image, line, w_beam / 2)
        ha = np.column_stack([(pa - clamp) @ e, (pa - clamp) @ n])
        hb = np.column_stack([(pb - clamp) @ e, (pb - clamp) @ n])
        # Name the sides by lateral sign: left (b > centre) and right.
        swap = np.median(ha[:, 1] - hb[:, 1]) < 0
        left, right = (hb, ha) if swap else (ha, hb)
        return left, right, float(np.median(spread))

    def _fit_edges(
        self, left: NDArray[np.float64], right: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], float, float]:
        """Reject outliers from each edge's polynomial fit; returns the inlier edges, the
        RMS residual (m) and the median width between the two fits (m)."""
        amax = float(max(left[:, 0].max(), right[:, 0].max()))
        out, res, coefs = [], [], []
        for pts in (left, right):
            keep = np.ones(len(pts), bool)
            for _ in range(2):
                if keep.sum() < 2 * self.poly_degree + 4:
                    raise FrameFailure("beam edges too ragged")
                c = _legfit(pts[keep, 0], pts[keep, 1], self.poly_degree, amax)
                r = pts[:, 1] - legendre.legval(_x(pts[:, 0], amax), c)
                sig = 1.4826 * np.median(np.abs(r[keep])) + 1e-9
                keep = np.abs(r) < 5 * sig
            out.append(pts[keep])
            res.append(r[keep])
            coefs.append(c)
        grid = _x(np.linspace(0.0, amax, 50), amax)
        width = float(np.median(np.abs(legendre.legval(grid, coefs[0] - coefs[1]))))
        rms = float(np.sqrt(np.mean(np.concatenate(res) ** 2)))
        return out[0], out[1], rms, width

    def _tip(
        self,
        image: NDArray[np.uint8],
        clamp: NDArray[np.float64],
        e: NDArray[np.float64],
        n: NDArray[np.float64],
        centre: _Poly,
        amax: float,
        w_beam: float,
    ) -> tuple[float, float]:
        """The end face: along the centre line's tangent beyond the last edge points."""
        a_ref = amax
        b_ref = float(centre(np.array([a_ref]))[0])
        slope = float(centre.deriv(np.array([a_ref]))[0])
        t = np.array([1.0, slope]) / math.hypot(1.0, slope)
        tang = t[0] * e + t[1] * n
        norm = np.array([-tang[1], tang[0]])
        origin = clamp + a_ref * e + b_ref * n
        lat = np.array([-0.2, 0.0, 0.2]) * w_beam
        dist = self._along_edge(image, origin, tang, norm, lat, 0.6 * w_beam, 1.2 * w_beam)
        a_tip = a_ref + dist * t[0]
        b_tip = b_ref + dist * t[1]
        return float(a_tip), float(b_tip)


class _Poly:
    """Centre line b(a) as a Legendre series on [0, amax], with linear extension past it."""

    def __init__(self, coef: NDArray[np.float64], amax: float) -> None:
        self.coef = coef
        self.amax = amax
        self.dcoef = legendre.legder(coef) * (2.0 / amax)

    def __call__(self, a: NDArray[np.float64]) -> NDArray[np.float64]:
        a = np.asarray(a, dtype=np.float64)
        ac = np.clip(a, 0.0, self.amax)
        return legendre.legval(_x(ac, self.amax), self.coef) + (a - ac) * legendre.legval(
            _x(ac, self.amax), self.dcoef
        )

    def deriv(self, a: NDArray[np.float64]) -> NDArray[np.float64]:
        ac = np.clip(np.asarray(a, dtype=np.float64), 0.0, self.amax)
        return legendre.legval(_x(ac, self.amax), self.dcoef)


def _x(a: NDArray[np.float64], amax: float) -> NDArray[np.float64]:
    return 2.0 * np.asarray(a) / amax - 1.0


def _legfit(a: NDArray[np.float64], b: NDArray[np.float64], deg: int, amax: float) -> NDArray:
    return legendre.legfit(_x(a, amax), b, deg)


def _centre_poly(
    left: NDArray[np.float64], right: NDArray[np.float64], deg: int, amax: float
) -> _Poly:
    """Mean of the two edge fits, as one series."""
    cl = _legfit(left[:, 0], left[:, 1], deg, amax)
    cr = _legfit(right[:, 0], right[:, 1], deg, amax)
    return _Poly(0.5 * (cl + cr), amax)


def _arc_length(centre: _Poly, a_end: float) -> float:
    a = np.linspace(0.0, a_end, 2001)
    return float(np.trapezoid(np.sqrt(1.0 + centre.deriv(a) ** 2), a))


def _stations_to_a(
    centre: _Poly, stations: NDArray[np.float64], a_end: float
) -> NDArray[np.float64]:
    """Axis coordinate of the material points at arc lengths ``stations`` from the clamp."""
    a = np.linspace(0.0, max(a_end, float(stations.max()) + 0.01), 4001)
    ds = np.sqrt(1.0 + centre.deriv(a) ** 2)
    s = np.concatenate([[0.0], np.cumsum(0.5 * (ds[1:] + ds[:-1]) * np.diff(a))])
    return np.interp(stations, s, a)
