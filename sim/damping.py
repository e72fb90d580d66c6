"""Proportional (Rayleigh) damping relations, Eqs. 37-39, and the logarithmic decrement.

With C = a0 M + a1 K the modal damping ratio of a mode of natural frequency w is
zeta = a0 / (2 w) + a1 w / 2 (Eq. 37 with i = 0, 1; Eq. 38 for two modes); Eq. 39 inverts it.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import brentq
from scipy.signal import find_peaks

from sim.checks import check_positive
from sim.errors import SimInputError

FloatArray = NDArray[np.float64]


def modal_damping_ratio(a0_per_s: float, a1_s: float, omega_rad_s: ArrayLike) -> FloatArray:
    """zeta = a0 / (2 w) + a1 w / 2 (Eq. 37) for natural frequencies w (rad/s)."""
    w = np.asarray(omega_rad_s, dtype=float)
    if np.any(~np.isfinite(w)) or np.any(w <= 0.0):
        raise SimInputError("omega_rad_s", "must be positive and finite")
    return a0_per_s / (2.0 * w) + 0.5 * a1_s * w


def damping_ratios_from_coefficients(
    a0_per_s: float, a1_s: float, omega1_rad_s: float, omega2_rad_s: float
) -> tuple[float, float]:
    """(zeta1, zeta2) from (a0, a1) (Eq. 38)."""
    w1 = check_positive("omega1_rad_s", omega1_rad_s)
    w2 = check_positive("omega2_rad_s", omega2_rad_s)
    z = modal_damping_ratio(a0_per_s, a1_s, np.array([w1, w2]))
    return float(z[0]), float(z[1])


def coefficients_from_damping_ratios(
    zeta1: float, zeta2: float, omega1_rad_s: float, omega2_rad_s: float
) -> tuple[float, float]:
    """(a0 [1/s], a1 [s]) giving damping ratios zeta1, zeta2 at w1, w2 (Eq. 39)."""
    w1 = check_positive("omega1_rad_s", omega1_rad_s)
    w2 = check_positive("omega2_rad_s", omega2_rad_s)
    if w1 == w2:
        raise SimInputError("omega2_rad_s", "must differ from omega1_rad_s")
    f = 2.0 / (w2 * w2 - w1 * w1)
    a0 = f * (w1 * w2 * w2 * zeta1 - w1 * w1 * w2 * zeta2)
    a1 = f * (-w1 * zeta1 + w2 * zeta2)
    return a0, a1


def damping_ratio_from_log_decrement(log_decrement: float) -> float:
    """zeta = delta / sqrt(4 pi^2 + delta^2) (exact for a viscously damped oscillator)."""
    d = float(log_decrement)
    if not math.isfinite(d) or d < 0.0:
        raise SimInputError(
            "log_decrement", f"must be a non-negative finite number, got {log_decrement!r}"
        )
    return d / math.sqrt(4.0 * math.pi**2 + d * d)


def log_decrement_from_damping_ratio(zeta: float) -> float:
    """delta = 2 pi zeta / sqrt(1 - zeta^2), for 0 <= zeta < 1."""
    z = float(zeta)
    if not math.isfinite(z) or z < 0.0 or z >= 1.0:
        raise SimInputError("zeta", f"must be in [0, 1) for an oscillating decay, got {zeta!r}")
    return 2.0 * math.pi * z / math.sqrt(1.0 - z * z)


def log_decrement(
    t_s: ArrayLike, signal: ArrayLike, *, min_peaks: int = 3, floor_fraction: float = 0.05
) -> float:
    """Logarithmic decrement of a decaying oscillation, robust to noise and an offset.

    The offset is the median of the last quarter of the record; the positive and the
    negative peaks (at least half a period of the dominant frequency apart, found from the
    zero crossings) above ``floor_fraction`` of the largest one are fitted with
    log|peak| = c - delta * t / T by least squares, so noise on single peaks averages out.

    Parameters
    ----------
    t_s : (N,) sample times, s.
    signal : (N,) decaying signal (any unit).

    Returns
    -------
    delta : the log decrement per period (dimensionless).
    """
    t = np.asarray(t_s, dtype=float).reshape(-1)
    y = np.asarray(signal, dtype=float).reshape(-1)
    if t.shape != y.shape or t.size < 8:
        raise SimInputError("signal", "must be a 1-D array as long as t_s, of at least 8 samples")
    ok = np.isfinite(y) & np.isfinite(t)
    t, y = t[ok], y[ok]
    y = y - np.median(y[-max(4, y.size // 4) :])
    # Dominant period from the periodogram peak (zero crossings are fooled by noise).
    dt = float(np.median(np.diff(t)))
    n_fft = 1 << int(np.ceil(np.log2(8 * y.size)))
    spectrum = np.abs(np.fft.rfft(y * np.hanning(y.size), n_fft))
    freqs = np.fft.rfftfreq(n_fft, dt)
    k = int(np.argmax(spectrum[1:])) + 1
    if freqs[k] * (t[-1] - t[0]) < min_peaks:
        raise SimInputError("signal", "has too few oscillations to measure a log decrement")
    half_period = 0.5 / float(freqs[k])
    distance = max(1, int(1.4 * half_period / dt))
    top = float(np.max(np.abs(y)))
    d2 = np.diff(y, 2)
    noise = float(np.median(np.abs(d2 - np.median(d2)))) / 0.6745 / math.sqrt(6.0)
    floor = max(floor_fraction * top, 10.0 * noise)
    half_width = max(1, int(0.15 * 2.0 * half_period / dt))
    times: list[float] = []
    logs: list[float] = []
    for sign in (1.0, -1.0):
        idx, _ = find_peaks(sign * y, distance=distance, height=floor)
        for i in idx:
            lo, hi = max(0, i - half_width), min(y.size, i + half_width + 1)
            if hi - lo < 3:
                continue
            # A parabola through the samples around the peak averages the noise out.
            c2, c1, c0 = np.polyfit(t[lo:hi] - t[i], sign * y[lo:hi], 2)
            value = c0 - c1 * c1 / (4.0 * c2) if c2 < 0.0 else sign * y[i]
            if value > 0.0:
                times.append(float(t[i]))
                logs.append(math.log(value))
    if len(times) < min_peaks:
        raise SimInputError("signal", "has too few peaks above the noise floor")
    slope = np.polyfit(np.asarray(times), np.asarray(logs), 1)[0]
    return float(-slope * 2.0 * half_period)


def identify_equal_coefficients(
    simulate: Callable[[float], tuple[FloatArray, FloatArray]],
    target_log_decrement: float,
    *,
    lower: float = 1e-6,
    upper: float = 1.0,
    rtol: float = 1e-4,
) -> float:
    """Find a = a0 = a1 so that the simulated signal decays with the target log decrement,
    as the paper did (§5.2.1).

    Parameters
    ----------
    simulate : a -> (t_s, signal), e.g. the free-decay strain at gauge 2 for a0 = a1 = a.
    target_log_decrement : the measured log decrement.
    lower, upper : bracket for a (the decrement must increase with a across it).

    Returns
    -------
    a (both a0 in 1/s and a1 in s).
    """
    target = check_positive("target_log_decrement", target_log_decrement)

    def miss(a: float) -> float:
        t, s = simulate(a)
        return log_decrement(t, s) - target

    f_lo, f_hi = miss(lower), miss(upper)
    if f_lo * f_hi > 0.0:
        raise SimInputError(
            "target_log_decrement",
            f"{target!r} is not bracketed by a in [{lower!r}, {upper!r}] "
            f"(decrements {f_lo + target:.4g} .. {f_hi + target:.4g})",
        )
    return float(brentq(miss, lower, upper, rtol=rtol))
