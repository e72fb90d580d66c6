"""Camera-to-DAQ time alignment.

The camera and the DAQ run on different clocks. The paper matched its stills to the
potentiometer record through the rocker extrema ("dial zeros"); here every frame's
image hub angle is matched against the potentiometer angle: the offset ``dt``, the
camera clock's rate error ``k`` (crystal drift, tens of ppm: 0.4 ms over 20 s at 20 ppm,
0.05 mm of tip swing) and a constant angle offset ``c`` between the image's plane frame
and the potentiometer's zero minimise

    sum_i (hub_image_i - c - rocker(t_i + dt + k (t_i - t_ref)))^2

over the frames that gave a measurement, with ``rocker`` interpolated from the 400 Hz
stream and ``t_ref`` the middle of the frames. ``dt`` is found first (``k = 0``; ``c``
has a closed form for each ``dt``) by a coarse scan and a bounded scalar minimisation,
then ``dt``, ``k`` and ``c`` together by nonlinear least squares.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.interpolate import CubicSpline
from scipy.optimize import least_squares, minimize_scalar


@dataclass(frozen=True)
class Alignment:
    """Result of matching image hub angles to the potentiometer angle.

    A camera timestamp ``t`` maps to DAQ time ``t + offset_s + drift_ppm * 1e-6 *
    (t - reference_time_s)`` (:meth:`to_daq_time`). ``angle_offset_rad`` is image hub
    angle minus rocker angle. ``rms_residual_rad`` is over the frames used. ``ok`` is
    False (with a reason) when the data cannot determine the offset.
    """

    offset_s: float
    angle_offset_rad: float
    rms_residual_rad: float
    n_frames: int
    ok: bool
    reason: str = ""
    drift_ppm: float = 0.0
    reference_time_s: float = 0.0

    def to_daq_time(self, t_cam_s: ArrayLike) -> np.ndarray:
        """Camera timestamps [s] on the DAQ clock [s]."""
        t = np.asarray(t_cam_s, dtype=float)
        return t + self.offset_s + self.drift_ppm * 1e-6 * (t - self.reference_time_s)


def _wrap(a: np.ndarray) -> np.ndarray:
    return (a + np.pi) % (2.0 * np.pi) - np.pi


def estimate_offset(
    frame_t_s: ArrayLike,
    hub_angle_image_rad: ArrayLike,
    daq_t_s: ArrayLike,
    rocker_angle_rad: ArrayLike,
    *,
    max_offset_s: float = 0.5,
) -> Alignment:
    """Estimate the camera-to-DAQ offset; see the module docstring.

    Parameters
    ----------
    frame_t_s : (F,) camera timestamps [s] (NaN-free); frames with NaN angle are skipped.
    hub_angle_image_rad : (F,) hub angle from the images [rad].
    daq_t_s, rocker_angle_rad : (N,) the potentiometer stream [s], [rad].
    max_offset_s : search half-width [s].
    """
    tf = np.asarray(frame_t_s, dtype=float)
    hf = np.asarray(hub_angle_image_rad, dtype=float)
    td = np.asarray(daq_t_s, dtype=float)
    rd = np.asarray(rocker_angle_rad, dtype=float)
    if tf.shape != hf.shape or td.shape != rd.shape:
        raise ValueError("frame and DAQ arrays must pair up (same shapes)")
    if not max_offset_s > 0:
        raise ValueError(f"max_offset_s must be positive, got {max_offset_s!r}")
    good_daq = np.isfinite(td) & np.isfinite(rd)
    td, rd = td[good_daq], rd[good_daq]
    if td.size < 4 or np.any(np.diff(td) <= 0):
        return Alignment(math.nan, math.nan, math.nan, 0, False, "too few or unordered DAQ samples")
    rocker = CubicSpline(td, np.unwrap(rd), extrapolate=False)
    use = np.isfinite(tf) & np.isfinite(hf)
    use &= (tf > td[0] + max_offset_s) & (tf < td[-1] - max_offset_s)
    tf, hf = tf[use], hf[use]
    if tf.size < 3:
        return Alignment(
            math.nan, math.nan, math.nan, int(tf.size), False, "fewer than 3 measured frames"
        )

    def cost(dt: float) -> tuple[float, float]:
        r = _wrap(hf - rocker(tf + dt))
        c = math.atan2(float(np.mean(np.sin(r))), float(np.mean(np.cos(r))))
        res = _wrap(r - c)
        return float(np.mean(res**2)), c

    # The scan step must resolve the motion: a fraction of the frame interval is plenty
    # because the cost is smooth in dt (the rocker angle is band-limited).
    scan = np.linspace(-max_offset_s, max_offset_s, 401)
    costs = np.array([cost(float(dt))[0] for dt in scan])
    k = int(np.argmin(costs))
    lo = scan[max(k - 1, 0)]
    hi = scan[min(k + 1, scan.size - 1)]
    best = minimize_scalar(
        lambda dt: cost(dt)[0], bounds=(lo, hi), method="bounded", options={"xatol": 1e-7}
    )
    dt = float(best.x)
    mse, c = cost(dt)
    spread = float(np.std(rocker(tf + dt)))
    if spread < 1e-3:
        return Alignment(
            dt,
            c,
            math.sqrt(mse),
            int(tf.size),
            False,
            "the rocker barely moved: offset undetermined",
        )
    if k in (0, scan.size - 1):
        return Alignment(
            dt,
            c,
            math.sqrt(mse),
            int(tf.size),
            False,
            f"best offset at the search limit (+/-{max_offset_s} s)",
        )
    return _with_drift(tf, hf, rocker, dt, c)


def _with_drift(
    tf: np.ndarray, hf: np.ndarray, rocker: CubicSpline, dt: float, c: float
) -> Alignment:
    """Refine (dt, k, c) together from the offset-only optimum."""
    t_ref = float(0.5 * (tf[0] + tf[-1]))
    span = float(tf[-1] - tf[0])

    def residual(p: np.ndarray) -> np.ndarray:
        dt_, k_ppm, c_ = p
        res: np.ndarray = _wrap(hf - c_ - rocker(tf + dt_ + k_ppm * 1e-6 * (tf - t_ref)))
        return res

    # x_scale: the parameters move by ~1 ms, ~10 ppm and ~1 mrad
    fit = least_squares(
        residual, np.array([dt, 0.0, c]), x_scale=np.array([1e-3, 10.0, 1e-3]), method="lm"
    )
    dt_, k_ppm, c_ = (float(v) for v in fit.x)
    rms = float(np.sqrt(np.mean(fit.fun**2)))
    # the drift is only believed when it moves the run's ends by less than a frame gap
    if not np.all(np.isfinite(fit.x)) or abs(k_ppm) * 1e-6 * span > 0.05:
        mse = float(np.mean(residual(np.array([dt, 0.0, c])) ** 2))
        return Alignment(dt, c, math.sqrt(mse), int(tf.size), True, reference_time_s=t_ref)
    return Alignment(dt_, c_, rms, int(tf.size), True, drift_ppm=k_ppm, reference_time_s=t_ref)
