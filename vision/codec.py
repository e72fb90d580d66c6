"""The image codec: uint8 gray [row, col] images to JPEG/PNG bytes and back.

:func:`encode` is what the synthetic camera sends; :func:`decode` reads any format
OpenCV reads (what a real camera or a folder of stills gives).
"""

from __future__ import annotations

import struct
import zlib

import cv2
import numpy as np
from numpy.typing import NDArray

from vision.errors import (
    CorruptImageError,
    DecodeError,
    EncodeError,
    ImageSizeError,
    ParameterError,
)

# the largest image decoded (a side, px): the largest camera sensors (16k); a 16384 x 16384
# gray image is 268 MB, so a forged header cannot make the decoder allocate more
MAX_SIDE_PX = 16384

#: The restart interval :func:`encode` writes into JPEGs (MCUs per segment; 4 MCUs are
#: 32 px of one 8-pixel row of a gray image, a 2048 px row 64 segments), so that the
#: parts of a frame that are measured can be decoded alone (:mod:`vision.jpeg_regions`).
#: The markers cost 2 bytes, the padding to a byte boundary and the DC restarting each:
#: a nominal 2048 x 1536 frame at quality 90 is 360 kB (326 kB at 16 MCUs, 314 without);
#: the reader decodes 21 % of its segments (28 % at 16 MCUs: the search circles' segments
#: alone are 10 % of the frame at 16, 3 % at 4). 4 divides by the previews' reductions.
RST_INTERVAL_MCU = 4

_PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
# JPEG start-of-frame markers (baseline, progressive, lossless, ...): not DHT, JPG or DAC
_SOF = {0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF}


def check_png(data: bytes) -> None:
    """Verify a PNG's chunks (each CRC, the closing IEND) before the decoder sees them:
    libpng reports damage on the process's stderr and may decode what it can."""
    i = 8
    while True:
        if i + 12 > len(data):
            raise CorruptImageError(f"the PNG ends at byte {len(data)} before its IEND chunk")
        (length,) = struct.unpack(">I", data[i : i + 4])
        kind = data[i + 4 : i + 8].decode("latin-1")
        end = i + 8 + length
        if end + 4 > len(data):
            raise CorruptImageError(
                f"the PNG's {kind} chunk at byte {i} runs past the end ({len(data)} bytes)"
            )
        (crc,) = struct.unpack(">I", data[end : end + 4])
        if zlib.crc32(data[i + 4 : end]) != crc:
            raise CorruptImageError(f"the PNG's {kind} chunk at byte {i} fails its CRC")
        if kind == "IEND":
            return
        i = end + 4


def header_size_px(data: bytes) -> tuple[int, int] | None:
    """``(width, height)`` from a PNG or JPEG header without decoding, or None when the
    bytes are neither (or the header is cut short)."""
    if data[:8] == _PNG_MAGIC and len(data) >= 24 and data[12:16] == b"IHDR":
        width, height = struct.unpack(">II", data[16:24])
        return int(width), int(height)
    if data[:2] != b"\xff\xd8":
        return None
    i = 2
    while i + 4 <= len(data):
        if data[i] != 0xFF:
            return None
        marker = data[i + 1]
        if marker == 0xFF:  # fill byte
            i += 1
            continue
        if marker in (0x01, *range(0xD0, 0xD8)):  # markers without a length
            i += 2
            continue
        (length,) = struct.unpack(">H", data[i + 2 : i + 4])
        if marker in _SOF:
            if i + 9 > len(data):
                return None
            height, width = struct.unpack(">HH", data[i + 5 : i + 9])
            return int(width), int(height)
        if length < 2:
            return None
        i += 2 + length
    return None


def decode(data: bytes) -> NDArray[np.uint8]:
    """Decode compressed image bytes to a uint8 gray [row, col] array.

    Raises :class:`~vision.errors.DecodeError` (a ``ValueError``) when the bytes are not
    a readable image.
    """
    if not isinstance(data, bytes | bytearray | memoryview):
        raise TypeError(f"data must be bytes, got {type(data).__name__}")
    raw = bytes(data)
    buf = np.frombuffer(raw, dtype=np.uint8)
    if buf.size == 0:
        raise DecodeError(0)
    size = header_size_px(raw)
    if size is not None and max(size) > MAX_SIDE_PX:
        raise ImageSizeError(size[0], size[1], MAX_SIDE_PX)
    if raw[:8] == _PNG_MAGIC:
        check_png(raw)
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


def encode(
    image: NDArray[np.uint8],
    encoding: str = "jpeg",
    quality: int = 90,
    restart_interval_mcu: int = RST_INTERVAL_MCU,
) -> bytes:
    """Compress a uint8 gray [row, col] image as JPEG (``quality`` 1-100; a restart
    marker every ``restart_interval_mcu`` MCUs, 0 for none) or PNG."""
    if not isinstance(image, np.ndarray) or image.dtype != np.uint8 or image.ndim != 2:
        raise TypeError("image must be a uint8 [row, col] numpy array")
    if encoding == "jpeg":
        if not 1 <= quality <= 100:
            raise ParameterError("quality", f"must be in 1..100, got {quality!r}")
        if not 0 <= restart_interval_mcu <= 65535:
            raise ParameterError(
                "restart_interval_mcu", f"must be in 0..65535, got {restart_interval_mcu!r}"
            )
        params = [cv2.IMWRITE_JPEG_QUALITY, int(quality)]
        if restart_interval_mcu:
            params += [cv2.IMWRITE_JPEG_RST_INTERVAL, int(restart_interval_mcu)]
        ok, buf = cv2.imencode(".jpg", image, params)
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
