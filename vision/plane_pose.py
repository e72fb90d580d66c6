"""The registration plane's mapping fitted to its straight edges, with its covariance.

The registration object's eight straight edges are lines of the plane; their images are
``H^T l`` for the plane-from-image homography ``H``. :func:`fit_lines` fits ``H`` to the
edge points either freely (8 degrees of freedom, any collineation) or, when the camera's
intrinsics ``K`` are known, as the pose of a plane seen by a pinhole camera (6 degrees of
freedom, ``H^-1 ~ K [r1 r2 t]``: a rotation and a translation). A plate a third of the
beam's reach across fixes a free homography's perspective terms poorly, and a fraction of
a pixel of error there grows to tenths of a millimetre at the beam's tip, 0.8 m away; the
pose leaves those terms to the physics of the camera, which the plate then pins.

A wrong ``K`` must not bias silently: the pose fit is a free fit with two constraints (a
square seen through ``K``: equal axes, at right angles), so with the right ``K`` its
residual sum of squares exceeds the free fit's by a chi-squared with 2 degrees of
freedom times the points' variance. :func:`fit_lines` takes the pose only when that test
accepts it (:data:`CONSISTENCY_P`), and says why not otherwise.

The fitted mapping's covariance, ``sigma^2 (J^T J)^-1`` from the residuals' Jacobian,
widened for the residuals' correlation along each edge, is returned for the nine
elements of ``H`` (normalised to ``H[2, 2] = 1``), which is what
:mod:`vision.calibration_error` carries to the pivot, the beam and each frame.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from vision.homography import apply_homography

#: The pose fit's extra residual must be at least this likely under the right intrinsics.
CONSISTENCY_P = 1e-3
#: Residual correlation along an edge above this is capped (the inflation would explode).
_MAX_RHO = 0.9
#: Standard deviation (px) of a bias of the edge locator common to every edge point (an
#: image translation of the whole plate, which no residual shows) when the edges run
#: along the pixel grid: the locator's error follows an edge's phase on the grid, and an
#: edge that crosses no phase keeps it whole. Measured on the rendered plates of ``bench
#: vision``'s nominal, blur and short-hub scenes (square to the grid), whose detected
#: corners sit 0.014-0.029 px from the truth on average along one image axis; an edge
#: that crosses ``c`` pixel phases keeps about ``1 / (pi c)`` of it
#: (:func:`_common_bias_px`; 0.002-0.016 px on 12 scenes turned 1-8 deg to the grid).
COMMON_BIAS_PX = 0.03


@dataclass(frozen=True)
class PlaneFit:
    """A plane-from-image mapping fitted to edge points.

    Attributes
    ----------
    matrix : (3, 3) plane-from-ideal-pixel homography, ``matrix[2, 2] = 1``.
    covariance : (9, 9) covariance of ``matrix.ravel()`` (zero on the last element).
    model : ``"pose"`` (6 degrees of freedom, known intrinsics) or ``"homography"`` (8).
    sigma_px : residual standard deviation of one edge point, px.
    inflation : variance factor for the residuals' correlation along the edges (>= 1).
    rss_px2 : residual sum of squares, px^2; ``n_points``: the points fitted.
    note : why the pose was not taken (empty when it was, or was not tried).
    focal_length_px : the pose's focal length (K's), or NaN for a free homography.
    edge_sd_px : standard deviation of each edge's own systematic offset (and tilt), px.
    """

    matrix: NDArray[np.float64]
    covariance: NDArray[np.float64]
    model: str
    sigma_px: float
    inflation: float
    rss_px2: float
    n_points: int
    note: str = ""
    focal_length_px: float = math.nan
    edge_sd_px: float = 0.0


def line_distances_px(
    plane_from_ideal: NDArray[np.float64],
    points_px: NDArray[np.float64],
    line_index: NDArray[np.intp],
    plane_lines: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Signed image distances (N,), px, of ideal-pixel points ``points_px`` (N, 2) from the
    images of the plane lines ``plane_lines[line_index]`` ((J, 3), ``a X + b Y + c = 0``)
    under the plane-from-ideal homography (3, 3)."""
    li = plane_lines @ plane_from_ideal  # (J, 3) image lines
    li = li / np.linalg.norm(li[:, :2], axis=1, keepdims=True)
    sel = li[line_index]
    return np.asarray(sel[:, 0] * points_px[:, 0] + sel[:, 1] * points_px[:, 1] + sel[:, 2])


def normalised(h: NDArray[np.float64]) -> NDArray[np.float64]:
    """``h`` (3, 3) scaled to ``h[2, 2] = 1``."""
    return np.asarray(h / h[2, 2], dtype=np.float64)


def pose_homography(params: NDArray[np.float64], k: NDArray[np.float64]) -> NDArray[np.float64]:
    """Plane-from-ideal homography (normalised) of the pose ``params`` = (rotation vector
    (3), translation (3), plane units) seen through the camera matrix ``k``."""
    r, _ = cv2.Rodrigues(np.asarray(params[:3], dtype=np.float64))
    g = k @ np.column_stack([r[:, 0], r[:, 1], params[3:6]])
    return normalised(np.asarray(np.linalg.inv(g), dtype=np.float64))


def pose_from_homography(
    plane_from_ideal: NDArray[np.float64], k: NDArray[np.float64]
) -> NDArray[np.float64]:
    """The pose (rotation vector, translation) nearest a homography, for a start."""
    m = np.linalg.inv(k) @ np.linalg.inv(plane_from_ideal)
    lam = 2.0 / (np.linalg.norm(m[:, 0]) + np.linalg.norm(m[:, 1]))
    if m[2, 2] * lam < 0:  # the plane in front of the camera
        lam = -lam
    r1, r2 = lam * m[:, 0], lam * m[:, 1]
    u, _, vt = np.linalg.svd(np.column_stack([r1, r2, np.cross(r1, r2)]))
    r = u @ vt
    if np.linalg.det(r) < 0:
        r = u @ np.diag([1.0, 1.0, -1.0]) @ vt
    rvec, _ = cv2.Rodrigues(r)
    return np.concatenate([rvec.ravel(), lam * m[:, 2]])


def jacobian(
    fn: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    x: NDArray[np.float64],
    steps: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Central-difference Jacobian of ``fn`` (vector valued) at ``x``."""
    cols = []
    for i, h in enumerate(steps):
        dx = np.zeros_like(x)
        dx[i] = h
        cols.append((np.ravel(fn(x + dx)) - np.ravel(fn(x - dx))) / (2.0 * h))
    return np.column_stack(cols)


def _steps(x: NDArray[np.float64], floor: float) -> NDArray[np.float64]:
    return np.asarray(1e-6 * np.maximum(np.abs(x), floor), dtype=np.float64)


def _correlation_inflation(r: NDArray[np.float64], line_index: NDArray[np.intp]) -> float:
    """Variance factor (1 + rho) / (1 - rho) for residuals correlated ``rho`` from one
    point to the next along an edge (an edge's points are one per scan line, and blur
    and JPEG blocks reach over several): the information of N correlated points is that
    of N (1 - rho) / (1 + rho) independent ones."""
    num = den = 0.0
    for j in np.unique(line_index):
        rj = r[line_index == j]
        rj = rj - rj.mean()
        num += float(rj[1:] @ rj[:-1])
        den += float(rj @ rj)
    rho = min(max(num / den, 0.0), _MAX_RHO) if den > 0 else 0.0
    return (1.0 + rho) / (1.0 - rho)


def _line_basis(
    points_px: NDArray[np.float64],
    line_index: NDArray[np.intp],
    plane_lines: NDArray[np.float64],
    plane_from_ideal: NDArray[np.float64],
) -> NDArray[np.float64]:
    """(N, 2 J + 2): each edge's own offset and tilt (a unit-RMS ramp along it) as
    patterns of its points' residuals, then an image translation of all of them (x, y)."""
    local = apply_homography(plane_from_ideal, points_px)
    along = np.where(np.abs(plane_lines[line_index, 0]) > 0.5, local[:, 1], local[:, 0])
    out = np.zeros((len(points_px), 2 * len(plane_lines) + 2))
    normals = plane_lines @ plane_from_ideal
    normals = normals[:, :2] / np.linalg.norm(normals[:, :2], axis=1, keepdims=True)
    out[:, -2:] = normals[line_index]
    for j in range(len(plane_lines)):
        sel = line_index == j
        if not sel.any():
            continue
        t = along[sel] - along[sel].mean()
        rms = float(np.sqrt(np.mean(t * t)))
        out[sel, 2 * j] = 1.0
        out[sel, 2 * j + 1] = t / rms if rms > 0 else 0.0
    return out


def _common_bias_px(points_px: NDArray[np.float64], line_index: NDArray[np.intp]) -> float:
    """The standard deviation (px) of the edge locator's bias common to all edges: each
    edge keeps ``min(1, 1 / (pi c))`` of :data:`COMMON_BIAS_PX`, ``c`` being the pixel
    phases it crosses (its extent across its scan lines), averaged over the edges."""
    kept = []
    for j in np.unique(line_index):
        p = points_px[line_index == j]
        cycles = float(np.min(np.ptp(p, axis=0)))
        kept.append(min(1.0, 1.0 / (math.pi * cycles)) if cycles > 0 else 1.0)
    return COMMON_BIAS_PX * float(np.mean(kept))


def _edge_variance(
    r: NDArray[np.float64], basis: NDArray[np.float64], point_var: float, n_params: int
) -> float:
    """Variance (px^2) of each edge's own offset and tilt beyond the points' noise: the
    systematic part of an edge's position (its locator's bias with the edge's blur,
    lighting and angle to the pixel grid), common to all its points. From the free fit's
    residuals' projection on the edges' patterns, of which the fit took ``n_params``."""
    edges = basis[:, :-2]  # the translation is a homography's: no residual shows it
    counts = edges[:, 0::2].sum(axis=0)
    coef, *_ = np.linalg.lstsq(edges, r, rcond=None)
    dof = edges.shape[1] - n_params
    if dof <= 0:
        return 0.0
    noise = point_var * float(np.mean(1.0 / np.maximum(counts, 1.0)))
    return max(float(coef @ coef) / dof - noise, 0.0)


@dataclass(frozen=True)
class _Cov:
    params: NDArray[np.float64]  # of the fit's parameters
    matrix: NDArray[np.float64]  # (9, 9) of the mapping's elements
    sigma_px: float
    inflation: float
    rss_px2: float


def _covariance(
    residuals: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    to_matrix: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    x: NDArray[np.float64],
    steps: NDArray[np.float64],
    line_index: NDArray[np.intp],
    basis: NDArray[np.float64],
    edge_var: float | None = None,
    common_px: float = 0.0,
) -> tuple[_Cov, float]:
    """The least-squares fit's covariance: the points' noise (widened for its
    correlation along the edges), each edge's own systematic offset and tilt (variance
    ``edge_var``, px^2; estimated here when None) and a bias common to all
    (standard deviation ``common_px``, :func:`_common_bias_px`), through the sandwich
    ``(J^T J)^-1 J^T V J (J^T J)^-1``. Returns it and ``edge_var``."""
    r = residuals(x)
    j = jacobian(residuals, x, steps)
    scale = np.linalg.norm(j, axis=0)
    scale[scale == 0] = 1.0
    js = j / scale
    n, p = j.shape
    rss = float(r @ r)
    sigma2 = rss / max(n - p, 1)
    inflation = _correlation_inflation(r, line_index)
    if edge_var is None:
        edge_var = _edge_variance(r, basis, sigma2 * inflation, p)
    bread = np.linalg.pinv(js.T @ js)
    jb = js.T @ basis[:, :-2]
    jt = js.T @ basis[:, -2:]
    meat = sigma2 * inflation * (js.T @ js) + edge_var * (jb @ jb.T)
    meat = meat + common_px**2 * (jt @ jt.T)
    cov_p = bread @ meat @ bread / np.outer(scale, scale)
    jh = jacobian(lambda v: normalised(to_matrix(v)), x, steps)
    return _Cov(cov_p, jh @ cov_p @ jh.T, math.sqrt(sigma2), inflation, rss), edge_var


def fit_lines(
    points_px: NDArray[np.float64],
    line_index: NDArray[np.intp],
    plane_lines: NDArray[np.float64],
    free: NDArray[np.float64],
    camera_matrix: NDArray[np.float64] | None,
    plane_from_local: NDArray[np.float64] | None = None,
) -> PlaneFit:
    """The plane's mapping from edge points on known plane lines, and its covariance.

    Parameters
    ----------
    points_px : (N, 2) ideal (undistorted) pixel points (x, y), outliers removed.
    line_index : (N,) the plane line each point lies on.
    plane_lines : (J, 3) lines ``a X + b Y + c = 0`` of the object's own plane frame, m.
    free : (3, 3) the free (8-DOF) maximum-likelihood fit, object-plane from ideal pixels.
    camera_matrix : (3, 3) intrinsics, or None (the free fit is kept).
    plane_from_local : (3, 3) similarity from the object's frame to the beam plane's;
        ``matrix`` and ``covariance`` are in the beam plane's (identity if None).

    Returns
    -------
    PlaneFit: the pose when ``camera_matrix`` is given and consistent with the points
    (:data:`CONSISTENCY_P`), else the free homography with a ``note`` saying why.
    """
    a = np.eye(3) if plane_from_local is None else np.asarray(plane_from_local, np.float64)
    pts = np.asarray(points_px, dtype=np.float64)
    idx = np.asarray(line_index, dtype=np.intp)
    lines = np.asarray(plane_lines, dtype=np.float64)
    h_free = normalised(np.asarray(free, dtype=np.float64))

    def res_free(v: NDArray[np.float64]) -> NDArray[np.float64]:
        return line_distances_px(np.append(v, 1.0).reshape(3, 3), pts, idx, lines)

    x_free = h_free.ravel()[:8]
    basis = _line_basis(pts, idx, lines, h_free)
    common = _common_bias_px(pts, idx)
    free_cov, edge_var = _covariance(
        res_free,
        lambda v: a @ np.append(v, 1.0).reshape(3, 3),
        x_free,
        _steps(x_free, 1e-12),
        idx,
        basis,
        common_px=common,
    )
    free_fit = PlaneFit(
        normalised(a @ h_free),
        free_cov.matrix,
        "homography",
        free_cov.sigma_px,
        free_cov.inflation,
        free_cov.rss_px2,
        len(pts),
        edge_sd_px=math.sqrt(edge_var),
    )
    if camera_matrix is None:
        return free_fit
    k = np.asarray(camera_matrix, dtype=np.float64)

    def res_pose(v: NDArray[np.float64]) -> NDArray[np.float64]:
        return line_distances_px(pose_homography(v, k), pts, idx, lines)

    # imported here: a frame worker loads vision but never fits a pose (scipy.optimize
    # and scipy.stats were ~0.7 s of its start-up)
    from scipy.optimize import least_squares

    x0 = pose_from_homography(h_free, k)
    sol = least_squares(res_pose, x0, method="lm", x_scale="jac")
    x = sol.x
    steps = np.concatenate([np.full(3, 1e-7), _steps(x[3:], 1e-3)])
    pose_cov, _ = _covariance(
        res_pose, lambda v: a @ pose_homography(v, k), x, steps, idx, basis, edge_var, common
    )
    # Nested models: the pose is the free fit with 2 constraints. Its mapping, written
    # in the free fit's parameters, must lie within the free fit's own uncertainty
    # (the points' noise and the edges' systematic offsets): a Mahalanobis distance,
    # chi-squared with 2 degrees of freedom at most (the free fit's covariance bounds
    # that of the difference).
    diff = pose_homography(x, k).ravel()[:8] - x_free
    excess = float(diff @ np.linalg.pinv(free_cov.params) @ diff)
    limit = -2.0 * math.log(CONSISTENCY_P)  # chi-squared, 2 dof: sf(x) = exp(-x / 2)
    if not excess <= limit:
        note = (
            f"the registration's edges do not fit a plane seen through the stated camera "
            f"matrix (focal length {k[0, 0]:.0f} px): the pose differs from the free "
            f"homography by {math.sqrt(excess):.1f} standard deviations (chi-squared "
            f"{excess:.1f}, 2 dof, limit {limit:.1f}); the free homography is used"
        )
        return dataclasses.replace(free_fit, note=note)
    return PlaneFit(
        normalised(a @ pose_homography(x, k)),
        pose_cov.matrix,
        "pose",
        pose_cov.sigma_px,
        pose_cov.inflation,
        pose_cov.rss_px2,
        len(pts),
        focal_length_px=float(k[0, 0]),
        edge_sd_px=math.sqrt(edge_var),
    )
