"""Coarse location of the beam and the hub in a frame, in beam-plane coordinates.

Nothing here depends on the renderer: the beam is a bright strip of the calibrated width
somewhere around the pivot (the plane origin); the hub is where the strip, followed back
toward the pivot, becomes wider; the clamp is where it does.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from vision.sampling import bilinear

ToPx = Callable[[NDArray[np.float64]], NDArray[np.float64]]


class FrameFailure(Exception):
    """A frame that gives no measurement; the message is the reason."""


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


def find_strip(
    values: NDArray[np.float64],
    offsets: NDArray[np.float64],
    expect: float,
    near: float | None = None,
) -> Strip | None:
    """The bright run (half-maximum crossings) nearest offset ``expect`` in a profile.
    With ``near``, the maximum is taken within ``near`` of ``expect`` (brighter objects
    elsewhere in the profile then do not hide a dimmer strip)."""
    ok = np.isfinite(values)
    n = len(values)
    if ok.sum() < 0.7 * n:
        return None
    v = np.where(ok, values, np.nanmedian(values)) if not ok.all() else values
    vs = np.sort(v)
    lo = float(vs[int(0.2 * (n - 1))])
    hi = float(vs[int(0.98 * (n - 1))])
    if near is not None:
        close = np.abs(offsets - expect) <= near
        if close.any():
            hi = float(np.max(v[close]))
    if hi - lo < 12.0:
        return None
    thr = 0.5 * (lo + hi)
    above = (v > thr).astype(np.int8)
    d = np.diff(above)
    starts = np.flatnonzero(d == 1) + 1  # first sample above
    ends = np.flatnonzero(d == -1)  # last sample above
    if starts.size == 0 or ends.size == 0:
        return None
    ends = ends[ends >= starts[0]]
    m = min(starts.size, ends.size)
    if m == 0:
        return None
    s0, s1 = starts[:m], ends[:m]
    step = offsets[1] - offsets[0]
    f0 = (thr - v[s0 - 1]) / (v[s0] - v[s0 - 1])
    f1 = (v[s1] - thr) / (v[s1] - v[s1 + 1])
    a = offsets[s0 - 1] + f0 * step
    b = offsets[s1] + f1 * step
    c = 0.5 * (a + b)
    k = int(np.argmin(np.abs(c - expect)))
    peak = float(np.max(v[s0[k] : s1[k] + 1]))
    return Strip(float(c[k]), float(b[k] - a[k]), peak - lo)


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


def _circle_candidates(
    image: NDArray[np.uint8], to_px: ToPx, radius: float, width: float, step: float
) -> list[tuple[float, float]]:
    """(angle, contrast) of strips of about ``width`` crossing a circle about the pivot."""
    n = int(np.ceil(2 * np.pi * radius / step))
    phi = np.linspace(0, 2 * np.pi, n, endpoint=False)
    pts = radius * np.column_stack([np.cos(phi), np.sin(phi)])
    v = bilinear(image, to_px(pts))
    ok = np.isfinite(v)
    if ok.sum() < 10:
        return []
    vv = np.where(ok, v, np.nanmedian(v))
    # Top-hat: brightness above the local floor over 3 widths.
    k = max(3, round(3 * width / step))
    from scipy.ndimage import grey_opening, uniform_filter1d

    sm = uniform_filter1d(vv, max(1, round(0.2 * width / step)), mode="wrap")
    floor = grey_opening(sm, size=k, mode="wrap")
    top = sm - floor
    noise = float(np.median(np.abs(np.diff(vv)))) + 1.0
    out = []
    thr = max(10.0, 5 * noise)
    peaks = np.flatnonzero((top > thr) & (top >= np.roll(top, 1)) & (top > np.roll(top, -1)) & ok)
    for p in peaks:
        half = top[p] / 2
        i0 = p
        while top[i0 % n] > half and p - i0 < n // 4:
            i0 -= 1
        i1 = p
        while top[i1 % n] > half and i1 - p < n // 4:
            i1 += 1
        wid = (i1 - i0 - 1) * step
        if 0.55 * width <= wid <= 1.7 * width:
            out.append((float(phi[p] + 0.5 * (i0 + i1 - 2 * p) * (2 * np.pi / n)), float(top[p])))
    return out


def locate(
    image: NDArray[np.uint8], to_px: ToPx, beam_length: float, beam_width: float, px_m: float
) -> Rough:
    """Find the beam around the pivot and follow it to the tip and back over the hub."""
    r1, r2 = 0.25 * beam_length, 0.45 * beam_length
    step = max(0.8 * px_m, beam_width / 16)
    c1 = _circle_candidates(image, to_px, r1, beam_width, step)
    c2 = _circle_candidates(image, to_px, r2, beam_width, step)
    best = None
    for a1, k1 in c1:
        for a2, k2 in c2:
            d = np.angle(np.exp(1j * (a2 - a1)))
            if abs(d) < 0.12 and (best is None or k1 + k2 > best[2]):
                best = (a1, a2, k1 + k2)
    if best is None:
        raise FrameFailure("no beam found (no bright strip of the beam's width about the pivot)")
    a1, a2, _ = best
    p1 = r1 * np.array([np.cos(a1), np.sin(a1)])
    p2 = r2 * np.array([np.cos(a2), np.sin(a2)])
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
    med = float(np.median(hub_w))
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
    return Rough(beam, clamp, hub_back, med, tip)


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

    All cross-profiles (perpendicular to ``direction``, +-``half_m``) are sampled in one
    call; the strip is then followed through them, each search starting where the last
    crossing was."""
    step = max(step_widths * width, 4 * px_m)
    ts = np.arange(step, max_len + step / 2, step)
    n = np.array([-direction[1], direction[0]])
    offs = np.arange(-half_m, half_m + 0.375 * px_m, 0.75 * px_m)
    pts = (
        start[None, None, :]
        + ts[:, None, None] * direction[None, None, :]
        + offs[None, :, None] * n[None, None, :]
    )
    vals = bilinear(image, to_px(pts.reshape(-1, 2))).reshape(len(ts), len(offs))
    out_pts, widths = [], []
    expect, prev_w = 0.0, width
    for k in range(len(ts)):
        s = find_strip(vals[k], offs, expect, near=0.6 * max(prev_w, width))
        if s is None or s.width < 0.5 * width or abs(s.centre - expect) > 0.7 * max(prev_w, width):
            break
        out_pts.append(start + ts[k] * direction + s.centre * n)
        widths.append(s.width)
        expect, prev_w = s.centre, s.width
    if not out_pts:
        return np.zeros((0, 2)), np.zeros(0)
    return np.array(out_pts), np.array(widths)
