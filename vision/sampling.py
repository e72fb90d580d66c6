"""Image sampling and 1-D sub-pixel edge location shared by the measurement methods."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from vision.errors import ParameterError


def median(x: NDArray[np.float64]) -> float:
    """``np.median`` of a 1-D array (NaN if it holds one) by partition, without the
    generic machinery that makes ``np.median`` several times slower on the small arrays
    a frame's measurement takes many medians of."""
    a = np.asarray(x, dtype=np.float64).ravel()
    n = a.size
    if n == 0 or np.isnan(a).any():
        return math.nan
    k = n // 2
    if n % 2:
        return float(np.partition(a, k)[k])
    part = np.partition(a, [k - 1, k])
    return float(0.5 * (part[k - 1] + part[k]))


def bilinear(image: NDArray[np.uint8], xy: NDArray[np.float64]) -> NDArray[np.float64]:
    """Bilinear samples of a [row, col] image at points (N, 2) (x, y); NaN off the image."""
    return BilinearPlan.at(image.shape, xy).sample(image)


@dataclass(frozen=True, eq=False)
class BilinearPlan:
    """:func:`bilinear` at fixed points for images of one shape: the four gather indices
    and the weights, made once (points searched in every frame of a camera placement)."""

    shape: tuple[int, ...]
    idx: tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.intp], NDArray[np.intp]]
    fx: NDArray[np.float64]
    fy: NDArray[np.float64]
    ok: NDArray[np.bool_] | None  # None: every point inside

    @classmethod
    def at(cls, shape: tuple[int, ...], xy: NDArray[np.float64]) -> BilinearPlan:
        h, w = shape
        x = xy[..., 0]
        y = xy[..., 1]
        # Four reductions decide the common case (every point inside; NaN fails them
        # too) without the element-wise mask.
        inside = bool(
            x.size and x.min() >= 0 and y.min() >= 0 and x.max() <= w - 1 and y.max() <= h - 1
        )
        if inside:
            xc, yc, ok = x, y, None
        else:
            ok = (x >= 0) & (y >= 0) & (x <= w - 1) & (y <= h - 1)
            xc = np.where(ok, x, 0.0)
            yc = np.where(ok, y, 0.0)
        # Non-negative here, so truncation is the floor.
        x0 = np.minimum(xc.astype(np.intp), w - 2)
        y0 = np.minimum(yc.astype(np.intp), h - 2)
        i = y0 * w + x0  # gathers from the flat image: cheaper than 2-D fancy indexing
        return cls(tuple(shape), (i, i + 1, i + w, i + (w + 1)), xc - x0, yc - y0, ok)

    def sample(self, image: NDArray[np.uint8]) -> NDArray[np.float64]:
        if image.shape != self.shape:
            raise ParameterError(
                "image", f"must have the plan's shape {self.shape}, got {image.shape}"
            )
        flat = image.ravel()
        i00, i01, i10, i11 = self.idx
        fx, fy = self.fx, self.fy
        v00 = flat[i00]
        v10 = flat[i10]
        top = v00 + fx * (flat[i01] - v00.astype(np.float64))
        bottom = v10 + fx * (flat[i11] - v10.astype(np.float64))
        v = top + fy * (bottom - top)
        return np.asarray(v) if self.ok is None else np.where(self.ok, v, np.nan)


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
