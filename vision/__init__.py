"""beambench vision: from camera frames to hub angle, tip deflection and the beam's
centre line, and the synthetic camera that draws such frames. numpy/scipy/OpenCV (and numba's
compiled kernels, ``jit``) only;
imports neither ``sim``, ``daq`` nor ``pipelines``.

Modules, roughly in the order of the data flow:

- ``errors``: the exception tree (root :class:`VisionError`); ``jit``: numba's compiled kernels.
- ``config``: camera, camera pose and registration-object settings (frozen dataclasses).
- ``camera``: pinhole model, the camera matrix, lens distortion, checkerboard calibration.
- ``homography``: plane-to-plane collineations (the paper's 4-point one, DLT, from lines).
- ``calibration``: :class:`Calibration`, one camera placement, with the plane <-> pixel
  mapping (``to_px`` / ``to_plane``) and the CAL.json file.
- ``plane_pose``: the registration plane's mapping fitted to its edges, as a camera pose
  when the intrinsics are known, with its covariance.
- ``registration``: finds the registration object in a frame and calibrates from it.
- ``calibration_error``: what the calibration's own error does to the plane and to each
  frame's hub angle and tip (one error common to all frames).
- ``codec``: JPEG/PNG bytes <-> uint8 gray images (JPEGs with restart markers);
  ``jpeg_regions``: a JPEG's restart segments decoded alone.
- ``sampling``, ``edges``: image sampling and sub-pixel edges along scan lines.
- ``locate``: rough location of beam and hub in the plane.
- ``hub``: the hub's axis and end faces; ``centreline``: the beam's fitted centre line.
- ``frame_measurement``: :class:`FrameMeasurement`, what one frame shows.
- ``measure``: :class:`Measurer`, the per-frame measurement and its default method;
  ``paper_chain``: the paper's method, from a calibration.
- ``regions``: :class:`~vision.regions.RegionReader`, a run's frames decoded only where
  the measurement reads them, with the same results.
- ``synthetic``: the scene (``scene``), its rasteriser (``render``) and the camera's
  placement (``pose``), for the synthetic bench and the tests.
"""

from vision.calibration import Calibration, load_calibration
from vision.codec import decode, encode
from vision.errors import VisionError
from vision.frame_measurement import FrameMeasurement
from vision.measure import Measurer
from vision.registration import (
    calibration_from_registration,
    detect_registration_corners,
    detect_registration_points,
)

__all__ = [
    "Calibration",
    "FrameMeasurement",
    "Measurer",
    "VisionError",
    "calibration_from_registration",
    "decode",
    "detect_registration_corners",
    "detect_registration_points",
    "encode",
    "load_calibration",
]
