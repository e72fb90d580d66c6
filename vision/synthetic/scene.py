"""The synthetic bench's scene: what the camera looks at, and the truth of a frame.

A :class:`SceneSpec` holds everything static about a view: the camera and its pose on
the beam plane, the registration plate, the hub and beam sizes, brightness levels,
lighting, noise and clutter; its :meth:`SceneSpec.to_px` is the exact projection of
plane points. A :class:`BeamPose` is the beam's shape at one instant.
:func:`vision.synthetic.render.render_frame` draws a scene with poses into a
:class:`RenderedFrame` with its :class:`RenderTruth`.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from vision.calibration import plane_to_px
from vision.camera import Lens, camera_matrix
from vision.config import CameraConfig, CameraPoseConfig, RegistrationConfig
from vision.errors import BehindCameraError, ParameterError
from vision.registration import registration_plane_points_m
from vision.synthetic.pose import camera_extrinsics, ideal_from_plane

__all__ = [
    "DEFAULT_STATIONS_M",
    "BeamMotion",
    "BeamPose",
    "Clutter",
    "RenderTruth",
    "RenderedFrame",
    "SceneSpec",
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

    @classmethod
    def from_load(
        cls,
        hub_angle_rad: float,
        length_m: float,
        load: Any,
        peak_m: float,
        n: int = 2001,
    ) -> BeamPose:
        """The shape of a uniform clamped-free (Euler-Bernoulli) beam under the lateral
        load per length ``load(s)`` (a callable of stations, m; any unit: the shape is
        scaled so that its largest deflection is ``peak_m``, sign included). The shear
        and the moment are integrated from the free end, where both vanish, the slope
        (the moment over EI) from the clamp, where it vanishes; the slope is the angle of
        an inextensible centre line (:meth:`from_slope`). A vibrating beam's shape at an
        instant is the static response to its inertial load, so a smooth load gives a
        physical shape; shapes built otherwise need not have a free end."""
        s = np.linspace(0.0, length_m, n)
        q = np.asarray(load(s), dtype=np.float64) * np.ones(n)

        def from_end(f: NDArray[np.float64]) -> NDArray[np.float64]:
            seg = 0.5 * (f[1:] + f[:-1]) * np.diff(s)
            return np.concatenate([np.cumsum(seg[::-1])[::-1], [0.0]])

        def from_root(f: NDArray[np.float64]) -> NDArray[np.float64]:
            return np.concatenate([[0.0], np.cumsum(0.5 * (f[1:] + f[:-1]) * np.diff(s))])

        moment = from_end(from_end(q))  # M(s) = int_s^L (x - s) q(x) dx
        slope = from_root(moment)
        w = from_root(slope)
        peak = float(w[np.argmax(np.abs(w))])
        if peak == 0.0 or not math.isfinite(peak):
            raise ParameterError("load", "bends the beam by nothing")
        slope *= peak_m / peak
        return cls.from_slope(hub_angle_rad, length_m, lambda x: np.interp(x, s, slope), n=n)

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


@dataclass(frozen=True, eq=False)
class BeamMotion:
    """The beam's pose at mid-exposure and its velocity then: what a still camera with an
    open shutter sees is the time-average of the moving beam over the exposure
    (:meth:`exposure_poses` samples it for :func:`vision.synthetic.render.render_frame`).

    Parameters
    ----------
    pose : the shape at mid-exposure.
    hub_rate_rad_s : the hub's angular velocity.
    lateral_rate_m_s : (S,) rate of the lateral deflection at ``pose.stations_m`` (the
        beam's own vibration, in the hub frame); zeros when omitted.
    """

    pose: BeamPose
    hub_rate_rad_s: float = 0.0
    lateral_rate_m_s: NDArray[np.float64] | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.pose, BeamPose):
            raise TypeError(f"pose must be a BeamPose, got {type(self.pose).__name__}")
        if not math.isfinite(self.hub_rate_rad_s):
            raise ParameterError("hub_rate_rad_s", "must be finite")
        s = self.pose.stations_m
        v = np.zeros_like(s) if self.lateral_rate_m_s is None else self.lateral_rate_m_s
        v = np.asarray(v, dtype=np.float64).ravel()
        if v.shape != s.shape or not np.all(np.isfinite(v)):
            raise ParameterError(
                "lateral_rate_m_s",
                f"must be finite with the shape of the pose's stations {s.shape}",
            )
        object.__setattr__(self, "lateral_rate_m_s", v)

    def at(self, dt_s: float) -> BeamPose:
        """The pose ``dt_s`` after mid-exposure (the velocity held over the exposure)."""
        p = self.pose
        assert self.lateral_rate_m_s is not None
        return BeamPose(
            p.hub_angle_rad + self.hub_rate_rad_s * dt_s,
            p.stations_m,
            p.lateral_m + self.lateral_rate_m_s * dt_s,
            p.longitudinal_m,
        )

    def tip_speed_m_s(self, hub_offset_m: float) -> float:
        """Speed of the tip across the beam (m/s): the hub's rotation carried to the tip
        (``hub_offset_m`` + the beam's length from the pivot) plus the beam's own rate."""
        assert self.lateral_rate_m_s is not None
        p = self.pose
        reach = hub_offset_m + p.stations_m[-1] + p.longitudinal_m[-1]
        return abs(self.hub_rate_rad_s * reach + self.lateral_rate_m_s[-1])

    def fastest_speed_m_s(self, hub_offset_m: float) -> float:
        """Speed across the beam of its fastest point (m/s): the tip's when the hub's turn
        and the beam's own rate add, a point nearer the root when they counter-move (the
        beam lagging the hub near a stroke end, its tip then barely moving)."""
        assert self.lateral_rate_m_s is not None
        p = self.pose
        radius = hub_offset_m + p.stations_m + p.longitudinal_m
        return float(np.max(np.abs(self.hub_rate_rad_s * radius + self.lateral_rate_m_s)))

    def tip_smear_m(self, exposure_s: float, hub_offset_m: float) -> float:
        """How far the tip moves across the beam during the exposure (m)."""
        return self.tip_speed_m_s(hub_offset_m) * exposure_s

    def exposure_poses(
        self, exposure_s: float, hub_offset_m: float, max_step_m: float = 2e-4
    ) -> list[BeamPose]:
        """Poses at the midpoints of equal slices of the exposure, enough slices that
        no point of the beam moves more than ``max_step_m`` per slice (the renderer
        averages their coverage: the midpoint rule for the time-average, exact for the
        smear's width to a slice). One pose for a still beam."""
        if not math.isfinite(exposure_s) or exposure_s < 0:
            raise ParameterError("exposure_s", f"must be >= 0, got {exposure_s!r}")
        if not max_step_m > 0:
            raise ParameterError("max_step_m", f"must be > 0, got {max_step_m!r}")
        smear = self.fastest_speed_m_s(hub_offset_m) * exposure_s
        n = max(1, math.ceil(smear / max_step_m))
        t = (np.arange(n) + 0.5) / n - 0.5
        return [self.at(float(k) * exposure_s) for k in t]


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
    #: The rasters drawn once per scene, filled on first use by
    #: :func:`vision.synthetic.render.static_layers` (frames may render in several threads).
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
        """(4, 2) corners of the registration square in the plane, in the order of
        :func:`vision.registration.registration_plane_points_m`."""
        return registration_plane_points_m(self.registration)


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
