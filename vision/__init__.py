"""beambench vision: camera model, registration/rectification, centre-line
extraction, hub angle and deflection, and the scene renderer. numpy/scipy/OpenCV
only; imports neither ``sim`` nor ``daq``."""

from vision.calibration import Calibration, load_calibration
from vision.codec import decode, encode
from vision.errors import VisionError
from vision.measure import FrameMeasurement, Measurer
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
