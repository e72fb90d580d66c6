"""A reciprocating run cut into crank cycles, and each signal's harmonics per cycle.

The cycles run from one upward crossing of the rocker angle through its mid-stroke to the
next, so each holds one period of the crank however its speed wanders. In each cycle a
signal is fitted by least squares with a mean and the harmonics ``k = 1..K`` of that
cycle's own frequency: ``y ~ c0 + sum_k Re(c_k exp(i k phi))`` with ``phi`` running from 0
to 2 pi over the cycle; ``|c_k|`` is the amplitude and ``arg c_k`` the phase (a lag is a
more negative phase). The same operator applied to a simulation on the same cycles gives
numbers directly comparable with the measured ones; how much they scatter from cycle to
cycle is the measurement's noise.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]

# Samples a cycle's fit needs beyond its parameters before its harmonics are trusted.
_SPARE_SAMPLES = 4


def cycle_windows(t_s: FloatArray, rocker_rad: FloatArray, start_s: float) -> FloatArray:
    """(C, 2) start and end times of the whole crank cycles that begin at or after
    ``start_s``: successive upward crossings of the rocker's mid-stroke.

    A crossing counts only after the rocker has been below ``mid - stroke / 4`` since the
    previous one, so the potentiometer's noise cannot make extra crossings.
    """
    t = np.asarray(t_s, float)
    r = np.asarray(rocker_rad, float)
    good = np.isfinite(r)
    t, r = t[good], r[good]
    if t.size < 4:
        return np.empty((0, 2))
    lo, hi = np.percentile(r, [2.0, 98.0])
    mid, quarter = 0.5 * (lo + hi), 0.25 * (hi - lo)
    if quarter <= 0.0:
        return np.empty((0, 2))
    crossings = []
    armed = False
    for i in range(1, r.size):
        if r[i] < mid - quarter:
            armed = True
        elif armed and r[i - 1] < mid <= r[i]:
            # linear interpolation between the two samples around the crossing
            f = (mid - r[i - 1]) / (r[i] - r[i - 1])
            crossings.append(t[i - 1] + f * (t[i] - t[i - 1]))
            armed = False
    c = np.asarray(crossings, float)
    c = c[c >= start_s]
    if c.size < 2:
        return np.empty((0, 2))
    return np.column_stack([c[:-1], c[1:]])


def harmonics_per_cycle(
    t_s: FloatArray, y: FloatArray, windows: FloatArray, n_harmonics: int
) -> ComplexArray:
    """(C, K) complex harmonic coefficients ``c_k`` of ``y(t_s)`` in each cycle of
    ``windows`` (NaN where a cycle holds too few finite samples for the fit)."""
    t = np.asarray(t_s, float)
    v = np.asarray(y, float)
    out = np.full((len(windows), n_harmonics), np.nan + 0j, dtype=complex)
    need = 1 + 2 * n_harmonics + _SPARE_SAMPLES
    k = np.arange(1, n_harmonics + 1)
    for c, (t0, t1) in enumerate(windows):
        sel = (t >= t0) & (t < t1) & np.isfinite(v)
        if np.count_nonzero(sel) < need:
            continue
        phi = 2.0 * math.pi * (t[sel] - t0) / (t1 - t0)
        arg = np.outer(phi, k)
        a = np.column_stack([np.ones_like(phi), np.cos(arg), np.sin(arg)])
        coef, *_ = np.linalg.lstsq(a, v[sel], rcond=None)
        # y = a_k cos + b_k sin = Re((a_k - i b_k) exp(i phi))
        out[c] = coef[1 : 1 + n_harmonics] - 1j * coef[1 + n_harmonics :]
    return out
