"""Calibration: the image <-> beam-plane mapping of one camera placement.

A :class:`Calibration` holds registration point pairs (raw image pixels and beam-plane
metres), optional intrinsics and lens distortion, and the beam's length and width. The
homography maps *undistorted* pixels to the plane; with four pairs it is the paper's
exact collineation (Eqs. 42-46), with more the normalized DLT.

The plane <-> pixel mapping (homography and lens distortion) is written once, here:
:meth:`Calibration.to_px` / :meth:`Calibration.to_plane`, which are :func:`plane_to_px` /
:func:`px_to_plane` with the calibration's homography and lens. The synthetic camera
projects through :func:`plane_to_px` too, with its true pose's homography.

CAL.json layout::

    {"registration": {"image_points_px": [[x, y], ...], "plane_points_m": [[X, Y], ...],
                      "plane_from_ideal_cov": [[...9...], ... 9 rows]},
     "camera": {"matrix": [[fx, 0, cx], [0, fy, cy], [0, 0, 1]], "distortion": [k1, ...]},
     "beam": {"length_m": 0.835, "width_m": 0.01905}}

``camera`` and ``beam`` (and each of their keys) are optional, as is
``registration.plane_from_ideal_cov`` (the fitted homography's covariance; absent: the
points are taken as exact).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from vision.camera import Lens, as_points, check_intrinsics, undistort_points_px
from vision.errors import CalibrationError, ParameterError
from vision.homography import (
    MAX_CONDITION,
    HomographyFit,
    apply_homography,
    collineation_4pt,
    dlt_homography,
    map_points,
)

DEFAULT_BEAM_LENGTH_M = 0.835
DEFAULT_BEAM_WIDTH_M = 0.01905
MAX_BEAM_LENGTH_M = 10.0  # a laboratory beam (as the rig's limit)


@dataclass(frozen=True, eq=False)
class Calibration:
    """Registration of one camera placement to the beam plane.

    Parameters
    ----------
    image_points_px : (N, 2) raw (distorted) pixel points (x, y), N >= 4.
    plane_points_m : (N, 2) the same points in the beam-plane frame, m.
    camera_matrix : (3, 3) intrinsics or None (no distortion correction).
    distortion : OpenCV coefficients (k1, k2, p1, p2[, k3...]) or None.
    beam_length_m, beam_width_m : free length (clamp to tip) and width of the beam, m.
    plane_from_ideal_cov : (9, 9) covariance of the plane-from-undistorted-pixel
        homography's elements (``plane_from_ideal.ravel()``, normalised to ``[2, 2] = 1``)
        as fitted to the registration (:mod:`vision.plane_pose`), or None: points taken
        as exact (a calibration file that states no uncertainty). What it does to each
        frame: :mod:`vision.calibration_error`.

    Map points with :meth:`to_px` (plane to raw pixels) and :meth:`to_plane` (raw pixels
    to plane), lens distortion included when the calibration has it.
    """

    image_points_px: NDArray[np.float64]
    plane_points_m: NDArray[np.float64]
    camera_matrix: NDArray[np.float64] | None = None
    distortion: NDArray[np.float64] | None = None
    beam_length_m: float = DEFAULT_BEAM_LENGTH_M
    beam_width_m: float = DEFAULT_BEAM_WIDTH_M
    plane_from_ideal_cov: NDArray[np.float64] | None = None
    fit: HomographyFit = field(init=False, repr=False)
    _ideal_from_plane: NDArray[np.float64] = field(init=False, repr=False)
    _lens: Lens = field(init=False, repr=False)

    def __post_init__(self) -> None:
        img = as_points(self.image_points_px, "image_points_px")
        pln = as_points(self.plane_points_m, "plane_points_m")
        if img.shape != pln.shape:
            raise ParameterError(
                "image_points_px and plane_points_m",
                f"must have the same shape, got {img.shape} and {pln.shape}",
            )
        k, d = check_intrinsics(self.camera_matrix, self.distortion)
        for name in ("beam_length_m", "beam_width_m"):
            v = getattr(self, name)
            if not isinstance(v, int | float) or not math.isfinite(v) or v <= 0:
                raise ParameterError(name, f"must be a positive number, got {v!r}")
        if self.beam_width_m >= self.beam_length_m:
            raise ParameterError("beam_width_m", "must be smaller than beam_length_m")
        for name, limit in (("beam_length_m", MAX_BEAM_LENGTH_M), ("beam_width_m", 0.5)):
            if getattr(self, name) > limit:
                raise ParameterError(
                    name,
                    f"must be at most {limit:g} m (a laboratory beam), got {getattr(self, name)!r}",
                )
        object.__setattr__(self, "image_points_px", img)
        object.__setattr__(self, "plane_points_m", pln)
        object.__setattr__(self, "camera_matrix", k)
        object.__setattr__(self, "distortion", d)
        if self.plane_from_ideal_cov is not None:
            cov = np.asarray(self.plane_from_ideal_cov, dtype=np.float64)
            if (
                cov.shape != (9, 9)
                or not np.all(np.isfinite(cov))
                or not np.allclose(cov, cov.T, rtol=1e-6, atol=0.0)
                or np.any(np.diag(cov) < 0)
            ):
                raise ParameterError(
                    "plane_from_ideal_cov", "must be a finite symmetric 9x9 covariance"
                )
            object.__setattr__(self, "plane_from_ideal_cov", cov)
        ideal = undistort_points_px(img, k, d)
        try:
            fit = collineation_4pt(ideal, pln) if len(img) == 4 else dlt_homography(ideal, pln)
        except ValueError as exc:
            raise CalibrationError(str(exc), section="registration") from None
        if not fit.condition < MAX_CONDITION:
            raise CalibrationError(
                f"the homography is badly conditioned (condition {fit.condition:.3g})",
                section="registration",
            )
        w = ideal @ fit.matrix[2, :2] + fit.matrix[2, 2]
        if not (np.all(w > 0) or np.all(w < 0)):
            raise CalibrationError(
                "the points are not in a consistent order (the plane's horizon crosses them)",
                section="registration",
            )
        # image x right, y down against the plane's X, Y (right-handed, seen from +Z): a
        # camera sees the plane with its orientation reversed, the Jacobian of pixels ->
        # plane, det(H) / w^3, negative. Positive is a mirror image: the points' pairing
        # is wrong (or the plane was seen from behind), and hub angles would flip sign.
        if np.linalg.det(fit.matrix) / w[0] ** 3 > 0:
            raise CalibrationError(
                "the plane is mirrored: image points and plane points pair up as a mirror "
                "image (the plane's X, Y must appear counter-clockwise as the image's x, -y)",
                section="registration",
            )
        object.__setattr__(self, "fit", fit)
        object.__setattr__(self, "_ideal_from_plane", np.linalg.inv(fit.matrix))
        object.__setattr__(self, "_lens", Lens(k, d))

    @property
    def plane_from_ideal(self) -> NDArray[np.float64]:
        """(3, 3) homography from undistorted pixels to beam-plane metres."""
        return self.fit.matrix

    def to_px(self, points_m: ArrayLike) -> NDArray[np.float64]:
        """Beam-plane points (N, 2), m, to raw (distorted) image pixels (N, 2), (x, y):
        :func:`plane_to_px` with the homography by its formula in a kernel
        (:func:`~vision.homography.map_points`: the measurement maps a dozen small
        batches a frame)."""
        ideal = map_points(self._ideal_from_plane, points_m)
        return ideal if self._lens.identity else self._lens.distort(ideal)

    @property
    def to_px_pointwise(self) -> bool:
        """Whether :meth:`to_px` maps each point by its own arithmetic (the homography's
        kernel, then the lens's formula or none): then mapping many frames' points in one
        call gives, bit for bit, what a call for each frame gives."""
        return self._lens.distorts_pointwise

    def to_plane(self, points_px: ArrayLike) -> NDArray[np.float64]:
        """Raw image pixels (N, 2), (x, y), to beam-plane points (N, 2), m (the inverse
        of :meth:`to_px`, :func:`px_to_plane` as it)."""
        lens = self._lens
        ideal = points_px if lens.identity else lens.undistort(np.asarray(points_px, np.float64))
        return map_points(self.fit.matrix, ideal)

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "registration": {
                "image_points_px": self.image_points_px.tolist(),
                "plane_points_m": self.plane_points_m.tolist(),
            },
            "beam": {"length_m": self.beam_length_m, "width_m": self.beam_width_m},
        }
        if self.plane_from_ideal_cov is not None:
            out["registration"]["plane_from_ideal_cov"] = self.plane_from_ideal_cov.tolist()
        cam: dict[str, Any] = {}
        if self.camera_matrix is not None:
            cam["matrix"] = self.camera_matrix.tolist()
        if self.distortion is not None:
            cam["distortion"] = self.distortion.tolist()
        if cam:
            out["camera"] = cam
        return out

    def to_json(self) -> str:
        """The CAL.json text (see the module docstring)."""
        return json.dumps(self.to_dict(), indent=2)


def plane_to_px(
    points_m: ArrayLike, ideal_from_plane: NDArray[np.float64], lens: Lens
) -> NDArray[np.float64]:
    """Beam-plane points (N, 2), m, to raw image pixels (N, 2): the homography
    ``ideal_from_plane`` (3, 3) to undistorted pixels, then the ``lens``."""
    ideal = apply_homography(ideal_from_plane, points_m)
    return ideal if lens.identity else lens.distort(ideal)


def px_to_plane(
    points_px: ArrayLike, plane_from_ideal: NDArray[np.float64], lens: Lens
) -> NDArray[np.float64]:
    """Raw image pixels (N, 2) to beam-plane points (N, 2), m: the ``lens`` undone, then
    the homography ``plane_from_ideal`` (3, 3). The inverse of :func:`plane_to_px`."""
    ideal = points_px if lens.identity else lens.undistort(np.asarray(points_px, np.float64))
    return apply_homography(plane_from_ideal, ideal)


def calibration_from_dict(data: Any) -> Calibration:
    """Build a :class:`Calibration` from the parsed CAL.json structure."""
    if not isinstance(data, dict):
        raise CalibrationError("the top level must be an object")
    unknown = set(data) - {"registration", "camera", "beam"}
    if unknown:
        raise CalibrationError(f"unknown key(s) {sorted(unknown)}")
    reg = data.get("registration")
    if not isinstance(reg, dict):
        raise CalibrationError("'registration' object is missing")
    for key in ("image_points_px", "plane_points_m"):
        if key not in reg:
            raise CalibrationError(f"registration.{key} is missing")
    cov = None
    if reg.get("plane_from_ideal_cov") is not None:
        try:
            cov = np.asarray(reg["plane_from_ideal_cov"], dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise CalibrationError(
                f"registration.plane_from_ideal_cov is not numeric ({exc})"
            ) from None
    cam = data.get("camera", {}) or {}
    beam = data.get("beam", {}) or {}
    if not isinstance(cam, dict) or not isinstance(beam, dict):
        raise CalibrationError("'camera' and 'beam' must be objects")
    img = _point_list(reg["image_points_px"], "registration.image_points_px")
    pln = _point_list(reg["plane_points_m"], "registration.plane_points_m")
    if np.any(img < 0.0):
        raise CalibrationError(
            "registration.image_points_px: a point has a negative pixel coordinate "
            "(outside the image, whose corner is (0, 0))"
        )
    try:
        matrix = None if cam.get("matrix") is None else np.asarray(cam["matrix"], float)
        dist = None if cam.get("distortion") is None else np.asarray(cam["distortion"], float)
    except (TypeError, ValueError) as exc:
        raise CalibrationError(f"a camera array is not numeric ({exc})") from None
    for key in beam:
        if key not in ("length_m", "width_m"):
            raise CalibrationError(f"unknown key beam.{key}")
    return Calibration(
        image_points_px=img,
        plane_points_m=pln,
        camera_matrix=matrix,
        distortion=dist,
        beam_length_m=_number(beam.get("length_m", DEFAULT_BEAM_LENGTH_M), "beam.length_m"),
        beam_width_m=_number(beam.get("width_m", DEFAULT_BEAM_WIDTH_M), "beam.width_m"),
        plane_from_ideal_cov=cov,
    )


def _point_list(value: Any, key: str) -> NDArray[np.float64]:
    """A JSON list of four or more [x, y] pairs of finite numbers as an (N, 2) array."""
    shape_hint = "a list of 4 or more numeric [x, y] pairs: shape (N, 2)"
    if not isinstance(value, list) or not all(
        isinstance(p, list)
        and len(p) == 2
        and all(isinstance(v, int | float) and not isinstance(v, bool) for v in p)
        for p in value
    ):
        raise CalibrationError(f"{key} must be {shape_hint}, got {_brief(value)}")
    arr = np.asarray(value, dtype=np.float64).reshape(-1, 2)
    if len(arr) < 4:
        raise CalibrationError(f"{key} needs 4 or more points, got {len(arr)}")
    if not np.all(np.isfinite(arr)):
        raise CalibrationError(f"{key} must be finite numbers")
    return arr


def _number(value: Any, key: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise CalibrationError(f"{key} must be a number, got {_brief(value)}")
    return float(value)


def _brief(value: Any) -> str:
    text = json.dumps(value)
    return text if len(text) <= 60 else text[:57] + "..."


def check_points_in_image(cal: Calibration, width_px: int, height_px: int) -> None:
    """Refuse a calibration whose registration points lie outside a ``width_px`` x
    ``height_px`` image: it was made for another camera or image size."""
    pts = cal.image_points_px
    outside = (pts[:, 0] > width_px) | (pts[:, 1] > height_px) | (pts < 0).any(axis=1)
    if outside.any():
        x, y = pts[outside][0]
        raise CalibrationError(
            f"registration point ({x:g}, {y:g}) px lies outside the {width_px} x {height_px} "
            "image (a calibration of another camera or image size)",
            section="registration",
        )


def load_calibration(path: str | Path) -> Calibration:
    """Read CAL.json; raises :class:`~vision.errors.CalibrationError` (or, for a bad
    value, :class:`~vision.errors.ParameterError`; both ``ValueError``) with the reason,
    not naming the file."""
    try:
        text = Path(path).read_text("utf-8")
    except FileNotFoundError:
        raise CalibrationError("no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise CalibrationError(f"cannot be read ({exc})") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise CalibrationError(f"not valid JSON ({exc})") from None
    return calibration_from_dict(data)
