"""Decode only parts of a JPEG: the restart-interval segments that cover given pixels.

A baseline JPEG written with a restart interval of ``k`` MCUs (``DRI``; beambench's own
capture writes one, :data:`RST_INTERVAL_MCU`) is a chain of self-contained segments: each
starts byte-aligned after an ``RSTn`` marker with the DC predictors reset, so any set of
them, renumbered ``RST0..7`` in turn, is itself a valid entropy-coded scan. Here the
selected segments of a single-component (gray) JPEG are spliced into a smaller baseline
JPEG, ``k`` MCUs wide and one MCU row per segment (the frame header's size changed, the
tables and ``DRI`` kept), decoded by OpenCV like any other JPEG and put back in place.
A gray JPEG's blocks are decoded independently (no chroma upsampling, no smoothing in a
baseline scan), so the pixels come out bit for bit as a full decode gives them.

A JPEG this cannot split (progressive, colour, no restart interval, segments that do not
tile the MCU rows, damaged markers) has no :class:`JpegLayout` (:func:`jpeg_layout`
returns None); callers then decode it whole (:func:`vision.codec.decode`), which reports
damaged bytes as its errors do.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Iterator
from dataclasses import dataclass
from functools import cached_property

import cv2
import numpy as np
from numpy.typing import NDArray

from vision.codec import MAX_SIDE_PX, RST_INTERVAL_MCU
from vision.errors import DecodeError, ParameterError

_MCU_PX = 8  # a single-component scan's MCU is one 8 x 8 block
# the spliced JPEG's height is a 16-bit field: at most this many segments in one splice
_MAX_SEGMENTS = 65535 // _MCU_PX
_EOI = b"\xff\xd9"
#: A splice's rows are about this wide (px): several narrow segments side by side.
_ROW_PX = 1024


@dataclass(frozen=True, eq=False)
class JpegLayout:
    """Where a gray baseline JPEG's restart segments lie: ``starts[i]`` / ``ends[i]`` are
    the byte offsets of segment ``i``'s entropy-coded data (markers excluded), segments in
    raster order of ``interval`` MCUs each, ``per_row`` to an MCU row."""

    data: bytes
    width_px: int
    height_px: int
    interval: int
    per_row: int
    mcu_rows: int
    header: bytes  # SOI to the end of the SOS header, the frame size to be rewritten
    sof_size_at: int  # offset in ``header`` of the frame header's height (then width)
    starts: NDArray[np.intp]
    ends: NDArray[np.intp]

    @cached_property
    def starts_list(self) -> list[int]:
        """``starts`` as a list (for callers that index it segment by segment)."""
        return list(self.starts.tolist())

    @cached_property
    def ends_list(self) -> list[int]:
        """``ends`` as a list."""
        return list(self.ends.tolist())

    @property
    def segment_px(self) -> tuple[int, int]:
        """(width, height) of one segment, px."""
        return self.interval * _MCU_PX, _MCU_PX


def jpeg_layout(data: bytes) -> JpegLayout | None:
    """The segment layout of ``data``, or None when it cannot be decoded in parts (not a
    JPEG, not baseline, not one component, no restart interval, an interval that does
    not divide the MCU row, restart markers missing, out of order or damaged)."""
    if data[:2] != b"\xff\xd8":
        return None
    i = 2
    interval = 0
    size: tuple[int, int] | None = None
    sof_at = -1
    n = len(data)
    while True:
        while i < n and data[i] == 0xFF and i + 1 < n and data[i + 1] == 0xFF:
            i += 1  # fill bytes
        if i + 4 > n or data[i] != 0xFF:
            return None
        marker = data[i + 1]
        (length,) = struct.unpack(">H", data[i + 2 : i + 4])
        if length < 2 or i + 2 + length > n:
            return None
        body = data[i + 4 : i + 2 + length]
        if marker in (0xC0, 0xC1):  # baseline / extended sequential, Huffman
            if len(body) < 6 or body[5] != 1:
                return None  # not a single component
            height, width = struct.unpack(">HH", body[1:5])
            size = (width, height)
            sof_at = i + 5
        elif marker in (0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF):
            return None  # progressive, lossless, hierarchical or arithmetic coded
        elif marker == 0xDD:
            if len(body) != 2:
                return None
            (interval,) = struct.unpack(">H", body)
        elif marker == 0xDA:
            scan_at = i + 2 + length
            break
        elif marker in (0xD8, 0xD9, *range(0xD0, 0xD8)):
            return None
        i += 2 + length
    if size is None or interval == 0:
        return None
    width, height = size
    if not 0 < width <= MAX_SIDE_PX or not 0 < height <= MAX_SIDE_PX:
        return None
    mcu_cols = math.ceil(width / _MCU_PX)
    mcu_rows = math.ceil(height / _MCU_PX)
    if mcu_cols % interval:
        return None
    per_row = mcu_cols // interval
    n_seg = per_row * mcu_rows
    # Every 0xFF in entropy-coded data is followed by 0x00 (stuffing), a restart marker
    # or the marker that ends the scan.
    buf = np.frombuffer(data, dtype=np.uint8)
    ff = np.flatnonzero(buf[scan_at:-1] == 0xFF) + scan_at
    marks = ff[buf[ff + 1] != 0]
    kinds = buf[marks + 1]
    is_rst = (kinds & 0xF8) == 0xD0
    end_of_scan = np.flatnonzero(~is_rst)
    if end_of_scan.size == 0 or kinds[end_of_scan[0]] != 0xD9:
        return None  # the scan must end at EOI (one scan: baseline gray)
    rst = marks[: end_of_scan[0]]
    if rst.size != n_seg - 1:
        return None
    numbers = kinds[: rst.size]  # each RSTn: 0xD0..0xD7 in turn from RST0
    if rst.size and (numbers[0] != 0xD0 or np.any(((numbers[1:] - numbers[:-1]) & 7) != 1)):
        return None
    stop = int(marks[end_of_scan[0]])
    starts = np.empty(n_seg, dtype=np.intp)
    starts[0] = scan_at
    starts[1:] = rst + 2
    ends = np.empty(n_seg, dtype=np.intp)
    ends[:-1] = rst
    ends[-1] = stop
    return JpegLayout(
        data=data,
        width_px=width,
        height_px=height,
        interval=interval,
        per_row=per_row,
        mcu_rows=mcu_rows,
        header=data[:scan_at],
        sof_size_at=sof_at,
        starts=starts,
        ends=ends,
    )


def segments_covering(layout: JpegLayout, mask_px: NDArray[np.bool_]) -> NDArray[np.intp]:
    """The segments (raster indices) holding any True pixel of a [row, col] mask the
    image's size."""
    if mask_px.shape != (layout.height_px, layout.width_px):
        raise ParameterError(
            "mask_px", f"must be {layout.height_px} x {layout.width_px}, got {mask_px.shape}"
        )
    pad = np.zeros((layout.mcu_rows * _MCU_PX, layout.per_row * layout.interval * _MCU_PX), bool)
    pad[: layout.height_px, : layout.width_px] = mask_px
    blocks = np.asarray(pad.reshape(layout.mcu_rows, _MCU_PX, -1, _MCU_PX).any(axis=(1, 3)))
    return segments_of_blocks(layout, blocks)


def segments_of_blocks(layout: JpegLayout, blocks: NDArray[np.bool_]) -> NDArray[np.intp]:
    """The segments (raster indices) holding any True 8 x 8 block of a [block row, block
    col] mask (``ceil(height / 8)`` x ``ceil(width / 8)``)."""
    return np.flatnonzero(segment_hits(layout, blocks))


def segment_hits(layout: JpegLayout, blocks: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """Per segment (raster order), whether it holds any True block of a [block row,
    block col] mask (``ceil(height / 8)`` x ``ceil(width / 8)``)."""
    shape = (layout.mcu_rows, layout.per_row * layout.interval)
    if blocks.shape != shape:
        raise ParameterError("blocks", f"must be {shape[0]} x {shape[1]}, got {blocks.shape}")
    per_seg = np.ascontiguousarray(blocks, dtype=bool).reshape(shape[0] * layout.per_row, -1)
    k = layout.interval
    if k % 8 == 0:  # a segment's flags as 64-bit words, OR-ed column by column (numpy's
        # reduction along a short axis costs ten times more)
        words = per_seg.view(np.uint64)
        acc = words[:, 0].copy()
        for j in range(1, k // 8):
            acc |= words[:, j]
        return acc != 0
    if k in _UINT_OF_BYTES:
        return per_seg.view(_UINT_OF_BYTES[k]).ravel() != 0
    return np.asarray(per_seg.any(axis=1))


_UINT_OF_BYTES = {1: np.uint8, 2: np.uint16, 4: np.uint32}


def splice(layout: JpegLayout, segments: NDArray[np.intp]) -> bytes:
    """A baseline JPEG of the given segments (ascending raster indices), one MCU row each,
    ``interval`` MCUs wide."""
    return bytes(_splice(layout, segments))


def _splice(layout: JpegLayout, segments: NDArray[np.intp], across: int = 1) -> bytearray:
    """:func:`splice`, ``across`` segments to a row (``len(segments)`` a multiple)."""
    seg_w, seg_h = layout.segment_px
    seg = np.asarray(segments, dtype=np.intp)
    n = len(seg)
    if not 0 < n <= _MAX_SEGMENTS * across or n % across:
        raise ParameterError(
            "segments", f"must number 1..{_MAX_SEGMENTS * across}, {across} to a row, got {n}"
        )
    head = bytearray(layout.header)
    struct.pack_into(">HH", head, layout.sof_size_at, n // across * seg_h, across * seg_w)
    # Runs of consecutive segments are one stretch of the scan each, their restart
    # markers in it; every segment after the first follows its marker (two bytes),
    # renumbered RST0..7 in the splice's order once the bytes are joined.
    brk = np.flatnonzero(seg[1:] != seg[:-1] + 1) + 1
    lo = layout.starts[seg[np.concatenate(([0], brk))]] - 2
    lo[0] += 2
    hi = layout.ends[seg[np.concatenate((brk - 1, [n - 1]))]]
    scan = memoryview(layout.data)
    out = bytearray().join(
        [head, *[scan[a:b] for a, b in zip(lo.tolist(), hi.tolist(), strict=True)], _EOI]
    )
    if n > 1:
        lens = layout.ends[seg[:-1]] - layout.starts[seg[:-1]]
        at = len(head) + np.cumsum(lens) + 2 * np.arange(1, n) - 1
        np.frombuffer(out, dtype=np.uint8)[at] = 0xD0 + (np.arange(n - 1) & 7)
    return out


def _decoded(
    layout: JpegLayout, segments: NDArray[np.intp]
) -> Iterator[tuple[NDArray[np.intp], NDArray[np.uint8]]]:
    """The given segments decoded, as ``(segments', pixels (rows, across, 8, 8 *
    interval))`` per splice: each splice's rows hold ``across`` segments side by side
    (about :data:`_ROW_PX` wide: the decoder's cost per output line, not per segment,
    is what narrow segments one to a row pay for), the last row filled up with its
    last segment again; ``segments'`` in the pixels' order, so padded too."""
    seg_w, seg_h = layout.segment_px
    segments = np.asarray(segments, dtype=np.intp)
    across = max(1, _ROW_PX // seg_w)
    per_splice = _MAX_SEGMENTS * across
    for k in range(0, len(segments), per_splice):
        part = segments[k : k + per_splice]
        a = min(across, len(part))
        pad = -len(part) % a
        if pad:
            part = np.concatenate((part, np.full(pad, part[-1], dtype=np.intp)))
        rows = len(part) // a
        img = _imdecode(_splice(layout, part, a))
        if img.shape != (rows * seg_h, a * seg_w):
            raise DecodeError(len(layout.data))
        yield part, img.reshape(rows, seg_h, a, seg_w).transpose(0, 2, 1, 3)


def decode_segments(layout: JpegLayout, segments: NDArray[np.intp]) -> NDArray[np.uint8]:
    """The given segments (ascending raster indices) decoded, one 8-pixel row each:
    ``(8 * len(segments), 8 * interval)``. Raises :class:`~vision.errors.DecodeError`
    when they do not decode."""
    seg_w, seg_h = layout.segment_px
    # only the last splice is padded: its extra segments are cut off the end
    parts = [pixels.reshape(-1, seg_h, seg_w) for _, pixels in _decoded(layout, segments)]
    if not parts:
        return np.zeros((0, seg_w), np.uint8)
    out = parts[0] if len(parts) == 1 else np.concatenate(parts)
    return out[: len(segments)].reshape(-1, seg_w)


def decode_into(layout: JpegLayout, canvas: NDArray[np.uint8], segments: NDArray[np.intp]) -> None:
    """Decode the given segments (ascending raster indices) into their place in a
    :func:`blank_canvas` (in place; what is there already stays where no segment is
    given). Raises :class:`~vision.errors.DecodeError` when they do not decode."""
    grid = _grid(layout, canvas)
    for part, pixels in _decoded(layout, segments):
        at = part.reshape(pixels.shape[:2])
        grid[at // layout.per_row, at % layout.per_row] = pixels


def _grid(layout: JpegLayout, canvas: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """A canvas as [segment row, segment col, row, col] (a view)."""
    seg_w, seg_h = layout.segment_px
    if canvas.shape != (layout.mcu_rows * seg_h, layout.per_row * seg_w):
        raise ParameterError("canvas", f"must be the layout's blank_canvas, got {canvas.shape}")
    return canvas.reshape(layout.mcu_rows, seg_h, layout.per_row, seg_w).transpose(0, 2, 1, 3)


def blank_canvas(layout: JpegLayout, fill: int) -> NDArray[np.uint8]:
    """An image to :func:`paste` segments into: the JPEG's MCU rows and columns (its size
    rounded up to whole segments), every pixel ``fill``."""
    seg_w, seg_h = layout.segment_px
    return np.full((layout.mcu_rows * seg_h, layout.per_row * seg_w), fill, dtype=np.uint8)


def paste(
    layout: JpegLayout,
    canvas: NDArray[np.uint8],
    segments: NDArray[np.intp],
    strip: NDArray[np.uint8],
) -> None:
    """Put decoded segments (:func:`decode_segments`) in their place in a
    :func:`blank_canvas` (in place)."""
    seg_w, seg_h = layout.segment_px
    grid = _grid(layout, canvas)
    segments = np.asarray(segments, dtype=np.intp)
    grid[segments // layout.per_row, segments % layout.per_row] = strip.reshape(
        len(segments), seg_h, seg_w
    )


def image_of(layout: JpegLayout, canvas: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """The image's own size cut from a canvas (the canvas itself when it is that size)."""
    if canvas.shape == (layout.height_px, layout.width_px):
        return canvas
    return np.ascontiguousarray(canvas[: layout.height_px, : layout.width_px])


def decode_region(layout: JpegLayout, segments: NDArray[np.intp], fill: int) -> NDArray[np.uint8]:
    """The full-size [row, col] image with the given segments decoded in place and every
    other pixel ``fill``."""
    canvas = blank_canvas(layout, fill)
    decode_into(layout, canvas, segments)
    return image_of(layout, canvas)


def decode_reduced(data: bytes, reduction: int) -> NDArray[np.uint8]:
    """A JPEG decoded at 1/``reduction`` (2, 4 or 8) of its width and height by libjpeg's
    DCT scaling; pixel ``(x, y)`` shows ``(reduction * (x + 0.5) - 0.5, ...)`` of the
    full image. Raises :class:`~vision.errors.DecodeError` when it does not decode."""
    flags = {
        2: cv2.IMREAD_REDUCED_GRAYSCALE_2,
        4: cv2.IMREAD_REDUCED_GRAYSCALE_4,
        8: cv2.IMREAD_REDUCED_GRAYSCALE_8,
    }
    if reduction not in flags:
        raise ParameterError("reduction", f"must be 2, 4 or 8, got {reduction!r}")
    return _imdecode(data, flags[reduction])


def _imdecode(data: bytes | bytearray, flags: int = cv2.IMREAD_GRAYSCALE) -> NDArray[np.uint8]:
    buf = np.frombuffer(data, dtype=np.uint8)
    level = cv2.utils.logging.getLogLevel()
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_ERROR)
    try:
        img = cv2.imdecode(buf, flags) if buf.size else None
    finally:
        cv2.utils.logging.setLogLevel(level)
    if img is None or img.dtype != np.uint8 or img.ndim != 2:
        raise DecodeError(buf.size)
    return np.asarray(img, dtype=np.uint8)


__all__ = [
    "RST_INTERVAL_MCU",
    "JpegLayout",
    "blank_canvas",
    "decode_into",
    "decode_reduced",
    "decode_region",
    "decode_segments",
    "image_of",
    "jpeg_layout",
    "paste",
    "segment_hits",
    "segments_covering",
    "segments_of_blocks",
    "splice",
]
