"""Coarse location of the beam and the hub in a frame, in beam-plane coordinates.

Nothing here depends on the renderer: the beam is a bright strip of the calibrated width
somewhere around the pivot (the plane origin); the hub is where the strip, followed back
toward the pivot, becomes wider; the clamp is where it does.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from vision.errors import FrameFailure
from vision.sampling import BilinearPlan, bilinear, median

ToPx = Callable[[NDArray[np.float64]], NDArray[np.float64]]


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
    n = len(values)
    if levels is not None:
        v = values
        lo, hi = levels
    else:
        ok = np.isfinite(values)
        if ok.sum() < 0.7 * n:
            return None
        v = np.where(ok, values, np.nanmedian(values)) if not ok.all() else values
        lo, hi = (float(x) for x in profile_levels(v[None, :])[0])
    if near is not None:
        # Only the slice about the window (uniform offsets) is tested, a sample wider
        # than it either side, with the same test.
        # The offsets are ascending and uniform, so the close ones are one run: its
        # ends from the spacing, then settled by the same test on single offsets.
        o0 = float(offsets[0])
        step0 = float(offsets[1] - offsets[0])
        j0 = min(max(int((expect - near - o0) / step0), 0), n - 1)
        j1 = min(max(int((expect + near - o0) / step0), 0), n - 1)
        while j0 > 0 and abs(float(offsets[j0 - 1]) - expect) <= near:
            j0 -= 1
        while j0 <= j1 and abs(float(offsets[j0]) - expect) > near:
            j0 += 1
        while j1 < n - 1 and abs(float(offsets[j1 + 1]) - expect) <= near:
            j1 += 1
        while j1 >= j0 and abs(float(offsets[j1]) - expect) > near:
            j1 -= 1
        if j0 <= j1:
            hi = float(v[j0 : j1 + 1].max())
    if hi - lo < 12.0:
        return None
    thr = 0.5 * (lo + hi)
    above = (v > thr).view(np.int8)
    d = above[1:] - above[:-1]
    where = d.nonzero()[0]
    # A profile has a few runs: their ends and centres in plain floats (the same
    # arithmetic, without a numpy call per step).
    starts, ends = [], []
    for i, g in zip(where.tolist(), d[where].tolist(), strict=True):
        if g == 1:
            starts.append(i + 1)  # first sample above
        else:
            ends.append(i)  # last sample above
    if not starts or not ends:
        return None
    ends = [e for e in ends if e >= starts[0]]
    m = min(len(starts), len(ends))
    if m == 0:
        return None
    step = float(offsets[1] - offsets[0])
    best, best_k = None, 0
    for k in range(m):
        s0, s1 = starts[k], ends[k]
        v0, v1, w0, w1 = float(v[s0 - 1]), float(v[s0]), float(v[s1]), float(v[s1 + 1])
        a = float(offsets[s0 - 1]) + (thr - v0) / (v1 - v0) * step
        b = float(offsets[s1]) + (w0 - thr) / (w0 - w1) * step
        c = 0.5 * (a + b)
        if best is None or abs(c - expect) < abs(best[0] - expect):
            best, best_k = (c, b - a), k
    assert best is not None
    peak = float(v[starts[best_k] : ends[best_k] + 1].max())
    return Strip(best[0], best[1], peak - lo)


def profile_levels(values: NDArray[np.float64]) -> NDArray[np.float64]:
    """(K, 2) background and bright level of each finite profile (K, M): its 20th and
    98th percentile samples (two order statistics; no full sort)."""
    n = values.shape[1]
    k = [int(0.2 * (n - 1)), int(0.98 * (n - 1))]
    return np.asarray(np.partition(values, k, axis=1)[:, k], dtype=np.float64)


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
    #: Sampling plans per image shape, made at the first frame of that shape.
    plans: dict[tuple[int, ...], tuple[BilinearPlan, BilinearPlan]] = field(
        default_factory=dict, compare=False
    )

    def sample(self, image: NDArray[np.uint8]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The image along both circles (bilinear, NaN off the image)."""
        plans = self.plans.get(image.shape)
        if plans is None:
            plans = (
                BilinearPlan.at(image.shape, self.px[0]),
                BilinearPlan.at(image.shape, self.px[1]),
            )
            self.plans[image.shape] = plans
        return plans[0].sample(image), plans[1].sample(image)


def search_circles(
    to_px: ToPx, beam_length: float, beam_width: float, px_m: float
) -> SearchCircles:
    """The search circles of a camera placement (see :class:`SearchCircles`)."""
    radii = (0.25 * beam_length, 0.45 * beam_length)
    step = max(0.8 * px_m, beam_width / 16)
    phis, pxs = [], []
    for radius in radii:
        n = int(np.ceil(2 * np.pi * radius / step))
        phi = np.linspace(0, 2 * np.pi, n, endpoint=False)
        phis.append(phi)
        pxs.append(to_px(radius * np.column_stack([np.cos(phi), np.sin(phi)])))
    return SearchCircles(step, (radii[0], radii[1]), (phis[0], phis[1]), (pxs[0], pxs[1]))


def _circle_candidates(
    v: NDArray[np.float64],
    phi: NDArray[np.float64],
    width: float,
    step: float,
) -> list[tuple[float, float]]:
    """(angle, contrast) of strips of about ``width`` crossing a circle about the pivot,
    from the image sampled along it (``v``) at angles ``phi``."""
    n = len(phi)
    ok = np.isfinite(v)
    if ok.sum() < 10:
        return []
    vv = v if ok.all() else np.where(ok, v, np.nanmedian(v))
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
    noise = median(np.abs(np.diff(vv))) + 1.0
    out = []
    thr = max(10.0, 5 * noise)
    # Local maxima around the circle (np.roll's generality costs more than the compare).
    before = np.concatenate((top[-1:], top[:-1]))
    after = np.concatenate((top[1:], top[:1]))
    peaks = np.flatnonzero((top > thr) & (top >= before) & (top > after) & ok)
    tl = top.tolist()  # the half-width walks index single samples
    for p in peaks.tolist():
        half = tl[p] / 2
        i0 = p
        while tl[i0 % n] > half and p - i0 < n // 4:
            i0 -= 1
        i1 = p
        while tl[i1 % n] > half and i1 - p < n // 4:
            i1 += 1
        wid = (i1 - i0 - 1) * step
        if 0.55 * width <= wid <= 1.7 * width:
            out.append((float(phi[p] + 0.5 * (i0 + i1 - 2 * p) * (2 * np.pi / n)), float(top[p])))
    return out


def crossings(
    image: NDArray[np.uint8], circles: SearchCircles, beam_width: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
    """Where the beam crosses the two search circles (plane, m): the strongest pair of
    strips of its width, one on each circle, at angles within 0.12 rad; None when there
    is none. Reads the image only on the circles (and one pixel beside them)."""
    r1, r2 = circles.radii
    step = circles.step
    v1, v2 = circles.sample(image)
    c1 = _circle_candidates(v1, circles.phi[0], beam_width, step)
    c2 = _circle_candidates(v2, circles.phi[1], beam_width, step)
    best = None
    for a1, k1 in c1:
        for a2, k2 in c2:
            d = np.angle(np.exp(1j * (a2 - a1)))
            if abs(d) < 0.12 and (best is None or k1 + k2 > best[2]):
                best = (a1, a2, k1 + k2)
    if best is None:
        return None
    a1, a2, _ = best
    p1 = r1 * np.array([np.cos(a1), np.sin(a1)])
    p2 = r2 * np.array([np.cos(a2), np.sin(a2)])
    return p1, p2


def locate(
    image: NDArray[np.uint8],
    to_px: ToPx,
    beam_length: float,
    beam_width: float,
    px_m: float,
    circles: SearchCircles | None = None,
    found: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None,
) -> Rough:
    """Find the beam around the pivot and follow it to the tip and back over the hub.
    ``circles``: :func:`search_circles` of this placement, when already mapped;
    ``found``: :func:`crossings` of this image on them, when already found."""
    if circles is None:
        circles = search_circles(to_px, beam_length, beam_width, px_m)
    if found is None:
        found = crossings(image, circles, beam_width)
    if found is None:
        raise FrameFailure("no beam found (no bright strip of the beam's width about the pivot)")
    p1, p2 = found
    d0 = (p2 - p1) / np.linalg.norm(p2 - p1)
    outward = _follow(
        image, to_px, p2, d0, beam_width, 5.0 * beam_width, beam_length * 0.7, px_m, 2.5
    )
    inward = _follow(image, to_px, p1, -d0, beam_width, 5.0 * beam_width, beam_length, px_m, 1.4)
    pts_in, widths_in = inward
    wide = np.flatnonzero(widths_in > 1.35 * beam_width)
    if wide.size < 2:
        raise FrameFailure("no hub found (the strip does not widen toward the pivot)")
    k0 = int(wide[0])
    clamp = pts_in[k0 - 1] if k0 > 0 else pts_in[0]
    clamp = 0.5 * (clamp + pts_in[k0])
    hub_pts = pts_in[k0:]
    hub_w = widths_in[k0:]
    # The hub continues while the width stays near its median.
    med = median(hub_w)
    keep = np.abs(hub_w - med) < 0.25 * med
    # The hub ends at the first two widths in a row that disagree (one noisy width is
    # not the end).
    bad2 = ~keep[:-1] & ~keep[1:]
    last = int(np.argmax(bad2)) if bad2.any() else len(keep)
    while last > 0 and not keep[last - 1]:
        last -= 1
    if last < 2:
        raise FrameFailure("no hub found (too short)")
    hub_back = hub_pts[last - 1]
    beam_in = pts_in[:k0][::-1]
    beam = np.vstack([beam_in, p1[None, :], outward[0]])
    tip = _strip_end(image, to_px, beam, beam_width, px_m)
    return Rough(beam, clamp, hub_back, med, tip, hub_pts[:last][keep[:last]])


def _strip_end(
    image: NDArray[np.uint8],
    to_px: ToPx,
    beam: NDArray[np.float64],
    width: float,
    px_m: float,
) -> NDArray[np.float64]:
    """Where the strip ends beyond the last tracked point (half-brightness crossing)."""
    last = beam[-1]
    d = last - beam[max(0, len(beam) - 3)]
    d /= np.linalg.norm(d)
    t = np.arange(-width, 4.0 * width, 0.5 * px_m)
    v = bilinear(image, to_px(last[None, :] + t[:, None] * d[None, :]))
    if not np.isfinite(v[0]):
        return last
    v = np.where(np.isfinite(v), v, np.nanmin(v))
    thr = 0.5 * (v[: int(width / (0.5 * px_m))].mean() + np.min(v))
    below = np.flatnonzero(v < thr)
    below = below[below > 0]
    return last + (t[below[0]] if below.size else t[-1]) * d


#: Cross-profiles sampled at a time by :func:`_follow`.
_FOLLOW_BATCH = 16


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
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Follow a bright strip from ``start`` along ``direction`` until it ends.

    The cross-profiles (perpendicular to ``direction``, +-``half_m``) are sampled a batch
    at a time (a strip usually ends well before ``max_len``); the strip is then followed
    through them, each search starting where the last crossing was."""
    step = max(step_widths * width, 4 * px_m)
    ts_all = np.arange(step, max_len + step / 2, step)
    n = np.array([-direction[1], direction[0]])
    offs = np.arange(-half_m, half_m + 0.375 * px_m, 0.75 * px_m)
    centres: list[float] = []
    widths: list[float] = []
    expect, prev_w = 0.0, width
    lost = False
    for b0 in range(0, len(ts_all), _FOLLOW_BATCH):
        if lost:
            break
        ts = ts_all[b0 : b0 + _FOLLOW_BATCH]
        pts = np.empty((len(ts), len(offs), 2))
        for c in range(2):  # x and y apart: broadcasting over a last axis of 2 is slow
            pts[:, :, c] = (start[c] + ts[:, None] * direction[c]) + offs[None, :] * n[c]
        vals = bilinear(image, to_px(pts.reshape(-1, 2))).reshape(len(ts), len(offs))
        # The levels of every finite profile of the batch in one call (the search itself
        # depends on where the strip was in the previous profile).
        finite = np.asarray(np.isfinite(vals).all(axis=1), dtype=bool)
        levels = np.full((len(ts), 2), np.nan)
        if finite.any():
            levels[finite] = profile_levels(vals[finite])
        known = [
            (lo, hi) if ok else None
            for (lo, hi), ok in zip(levels.tolist(), finite.tolist(), strict=True)
        ]
        for k in range(len(ts)):
            near = 0.6 * max(prev_w, width)
            s = find_strip(vals[k], offs, expect, near=near, levels=known[k])
            if (
                s is None
                or s.width < 0.5 * width
                or abs(s.centre - expect) > 0.7 * max(prev_w, width)
            ):
                lost = True
                break
            centres.append(s.centre)
            widths.append(s.width)
            expect, prev_w = s.centre, s.width
    if not centres:
        return np.zeros((0, 2)), np.zeros(0)
    cs = np.array(centres)
    ts = ts_all[: len(cs)]
    out = (start[None, :] + ts[:, None] * direction[None, :]) + cs[:, None] * n[None, :]
    return out, np.array(widths)
