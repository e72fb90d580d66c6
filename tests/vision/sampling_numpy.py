"""The numpy form of vision.sampling's bilinear samples, as it was before its numba
kernel (issue #19): the reference the kernel is tested against. Not used by the
package."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray


def bilinear_numpy(image: NDArray[np.uint8], xy: NDArray[np.float64]) -> NDArray[np.float64]:
    """The numpy form the kernel replaced: flat gathers, NaN off the image."""
    h, w = image.shape
    x, y = xy[..., 0], xy[..., 1]
    ok = (x >= 0) & (y >= 0) & (x <= w - 1) & (y <= h - 1)
    xc, yc = np.where(ok, x, 0.0), np.where(ok, y, 0.0)
    x0 = np.minimum(xc.astype(np.intp), w - 2)
    y0 = np.minimum(yc.astype(np.intp), h - 2)
    i = y0 * w + x0
    flat = image.ravel()
    fx, fy = xc - x0, yc - y0
    v00, v10 = flat[i], flat[i + w]
    top = v00 + fx * (flat[i + 1] - v00.astype(np.float64))
    bottom = v10 + fx * (flat[i + w + 1] - v10.astype(np.float64))
    return np.where(ok, top + fy * (bottom - top), np.nan)
