"""Capture time of a still from its EXIF DateTimeOriginal (JPEG APP1), pure Python."""

from __future__ import annotations

import struct
from datetime import datetime

_TAG_EXIF_IFD = 0x8769
_TAG_DATETIME = 0x0132
_TAG_DATETIME_ORIGINAL = 0x9003
_TAG_SUBSEC_ORIGINAL = 0x9291


def _exif_block(data: bytes) -> bytes | None:
    if data[:2] != b"\xff\xd8":
        return None
    i = 2
    while i + 4 <= len(data) and data[i] == 0xFF:
        marker = data[i + 1]
        if marker in (0xDA, 0xD9):  # start of scan / end: no more metadata
            return None
        (length,) = struct.unpack(">H", data[i + 2 : i + 4])
        if marker == 0xE1 and data[i + 4 : i + 10] == b"Exif\x00\x00":
            return data[i + 10 : i + 2 + length]
        i += 2 + length
    return None


def _ifd(tiff: bytes, offset: int, endian: str) -> dict[int, tuple[int, int, bytes]]:
    (count,) = struct.unpack(endian + "H", tiff[offset : offset + 2])
    entries = {}
    for k in range(count):
        e = offset + 2 + 12 * k
        tag, typ, n = struct.unpack(endian + "HHI", tiff[e : e + 8])
        entries[tag] = (typ, n, tiff[e + 8 : e + 12])
    return entries


def _ascii(tiff: bytes, entry: tuple[int, int, bytes], endian: str) -> str:
    typ, n, raw = entry
    if typ != 2:
        raise ValueError("EXIF: expected an ASCII field")
    if n <= 4:
        text = raw[:n]
    else:
        (off,) = struct.unpack(endian + "I", raw)
        text = tiff[off : off + n]
    return text.split(b"\x00")[0].decode("ascii").strip()


def exif_datetime_original(data: bytes) -> datetime | None:
    """``DateTimeOriginal`` (+ ``SubSecTimeOriginal``) of a JPEG as a naive local
    ``datetime`` (EXIF stores no time zone), or ``None`` if absent or unreadable."""
    tiff = _exif_block(data)
    if tiff is None or len(tiff) < 8:
        return None
    try:
        endian = {b"II": "<", b"MM": ">"}[tiff[:2]]
        (ifd0,) = struct.unpack(endian + "I", tiff[4:8])
        entries = _ifd(tiff, ifd0, endian)
        text, subsec = None, ""
        if _TAG_EXIF_IFD in entries:
            (exif_off,) = struct.unpack(endian + "I", entries[_TAG_EXIF_IFD][2])
            sub = _ifd(tiff, exif_off, endian)
            if _TAG_DATETIME_ORIGINAL in sub:
                text = _ascii(tiff, sub[_TAG_DATETIME_ORIGINAL], endian)
            if _TAG_SUBSEC_ORIGINAL in sub:
                subsec = _ascii(tiff, sub[_TAG_SUBSEC_ORIGINAL], endian)
        if text is None and _TAG_DATETIME in entries:
            text = _ascii(tiff, entries[_TAG_DATETIME], endian)
        if not text:
            return None
        when = datetime.strptime(text, "%Y:%m:%d %H:%M:%S")
        if subsec.isdigit():
            when = when.replace(microsecond=int((subsec + "000000")[:6]))
        return when
    except (KeyError, ValueError, struct.error, UnicodeDecodeError):
        return None
