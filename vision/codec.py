"""The image codec: uint8 gray [row, col] images to JPEG/PNG bytes and back.

:func:`encode` is what the synthetic camera sends; :func:`decode` reads any format
OpenCV reads (what a real camera or a folder of stills gives).
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from vision.errors import DecodeError, EncodeError, ParameterError


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


def encode(image: NDArray[np.uint8], encoding: str = "jpeg", quality: int = 90) -> bytes:
    """Compress a uint8 gray [row, col] image as JPEG (``quality`` 1-100) or PNG."""
    if not isinstance(image, np.ndarray) or image.dtype != np.uint8 or image.ndim != 2:
        raise TypeError("image must be a uint8 [row, col] numpy array")
    if encoding == "jpeg":
        if not 1 <= quality <= 100:
            raise ParameterError("quality", f"must be in 1..100, got {quality!r}")
        ok, buf = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    elif encoding == "png":
        ok, buf = cv2.imencode(".png", image, [cv2.IMWRITE_PNG_COMPRESSION, 1])
    else:
        raise ParameterError("encoding", f"must be 'jpeg' or 'png', got {encoding!r}")
    if not ok:
        raise EncodeError(encoding)
    return bytes(buf)


_REDUCED = {2: cv2.IMREAD_REDUCED_GRAYSCALE_2, 4: cv2.IMREAD_REDUCED_GRAYSCALE_4}


def preview(data: bytes, reduction: int, quality: int = 85) -> bytes:
    """A reduced copy of an encoded image for display: 1/``reduction`` of its width and
    height (2 or 4), re-encoded as JPEG at ``quality``.

    JPEG is decoded straight at the reduced size (libjpeg's DCT scaling, a fraction of a
    full decode); PNG is decoded and then averaged down. Pixel ``(x, y)`` of the preview
    shows ``(reduction * (x + 0.5) - 0.5, ...)`` of the original.
    """
    if reduction not in _REDUCED:
        raise ParameterError("reduction", f"must be 2 or 4, got {reduction!r}")
    if not isinstance(data, bytes | bytearray | memoryview):
        raise TypeError(f"data must be bytes, got {type(data).__name__}")
    buf = np.frombuffer(bytes(data), dtype=np.uint8)
    level = cv2.utils.logging.getLogLevel()
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_ERROR)
    try:
        img = cv2.imdecode(buf, _REDUCED[reduction]) if buf.size else None
    finally:
        cv2.utils.logging.setLogLevel(level)
    if img is None:
        raise DecodeError(buf.size)
    if img.dtype != np.uint8:
        img = cv2.convertScaleAbs(img, alpha=255.0 / max(float(img.max()), 1.0))
    return encode(np.ascontiguousarray(img), "jpeg", quality)
