"""Sub-pixel edges of a bright strip along pixel rows or columns of the raw image.

Working on the raw pixels (no resampling) keeps the edge estimate free of interpolation
bias: each scan line across the strip gives a rising and a falling edge, located by the
first moment of the intensity steps around the strongest step (exact for a box-sampled
or symmetric-blurred step edge). The points are mapped to the plane afterwards.

The scan is compiled (:mod:`vision.jit`): one kernel call per strip for its scan lines'
geometry, then for all strips of a frame one for every line's samples, steepest steps,
levels and windows, the erf fit and the edge points; its numpy form was ~200 array calls
of a few microseconds each (kept as the tests' reference, tests/vision/edges_reference.py).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from vision.jit import kernel
from vision.sampling import median_in_place, select_kth


def edge_moment(
    diff: NDArray[np.float64], peak: NDArray[np.intp], half: int | NDArray[np.intp]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """First moment of positive differences around ``peak`` in each row of ``diff``.

    ``diff[i, k]`` is the step between samples k and k+1 (located at k + 0.5); ``half`` is
    the window half-width (steps), one for all rows or one per row. Returns the sub-sample
    edge position, the summed step (contrast) and the RMS spread (samples)."""
    _n, m = diff.shape
    halves = np.broadcast_to(np.asarray(half), peak.shape)
    hmax = int(np.max(halves)) if halves.size else 0
    offs = np.arange(-hmax, hmax + 1)
    idx = peak[:, None] + offs[None, :]
    valid = (idx >= 0) & (idx < m) & (np.abs(offs)[None, :] <= halves[:, None])
    idx = np.clip(idx, 0, m - 1)
    d = np.take_along_axis(diff, idx, axis=1)
    d = np.where(valid & (d > 0), d, 0.0)
    total = d.sum(axis=1)
    pos = idx + 0.5
    with np.errstate(invalid="ignore", divide="ignore"):
        centre = (d * pos).sum(axis=1) / total
        spread = np.sqrt(np.maximum((d * (pos - centre[:, None]) ** 2).sum(axis=1) / total, 0))
    return centre, total, spread


def edge_gauss3(diff: NDArray[np.float64], peak: NDArray[np.intp]) -> NDArray[np.float64]:
    """Sub-sample edge position from a Gaussian through the three steps around ``peak``
    (log-parabola vertex); NaN where a step is not positive. Positions as in
    :func:`edge_moment` (step k at k + 0.5)."""
    m = diff.shape[1]
    p = np.clip(peak, 1, m - 2)
    rows = np.arange(len(p))
    a, b, c = diff[rows, p - 1], diff[rows, p], diff[rows, p + 1]
    ok = (a > 0) & (b > 0) & (c > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        la, lb, lc = (
            np.log(np.where(ok, a, 1.0)),
            np.log(np.where(ok, b, 1.0)),
            np.log(np.where(ok, c, 1.0)),
        )
        den = la - 2 * lb + lc
        off = np.where(ok & (den < 0), 0.5 * (la - lc) / den, np.nan)
    off = np.where(np.abs(off) <= 1.0, off, np.nan)
    return np.asarray(p + 0.5 + off, dtype=np.float64)


@dataclass
class StripEdges:
    """Edge points (raw px, (N, 2) x, y) on the two sides of a strip, paired by scan line,
    with their contrast (DN) and ramp width along the scan line (px)."""

    side_a: NDArray[np.float64]
    side_b: NDArray[np.float64]
    contrast: NDArray[np.float64]
    spread: NDArray[np.float64]


def strip_edges(
    image: NDArray[np.uint8],
    centre_px: NDArray[np.float64],
    half_width_px: float | NDArray[np.float64],
    margin_px: int = 5,
    window: int = 2,
    estimator: str = "moment",
    max_window: int = 8,
) -> StripEdges:
    """Scan across a bright strip whose centre line is the polyline ``centre_px``
    ((M, 2) raw px, ordered along the strip, dense). ``half_width_px`` (scalar or (M,)):
    its half width across the strip in px; along the scan lines it is widened by the
    polyline's slope."""
    return strip_edges_many(
        image, [(centre_px, half_width_px)], margin_px, window, estimator, max_window
    )[0]


def strip_edges_many(
    image: NDArray[np.uint8],
    strips: Sequence[tuple[NDArray[np.float64], float | NDArray[np.float64]]],
    margin_px: int = 5,
    window: int = 2,
    estimator: str = "moment",
    max_window: int = 8,
) -> list[StripEdges]:
    """:func:`strip_edges` for several strips ``(centre_px, half_width_px)`` at once: one
    pass of the kernels over all their scan lines. Each strip keeps what it would have
    alone: its scan direction (strips scanned the other way go in a second pass), its
    lines' reach and background samples, its level smoothing and its own fitted edge
    width."""
    out = [_EMPTY] * len(strips)
    geos = [_scan_lines(image.shape, c, hw, margin_px, max_window) for c, hw in strips]
    for columns in (True, False):
        which = [(i, g) for i, g in enumerate(geos) if g is not None and g.columns == columns]
        if which:
            chosen = [g for _, g in which]
            found = _scan(image, columns, chosen, margin_px, window, estimator, max_window)
            for (i, _), edges in zip(which, found, strict=True):
                out[i] = edges
    return out


_EMPTY = StripEdges(np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0), np.zeros(0))


@dataclass
class _Lines:
    """The scan lines of one strip: pixel columns (``columns``) or rows, their indices,
    the strip's centre and half width along each (px) and the first sample's position."""

    columns: bool
    lines: NDArray[np.intp]
    yc: NDArray[np.float64]
    half: NDArray[np.float64]
    top: NDArray[np.intp]
    reach: int


def _scan_lines(
    shape: tuple[int, ...],
    centre_px: NDArray[np.float64],
    half_width_px: float | NDArray[np.float64],
    margin_px: int,
    max_window: int,
) -> _Lines | None:
    hw = np.asarray(half_width_px, dtype=np.float64)
    if (
        centre_px.dtype == np.float64
        and centre_px.ndim == 2
        and len(centre_px) > 1
        and hw.shape == (len(centre_px),)
    ):
        # (the measurement's strips: in one call, unless the sort below is needed)
        found, columns, lines, yc, half, top, reach = _lines_k(
            centre_px, hw, shape[0], shape[1], margin_px + max_window
        )
        if found >= 0:
            return _Lines(columns, lines, yc, half, top, reach) if found else None
    d = centre_px[-1] - centre_px[0]
    columns = bool(abs(d[0]) >= abs(d[1]))
    # The scan-line index axis (x) and the position along the lines (y), each as one
    # contiguous array ordered along x.
    x, y = (centre_px[:, 0], centre_px[:, 1]) if columns else (centre_px[:, 1], centre_px[:, 0])
    ordered = False
    if hw.shape == x.shape and x.dtype == np.float64 and len(x) > 1:
        # x strictly monotonic (a strip's centre line along its scan-line axis): the
        # one order any sort gives, taken without one (:func:`_monotonic_k`)
        ordered, xs, ys, hs = _monotonic_k(x, y, hw)
        if ordered:
            x, y, hw = xs, ys, hs
    if not ordered:
        order = np.argsort(x)
        x, y = x[order], y[order]
        if hw.ndim == 0:
            hw = np.full(len(x), float(hw))
        else:
            hw = (hw if hw.shape == x.shape else np.broadcast_to(hw, x.shape))[order]
    # Along-scan positions and scan-line indices (columns: rows and columns of the image).
    h, w = shape if columns else shape[::-1]
    lines, yc, half, top, reach = _line_geometry(x, y, hw, h, w, margin_px + max_window)
    if reach < 0 or not len(lines):
        return None
    return _Lines(columns, lines, yc, half, top, reach)


@kernel
def _lines_k(
    centre: NDArray[np.float64], hw: NDArray[np.float64], rows: int, cols: int, extra: int
) -> tuple[
    int, bool, NDArray[np.intp], NDArray[np.float64], NDArray[np.float64], NDArray[np.intp], int
]:
    """:func:`_scan_lines` of a centre line ``centre`` (M, 2), M > 1, with a half width
    per point ``hw`` in an image of ``rows`` x ``cols``: 1 and the scan lines
    (:func:`_line_geometry`, the lines' axis ordered by :func:`_monotonic_k`), 0 when
    none, -1 when that axis is not strictly monotonic (left to the caller's sort)."""
    columns = abs(centre[-1, 0] - centre[0, 0]) >= abs(centre[-1, 1] - centre[0, 1])
    a, b = (0, 1) if columns else (1, 0)
    ordered, x, y, h = _monotonic_k(centre[:, a], centre[:, b], hw)
    if not ordered:
        e = np.empty(0, dtype=np.intp)
        return -1, columns, e, np.empty(0), np.empty(0), e, -1
    lines, yc, half, top, reach = _line_geometry(
        x, y, h, rows if columns else cols, cols if columns else rows, extra
    )
    return (1 if reach >= 0 and len(lines) else 0), columns, lines, yc, half, top, reach


@kernel
def _monotonic_k(
    x: NDArray[np.float64], y: NDArray[np.float64], hw: NDArray[np.float64]
) -> tuple[bool, NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """``x``, ``y``, ``hw`` in the order of increasing ``x`` when ``x`` is strictly
    increasing or strictly decreasing (copies, reversed for the latter); False (and
    empties) otherwise, and for NaN."""
    n = x.shape[0]
    up, down = True, True
    for i in range(n - 1):
        if not x[i + 1] > x[i]:
            up = False
        if not x[i + 1] < x[i]:
            down = False
    if not (up or down):
        return False, np.empty(0), np.empty(0), np.empty(0)
    xs, ys, hs = np.empty(n), np.empty(n), np.empty(n)
    for i in range(n):
        j = i if up else n - 1 - i
        xs[i], ys[i], hs[i] = x[j], y[j], hw[j]
    return True, xs, ys, hs


@kernel
def _line_geometry(
    x: NDArray[np.float64],
    y: NDArray[np.float64],
    hw: NDArray[np.float64],
    h: int,
    w: int,
    extra: int,
) -> tuple[NDArray[np.intp], NDArray[np.float64], NDArray[np.float64], NDArray[np.intp], int]:
    """The scan lines ``ceil(x[0]) .. floor(x[-1])`` within ``0 .. w - 1`` of a strip
    whose centre is at ``y`` and half width ``hw`` across it at ``x`` (increasing): the
    centre and the half width along each line (widened by the centre line's slope,
    central differences; two lines taken as level), the first sample's position and the
    lines' reach (the widest half width, rounded up, plus ``extra``); only the lines
    whose 2 reach + 1 samples fit ``0 .. h - 1``. Reach -1: fewer than two lines."""
    first = max(math.ceil(x[0]), 0)
    last = min(math.floor(x[-1]), w - 1)
    count = last - first + 1
    if count < 2:
        return np.empty(0, np.intp), np.empty(0), np.empty(0), np.empty(0, np.intp), -1
    lines = np.arange(first, last + 1)
    yc = _interp(lines, x, y)
    half = _interp(lines, x, hw)
    for i in range(count):
        # d yc / d line (lines one apart), as np.gradient
        if count == 2:
            slope = 0.0
        elif i == 0:
            slope = yc[1] - yc[0]
        elif i == count - 1:
            slope = yc[i] - yc[i - 1]
        else:
            slope = (yc[i + 1] - yc[i - 1]) / 2.0
        half[i] *= np.sqrt(1.0 + slope * slope)
    reach = math.ceil(half.max()) + extra
    keep = np.empty(count, dtype=np.bool_)
    top = np.empty(count, dtype=np.intp)
    kept = 0
    for i in range(count):
        top[i] = int(np.rint(yc[i])) - reach
        keep[i] = top[i] >= 0 and top[i] + 2 * reach < h
        kept += keep[i]
    if kept == count:
        return lines, yc, half, top, reach
    return lines[keep], yc[keep], half[keep], top[keep], reach


@kernel
def _interp(
    xq: NDArray[np.intp], xp: NDArray[np.float64], fp: NDArray[np.float64]
) -> NDArray[np.float64]:
    """``np.interp(xq, xp, fp)`` (``xp`` and ``xq`` increasing, two points or more), to
    the bit: its interval (the last ``j`` with ``xp[j] <= x``), its exact hits and its
    slope formula. The intervals found by one walk along both (a bisection for each
    query was half of the scan lines' geometry)."""
    n = len(xp)
    out = np.empty(len(xq))
    j = 0
    for i in range(len(xq)):
        xv = np.float64(xq[i])
        if xv > xp[n - 1]:
            out[i] = fp[n - 1]
            continue
        if xv < xp[0]:
            out[i] = fp[0]
            continue
        while j + 1 < n and xp[j + 1] <= xv:  # (xq increasing: j never goes back)
            j += 1
        if j == n - 1 or xp[j] == xv:
            out[i] = fp[j]
            continue
        slope = (fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j])
        r = slope * (xv - xp[j]) + fp[j]
        if np.isnan(r):  # numpy's second try, from the other end
            r = slope * (xv - xp[j + 1]) + fp[j + 1]
            if np.isnan(r) and fp[j] == fp[j + 1]:
                r = fp[j]
        out[i] = r
    return out


def _scan(
    image: NDArray[np.uint8],
    columns: bool,
    geos: list[_Lines],
    margin_px: int,
    window: int,
    estimator: str,
    max_window: int,
) -> list[StripEdges]:
    lines = np.concatenate([g.lines for g in geos])
    sizes = [len(g.lines) for g in geos]
    bounds = np.array(list(itertools.accumulate(sizes, initial=0)), dtype=np.intp)
    reaches = np.array([g.reach for g in geos], dtype=np.intp)
    tops = np.concatenate([g.top for g in geos])
    args = (
        np.ascontiguousarray(image),
        columns,
        lines,
        tops,
        np.concatenate([g.yc for g in geos]),
        np.concatenate([g.half for g in geos]),
        bounds,
        reaches,
        margin_px,
        window,
        max_window,
    )
    if estimator == "erf":  # (the measurement's: the whole scan in one call)
        side_a, side_b, contrast, spread, ends = _scan_erf_k(*args)
    else:
        buf, peak, cen, step, ramp, _, _ = _scan_kernel(*args, estimator == "area")
        if estimator == "gauss3":
            # Each line spans its own strip's 2 reach + 1 samples (see _scan_kernel).
            pad, m = max_window, 2 * max(g.reach for g in geos) + 1
            prof2 = buf[:, pad : pad + m]
            g = edge_gauss3(np.subtract(prof2[:, 1:], prof2[:, :-1]), peak)
            cen = np.where(np.isfinite(g), g, cen)
        side_a, side_b, contrast, spread, ends = _sides_k(
            lines, tops, cen, step, ramp, bounds, columns
        )
    return [
        StripEdges(side_a[a:b], side_b[a:b], contrast[a:b], spread[a:b])
        for a, b in itertools.pairwise(ends.tolist())
    ]


@kernel
def _scan_erf_k(
    image: NDArray[np.uint8],
    columns: bool,
    lines: NDArray[np.intp],
    top: NDArray[np.intp],
    yc: NDArray[np.float64],
    half: NDArray[np.float64],
    bounds: NDArray[np.intp],
    reaches: NDArray[np.intp],
    margin: int,
    window: int,
    max_window: int,
) -> tuple[
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.intp],
]:
    """:func:`_scan` with the erf estimator: :func:`_scan_kernel`, :func:`_erf_fit` on
    its samples (one edge width per strip and side: lines n.. are the falling sides)
    and :func:`_sides_k`, in one call (each call's arrays boxed and unboxed were a
    tenth of the scan)."""
    n = len(lines)
    buf, _, cen, step, ramp, lo2, hi2 = _scan_kernel(
        image, columns, lines, top, yc, half, bounds, reaches, margin, window, max_window, True
    )
    # Each line spans its own strip's 2 reach + 1 samples (see _scan_kernel).
    pad, m = max_window, 2 * reaches.max() + 1
    prof2 = buf[:, pad : pad + m]
    nb = len(bounds) - 1
    blocks = np.empty(2 * nb + 1, dtype=np.intp)
    for b in range(nb + 1):
        blocks[b] = bounds[b]
    for b in range(1, nb + 1):
        blocks[nb + b] = bounds[b] + n
    fitted = _erf_fit(prof2, cen, lo2, hi2, 0.4 * ramp, 1.0, blocks)
    return _sides_k(lines, top, fitted, step, ramp, bounds, columns)


@kernel
def _sides_k(
    lines: NDArray[np.intp],
    tops: NDArray[np.intp],
    cen: NDArray[np.float64],
    step: NDArray[np.float64],
    ramp: NDArray[np.float64],
    bounds: NDArray[np.intp],
    columns: bool,
) -> tuple[
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.intp],
]:
    """:func:`_scan`'s edge points (x, y) of both sides (``cen``: the rising sides'
    positions along the lines, then the falling sides'): the line index and its first
    sample's position plus the edge's, whichever axis each is; with each line's
    contrast (the smaller side's summed step, ``step``) and ramp width (the wider
    side's, ``ramp``). Only the lines with both edges (finite) and contrast, packed
    strip after strip (``bounds``): the strips' ends among them last."""
    n = lines.shape[0]
    la, aa = (0, 1) if columns else (1, 0)
    side_a, side_b = np.empty((n, 2)), np.empty((n, 2))
    contrast, spread = np.empty(n), np.empty(n)
    ends = np.empty(len(bounds), dtype=np.intp)
    ends[0] = 0
    k = 0
    for s in range(len(bounds) - 1):
        for i in range(bounds[s], bounds[s + 1]):
            con = np.minimum(step[i], step[n + i])
            if not (np.isfinite(cen[i]) and np.isfinite(cen[n + i]) and con > 0):
                continue
            base = np.float64(tops[i])
            side_a[k, la] = side_b[k, la] = np.float64(lines[i])
            side_a[k, aa] = base + cen[i]
            side_b[k, aa] = base + cen[n + i]
            contrast[k] = con
            spread[k] = np.maximum(ramp[i], ramp[n + i])
            k += 1
        ends[s + 1] = k
    return side_a[:k], side_b[:k], contrast[:k], spread[:k], ends


#: The profiles' padding above their first sample (and its negation below the last).
_PAD_LEVEL = 1000


@kernel
def _scan_kernel(
    image: NDArray[np.uint8],
    columns: bool,
    lines: NDArray[np.intp],
    top: NDArray[np.intp],
    yc: NDArray[np.float64],
    half: NDArray[np.float64],
    bounds: NDArray[np.intp],
    reaches: NDArray[np.intp],
    margin: int,
    window: int,
    max_window: int,
    levels: bool,
) -> tuple[
    NDArray[np.int16],
    NDArray[np.intp],
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.float64],
]:
    """The edges of every strip's scan lines (pixel columns ``columns`` or rows
    ``lines``, strip s the lines ``bounds[s]:bounds[s + 1]``, of ``2 reaches[s] + 1``
    samples from ``top`` on; the strip's centre ``yc`` and half width ``half`` along
    each): the samples, each side's steepest step, moment or area position, contrast and
    ramp width, and the plateau levels at each edge (``levels``, else zeros).

    The samples are held (line, position along the line) as int16: 8-bit values and
    their negations. Both sides at once: the falling edge of a profile between levels lo
    and hi is the rising edge of the negated profile between -hi and -lo, so lines n..
    hold -prof and every step below sees rising edges only. ``max_window`` samples of
    padding before and after (never counted as samples) step down into the line and out
    of it, so that only steps between a line's own samples can be positive in an edge
    window. Lines of a narrower strip carry samples past their end (clipped to the
    image) that nothing reads but the steepest-step search, as before.

    Returns (padded samples, peak step, position, contrast (summed rising steps), ramp
    width, lo, hi) per side-line (lines 0..n-1 the rising sides, n.. the falling)."""
    n = len(lines)
    nb = len(reaches)
    m = 2 * reaches.max() + 1 if nb else 1
    pad = max_window
    extent = image.shape[0] if columns else image.shape[1]
    buf = np.empty((2 * n, m + 2 * pad), dtype=np.int16)
    for j in range(2 * n):
        head, tail = buf[j, :pad], buf[j, pad + m :]
        for k in range(pad):
            head[k] = _PAD_LEVEL
            tail[k] = -_PAD_LEVEL
    for i in range(n):
        # Samples past the image's end repeat its last pixel. Each loop on views, its
        # index from 0: numba's negative-index fix-up on ``pad + k`` kept it scalar.
        inside = min(m, extent - top[i])
        pos, neg = buf[i, pad : pad + m], buf[n + i, pad : pad + m]
        if columns:  # a strided column: its loads one by one, the negation after
            col = image[top[i] :, lines[i]]
            for k in range(inside):
                pos[k] = np.int16(col[k])
            for k in range(inside, m):
                pos[k] = np.int16(col[inside - 1])
            for k in range(m):
                neg[k] = -pos[k]
        else:  # a contiguous run of one image row (a loop LLVM vectorises)
            run = image[lines[i], top[i] :]
            for k in range(inside):
                v = np.int16(run[k])
                pos[k] = v
                neg[k] = -v
            for k in range(inside, m):
                v = np.int16(run[inside - 1])
                pos[k] = v
                neg[k] = -v
    # Per line: its strip's sample count (its far background's end).
    ends = np.empty(n, dtype=np.intp)
    for s in range(nb):
        for i in range(bounds[s], bounds[s + 1]):
            ends[i] = 2 * reaches[s] + 1
    level_in = np.empty(n)
    diff_ends = np.empty(n)  # far sum - near sum (the pooled tilt's input)
    ends_vals = np.empty((2 * margin, n), dtype=np.int32)  # (end sample, line)
    for i in range(n):
        mid = yc[i] - top[i]
        # Mean of the samples k with |k - mid| < half / 2 (integer sums, exact).
        h = 0.5 * half[i]
        k0 = min(max(int(np.floor(mid - h)) + 1, 0), m)
        k1 = min(max(int(np.ceil(mid + h)), 0), m)
        tot = 0
        inner = buf[i, pad + min(k0, k1) : pad + max(k0, k1)]  # (a view from 0: vectorised)
        for k in range(len(inner)):
            tot += inner[k]
        if k1 < k0:
            tot = -tot
        level_in[i] = tot / max(k1 - k0, 1)
        # Background: the median of the first and the last ``margin`` samples.
        near = 0
        far = 0
        for k in range(margin):
            va = buf[i, pad + k]
            vb = buf[i, pad + ends[i] - margin + k]
            ends_vals[k, i] = va
            ends_vals[margin + k, i] = vb
            near += va
            far += vb
        diff_ends[i] = far - near
    level_out = _column_medians_even(ends_vals)
    peak = np.empty(2 * n, dtype=np.intp)
    ramp = np.empty(2 * n)
    steps = m - 1  # a line's steps
    for j in range(2 * n):
        i = j if j < n else j - n  # (j % n: a 64-bit division a line)
        mid = yc[i] - top[i]
        centre = mid - half[i] if j < n else mid + half[i]
        tol = max(0.35 * half[i], 2.5)
        # The steepest rising step within tol of the expected edge (the first, on a
        # tie); step k, between samples k and k + 1, sits at k + 0.5.
        k0 = min(max(int(np.ceil(centre - tol - 0.5)), 0), steps - 1)
        k1 = min(max(int(np.floor(centre + tol - 0.5)), 0), steps - 1)
        best = -32768
        at = k0
        row = buf[j, pad + k0 : pad + k1 + 2]
        for k in range(k1 + 1 - k0):
            # (selects, not branches: which step is the steepest so far is a coin flip
            # on a noisy ramp, and its mispredictions were most of this loop's time)
            d = int(row[k + 1]) - int(row[k])
            up = d > best
            best = d if up else best
            at = k0 + k if up else at
        peak[j] = at
        # Ramp width (px) = contrast / steepest step: motion blur widens it; the
        # moment window grows with it so a blurred edge is still located at its centre.
        contrast = max(level_in[i] - level_out[i], 1e-6)
        steepest = np.int16(buf[j, pad + at + 1] - buf[j, pad + at])
        ramp[j] = contrast / max(np.float64(steepest), 1e-6)
    lo2 = np.zeros(2 * n)
    hi2 = np.zeros(2 * n)
    if levels:
        # The plateau levels smoothed along each strip (not across strips).
        lo = _smoothed(level_out, bounds)
        hi = _smoothed(level_in, bounds)
        # The levels at each edge, not at the line's middle (see _pooled_tilt).
        rel = np.empty(n)
        for i in range(n):
            rel[i] = diff_ends[i] / (margin * max(level_out[i], 1.0))
        for s in range(nb):
            a, b = bounds[s], bounds[s + 1]
            t = _pooled_tilt(rel[a:b]) / (2 * reaches[s] + 1 - margin)
            for i in range(a, b):
                tilt = t * half[i]
                fa, fb = 1.0 - tilt, 1.0 + tilt  # the light at the edges
                lo2[i] = lo[i] * fa
                hi2[i] = hi[i] * fa
                lo2[n + i] = -(hi[i] * fb)
                hi2[n + i] = -(lo[i] * fb)
    cen = np.empty(2 * n)
    step = np.empty(2 * n)
    for j in range(2 * n):
        p = peak[j]
        w = int(min(max(np.ceil(0.5 * ramp[j] + 0.5), window), max_window))
        cen[j], step[j] = _window_edge(buf[j], pad, m, p, w, levels, lo2[j], hi2[j])
    return buf, peak, cen, step, ramp, lo2, hi2


@kernel
def _window_edge(
    row: NDArray[np.int16],
    pad: int,
    m: int,
    p: int,
    w: int,
    levels: bool,
    lo: float,
    hi: float,
) -> tuple[float, float]:
    """The rising edge about the steepest step ``p`` of one side-line's padded samples
    ``row`` (``m`` samples after ``pad`` of padding), from the samples p - w .. p + w + 1, and the
    sum of its rising steps (its contrast):

    - the first moment of the rising steps within ``w`` of the peak (as
      :func:`edge_moment`);
    - with plateau levels ``lo`` and ``hi`` (``levels``): the position of the sharp step
      with the same area between them (exact for any blur once the window spans the
      ramp; less noisy than the moment of the steps), where the window stays on the line
      and the levels differ by more than 1 DN. Integer sums: exact in any order."""
    total = 0
    moment = 0
    total_v = 0
    seg = row[pad + p - w : pad + p + w + 2]  # (a view from 0: no negative-index fix-up)
    for q in range(2 * w + 1):
        d = max(int(seg[q + 1]) - int(seg[q]), 0)  # (no branch to mispredict)
        total += d
        moment += (q - w) * d
        total_v += seg[q]
    total_v += seg[2 * w + 1]
    step = np.float64(total)
    centre = p + 0.5 + moment / step
    if levels and p >= w and p + w + 1 < m and hi - lo > 1.0:
        frac = (total_v - (2 * w + 2) * lo) / max(hi - lo, 1e-6)
        area = np.float64(p + w + 1) + 0.5 - frac
        if np.isfinite(area):
            return area, step
    return centre, step


@kernel
def _smoothed(x: NDArray[np.float64], bounds: NDArray[np.intp]) -> NDArray[np.float64]:
    """Each strip's (``bounds``) series smoothed along it by a running median of 9 lines
    (fewer on a short strip: the largest odd size it holds, none below 3 lines), its ends
    held: ``scipy.ndimage.median_filter`` with ``mode="nearest"`` (an odd window's median
    is one of its values: exact). No NaN."""
    out = np.empty(len(x))
    win = np.empty(9)
    for s in range(len(bounds) - 1):
        a, b = bounds[s], bounds[s + 1]
        size = min(9, 2 * ((b - a) // 2) + 1) if b - a > 2 else 1
        h = size // 2
        for i in range(a, b):
            if size == 9 and a + 4 <= i < b - 4:
                continue  # (below: the window whole, in a loop LLVM vectorises)
            for o in range(size):
                win[o] = x[min(max(i - h + o, a), b - 1)]
            if size == 9:
                out[i] = _median9(win)
            else:
                _sort(win[:size])
                out[i] = win[h]
        if size == 9:
            # views indexed from 0 (numba's negative-index fix-up on i - 4 kept the
            # loads gathers)
            k = b - a - 8
            q0, q1, q2 = x[a : a + k], x[a + 1 : a + 1 + k], x[a + 2 : a + 2 + k]
            q3, q4, q5 = x[a + 3 : a + 3 + k], x[a + 4 : a + 4 + k], x[a + 5 : a + 5 + k]
            q6, q7, q8 = x[a + 6 : a + 6 + k], x[a + 7 : a + 7 + k], x[a + 8 : a + 8 + k]
            mid = out[a + 4 : a + 4 + k]
            for j in range(k):
                mid[j] = _median9_of(q0[j], q1[j], q2[j], q3[j], q4[j], q5[j], q6[j], q7[j], q8[j])
    return out


@kernel
def _median9(p: NDArray[np.float64]) -> float:
    """The median of the 9 values ``p`` (no NaN), exactly and without branches: the
    median of the three sorted triples' largest minimum, median of medians and smallest
    maximum (a min/max network, checked on every 0-1 input)."""
    return _median9_of(p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], p[8])


@kernel
def _median9_of(
    p0: float,
    p1: float,
    p2: float,
    p3: float,
    p4: float,
    p5: float,
    p6: float,
    p7: float,
    p8: float,
) -> float:
    """:func:`_median9` of nine values (no memory: inlined into a loop, it vectorises)."""
    lo, hi = min(p0, p1), max(p0, p1)
    a0, a1, a2 = min(lo, p2), min(hi, max(lo, p2)), max(hi, p2)
    lo, hi = min(p3, p4), max(p3, p4)
    b0, b1, b2 = min(lo, p5), min(hi, max(lo, p5)), max(hi, p5)
    lo, hi = min(p6, p7), max(p6, p7)
    c0, c1, c2 = min(lo, p8), min(hi, max(lo, p8)), max(hi, p8)
    first = max(max(a0, b0), c0)
    last = min(min(a2, b2), c2)
    lo, hi = min(a1, b1), max(a1, b1)
    mid = min(hi, max(lo, c1))
    lo, hi = min(first, mid), max(first, mid)
    return min(hi, max(lo, last))


@kernel
def _column_medians_even(x: NDArray[np.int32]) -> NDArray[np.float64]:
    """``np.median(x, axis=0)`` of an even number of rows, sorting each column in place:
    odd-even transposition (as many rounds as rows), each compare-exchange a min and a
    max along the row pair, a loop over the columns that LLVM vectorises (a column at a
    time, ten values took 100 compares and 0.1 ms a frame). Exact (integers; the mean of
    the two middle ones as numpy's)."""
    rows, n = x.shape
    if rows == 0:  # (no background samples: level 0, as before)
        return np.zeros(n)
    for rnd in range(rows):
        for a in range(rnd % 2, rows - 1, 2):
            lo, hi = x[a], x[a + 1]
            for i in range(n):
                p, q = lo[i], hi[i]
                lo[i] = min(p, q)
                hi[i] = max(p, q)
    out = np.empty(n)
    h = rows // 2
    for i in range(n):
        out[i] = 0.5 * (np.float64(x[h - 1, i]) + np.float64(x[h, i]))
    return out


@kernel
def _sort(a: NDArray[np.float64]) -> None:
    """Sort ``a`` (no NaN) in place: Shell's sort with Ciura's gaps (a few to a few
    hundred values: ``np.sort`` compiles several times slower)."""
    n = len(a)
    for gap in (701, 301, 132, 57, 23, 10, 4, 1):
        for k in range(gap, n):
            v = a[k]
            q = k
            while q >= gap and a[q - gap] > v:
                a[q] = a[q - gap]
                q -= gap
            a[q] = v


@kernel
def _pooled_tilt(rel: NDArray[np.float64]) -> float:
    """A strip's relative change of the background level along its lines (per line, over
    the span between the ends' centres, which the caller divides by), from each line's
    ``rel``; 0 for a strip of fewer than 8 lines.

    The uneven light tilts both plateaus, and levels taken at a line's middle put both
    edges of a strip off the same way, toward the light (by about the mid-level's change
    over a half width over the edge's slope: 0.004 px on a 21 px beam and 0.01 px on a
    42 px hub with the light 15 % brighter across a 2048 px frame, which turned the hub
    angle +0.5 of its sd on average). The light scales what it falls on, so both levels
    tilt by the same fraction per sample: the background's, from the lines' two ends
    (44-64 samples apart), pooled over the strip's lines (the light is smooth; one line's
    tilt is mostly noise). The strip's own inner part is a short base (5-10 samples): its
    tilt, tried, was noisier, and moved the other renderer's even-light frames more.

    The lines' values are pooled by the mean of their middle half (lines whose ends cross
    clutter are outliers), shrunk toward 0 by ``max(0, 1 - (se / t)^2)`` (``se``: that
    mean's standard error, Tukey and McLaughlin's, from the winsorized variance). Without
    it, the tilt's noise in even light (a short wide hub: few lines of many samples each)
    moved the hub angle by 0.14 of its sd RMS; shrunk, about a third of that noise's
    variance is left, while a tilt of 4 standard errors keeps 94 % of its correction."""
    k = len(rel)
    if k < 8:
        return 0.0
    # The order statistics lo .. hi by two selections (a sort of the strip's hundreds
    # of lines was 0.06 ms a frame): q[lo .. hi] then hold them, in another order.
    q = rel.copy()
    lo, hi = k // 4, (3 * k) // 4
    select_kth(q, lo, k)
    select_kth(q[lo + 1 :], hi - lo - 1, k - lo - 1)
    t = 0.0
    for i in range(lo, hi + 1):
        t += q[i]
    t /= hi + 1 - lo
    w = np.empty(k)
    wsum = 0.0
    for i in range(k):
        w[i] = min(max(q[i], q[lo]), q[hi])  # winsorized
        wsum += w[i]
    wmean = wsum / k
    ww = 0.0
    for i in range(k):
        d = w[i] - wmean
        ww += d * d
    se = math.sqrt(ww / k) / ((hi + 1 - lo) / k * math.sqrt(k))
    if t == 0.0:
        return 0.0
    return t * max(0.0, 1.0 - (se / t) ** 2)


def erf_edge(
    prof: NDArray[np.floating] | NDArray[np.integer],
    start: NDArray[np.float64],
    lo: NDArray[np.float64],
    hi: NDArray[np.float64],
    sigma0: NDArray[np.float64],
    rising: bool = True,
    blocks: int = 1,
) -> NDArray[np.float64]:
    """Least-squares edge position (sample units) of a blurred step
    ``lo + (hi - lo) Phi((j - c) / s)`` fitted to the samples ``j`` near ``start``
    (profiles (lines, samples)).

    The step's width ``s`` is fitted with ``c`` on a subsample of the lines and fixed at
    its median (one lens, one edge direction); then only ``c`` is fitted on every line:
    the maximum-likelihood position under white noise, which weights each sample by the
    local slope of the edge instead of equally (the area estimator's noise grows with
    its window). ``blocks``: the lines are that many consecutive (near) equal blocks
    (``np.array_split``'s), each a different edge with its own median width."""
    n = len(start)
    size, extra = divmod(n, blocks)
    bounds = np.cumsum([0] + [size + 1] * extra + [size] * (blocks - extra))
    return _erf_fit(
        np.ascontiguousarray(prof, dtype=np.float64),
        np.asarray(start, dtype=np.float64),
        np.asarray(lo, dtype=np.float64),
        np.asarray(hi, dtype=np.float64),
        np.asarray(sigma0, dtype=np.float64),
        1.0 if rising else -1.0,
        bounds.astype(np.intp),
    )


#: Lines per block whose joint fit sets the block's edge width (its median).
_WIDTH_LINES = 96
#: A position step below this (px) ends a line's fit.
_CONVERGED_PX = 1e-3


@kernel
def _erf_fit(
    prof: NDArray[Any],
    start: NDArray[np.float64],
    lo: NDArray[np.float64],
    hi: NDArray[np.float64],
    sigma0: NDArray[np.float64],
    sign: float,
    bounds: NDArray[np.intp],
) -> NDArray[np.float64]:
    """:func:`erf_edge` on profiles (lines, samples), the lines' blocks
    ``bounds[b] : bounds[b + 1]``.

    Two stages. The width: joint (c, s) Gauss-Newton steps on a subsample of each block's
    lines (at most ``_WIDTH_LINES``), whose median width is the block's ``s`` (a symmetric
    edge's position and width are orthogonal parameters, so the position hardly depends
    on the width's small error). The position: ``c``-only Gauss-Newton steps on every
    line with that width."""
    m = prof.shape[1]
    half, ok, c, s, centre = _erf_start(start, sigma0, bounds, m)
    if m < 2 * half + 1:  # no window fits
        return np.full(len(start), np.nan)
    v = _erf_samples(prof, centre, lo, half)
    return _erf_solve(v, ok, c, s, centre, start, hi - lo, sign, bounds)


@kernel
def _erf_start(
    start: NDArray[np.float64],
    sigma0: NDArray[np.float64],
    bounds: NDArray[np.intp],
    m: int,
) -> tuple[int, NDArray[np.bool_], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """:func:`_erf_fit`'s window: its half width, and per line whether it has a start
    whose window fits the ``m`` samples, the start (else the window's centre), the
    initial width and the window's centre (the profile's middle where none fits)."""
    n = len(start)
    nb = len(bounds) - 1
    ok = np.empty(n, dtype=np.bool_)
    c = np.empty(n)
    s = np.empty(n)
    for i in range(n):
        ok[i] = np.isfinite(start[i])
        c[i] = start[i] if ok[i] else 0.0
        s0 = sigma0[i] if np.isfinite(sigma0[i]) else 0.8
        s[i] = min(max(s0, 0.4), 3.0)
    # One window of samples about the start (it is within a sample of the edge): +-3
    # samples hold all but ~1e-3 of a sharp edge's information (the weight of a sample
    # u widths out is exp(-u^2)); blurred edges (a block's median width above 1.2 px)
    # get +-4.
    half = 3
    sub = _subsample(bounds, ok)
    for b in range(nb):
        if sub[b + 1] > sub[b] and _median_of(s, sub[nb + 1 + sub[b] : nb + 1 + sub[b + 1]]) > 1.2:
            half = 4
    # A start whose window leaves the profile is no edge of this strip (the area
    # estimate runs off on lines that cross something else): NaN, like no start. Those
    # lines sit at the profile's middle, so every window is whole.
    centre = np.empty(n)
    for i in range(n):
        ci = np.rint(c[i])
        ok[i] = ok[i] and ci >= half and ci <= m - 1 - half
        centre[i] = ci if ok[i] else np.float64(m // 2)
        if not ok[i]:
            c[i] = centre[i]
    return half, ok, c, s, centre


@kernel
def _erf_samples(
    prof: NDArray[Any], centre: NDArray[np.float64], lo: NDArray[np.float64], half: int
) -> NDArray[np.float32]:
    """Each line's window of samples about ``centre``, less ``lo``, (window sample,
    line), in single precision: the model is evaluated in single precision about the
    window's centre (the residuals are then good to 1e-5 DN and a step to 1e-7 px, far
    below the noise); the positions themselves, and the 2x2 solves, stay double. The
    line last: the fit's loops run along the lines (see :func:`_erf_steps`)."""
    n = len(centre)
    width = 2 * half + 1
    v = np.empty((width, n), dtype=np.float32)
    for i in range(n):
        first = int(centre[i]) - half
        for w in range(width):
            v[w, i] = np.float32(np.float64(prof[i, first + w]) - lo[i])
    return v


@kernel
def _erf_solve(
    v: NDArray[np.float32],
    ok: NDArray[np.bool_],
    c: NDArray[np.float64],
    s: NDArray[np.float64],
    centre: NDArray[np.float64],
    start: NDArray[np.float64],
    span: NDArray[np.float64],
    sign: float,
    bounds: NDArray[np.intp],
) -> NDArray[np.float64]:
    """:func:`_erf_fit`'s two stages on the windows ``v`` ((window sample, line);
    ``span``: hi - lo). ``s`` is overwritten by the blocks' widths. Each step is one
    :func:`_erf_steps` call on all the lines it moves (the width's subsample, every
    line, the lines not yet converged), as the numpy form did."""
    n = len(c)
    nb = len(bounds) - 1
    half = v.shape[0] // 2
    offs = np.empty(2 * half + 1, dtype=np.float32)
    for w in range(2 * half + 1):
        offs[w] = np.float32(w - half)
    amp = np.empty(n)
    for i in range(n):
        amp[i] = span[i] if not span[i] < 1e-6 else 1e-6  # (NaN stays NaN)
    # Width, per block, from a subsample of its lines.
    sub = _subsample(bounds, ok)
    pick = sub[nb + 1 :]
    k = len(pick)
    cs, ss, cen, amps = np.empty(k), np.empty(k), np.empty(k), np.empty(k)
    for q in range(k):
        i = pick[q]
        cs[q], ss[q], cen[q], amps[q] = c[i], s[i], centre[i], amp[i]
    vs = _erf_take(v, pick)
    dc, ds = np.empty(k), np.empty(k)
    for _ in range(2):
        _erf_steps(vs, offs, amps, sign, cs, cen, ss, True, dc, ds)
        for q in range(k):
            cs[q] += min(max(dc[q], -1.0), 1.0) if np.isfinite(dc[q]) else 0.0
            step = min(max(ds[q], -0.5), 0.5) if np.isfinite(ds[q]) else 0.0
            ss[q] = min(max(ss[q] + step, 0.3), 4.0)
    for b in range(nb):
        if sub[b + 1] > sub[b]:
            med = _median_of(ss[sub[b] : sub[b + 1]], np.arange(sub[b + 1] - sub[b]))
            for i in range(bounds[b], bounds[b + 1]):
                s[i] = med
    # Position: two steps on every line, a third where the second still moved the edge
    # by more than _CONVERGED_PX (the steps shrink about tenfold each: p99 9e-2, 8e-3,
    # 1e-3 px on nominal frames, so a line skipped keeps ~1e-4 px of its last step).
    ci = c.copy()
    dc, ds = np.empty(n), np.empty(0)
    for _ in range(2):
        _erf_steps(v, offs, amp, sign, ci, centre, s, False, dc, ds)
        for i in range(n):
            ci[i] += min(max(dc[i], -1.0), 1.0) if np.isfinite(dc[i]) else 0.0
    k = 0
    for i in range(n):
        k += abs(dc[i]) > _CONVERGED_PX
    if k:
        pick = np.empty(k, dtype=np.intp)
        k = 0
        for i in range(n):
            if abs(dc[i]) > _CONVERGED_PX:
                pick[k] = i
                k += 1
        cs, ss, cen, amps = np.empty(k), np.empty(k), np.empty(k), np.empty(k)
        for q in range(k):
            i = pick[q]
            cs[q], ss[q], cen[q], amps[q] = ci[i], s[i], centre[i], amp[i]
        dc3 = np.empty(k)
        _erf_steps(_erf_take(v, pick), offs, amps, sign, cs, cen, ss, False, dc3, ds)
        for q in range(k):
            ci[pick[q]] += min(max(dc3[q], -1.0), 1.0) if np.isfinite(dc3[q]) else 0.0
    out = np.empty(n)
    for i in range(n):
        good = ok[i] and span[i] > 1.0 and abs(ci[i] - start[i]) <= 2.0
        out[i] = ci[i] if good else np.nan
    return out


@kernel
def _erf_take(v: NDArray[np.float32], pick: NDArray[np.intp]) -> NDArray[np.float32]:
    """The windows (columns) ``pick`` of ``v``, contiguous."""
    out = np.empty((v.shape[0], len(pick)), dtype=np.float32)
    for w in range(v.shape[0]):
        for q in range(len(pick)):
            out[w, q] = v[w, pick[q]]
    return out


@kernel
def _subsample(bounds: NDArray[np.intp], ok: NDArray[np.bool_]) -> NDArray[np.intp]:
    """Of each block's lines with ``ok``, about ``_WIDTH_LINES`` evenly spread: the
    counts' offsets (``nb + 1``) followed by the chosen lines, block by block."""
    nb = len(bounds) - 1
    out = np.empty(nb + 1 + len(ok), dtype=np.intp)
    q = nb + 1
    out[0] = 0
    for b in range(nb):
        cnt = 0
        for i in range(bounds[b], bounds[b + 1]):
            cnt += ok[i]
        stride = max(1, cnt // _WIDTH_LINES)
        k = 0
        for i in range(bounds[b], bounds[b + 1]):
            if ok[i]:
                if k % stride == 0:
                    out[q] = i
                    q += 1
                k += 1
        out[b + 1] = q - (nb + 1)
    return out[:q]


@kernel
def _median_of(x: NDArray[np.float64], idx: NDArray[np.intp]) -> float:
    """``np.median(x[idx])`` (``idx`` not empty; no NaN), by selection (a sort of the
    width's subsample, up to 96 values a block, was 0.02 ms a frame)."""
    k = len(idx)
    a = np.empty(k)
    for q in range(k):
        a[q] = x[idx[q]]
    return median_in_place(a)


_ROOT2PI = math.sqrt(2 * math.pi)


@kernel
def _erf_steps(
    v: NDArray[np.float32],
    offs: NDArray[np.float32],
    amp: NDArray[np.float64],
    sign: float,
    c: NDArray[np.float64],
    centre: NDArray[np.float64],
    s: NDArray[np.float64],
    joint: bool,
    dc: NDArray[np.float64],
    ds: NDArray[np.float64],
) -> None:
    """One Gauss-Newton step of every line's fit (windows ``v`` (window sample, line)):
    into ``dc`` the position's step, at fixed width or (``joint``) with the width's step
    into ``ds``. The model in single precision: ``u = (offs - (c - centre)) sign / s``,
    the weight ``g = exp(-u^2 / 2)``, the residual ``v - amp Phi(u)``; each window's sums
    in single precision in window order (as numpy's column sums of a (window, lines)
    array), the 2x2 solves in double.

    The sums run window sample by window sample, each over all the lines: a loop of
    independent lines with :func:`_exp32` and :func:`_ndtr32` inlined, which LLVM
    vectorises (the window's own loop, a sum, cannot be without reordering it)."""
    n = len(c)
    du = np.empty(n, dtype=np.float32)
    sc = np.empty(n, dtype=np.float32)
    amp32 = np.empty(n, dtype=np.float32)
    for i in range(n):
        du[i] = np.float32(c[i] - centre[i])
        sc[i] = np.float32(sign / s[i])
        amp32[i] = np.float32(amp[i])
    s0 = np.zeros(n, dtype=np.float32)
    t0 = np.zeros(n, dtype=np.float32)
    if joint:
        s1 = np.zeros(n, dtype=np.float32)
        s2 = np.zeros(n, dtype=np.float32)
        t1 = np.zeros(n, dtype=np.float32)
        for w in range(len(offs)):
            _erf_sums_joint(v[w], offs[w], du, sc, amp32, s0, s1, s2, t0, t1)
    else:
        for w in range(len(offs)):
            _erf_sums(v[w], offs[w], du, sc, amp32, s0, t0)
    for i in range(n):
        k = (-sign / _ROOT2PI) * amp[i] / s[i]
        f0, r0 = np.float64(s0[i]), np.float64(t0[i])
        if not joint:
            dc[i] = r0 / f0 / k
            continue
        f1, f2, r1 = np.float64(s1[i]), np.float64(s2[i]), np.float64(t1[i])
        kd = k * (f0 * f2 - f1 * f1)
        dc[i] = (f2 * r0 - f1 * r1) / kd
        ds[i] = sign * (f0 * r1 - f1 * r0) / kd


@kernel
def _erf_sums(
    v: NDArray[np.float32],
    off: np.float32,
    du: NDArray[np.float32],
    sc: NDArray[np.float32],
    amp: NDArray[np.float32],
    s0: NDArray[np.float32],
    t0: NDArray[np.float32],
) -> None:
    """One window sample ``v`` (per line, at offset ``off``) added to each line's sums
    of g^2 and g r (:func:`_erf_steps`)."""
    for i in range(len(du)):
        u = (off - du[i]) * sc[i]
        g = _exp32((u * u) * np.float32(-0.5))
        r = v[i] - _ndtr32(u, g) * amp[i]
        s0[i] += g * g
        t0[i] += g * r


@kernel
def _erf_sums_joint(
    v: NDArray[np.float32],
    off: np.float32,
    du: NDArray[np.float32],
    sc: NDArray[np.float32],
    amp: NDArray[np.float32],
    s0: NDArray[np.float32],
    s1: NDArray[np.float32],
    s2: NDArray[np.float32],
    t0: NDArray[np.float32],
    t1: NDArray[np.float32],
) -> None:
    """:func:`_erf_sums` with the joint step's g^2 u, g^2 u^2 and g u r."""
    for i in range(len(du)):
        u = (off - du[i]) * sc[i]
        g = _exp32((u * u) * np.float32(-0.5))
        r = v[i] - _ndtr32(u, g) * amp[i]
        gu = g * u
        s0[i] += g * g
        s1[i] += g * gu
        s2[i] += gu * gu
        t0[i] += g * r
        t1[i] += gu * r


#: :func:`_exp32`'s table: the bits of 2^(i/32), i = 0 .. 31 (rounded to the nearest double,
#: checked in tests/vision/test_edges_kernels.py), less i 2^47, so that adding k 2^47 to
#: entry k mod 32 gives the bits of 2^(k/32) for any integer k in range (the exponent
#: field takes k // 32, the rest cancels).
_EXP2_TABLE = np.array(
    [
        int(h, 16)
        for h in """
    3FF0000000000000 3FF059B0D3158574 3FF0B5586CF9890F 3FF11301D0125B51
    3FF172B83C7D517B 3FF1D4873168B9AA 3FF2387A6E756238 3FF29E9DF51FDEE1
    3FF306FE0A31B715 3FF371A7373AA9CB 3FF3DEA64C123422 3FF44E086061892D
    3FF4BFDAD5362A27 3FF5342B569D4F82 3FF5AB07DD485429 3FF6247EB03A5585
    3FF6A09E667F3BCD 3FF71F75E8EC5F74 3FF7A11473EB0187 3FF82589994CCE13
    3FF8ACE5422AA0DB 3FF93737B0CDC5E5 3FF9C49182A3F090 3FFA5503B23E255D
    3FFAE89F995AD3AD 3FFB7F76F2FB5E47 3FFC199BDD85529C 3FFCB720DCEF9069
    3FFD5818DCFBA487 3FFDFC97337B9B5F 3FFEA4AFA2A490DA 3FFF50765B6E4540
    """.split()
    ],
    dtype=np.uint64,
) - (np.arange(32, dtype=np.uint64) << np.uint64(47))
#: 32 / ln 2; 1.5 2^52, which rounds a double below 2^51 to an integer when added (and
#: leaves that integer in its low bits); ln 2 / 32 to the fourth power over 4!: the
#: Taylor coefficients of exp(r ln 2 / 32) on |r| <= 1/2.
_EXP_SCALE = 32.0 / math.log(2.0)
_EXP_ROUND = 6755399441055744.0
_EXP_C1 = math.log(2.0) / 32.0
_EXP_C2, _EXP_C3, _EXP_C4 = _EXP_C1**2 / 2.0, _EXP_C1**3 / 6.0, _EXP_C1**4 / 24.0


@kernel
def _exp32(x: np.float32) -> np.float32:
    """exp(x) in single precision: the exact value rounded once, but for arguments
    within ~2e-5 ulp of a rounding boundary (within 0.50001 ulp on 650,000 seeded
    arguments, subnormal results included; the C library's expf, which the fit called
    before, is within 0.5016 ulp, and the two differ in the last place on ~6e-4 of
    them: tests/vision/test_edges_kernels.py). 0 below -103.97, inf above 88.7228, NaN for
    NaN. Written out rather than ``np.exp``, a call into the C library that keeps a loop
    scalar: this one inlines into a loop that LLVM vectorises (3.6x the C library's
    throughput on this machine's AVX-512, 6x where results are subnormal).

    In double precision (the method of the C library's own): x = (k + r) ln 2 / 32
    with k the nearest integer and |r| <= 1/2, exp(x) = 2^(k/32) exp(r ln 2 / 32), the
    first factor from a table of 32 and the bits of 2^(k // 32), the second a Taylor
    polynomial of degree 4 (relative error 1.2e-12); one rounding to single precision
    at the end. No branch: the clamp keeps k in range and the NaN test is a select."""
    xd = np.float64(min(max(x, np.float32(-104.0)), np.float32(89.0)))
    z = xd * _EXP_SCALE
    kd = z + _EXP_ROUND  # (no fastmath: not folded away)
    k = np.float64(kd).view(np.uint64)
    r = z - (kd - _EXP_ROUND)
    bits = _EXP2_TABLE[k & np.uint64(31)] + (k << np.uint64(47))
    p = (((_EXP_C4 * r + _EXP_C3) * r + _EXP_C2) * r + _EXP_C1) * r + 1.0
    y = np.float32(p * np.uint64(bits).view(np.float64))
    return y if x == x else x


@kernel
def _exp32_of(x: NDArray[np.float32]) -> NDArray[np.float32]:
    """:func:`_exp32` of an array (the tests' and the numpy reference's)."""
    out = np.empty(x.shape, dtype=np.float32)
    for i in range(x.size):
        out.flat[i] = _exp32(x.flat[i])
    return out


#: Abramowitz & Stegun 7.1.26: erfc(x) = (a1 t + .. + a5 t^5) exp(-x^2), t = 1 / (1 + p x),
#: x >= 0, absolute error below 1.5e-7; in single precision, the coefficients halved
#: (exactly) and p for x = |u| / sqrt(2).
_AS_A = (0.254829592, -0.284496736, 1.421413741, -1.453152027, 1.061405429)
_AS_P32 = np.float32(0.3275911 / math.sqrt(2.0))
_A1, _A2, _A3, _A4, _A5 = (np.float32(a) * np.float32(0.5) for a in _AS_A)


@kernel
def _ndtr32(u: np.float32, g: np.float32) -> np.float32:
    """The normal CDF Phi(u) given ``g = exp(-u^2 / 2)`` (which the fit computes anyway),
    to 3e-7 in single precision: a polynomial instead of an erf. In a residual that is
    6e-5 DN on a 200 DN edge, against 2-10 DN of noise.

    The coefficients are halved: the polynomial's value is exactly half (every partial
    value is far from underflow where g > 0), so the product with g is Phi(-|u|) to the
    bit wherever it is not a subnormal, and those vanish from 1/2 - Phi(-|u|)."""
    t = np.float32(1.0) / (abs(u) * _AS_P32 + np.float32(1.0))
    p = t * _A5
    p = (p + _A4) * t
    p = (p + _A3) * t
    p = (p + _A2) * t
    p = (p + _A1) * t
    p = np.float32(0.5) - p * g  # 1/2 - Phi(-|u|) = |Phi(u) - 1/2|
    return np.float32(math.copysign(p, u)) + np.float32(0.5)


@kernel
def _ndtr_from_weight(u: NDArray[np.float32], g: NDArray[np.float32]) -> NDArray[np.float32]:
    """:func:`_ndtr32` of arrays."""
    out = np.empty(u.shape, dtype=np.float32)
    for i in range(u.size):
        out.flat[i] = _ndtr32(u.flat[i], g.flat[i])
    return out
