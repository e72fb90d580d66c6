"""Size of an encoded JPEG or PNG from its header, without decoding the pixels."""

from __future__ import annotations

import struct

from daq.errors import DaqInputError

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_SOF_MARKERS = {0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF}


def image_encoding(data: bytes) -> str | None:
    """``"jpeg"``, ``"png"`` or ``None`` from the file signature."""
    if data[:8] == PNG_SIGNATURE:
        return "png"
    if data[:2] == b"\xff\xd8":
        return "jpeg"
    return None


def image_size_px(data: bytes) -> tuple[int, int]:
    """``(width_px, height_px)`` of a JPEG or PNG; ``DaqInputError`` (a ``ValueError``)
    if it is neither."""
    kind = image_encoding(data)
    if kind == "png":
        if len(data) < 24 or data[12:16] != b"IHDR":
            raise DaqInputError("data: PNG without an IHDR chunk")
        width, height = struct.unpack(">II", data[16:24])
        return int(width), int(height)
    if kind == "jpeg":
        i = 2
        n = len(data)
        while i + 4 <= n:
            if data[i] != 0xFF:
                raise DaqInputError(f"data: corrupt JPEG marker at byte {i}")
            marker = data[i + 1]
            if marker == 0xFF:  # fill byte
                i += 1
                continue
            if marker in (0xD8, 0x01) or 0xD0 <= marker <= 0xD7:
                i += 2
                continue
            (length,) = struct.unpack(">H", data[i + 2 : i + 4])
            if marker in _SOF_MARKERS:
                if i + 9 > n:
                    break
                height, width = struct.unpack(">HH", data[i + 5 : i + 9])
                return int(width), int(height)
            i += 2 + length
        raise DaqInputError("data: JPEG without a frame header (SOF)")
    raise DaqInputError("data: not a JPEG or PNG image")
