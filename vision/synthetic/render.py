"""Scene renderer: the bench as a camera sees it (the synthetic camera and the tests).

Everything drawn lies in the beam plane: a dark background with optional clutter, the
registration plate (light, with two orthogonal dark grooves crossing in a square), the hub
(a wider bright bar coaxial with the clamped beam end, extending back past the pivot) and
the beam (a bright strip of the beam's width along its deflected centre line, ending
square at the tip). Each pixel is traced back to the plane through the lens distortion and
the plane-to-image homography; pixels near edges are supersampled (``supersample`` x
``supersample`` samples through the local Jacobian of the pixel-to-plane map). Static parts
are drawn once per :class:`SceneSpec`; a frame redraws only a band around the hub and beam.
Motion blur averages the coverage of several poses over the exposure.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from vision.calibration import plane_to_px
from vision.camera import Lens, camera_matrix, undistort_points_px
from vision.config import CameraConfig, CameraPoseConfig, RegistrationConfig
from vision.errors import BehindCameraError, ParameterError
from vision.homography import apply_homography
from vision.synthetic.pose import camera_extrinsics, ideal_from_plane

__all__ = [
    "BeamPose",
    "Clutter",
    "RenderTruth",
    "RenderedFrame",
    "SceneSpec",
    "render_frame",
]

DEFAULT_STATIONS_M = (0.005, 0.204, 0.403, 0.603)


@dataclass(frozen=True, eq=False)
class BeamPose:
    """The beam's shape at one instant.

    Parameters
    ----------
    hub_angle_rad : direction of the hub axis from the pivot toward the beam, CCW from +X.
    stations_m : (S,) ascending distances from the clamp along the undeformed beam (0 = clamp).
    lateral_m : (S,) deflection perpendicular to the hub axis, positive toward increasing
        hub angle.
    longitudinal_m : (S,) deflection along the hub axis (negative when pulled in).
    """

    hub_angle_rad: float
    stations_m: NDArray[np.float64]
    lateral_m: NDArray[np.float64]
    longitudinal_m: NDArray[np.float64]

    def __post_init__(self) -> None:
        s = np.asarray(self.stations_m, dtype=np.float64).ravel()
        if s.size < 2 or np.any(np.diff(s) <= 0) or not np.all(np.isfinite(s)):
            raise ParameterError("stations_m", "must hold 2 or more finite ascending stations")
        for name in ("lateral_m", "longitudinal_m"):
            v = np.asarray(getattr(self, name), dtype=np.float64).ravel()
            if v.shape != s.shape or not np.all(np.isfinite(v)):
                raise ParameterError(name, f"must be finite with the shape of stations_m {s.shape}")
            object.__setattr__(self, name, v)
        if not math.isfinite(self.hub_angle_rad):
            raise ParameterError("hub_angle_rad", "must be finite")
        object.__setattr__(self, "stations_m", s)

    @classmethod
    def straight(cls, hub_angle_rad: float, length_m: float) -> BeamPose:
        """The undeflected (rigid) beam."""
        s = np.array([0.0, length_m])
        return cls(hub_angle_rad, s, np.zeros(2), np.zeros(2))

    @classmethod
    def from_slope(
        cls, hub_angle_rad: float, length_m: float, slope_rad: Any, n: int = 401
    ) -> BeamPose:
        """An inextensible shape from its slope ``slope_rad(s)`` relative to the hub axis
        (a callable of stations, m); the deflections follow by integration."""
        s = np.linspace(0.0, length_m, n)
        th = np.asarray(slope_rad(s), dtype=np.float64)
        ds = np.diff(s)
        c, sn = np.cos(th), np.sin(th)
        x = np.concatenate([[0.0], np.cumsum(0.5 * (c[1:] + c[:-1]) * ds)])
        y = np.concatenate([[0.0], np.cumsum(0.5 * (sn[1:] + sn[:-1]) * ds)])
        return cls(hub_angle_rad, s, y, x - s)

    def at(self, stations_m: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(lateral, longitudinal) deflections at ``stations_m``, interpolated."""
        q = np.asarray(stations_m, dtype=np.float64)
        if len(self.stations_m) >= 4:
            from scipy.interpolate import CubicSpline

            lat = CubicSpline(self.stations_m, self.lateral_m)(q)
            lon = CubicSpline(self.stations_m, self.longitudinal_m)(q)
            return np.asarray(lat), np.asarray(lon)
        return (
            np.interp(q, self.stations_m, self.lateral_m),
            np.interp(q, self.stations_m, self.longitudinal_m),
        )


@dataclass(frozen=True)
class Clutter:
    """A rectangle lying in the beam plane: centre (x, y) m, size (long, short) m, angle
    of its long side from +X, brightness in DN (before lighting)."""

    center_m: tuple[float, float]
    size_m: tuple[float, float]
    angle_rad: float = 0.0
    level_dn: float = 230.0


@dataclass(frozen=True, eq=False)
class SceneSpec:
    """Everything static about a synthetic view. Build with :meth:`from_rig`.

    Brightness levels are in DN before lighting (``lighting_gradient``: fractional change
    of illumination across the image width; ``vignetting``: fractional loss at the corners).
    ``hub_length_m``/``hub_width_m`` size the hub bar: it ends at the clamp
    (``hub_offset_m`` from the pivot along the hub axis) and extends back from there.
    """

    camera: CameraConfig
    pose: CameraPoseConfig
    registration: RegistrationConfig
    beam_length_m: float = 0.835
    beam_width_m: float = 0.01905
    hub_offset_m: float = 0.008
    hub_length_m: float = 0.20
    hub_width_m: float = 0.04
    noise_dn: float = 2.0
    seed: int = 0
    background_dn: float = 40.0
    beam_dn: float = 215.0
    hub_dn: float = 190.0
    plate_dn: float = 205.0
    groove_dn: float = 45.0
    lighting_gradient: float = 0.0
    lighting_azimuth_rad: float = 0.0
    vignetting: float = 0.0
    blur_sigma_px: float = 0.6
    supersample: int = 4
    clutter: tuple[Clutter, ...] = ()
    draw_registration: bool = True
    stations_m: tuple[float, ...] = DEFAULT_STATIONS_M
    _cache: dict[str, Any] = field(default_factory=dict, init=False, repr=False)
    _cache_lock: threading.Lock = field(
        default_factory=threading.Lock, init=False, repr=False, compare=False
    )

    def __post_init__(self) -> None:
        for name in ("beam_length_m", "beam_width_m", "hub_length_m", "hub_width_m"):
            v = getattr(self, name)
            if not math.isfinite(v) or v <= 0:
                raise ParameterError(name, f"must be positive, got {v!r}")
        if self.hub_width_m <= self.beam_width_m:
            raise ParameterError(
                "hub_width_m", "must exceed beam_width_m (the hub is the wider bar)"
            )
        if self.noise_dn < 0 or self.blur_sigma_px < 0:
            raise ParameterError("noise_dn and blur_sigma_px", "must be >= 0")
        if not 1 <= self.supersample <= 16:
            raise ParameterError("supersample", f"must be in 1..16, got {self.supersample}")

    @classmethod
    def from_rig(
        cls,
        camera: CameraConfig,
        pose: CameraPoseConfig,
        registration: RegistrationConfig,
        *,
        beam_length_m: float,
        beam_width_m: float,
        hub_offset_m: float,
        noise_dn: float = 2.0,
        seed: int = 0,
        **options: Any,
    ) -> SceneSpec:
        """A scene from the rig's camera, camera pose and registration sections."""
        return cls(
            camera=camera,
            pose=pose,
            registration=registration,
            beam_length_m=beam_length_m,
            beam_width_m=beam_width_m,
            hub_offset_m=hub_offset_m,
            noise_dn=noise_dn,
            seed=seed,
            **options,
        )

    # -- geometry -------------------------------------------------------------------
    @property
    def camera_matrix(self) -> NDArray[np.float64]:
        c = self.camera
        return camera_matrix(c.focal_length_px, c.width_px, c.height_px)

    @property
    def distortion(self) -> NDArray[np.float64]:
        return np.asarray(self.camera.distortion, dtype=np.float64)

    @property
    def ideal_from_plane(self) -> NDArray[np.float64]:
        r, t = camera_extrinsics(self.pose)
        return ideal_from_plane(self.camera_matrix, r, t)

    def to_px(self, points_m: ArrayLike) -> NDArray[np.float64]:
        """Exact projection of beam-plane points (N, 2), m, to raw pixels (N, 2): the
        calibration's mapping (:func:`vision.calibration.plane_to_px`) with the true
        pose's homography. Raises :class:`~vision.errors.BehindCameraError` for a point
        the camera cannot see."""
        pts = np.asarray(points_m, dtype=np.float64).reshape(-1, 2)
        r, t = camera_extrinsics(self.pose)
        if np.any(pts @ r[2, :2] + t[2] <= 0):
            raise BehindCameraError()
        k = self.camera_matrix
        return plane_to_px(pts, ideal_from_plane(k, r, t), Lens(k, self.distortion))

    def registration_points_m(self) -> NDArray[np.float64]:
        """(4, 2) corners of the registration square, CCW in the plane, starting at the
        corner at (-s/2, -s/2) of the square's own frame (first groove = its x axis)."""
        reg = self.registration
        h = reg.square_side_m / 2.0
        local = np.array([[-h, -h], [h, -h], [h, h], [-h, h]])
        c, s = math.cos(reg.angle_rad), math.sin(reg.angle_rad)
        return local @ np.array([[c, s], [-s, c]]) + np.asarray(reg.center_m)

    # -- cached rasters ---------------------------------------------------------------
    def _static(self) -> dict[str, Any]:
        with self._cache_lock:  # frames may render in several threads
            if not self._cache:
                self._cache.update(_build_static(self))
        return self._cache


@dataclass(frozen=True, eq=False)
class RenderTruth:
    """Ground truth of a rendered frame (means over the exposure's poses)."""

    hub_angle_rad: float
    tip_lateral_m: float
    tip_longitudinal_m: float
    stations_m: NDArray[np.float64]
    lateral_at_stations_m: NDArray[np.float64]
    corners_px: NDArray[np.float64]
    plane_points_m: NDArray[np.float64]
    camera_matrix: NDArray[np.float64]
    distortion: NDArray[np.float64]
    clamp_plane_m: NDArray[np.float64]
    tip_plane_m: NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class RenderedFrame:
    """``image``: uint8 gray [row, col]; ``truth``: what it shows."""

    image: NDArray[np.uint8]
    truth: RenderTruth


# ---------------------------------------------------------------------------------------
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
    st = spec._static()
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
    for sh in shapes:
        e, n = sh.e, sh.n
        pa = px * e[0] + py * e[1]
        pb = px * n[0] + py * n[1]
        da = dx * e[0] + dy * e[1]
        db = dx * n[0] + dy * n[1]
        a_sub = pa[:, None] + da
        b_sub = pb[:, None] + db
        in_hub = (
            (a_sub <= spec.hub_offset_m)
            & (a_sub >= spec.hub_offset_m - spec.hub_length_m)
            & (np.abs(b_sub) <= spec.hub_width_m / 2)
        )
        s, d, ta, tb = sh.foot(pa, pb)
        s_sub = s[:, None] + da * ta[:, None] + db * tb[:, None]
        d_sub = d[:, None] - da * tb[:, None] + db * ta[:, None]
        in_beam = (np.abs(d_sub) <= half_w) & (s_sub <= sh.length) & (s_sub >= -0.002)
        in_beam &= ~in_hub
        cov_hub += in_hub.mean(axis=1)
        cov_beam += in_beam.mean(axis=1)
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
