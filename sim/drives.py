"""Prescribed hub motions: angle, rate and acceleration as functions of time.

Every drive is vectorised over ``t_s`` and returns radians, rad/s and rad/s^2. The hub
angle is measured in the frame the drive names (for the paper's sinusoid: about
mid-stroke); beam models only use it through its derivatives and the rotation of the
hub frame, so a constant offset does not change the deflection.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sim.errors import SimInputError

FloatArray = NDArray[np.float64]


@runtime_checkable
class Drive(Protocol):
    """A prescribed hub angle Phi(t) with consistent first and second derivatives."""

    def angle(self, t_s: ArrayLike) -> FloatArray: ...

    def rate(self, t_s: ArrayLike) -> FloatArray: ...

    def accel(self, t_s: ArrayLike) -> FloatArray: ...


@dataclass(frozen=True)
class SinusoidDrive:
    """Phi = amplitude * sin(omega * t + phase) (paper Eq. 53: 0.7669 sin(4.970 t))."""

    amplitude_rad: float = 0.7669
    omega_rad_s: float = 4.970
    phase_rad: float = 0.0

    def angle(self, t_s: ArrayLike) -> FloatArray:
        t = np.asarray(t_s, dtype=float)
        return self.amplitude_rad * np.sin(self.omega_rad_s * t + self.phase_rad)

    def rate(self, t_s: ArrayLike) -> FloatArray:
        t = np.asarray(t_s, dtype=float)
        return self.amplitude_rad * self.omega_rad_s * np.cos(self.omega_rad_s * t + self.phase_rad)

    def accel(self, t_s: ArrayLike) -> FloatArray:
        t = np.asarray(t_s, dtype=float)
        w = self.omega_rad_s
        return -self.amplitude_rad * w * w * np.sin(w * t + self.phase_rad)

    def time_scale_s(self) -> float:
        """The shortest period in the motion, s (see :func:`drive_time_scale_s`)."""
        w = abs(self.omega_rad_s)
        return 2.0 * math.pi / w if w > 0.0 else math.inf


def _times(t_s: ArrayLike) -> FloatArray:
    return np.asarray(t_s, dtype=float)


class FourBarDrive:
    """The hub angle the crank-rocker itself produces at a constant crank speed.

    Parameters
    ----------
    four_bar : a ``sim.four_bar.FourBar`` (any object with ``rocker_angle_rad``,
        ``rocker_rate_rad_s``, ``rocker_accel_rad_s2`` and ``extrema()``).
    crank_speed_rad_s : crank angular speed (rad/s; 2 pi * 0.92 Hz on the bench).
    about : ``"mid"``: rocker angle minus mid-stroke (the true dead-centre extrema's mean),
        like the paper's Eq. 53; ``"absolute"``: the rocker angle in the frame of Eqs. 1-2.
    crank_phase_rad : crank angle at t = 0.
    """

    def __init__(
        self,
        four_bar: object,
        crank_speed_rad_s: float,
        about: str = "mid",
        crank_phase_rad: float = 0.0,
    ) -> None:
        for attr in ("rocker_angle_rad", "rocker_rate_rad_s", "rocker_accel_rad_s2", "extrema"):
            if not hasattr(four_bar, attr):
                raise TypeError(f"four_bar must be a sim.four_bar.FourBar, lacks {attr}")
        if not np.isfinite(crank_speed_rad_s) or crank_speed_rad_s == 0.0:
            raise SimInputError(
                "crank_speed_rad_s", f"must be a finite non-zero number, got {crank_speed_rad_s!r}"
            )
        if about not in ("mid", "absolute"):
            raise SimInputError("about", f"must be 'mid' or 'absolute', got {about!r}")
        if not np.isfinite(crank_phase_rad):
            raise SimInputError("crank_phase_rad", f"must be finite, got {crank_phase_rad!r}")
        self.four_bar = four_bar
        self.crank_speed_rad_s = float(crank_speed_rad_s)
        self.about = about
        self.crank_phase_rad = float(crank_phase_rad)
        self.offset_rad = four_bar.extrema().mid_rad if about == "mid" else 0.0  # type: ignore[attr-defined]

    def crank_angle_rad(self, t_s: ArrayLike) -> FloatArray:
        return self.crank_phase_rad + self.crank_speed_rad_s * _times(t_s)

    def angle(self, t_s: ArrayLike) -> FloatArray:
        fb = self.four_bar
        return np.asarray(fb.rocker_angle_rad(self.crank_angle_rad(t_s)) - self.offset_rad)  # type: ignore[attr-defined]

    def rate(self, t_s: ArrayLike) -> FloatArray:
        fb = self.four_bar
        psi = self.crank_angle_rad(t_s)
        return np.asarray(fb.rocker_rate_rad_s(psi, self.crank_speed_rad_s))  # type: ignore[attr-defined]

    def accel(self, t_s: ArrayLike) -> FloatArray:
        fb = self.four_bar
        psi = self.crank_angle_rad(t_s)
        return np.asarray(fb.rocker_accel_rad_s2(psi, self.crank_speed_rad_s, 0.0))  # type: ignore[attr-defined]


END_PAD_S = 0.2
END_FIT_S = 0.15


def _pad_ends(t: FloatArray, y: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The trace extended at both ends by a local cubic fit (see :class:`TraceDrive`)."""
    span = float(t[-1] - t[0])
    fit_s = min(END_FIT_S, 0.25 * span)
    dt = span / max(t.size - 1, 1)
    n_pad = round(min(END_PAD_S, span) / dt)
    if n_pad < 1:
        return t, y
    pieces_t, pieces_y = [], []
    for side in (0, 1):
        near = t <= t[0] + fit_s if side == 0 else t >= t[-1] - fit_s
        if near.sum() < 5:
            return t, y
        origin = t[0] if side == 0 else t[-1]
        coef = np.polyfit(t[near] - origin, y[near], 3)
        steps = dt * np.arange(1, n_pad + 1)
        tt = origin - steps[::-1] if side == 0 else origin + steps
        pieces_t.append(tt)
        pieces_y.append(np.polyval(coef, tt - origin))
    return (
        np.concatenate([pieces_t[0], t, pieces_t[1]]),
        np.concatenate([pieces_y[0], y, pieces_y[1]]),
    )


GCV_WINDOW = 600  # samples: 1.5 s at 400 Hz, more than one rocker cycle (1.09 s)


def _gcv_smoothing(t: FloatArray, y: FloatArray) -> float:
    """The smoothing penalty chosen by generalised cross-validation on a central window.

    The penalty depends on the noise level and the signal's smoothness, not on the
    trace's length, while scipy's GCV search costs ~0.4 ms per sample (10 s for a minute
    at 400 Hz); so it runs on at most ``GCV_WINDOW`` samples. scipy does not return the
    penalty it chose, so it is recovered as the one whose fit leaves the same residual
    (the residual grows monotonically with the penalty).
    """
    from scipy.interpolate import make_smoothing_spline
    from scipy.optimize import brentq

    if t.size > GCV_WINDOW:
        i0 = (t.size - GCV_WINDOW) // 2
        t, y = t[i0 : i0 + GCV_WINDOW], y[i0 : i0 + GCV_WINDOW]
    rss_gcv = float(np.sum((make_smoothing_spline(t, y)(t) - y) ** 2))

    def miss(log_lam: float) -> float:
        fit = make_smoothing_spline(t, y, lam=math.exp(log_lam))
        return math.log(float(np.sum((fit(t) - y) ** 2)) + 1e-300) - math.log(rss_gcv + 1e-300)

    lo, hi = math.log(1e-16), math.log(1e2)
    if rss_gcv <= 0.0 or miss(lo) >= 0.0:
        return 0.0
    if miss(hi) <= 0.0:
        return math.exp(hi)
    return math.exp(brentq(miss, lo, hi, xtol=1e-3))


def finite_trace(
    t_s: ArrayLike, angle_rad: ArrayLike, n_min: int
) -> tuple[NDArray[Any], NDArray[Any]]:
    """A measured trace's finite samples, checked: ``t_s`` finite and strictly increasing,
    ``angle_rad`` of its length with at least ``n_min`` finite values (NaN marks a gap).
    Raises ``SimInputError``."""
    t = np.asarray(t_s, dtype=np.float64).reshape(-1)
    y = np.asarray(angle_rad, dtype=np.float64).reshape(-1)
    if t.shape != y.shape:
        raise SimInputError("angle_rad", f"must have the length of t_s, got {y.size} and {t.size}")
    if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0.0):
        raise SimInputError("t_s", "must be finite and strictly increasing")
    ok = np.isfinite(y)
    if ok.sum() < n_min:
        raise SimInputError(
            "angle_rad", f"needs at least {n_min} finite samples, got {int(ok.sum())}"
        )
    return t[ok], y[ok]


class TraceDrive:
    """A measured hub-angle trace (e.g. the 400 Hz potentiometer), smoothed.

    A cubic smoothing spline (``scipy.interpolate.make_smoothing_spline``) through the
    finite samples; its first and second derivatives are the rate and acceleration, so the
    three are consistent. NaN samples (gaps) are dropped.

    A smoothing spline is natural: its acceleration is forced to zero at its ends, which
    is wrong for a trace cut mid-swing (on the bench, 0.5 rad/s^2 ... 25 rad/s^2). So the
    trace is extended by ``END_PAD_S`` at each end with a cubic fitted to its last
    ``END_FIT_S``, and the natural end conditions act out there, beyond the data.

    Parameters
    ----------
    t_s : (N,) sample times, strictly increasing, s.
    angle_rad : (N,) hub angle, rad; NaN marks a missing sample.
    smoothing : the spline's penalty lambda (s^3 units of the second-derivative penalty);
        ``None`` chooses it by generalised cross-validation.
    """

    def __init__(
        self, t_s: ArrayLike, angle_rad: ArrayLike, smoothing: float | None = None
    ) -> None:
        from scipy.interpolate import make_smoothing_spline

        t, y = finite_trace(t_s, angle_rad, 5)
        if smoothing is not None and (not np.isfinite(smoothing) or smoothing < 0.0):
            raise SimInputError(
                "smoothing", f"must be a non-negative number or None, got {smoothing!r}"
            )
        self.t_min_s = float(t[0])
        self.t_max_s = float(t[-1])
        tp, yp = _pad_ends(t, y)
        if smoothing is None:
            smoothing = _gcv_smoothing(tp, yp)
        self.smoothing = smoothing
        self._spline = make_smoothing_spline(tp, yp, lam=smoothing)
        self._d1 = self._spline.derivative(1)
        self._d2 = self._spline.derivative(2)

    def _check(self, t_s: ArrayLike) -> FloatArray:
        t = _times(t_s)
        span = self.t_max_s - self.t_min_s
        if np.any(t < self.t_min_s - 1e-9 * span) or np.any(t > self.t_max_s + 1e-9 * span):
            raise SimInputError(
                "t_s", f"must lie within the trace, [{self.t_min_s!r}, {self.t_max_s!r}] s"
            )
        return t

    def angle(self, t_s: ArrayLike) -> FloatArray:
        return np.asarray(self._spline(self._check(t_s)), dtype=float)

    def rate(self, t_s: ArrayLike) -> FloatArray:
        return np.asarray(self._d1(self._check(t_s)), dtype=float)

    def accel(self, t_s: ArrayLike) -> FloatArray:
        return np.asarray(self._d2(self._check(t_s)), dtype=float)


@dataclass(frozen=True)
class SpinUpDrive:
    """The Kane et al. / Simo-Vu-Quoc spin-up profile.

    theta = (w_s / T_s) (t^2 / 2 + (T_s / 2 pi)^2 (cos(2 pi t / T_s) - 1)) for 0 <= t < T_s,
    theta = w_s (t - T_s / 2) afterwards, and at rest before t = 0; the acceleration
    (w_s / T_s)(1 - cos(2 pi t / T_s)) is continuous.
    """

    omega_s_rad_s: float
    ramp_s: float = 15.0

    def __post_init__(self) -> None:
        if not np.isfinite(self.omega_s_rad_s):
            raise SimInputError("omega_s_rad_s", f"must be finite, got {self.omega_s_rad_s!r}")
        if not np.isfinite(self.ramp_s) or self.ramp_s <= 0.0:
            raise SimInputError("ramp_s", f"must be a positive finite number, got {self.ramp_s!r}")

    def angle(self, t_s: ArrayLike) -> FloatArray:
        t = _times(t_s)
        w, ts = self.omega_s_rad_s, self.ramp_s
        k = ts / (2.0 * np.pi)
        tc = np.clip(t, 0.0, ts)
        ramp = (w / ts) * (0.5 * tc * tc + k * k * (np.cos(tc / k) - 1.0))
        return np.where(t < ts, ramp, w * (t - 0.5 * ts))

    def rate(self, t_s: ArrayLike) -> FloatArray:
        t = _times(t_s)
        w, ts = self.omega_s_rad_s, self.ramp_s
        k = ts / (2.0 * np.pi)
        tc = np.clip(t, 0.0, ts)
        return (w / ts) * (tc - k * np.sin(tc / k))

    def accel(self, t_s: ArrayLike) -> FloatArray:
        t = _times(t_s)
        w, ts = self.omega_s_rad_s, self.ramp_s
        inside = (t >= 0.0) & (t < ts)
        return np.where(
            inside, (w / ts) * (1.0 - np.cos(2.0 * np.pi * np.clip(t, 0.0, ts) / ts)), 0.0
        )


@dataclass(frozen=True)
class FixedDrive:
    """A hub held still at ``angle_rad`` (free decay, statics)."""

    angle_rad: float = 0.0

    def angle(self, t_s: ArrayLike) -> FloatArray:
        return np.full(np.shape(t_s), self.angle_rad, dtype=float)

    def rate(self, t_s: ArrayLike) -> FloatArray:
        return np.zeros(np.shape(t_s))

    def accel(self, t_s: ArrayLike) -> FloatArray:
        return np.zeros(np.shape(t_s))

    def time_scale_s(self) -> float:
        """No motion: no time scale (see :func:`drive_time_scale_s`)."""
        return math.inf


def drive_time_scale_s(drive: object) -> float | None:
    """The shortest time scale of a drive's motion, s: the period of its highest harmonic,
    or the knot spacing of a spline (inside which it is a polynomial); ``math.inf`` for a
    hub at rest. None when the drive does not say (:class:`TraceDrive`'s cubic smoothing
    spline has a knot at every sample; :class:`SpinUpDrive`'s and :class:`FourBarDrive`'s
    motions are not described by one). A fixed-step integrator resolves the drive only
    with steps well below it (:mod:`sim.models.model_choice`)."""
    method = getattr(drive, "time_scale_s", None)
    if method is None:
        return None
    scale = float(method())
    return scale if scale > 0.0 else None
