"""Sub-pixel edges of a bright strip along pixel rows or columns of the raw image.

Working on the raw pixels (no resampling) keeps the edge estimate free of interpolation
bias: each scan line across the strip gives a rising and a falling edge, located by the
first moment of the intensity steps around the strongest step (exact for a box-sampled
or symmetric-blurred step edge). The points are mapped to the plane afterwards.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from vision.sampling import edge_gauss3, edge_moment


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
    d = centre_px[-1] - centre_px[0]
    columns = abs(d[0]) >= abs(d[1])
    img = image if columns else image.T
    pts = centre_px if columns else centre_px[:, ::-1]
    # pts[:, 0] is now the scan-line index axis, pts[:, 1] the position along the line.
    order = np.argsort(pts[:, 0])
    pts = pts[order]
    hw = np.broadcast_to(np.asarray(half_width_px, dtype=np.float64), (len(pts),))[order]
    h, w = img.shape  # rows = along-scan positions, cols = scan-line index
    x0 = int(np.ceil(pts[0, 0]))
    x1 = int(np.floor(pts[-1, 0]))
    lines = np.arange(max(x0, 0), min(x1, w - 1) + 1)
    empty = StripEdges(np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0), np.zeros(0))
    if lines.size < 2:
        return empty
    yc = np.interp(lines, pts[:, 0], pts[:, 1])
    slope = np.gradient(yc, lines) if lines.size > 2 else np.zeros_like(yc)
    half = np.interp(lines, pts[:, 0], hw) * np.sqrt(1.0 + slope**2)
    reach = int(np.ceil(np.max(half))) + margin_px + max_window
    offs = np.arange(-reach, reach + 1)
    rows = np.round(yc).astype(np.intp)[:, None] + offs[None, :]
    inside = (rows.min(axis=1) >= 0) & (rows.max(axis=1) < h)
    if not inside.any():
        return empty
    lines, yc, half, rows = lines[inside], yc[inside], half[inside], rows[inside]
    prof = img[rows, lines[:, None]].astype(np.float64)
    diff = np.diff(prof, axis=1)  # step k sits at offs[k] + 0.5
    base = rows[:, 0].astype(np.float64)
    mid = yc - base  # centre's position in sample units
    pos = np.arange(diff.shape[1]) + 0.5
    exp_a = mid - half
    exp_b = mid + half
    tol = np.maximum(0.35 * half, 2.5)[:, None]
    near_a = np.abs(pos[None, :] - exp_a[:, None]) <= tol
    near_b = np.abs(pos[None, :] - exp_b[:, None]) <= tol
    pa = np.argmax(np.where(near_a, diff, -np.inf), axis=1)
    pb = np.argmax(np.where(near_b, -diff, -np.inf), axis=1)
    # Ramp width (px) = contrast / steepest step: motion blur widens it; the moment
    # window grows with it so a blurred edge is still located at its centre.
    rr = np.arange(len(lines))
    inner = np.abs(np.arange(prof.shape[1])[None, :] - mid[:, None]) < 0.5 * half[:, None]
    level_in = (prof * inner).sum(axis=1) / np.maximum(inner.sum(axis=1), 1)
    outer = np.concatenate([prof[:, :margin_px], prof[:, -margin_px:]], axis=1)
    level_out = np.median(outer, axis=1)
    contrast = np.maximum(level_in - level_out, 1e-6)
    width_a = contrast / np.maximum(diff[rr, pa], 1e-6)
    width_b = contrast / np.maximum(-diff[rr, pb], 1e-6)
    wa = np.clip(np.ceil(0.5 * width_a + 0.5), window, max_window).astype(np.intp)
    wb = np.clip(np.ceil(0.5 * width_b + 0.5), window, max_window).astype(np.intp)
    ca, ka, _ = edge_moment(diff, pa, wa)
    cb, kb, _ = edge_moment(-diff, pb, wb)
    sa, sb = width_a, width_b
    if estimator == "area":
        from scipy.ndimage import median_filter

        k = min(9, 2 * (len(lines) // 2) + 1) if len(lines) > 2 else 1
        lo = median_filter(level_out, size=k, mode="nearest")
        hi = median_filter(level_in, size=k, mode="nearest")
        ea = _area_edge(prof, pa, wa, lo, hi, rising=True)
        eb = _area_edge(prof, pb, wb, lo, hi, rising=False)
        ca = np.where(np.isfinite(ea), ea, ca)
        cb = np.where(np.isfinite(eb), eb, cb)
    if estimator == "erf":
        from scipy.ndimage import median_filter

        k = min(9, 2 * (len(lines) // 2) + 1) if len(lines) > 2 else 1
        lo = median_filter(level_out, size=k, mode="nearest")
        hi = median_filter(level_in, size=k, mode="nearest")
        ea = _area_edge(prof, pa, wa, lo, hi, rising=True)
        eb = _area_edge(prof, pb, wb, lo, hi, rising=False)
        ea = np.where(np.isfinite(ea), ea, ca)
        eb = np.where(np.isfinite(eb), eb, cb)
        ca = erf_edge(prof, ea, lo, hi, 0.4 * width_a, rising=True)
        cb = erf_edge(prof, eb, lo, hi, 0.4 * width_b, rising=False)
    if estimator == "gauss3":
        ga, gb = edge_gauss3(diff, pa), edge_gauss3(-diff, pb)
        ca = np.where(np.isfinite(ga), ga, ca)
        cb = np.where(np.isfinite(gb), gb, cb)
    along_a = base + ca
    along_b = base + cb
    side_a = np.column_stack([lines.astype(np.float64), along_a])
    side_b = np.column_stack([lines.astype(np.float64), along_b])
    if not columns:
        side_a = side_a[:, ::-1]
        side_b = side_b[:, ::-1]
    contrast = np.minimum(ka, kb)
    spread = np.maximum(sa, sb)
    good = np.isfinite(ca) & np.isfinite(cb) & (contrast > 0)
    return StripEdges(side_a[good], side_b[good], contrast[good], spread[good])


def _area_edge(
    prof: NDArray[np.float64],
    peak: NDArray[np.intp],
    half: NDArray[np.intp],
    lo: NDArray[np.float64],
    hi: NDArray[np.float64],
    rising: bool,
) -> NDArray[np.float64]:
    """Edge position (sample units) of the sharp step with the same area between the
    plateau levels ``lo`` and ``hi`` over samples peak-half .. peak+half+1 (exact for any
    blur once the window spans the ramp; less noisy than the moment of the steps)."""
    _n, m = prof.shape
    hmax = int(np.max(half))
    offs = np.arange(-hmax, hmax + 2)
    idx = peak[:, None] + offs[None, :]
    inwin = (offs[None, :] >= -half[:, None]) & (offs[None, :] <= half[:, None] + 1)
    ok = np.all((idx >= 0) & (idx < m) | ~inwin, axis=1)
    idx = np.clip(idx, 0, m - 1)
    v = np.take_along_axis(prof, idx, axis=1)
    frac = np.where(inwin, (v - lo[:, None]) / np.maximum(hi - lo, 1e-6)[:, None], 0.0)
    total = frac.sum(axis=1)
    j0 = (peak - half).astype(np.float64)
    j1 = (peak + half + 1).astype(np.float64)
    e = j1 + 0.5 - total if rising else j0 - 0.5 + total
    return np.where(ok & (hi - lo > 1.0), e, np.nan)


def erf_edge(
    prof: NDArray[np.float64],
    start: NDArray[np.float64],
    lo: NDArray[np.float64],
    hi: NDArray[np.float64],
    sigma0: NDArray[np.float64],
    rising: bool,
) -> NDArray[np.float64]:
    """Least-squares edge position (sample units) of a blurred step
    ``lo + (hi - lo) Phi((j - c) / s)`` fitted to the samples ``j`` near ``start``.

    The step's width ``s`` is fitted per line first, then fixed at its median over the
    lines (one lens, one edge direction) and only ``c`` is refitted: the maximum-
    likelihood position under white noise, which weights each sample by the local slope
    of the edge instead of equally (the area estimator's noise grows with its window)."""
    from scipy.special import ndtr

    _n, m = prof.shape
    sign = 1.0 if rising else -1.0
    amp = np.maximum(hi - lo, 1e-6)
    ok = np.isfinite(start)
    c = np.where(ok, start, 0.0)
    s = np.clip(np.where(np.isfinite(sigma0), sigma0, 0.8), 0.4, 3.0)
    # One window of samples about the start (it is within a sample of the edge).
    offs = np.arange(-4, 5)
    idx = np.round(c).astype(np.intp)[:, None] + offs[None, :]
    valid = (idx >= 0) & (idx < m)
    v = np.take_along_axis(prof, np.clip(idx, 0, m - 1), axis=1) - lo[:, None]
    j = idx.astype(np.float64)
    root2pi = math.sqrt(2 * math.pi)
    for it in range(4):
        u = sign * (j - c[:, None]) / s[:, None]
        phi = np.exp(-0.5 * u * u) / root2pi
        r = np.where(valid, v - amp[:, None] * ndtr(u), 0.0)
        jc = np.where(valid, (-sign / s)[:, None] * amp[:, None] * phi, 0.0)  # d model/d c
        if it < 2:
            js = jc * sign * u  # d model / d s
            a11, a12, a22 = (jc * jc).sum(1), (jc * js).sum(1), (js * js).sum(1)
            b1, b2 = (jc * r).sum(1), (js * r).sum(1)
            det = a11 * a22 - a12 * a12
            with np.errstate(divide="ignore", invalid="ignore"):
                dc = (a22 * b1 - a12 * b2) / det
                ds = (a11 * b2 - a12 * b1) / det
            c = c + np.where(np.isfinite(dc), np.clip(dc, -1.0, 1.0), 0.0)
            s = np.clip(s + np.where(np.isfinite(ds), np.clip(ds, -0.5, 0.5), 0.0), 0.3, 4.0)
            if it == 1 and ok.any():
                s = np.full_like(s, float(np.median(s[ok])))
        else:
            with np.errstate(divide="ignore", invalid="ignore"):
                dc = (jc * r).sum(1) / (jc * jc).sum(1)
            c = c + np.where(np.isfinite(dc), np.clip(dc, -1.0, 1.0), 0.0)
    bad = ~ok | (np.abs(c - start) > 2.0) | (hi - lo <= 1.0)
    return np.where(bad, np.nan, c)
