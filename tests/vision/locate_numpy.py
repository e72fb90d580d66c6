"""The numpy forms of vision.locate's search steps, as they were before their numba
kernels (issue #19): the references the kernels are tested against
(tests/vision/test_locate_kernels.py). Not used by the package."""

# mypy: ignore-errors
from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from vision.locate import Strip, _Candidate


def find_strip_numpy(
    values: NDArray[np.float64],
    offsets: NDArray[np.float64],
    expect: float,
    near: float | None = None,
    levels: tuple[float, float] | None = None,
) -> Strip | None:
    """The bright run (half-maximum crossings) nearest offset ``expect`` in a profile.
    With ``near``, the maximum is taken within ``near`` of ``expect`` (brighter objects
    elsewhere in the profile then do not hide a dimmer strip). ``levels``: the profile's
    (:func:`profile_levels`), when already known (a finite profile only)."""
    n = len(values)
    if levels is not None:
        v = values
        lo, hi = levels
    else:
        ok = np.isfinite(values)
        if ok.sum() < 0.7 * n:
            return None
        v = np.where(ok, values, np.nanmedian(values)) if not ok.all() else values
        lo, hi = (float(x) for x in profile_levels_numpy(v[None, :])[0])
    return _strip_numpy(v, offsets, float(offsets[1] - offsets[0]), expect, near, lo, hi)


#: ``np.maximum.reduce``: a slice's maximum without ``ndarray.max``'s wrapper.
_max = np.maximum.reduce


def _strip_numpy(
    v: NDArray[np.float64],
    offsets: NDArray[np.float64] | list[float],
    step: float,
    expect: float,
    near: float | None,
    lo: float,
    hi: float,
) -> Strip | None:
    """:func:`find_strip` of a finite profile ``v`` of levels ``lo``, ``hi`` at
    ``offsets`` (ascending, uniform, ``step`` apart; a list of floats in a loop over
    profiles: single offsets are read from it)."""
    n = len(v)
    if near is not None:
        # Only the slice about the window (uniform offsets) is tested, a sample wider
        # than it either side, with the same test.
        # The offsets are ascending and uniform, so the close ones are one run: its
        # ends from the spacing, then settled by the same test on single offsets.
        o0 = float(offsets[0])
        j0 = min(max(int((expect - near - o0) / step), 0), n - 1)
        j1 = min(max(int((expect + near - o0) / step), 0), n - 1)
        while j0 > 0 and abs(float(offsets[j0 - 1]) - expect) <= near:
            j0 -= 1
        while j0 <= j1 and abs(float(offsets[j0]) - expect) > near:
            j0 += 1
        while j1 < n - 1 and abs(float(offsets[j1 + 1]) - expect) <= near:
            j1 += 1
        while j1 >= j0 and abs(float(offsets[j1]) - expect) > near:
            j1 -= 1
        if j0 <= j1:
            hi = float(_max(v[j0 : j1 + 1]))
    if hi - lo < 12.0:
        return None
    thr = 0.5 * (lo + hi)
    above = (v > thr).view(np.int8)
    d = above[1:] - above[:-1]
    # The sample before each change: changes alternate, up (first sample above at i + 1)
    # and down (last sample above at i); a run is an up and the down after it.
    where = d.nonzero()[0].tolist()
    first = 0 if where and d[where[0]] == 1 else 1
    m = (len(where) - first) // 2
    if m <= 0:
        return None
    # A profile has a few runs: their ends and centres in plain floats (the same
    # arithmetic, without a numpy call per step).
    best, best_k = None, 0
    for k in range(m):
        s0, s1 = where[first + 2 * k] + 1, where[first + 2 * k + 1]
        v0, v1, w0, w1 = float(v[s0 - 1]), float(v[s0]), float(v[s1]), float(v[s1 + 1])
        a = float(offsets[s0 - 1]) + (thr - v0) / (v1 - v0) * step
        b = float(offsets[s1]) + (w0 - thr) / (w0 - w1) * step
        c = 0.5 * (a + b)
        if best is None or abs(c - expect) < abs(best[0] - expect):
            best, best_k = (c, b - a), k
    assert best is not None
    s0, s1 = where[first + 2 * best_k] + 1, where[first + 2 * best_k + 1]
    peak = float(_max(v[s0 : s1 + 1]))
    return Strip(best[0], best[1], peak - lo)


def profile_levels_numpy(values: NDArray[np.float64]) -> NDArray[np.float64]:
    """(K, 2) background and bright level of each finite profile (K, M): its 20th and
    98th percentile samples (two order statistics: numpy's vectorised sort of the rows
    takes a third of the time of a partition about the two)."""
    n = values.shape[1]
    k = [int(0.2 * (n - 1)), int(0.98 * (n - 1))]
    return np.asarray(np.sort(values, axis=1)[:, k], dtype=np.float64)


def circle_candidates_numpy(
    v: NDArray[np.float64],
    phi: NDArray[np.float64],
    width: float,
    step: float,
    accept: tuple[float, float] | None = None,
) -> list[_Candidate]:
    """Strips of about ``width`` (0.55 .. 1.7 of it, within ``accept`` when given)
    crossing a circle about the pivot, from the image sampled along it (``v``) at angles
    ``phi``."""
    n = len(phi)
    ok: NDArray[np.bool_] | None = None  # None: every sample on the image
    if not math.isfinite(float(v.sum())):  # NaN off the image
        ok = np.isfinite(v)
        if ok.sum() < 10:
            return []
    vv = v if ok is None else np.where(ok, v, np.nanmedian(v))
    # Top-hat: brightness above the local floor over 3 widths.
    k = max(3, round(3 * width / step))
    from scipy.ndimage import maximum_filter1d, minimum_filter1d, uniform_filter1d

    sm = uniform_filter1d(vv, max(1, round(0.2 * width / step)), mode="wrap")
    # Grey opening (erosion, then dilation with the flat element mirrored: origin -1 for
    # an even size), as scipy's grey_opening computes it, by the 1-D filters.
    floor = maximum_filter1d(
        minimum_filter1d(sm, k, mode="wrap"), k, mode="wrap", origin=-1 if k % 2 == 0 else 0
    )
    top = sm - floor
    noise = float(np.median(np.abs(np.diff(vv)))) + 1.0
    out: list[_Candidate] = []
    thr = max(10.0, 5 * noise)
    lo, hi = 0.55 * width, 1.7 * width
    if accept is not None:
        lo, hi = max(lo, accept[0]), min(hi, accept[1])
    # Local maxima around the circle (np.roll's generality costs more than the compare).
    before = np.concatenate((top[-1:], top[:-1]))
    after = np.concatenate((top[1:], top[:1]))
    at_peak = (top > thr) & (top >= before) & (top > after)
    peaks = np.flatnonzero(at_peak if ok is None else at_peak & ok)
    if not peaks.size:
        return out
    # Each peak's half-maximum ends: the first samples either side at or below half its
    # height, at most a quarter of the circle away; read from a window of samples
    # about every peak at once (a peak whose half maximum lies beyond it is walked
    # sample by sample).
    quarter = n // 4
    reach = min(quarter, _WALK)
    win = np.take(top, peaks[:, None] + np.arange(-reach, reach + 1)[None, :], mode="wrap")
    half = win[:, reach] / 2
    down = ~(win[:, reach::-1] > half[:, None])  # j samples before the peak
    up = ~(win[:, reach:] > half[:, None])  # j samples after it
    j_down = np.where(down.any(axis=1), down.argmax(axis=1), reach + 1).tolist()
    j_up = np.where(up.any(axis=1), up.argmax(axis=1), reach + 1).tolist()
    for p, h, jd, ju in zip(peaks.tolist(), half.tolist(), j_down, j_up, strict=True):
        i0 = p - min(jd, quarter) if jd <= reach else _walk(top, p, h, -1, quarter)
        i1 = p + min(ju, quarter) if ju <= reach else _walk(top, p, h, 1, quarter)
        wid = (i1 - i0 - 1) * step
        if lo <= wid <= hi:
            angle = float(phi[p] + 0.5 * (i0 + i1 - 2 * p) * (2 * np.pi / n))
            out.append(_Candidate(angle, float(top[p]), wid, i0 + 1, i1 - 1))
    return out


#: Samples either side of a peak on a search circle read at once for its half-maximum
#: ends (:func:`_circle_candidates`).
_WALK = 64


def _walk(top: NDArray[np.float64], p: int, half: float, way: int, quarter: int) -> int:
    """The first sample from peak ``p`` along ``way`` (+-1) around the circle whose
    ``top`` is at or below ``half``, at most ``quarter`` samples away."""
    n, i = len(top), p
    while float(top[i % n]) > half and abs(i - p) < quarter:
        i += way
    return i


def follow_numpy(vals, offs, width, to_hub, hub_widening):
    """The old follow's search through cross-profiles ``vals`` (K, M): the profiles'
    indices that found the strip, its centres and widths, and whether it was lost."""
    offs_l = offs.tolist()
    step_o = float(offs[1] - offs[0])
    expect, prev_w, missed = 0.0, width, False
    finite = np.isfinite(vals).all(axis=1)
    levels = np.full((len(vals), 2), np.nan)
    if finite.any():
        levels[finite] = profile_levels_numpy(vals[finite])
    found, centres, widths = [], [], []
    for k in range(len(vals)):
        near = 0.6 * max(prev_w, width)
        s = (
            find_strip_numpy(vals[k], offs, expect, near=near)
            if not finite[k]
            else _strip_numpy(vals[k], offs_l, step_o, expect, near, *levels[k].tolist())
        )
        if s is None or s.width < 0.5 * width or abs(s.centre - expect) > 0.7 * max(prev_w, width):
            if missed or not to_hub:
                return found, centres, widths, True
            missed = True
            continue
        if missed and s.width <= hub_widening * width:
            return found, centres, widths, True
        missed = False
        found.append(k)
        centres.append(s.centre)
        widths.append(s.width)
        expect, prev_w = s.centre, s.width
    return found, centres, widths, False


def strip_end_numpy(v, inside):
    """The old _strip_end after its samples: the index of t taken, -1 for the last point."""
    if not np.isfinite(v[0]):
        return -1
    if not math.isfinite(float(v.sum())):
        v = np.where(np.isfinite(v), v, np.nanmin(v))
    thr = 0.5 * (v[:inside].mean() + v.min())
    below = np.flatnonzero(v[1:] < thr)
    return int(below[0]) + 1 if below.size else len(v) - 1
