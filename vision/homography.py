"""Plane-to-plane projective collineations (homographies).

``collineation_4pt`` is the paper's construction (seed 000, Eqs. 42-46): four point
pairs, homogeneous coordinates with the scale coordinate first, ``t11 = 1`` and the
four scale factors ``rho_i`` solved together with the eight other elements of [T].
``dlt_homography`` is the normalized least-squares DLT for four or more pairs.
Both return a 3x3 matrix ``H`` acting on ``(x, y, 1)`` column vectors:
``dst ~ H @ src``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from itertools import combinations

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from vision.camera import as_points
from vision.errors import DegeneratePointsError, ParameterError
from vision.jit import kernel

#: Below this relative triangle area three points count as collinear.
COLLINEAR_TOLERANCE = 1e-3
#: Above this condition number a homography is refused as badly conditioned.
MAX_CONDITION = 1e7


@dataclass(frozen=True)
class HomographyFit:
    """A fitted homography and how well the points determined it.

    ``condition`` is the ratio of the largest to the smallest significant singular
    value of the (normalized) design matrix: large means ill-determined.
    ``rms_residual`` is the RMS transfer error of the fit in destination units
    (zero for an exact 4-point collineation).
    """

    matrix: NDArray[np.float64]
    condition: float
    rms_residual: float


def check_general_position(points: NDArray[np.float64], name: str) -> None:
    """Refuse point sets with duplicate points or (for four points) three nearly
    collinear points; for more points, refuse when all are nearly collinear."""
    n = len(points)
    if n < 4:
        raise DegeneratePointsError(name, f"needs at least 4 points, got {n}")
    span = float(np.max(np.linalg.norm(points[:, None, :] - points[None, :, :], axis=-1)))
    if span == 0.0:
        raise DegeneratePointsError(name, "all points coincide")
    for i, j in combinations(range(n), 2):
        if np.linalg.norm(points[i] - points[j]) < 1e-9 * span:
            raise DegeneratePointsError(name, f"points {i} and {j} coincide")
    if n == 4:
        for i, j, k in combinations(range(4), 3):
            a, b, c = points[i], points[j], points[k]
            area = abs((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])) / 2
            if area < COLLINEAR_TOLERANCE * span**2:
                raise DegeneratePointsError(name, f"points {i}, {j}, {k} are nearly collinear")
    else:
        centred = points - points.mean(axis=0)
        sv = np.linalg.svd(centred, compute_uv=False)
        if sv[1] < COLLINEAR_TOLERANCE * sv[0]:
            raise DegeneratePointsError(name, "all points are nearly collinear")


def _validated(src: ArrayLike, dst: ArrayLike) -> tuple[NDArray[np.float64], ...]:
    s = as_points(src, "src")
    d = as_points(dst, "dst")
    if s.shape != d.shape:
        raise ParameterError(
            "src and dst", f"must have the same shape, got {s.shape} and {d.shape}"
        )
    check_general_position(s, "src")
    check_general_position(d, "dst")
    return s, d


def collineation_4pt(src: ArrayLike, dst: ArrayLike) -> HomographyFit:
    """The exact collineation through four point pairs, solved as in Eq. 46.

    Parameters
    ----------
    src, dst : (4, 2) points (x, y); no three collinear in either set.

    Returns
    -------
    HomographyFit with ``matrix`` H (3, 3), ``dst ~ H (x, y, 1)``.
    """
    s, d = _validated(src, dst)
    if len(s) != 4:
        raise ParameterError("src and dst", f"must be exactly 4 point pairs, got {len(s)}")
    # Paper order: homogeneous scale first, w = (w0 : w1 : w2) = (1 : x : y).
    w = np.column_stack([np.ones(4), s])
    big_w = np.column_stack([np.ones(4), d])
    # Unknowns: t12 t13 t21 t22 t23 t31 t32 t33 rho1..rho4 (t11 = 1).
    a = np.zeros((12, 12))
    b = np.zeros(12)
    t_index = {(0, 1): 0, (0, 2): 1, (1, 0): 2, (1, 1): 3, (1, 2): 4, (2, 0): 5, (2, 1): 6}
    t_index[(2, 2)] = 7
    for i in range(4):
        for r in range(3):
            row = 3 * i + r
            for c in range(3):
                if (r, c) == (0, 0):
                    b[row] -= w[i, 0]
                else:
                    a[row, t_index[(r, c)]] = w[i, c]
            a[row, 8 + i] = -big_w[i, r]
    if not np.isfinite(np.linalg.cond(a)) or np.linalg.matrix_rank(a) < 12:
        raise DegeneratePointsError(None, "the collineation equations (Eq. 46) are singular")
    sol = np.linalg.solve(a, b)
    t = np.empty((3, 3))
    t[0, 0] = 1.0
    for (r, c), k in t_index.items():
        t[r, c] = sol[k]
    # (x, y, 1) -> (1, x, y) permutation: H = P^-1 T P.
    p = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    h = p.T @ t @ p
    h = h / h[2, 2] if abs(h[2, 2]) > 1e-300 else h
    return HomographyFit(h, _design(s, d)[1], _rms(h, s, d))


def _normalizer(p: NDArray[np.float64]) -> NDArray[np.float64]:
    c = p.mean(axis=0)
    scale = np.sqrt(2.0) / np.mean(np.linalg.norm(p - c, axis=1))
    return np.array([[scale, 0, -scale * c[0]], [0, scale, -scale * c[1]], [0, 0, 1.0]])


def dlt_homography(src: ArrayLike, dst: ArrayLike) -> HomographyFit:
    """Normalized DLT (Hartley) homography through four or more point pairs.

    Parameters
    ----------
    src, dst : (N, 2) points (x, y), N >= 4.
    """
    s, d = _validated(src, dst)
    (ts, td, vt), cond = _design(s, d)
    hn = vt[-1].reshape(3, 3)
    h = np.linalg.inv(td) @ hn @ ts
    h = h / h[2, 2] if abs(h[2, 2]) > 1e-300 else h / np.linalg.norm(h)
    return HomographyFit(h, cond, _rms(h, s, d))


def _design(
    s: NDArray[np.float64], d: NDArray[np.float64]
) -> tuple[tuple[NDArray[np.float64], ...], float]:
    """Normalizing transforms, right singular vectors and condition of the DLT system."""
    ts, td = _normalizer(s), _normalizer(d)
    sn = apply_homography(ts, s)
    dn = apply_homography(td, d)
    n = len(s)
    a = np.zeros((2 * n, 9))
    x, y = sn[:, 0], sn[:, 1]
    u, v = dn[:, 0], dn[:, 1]
    a[0::2, 0:3] = np.column_stack([x, y, np.ones(n)])
    a[0::2, 6:9] = -u[:, None] * np.column_stack([x, y, np.ones(n)])
    a[1::2, 3:6] = np.column_stack([x, y, np.ones(n)])
    a[1::2, 6:9] = -v[:, None] * np.column_stack([x, y, np.ones(n)])
    _, sv, vt = np.linalg.svd(a)
    cond = float(sv[0] / sv[7]) if sv[7] > 0 else float("inf")
    return (ts, td, vt), cond


def apply_homography(matrix: ArrayLike, points: ArrayLike) -> NDArray[np.float64]:
    """Map ``(N, 2)`` points through a 3x3 homography; points sent to infinity give NaN."""
    h = np.asarray(matrix, dtype=np.float64)
    p = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 2)
    if len(p) == 0 or h.shape != (3, 3):
        return _apply_numpy(h, p)
    # OpenCV's loop in double precision: a sixth of the time of the numpy expression
    # (the measurement maps points a dozen times per frame), equal to it within
    # rounding. OpenCV sends points with |w| <= FLT_EPSILON (or NaN) to (0, 0); those
    # (and any true (0, 0)) are recomputed here so the result is the formula's.
    out = np.asarray(cv2.perspectiveTransform(p.reshape(-1, 1, 2), h), np.float64).reshape(-1, 2)
    if not out.all():  # one pass; a coordinate exactly 0.0 is rare
        zero = (out[:, 0] == 0.0) & (out[:, 1] == 0.0)
        if zero.any():
            out[zero] = _apply_numpy(h, p[zero])
    return out


def map_points(matrix: NDArray[np.float64], points: ArrayLike) -> NDArray[np.float64]:
    """:func:`apply_homography` of a float64 (3, 3) ``matrix`` by the formula in a kernel
    (:func:`_map_k`: the numpy form's operations, so its values exactly): the
    measurement's mappings, a dozen small batches a frame, where OpenCV's call and
    its check for points sent to (0, 0) cost several times the arithmetic."""
    p = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 2)
    return _map_k(np.ascontiguousarray(matrix, dtype=np.float64), p)


@kernel
def _map_k(h: NDArray[np.float64], p: NDArray[np.float64]) -> NDArray[np.float64]:
    """:func:`_apply_numpy` point by point (NaN where ``|w| < 1e-300``)."""
    out = np.empty((p.shape[0], 2))
    for i in range(p.shape[0]):
        x, y = p[i, 0], p[i, 1]
        w = x * h[2, 0] + y * h[2, 1] + h[2, 2]
        if abs(w) < 1e-300:
            out[i, 0] = out[i, 1] = np.nan
        else:
            out[i, 0] = (x * h[0, 0] + y * h[0, 1] + h[0, 2]) / w
            out[i, 1] = (x * h[1, 0] + y * h[1, 1] + h[1, 2]) / w
    return out


def _apply_numpy(h: NDArray[np.float64], p: NDArray[np.float64]) -> NDArray[np.float64]:
    """:func:`apply_homography` by the formula; points with w = 0 give NaN."""
    x, y = p[:, 0], p[:, 1]
    w = x * h[2, 0] + y * h[2, 1] + h[2, 2]
    out = np.empty_like(p)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        out[:, 0] = (x * h[0, 0] + y * h[0, 1] + h[0, 2]) / w
        out[:, 1] = (x * h[1, 0] + y * h[1, 1] + h[1, 2]) / w
    out[np.abs(w) < 1e-300] = np.nan
    return out


def _rms(h: NDArray[np.float64], s: NDArray[np.float64], d: NDArray[np.float64]) -> float:
    r = apply_homography(h, s) - d
    return float(np.sqrt(np.mean(np.sum(r * r, axis=1))))


@dataclass(frozen=True)
class LineHomographyFit:
    """A homography fitted to points on the images of known plane lines.

    ``matrix``: (3, 3) plane-from-image ``H`` (``X ~ H (x, y, 1)``); ``residuals_px``:
    per line, the signed image distance (px) of each point from the fitted line's image;
    ``inliers``: per line, the points kept; ``rms_px``: RMS distance of the inliers.
    """

    matrix: NDArray[np.float64]
    residuals_px: list[NDArray[np.float64]]
    inliers: list[NDArray[np.bool_]]
    rms_px: float


def homography_from_lines(
    points_px: list[NDArray[np.float64]],
    plane_lines: NDArray[np.float64],
    initial: NDArray[np.float64],
    reject: float = 4.0,
    min_sigma_px: float = 0.05,
) -> LineHomographyFit:
    """Maximum-likelihood homography from image points known to lie on plane lines.

    Each plane line ``l = (a, b, c)`` (``a X + b Y + c = 0``, plane units) appears in the
    image as the line ``H^T l``; the fit minimises the squared image distances of the
    points ``points_px[j]`` ((N_j, 2), px) from the image of line ``j`` over the eight
    degrees of freedom of ``H``, starting from ``initial`` (plane from image). Using every
    edge point, not the few corners the lines cross at, is what pins the perspective
    terms that decide the plane's scale and rotation far from the object. Points farther
    than ``reject`` robust sigmas (at least ``min_sigma_px``: a noise-free image's
    aliasing is not an outlier) from their line are dropped and the fit repeated.
    """
    from scipy.optimize import least_squares

    if len(points_px) != len(plane_lines):
        raise ParameterError("points_px and plane_lines", "must have one entry per line")
    allp = np.vstack(points_px)
    tn = _normalizer(allp)
    lines = np.asarray(plane_lines, dtype=np.float64)
    # Work with normalized image coordinates: H_n = H T^-1.
    tn_inv = np.linalg.inv(tn)
    h_n = np.asarray(initial, dtype=np.float64) @ tn_inv
    h_n = h_n / np.linalg.norm(h_n)
    idx = np.concatenate([np.full(len(p), j) for j, p in enumerate(points_px)])
    pn = np.column_stack([apply_homography(tn, allp), np.ones(len(allp))])
    scale = 1.0 / tn[0, 0]  # normalized units -> px
    keep = np.ones(len(allp), dtype=bool)

    def distances(h: NDArray[np.float64], sel: NDArray[np.bool_]) -> NDArray[np.float64]:
        hm = h.reshape(3, 3)
        li = lines @ hm  # (J, 3) image lines, normalized coordinates
        li = li / np.linalg.norm(li[:, :2], axis=1, keepdims=True)
        return np.asarray(np.sum(li[idx[sel]] * pn[sel], axis=1) * scale)

    x = h_n.ravel()
    # Gross outliers (clutter over an edge) go before the first fit: the initial
    # homography is good to a fraction of a pixel.
    r = distances(x, keep)
    sig = max(1.4826 * float(np.median(np.abs(r))), min_sigma_px)
    keep = np.abs(r) < reject * sig
    for _ in range(2):
        sel = keep.copy()
        sol = least_squares(
            lambda v, s=sel: np.append(distances(v, s), 1e3 * (v @ v - 1.0)), x, method="lm"
        )
        x = sol.x / np.linalg.norm(sol.x)
        r = distances(x, np.ones(len(allp), dtype=bool))
        sig = max(1.4826 * float(np.median(np.abs(r[keep]))), min_sigma_px)
        keep = np.abs(r) < reject * sig
    h = x.reshape(3, 3) @ tn
    h = h / h[2, 2] if abs(h[2, 2]) > 1e-300 else h
    splits = np.cumsum([len(p) for p in points_px])[:-1]
    rms = float(np.sqrt(np.mean(r[keep] ** 2))) if keep.any() else math.inf
    return LineHomographyFit(h, np.split(r, splits), np.split(keep, splits), rms)
