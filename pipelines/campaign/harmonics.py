"""The crank frequency of a run and the amplitude and phase of a signal's crank
fundamental: least squares, with the uncertainties the residuals give.

The bench's motion is periodic at the crank frequency but not sinusoidal (the four-bar's
rocker angle carries harmonics), so every fit holds a mean and the first
:data:`N_HARMONICS` harmonics: what is left in the residual is then noise, and the
covariance ``s^2 (J^T J)^-1`` with ``s^2 = RSS / (n - p)`` is the fit's standard
uncertainty. Phases use ``y ~ R cos(2 pi f t - phi)``; a phase *lag* is the signal's
phase minus the rocker angle's, wrapped to (-pi, pi].
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

N_HARMONICS = 5


@dataclass(frozen=True)
class Fundamental:
    """The crank-frequency component ``amplitude * cos(2 pi f t - phase_rad)`` of a
    signal, with standard uncertainties (NaN when the fit is not possible)."""

    amplitude: float
    amplitude_sd: float
    phase_rad: float
    phase_sd_rad: float
    n_samples: int

    @classmethod
    def missing(cls) -> Fundamental:
        return cls(math.nan, math.nan, math.nan, math.nan, 0)


def _basis(t_s: FloatArray, f_hz: float, n_harmonics: int) -> FloatArray:
    cols = [np.ones_like(t_s)]
    for k in range(1, n_harmonics + 1):
        w = 2.0 * math.pi * k * f_hz * t_s
        cols += [np.cos(w), np.sin(w)]
    return np.column_stack(cols)


def _finite(t_s: FloatArray, y: FloatArray) -> tuple[FloatArray, FloatArray]:
    t = np.asarray(t_s, float)
    v = np.asarray(y, float)
    if t.shape != v.shape or t.ndim != 1:
        raise ValueError(f"t_s and y must be 1-D of one shape, got {t.shape} and {v.shape}")
    good = np.isfinite(t) & np.isfinite(v)
    return t[good], v[good]


def fit_fundamental(
    t_s: FloatArray, y: FloatArray, f_hz: float, *, n_harmonics: int = N_HARMONICS
) -> Fundamental:
    """Amplitude and phase of ``y(t_s)``'s component at ``f_hz`` (non-finite samples
    dropped); NaN when fewer samples than twice the parameters or no full period.

    Only the harmonics the samples resolve are fitted: those below the Nyquist frequency
    of the median sample spacing (15 frames/s resolve three harmonics of a 2.35 Hz crank,
    not five: the others alias onto the basis), and no more than half as many parameters
    as samples (frames refused leave gaps)."""
    t, v = _finite(t_s, y)
    if t.size >= 2:
        fs_hz = 1.0 / float(np.median(np.diff(t)))
        if math.isfinite(f_hz) and f_hz > 0 and math.isfinite(fs_hz):
            n_harmonics = min(n_harmonics, math.ceil(0.5 * fs_hz / f_hz) - 1)
    n_harmonics = min(n_harmonics, (t.size // 2 - 1) // 2)
    if n_harmonics < 1:
        return Fundamental.missing()
    p = 1 + 2 * n_harmonics
    if not (math.isfinite(f_hz) and f_hz > 0) or t.size < 2 * p or np.ptp(t) * f_hz < 1.0:
        return Fundamental.missing()
    # the time origin moved to the middle so the columns are well conditioned; the phase
    # is then carried back to t = 0
    t_mid = 0.5 * (t[0] + t[-1])
    a = _basis(t - t_mid, f_hz, n_harmonics)
    coef, *_ = np.linalg.lstsq(a, v, rcond=None)
    resid = v - a @ coef
    s2 = float(resid @ resid) / (t.size - p)
    cov = s2 * np.linalg.inv(a.T @ a)
    c, s = float(coef[1]), float(coef[2])
    r = math.hypot(c, s)
    vc, vs, cs = cov[1, 1], cov[2, 2], cov[1, 2]
    if r > 0:
        r_sd = math.sqrt(max(c * c * vc + s * s * vs + 2 * c * s * cs, 0.0)) / r
        phi_sd = math.sqrt(max(s * s * vc + c * c * vs - 2 * c * s * cs, 0.0)) / (r * r)
    else:
        r_sd = phi_sd = math.nan
    phase = math.atan2(s, c) + 2.0 * math.pi * f_hz * t_mid
    return Fundamental(r, r_sd, wrap_rad(phase), phi_sd, int(t.size))


def wrap_rad(angle_rad: float) -> float:
    """``angle_rad`` wrapped to (-pi, pi]."""
    w = math.remainder(angle_rad, 2.0 * math.pi)
    return math.pi if w == -math.pi else w


def phase_lag(signal: Fundamental, reference: Fundamental) -> tuple[float, float]:
    """``signal``'s phase minus ``reference``'s, wrapped, and its standard uncertainty
    (the two fits' uncertainties added in quadrature)."""
    lag = wrap_rad(signal.phase_rad - reference.phase_rad)
    return lag, math.hypot(signal.phase_sd_rad, reference.phase_sd_rad)


@dataclass(frozen=True)
class CrankFrequency:
    frequency_hz: float
    frequency_sd_hz: float


def crank_frequency(
    t_s: FloatArray, rocker_angle_rad: FloatArray, *, n_harmonics: int = N_HARMONICS
) -> CrankFrequency:
    """The crank frequency from the rocker angle: the mean period between upward
    crossings of the mean gives a start, then the frequency minimising the residual of a
    harmonic fit (Gauss-Newton on the frequency with the linear coefficients), with its
    standard uncertainty from the full Jacobian. NaN when the rocker does not swing
    through at least one full period."""
    t, v = _finite(t_s, rocker_angle_rad)
    nan = CrankFrequency(math.nan, math.nan)
    if t.size < 10:
        return nan
    x = v - np.mean(v)
    up = np.flatnonzero((x[:-1] < 0) & (x[1:] >= 0))
    if up.size < 2:
        return nan
    # crossing times interpolated between the samples
    tc = t[up] - x[up] * (t[up + 1] - t[up]) / (x[up + 1] - x[up])
    f = 1.0 / float(np.mean(np.diff(tc)))
    t_mid = 0.5 * (t[0] + t[-1])
    tt = t - t_mid
    p = 2 + 2 * n_harmonics
    if t.size < 2 * p:
        return nan
    cov_f = math.nan
    for _ in range(8):
        a = _basis(tt, f, n_harmonics)
        coef, *_ = np.linalg.lstsq(a, v, rcond=None)
        k = np.arange(1, n_harmonics + 1)
        w = 2.0 * math.pi * f * np.outer(tt, k)
        ck, sk = coef[1::2], coef[2::2]
        d_df = (2.0 * math.pi * tt[:, None] * k * (-ck * np.sin(w) + sk * np.cos(w))).sum(axis=1)
        jac = np.column_stack([a, d_df])
        resid = v - a @ coef
        step, *_ = np.linalg.lstsq(jac, resid, rcond=None)
        f += float(step[-1])
        s2 = float(resid @ resid) / (t.size - p)
        cov_f = float(s2 * np.linalg.inv(jac.T @ jac)[-1, -1])
        if abs(step[-1]) < 1e-12 * f:
            break
    return CrankFrequency(f, math.sqrt(max(cov_f, 0.0)))
