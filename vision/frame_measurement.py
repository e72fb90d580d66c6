"""The record of one frame's measurement, whichever method made it."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

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
    hub_width_m, beam_width_m : widths measured in the frame (``hub_width_m`` from the
        hub's two long edges as straight lines: NaN where they are not, e.g. a bar lying
        against one of them, or where the hub shows none clear of its end faces).
    hub_width_std_m : the standard uncertainty of ``hub_width_m`` (noise only, from
        the fit's covariance).
    hub_width_located_m : the hub's width the measurement worked with: ``hub_width_m``
        where measured, else the hub locator's rough one (a search width: where to look
        in the next frame, not a measurement).
    edge_rms_m : RMS residual of the beam edge fits.
    hub_angle_std_rad, tip_lateral_std_m : standard uncertainties predicted from the edge
        fits' residuals (noise only; the calibration's error, common to all frames, is
        :mod:`vision.calibration_error`'s).
    blur_px : median ramp width of the beam's edges along the scan lines, px (motion blur
        widens it; frames beyond ``max_blur_px`` are flagged).

    :meth:`to_dict` carries the standard uncertainties beside the values
    (``hub_angle_sd_rad``, ``tip_lateral_sd_m``).
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
    hub_width_std_m: float = math.nan
    hub_width_located_m: float = math.nan

    @property
    def hub_search_width_m(self) -> float:
        """The hub's width to look for it with (the next frame's regions, the recording's
        previews): the one the measurement worked with (on a frame whose hub edges were no
        straight lines, the rough locator's: the measured width is then NaN), else the
        reported one (a measurement made without it)."""
        w = self.hub_width_located_m
        return w if math.isfinite(w) else self.hub_width_m

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
            "hub_angle_sd_rad": num(self.hub_angle_std_rad),
            "tip_lateral_sd_m": num(self.tip_lateral_std_m),
        }
