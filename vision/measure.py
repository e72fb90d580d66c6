"""Per-frame measurement: hub angle, tip deflection and the beam's centre line.

:class:`Measurer` holds one camera placement's calibration and settings and measures a
frame into a :class:`~vision.frame_measurement.FrameMeasurement` by one of two methods.

Methods
-------
``"default"``
    Locate the beam and hub around the pivot (:mod:`vision.locate`), take sub-pixel
    edges along raw pixel rows/columns (:mod:`vision.edges`), map the edge points through
    undistortion and the homography into the plane (:meth:`Calibration.to_plane
    <vision.calibration.Calibration.to_plane>`), find the clamp (where the hub ends) by
    1-D edge moments along the axis (:mod:`vision.hub`), then fit the hub's axis and the
    beam's clamped centre line together (:func:`vision.centreline.fit_clamped_joint`):
    the beam leaves the clamp, on the axis through the pivot (the plane's origin), along
    the axis, so its root fixes the axis whatever the hub's length; the hub's long edges,
    when it shows any clear of its end faces, add their direction (a hub at least twice
    as long as wide is also fitted alone, as a check). Find the tip (where the strip
    ends) as the clamp was found. The beam's steps are here.
``"paper"``
    The paper's chain (seed 000 §4): whole-frame rectification with the homography,
    3x3 mean filter, Prewitt edges, 5x1 boxcar, first moments (:mod:`vision.paper_chain`).
"""

from __future__ import annotations

import functools
import itertools
import logging
import math
from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import NDArray

from vision.calibration import Calibration
from vision.centreline import (
    TUKEY_C,
    CentreLine,
    JointFit,
    ModalCentreLine,
    PointsMemo,
    _polyval_rows_k,
    arc_length,
    fit_clamped_joint,
    linspace,
    stations_to_a,
)
from vision.edges import strip_edges_many
from vision.errors import FrameFailure, ParameterError
from vision.frame_measurement import FrameMeasurement
from vision.hub import back_face, clamp_face, end_edge, hub_axis, rough_axis
from vision.jit import kernel
from vision.locate import Rough, locate, search_circles
from vision.paper_chain import measure_paper
from vision.sampling import along_across, bilinear, median, median_in_place, select_kth

log = logging.getLogger(__name__)

METHODS = ("default", "paper")
#: Hub edge points are taken this many pixels clear of the hub's end faces (the scan
#: window and the blur reach that far).
_END_MARGIN_PX = 10.0
#: A turn of the trial axis below which the joint fit is not repeated in the turned frame
#: (its second-order terms, ~turn^2 x the beam's length, are then below 1e-10 m).
_SMALL_TURN_RAD = 1e-4


#: Frames whose beam edges have more than this fraction of their points beyond the
#: biweight's reach are refused: Gaussian noise puts 3e-6 there, clutter beside the beam
#: none (at most 0.1 % on every rendered bench set); a damaged JPEG's shifted blocks 16-20 %.
_MAX_OUTLIER_FRACTION = 0.1

#: The hub's width is not reported where the joint fit left out more than this fraction
#: of either hub edge's points: a straight edge's noise puts 3e-6 of them beyond the
#: biweight's reach, its ends a few more (up to 6.7 % on the other renderer's plain
#: frames: the scan lines nearest the clamp face); a bar lying against part of an edge
#: puts that part there (4-49 % on such frames where it left any out; the beam's limit,
#: as for its edges, leaves those below it, 3 in 70, reporting the bar's edge).
_MAX_HUB_OUTLIER_FRACTION = _MAX_OUTLIER_FRACTION

#: Frames whose beam edges spread within ``max_blur_px`` overall but beyond this many
#: times it on a tenth of the beam (the 90th percentile: near the tip, which a swinging
#: beam smears most) are refused with the smear in the reason: the edges' erf model
#: holds to ~9 px of ramp (the blur set's tips reach 7.4 px and are measured from their
#: edges within their uncertainty; smear-20/40 frames with a sharp root reach 12-13 px).
_TIP_BLUR_FACTOR = 1.5

#: The modal fit is repeated in the turned frame above this turn: what the first-order
#: turn leaves, ~turn x the deflection x the slope, is then below 2e-6 m.
_MODAL_TURN_RAD = 5e-4


#: The modes' truncation error is taken as the change that this many more modes make
#: (the first two omitted modes together: on the fast set's frame whose four modes leave
#: 0.022 mrad of hub angle, five to ten modes agreeing on it, two more show 0.025 and
#: one more 0.017).
_MORE_MODES = 2


def _chi2_999(dof: int) -> float:
    """The 0.999 quantile of chi-squared with ``dof`` degrees of freedom (Wilson and
    Hilferty's cube-root normal approximation, within 1 % from 3 degrees of freedom)."""
    z = 3.0902  # the normal's 0.999 quantile
    h = 2.0 / (9.0 * dof)
    return dof * (1.0 - h + z * math.sqrt(h)) ** 3


class Measurer:
    """Measures frames of one camera placement. Build once, call :meth:`measure` per frame;
    picklable (plain arrays), so it can be sent to worker processes.

    Parameters
    ----------
    calibration : the camera placement's :class:`~vision.calibration.Calibration`.
    stations_m : distances from the clamp (m) at which lateral deflection is reported.
    method : ``"default"`` or ``"paper"``.
    max_blur_px : frames whose beam edges spread wider (median ramp width along the scan
        lines, motion blur) are measured from the centroids of the beam's light on each
        scan line instead of its edges (the edge fits are biased beyond it; the centroid
        of the exposure's time-average is the centre at mid-exposure).
    max_smear_px : smeared frames whose edges spread beyond it (99th percentile) are
        refused, the smear in the reason.
    max_root_slope_rad : a free fit's slope at the root beyond this and beyond 4 of its
        standard uncertainties flags the frame (hub or beam mis-measured).
    max_tip_uncertainty_m : frames whose stated tip lateral standard uncertainty exceeds
        it are refused ("too noisy"); below it, they are measured with that uncertainty
        (``max_tip_std_m`` is its former name).
    shape_modes : the beam's shape is fitted as this many clamped-free modes (the
        physics of a cantilever: zero moment and shear at its free end) as well as the
        generic clamped polynomial of ``poly_degree``; the modal fit is taken when its
        shape test passes and it agrees with the clamped polynomial (refitted in its
        frame) on the hub angle and the tip within 3 standard uncertainties of their
        difference, its uncertainties then widened by the shape model's own error: what
        two more modes change (truncation), and what of the polynomial's extra shapes
        their noise does not explain (no cantilever's shape). 0: the polynomial alone.
    max_edge_correlation : frames whose beam-edge residuals correlate beyond it from one
        scan line to the next are refused: the edges then run away from any smooth beam
        shape (a damaged JPEG's shifted blocks measured 0.89-0.91 and came out ``ok`` with
        11-14 mm of tip error; the rendered bench sets stay below 0.54). The hub's
        edges' residuals correlating beyond it leave its width unmeasured (NaN).
    """

    def __init__(
        self,
        calibration: Calibration,
        *,
        stations_m: Sequence[float] = (0.005, 0.204, 0.403, 0.603),
        method: str = "default",
        poly_degree: int = 8,
        max_blur_px: float = 6.0,
        max_smear_px: float = 80.0,
        edge_estimator: str = "erf",
        max_root_slope_rad: float = 0.01,
        max_tip_uncertainty_m: float = 0.5e-3,
        max_tip_std_m: float | None = None,
        shape_modes: int = 4,
        max_edge_correlation: float = 0.85,
    ) -> None:
        if not isinstance(calibration, Calibration):
            raise TypeError(f"calibration must be a Calibration, got {type(calibration).__name__}")
        if method not in METHODS:
            raise ParameterError("method", f"must be one of {METHODS}, got {method!r}")
        st = np.asarray(stations_m, dtype=np.float64).ravel()
        if not np.all(np.isfinite(st)) or np.any(st < 0) or np.any(st > calibration.beam_length_m):
            raise ParameterError("stations_m", "must lie on the beam (0 .. beam_length_m)")
        self.calibration = calibration
        self.stations_m = st
        self.method = method
        self.poly_degree = int(poly_degree)
        self.max_blur_px = float(max_blur_px)
        self.max_smear_px = float(max_smear_px)
        self.edge_estimator = edge_estimator
        self.max_root_slope_rad = float(max_root_slope_rad)
        # ``max_tip_std_m``: the former name of ``max_tip_uncertainty_m``.
        limit = max_tip_uncertainty_m if max_tip_std_m is None else max_tip_std_m
        self.max_tip_std_m = float(limit)
        self.shape_modes = int(shape_modes)
        self.max_edge_correlation = float(max_edge_correlation)
        # Plane size of a pixel about the pivot (search step sizes are set from it).
        pivot_px = calibration.to_px(np.zeros((1, 2)))[0]
        nb = calibration.to_plane(pivot_px[None, :] + np.array([[1.0, 0.0], [0.0, 1.0]]))
        self.px_m = float(np.mean(np.linalg.norm(nb - 0.0, axis=1)))
        if not math.isfinite(self.px_m) or self.px_m <= 0:
            raise ParameterError("calibration", "does not map the pivot into the image plane")
        # The search circles for the beam are fixed in the plane: mapped once.
        self._circles = (
            search_circles(
                calibration.to_px, calibration.beam_length_m, calibration.beam_width_m, self.px_m
            )
            if method == "default"
            else None
        )

    # -- entry point --------------------------------------------------------------------
    def measure(
        self,
        image_gray: NDArray[np.uint8],
        *,
        crossings_m: tuple[NDArray[np.float64], NDArray[np.float64], float] | None = None,
    ) -> FrameMeasurement:
        """Measure one uint8 gray [row, col] frame; never raises for a bad frame.
        ``crossings_m``: where the beam crosses the search circles in this frame
        (:func:`vision.locate.crossings` on this placement's circles), when the caller
        has found them already (default method)."""
        if not isinstance(image_gray, np.ndarray):
            raise TypeError(f"image_gray must be a numpy array, got {type(image_gray).__name__}")
        if image_gray.ndim != 2 or image_gray.dtype != np.uint8 or min(image_gray.shape) < 16:
            return self._fail(f"not a uint8 gray [row, col] image (shape {image_gray.shape})")
        if _blank(image_gray):
            return self._fail("blank frame (no contrast)")
        try:
            if self.method == "paper":
                return measure_paper(
                    self.calibration, image_gray, stations_m=self.stations_m, resolution_m=self.px_m
                )
            return self._measure_default(image_gray, crossings_m)
        except FrameFailure as exc:
            return self._fail(exc.reason)
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
    def _measure_default(
        self,
        image: NDArray[np.uint8],
        crossings_m: tuple[NDArray[np.float64], NDArray[np.float64], float] | None = None,
    ) -> FrameMeasurement:
        cal = self.calibration
        w_beam, length = cal.beam_width_m, cal.beam_length_m
        rough = locate(image, cal.to_px, length, w_beam, self.px_m, self._circles, crossings_m)
        w_beam = rough.beam_width  # the width the image shows (the calibration's: a hint)
        # The hub's axis, first through the rough centres of its cross-profiles: enough
        # to place the searches for its end faces, whose lines lie symmetrically about it.
        e, n, axis_b = rough_axis(rough)
        hub_w = rough.hub_width
        # Clamp: the hub's end face, on its shoulders either side of the beam.
        origin0 = rough.clamp - ((rough.clamp @ n) - axis_b) * n
        to_px, px_m = cal.to_px, self.px_m
        a_clamp = clamp_face(image, origin0, e, n, hub_w, w_beam, to_px=to_px, px_m=px_m)
        clamp = origin0 + a_clamp * e
        guess_back = float((rough.hub_back - clamp) @ e)
        back_a = back_face(image, clamp, e, n, hub_w, guess_back, to_px=to_px, px_m=px_m)
        back = clamp + back_a * e
        # The hub's and the beam's edges, scanned in one pass (a scan's fixed cost is
        # about that of its lines); a hub too short to show edge points clear of its end
        # faces gives none.
        hub_pts, (pa, pb), spread = self._scan(image, rough, back, clamp, e, n, hub_w, w_beam)
        blur = median(spread)
        smear_px = 0.0
        k90 = int(0.9 * (len(spread) - 1))
        tip_blur = _kth(spread, k90)  # the 90th percentile
        if blur <= self.max_blur_px and tip_blur > _TIP_BLUR_FACTOR * self.max_blur_px:
            # A beam swinging about its root smears most toward its tip: a sharp root
            # and an outer tenth smeared beyond the edges' reach. Its edges there are
            # no erf ramps (18-24 % of the points left as outliers); the smeared beam's
            # centroids measured one such frame 0.2 mm off against 0.04 mm stated.
            raise FrameFailure(
                f"motion blur toward the tip: beam edges spread {tip_blur:.0f} px over "
                f"its outer tenth ({tip_blur * self.px_m * 1e3:.0f} mm in the plane) "
                f"against {blur:.0f} px overall; not measured"
            )
        if blur > self.max_blur_px:
            # Motion blur: the beam's edges are ramps, and beyond a smear of its width
            # they have no plateau between them; the centroid of each scan line's light
            # is its centre at mid-exposure (edge estimators are biased there).
            smear_px = float(np.percentile(spread, 99))
            pa, pb = self._centroid_points(image, rough, clamp, e, n, hub_w, w_beam, smear_px)
        margin = _END_MARGIN_PX * px_m
        sd_hub_edges, e_hub = math.nan, None
        if hub_pts is not None and float((clamp - back) @ e) >= max(20 * px_m, 2.0 * hub_w):
            # A long hub: its axis from its two long edges alone (the direction's noise
            # falls as length^-1.5), a start for the joint fit and a check on it.
            e_hub, _, _, hub_w, sd_hub_edges = hub_axis(*hub_pts, back, clamp, e, margin)
            e = e_hub
        hub_a, hub_b = _clear_of_faces(hub_pts, back, clamp, e, margin)
        # The axis and the clamped centre line together: the beam leaves the clamp, on
        # the axis a known distance from the pivot (the plane's origin), along the axis.
        # Edge points lie half the beam's width from its centre line along the normal
        # (1 / cos(slope) across the axis): the slope first from the rough centre line,
        # then from the previous fit. Smeared beams give centres, not edges: none.
        joint = None
        edges = smear_px == 0.0
        slope_fn = _rough_slope(rough, clamp, e) if edges else None
        for _ in range(6):
            d_clamp = float(clamp @ e)
            la, lb, ha, hb, amax = self._frame(pa, pb, hub_a, hub_b, d_clamp, e, hub_w, length)
            res = fit_clamped_joint(
                la, lb, ha, hb, self.poly_degree, amax, d_clamp, edge_slope=slope_fn
            )
            if isinstance(res, str):
                raise FrameFailure(res)
            joint = res
            if edges:
                slope_fn = joint.fit.centre.deriv
            turn = joint.rotation_rad
            c, sn = math.cos(turn), math.sin(turn)
            e = np.array([c * e[0] - sn * e[1], sn * e[0] + c * e[1]])
            # The fitted shape is already in the turned frame to first order; what a
            # turn below 1e-4 rad leaves is below 1e-10 m at the tip: no second fit.
            if abs(turn) < _SMALL_TURN_RAD:
                break
        assert joint is not None
        sd_hub = joint.rotation_sd_rad
        sd_tip = joint.fit.tip_sd
        poly_fit = joint.fit  # the generic shape: the checks on the edges' residuals
        if self.shape_modes > 0:
            modal = self._modal(pa, pb, hub_a, hub_b, e, clamp, hub_w, length, joint, amax, edges)
            if modal is not None:
                e, joint, amax, sd_hub, sd_tip = modal
                d_clamp = float(clamp @ e)
        n = np.array([-e[1], e[0]])
        clamp = d_clamp * e
        # The width the frame measured: the joint fit's, from the hub's two long edges
        # as straight lines. Where they are none (a bar lying against part of one: the
        # fit then took the root alone, or left the stepped part out, or kept it in one
        # run of residuals) the frame did not measure it: NaN. The width the steps
        # worked with is kept apart (where to look, not a measurement: the rough
        # locator's reads 44 mm on a 40 mm hub).
        hub_w_measured, hub_w_sd = math.nan, math.nan
        if math.isfinite(joint.hub_width):
            hub_w = joint.hub_width
            hub_out, hub_rho = joint.hub_straightness()
            if hub_out <= _MAX_HUB_OUTLIER_FRACTION and hub_rho <= self.max_edge_correlation:
                hub_w_measured, hub_w_sd = hub_w, joint.hub_width_sd
        fit = joint.fit
        if e_hub is not None:
            gap = math.asin(max(-1.0, min(1.0, float(e_hub[0] * e[1] - e_hub[1] * e[0]))))
            if abs(gap) > 5.0 * math.hypot(sd_hub_edges, sd_hub):
                raise FrameFailure(
                    f"the hub's edges and the beam's root disagree on the hub angle by "
                    f"{math.degrees(gap):.3f} deg: hub or beam mis-measured"
                )
        centre, rms, width = fit.centre, fit.rms, fit.width
        if abs(width - w_beam) > 0.15 * w_beam:
            raise FrameFailure(
                f"beam width {width * 1e3:.1f} mm from its edges disagrees with the "
                f"{w_beam * 1e3:.1f} mm of its cross-profiles"
            )
        # A beam is a smooth curve: the edges' residuals from its fitted shape are the
        # image noise, correlated from one scan line to the next only through the
        # noise's own reach (up to 0.54 on every bench set). Residuals that run together
        # (a shifted image block of a damaged JPEG, an occlusion) are a shape the beam
        # does not have.
        if poly_fit.outlier_fraction > _MAX_OUTLIER_FRACTION:
            raise FrameFailure(
                f"the beam's edges leave any smooth beam shape at "
                f"{poly_fit.outlier_fraction:.0%} of their points (outliers beyond "
                f"{TUKEY_C:.1f} sigma): damaged or occluded frame?"
            )
        if poly_fit.edge_rho > self.max_edge_correlation:
            raise FrameFailure(
                f"the beam's edges depart from a smooth beam in runs (residuals "
                f"{poly_fit.rms * 1e3:.2f} mm RMS, correlated {poly_fit.edge_rho:.2f} from "
                "line to line): "
                "damaged or occluded frame?"
            )
        # The clamped prior's check: a hub or beam mis-measured shows as a slope at the
        # root, beyond what the edges' noise explains (a noisy frame's slope is as
        # uncertain as its tip, which the uncertainty limit below refuses).
        slope_sd = fit.root_slope_sd_rad if math.isfinite(fit.root_slope_sd_rad) else 0.0
        if abs(fit.root_slope_rad) > max(self.max_root_slope_rad, 4.0 * slope_sd):
            raise FrameFailure(
                f"the beam leaves the clamp at {math.degrees(fit.root_slope_rad):.2f} deg to "
                "the hub axis (a clamped beam leaves along it): hub or beam mis-measured"
            )
        a_tip, b_tip = self._tip(image, clamp, e, n, centre, amax, w_beam)
        # The tip lies beyond the last edge point, along the centre line's tangent there:
        # its lateral carries the slope's uncertainty over that distance too.
        sd_tip = math.sqrt(sd_tip**2 + max(fit.extrapolation_var(a_tip - amax), 0.0))
        arc = arc_length(centre, a_tip)
        if abs(arc - length) > 0.02 * length:
            raise FrameFailure(
                f"beam length {arc * 1e3:.0f} mm along the centre line disagrees with "
                f"{length * 1e3:.0f} mm (occluded or out of view?)"
            )
        # Predicted noise of the tip's lateral deflection: the centre line's uncertainty
        # at its end, the axis's (fitted with it) included (``sd_tip`` above).
        if sd_tip > self.max_tip_std_m:
            raise FrameFailure(
                f"too noisy: tip lateral uncertainty {sd_tip * 1e3:.2f} mm "
                f"(edge scatter {rms * 1e3:.2f} mm; low contrast?)"
            )
        a_st = stations_to_a(centre, self.stations_m, a_tip)
        lat_st = centre(a_st)
        k = 200
        a_line = linspace(0.0, a_tip, k)
        b_line = centre(a_line)
        b_line[-1] = b_tip
        line_m = along_across(clamp, e, n, a_line, b_line)
        back = clamp + back_a * e
        # the centre line's and the hub's pixels in one mapping (point by point)
        both_px = cal.to_px(np.concatenate([line_m, [back, clamp]]))
        line_px, hub_px = both_px[:k], both_px[k:]
        return FrameMeasurement(
            ok=True,
            hub_angle_rad=float(math.atan2(e[1], e[0]) % (2 * math.pi)),
            tip_lateral_m=float(b_tip),
            tip_longitudinal_m=float(a_tip - length),
            stations_m=self.stations_m.copy(),
            lateral_at_stations_m=np.asarray(lat_st, dtype=np.float64),
            centreline_plane_m=line_m,
            centreline_px=line_px,
            hub_line_px=hub_px,
            clamp_plane_m=clamp,
            tip_plane_m=line_m[-1].copy(),
            hub_width_m=hub_w_measured,
            hub_width_std_m=hub_w_sd,
            hub_width_located_m=hub_w,
            hub_angle_std_rad=sd_hub,
            tip_lateral_std_m=sd_tip,
            beam_width_m=width,
            edge_rms_m=rms,
            blur_px=blur,
            method="default",
        )

    def _modal(
        self,
        pa: NDArray[np.float64],
        pb: NDArray[np.float64],
        hub_a: NDArray[np.float64],
        hub_b: NDArray[np.float64],
        e: NDArray[np.float64],
        clamp: NDArray[np.float64],
        hub_w: float,
        length: float,
        poly: JointFit,
        amax_poly: float,
        edges: bool = True,
    ) -> tuple[NDArray[np.float64], JointFit, float, float, float] | None:
        """The axis and the shape fitted in the cantilever's mode space, starting from the
        polynomial fit's axis ``e``: (axis, fit, amax, hub sd, tip sd), or None when the
        modal fit fails, its shape test fails, or it disagrees with the generic clamped
        polynomial refitted in its frame on its inliers beyond 3 standard
        uncertainties of the difference on the hub angle or the tip (the polynomial's
        variance less the modal one's: the difference of an efficient and a consistent
        estimator, Hausman's test). The stated uncertainties include the modes' own
        error: their truncation (what two more modes change) and, pooled over the
        shape test's extra shapes, what of the polynomial's difference its noise does
        not explain. ``poly``: the polynomial fit (its
        centre line gives the edges' slope and the arc lengths)."""
        joint: JointFit | None = None
        amax = amax_poly
        for _ in range(4):
            d_clamp = float(clamp @ e)
            la, lb, ha, hb, amax = self._frame(pa, pb, hub_a, hub_b, d_clamp, e, hub_w, length)
            # what the fits of these points compute from them alone, kept for the
            # references below
            memo = PointsMemo()
            res = fit_clamped_joint(
                la,
                lb,
                ha,
                hb,
                self.poly_degree,
                amax,
                d_clamp,
                modes=self.shape_modes,
                beam_length=length,
                along=poly.fit.centre,
                edge_slope=poly.fit.centre.deriv if edges else None,
                memo=memo,
            )
            if isinstance(res, str):
                return None
            joint = res
            c, sn = math.cos(res.rotation_rad), math.sin(res.rotation_rad)
            e = np.array([c * e[0] - sn * e[1], sn * e[0] + c * e[1]])
            if abs(res.rotation_rad) < _MODAL_TURN_RAD:
                break
        if joint is None or not joint.shape_chi2 <= _chi2_999(joint.shape_dof):
            return None
        # The reference: the generic clamped polynomial refitted in the modes' frame on
        # their inliers (a degree-12 reference, nearly unbiased on a cantilever's shape,
        # turned the modes down on the foreign bench's frames, whose detected
        # registration bends the shape: 81 % measured against 100 %).
        # the modes' frame and inliers: the reference and the two-more-modes fit below
        refit = functools.partial(
            fit_clamped_joint,
            la,
            lb,
            ha,
            hb,
            self.poly_degree,
            amax,
            d_clamp,
            edge_slope=poly.fit.centre.deriv if edges else None,
            inliers=joint.inliers,
            memo=memo,
        )
        ref = refit()
        if isinstance(ref, str):
            return None
        gap = joint.rotation_rad - ref.rotation_rad
        var_gap = ref.rotation_sd_rad**2 - joint.rotation_sd_rad**2
        var_tip = ref.fit.tip_sd**2 - joint.fit.tip_sd**2
        if var_gap <= 0 or var_tip <= 0 or gap * gap > 9.0 * var_gap:
            return None
        # The tip's difference after the hub angle's: the modes' centre line is
        # tabulated when first read (1601 samples), which a refused axis spares.
        centre_at = np.array([amax])
        d_tip = float(joint.fit.centre(centre_at)[0]) - float(ref.fit.centre(centre_at)[0])
        if d_tip * d_tip > 9.0 * var_tip:
            return None
        # The modes' own error, in two parts. (1) Their truncation: the change that two
        # more modes make, fitted on the same inliers in the same frame (the whole
        # change, its noise included: small, since the next modes are smooth and well
        # determined). (2) A shape that is no cantilever's: the polynomial's
        # extra shapes, as far as they rise above their noise (the shape test's
        # chi-squared per degree of freedom beyond 1, the excess spread over the
        # difference's noise variance: the pooled estimate over all the extra shapes).
        # Formerly the whole difference from the polynomial: on a short clamp block
        # the polynomial's axis is 3-4 times noisier than the modes' (its shapes bend
        # freely at the root), so the modes stated about the polynomial's uncertainty
        # and two frames of 24 were refused at 0.53-0.57 mm with modal fits within
        # 0.2 mm. Part (2) alone (or d^2 - var_d) does not see the truncation on the
        # synthetic bench's swinging beams (one frame of 24 at 3.5-3.9 sd): four modes
        # leave 0.02 mrad of the hub angle there, on which five to ten modes agree.
        more = refit(
            modes=self.shape_modes + _MORE_MODES, beam_length=length, along=poly.fit.centre
        )
        if isinstance(more, str):
            return None
        gap = joint.rotation_rad - more.rotation_rad
        d_tip = float(joint.fit.centre(centre_at)[0]) - float(more.fit.centre(centre_at)[0])
        excess = max(joint.shape_chi2 / joint.shape_dof - 1.0, 0.0)
        sd_hub = math.sqrt(joint.rotation_sd_rad**2 + gap**2 + var_gap * excess)
        sd_tip = math.sqrt(joint.fit.tip_sd**2 + d_tip**2 + var_tip * excess)
        return e, joint, amax, sd_hub, sd_tip

    def _strip_points(
        self,
        image: NDArray[np.uint8],
        strips: list[tuple[NDArray[np.float64], float]],
    ) -> list[tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]]:
        """Edge points (plane, m) on both sides of strips ``(centre line (K, 2) m, half
        width m)``, scanned in one pass, and the ramp widths (px) of each point pair."""
        # Half width in pixels across the strip, point by point (perspective
        # foreshortens across and along differently): the lines and their points offset
        # by the half width along the normal, mapped in one batch (:func:`_offsets_k`).
        sizes = list(itertools.accumulate([len(x) for x, _ in strips], initial=0))
        both = self.calibration.to_px(
            _offsets_k(
                np.vstack([x for x, _ in strips]),
                np.array(sizes, dtype=np.intp),
                np.array([h for _, h in strips], dtype=np.float64),
            )
        )
        px, off = both[: sizes[-1]], both[sizes[-1] :]
        across = np.hypot(off[:, 0] - px[:, 0], off[:, 1] - px[:, 1])
        found = strip_edges_many(
            image,
            [(px[a:b], across[a:b]) for a, b in itertools.pairwise(sizes)],
            estimator=self.edge_estimator,
        )
        kept = []
        for edges in found:
            if len(edges.side_a) < 5:
                raise FrameFailure("too few edge points (strip not visible)")
            # the lines of more than 0.35 of the strip's median contrast
            kept.append(
                _strong_k(
                    np.ascontiguousarray(edges.side_a, dtype=np.float64),
                    np.ascontiguousarray(edges.side_b, dtype=np.float64),
                    np.ascontiguousarray(edges.contrast, dtype=np.float64),
                    np.ascontiguousarray(edges.spread, dtype=np.float64),
                )
            )
        plane = self.calibration.to_plane(np.concatenate([p for p, _ in kept]))
        out, i = [], 0
        for _, spread in kept:
            m = len(spread)
            out.append((plane[i : i + m], plane[i + m : i + 2 * m], spread))
            i += 2 * m
        return out

    def _scan(
        self,
        image: NDArray[np.uint8],
        rough: Rough,
        back: NDArray[np.float64],
        clamp: NDArray[np.float64],
        e: NDArray[np.float64],
        n: NDArray[np.float64],
        hub_w: float,
        w_beam: float,
    ) -> tuple[tuple[NDArray, NDArray] | None, tuple[NDArray, NDArray], NDArray[np.float64]]:
        """Edge points (plane, m) of the hub (past both its faces, along the rough axis;
        None when it is too short to show any clear of them) and of the beam (along its
        rough centre line, from past the shoulders to short of the tip), the two strips
        scanned in one pass; and the beam edges' ramp widths (px)."""
        hub_len = float((clamp - back) @ e)
        with_hub = hub_len - 2 * _END_MARGIN_PX * self.px_m >= 8 * self.px_m
        # A scan line (a pixel row or column) crosses the hub's two edges up to a hub
        # width apart along the axis: scan past both faces, keep points clear of them.
        ext = 0.5 * hub_w
        t = linspace(-ext, hub_len + ext, max(8, int((hub_len + 2 * ext) / self.px_m / 3)))
        hub_line = back[None, :] + t[:, None] * e[None, :]
        # The beam from past the clamp (its first scan lines would cross the shoulders)
        # to short of the tip (its last ones, the end face), on the rough centre line.
        rel = rough.beam - clamp
        a, b = rel @ e, rel @ n
        order = np.argsort(a)
        a, b = a[order], b[order]
        a_end = float((rough.tip - clamp) @ e)
        a0 = self._beam_start(hub_w)
        a1 = a_end - 0.6 * w_beam - 4 * self.px_m
        if a1 - a0 < 0.3 * self.calibration.beam_length_m:
            raise FrameFailure("beam too short in view")
        aq = linspace(a0, a1, max(20, int((a1 - a0) / (2 * self.px_m))))
        bq = np.interp(aq, a, b)
        beam_line = along_across(clamp, e, n, aq, bq)
        if not with_hub:
            ((pa, pb, spread),) = self._strip_points(image, [(beam_line, 0.5 * w_beam)])
            return None, (pa, pb), spread
        (ha, hb, _), (pa, pb, spread) = self._strip_points(
            image, [(hub_line, 0.5 * hub_w), (beam_line, 0.5 * w_beam)]
        )
        return (ha, hb), (pa, pb), spread

    def _centroid_points(
        self,
        image: NDArray[np.uint8],
        rough: Rough,
        clamp: NDArray[np.float64],
        e: NDArray[np.float64],
        n: NDArray[np.float64],
        hub_w: float,
        w_beam: float,
        smear_px: float,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """A smeared beam's centre points (plane, m): the centroids of its light on cuts
        along its local normal every 2 px, sampled every half pixel in the plane, the
        background a line under each cut (its level the median of the cut's ends, its
        slope the light's gradient across the cuts, :func:`_background_slope`; a
        time-average's centroid is the time-averaged centre: mid-exposure for a motion
        nearly linear over it). Given as
        two interleaved "edges" half the beam's width either side across the hub axis,
        which is how the centre-line fit sees edges (each centroid used once)."""
        px_m = self.px_m
        reach_m = 1.5 * smear_px * px_m + 0.5 * w_beam + 3 * px_m
        if smear_px > self.max_smear_px:
            raise FrameFailure(
                f"motion blur: beam edges spread up to {smear_px:.0f} px "
                f"({smear_px * px_m * 1e3:.0f} mm of smear in the plane; measured up to "
                f"{self.max_smear_px:.0f} px)"
            )
        rel = rough.beam - clamp
        a, b = rel @ e, rel @ n
        order = np.argsort(a)
        a, b = a[order], b[order]
        a0 = self._beam_start(hub_w)
        a1 = float((rough.tip - clamp) @ e) - 0.6 * w_beam - 4 * px_m
        aq = linspace(a0, a1, max(20, int((a1 - a0) / (2 * px_m))))
        bq = np.interp(aq, a, b)
        # Cuts across the beam along its local normal, sampled evenly in the plane (so the
        # centroid is the plane's; a cut oblique to a band whose smear grows along the
        # beam would see one side wider than the other).
        th = np.arctan(np.gradient(bq, aq))
        nl = np.column_stack([-np.sin(th), np.cos(th)])  # hub frame (a, b)
        t = np.arange(-reach_m, reach_m + 1e-12, 0.5 * px_m)
        ca = aq[:, None] + t[None, :] * nl[:, 0:1]
        cb = bq[:, None] + t[None, :] * nl[:, 1:2]
        pts = clamp + ca.reshape(-1, 1) * e[None, :] + cb.reshape(-1, 1) * n[None, :]
        prof = bilinear(image, self.calibration.to_px(pts)).reshape(ca.shape)
        ok_line = np.all(np.isfinite(prof), axis=1)
        prof, aq, bq, nl = prof[ok_line], aq[ok_line], bq[ok_line], nl[ok_line]
        if len(prof) < 20:
            raise FrameFailure("too few cuts across the smeared beam inside the image")
        m_edge = max(3, int(4 * px_m / (0.5 * px_m)))
        # The background under a cut: a line, its slope across the cut the light's
        # gradient, smooth along the beam (a cut's own ends are too few pixels for it:
        # a slope's error moves the centroid by its second moment over the window, the
        # cube of the window's reach), its level the cut's own (the window is centred on
        # the centroid, so a level's error moves it little).
        slope = _background_slope(prof, t, m_edge, aq)
        ends = np.r_[0:m_edge, len(t) - m_edge : len(t)]
        flat = prof[:, ends] - slope[:, None] * t[None, ends]
        level = np.median(flat, axis=1)
        excess = prof - level[:, None] - slope[:, None] * t[None, :]
        # Re-centred once: the window then holds the light evenly about its centroid.
        half_n = len(t) // 2 - m_edge
        cen = np.zeros(len(prof))
        mass = np.ones(len(prof))
        idx = np.arange(len(t))[None, :]
        for _ in range(2):
            mid = np.round(cen / (0.5 * px_m)).astype(np.intp) + len(t) // 2
            inside = np.abs(idx - mid[:, None]) <= half_n
            ex = np.where(inside, excess, 0.0)
            mass = ex.sum(axis=1)
            cen = np.where(mass > 0, (ex * t[None, :]).sum(axis=1) / np.where(mass > 0, mass, 1), 0)
        keep = mass > 0.35 * median(mass)
        if keep.sum() < 20:
            raise FrameFailure("too few cuts across the smeared beam")
        ac = aq + cen * nl[:, 0]
        bc = bq + cen * nl[:, 1]
        ac, bc = ac[keep], bc[keep]
        ac, bc = ac[: 2 * (len(ac) // 2)], bc[: 2 * (len(bc) // 2)]  # pair up point by point
        cen_m = clamp + ac[:, None] * e[None, :] + bc[:, None] * n[None, :]
        half = 0.5 * w_beam * n[None, :]
        return cen_m[0::2] + half, cen_m[1::2] - half

    def _beam_start(self, hub_w: float) -> float:
        """Distance from the clamp (m) where the beam's edges start: scan lines nearer
        the clamp cross the hub's shoulders."""
        return 0.5 * hub_w + 4 * self.px_m

    def _frame(
        self,
        pa: NDArray[np.float64],
        pb: NDArray[np.float64],
        hub_a: NDArray[np.float64],
        hub_b: NDArray[np.float64],
        d_clamp: float,
        e: NDArray[np.float64],
        hub_w: float,
        length: float,
    ) -> tuple[
        NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], float
    ]:
        """The beam's edge points (:meth:`_beam_frame`) and the hub's (``hub_a``,
        ``hub_b``: all of them) in the hub frame of axis ``e`` through the clamp
        ``d_clamp`` along it, and the beam's largest ``a``: one kernel
        (:func:`_beam_frame_points`)."""
        ex, ey = float(e[0]), float(e[1])
        ox, oy = d_clamp * ex, d_clamp * ey
        la, lb, amax, swap = _beam_frame_points(
            np.ascontiguousarray(pa, dtype=np.float64),
            np.ascontiguousarray(pb, dtype=np.float64),
            ox,
            oy,
            ex,
            ey,
            -ey,
            ex,
            self._beam_start(hub_w),
        )
        if len(la) < 5 or amax < 0.3 * length:
            raise FrameFailure("beam too short in view")
        amax = float(max(amax, np.maximum.reduce(lb[:, 0])))
        n = np.array([-ey, ex])
        o = np.array([ox, oy])
        ha, hb = _columns(hub_a - o, e, n), _columns(hub_b - o, e, n)
        if swap:
            la, lb = lb, la
        return la, lb, ha, hb, amax

    def _beam_frame(
        self,
        pa: NDArray[np.float64],
        pb: NDArray[np.float64],
        clamp: NDArray[np.float64],
        e: NDArray[np.float64],
        n: NDArray[np.float64],
        hub_w: float,
        length: float,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The beam's edge points in the hub frame (a from the clamp along e, b along n),
        those clear of the shoulders, named by side: left (b above the other) first."""
        ha, hb, amax, swap = _beam_frame_points(
            np.ascontiguousarray(pa, dtype=np.float64),
            np.ascontiguousarray(pb, dtype=np.float64),
            float(clamp[0]),
            float(clamp[1]),
            float(e[0]),
            float(e[1]),
            float(n[0]),
            float(n[1]),
            self._beam_start(hub_w),
        )
        if len(ha) < 5 or amax < 0.3 * length:
            raise FrameFailure("beam too short in view")
        return (hb, ha) if swap else (ha, hb)

    def _tip(
        self,
        image: NDArray[np.uint8],
        clamp: NDArray[np.float64],
        e: NDArray[np.float64],
        n: NDArray[np.float64],
        centre: CentreLine | ModalCentreLine,
        amax: float,
        w_beam: float,
    ) -> tuple[float, float]:
        """The end face: along the centre line's tangent beyond the last edge points."""
        a_ref = amax
        at = np.array([a_ref])
        b_ref = float(centre(at)[0])
        slope = float(centre.deriv(at)[0])
        # (2-vectors as floats: numpy's element operations, without its calls)
        h = math.hypot(1.0, slope)
        t = (1.0 / h, slope / h)
        e0, e1, n0, n1 = float(e[0]), float(e[1]), float(n[0]), float(n[1])
        tx, ty = t[0] * e0 + t[1] * n0, t[0] * e1 + t[1] * n1
        tang, norm = np.array([tx, ty]), np.array([-ty, tx])
        c0, c1 = float(clamp[0]), float(clamp[1])
        origin = np.array([c0 + a_ref * e0 + b_ref * n0, c1 + a_ref * e1 + b_ref * n1])
        lat = np.array([-0.2 * w_beam, 0.0 * w_beam, 0.2 * w_beam])
        # The edge scans end 0.6 widths and 4 px short of the rough tip (``_scan``).
        dist = end_edge(
            image,
            origin,
            tang,
            norm,
            lat,
            0.6 * w_beam + 4 * self.px_m,
            1.2 * w_beam + 4 * self.px_m,
            to_px=self.calibration.to_px,
            px_m=self.px_m,
        )
        a_tip = a_ref + dist * t[0]
        b_tip = b_ref + dist * t[1]
        return float(a_tip), float(b_tip)


@kernel
def _beam_frame_points(
    pa: NDArray[np.float64],
    pb: NDArray[np.float64],
    cx: float,
    cy: float,
    ex: float,
    ey: float,
    nx: float,
    ny: float,
    a0: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64], float, bool]:
    """:meth:`Measurer._beam_frame` of the paired edge points ``pa``, ``pb`` (N, 2)
    about the clamp (cx, cy) along (ex, ey) and (nx, ny): the pairs with both beyond
    ``a0`` (a, b each), the largest a of ``pa``'s (-inf: none) and whether ``pb`` is the
    left side (the median of b_a - b_b negative)."""
    ha, hb = np.empty((pa.shape[0], 2)), np.empty((pa.shape[0], 2))
    m = 0
    amax = -math.inf
    for i in range(pa.shape[0]):
        dxa, dya = pa[i, 0] - cx, pa[i, 1] - cy
        dxb, dyb = pb[i, 0] - cx, pb[i, 1] - cy
        aa, ab = dxa * ex + dya * ey, dxb * ex + dyb * ey
        if aa > a0 and ab > a0:
            ha[m, 0], ha[m, 1] = aa, dxa * nx + dya * ny
            hb[m, 0], hb[m, 1] = ab, dxb * nx + dyb * ny
            amax = max(amax, aa)
            m += 1
    diff = np.empty(m)
    for i in range(m):
        diff[i] = ha[i, 1] - hb[i, 1]
    return ha[:m], hb[:m], amax, median_in_place(diff) < 0


@kernel
def _strong_k(
    side_a: NDArray[np.float64],
    side_b: NDArray[np.float64],
    contrast: NDArray[np.float64],
    spread: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """:meth:`Measurer._strip_points`' choice of a strip's lines: those of contrast
    above 0.35 of its median (:func:`~vision.sampling.median`'s), their side-a points
    then their side-b points (2K, 2), and their ramp widths (K)."""
    lim = 0.35 * median_in_place(contrast.copy())
    n = contrast.shape[0]
    m = 0
    for i in range(n):
        if contrast[i] > lim:
            m += 1
    pts, sp = np.empty((2 * m, 2)), np.empty(m)
    k = 0
    for i in range(n):
        if contrast[i] > lim:
            pts[k, 0], pts[k, 1] = side_a[i, 0], side_a[i, 1]
            pts[m + k, 0], pts[m + k, 1] = side_b[i, 0], side_b[i, 1]
            sp[k] = spread[i]
            k += 1
    return pts, sp


@kernel
def _offsets_k(
    lines: NDArray[np.float64], sizes: NDArray[np.intp], halves: NDArray[np.float64]
) -> NDArray[np.float64]:
    """:meth:`Measurer._strip_points`' points: the strips' centre lines (``lines[sizes[k]
    : sizes[k + 1]]``, each at least 2 points) and after them each point moved by its
    strip's half width along the line's unit normal (``(-t_y, t_x)``, ``t`` the unit
    step gradient: central differences, one-sided at the ends, as
    ``np.gradient(lines, axis=0)``)."""
    n = lines.shape[0]
    out = np.empty((2 * n, 2))
    for k in range(sizes.shape[0] - 1):
        lo, hi, half = sizes[k], sizes[k + 1], halves[k]
        for i in range(lo, hi):
            if i == lo:
                tx, ty = lines[i + 1, 0] - lines[i, 0], lines[i + 1, 1] - lines[i, 1]
            elif i == hi - 1:
                tx, ty = lines[i, 0] - lines[i - 1, 0], lines[i, 1] - lines[i - 1, 1]
            else:
                tx = (lines[i + 1, 0] - lines[i - 1, 0]) / 2.0
                ty = (lines[i + 1, 1] - lines[i - 1, 1]) / 2.0
            norm = math.hypot(tx, ty)
            tx, ty = tx / norm, ty / norm
            out[i, 0], out[i, 1] = lines[i, 0], lines[i, 1]
            out[n + i, 0] = lines[i, 0] + half * -ty
            out[n + i, 1] = lines[i, 1] + half * tx
    return out


def _background_slope(
    prof: NDArray[np.float64], t: NDArray[np.float64], m_edge: int, a: NDArray[np.float64]
) -> NDArray[np.float64]:
    """The background's slope (DN per m across each cut, at stations ``a`` along the
    beam) from the two ends of the cuts' profiles ``prof`` [cut, sample at ``t``]: each
    cut's end medians give a slope, a quadratic in ``a`` fitted to them with Tukey's
    weights (an end on the hub, the plate or the other side's clutter is an outlier)."""
    left = np.median(prof[:, :m_edge], axis=1)
    right = np.median(prof[:, -m_edge:], axis=1)
    span = float(t[-m_edge:].mean() - t[:m_edge].mean())
    raw = (right - left) / span
    u = (a - a.mean()) / max(float(np.ptp(a)), 1e-12)
    basis = np.column_stack([np.ones_like(u), u, u * u])
    w = np.ones_like(u)
    coef = np.zeros(3)
    for _ in range(6):
        sw = np.sqrt(w)
        coef = np.linalg.lstsq(basis * sw[:, None], raw * sw, rcond=None)[0]
        r = raw - basis @ coef
        sig = 1.4826 * float(np.median(np.abs(r))) + 1e-12
        z = r / (TUKEY_C * sig)
        w = np.where(np.abs(z) < 1.0, (1.0 - z * z) ** 2, 0.0)
    return np.asarray(basis @ coef, dtype=np.float64)


#: A frame is blank when the standard deviation of every 16th pixel of every 16th row
#: is below this (DN; an integer: its square is compared exactly).
_BLANK_STD = 2


def _blank(image: NDArray[np.uint8]) -> bool:
    """Whether ``image[::16, ::16].std() < _BLANK_STD``: decided from the samples'
    exact integer sums (:func:`_coarse_sums`; numpy's float ``std`` of them is a
    twentieth of a frame's measurement), and by numpy's own ``std`` where the exact
    variance lies within 1e-9 of the limit's square, where its rounding could decide."""
    n, s1, s2 = _coarse_sums(image)
    # n^2 var = n s2 - s1^2, in Python's integers (exact)
    limit = _BLANK_STD * _BLANK_STD * n * n
    gap = n * int(s2) - int(s1) * int(s1) - limit
    if abs(gap) * 10**9 <= limit or n > 10**7:
        return float(image[::16, ::16].std()) < _BLANK_STD
    return gap < 0


@kernel
def _coarse_sums(image: NDArray[np.uint8]) -> tuple[int, int, int]:
    """The count, sum and sum of squares of ``image[::16, ::16]`` (integers: exact)."""
    h, w = image.shape
    s1, s2 = 0, 0
    for i in range(0, h, 16):
        for j in range(0, w, 16):
            v = int(image[i, j])
            s1 += v
            s2 += v * v
    return ((h + 15) // 16) * ((w + 15) // 16), s1, s2


def _rough_slope(
    rough: Rough, clamp: NDArray[np.float64], e: NDArray[np.float64]
) -> Callable[[NDArray[np.float64]], NDArray[np.float64]]:
    """The rough centre line's slope ``db/da`` in the frame of axis ``e`` at the clamp,
    as a function of ``a``: a quartic through its points (the slope to ~1e-3, which
    leaves micrometres in the edges' half-width ``(w/2) / cos(theta)``)."""
    n = np.array([-e[1], e[0]])
    rel = rough.beam - clamp
    a, b = rel @ e, rel @ n
    scale = max(float(np.maximum.reduce(np.abs(a))), 1e-6)  # (np.max's reduction)
    deg = min(4, max(len(a) - 2, 0))
    if deg < 1:
        return lambda q: np.zeros_like(np.asarray(q, dtype=np.float64))
    # Least squares by the normal equations (a quartic in a / scale on [0, 1]: well
    # conditioned; a tenth of polyfit's SVD).
    vand = _vander_k(np.ascontiguousarray(a / scale), deg + 1)
    coef = np.linalg.solve(vand.T @ vand, vand.T @ b)
    der = np.ascontiguousarray(coef[1:] * np.arange(1, deg + 1), dtype=np.float64)

    def slope(q: NDArray[np.float64]) -> NDArray[np.float64]:
        # polyval(q / scale, der) / scale (:func:`_scaled_polyval_k`)
        x = np.ascontiguousarray(q, dtype=np.float64)
        return _scaled_polyval_k(x.reshape(-1), der, scale).reshape(x.shape)

    return slope


@kernel
def _vander_k(x: NDArray[np.float64], n: int) -> NDArray[np.float64]:
    """``np.vander(x, n, increasing=True)`` of float64 ``x``: 1, x, then each power the
    last times x (numpy's ``multiply.accumulate``)."""
    out = np.empty((x.shape[0], n))
    for i in range(x.shape[0]):
        if n > 0:
            out[i, 0] = 1.0
        if n > 1:
            out[i, 1] = x[i]
        for k in range(2, n):
            out[i, k] = out[i, k - 1] * x[i]
    return out


@kernel
def _scaled_polyval_k(
    q: NDArray[np.float64], c: NDArray[np.float64], scale: float
) -> NDArray[np.float64]:
    """``np.polynomial.polynomial.polyval(q / scale, c) / scale`` point by point
    (:func:`~vision.centreline._polyval_k`: Horner's rule as numpy runs it, for all the
    points at once by :func:`~vision.centreline._polyval_rows_k`)."""
    n = q.shape[0]
    x, out = np.empty(n), np.empty(n)
    for i in range(n):
        x[i] = q[i] / scale
    _polyval_rows_k(c, x, out)
    for i in range(n):
        out[i] = out[i] / scale
    return out


def _columns(
    d: NDArray[np.float64], e: NDArray[np.float64], n: NDArray[np.float64]
) -> NDArray[np.float64]:
    """``np.column_stack([d @ e, d @ n])`` of points ``d`` (N, 2), without its
    wrapper's calls (the products stay numpy's: BLAS rounds them its own way)."""
    out = np.empty((len(d), 2))
    out[:, 0] = d @ e
    out[:, 1] = d @ n
    return out


def _kth(x: NDArray[np.float64], k: int) -> float:
    """``np.partition(x, k)[k]`` of a float64 vector: its k-th smallest value, NaN where
    k reaches the NaNs numpy sorts last (:func:`_kth_k`)."""
    return float(_kth_k(np.ascontiguousarray(x, dtype=np.float64), k))


@kernel
def _kth_k(x: NDArray[np.float64], k: int) -> float:
    """:func:`_kth`: the finite values' (and infinities') k-th by selection on a copy."""
    w = np.empty(x.shape[0])
    m = 0
    for i in range(x.shape[0]):
        if x[i] == x[i]:
            w[m] = x[i]
            m += 1
    if k >= m:
        return math.nan
    select_kth(w, k, m)
    return w[k]


def _clear_of_faces(
    hub_pts: tuple[NDArray[np.float64], NDArray[np.float64]] | None,
    back: NDArray[np.float64],
    front: NDArray[np.float64],
    e: NDArray[np.float64],
    margin: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The hub's edge points (plane, m) ``margin`` clear of its end faces (none when the
    hub gave none)."""
    if hub_pts is None:
        return np.zeros((0, 2)), np.zeros((0, 2))
    length = float((front - back) @ e)
    out = []
    for p in hub_pts:
        sa = (p - back) @ e
        out.append(p[(sa > margin) & (sa < length - margin)])
    return out[0], out[1]
