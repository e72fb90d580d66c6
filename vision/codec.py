"""Image decoding (JPEG, PNG, ...) to uint8 gray [row, col]."""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from vision.errors import DecodeError


def decode(data: bytes) -> NDArray[np.uint8]:
    """Decode compressed image bytes to a uint8 gray [row, col] array.

    Raises :class:`~vision.errors.DecodeError` (a ``ValueError``) when the bytes are not
    a readable image.
    """
    if not isinstance(data, bytes | bytearray | memoryview):
        raise TypeError(f"data must be bytes, got {type(data).__name__}")
    buf = np.frombuffer(bytes(data), dtype=np.uint8)
    if buf.size == 0:
        raise DecodeError(0)
    # OpenCV warns on stderr about damaged data; the DecodeError below says it once, so
    # the caller's single error line is not preceded by a library's.
    level = cv2.utils.logging.getLogLevel()
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_ERROR)
    try:
        img = cv2.imdecode(buf, cv2.IMREAD_GRAYSCALE)
    finally:
        cv2.utils.logging.setLogLevel(level)
    if img is None:
        raise DecodeError(buf.size)
    if img.dtype != np.uint8:
        img = cv2.convertScaleAbs(img, alpha=255.0 / max(float(img.max()), 1.0))
    return np.ascontiguousarray(img)
