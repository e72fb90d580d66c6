"""The hub in a frame (the default method's hub steps): its axis and its end faces.

The hub is the wider bright bar the beam is clamped in. A rough axis through the located
hub (:func:`rough_axis`) places the searches; a long hub's axis is fitted to points on its
two long edges as two parallel lines (:func:`hub_axis`), and the measurement then fits
the axis with the beam's clamped shape (:func:`vision.centreline.fit_clamped_joint`), so a
short clamp block is enough. Its end faces, the clamp
(where the shoulders beside the beam end) and the back, are bright-to-dark edges along the
axis found by 1-D edge moments of profiles sampled along it (:func:`end_edge`, which also
finds the beam's tip face). Points are beam-plane (x, y) in metres; ``to_px`` maps them to
raw image pixels (:meth:`vision.calibration.Calibration.to_px`) and ``px_m`` is the plane
size of a pixel, which sets the sampling step.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from vision.centreline import correlation_inflation, lag1_sums, linspace
from vision.errors import FrameFailure
from vision.jit import kernel
from vision.locate import Rough, ToPx
from vision.sampling import bilinear_points, median_in_place, numpy_sum


def rough_axis(rough: Rough) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """Unit direction (back to clamp), normal and offset along the normal of the line
    through the hub's rough profile centres and the rough clamp (least squares)."""
    hub = rough.hub if len(rough.hub) else rough.hub_back[None, :]
    cx, cy, ux, uy = _major_axis(
        np.ascontiguousarray(hub, dtype=np.float64), float(rough.clamp[0]), float(rough.clamp[1])
    )
    e = np.array([ux, uy])
    if not e @ (rough.clamp - rough.hub_back) > 0:
        e = -e
    n = np.array([-e[1], e[0]])
    return e, n, cx * float(n[0]) + cy * float(n[1])


@kernel
def _major_axis(
    hub: NDArray[np.float64], px: float, py: float
) -> tuple[float, float, float, float]:
    """Centroid and unit major axis (either sense) of the points ``hub`` (N, 2) and
    (px, py): the principal direction of their scatter, in closed form."""
    m = hub.shape[0] + 1
    cx, cy = 0.0, 0.0
    for i in range(hub.shape[0]):
        cx += hub[i, 0]
        cy += hub[i, 1]
    cx, cy = (cx + px) / m, (cy + py) / m
    sxx, syy, sxy = 0.0, 0.0, 0.0
    for i in range(m):
        dx = (hub[i, 0] if i < m - 1 else px) - cx
        dy = (hub[i, 1] if i < m - 1 else py) - cy
        sxx += dx * dx
        syy += dy * dy
        sxy += dx * dy
    th = 0.5 * math.atan2(2.0 * sxy, sxx - syy)
    return cx, cy, math.cos(th), math.sin(th)


def hub_axis(
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
    status, c, s, ba, bb, res_ss, spread, along_a, along_b = _hub_axis(
        np.ascontiguousarray(pa, dtype=np.float64),
        np.ascontiguousarray(pb, dtype=np.float64),
        float(back[0]),
        float(back[1]),
        float((front - back) @ e),
        float(e[0]),
        float(e[1]),
        margin,
    )
    if status == 1:
        raise FrameFailure("hub edges not visible")
    if status == 2:
        raise FrameFailure("hub edges not straight")
    e = np.array([c, s])
    n = np.array([-s, c])
    ra, rb = along_a[1], along_b[1]
    dof = max(len(ra) + len(rb) - 3, 1)
    infl = max(correlation_inflation(ra), correlation_inflation(rb))
    sd = math.sqrt(res_ss / dof / max(spread, 1e-18) * infl)
    # Two checks on the direction from the points it kept. (1) Its last robust pass
    # dropped points after the direction was fitted: the kept points' own common
    # slope across it, ``turn``, is what one more fit would turn it by (0 where that
    # pass dropped none). A bar lying against part of an edge tilts the first fits
    # toward its step and then is dropped: the turn is that tilt. (2) The edges of one
    # bar are parallel: each edge's own direction agrees with the other's within their
    # noise unless one is no straight line (a step kept in the fit); Birge's ratio of
    # their disagreement to its noise, where above 1, scales the sd.
    chi2, turn = _axis_checks(along_a, along_b)
    sd = math.hypot(sd * max(1.0, math.sqrt(chi2)), turn)
    return e, n, 0.5 * (ba + bb), abs(ba - bb), sd


@kernel
def _axis_checks(along_a: NDArray[np.float64], along_b: NDArray[np.float64]) -> tuple[float, float]:
    """:func:`hub_axis`'s checks on its direction from each edge's positions along it
    and residuals across it (:func:`_along`): the chi-squared of the two edges' own
    directions' difference (their slopes of residual on position; each one's variance
    from its scatter about its own line, inflated for lag-1 correlation as
    :func:`vision.centreline.correlation_inflation`), and the kept points' common
    slope (the turn one more fit would make)."""
    tilt, var = np.zeros(2), np.zeros(2)
    s_ur, s_uu = 0.0, 0.0
    for k in range(2):
        al = along_a if k == 0 else along_b
        u, r = al[0], al[1]
        n = u.shape[0]
        suu, sur = 0.0, 0.0
        for i in range(n):
            suu += u[i] * u[i]
            sur += u[i] * r[i]
        suu = max(suu, 1e-18)
        t = sur / suu
        ss, lag = lag1_sums(r - t * u, n)
        infl = 1.0
        if n >= 4 and ss > 0:
            rho = min(max(lag / ss, 0.0), 0.9)
            infl = (1.0 + rho) / (1.0 - rho)
        tilt[k] = t
        var[k] = ss / max(n - 2, 1) / suu * infl
        s_ur += sur
        s_uu += suu
    chi2 = (tilt[0] - tilt[1]) ** 2 / max(var[0] + var[1], 1e-300)
    return chi2, s_ur / s_uu


@kernel
def _hub_axis(
    pa: NDArray[np.float64],
    pb: NDArray[np.float64],
    back_x: float,
    back_y: float,
    length: float,
    ex: float,
    ey: float,
    margin: float,
) -> tuple[int, float, float, float, float, float, float, NDArray[np.float64], NDArray]:
    """:func:`hub_axis` up to the residuals' correlation: a status (0, or 1: too few
    points clear of the ends, 2: too few kept), the direction (c, s), the two edges'
    offsets along the normal, the residuals' sum of squares, the points' spread along
    the direction, and each edge's positions along it and residuals across it about
    its mean, ordered along it (:func:`_along`)."""
    xa, ya = _clear(pa, back_x, back_y, length, ex, ey, margin)
    xb, yb = _clear(pb, back_x, back_y, length, ex, ey, margin)
    empty = np.empty((2, 0))
    if xa.size < 5 or xb.size < 5:
        return 1, ex, ey, 0.0, 0.0, 0.0, 0.0, empty, empty
    # Two robust passes: the common direction of both edges (the major axis of their
    # scatter about their own centroids, in closed form), then drop points beyond
    # four robust sigmas across it.
    c, s = ex, ey
    for _ in range(2):
        na, nb = xa.size, xb.size
        mxa, mya, mxb, myb = _mean(xa), _mean(ya), _mean(xb), _mean(yb)
        sxx, syy, sxy = 0.0, 0.0, 0.0
        for i in range(na):
            dx, dy = xa[i] - mxa, ya[i] - mya
            sxx += dx * dx
            syy += dy * dy
            sxy += dx * dy
        for i in range(nb):
            dx, dy = xb[i] - mxb, yb[i] - myb
            sxx += dx * dx
            syy += dy * dy
            sxy += dx * dy
        th = 0.5 * math.atan2(2.0 * sxy, sxx - syy)
        c0, s0 = math.cos(th), math.sin(th)
        # The major axis's sense: along the rough axis (within a few degrees of it).
        if not c0 * c + s0 * s > 0:
            c0, s0 = -c0, -s0
        c, s = c0, s0
        r = np.empty(na + nb)
        for i in range(na):
            r[i] = abs((ya[i] - mya) * c - (xa[i] - mxa) * s)
        for i in range(nb):
            r[na + i] = abs((yb[i] - myb) * c - (xb[i] - mxb) * s)
        sig = 1.4826 * median_in_place(r.copy()) + 1e-9
        xa, ya = _kept(xa, ya, r[:na], 4 * sig)
        xb, yb = _kept(xb, yb, r[na:], 4 * sig)
        if xa.size < 3 or xb.size < 3:
            return 2, c, s, 0.0, 0.0, 0.0, 0.0, empty, empty
    mxa, mya, mxb, myb = _mean(xa), _mean(ya), _mean(xb), _mean(yb)
    ba, bb = mxa * -s + mya * c, mxb * -s + myb * c
    # Direction uncertainty of the common-direction fit: residual / spread along it.
    res_ss, spread = 0.0, 0.0
    for x, y, mx, my in ((xa, ya, mxa, mya), (xb, yb, mxb, myb)):
        for i in range(x.size):
            dx, dy = x[i] - mx, y[i] - my
            res = dx * -s + dy * c
            u = dx * c + dy * s
            res_ss += res * res
            spread += u * u
    return 0, c, s, ba, bb, res_ss, spread, _along(xa, ya, c, s), _along(xb, yb, c, s)


@kernel
def _clear(
    p: NDArray[np.float64],
    back_x: float,
    back_y: float,
    length: float,
    ex: float,
    ey: float,
    margin: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """x and y of the points ``p`` (N, 2) more than ``margin`` clear of both ends."""
    x, y = np.empty(p.shape[0]), np.empty(p.shape[0])
    m = 0
    for i in range(p.shape[0]):
        a = (p[i, 0] - back_x) * ex + (p[i, 1] - back_y) * ey
        if a > margin and a < length - margin:
            x[m], y[m] = p[i, 0], p[i, 1]
            m += 1
    return x[:m], y[:m]


@kernel
def _kept(
    x: NDArray[np.float64], y: NDArray[np.float64], r: NDArray[np.float64], limit: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The points whose ``r`` is below ``limit``."""
    m = 0
    kx, ky = np.empty(x.size), np.empty(x.size)
    for i in range(x.size):
        if r[i] < limit:
            kx[m], ky[m] = x[i], y[i]
            m += 1
    return kx[:m], ky[:m]


@kernel
def _mean(x: NDArray[np.float64]) -> float:
    s = 0.0
    for i in range(x.size):
        s += x[i]
    return s / x.size


@kernel
def _along(x: NDArray[np.float64], y: NDArray[np.float64], c: float, s: float) -> NDArray:
    """Positions along a straight edge (points x, y; direction c, s) and residuals across
    it, both about its mean, ordered along it (a stable insertion sort: the points come
    nearly in order): (2, N)."""
    mx, my = _mean(x), _mean(y)
    n = x.size
    u, r = np.empty(n), np.empty(n)
    for i in range(n):
        dx, dy = x[i] - mx, y[i] - my
        ui, ri = dx * c + dy * s, dx * -s + dy * c
        j = i
        while j > 0 and u[j - 1] > ui:
            u[j], r[j] = u[j - 1], r[j - 1]
            j -= 1
        u[j], r[j] = ui, ri
    out = np.empty((2, n))
    out[0], out[1] = u, r
    return out


def clamp_face(
    image: NDArray[np.uint8],
    origin: NDArray[np.float64],
    e: NDArray[np.float64],
    n: NDArray[np.float64],
    hub_w: float,
    w_beam: float,
    *,
    to_px: ToPx,
    px_m: float,
) -> float:
    """Position along the axis (from ``origin``) where the hub's shoulders end."""
    inner, outer = w_beam / 2, hub_w / 2
    if outer - inner < 3 * px_m:
        raise FrameFailure("hub not wider than the beam by enough to find the clamp")
    lat = linspace(inner + 0.3 * (outer - inner), outer - 0.3 * (outer - inner), 3)
    lateral = np.concatenate([lat, -lat])
    return end_edge(image, origin, e, n, lateral, 0.0, hub_w, to_px=to_px, px_m=px_m)


def back_face(
    image: NDArray[np.uint8],
    clamp: NDArray[np.float64],
    e: NDArray[np.float64],
    n: NDArray[np.float64],
    hub_w: float,
    guess_a: float,
    *,
    to_px: ToPx,
    px_m: float,
) -> float:
    """Axis coordinate (from the clamp, negative) of the hub's back end face."""
    lat = linspace(-0.6, 0.6, 5) * hub_w / 2
    reach = 0.5 * min(abs(guess_a), 2.0 * hub_w)
    return -end_edge(image, clamp, -e, n, lat, -guess_a, reach, to_px=to_px, px_m=px_m)


def end_edge(
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
    pts = _face_grid(
        np.ascontiguousarray(lateral, dtype=np.float64),
        np.ascontiguousarray(n, dtype=np.float64),
        np.ascontiguousarray(origin, dtype=np.float64),
        t,
        np.ascontiguousarray(e, dtype=np.float64),
    )
    px = np.ascontiguousarray(to_px(pts), dtype=np.float64)
    centre, total = _end_edge(np.ascontiguousarray(image), px, len(lateral), round(3.0 / 0.25))
    if total != total:  # NaN off the image
        raise FrameFailure("clamp or tip outside the image")
    if not math.isfinite(centre) or total < 8.0:
        raise FrameFailure("no clear end edge (clamp or tip)")
    return float(t[0] + centre * step)


@kernel
def _face_grid(
    lateral: NDArray[np.float64],
    n: NDArray[np.float64],
    origin: NDArray[np.float64],
    t: NDArray[np.float64],
    e: NDArray[np.float64],
) -> NDArray[np.float64]:
    """:func:`end_edge`'s sample points (K * M, 2), line by line: ``lateral_k n +
    (origin + t_j e)``, as :func:`~vision.locate._grid` of the numpy arrays
    ``lateral * n`` and ``origin + t * e`` (the same products and sums)."""
    m = t.size
    out = np.empty((lateral.size * m, 2))
    for k in range(lateral.size):
        x, y = lateral[k] * n[0], lateral[k] * n[1]
        for j in range(m):
            out[k * m + j, 0] = x + (origin[0] + t[j] * e[0])
            out[k * m + j, 1] = y + (origin[1] + t[j] * e[1])
    return out


@kernel
def _end_edge(
    image: NDArray[np.uint8], px: NDArray[np.float64], lines: int, half: int
) -> tuple[float, float]:
    """:func:`end_edge` from the raw pixels ``px`` of its ``lines`` profiles (one after
    the other): the first moment (step k at k + 0.5) and the sum of the positive
    steps (bright to dark, from the lines' mean profile) within ``half`` steps of the
    largest; NaN, NaN when a sample is off the image (moment NaN: no positive step)."""
    v = bilinear_points(image, px)
    m = v.size // lines
    prof = np.zeros(m)
    for line in range(lines):
        for j in range(m):
            x = v[line * m + j]
            if x != x:
                return math.nan, math.nan
            prof[j] += x
    for j in range(m):
        prof[j] /= lines
    peak, top = 0, -math.inf
    for j in range(m - 1):
        d = prof[j] - prof[j + 1]
        if d > top:
            peak, top = j, d
    lo, hi = max(peak - half, 0), min(peak + half, m - 2)
    d, dk = np.empty(hi - lo + 1), np.empty(hi - lo + 1)
    for k in range(lo, hi + 1):
        step = prof[k] - prof[k + 1]
        d[k - lo] = step if step > 0 else 0.0
        dk[k - lo] = d[k - lo] * (k + 0.5)
    total = numpy_sum(d, d.size)  # numpy's sums (pairwise)
    if total <= 0.0:
        return math.nan, total
    return numpy_sum(dk, dk.size) / total, total
