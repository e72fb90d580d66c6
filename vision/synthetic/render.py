"""Scene renderer: the bench as a camera sees it (the synthetic camera and the tests).

The scene (:class:`~vision.synthetic.scene.SceneSpec`, :class:`BeamPose`, the truth) is
described in :mod:`vision.synthetic.scene`; this module rasterises it. Everything drawn
lies in the beam plane: a dark background with optional clutter, the registration plate
(light, with two orthogonal dark grooves crossing in a square), the hub (a wider bright
bar coaxial with the clamped beam end, extending back past the pivot) and the beam (a
bright strip of the beam's width along its deflected centre line, ending square at the
tip). Each pixel is traced back to the plane through the lens distortion and the
plane-to-image homography; pixels near edges are supersampled (``supersample`` x
``supersample`` samples through the local Jacobian of the pixel-to-plane map). Static
parts are drawn once per :class:`SceneSpec` (:func:`static_layers`); a frame redraws only
a band around the hub and beam. Motion blur averages the coverage of several poses over
the exposure (:meth:`BeamMotion.exposure_poses
<vision.synthetic.scene.BeamMotion.exposure_poses>` samples a moving beam's); only pixels
near a pose's edges are supersampled, so an exposure of a hundred poses stays cheap.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from vision.camera import undistort_points_px
from vision.errors import BehindCameraError, ParameterError
from vision.homography import apply_homography
from vision.synthetic.scene import BeamPose, Clutter, RenderedFrame, RenderTruth, SceneSpec

__all__ = ["render_frame", "static_layers"]


def _pixel_maps(spec: SceneSpec) -> tuple[NDArray[Any], ...]:
    """Plane coordinates of every pixel centre and the pixel-to-plane Jacobian."""
    w, h = spec.camera.width_px, spec.camera.height_px
    k, d = spec.camera_matrix, spec.distortion
    plane_from_ideal = np.linalg.inv(spec.ideal_from_plane)
    uu, vv = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    pts = np.column_stack([uu.ravel(), vv.ravel()])
    if np.any(d):
        # Exact (iterative) undistortion on a 4-px grid, cubic interpolation between:
        # the distortion field is smooth, the interpolation error is ~1e-4 px.
        from scipy.ndimage import map_coordinates

        g = 4
        gu, gv = np.meshgrid(
            np.arange(-3 * g, w + 3 * g, g, dtype=float),
            np.arange(-3 * g, h + 3 * g, g, dtype=float),
        )
        coarse = undistort_points_px(np.column_stack([gu.ravel(), gv.ravel()]), k, d)
        where = np.vstack([vv.ravel() / g + 3, uu.ravel() / g + 3])
        ideal = np.column_stack(
            [
                map_coordinates(coarse[:, i].reshape(gu.shape), where, order=3, mode="nearest")
                for i in (0, 1)
            ]
        )
    else:
        ideal = pts
    plane = apply_homography(plane_from_ideal, ideal)
    x = plane[:, 0].reshape(h, w)
    y = plane[:, 1].reshape(h, w)
    jx_u = np.asarray(np.gradient(x, axis=1), dtype=np.float32)
    jx_v = np.asarray(np.gradient(x, axis=0), dtype=np.float32)
    jy_u = np.asarray(np.gradient(y, axis=1), dtype=np.float32)
    jy_v = np.asarray(np.gradient(y, axis=0), dtype=np.float32)
    return x, y, jx_u, jx_v, jy_u, jy_v


def _offsets(n: int) -> NDArray[np.float64]:
    """n*n sample offsets (px) in a pixel: an n-rooks pattern (every sample on its own row
    and column), so edges along the pixel grid see n*n coverage levels, not n."""
    m = n * n
    k = np.arange(m)
    step = next(s for s in range(max(2, int(np.sqrt(m))), m) if np.gcd(s, m) == 1)
    return np.column_stack([(k + 0.5) / m - 0.5, ((k * step) % m + 0.5) / m - 0.5])


def _sub_plane_deltas(
    maps: dict[str, Any], rows: NDArray[np.intp], cols: NDArray[np.intp], offs: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Plane offsets (P, M) of the M supersample positions of P pixels from their centres."""
    du, dv = offs[:, 0][None, :], offs[:, 1][None, :]
    dx = maps["jx_u"][rows, cols][:, None] * du + maps["jx_v"][rows, cols][:, None] * dv
    dy = maps["jy_u"][rows, cols][:, None] * du + maps["jy_v"][rows, cols][:, None] * dv
    return dx.astype(np.float64), dy.astype(np.float64)


def _rect_halfplanes(
    center: Sequence[float], length: float, width: float, angle: float
) -> list[tuple[float, float, float]]:
    """Half-planes (nx, ny, c) with inside where nx*x + ny*y - c <= 0."""
    c, s = math.cos(angle), math.sin(angle)
    cx, cy = center
    out = []
    for nx, ny, half in ((c, s, length / 2), (-c, -s, length / 2), (-s, c, width / 2)):
        out.append((nx, ny, nx * cx + ny * cy + half))
    out.append((s, -c, s * cx - c * cy + width / 2))
    return out


def _draw_convex(
    refl: NDArray[np.float32],
    maps: dict[str, Any],
    spec: SceneSpec,
    planes: list[tuple[float, float, float]],
    corners_m: NDArray[np.float64],
    level: float,
) -> None:
    """Paint a convex plane polygon into ``refl`` with supersampled edges."""
    h, w = refl.shape
    try:
        px = spec.to_px(corners_m)
    except BehindCameraError:
        return
    x0, y0 = np.floor(px.min(axis=0)).astype(int) - 3
    x1, y1 = np.ceil(px.max(axis=0)).astype(int) + 4
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
    if x0 >= x1 or y0 >= y1:
        return
    xs = maps["x"][y0:y1, x0:x1]
    ys = maps["y"][y0:y1, x0:x1]
    sd = np.full(xs.shape, -np.inf)
    for nx, ny, c in planes:
        sd = np.maximum(sd, nx * xs + ny * ys - c)
    fp = maps["footprint_m"]
    region = refl[y0:y1, x0:x1]
    region[sd < -fp] = level
    edge_r, edge_c = np.nonzero(np.abs(sd) <= fp)
    if edge_r.size == 0:
        return
    rows, cols = edge_r + y0, edge_c + x0
    dx, dy = _sub_plane_deltas(maps, rows, cols, maps["offsets"])
    px_x = maps["x"][rows, cols][:, None] + dx
    px_y = maps["y"][rows, cols][:, None] + dy
    inside = np.ones(px_x.shape, dtype=bool)
    for nx, ny, c in planes:
        inside &= nx * px_x + ny * px_y - c <= 0
    cov = inside.mean(axis=1)
    region[edge_r, edge_c] = region[edge_r, edge_c] * (1 - cov) + level * cov


def static_layers(spec: SceneSpec) -> dict[str, Any]:
    """What a scene draws once, built on first use and kept on the spec: pixel maps,
    reflectance, lighting gain, the noise field and ``"lit"``, the float32 [row, col]
    picture of the scene without hub, beam and noise."""
    with spec._cache_lock:  # frames may render in several threads
        if not spec._cache:
            spec._cache.update(_build_static(spec))
    return spec._cache


def _build_static(spec: SceneSpec) -> dict[str, Any]:
    x, y, jxu, jxv, jyu, jyv = _pixel_maps(spec)
    det = np.abs(jxu.astype(np.float64) * jyv - jxv.astype(np.float64) * jyu)
    maps: dict[str, Any] = {"x": x, "y": y, "jx_u": jxu, "jx_v": jxv, "jy_u": jyu, "jy_v": jyv}
    # Largest pixel footprint (m): pixels within it of an edge get supersampled.
    maps["footprint_m"] = float(np.sqrt(np.max(jxu.astype(float) ** 2 + jxv**2 + jyu**2 + jyv**2)))
    maps["median_footprint_m"] = float(np.sqrt(np.median(det)))
    maps["offsets"] = _offsets(spec.supersample)
    h, w = x.shape
    refl = np.full((h, w), spec.background_dn, dtype=np.float32)
    for cl in spec.clutter:
        planes = _rect_halfplanes(cl.center_m, cl.size_m[0], cl.size_m[1], cl.angle_rad)
        _draw_convex(refl, maps, spec, planes, _rect_corners(cl), cl.level_dn)
    if spec.draw_registration:
        reg = spec.registration
        side, sq = reg.plate_side_m, reg.square_side_m
        plate = Clutter(tuple(reg.center_m), (side, side), reg.angle_rad, spec.plate_dn)  # type: ignore[arg-type]
        for item in (
            plate,
            Clutter(tuple(reg.center_m), (side, sq), reg.angle_rad, spec.groove_dn),  # type: ignore[arg-type]
            Clutter(tuple(reg.center_m), (side, sq), reg.angle_rad + math.pi / 2, spec.groove_dn),  # type: ignore[arg-type]
        ):
            planes = _rect_halfplanes(item.center_m, item.size_m[0], item.size_m[1], item.angle_rad)
            _draw_convex(refl, maps, spec, planes, _rect_corners(item), item.level_dn)
    # Illumination: a linear gradient and a quadratic vignette.
    uu, vv = np.meshgrid(np.linspace(-1, 1, w), np.linspace(-1, 1, h))
    ca, sa = math.cos(spec.lighting_azimuth_rad), math.sin(spec.lighting_azimuth_rad)
    gain = 1.0 + 0.5 * spec.lighting_gradient * (ca * uu + sa * vv)
    gain *= 1.0 - spec.vignetting * (uu**2 + vv**2) / 2.0
    gain = gain.astype(np.float32)
    lit = _blur(refl * gain, spec.blur_sigma_px)
    rng = np.random.default_rng(spec.seed)
    pad = 64
    noise = (rng.standard_normal((h + pad, w + pad), dtype=np.float32) * spec.noise_dn).astype(
        np.float32
    )
    return {"maps": maps, "refl": refl, "gain": gain, "lit": lit, "noise": noise, "pad": pad}


def _rect_corners(cl: Clutter) -> NDArray[np.float64]:
    c, s = math.cos(cl.angle_rad), math.sin(cl.angle_rad)
    a, b = cl.size_m[0] / 2, cl.size_m[1] / 2
    local = np.array([[-a, -b], [a, -b], [a, b], [-a, b]])
    return local @ np.array([[c, s], [-s, c]]) + np.asarray(cl.center_m)


def _blur(img: NDArray[Any], sigma: float) -> NDArray[np.float32]:
    img = np.asarray(img, dtype=np.float32)
    if sigma <= 0:
        return img.copy()
    k = 2 * math.ceil(3 * sigma) + 1
    out = cv2.GaussianBlur(img, (k, k), sigma, borderType=cv2.BORDER_REFLECT)
    return np.asarray(out, dtype=np.float32)


# ---------------------------------------------------------------------------------------
class _Shape:
    """A pose resampled densely for fast per-pixel evaluation (hub frame, metres)."""

    def __init__(self, spec: SceneSpec, pose: BeamPose, n: int = 800) -> None:
        self.length = spec.beam_length_m
        s = np.linspace(0.0, self.length, n)
        lat, lon = pose.at(s)
        self.s = s
        self.a = spec.hub_offset_m + s + lon
        self.b = lat
        ta = np.gradient(self.a, s)
        tb = np.gradient(self.b, s)
        norm = np.hypot(ta, tb)
        self.ta, self.tb = ta / norm, tb / norm
        th = pose.hub_angle_rad
        self.e = np.array([math.cos(th), math.sin(th)])
        self.n = np.array([-math.sin(th), math.cos(th)])
        self.pose = pose

    def plane_points(self, a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
        return a[:, None] * self.e + b[:, None] * self.n

    def foot(
        self, pa: NDArray[np.float64], pb: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], ...]:
        """Station of the nearest centre-line point, signed normal distance, and the unit
        tangent and normal there, for hub-frame points (pa, pb)."""
        s = np.interp(pa, self.a, self.s, left=-np.inf, right=np.inf)
        s = np.where(np.isfinite(s), s, np.where(pa < self.a[0], pa - self.a[0], self.length))
        for _ in range(2):
            sc = np.clip(s, 0.0, self.length)
            ta = np.interp(sc, self.s, self.ta)
            tb = np.interp(sc, self.s, self.tb)
            ca = np.interp(sc, self.s, self.a) + (s - sc) * ta
            cb = np.interp(sc, self.s, self.b) + (s - sc) * tb
            s = s + (pa - ca) * ta + (pb - cb) * tb
        sc = np.clip(s, 0.0, self.length)
        ta = np.interp(sc, self.s, self.ta)
        tb = np.interp(sc, self.s, self.tb)
        ca = np.interp(sc, self.s, self.a) + (s - sc) * ta
        cb = np.interp(sc, self.s, self.b) + (s - sc) * tb
        d = (pa - ca) * (-tb) + (pb - cb) * ta
        return s, d, ta, tb


def _band_mask(spec: SceneSpec, shapes: list[_Shape], margin_m: float) -> NDArray[np.uint8]:
    h, w = spec.camera.height_px, spec.camera.width_px
    mask = np.zeros((h, w), np.uint8)
    hw = spec.beam_width_m / 2 + margin_m
    for sh in shapes:
        idx = np.linspace(0, len(sh.s) - 1, 120).astype(int)
        a = np.concatenate([sh.a[idx], [sh.a[-1] + margin_m * 1.5]])
        b = np.concatenate([sh.b[idx], [sh.b[-1]]])
        na = np.concatenate([-sh.tb[idx], [-sh.tb[-1]]])
        nb = np.concatenate([sh.ta[idx], [sh.ta[-1]]])
        left = sh.plane_points(a + hw * na, b + hw * nb)
        right = sh.plane_points(a - hw * na, b - hw * nb)
        poly_m = np.vstack([left, right[::-1]])
        hub_a0 = spec.hub_offset_m - spec.hub_length_m - margin_m
        hub_a1 = spec.hub_offset_m + margin_m
        hub_b = spec.hub_width_m / 2 + margin_m
        hub_m = sh.plane_points(
            np.array([hub_a0, hub_a1, hub_a1, hub_a0]), np.array([-hub_b, -hub_b, hub_b, hub_b])
        )
        for poly in (poly_m, hub_m):
            try:
                px = spec.to_px(poly)
            except BehindCameraError:
                continue
            px = np.clip(px, -4 * w, 5 * w)
            cv2.fillPoly(mask, [np.round(px * 16).astype(np.int32)], 1, cv2.LINE_8, 4)
    return mask


def render_frame(
    spec: SceneSpec, poses: Sequence[BeamPose], *, rng: np.random.Generator | None = None
) -> RenderedFrame:
    """Draw one frame.

    Parameters
    ----------
    spec : the static scene.
    poses : beam poses sampled evenly over the exposure (one pose: no motion blur).
    rng : picks this frame's noise (default: seeded from ``spec.seed``).

    Returns
    -------
    RenderedFrame with ``image`` uint8 [row, col] (height_px x width_px) and ``truth``.
    """
    if len(poses) == 0:
        raise ParameterError("poses", "must hold at least one BeamPose")
    for i, p in enumerate(poses):
        if not isinstance(p, BeamPose):
            raise TypeError(f"poses[{i}] must be a BeamPose, got {type(p).__name__}")
    st = static_layers(spec)
    maps = st["maps"]
    rng = np.random.default_rng(spec.seed + 1) if rng is None else rng
    shapes = [_Shape(spec, p) for p in poses]
    margin = 4.0 * maps["footprint_m"] + 2.0 * spec.blur_sigma_px * maps["footprint_m"]
    mask = _band_mask(spec, shapes, margin)
    ys, xs = np.nonzero(mask)
    out = st["lit"].copy()
    if ys.size:
        _draw_dynamic(spec, st, shapes, out, ys, xs)
    h, w = out.shape
    pad = st["pad"]
    r0, c0 = rng.integers(0, pad, size=2)
    out += st["noise"][r0 : r0 + h, c0 : c0 + w]
    image = np.clip(np.rint(out), 0, 255).astype(np.uint8)
    return RenderedFrame(image, _truth(spec, poses, shapes))


def _draw_dynamic(
    spec: SceneSpec,
    st: dict[str, Any],
    shapes: list[_Shape],
    out: NDArray[np.float32],
    ys: NDArray[np.intp],
    xs: NDArray[np.intp],
) -> None:
    maps = st["maps"]
    offs = maps["offsets"]
    px = maps["x"][ys, xs]
    py = maps["y"][ys, xs]
    dx, dy = _sub_plane_deltas(maps, ys, xs, offs)
    cov_hub = np.zeros(len(ys))
    cov_beam = np.zeros(len(ys))
    half_w = spec.beam_width_m / 2
    hub_a0, hub_a1 = spec.hub_offset_m - spec.hub_length_m, spec.hub_offset_m
    hub_hw = spec.hub_width_m / 2
    # A supersample lies within |offset| <= 0.5 px of its pixel's centre along both image
    # axes, so within ``fp`` (the largest pixel footprint) of it in the plane: a pixel
    # whose centre is farther than ``fp`` from every edge of a shape is wholly in or out
    # of it, and only the others are supersampled (the same coverage, a fraction of the
    # work when many poses sample an exposure).
    fp = maps["footprint_m"]
    for sh in shapes:
        e, n = sh.e, sh.n
        pa = px * e[0] + py * e[1]
        pb = px * n[0] + py * n[1]
        # The hub (a rectangle in the hub frame).
        out_h = np.maximum(
            np.maximum(pa - hub_a1, hub_a0 - pa), np.abs(pb) - hub_hw
        )  # > 0 outside, < 0 inside (distance to the nearest side, or less)
        in_hub_c = out_h < -fp
        near_h = np.flatnonzero(np.abs(out_h) <= fp)
        in_hub = in_hub_c.astype(np.float64)
        if near_h.size:
            da = dx[near_h] * e[0] + dy[near_h] * e[1]
            db = dx[near_h] * n[0] + dy[near_h] * n[1]
            a_sub = pa[near_h, None] + da
            b_sub = pb[near_h, None] + db
            sub = (a_sub <= hub_a1) & (a_sub >= hub_a0) & (np.abs(b_sub) <= hub_hw)
            in_hub[near_h] = sub.mean(axis=1)
        # The beam: pixels within reach of this pose's strip (the centre line's b at
        # the pixel's a, with room for the slope), then their foot on the centre line.
        bb = np.interp(pa, sh.a, sh.b)
        slack = (half_w + 2 * fp) * 1.5 + 2 * fp
        cand = np.flatnonzero(
            (np.abs(pb - bb) <= slack) & (pa >= sh.a[0] - 0.004 - fp) & (pa <= sh.a[-1] + slack)
        )
        in_beam = np.zeros(len(ys))
        if cand.size:
            s, d, ta, tb = sh.foot(pa[cand], pb[cand])
            inside_c = (np.abs(d) < half_w - fp) & (s < sh.length - fp) & (s > -0.002 + fp)
            edge = ~inside_c & (np.abs(d) <= half_w + fp) & (s <= sh.length + fp)
            edge &= s >= -0.002 - fp
            in_beam[cand[inside_c]] = 1.0
            ke = np.flatnonzero(edge)
            if ke.size:
                rows = cand[ke]
                da = dx[rows] * e[0] + dy[rows] * e[1]
                db = dx[rows] * n[0] + dy[rows] * n[1]
                s_sub = s[ke, None] + da * ta[ke, None] + db * tb[ke, None]
                d_sub = d[ke, None] - da * tb[ke, None] + db * ta[ke, None]
                sub = (np.abs(d_sub) <= half_w) & (s_sub <= sh.length) & (s_sub >= -0.002)
                # Minus the hub, subsample by subsample where the hub's edge is near.
                if near_h.size:
                    hub_near = np.isin(rows, near_h)
                    if hub_near.any():
                        r2 = rows[hub_near]
                        a2 = pa[r2, None] + dx[r2] * e[0] + dy[r2] * e[1]
                        b2 = pb[r2, None] + dx[r2] * n[0] + dy[r2] * n[1]
                        sub[hub_near] &= ~((a2 <= hub_a1) & (a2 >= hub_a0) & (np.abs(b2) <= hub_hw))
                in_beam[rows] = sub.mean(axis=1)
            in_beam[in_hub_c] = 0.0
            # Wholly-in beam pixels beside the hub's edge: the hub takes its share.
            whole = cand[inside_c]
            in_beam[whole] = np.minimum(in_beam[whole], 1.0 - in_hub[whole])
        cov_hub += in_hub
        cov_beam += in_beam
    cov_hub /= len(shapes)
    cov_beam /= len(shapes)
    y0, y1 = int(ys.min()), int(ys.max()) + 1
    x0, x1 = int(xs.min()), int(xs.max()) + 1
    pad = math.ceil(3 * spec.blur_sigma_px) + 2
    y0, x0 = max(y0 - pad, 0), max(x0 - pad, 0)
    y1, x1 = min(y1 + pad, out.shape[0]), min(x1 + pad, out.shape[1])
    refl = st["refl"][y0:y1, x0:x1].copy()
    ry, rx = ys - y0, xs - x0
    base = refl[ry, rx]
    refl[ry, rx] = base * (1 - cov_hub - cov_beam) + spec.hub_dn * cov_hub + spec.beam_dn * cov_beam
    lit = _blur(refl * st["gain"][y0:y1, x0:x1], spec.blur_sigma_px)
    # Only the band changed; keep the pre-blurred static picture elsewhere.
    changed = np.zeros(refl.shape, np.uint8)
    changed[ry, rx] = 1
    k = 2 * pad + 1
    changed = cv2.dilate(changed, np.ones((k, k), np.uint8))
    region = out[y0:y1, x0:x1]
    np.copyto(region, lit, where=changed.astype(bool))


def _truth(spec: SceneSpec, poses: Sequence[BeamPose], shapes: list[_Shape]) -> RenderTruth:
    st_m = np.asarray(spec.stations_m, dtype=np.float64)
    lat_st = np.mean([p.at(st_m)[0] for p in poses], axis=0)
    tips = [p.at(np.array([spec.beam_length_m])) for p in poses]
    tip_lat = float(np.mean([t[0][0] for t in tips]))
    tip_lon = float(np.mean([t[1][0] for t in tips]))
    th = float(np.mean([p.hub_angle_rad for p in poses]))
    sh = shapes[len(shapes) // 2]
    clamp = sh.plane_points(np.array([spec.hub_offset_m]), np.array([0.0]))[0]
    tip = sh.plane_points(sh.a[-1:], sh.b[-1:])[0]
    plane_pts = spec.registration_points_m()
    return RenderTruth(
        hub_angle_rad=th,
        tip_lateral_m=tip_lat,
        tip_longitudinal_m=tip_lon,
        stations_m=st_m,
        lateral_at_stations_m=lat_st,
        corners_px=spec.to_px(plane_pts),
        plane_points_m=plane_pts,
        camera_matrix=spec.camera_matrix,
        distortion=spec.distortion,
        clamp_plane_m=clamp,
        tip_plane_m=tip,
    )
