"""The numpy forms of vision.hub's hub axis and end-face search, as they were before
their numba kernels (issue #19): the references the kernels are tested against
(tests/vision/test_hub.py). Not used by the package."""

# mypy: ignore-errors
from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from tests.vision.sampling_numpy import bilinear_numpy
from vision.centreline import correlation_inflation
from vision.errors import FrameFailure
from vision.locate import ToPx


def hub_axis_numpy(
    pa: NDArray[np.float64],
    pb: NDArray[np.float64],
    back: NDArray[np.float64],
    front: NDArray[np.float64],
    e: NDArray[np.float64],
    margin: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64], float, float, float]:
    """Hub axis from points (plane, m) on its two long edges (``pa``, ``pb``), those
    ``margin`` clear of ``back`` and ``front`` (the end faces), fitted as parallel lines.
    ``e``: the rough axis direction. Returns the unit direction (back to front) and
    normal, the axis offset along the normal, the width and the standard uncertainty of
    the direction (rad)."""
    length = float((front - back) @ e)
    sa, sb = (pa - back) @ e, (pb - back) @ e
    pa = pa[(sa > margin) & (sa < length - margin)]
    pb = pb[(sb > margin) & (sb < length - margin)]
    if len(pa) < 5 or len(pb) < 5:
        raise FrameFailure("hub edges not visible")
    # Two robust passes: the common direction of both edges (the major axis of their
    # scatter about their own centroids, in closed form), then drop points beyond
    # four robust sigmas across it. x and y apart: (N, 2) arrays are slow to operate on.
    xa, ya, xb, yb = pa[:, 0], pa[:, 1], pb[:, 0], pb[:, 1]
    for _ in range(2):
        na, nb = len(xa), len(xb)  # sum / n: ndarray.mean's wrapper costs more here
        dxa, dya = xa - xa.sum() / na, ya - ya.sum() / na
        dxb, dyb = xb - xb.sum() / nb, yb - yb.sum() / nb
        sxx = float(dxa @ dxa + dxb @ dxb)
        syy = float(dya @ dya + dyb @ dyb)
        sxy = float(dxa @ dya + dxb @ dyb)
        th = 0.5 * math.atan2(2.0 * sxy, sxx - syy)
        c, s = math.cos(th), math.sin(th)
        # The major axis's sense: along the rough axis (within a few degrees of it).
        if not c * float(e[0]) + s * float(e[1]) > 0:
            c, s = -c, -s
        e = np.array([c, s])
        ra, rb = dya * c - dxa * s, dyb * c - dxb * s
        r = np.abs(np.concatenate([ra, rb]))
        sig = 1.4826 * float(np.median(r)) + 1e-9
        keep = r < 4 * sig
        ka, kb = keep[:na], keep[na:]
        if np.count_nonzero(ka) < 3 or np.count_nonzero(kb) < 3:
            raise FrameFailure("hub edges not straight")
        xa, ya, xb, yb = xa[ka], ya[ka], xb[kb], yb[kb]
    n = np.array([-e[1], e[0]])
    pa, pb = np.column_stack([xa, ya]), np.column_stack([xb, yb])
    ca = np.array([xa.sum() / len(xa), ya.sum() / len(ya)])
    cb = np.array([xb.sum() / len(xb), yb.sum() / len(yb)])
    ba, bb = float(ca @ n), float(cb @ n)
    # Direction uncertainty of the common-direction fit: residual / spread along it.
    da, db = pa - ca, pb - cb
    ra, rb = da @ n, db @ n
    res = np.concatenate([ra, rb])
    ua, ub = da @ e, db @ e
    spread = float((ua * ua).sum() + (ub * ub).sum())
    dof = max(len(res) - 3, 1)
    infl = max(correlation_inflation(_along(pa, e, n)), correlation_inflation(_along(pb, e, n)))
    sd = math.sqrt(float((res * res).sum()) / dof / max(spread, 1e-18) * infl)
    # the kept points' own common slope (what one more fit would turn it by) and
    # Birge's ratio of the two edges' own directions' disagreement to its noise
    tilt, var = [], []
    for u, r in ((ua, ra), (ub, rb)):
        t = float(u @ r) / max(float(u @ u), 1e-18)
        rest = (r - t * u)[np.argsort(u, kind="stable")]
        tilt.append(t)
        var.append(
            float(rest @ rest)
            / max(len(r) - 2, 1)
            / max(float(u @ u), 1e-18)
            * correlation_inflation(rest)
        )
    chi2 = (tilt[0] - tilt[1]) ** 2 / max(var[0] + var[1], 1e-300)
    turn = float(ua @ ra + ub @ rb) / max(float(ua @ ua + ub @ ub), 1e-18)
    sd = math.hypot(sd * max(1.0, math.sqrt(chi2)), turn)
    return e, n, 0.5 * (ba + bb), abs(ba - bb), sd


def end_edge_numpy(
    image: NDArray[np.uint8],
    origin: NDArray[np.float64],
    e: NDArray[np.float64],
    n: NDArray[np.float64],
    lateral: NDArray[np.float64],
    guess: float,
    reach: float,
    *,
    to_px: ToPx,
    px_m: float,
) -> float:
    """Bright-to-dark edge along ``e`` near ``guess`` (m from ``origin``, within
    ``reach``) on lines offset by ``lateral`` (m along ``n``): an end face of the hub or
    the beam's tip."""
    step = 0.25 * px_m
    t = np.arange(guess - reach, guess + reach, step)
    pts = np.empty((len(lateral), len(t), 2))
    for c in range(2):  # x and y apart: broadcasting over a last axis of 2 is slow
        np.add(origin[c] + t * e[c], (lateral * n[c])[:, None], out=pts[:, :, c])
    v = bilinear_numpy(image, to_px(pts.reshape(-1, 2))).reshape(len(lateral), len(t))
    if not math.isfinite(float(v.sum())):  # NaN off the image
        raise FrameFailure("clamp or tip outside the image")
    prof = v.mean(axis=0)
    diff = prof[:-1] - prof[1:]  # bright to dark: the fall from each sample to the next
    centre, total = _step_moment(diff, int(np.argmax(diff)), round(3.0 / 0.25))
    if not math.isfinite(centre) or total < 8.0:
        raise FrameFailure("no clear end edge (clamp or tip)")
    return float(t[0] + centre * step)


def _step_moment(diff: NDArray[np.float64], peak: int, half: int) -> tuple[float, float]:
    """First moment (position, step k at k + 0.5) and sum of the positive steps within
    ``half`` of ``peak`` in one profile's steps: :func:`vision.sampling.edge_moment` for
    a single line, without its batch machinery."""
    lo, hi = max(peak - half, 0), min(peak + half, len(diff) - 1)
    d = diff[lo : hi + 1]
    d = np.where(d > 0, d, 0.0)
    total = float(d.sum())
    if total <= 0.0:
        return math.nan, total
    return float((d * (np.arange(lo, hi + 1) + 0.5)).sum()) / total, total


def _along(p: NDArray[np.float64], e: NDArray[np.float64], n: NDArray[np.float64]) -> NDArray:
    """Residuals across a straight edge (N, 2) about its mean, ordered along it."""
    c = p - p.mean(axis=0)
    return (c @ n)[np.argsort(c @ e)]


def rough_axis_numpy(rough):
    """The rough axis by the SVD of the centred points (the form before the kernel)."""
    hub = rough.hub if len(rough.hub) else rough.hub_back[None, :]
    pts = np.vstack([hub, rough.clamp[None, :]])
    c = pts.mean(axis=0)
    _, _, vt = np.linalg.svd(pts - c, full_matrices=False)
    e = vt[0] if vt[0] @ (rough.clamp - rough.hub_back) > 0 else -vt[0]
    n = np.array([-e[1], e[0]])
    return e, n, float(c @ n)
