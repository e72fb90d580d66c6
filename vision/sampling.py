"""Image sampling: bilinear interpolation at sub-pixel points (with a reusable plan) and a fast
median, shared by the measurement steps. The edge estimators are in :mod:`vision.edges`."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from vision.errors import ParameterError


def median(x: NDArray[np.float64], overwrite_input: bool = False) -> float:
    """``np.median`` of a 1-D array (NaN if it holds one) by partition, without the
    generic machinery that makes ``np.median`` several times slower on the small arrays
    a frame's measurement takes many medians of. ``overwrite_input``: partition ``x``
    itself (a float64 array the caller no longer needs) instead of a copy."""
    a = np.asarray(x, dtype=np.float64).ravel()
    n = a.size
    if n == 0:
        return math.nan
    top = a.max()  # NaN if a value is: one reduction, not a mask
    if top != top:
        return math.nan
    k = n // 2
    # the ndarray method: np.partition's wrapper costs more than the work
    part = a if overwrite_input else a.copy()
    if n % 2:
        part.partition(k)
        return float(part[k])
    part.partition((k - 1, k))
    return float(0.5 * (part[k - 1] + part[k]))


def unit_step_gradient(x: NDArray[np.float64]) -> NDArray[np.float64]:
    """``np.gradient(x, axis=0)`` for samples one apart (``len(x) >= 2``): central
    differences, one-sided at the ends, without its generic overhead (called on short
    arrays in every frame)."""
    g = np.empty_like(x)
    g[1:-1] = (x[2:] - x[:-2]) / 2.0
    g[0], g[-1] = x[1] - x[0], x[-1] - x[-2]
    return g


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
