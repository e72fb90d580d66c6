"""Configuration of the camera and the registration object.

Frozen dataclasses validated on construction; a bad value raises
:class:`~vision.errors.ParameterError` (a ``ValueError``) whose message starts with the
field name.

The beam-plane frame: origin at the beam pivot (the rocker's ground pivot), X along
the mechanism's ground link (crank pivot towards rocker pivot, Eqs. 1-2), Y to make a
right-handed frame in the plane of motion; metres.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from vision.errors import ParameterError

ENCODINGS = ("jpeg", "png")


def _positive(name: str, value: float) -> None:
    if not math.isfinite(value) or value <= 0.0:
        raise ParameterError(name, f"must be a positive finite number, got {value!r}")


def _at_most(name: str, value: float, limit: float, unit: str, why: str) -> None:
    if not abs(value) <= limit:
        raise ParameterError(name, f"must be at most {limit:g} {unit} ({why}), got {value!r}")


def _finite_pair(name: str, value: tuple[float, ...], limit_m: float) -> None:
    if len(value) != 2:
        raise ParameterError(name, f"must be (x, y), got {value!r}")
    if not all(abs(v) <= limit_m for v in value):
        raise ParameterError(
            name, f"must be finite and within +/-{limit_m:g} m of the pivot, got {value!r}"
        )


# Limits of the cameras this package drives (each error states its reason).
MAX_SIDE_PX = 16384  # the largest sensors made (16k)
MAX_FRAME_RATE_HZ = 1000.0  # a high-speed machine-vision camera
# pixels per second a camera delivers and beambench can encode and measure: 2048 x 1536 at
# 150 frames/s, 4096 x 3072 at 37; what a USB3/GigE camera of that size does
MAX_PIXEL_RATE_PX_S = 5e8
MAX_LATENCY_S = 10.0  # trigger to timestamp
MAX_DISTORTION = 1e3  # |k|, |p|: a fisheye's coefficients stay well below
MAX_SCENE_M = 10.0  # positions in the beam plane, from the pivot
MAX_DISTANCE_M = 100.0  # camera to the beam plane


@dataclass(frozen=True)
class CameraConfig:
    """The still camera (paper §4: Canon PowerShot A70, about 3.2 MP, 2048 x 1536).

    ``focal_length_px`` defaults to the A70's wide end (5.4 mm on a 1/2.7" sensor,
    2.6 um pixels). ``distortion`` is in OpenCV order (k1, k2, p1, p2, k3).
    ``device`` is a V4L2 index/path, a video file or a folder of stills.
    """

    width_px: int = 2048
    height_px: int = 1536
    frame_rate_hz: float = 15.0
    encoding: str = "jpeg"
    jpeg_quality: int = 90
    exposure_s: float = 0.0005
    latency_s: float = 0.030
    focal_length_px: float = 2100.0
    distortion: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0)
    device: str = "0"

    def __post_init__(self) -> None:
        for name in ("width_px", "height_px"):
            v = getattr(self, name)
            if not 16 <= v <= MAX_SIDE_PX:
                raise ParameterError(
                    name, f"must be between 16 and {MAX_SIDE_PX} (a 16k sensor), got {v!r}"
                )
        for name in ("frame_rate_hz", "exposure_s", "focal_length_px"):
            _positive(name, getattr(self, name))
        pixels = self.width_px * self.height_px
        max_rate = min(MAX_FRAME_RATE_HZ, MAX_PIXEL_RATE_PX_S / pixels)
        if self.frame_rate_hz > max_rate:
            raise ParameterError(
                "frame_rate_hz",
                f"must be at most {max_rate:.4g} frames/s for a {self.width_px} x "
                f"{self.height_px} camera ({MAX_PIXEL_RATE_PX_S:.3g} pixels/s, at most "
                f"{MAX_FRAME_RATE_HZ:g} frames/s), got {self.frame_rate_hz!r}",
            )
        if not 0.0 <= self.latency_s <= MAX_LATENCY_S:
            raise ParameterError(
                "latency_s",
                f"must be finite, within 0..{MAX_LATENCY_S:g} s (trigger to timestamp), "
                f"got {self.latency_s!r}",
            )
        side = max(self.width_px, self.height_px)
        if not 0.05 * side <= self.focal_length_px <= 50.0 * side:
            raise ParameterError(
                "focal_length_px",
                f"must be within 0.05..50 times the image's long side ({side} px: a fisheye "
                f"to a long telephoto), got {self.focal_length_px!r}",
            )
        if not all(abs(k) <= MAX_DISTORTION for k in self.distortion):
            raise ParameterError(
                "distortion",
                f"coefficients must be finite, within +/-{MAX_DISTORTION:g}, "
                f"got {self.distortion!r}",
            )
        if self.exposure_s * self.frame_rate_hz > 1.0:
            raise ParameterError(
                "exposure_s",
                f"({self.exposure_s!r}) must be shorter than the frame period "
                f"(1 / frame_rate_hz = {1.0 / self.frame_rate_hz:.6g} s)",
            )
        if self.encoding not in ENCODINGS:
            raise ParameterError("encoding", f"must be one of {ENCODINGS}, got {self.encoding!r}")
        if not 1 <= self.jpeg_quality <= 100:
            raise ParameterError(
                "jpeg_quality", f"must be between 1 and 100, got {self.jpeg_quality!r}"
            )
        if len(self.distortion) not in (4, 5, 8):
            raise ParameterError(
                "distortion",
                f"must have 4, 5 or 8 OpenCV coefficients, got {len(self.distortion)}",
            )


@dataclass(frozen=True)
class CameraPoseConfig:
    """Where the camera looks at the beam plane from (used by the synthetic camera).

    The optical axis passes through ``target_m`` (x, y in the beam-plane frame) at
    ``distance_m``; ``tilt_rad`` is the angle between the optical axis and the plane
    normal, tilting about an axis in the plane at ``tilt_azimuth_rad`` from +X;
    ``roll_rad`` turns the image about the optical axis.
    """

    distance_m: float = 2.0
    target_m: tuple[float, ...] = (0.15, -0.37)
    tilt_rad: float = math.radians(15.0)
    tilt_azimuth_rad: float = 0.0
    roll_rad: float = 0.0

    def __post_init__(self) -> None:
        _positive("distance_m", self.distance_m)
        _at_most("distance_m", self.distance_m, MAX_DISTANCE_M, "m", "camera to beam plane")
        _finite_pair("target_m", self.target_m, MAX_SCENE_M)
        if not 0.0 <= self.tilt_rad < math.radians(80.0):
            raise ParameterError("tilt_rad", f"must be in [0, 80 deg), got {self.tilt_rad!r}")
        for name in ("tilt_azimuth_rad", "roll_rad"):
            _at_most(name, getattr(self, name), 2.0 * math.pi, "rad", "one turn")


@dataclass(frozen=True)
class RegistrationConfig:
    """The registration object of paper §4.3: a light plate in the beam plane with two
    orthogonal dark grooves crossing in a square of side ``square_side_m``.

    ``center_m`` is the square's centre in the beam-plane frame, ``angle_rad`` the
    direction of the first groove from +X.
    """

    square_side_m: float = 0.100
    plate_side_m: float = 0.300
    center_m: tuple[float, ...] = (0.50, 0.05)
    angle_rad: float = 0.0

    def __post_init__(self) -> None:
        _positive("square_side_m", self.square_side_m)
        _positive("plate_side_m", self.plate_side_m)
        if self.plate_side_m <= 2.0 * self.square_side_m:
            raise ParameterError(
                "plate_side_m",
                f"({self.plate_side_m!r}) must exceed twice square_side_m "
                f"({self.square_side_m!r}) so the grooves show on the plate",
            )
        _at_most("plate_side_m", self.plate_side_m, 2.0, "m", "a plate on the bench")
        _finite_pair("center_m", self.center_m, MAX_SCENE_M)
        _at_most("angle_rad", self.angle_rad, 2.0 * math.pi, "rad", "one turn")
