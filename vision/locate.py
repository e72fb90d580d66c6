"""Coarse location of the beam and the hub in a frame, in beam-plane coordinates.

Nothing here depends on the renderer: the beam is a bright strip somewhere around the
pivot (the plane origin); the hub is where the strip, followed back toward the pivot,
becomes wider; the clamp is where it does.

The beam's width in the image is measured, not assumed: a beam bending in the plane of the
mechanism is seen edge-on by a camera looking at that plane (a strip its thickness wide,
3.2 mm on the paper's bench, plus some side face under tilt), or face-on by another
bench's camera (19 mm). The calibration's ``beam_width_m`` is a hint only: the search
circles accept strips from :data:`MIN_STRIP_WIDTH_M` (two pixels or two of the circles'
samples at least: 2.4 mm with the rig's 19.05 mm) up to :data:`MAX_STRIP_WIDTH_M`, and the
beam is followed, and the hub found, with the width the strip shows
(:attr:`Rough.beam_width`; the calibration's where the two agree).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from vision.errors import FrameFailure
from vision.jit import kernel
from vision.sampling import (
    BilinearPlan,
    along_across,
    bilinear,
    bilinear_points,
    median,
    median_bounded,
    median_in_place,
    numpy_sum,
    order_stats_bounded,
    select_kth,
)

ToPx = Callable[[NDArray[np.float64]], NDArray[np.float64]]

#: The narrowest and the widest strip the search circles take for the beam (m): a beam
#: seen edge-on (1.5 mm: half the paper's beam thickness) up to a bar wider than the
#: paper's beam seen face-on (19 mm). A strip narrower than two pixels, or two of the
#: circles' samples, is never taken (:func:`strip_widths`).
MIN_STRIP_WIDTH_M = 1.5e-3
MAX_STRIP_WIDTH_M = 0.04
#: The follow's cross-profiles reach at least this far either side (m), whatever the
#: beam's width: a bent beam leaves the chord through its crossings of the search
#: circles by centimetres toward its tip, and a hub is found where the strip widens up
#: to about twice this wide (the profile's background level is its 20th percentile).
FOLLOW_HALF_M = 0.05
#: The hub begins where the strip, followed toward the pivot, is this much wider.
_HUB_WIDENING = 1.35
#: Cross-profiles reach this many beam widths either side of the followed strip.
PROFILE_HALF_WIDTHS = 5.0


@dataclass
class Strip:
    centre: float  # offset along the profile, m
    width: float  # m
    contrast: float  # DN


@dataclass
class Rough:
    """Rough geometry (plane, m): beam polyline from clamp to tip, hub axis and extent."""

    beam: NDArray[np.float64]  # (M, 2) from near the clamp to the tip
    clamp: NDArray[np.float64]  # (2,)
    hub_back: NDArray[np.float64]  # (2,) far end of the hub
    hub_width: float
    tip: NDArray[np.float64]
    #: (H, 2) centres of the cross-profiles on the hub whose width agrees with the hub's
    #: (half-maximum crossings, sub-sample): points on its axis.
    hub: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 2)))
    #: The beam's width as the image shows it (m): the median half-maximum width of the
    #: cross-profiles followed outward from the search circles, or the calibration's
    #: where the two agree (:func:`working_width`).
    beam_width: float = math.nan


def circle_step(beam_width: float, px_m: float) -> float:
    """The search circles' sample spacing (m) for a calibration's width ``beam_width``."""
    return max(0.8 * px_m, beam_width / 16)


def strip_widths(beam_width: float, px_m: float) -> tuple[float, float]:
    """The range of strip widths (m) the search circles take for the beam: the fixed
    range (:data:`MIN_STRIP_WIDTH_M` .. :data:`MAX_STRIP_WIDTH_M`, never below two
    pixels nor two of the circles' samples), widened to the calibration's hint
    ``beam_width`` (0.55 .. 1.7 of it)."""
    floor = max(MIN_STRIP_WIDTH_M, 2.0 * px_m, 2.0 * circle_step(beam_width, px_m))
    lo = min(floor, 0.55 * beam_width)
    hi = max(MAX_STRIP_WIDTH_M, 1.7 * beam_width)
    return lo, hi


#: A width shown within this fraction of the calibration's is the calibration's (the
#: edges' width is checked against it to the same fraction, vision.measure).
_HINT_AGREES = 0.15


def working_width(shown: float, hint: float) -> float:
    """The beam width (m) to follow the strip and scan its edges with: the calibration's
    ``hint`` when the width the image shows agrees with it (within
    :data:`_HINT_AGREES`), else the width shown."""
    return hint if abs(shown - hint) <= _HINT_AGREES * hint else shown


def outward_width(shown: float, hint: float) -> float:
    """The width (m) to follow the strip outward from the search circles with: the
    circles' width is known to a sample, so within their window about the ``hint``
    (0.55 .. 1.7 of it) the hint's; the strip's width is then measured on the way."""
    return hint if 0.55 * hint <= shown <= 1.7 * hint else shown


def follow_half_width(beam_width: float) -> float:
    """The half-width (m) of the follow's cross-profiles for a beam ``beam_width`` wide
    in the image."""
    return max(PROFILE_HALF_WIDTHS * beam_width, FOLLOW_HALF_M)


def find_strip(
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
    v = np.ascontiguousarray(values, dtype=np.float64)
    offs = np.ascontiguousarray(offsets, dtype=np.float64)
    step = float(offs[1] - offs[0])
    wide = math.nan if near is None else near
    if levels is None:
        found, c, w, contrast = _find_strip(v, offs, step, expect, wide)
    else:
        found, c, w, contrast = _strip(v, offs, step, expect, wide, levels[0], levels[1])
    return Strip(c, w, contrast) if found else None


@kernel
def _nan_filled(v: NDArray[np.float64], finite: int) -> NDArray[np.float64]:
    """A copy of ``v`` (``finite`` of its samples finite, at least one) whose other
    samples are the finite ones' median (a profile or a circle partly off the image)."""
    kept = np.empty(finite)
    j = 0
    for i in range(v.size):
        if math.isfinite(v[i]):
            kept[j] = v[i]
            j += 1
    fill = median_in_place(kept)
    w = v.copy()
    for i in range(v.size):
        if not math.isfinite(v[i]):
            w[i] = fill
    return w


@kernel
def _find_strip(
    v: NDArray[np.float64], offs: NDArray[np.float64], step: float, expect: float, near: float
) -> tuple[bool, float, float, float]:
    """:func:`find_strip` without levels: a profile at least 70 % on the image, NaN
    samples set to the others' median, its levels its own (:func:`_levels`)."""
    n = v.size
    finite = 0
    for i in range(n):
        if math.isfinite(v[i]):
            finite += 1
    if finite < 0.7 * n:
        return False, math.nan, math.nan, math.nan
    if finite < n:
        v = _nan_filled(v, finite)
    lo, hi = _levels(v)
    return _strip(v, offs, step, expect, near, lo, hi)


@kernel
def _levels(v: NDArray[np.float64]) -> tuple[float, float]:
    """:func:`profile_levels` of one finite profile: its samples of rank
    ``int(0.2 (n - 1))`` and ``int(0.98 (n - 1))``, by selection."""
    n = v.size
    k1, k2 = int(0.2 * (n - 1)), int(0.98 * (n - 1))
    # Image samples (0 .. 255): counted in quarter-DN buckets (a selection's compares
    # were nine tenths of a followed profile's search).
    ok, lo, hi = order_stats_bounded(v, k1, k2, 4.0, 1024)
    if ok:
        return lo, hi
    w = v.copy()
    select_kth(w, k2, n)
    select_kth(w, k1, k2 + 1)  # none of w[:k2] is above w[k2]
    return w[k1], w[k2]


@kernel
def _strip(
    v: NDArray[np.float64],
    offs: NDArray[np.float64],
    step: float,
    expect: float,
    near: float,
    lo: float,
    hi: float,
) -> tuple[bool, float, float, float]:
    """:func:`find_strip` of a finite profile ``v`` of levels ``lo``, ``hi`` at
    ``offs`` (ascending, uniform, ``step`` apart); ``near`` NaN: none. Returns whether
    a strip was found, its centre, width and contrast."""
    n = v.size
    if near == near:
        # The offsets are ascending and uniform, so the close ones are one run: its
        # ends from the spacing, then settled by the same test on single offsets.
        o0 = offs[0]
        j0 = min(max(int((expect - near - o0) / step), 0), n - 1)
        j1 = min(max(int((expect + near - o0) / step), 0), n - 1)
        while j0 > 0 and abs(offs[j0 - 1] - expect) <= near:
            j0 -= 1
        while j0 <= j1 and abs(offs[j0] - expect) > near:
            j0 += 1
        while j1 < n - 1 and abs(offs[j1 + 1] - expect) <= near:
            j1 += 1
        while j1 >= j0 and abs(offs[j1] - expect) > near:
            j1 -= 1
        if j0 <= j1:
            hi = v[j0]
            for j in range(j0 + 1, j1 + 1):
                if v[j] > hi:
                    hi = v[j]
    if hi - lo < 12.0:
        return False, math.nan, math.nan, math.nan
    thr = 0.5 * (lo + hi)
    # The sample before each change of "above": changes alternate, up (first sample
    # above at i + 1) and down (last sample above at i); a run is an up and the down
    # after it.
    where = np.empty(max(n - 1, 1), np.int64)
    m = 0
    for i in range(n - 1):
        if (v[i + 1] > thr) != (v[i] > thr):
            where[m] = i
            m += 1
    if m == 0:
        return False, math.nan, math.nan, math.nan
    first = 0 if v[where[0] + 1] > thr else 1
    runs = (m - first) // 2
    if runs <= 0:
        return False, math.nan, math.nan, math.nan
    best_c, best_w, best_k = math.nan, math.nan, -1
    for k in range(runs):
        s0, s1 = where[first + 2 * k] + 1, where[first + 2 * k + 1]
        v0, v1, w0, w1 = v[s0 - 1], v[s0], v[s1], v[s1 + 1]
        a = offs[s0 - 1] + (thr - v0) / (v1 - v0) * step
        b = offs[s1] + (w0 - thr) / (w0 - w1) * step
        c = 0.5 * (a + b)
        if best_k < 0 or abs(c - expect) < abs(best_c - expect):
            best_c, best_w, best_k = c, b - a, k
    s0, s1 = where[first + 2 * best_k] + 1, where[first + 2 * best_k + 1]
    peak = v[s0]
    for j in range(s0 + 1, s1 + 1):
        if v[j] > peak:
            peak = v[j]
    return True, best_c, best_w, peak - lo


def profile_levels(values: NDArray[np.float64]) -> NDArray[np.float64]:
    """(K, 2) background and bright level of each finite profile (K, M): its 20th and
    98th percentile samples (two order statistics: numpy's vectorised sort of the rows
    takes a third of the time of a partition about the two)."""
    n = values.shape[1]
    k = [int(0.2 * (n - 1)), int(0.98 * (n - 1))]
    return np.asarray(np.sort(values, axis=1)[:, k], dtype=np.float64)


def profile(
    image: NDArray[np.uint8],
    to_px: ToPx,
    centre: NDArray[np.float64],
    normal: NDArray[np.float64],
    half_m: float,
    step_m: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    offs = np.arange(-half_m, half_m + step_m / 2, step_m)
    pts = centre[None, :] + offs[:, None] * normal[None, :]
    return bilinear(image, to_px(pts)), offs


@dataclass(frozen=True, eq=False)
class SearchCircles:
    """The two circles about the pivot that :func:`locate` searches for the beam, as raw
    pixel positions: they depend on the camera placement only, so a measurer maps them
    once (:func:`search_circles`) instead of every frame."""

    step: float  # m between samples
    radii: tuple[float, float]  # m
    phi: tuple[NDArray[np.float64], NDArray[np.float64]]  # sample angles, rad
    px: tuple[NDArray[np.float64], NDArray[np.float64]]  # (n, 2) raw pixels
    #: The strip widths (m) taken for the beam (:func:`strip_widths`), and the widths the
    #: top-hat is tuned to: the calibration's hint and factors of two from it.
    widths: tuple[float, float] = (MIN_STRIP_WIDTH_M, MAX_STRIP_WIDTH_M)
    scales: tuple[float, ...] = ()
    hint: float = 0.01905
    #: Sampling plans per image shape (both circles in one), made at the first frame of
    #: that shape.
    plans: dict[tuple[int, ...], BilinearPlan] = field(default_factory=dict, compare=False)

    def sample(self, image: NDArray[np.uint8]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The image along both circles (bilinear, NaN off the image)."""
        plan = self.plans.get(image.shape)
        if plan is None:
            plan = BilinearPlan.at(image.shape, np.concatenate(self.px))
            self.plans[image.shape] = plan
        v = plan.sample(image)
        n0 = len(self.px[0])
        return v[:n0], v[n0:]


def search_circles(
    to_px: ToPx, beam_length: float, beam_width: float, px_m: float
) -> SearchCircles:
    """The search circles of a camera placement (see :class:`SearchCircles`);
    ``beam_width``: the calibration's width, a hint."""
    radii = (0.25 * beam_length, 0.45 * beam_length)
    lo, hi = strip_widths(beam_width, px_m)
    step = circle_step(beam_width, px_m)
    # Each scale takes strips of 0.55 .. 1.7 of it: factors of two overlap.
    scales = [beam_width]
    while 1.7 * scales[0] / 2 >= lo:
        scales.insert(0, scales[0] / 2)
    while 0.55 * scales[-1] * 2 <= hi:
        scales.append(scales[-1] * 2)
    phis, pxs = [], []
    for radius in radii:
        n = int(np.ceil(2 * np.pi * radius / step))
        phi = np.linspace(0, 2 * np.pi, n, endpoint=False)
        phis.append(phi)
        pxs.append(to_px(radius * np.column_stack([np.cos(phi), np.sin(phi)])))
    return SearchCircles(
        step,
        (radii[0], radii[1]),
        (phis[0], phis[1]),
        (pxs[0], pxs[1]),
        (lo, hi),
        tuple(scales),
        beam_width,
    )


@dataclass(frozen=True)
class _Candidate:
    angle: float  # rad, the strip's centre on the circle
    contrast: float  # DN above the local floor
    width: float  # m along the circle (half-maximum)
    i0: int  # first and last sample above half maximum
    i1: int


def _circle_candidates(
    v: NDArray[np.float64],
    phi: NDArray[np.float64],
    width: float,
    step: float,
    accept: tuple[float, float] | None = None,
) -> list[_Candidate]:
    """Strips of about ``width`` (0.55 .. 1.7 of it, within ``accept`` when given)
    crossing a circle about the pivot, from the image sampled along it (``v``) at angles
    ``phi``."""
    lo, hi = 0.55 * width, 1.7 * width
    if accept is not None:
        lo, hi = max(lo, accept[0]), min(hi, accept[1])
    # Top-hat over 3 widths, on the samples smoothed over a fifth of one (Python's round:
    # half to even).
    k = max(3, round(3 * width / step))
    smooth = max(1, round(0.2 * width / step))
    found = _circle_peaks(np.ascontiguousarray(v, dtype=np.float64), phi, k, smooth, step, lo, hi)
    return [_Candidate(a, c, w, int(i0), int(i1)) for a, c, w, i0, i1 in found.tolist()]


@kernel
def _circle_peaks(
    v: NDArray[np.float64],
    phi: NDArray[np.float64],
    k: int,
    smooth: int,
    step: float,
    lo: float,
    hi: float,
) -> NDArray[np.float64]:
    """:func:`_circle_candidates`: a row per strip (S, 5), its angle, contrast, width
    and first and last samples above half maximum, from the circle's samples ``v`` (NaN
    off the image: set to the others' median, never a peak) with a top-hat of ``k``
    samples on the samples smoothed over ``smooth``."""
    n = v.size
    finite = 0
    for i in range(n):
        finite += math.isfinite(v[i])
    w = v
    if finite < n:
        if finite < 10:
            return np.empty((0, 5))
        w = _nan_filled(v, finite)
    # Top-hat: brightness above the local floor over k samples, a grey opening of the
    # smoothed samples (erosion, then dilation with the flat element mirrored: origin -1
    # for an even size), all as scipy.ndimage's 1-D filters compute them, around the
    # circle (mode "wrap").
    sm = _uniform_wrap(w, smooth)
    # (window starts and the sign as computed values: a literal argument would compile
    # another specialisation)
    start = -(k // 2)
    floor = _extreme_wrap(_extreme_wrap(sm, k, start, -1.0), k, start + (k % 2 == 0), 1.0)
    top = sm - floor
    dv = np.empty(n - 1)
    for i in range(n - 1):
        dv[i] = abs(w[i + 1] - w[i])
    noise = median_bounded(dv, 8.0, 2048) + 1.0  # (differences of 0 .. 255)
    thr = max(10.0, 5 * noise)
    # Each peak's half-maximum ends: the first samples either side at or below half
    # its height, at most a quarter of the circle away.
    quarter = n // 4
    out = np.empty((n, 5))
    m = 0
    for p in range(n):
        t = top[p]
        if not (math.isfinite(v[p]) and t > thr and t >= top[p - 1]):
            continue
        if not t > top[p + 1 if p + 1 < n else 0]:
            continue
        half = t / 2
        i0, j = p, p  # j: i0 around the circle
        while top[j] > half and p - i0 < quarter:
            i0 -= 1
            j = j - 1 if j > 0 else n - 1
        i1, j = p, p
        while top[j] > half and i1 - p < quarter:
            i1 += 1
            j = j + 1 if j < n - 1 else 0
        width = (i1 - i0 - 1) * step
        if lo <= width <= hi:
            out[m, 0] = phi[p] + 0.5 * (i0 + i1 - 2 * p) * (2 * np.pi / n)
            out[m, 1], out[m, 2] = t, width
            out[m, 3], out[m, 4] = i0 + 1, i1 - 1
            m += 1
    return out[:m]


@kernel
def _uniform_wrap(x: NDArray[np.float64], size: int) -> NDArray[np.float64]:
    """``scipy.ndimage.uniform_filter1d(x, size, mode="wrap")`` with its arithmetic: a
    running sum (the first window's in order, then the sample entering less the one
    leaving), each divided by ``size``."""
    n = x.size
    ext = _wrapped(x, -(size // 2), n + size - 1)
    out = np.empty(n)
    tmp = 0.0
    for j in range(size):
        tmp += ext[j]
    out[0] = tmp / size
    for i in range(1, n):
        tmp += ext[i + size - 1] - ext[i - 1]
        out[i] = tmp / size
    return out


@kernel
def _wrapped(x: NDArray[np.float64], start: int, m: int) -> NDArray[np.float64]:
    """``m`` samples of ``x`` around the circle from index ``start`` (may be negative)."""
    n = x.size
    out = np.empty(m)
    j = start % n
    for i in range(m):
        out[i] = x[j]
        j = j + 1 if j < n - 1 else 0
    return out


@kernel
def _extreme_wrap(
    x: NDArray[np.float64], size: int, start: int, sign: float
) -> NDArray[np.float64]:
    """``scipy.ndimage.maximum_filter1d`` (``sign`` 1) or ``minimum_filter1d`` (-1) of
    ``x`` with ``size``, mode "wrap", each output the extreme of the window from
    ``i + start`` (``start = -(size // 2) - origin``) .. ``+ size - 1``, by van Herk /
    Gil-Werman's running extremes over blocks of ``size``: exact, whatever the order."""
    n = x.size
    m = n + size - 1
    ext = _wrapped(x, start, m)
    fwd, bwd = np.empty(m), np.empty(m)
    for b in range(0, m, size):  # blocks of size: running extremes either way
        end = min(b + size, m)
        # Both runs in one loop, each in a register: two independent chains of
        # compares, not one chain at a time through a store and a load.
        up, down = sign * ext[b], sign * ext[end - 1]
        fwd[b], bwd[end - 1] = up, down
        for t in range(1, end - b):
            e = sign * ext[b + t]
            up = e if e > up else up
            fwd[b + t] = up
            e = sign * ext[end - 1 - t]
            down = e if e > down else down
            bwd[end - 1 - t] = down
    out = np.empty(n)
    for i in range(n):
        a, b = bwd[i], fwd[i + size - 1]
        out[i] = sign * (a if a > b else b)
    return out


def _circle_strips(
    v: NDArray[np.float64], phi: NDArray[np.float64], circles: SearchCircles
) -> list[_Candidate]:
    """The strips of every width the circles take (:attr:`SearchCircles.widths`), each
    once: a strip found at several scales is kept as the widest; a narrower one inside
    a wider one (noise on a wide strip's plateau) is not a strip."""
    found: list[_Candidate] = []
    for w in circles.scales:
        found += _circle_candidates(v, phi, w, circles.step, circles.widths)
    found.sort(key=lambda c: -c.width)
    n = len(phi)
    kept: list[_Candidate] = []
    for c in found:
        p = round(c.angle / (2 * np.pi) * n)
        if not any((p - k.i0) % n <= (k.i1 - k.i0) % n for k in kept):
            kept.append(c)
    return kept


#: The two crossings' widths agree within this factor (the half-maximum width of a strip
#: a few samples wide is known to a sample).
_CROSSING_WIDTH_RATIO = 1.6


def _best_pair(
    c1: list[_Candidate], c2: list[_Candidate], max_ratio: float
) -> tuple[_Candidate, _Candidate, float] | None:
    """The pair of strips, one on each circle at angles within 0.12 rad and widths within
    ``max_ratio``, of the largest summed contrast."""
    best = None
    if not c1 or not c2:
        return best
    # The angles between every pair at once (the same complex arithmetic per pair).
    a1 = np.array([s.angle for s in c1])
    a2 = np.array([s.angle for s in c2])
    gaps = np.angle(np.exp(1j * (a2[None, :] - a1[:, None]))).tolist()
    for s1, row in zip(c1, gaps, strict=True):
        for s2, d in zip(c2, row, strict=True):
            ratio = max(s1.width, s2.width) / min(s1.width, s2.width)
            if (
                abs(d) < 0.12
                and ratio <= max_ratio
                and (best is None or s1.contrast + s2.contrast > best[2])
            ):
                best = (s1, s2, s1.contrast + s2.contrast)
    return best


def crossings(
    image: NDArray[np.uint8], circles: SearchCircles, beam_width: float | None = None
) -> tuple[NDArray[np.float64], NDArray[np.float64], float] | None:
    """Where the beam crosses the two search circles (plane, m), and the width it shows
    there (m; the narrower crossing's, the less smeared): the strongest pair of strips
    of one width, one on each circle, at angles within 0.12 rad (of about the
    calibration's width first); None when there is none. Reads the image only on the
    circles (and one pixel beside them). ``beam_width``: unused (the circles carry the
    widths taken)."""
    r1, r2 = circles.radii
    v1, v2 = circles.sample(image)
    # Strips of about the calibration's width first (0.55 .. 1.7 of it), then of any
    # width the circles take, of one width on both.
    best = _best_pair(
        _circle_candidates(v1, circles.phi[0], circles.hint, circles.step),
        _circle_candidates(v2, circles.phi[1], circles.hint, circles.step),
        math.inf,
    )
    if best is None:
        best = _best_pair(
            _circle_strips(v1, circles.phi[0], circles),
            _circle_strips(v2, circles.phi[1], circles),
            _CROSSING_WIDTH_RATIO,
        )
    if best is None:
        return None
    s1, s2, _ = best
    p1 = r1 * np.array([np.cos(s1.angle), np.sin(s1.angle)])
    p2 = r2 * np.array([np.cos(s2.angle), np.sin(s2.angle)])
    return p1, p2, min(s1.width, s2.width)


def locate(
    image: NDArray[np.uint8],
    to_px: ToPx,
    beam_length: float,
    beam_width: float,
    px_m: float,
    circles: SearchCircles | None = None,
    found: tuple[NDArray[np.float64], NDArray[np.float64], float] | None = None,
) -> Rough:
    """Find the beam around the pivot and follow it to the tip and back over the hub.
    ``beam_width``: the calibration's, a hint (the width followed is the one the strip
    shows). ``circles``: :func:`search_circles` of this placement, when already mapped;
    ``found``: :func:`crossings` of this image on them, when already found."""
    if circles is None:
        circles = search_circles(to_px, beam_length, beam_width, px_m)
    if found is None:
        found = crossings(image, circles)
    if found is None:
        lo, hi = circles.widths
        raise FrameFailure(
            "no beam found (no bright strip "
            f"{lo * 1e3:.1f} .. {hi * 1e3:.0f} mm wide crossing both circles about the pivot)"
        )
    p1, p2, w0 = found
    d0 = _unit(p2 - p1)
    w_out = outward_width(w0, beam_width)
    outward = _follow(
        image, to_px, p2, d0, w_out, follow_half_width(w_out), beam_length * 0.7, px_m, 2.5
    )
    if len(outward[1]) == 0:
        raise FrameFailure(
            f"no beam found (the {w0 * 1e3:.1f} mm strip on the search circles "
            "does not continue outward)"
        )
    # The width the beam shows: the least smeared one (a beam swinging about the pivot
    # smears in proportion to the radius, and a strip's half-maximum width is the
    # larger of its width and its smear): the inner circle's, the outward profiles',
    # then the first inward profiles' (between the inner circle and the root).
    shown_out = median(outward[1])
    shown = min(shown_out, w0)
    w_in = working_width(shown, beam_width)
    inward = _follow(
        image, to_px, p1, -d0, w_in, follow_half_width(w_in), beam_length, px_m, 1.4, True
    )
    pts_in, widths_in = inward
    if len(widths_in):
        shown = min(shown_out, median(widths_in[:3]))
    w_beam = working_width(shown, beam_width)
    # The hub: from the first profile wider than the beam by _HUB_WIDENING (two at
    # least), while the width stays near its median; it ends at the first two widths
    # in a row that disagree (one noisy width is not the end): :func:`_hub_run`.
    n_wide, k0, med, keep, last = _hub_run(
        np.ascontiguousarray(widths_in, dtype=np.float64), _HUB_WIDENING * w_beam
    )
    if n_wide < 2:
        raise FrameFailure(
            f"no hub found (the {shown * 1e3:.1f} mm strip does not widen toward the pivot)"
        )
    clamp = pts_in[k0 - 1] if k0 > 0 else pts_in[0]
    clamp = 0.5 * (clamp + pts_in[k0])
    hub_pts = pts_in[k0:]
    if last < 2:
        raise FrameFailure("no hub found (too short)")
    hub_back = hub_pts[last - 1]
    beam_in = pts_in[:k0][::-1]
    beam = np.vstack([beam_in, p1[None, :], outward[0]])
    tip = _strip_end(image, to_px, beam, w_beam, px_m)
    return Rough(beam, clamp, hub_back, med, tip, hub_pts[:last][keep[:last]], w_beam)


@kernel
def _hub_run(
    widths: NDArray[np.float64], wider: float
) -> tuple[int, int, float, NDArray[np.bool_], int]:
    """:func:`locate`'s hub along the inward profiles' ``widths``: how many are wider
    than ``wider`` and the first of them ``k0``; from it on (the hub's widths), their
    median, which of them lie within a quarter of it (``keep``), and where the hub ends
    (``last``: before the first two in a row that do not, less the kept run's
    trailing misses). (NaN widths are never wider; a NaN among the hub's makes its
    median NaN, as numpy's.)"""
    n_wide, k0 = 0, -1
    for i in range(widths.size):
        if widths[i] > wider:
            if n_wide == 0:
                k0 = i
            n_wide += 1
    if n_wide < 2:
        return n_wide, k0, math.nan, np.zeros(0, dtype=np.bool_), 0
    hub_w = widths[k0:]
    med = median_in_place(hub_w.copy())
    n = hub_w.size
    keep = np.empty(n, dtype=np.bool_)
    for i in range(n):
        keep[i] = abs(hub_w[i] - med) < 0.25 * med
    last = n
    for i in range(n - 1):
        if not keep[i] and not keep[i + 1]:
            last = i
            break
    while last > 0 and not keep[last - 1]:
        last -= 1
    return n_wide, k0, med, keep, last


def _unit(d: NDArray[np.float64]) -> NDArray[np.float64]:
    """``d / np.linalg.norm(d)`` of a float64 vector: the norm as numpy computes it,
    ``sqrt(d.dot(d))``, without its generic checks."""
    return d / math.sqrt(float(d.dot(d)))


def _strip_end(
    image: NDArray[np.uint8],
    to_px: ToPx,
    beam: NDArray[np.float64],
    width: float,
    px_m: float,
) -> NDArray[np.float64]:
    """Where the strip ends beyond the last tracked point (half-brightness crossing)."""
    last = beam[-1]
    d = _unit(last - beam[max(0, len(beam) - 3)])
    t = np.arange(-width, 4.0 * width, 0.5 * px_m)
    v = bilinear(image, to_px(last[None, :] + t[:, None] * d[None, :]))
    k = _strip_end_at(v, int(width / (0.5 * px_m)))
    return last if k < 0 else last + t[k] * d


@kernel
def _strip_end_at(v: NDArray[np.float64], inside: int) -> int:
    """:func:`_strip_end` along samples ``v`` (NaN off the image) whose first
    ``inside`` lie on the strip: the first sample past the first below half way from
    those samples' mean to the darkest (the last when none is), -1 when the first
    sample is off the image. NaN samples are taken as the darkest."""
    n = v.size
    if not math.isfinite(v[0]):
        return -1
    low = math.inf
    for i in range(n):
        if v[i] < low:  # NaN fails
            low = v[i]
    w = v.copy()
    for i in range(n):
        if not math.isfinite(w[i]):
            w[i] = low
    inside = min(inside, n)
    thr = 0.5 * (numpy_sum(w, inside) / inside + low)  # numpy's mean (pairwise sum)
    for i in range(1, n):
        if w[i] < thr:
            return i
    return n - 1


#: Cross-profiles sampled at a time by :func:`_follow`: a first batch, then batches
#: growing from a few (a strip followed past the first batch usually ends soon after:
#: a hub's back end; every profile sampled and not searched is work lost).
_FOLLOW_BATCH = 16
_FOLLOW_MORE = (2, 4, 8)


def _follow(
    image: NDArray[np.uint8],
    to_px: ToPx,
    start: NDArray[np.float64],
    direction: NDArray[np.float64],
    width: float,
    half_m: float,
    max_len: float,
    px_m: float,
    step_widths: float,
    to_hub: bool = False,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Follow a bright strip from ``start`` along ``direction`` until it ends.

    The cross-profiles (perpendicular to ``direction``, +-``half_m``) are sampled a batch
    at a time (a strip usually ends well before ``max_len``); the strip is then followed
    through them, each search starting where the last crossing was; it ends at the
    first profile without it (``to_hub``: unless the next one finds the hub, a strip
    wider by :data:`_HUB_WIDENING`)."""
    step = max(step_widths * width, 4 * px_m)
    ts_all = np.arange(step, max_len + step / 2, step)
    n = np.array([-direction[1], direction[0]])
    offs = np.arange(-half_m, half_m + 0.375 * px_m, 0.75 * px_m)
    across = (offs * n[0], offs * n[1])  # the profiles' offsets in the plane, x and y
    step_o = float(offs[1] - offs[0])
    centres: list[NDArray[np.float64]] = []
    widths: list[NDArray[np.float64]] = []
    at: list[NDArray[np.int64]] = []  # the profiles that found the strip
    expect, prev_w = 0.0, width
    lost = False
    missed = False
    b0, size, more = 0, _FOLLOW_BATCH, iter(_FOLLOW_MORE)
    image = np.ascontiguousarray(image)
    while b0 < len(ts_all) and not lost:
        ts = ts_all[b0 : b0 + size]
        pts = _offset_grid(ts, start, direction, *across)
        # (bilinear's kernel on the mapped points: one call, not bilinear's five)
        px = np.ascontiguousarray(to_px(pts), dtype=np.float64)
        vals = bilinear_points(image, px).reshape(len(ts), len(offs))
        cb, wb, kb = np.empty(len(ts)), np.empty(len(ts)), np.empty(len(ts), np.int64)
        count, expect, prev_w, missed, lost = _follow_batch(
            vals, offs, step_o, width, to_hub, expect, prev_w, missed, cb, wb, kb
        )
        centres.append(cb[:count])
        widths.append(wb[:count])
        at.append(kb[:count] + b0)
        b0 += len(ts)
        size = next(more, 2 * size)
    cs = np.concatenate(centres) if centres else np.zeros(0)
    if not len(cs):
        return np.zeros((0, 2)), np.zeros(0)
    ts = ts_all[np.concatenate(at)]
    return along_across(start, direction, n, ts, cs), np.concatenate(widths)


@kernel
def _offset_grid(
    t: NDArray[np.float64],
    start: NDArray[np.float64],
    direction: NDArray[np.float64],
    dx: NDArray[np.float64],
    dy: NDArray[np.float64],
) -> NDArray[np.float64]:
    """:func:`_grid` of the points ``start + t direction`` (K) and the offsets (dx, dy)
    (M): ``(start + t_k direction) + d_j``, the sums as numpy's arrays gave them."""
    out = np.empty((t.size * dx.size, 2))
    for k in range(t.size):
        x = start[0] + t[k] * direction[0]
        y = start[1] + t[k] * direction[1]
        for j in range(dx.size):
            out[k * dx.size + j, 0] = x + dx[j]
            out[k * dx.size + j, 1] = y + dy[j]
    return out


@kernel
def _grid(
    x: NDArray[np.float64], y: NDArray[np.float64], dx: NDArray[np.float64], dy: NDArray
) -> NDArray[np.float64]:
    """Points (K * M, 2): each of (x, y) (K) plus each of (dx, dy) (M), row by row."""
    out = np.empty((x.size * dx.size, 2))
    for k in range(x.size):
        for j in range(dx.size):
            out[k * dx.size + j, 0] = x[k] + dx[j]
            out[k * dx.size + j, 1] = y[k] + dy[j]
    return out


@kernel
def _follow_batch(
    vals: NDArray[np.float64],
    offs: NDArray[np.float64],
    step: float,
    width: float,
    to_hub: bool,
    expect: float,
    prev_w: float,
    missed: bool,
    centres: NDArray[np.float64],
    widths: NDArray[np.float64],
    found: NDArray[np.int64],
) -> tuple[int, float, float, bool, bool]:
    """:func:`_follow` through one batch of cross-profiles ``vals`` (K, M): the strip
    in each (:func:`find_strip` within 0.6 of the last width of the last crossing),
    written to ``centres``, ``widths`` and ``found`` (the profile's index). Returns
    how many were found, the search's state after the batch (``expect``, ``prev_w``,
    ``missed``) and whether the strip was lost."""
    count = 0
    for k in range(vals.shape[0]):
        near = 0.6 * max(prev_w, width)
        row = vals[k]
        finite = True
        for i in range(row.size):
            if not math.isfinite(row[i]):
                finite = False
                break
        if finite:
            lo, hi = _levels(row)
            ok, c, w, _ = _strip(row, offs, step, expect, near, lo, hi)
        else:
            ok, c, w, _ = _find_strip(row, offs, step, expect, near)
        if not ok or w < 0.5 * width or abs(c - expect) > 0.7 * max(prev_w, width):
            # Toward the hub, one profile missed is not the end when the next finds
            # the hub: a profile along the clamp face is half bright (a narrow
            # beam's window then sees the beam brighter than the face).
            if missed or not to_hub:
                return count, expect, prev_w, missed, True
            missed = True
            continue
        if missed and w <= _HUB_WIDENING * width:
            return count, expect, prev_w, missed, True
        missed = False
        centres[count], widths[count], found[count] = c, w, k
        count += 1
        expect, prev_w = c, w
    return count, expect, prev_w, missed, False
