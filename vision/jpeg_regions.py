"""Decode only parts of a JPEG: the restart-interval segments that cover given pixels.

A baseline JPEG written with a restart interval of ``k`` MCUs (``DRI``; beambench's own
capture writes one, :data:`RST_INTERVAL_MCU`) is a chain of self-contained segments: each
starts byte-aligned after an ``RSTn`` marker with the DC predictors reset, so any set of
them, renumbered ``RST0..7`` in turn, is itself a valid entropy-coded scan. Here the
selected segments are spliced into a smaller baseline JPEG, ``k`` MCUs wide and one MCU
row per segment (the frame header's size changed, the tables and ``DRI`` kept), decoded
by OpenCV like any other JPEG and put back in place.

The JPEG may be gray (one component: an MCU is one 8 x 8 block) or YCbCr colour (three
components in one interleaved scan, Y sampled ``H x V`` with H, V in {1, 2} and Cb, Cr
1 x 1: 4:4:4, 4:2:2, 4:2:0, 4:4:0; an MCU is ``8H x 8V`` pixels, ``H x V`` Y blocks and
one of each chroma), as a colour camera's JPEGs are (``daq/drivers/opencv_camera.py``).
Decoded gray (``IMREAD_GRAYSCALE`` and its reduced forms, as :func:`vision.codec.decode`),
a YCbCr JPEG is its Y component alone: libjpeg neither upsamples nor converts the chroma,
and the Y blocks, like a gray JPEG's, are decoded independently (no smoothing in a
baseline scan), so the pixels come out bit for bit as a full decode gives them.

A JPEG this cannot split (progressive, CMYK or other component counts, RGB or
unusual sampling, several scans, no restart interval, segments that do not tile the MCU
rows, damaged markers) has no :class:`JpegLayout` (:func:`jpeg_layout` returns None);
callers then decode it whole (:func:`vision.codec.decode`), which reports damaged bytes
as its errors do.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from vision.codec import MAX_SIDE_PX, RST_INTERVAL_MCU
from vision.errors import DecodeError, ParameterError
from vision.jit import kernel

_BLOCK_PX = 8  # a DCT block's side; a gray scan's MCU is one block
# the spliced JPEG's height is a 16-bit field: at most this many segments in one splice
# (of one block's height; of an MCU twice as tall, half as many: _max_segments)
_MAX_SEGMENTS = 65535 // _BLOCK_PX
#: A splice's rows are about this wide (px): several narrow segments side by side.
_ROW_PX = 1024
#: A de Bruijn sequence of 64 bits: the top six bits of ``2**i`` times it differ for each
#: ``i``, :data:`_BIT_OF` maps them back to ``i`` (a 64-bit word's lowest set bit).
_DEBRUIJN = 0x03F79D71B4CB0A89
_BIT_OF = np.zeros(64, dtype=np.uint8)
_BIT_OF[[((_DEBRUIJN << i) & (2**64 - 1)) >> 58 for i in range(64)]] = np.arange(64)


@dataclass(frozen=True, eq=False)
class JpegLayout:
    """Where a baseline JPEG's restart segments lie: ``starts[i]`` / ``ends[i]`` are the
    byte offsets of segment ``i``'s entropy-coded data (markers excluded), segments in
    raster order of ``interval`` MCUs each, ``per_row`` to an MCU row; an MCU is
    ``mcu_w_px x mcu_h_px`` (8 x 8 gray; 8H x 8V of a YCbCr JPEG whose Y is sampled
    H x V)."""

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
    mcu_w_px: int = _BLOCK_PX
    mcu_h_px: int = _BLOCK_PX

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
        """(width, height) of one segment, px: ``interval`` MCUs by one."""
        return self.interval * self.mcu_w_px, self.mcu_h_px

    @property
    def blocks_shape(self) -> tuple[int, int]:
        """(rows, columns) of the 8 x 8 blocks of the MCU grid (the image's size rounded
        up to whole MCUs): the shape of the block masks :func:`segment_hits` takes (for
        a gray JPEG ``ceil(height / 8) x ceil(width / 8)``)."""
        return (
            self.mcu_rows * self.mcu_h_px // _BLOCK_PX,
            self.per_row * self.interval * self.mcu_w_px // _BLOCK_PX,
        )


def jpeg_layout(data: bytes) -> JpegLayout | None:
    """The segment layout of ``data``, or None when it cannot be decoded in parts (not a
    JPEG, not baseline, neither gray nor YCbCr with the sampling the module's notes
    name in one interleaved scan, no restart interval, an interval that does not divide
    the MCU row, restart markers missing, out of order or damaged)."""
    buf = np.frombuffer(data, dtype=np.uint8)
    _touch(buf)
    got = _parse_layout(buf, MAX_SIDE_PX)
    if got[0] == 0:
        return None
    width, height, interval, sof_at, scan_at, starts, ends, h, v = got
    mcu_w, mcu_h = _BLOCK_PX * h, _BLOCK_PX * v
    mcu_cols = (width + mcu_w - 1) // mcu_w
    return JpegLayout(
        data=data,
        width_px=width,
        height_px=height,
        interval=interval,
        per_row=mcu_cols // interval,
        mcu_rows=(height + mcu_h - 1) // mcu_h,
        header=data[:scan_at],
        sof_size_at=sof_at,
        starts=starts,
        ends=ends,
        mcu_w_px=mcu_w,
        mcu_h_px=mcu_h,
    )


@kernel
def _touch(buf: NDArray[np.uint8]) -> int:
    """A load of every 64-byte line of ``buf`` (their OR returned, so that none is left
    out): bytes not in the core's cache arrive many at once, before :func:`_parse_layout`
    reads them in a loop whose branches would wait on each in turn (half its time on a
    JPEG just read, or one the measurement of the last frame has pushed out of cache)."""
    words = buf[: buf.size // 8 * 8].view(np.uint64)
    acc = np.uint64(0)
    for i in range(0, words.size, 8):
        acc |= words[i]
    return int(acc & np.uint64(1))


@kernel
def _parse_layout(
    buf: NDArray[np.uint8], max_side: int
) -> tuple[int, int, int, int, int, NDArray[np.intp], NDArray[np.intp], int, int]:
    """:func:`jpeg_layout`'s parse: ``(width, height, interval, offset of the frame
    header's size, offset of the scan, starts, ends, H, V)`` (an MCU is ``H x V``
    blocks), width 0 when there is none. The markers before the scan one by one; then,
    in the entropy-coded data, every 0xFF is followed by 0x00 (stuffing), a restart
    marker or the marker that ends the scan, which must be EOI (one scan)."""
    none = np.zeros(0, np.intp)
    nothing = (0, 0, 0, 0, 0, none, none, 0, 0)
    n = buf.size
    if n < 2 or buf[0] != 0xFF or buf[1] != 0xD8:
        return nothing
    i = 2
    interval = 0
    width = height = 0
    have_size = False
    sof_at = -1
    scan_at = 0
    n_comp = 0
    h = v = 1
    id0 = id1 = id2 = 0
    adobe = -1  # an Adobe APP14 marker's colour transform (-2: one too short to say)
    while True:
        while i < n and buf[i] == 0xFF and i + 1 < n and buf[i + 1] == 0xFF:
            i += 1  # fill bytes
        if i + 4 > n or buf[i] != 0xFF:
            return nothing
        marker = int(buf[i + 1])
        length = int(buf[i + 2]) * 256 + int(buf[i + 3])
        if length < 2 or i + 2 + length > n:
            return nothing
        body = i + 4
        if marker == 0xC0 or marker == 0xC1:  # baseline / extended sequential, Huffman
            if length - 2 < 6:
                return nothing
            n_comp = int(buf[body + 5])
            if n_comp == 3:
                # YCbCr: 8-bit, Y sampled 1 or 2 either way, Cb and Cr once per MCU
                if length - 2 != 15 or buf[body] != 8:
                    return nothing
                id0, id1, id2 = int(buf[body + 6]), int(buf[body + 9]), int(buf[body + 12])
                h, v = int(buf[body + 7]) // 16, int(buf[body + 7]) % 16
                if h < 1 or h > 2 or v < 1 or v > 2:
                    return nothing
                if buf[body + 10] != 0x11 or buf[body + 13] != 0x11:
                    return nothing
            elif n_comp != 1:
                return nothing  # CMYK, two components, ...
            height = int(buf[body + 1]) * 256 + int(buf[body + 2])
            width = int(buf[body + 3]) * 256 + int(buf[body + 4])
            have_size = True
            sof_at = i + 5
        elif 0xC2 <= marker <= 0xCF and marker != 0xC4 and marker != 0xC8 and marker != 0xCC:
            return nothing  # progressive, lossless, hierarchical or arithmetic coded
        elif marker == 0xDD:
            if length - 2 != 2:
                return nothing
            interval = int(buf[body]) * 256 + int(buf[body + 1])
        elif marker == 0xEE:  # APP14: Adobe's says RGB (0), YCbCr (1) or YCCK (2)
            if (
                length - 2 >= 5
                and buf[body] == 0x41  # "Adobe"
                and buf[body + 1] == 0x64
                and buf[body + 2] == 0x6F
                and buf[body + 3] == 0x62
                and buf[body + 4] == 0x65
            ):
                adobe = int(buf[body + 11]) if length - 2 >= 12 else -2
        elif marker == 0xDA:
            if n_comp == 3:  # one scan of all three, in the frame's order
                if length - 2 != 10 or buf[body] != 3 or buf[body + 1] != id0:
                    return nothing
                if buf[body + 3] != id1 or buf[body + 5] != id2:
                    return nothing
            scan_at = i + 2 + length
            break
        elif 0xD0 <= marker <= 0xD9:  # RSTn, SOI, EOI
            return nothing
        i += 2 + length
    if not have_size or interval == 0:
        return nothing
    if n_comp == 3:
        # three components that libjpeg (libjpeg-turbo's and IJG's rules alike) takes
        # for YCbCr, decoded gray as Y alone: not RGB by the IDs "R", "G", "B", not IJG's
        # big-gamut YCC (IDs 1, 0x22, 0x23), no Adobe marker saying anything but YCbCr
        if id0 == 0x52 and id1 == 0x47 and id2 == 0x42:
            return nothing
        if id0 == 1 and id1 == 0x22 and id2 == 0x23:
            return nothing
        if adobe != -1 and adobe != 1:
            return nothing
    else:
        h = v = 1  # one component: an MCU is one block, whatever its sampling factors
    if not 0 < width <= max_side or not 0 < height <= max_side:
        return nothing
    mcu_w = 8 * h
    mcu_h = 8 * v
    mcu_cols = (width + mcu_w - 1) // mcu_w
    mcu_rows = (height + mcu_h - 1) // mcu_h
    if mcu_cols % interval:
        return nothing
    n_seg = mcu_cols // interval * mcu_rows
    # Every 0xFF after the scan's header is followed by 0x00 (stuffing), RSTn (0xD0..0xD7
    # in turn from RST0) or the scan's end, which must be EOI. The data is read 64 bytes
    # at a time: the 0xFF bytes of each little-endian word found at once (the zero bytes
    # of its complement, exactly: bit 8j + 7 set where byte j is 0xFF), gathered into one
    # bit a byte (a multiplication moves bit 8j to bit 56 + j, no two products overlap)
    # and taken in order, the lowest first (its index by a de Bruijn sequence). The
    # markers come at random, ~one every 30 bytes: branching byte by byte, or word by
    # word, costs more in mispredicted branches than the work (a 64-byte block holds ~2;
    # half the time of the word-by-word loop this replaced).
    starts = np.empty(n_seg, dtype=np.intp)
    ends = np.empty(n_seg, dtype=np.intp)
    starts[0] = scan_at
    n_rst = 0
    stop = -1
    n_blk = n // 64
    words = buf[: 64 * n_blk].view(np.uint64)
    low7 = np.uint64(0x7F7F7F7F7F7F7F7F)
    gather = np.uint64(0x0102040810204080)
    debruijn = np.uint64(_DEBRUIJN)
    first = scan_at // 64
    for b in range(first, n_blk + 1):
        ff = np.uint64(0)  # bit j: byte 64 b + j is 0xFF
        if b < n_blk:
            for i in range(8):
                x = ~words[8 * b + i]
                w = ~(((x & low7) + low7) | x | low7) >> np.uint64(7)
                ff |= ((w * gather) >> np.uint64(56)) << np.uint64(8 * i)
        else:  # the last bytes, short of a block
            for j in range(n - 64 * b):
                if buf[64 * b + j] == 0xFF:
                    ff |= np.uint64(1) << np.uint64(j)
        if b == first:  # the scan's header and what precedes it
            ff &= ~np.uint64(0) << np.uint64(scan_at - 64 * b)
        while ff:
            p = 64 * b + int(_BIT_OF[((ff & (~ff + np.uint64(1))) * debruijn) >> np.uint64(58)])
            ff &= ff - np.uint64(1)
            if p >= n - 1:
                continue
            kind = int(buf[p + 1])
            if kind == 0:
                continue
            if kind != 0xD0 + (n_rst & 7):  # not the next RSTn
                if kind & 0xF8 == 0xD0 or kind != 0xD9:
                    return nothing
                stop = p
                break
            if n_rst == n_seg - 1:
                return nothing
            ends[n_rst] = p
            n_rst += 1
            starts[n_rst] = p + 2
        if stop >= 0:
            break
    if stop < 0 or n_rst != n_seg - 1:
        return nothing
    ends[n_seg - 1] = stop
    return width, height, interval, sof_at, scan_at, starts, ends, h, v


def segments_covering(layout: JpegLayout, mask_px: NDArray[np.bool_]) -> NDArray[np.intp]:
    """The segments (raster indices) holding any True pixel of a [row, col] mask the
    image's size."""
    if mask_px.shape != (layout.height_px, layout.width_px):
        raise ParameterError(
            "mask_px", f"must be {layout.height_px} x {layout.width_px}, got {mask_px.shape}"
        )
    rows, cols = layout.blocks_shape
    pad = np.zeros((rows * _BLOCK_PX, cols * _BLOCK_PX), bool)
    pad[: layout.height_px, : layout.width_px] = mask_px
    blocks = np.asarray(pad.reshape(rows, _BLOCK_PX, cols, _BLOCK_PX).any(axis=(1, 3)))
    return segments_of_blocks(layout, blocks)


def segments_of_blocks(layout: JpegLayout, blocks: NDArray[np.bool_]) -> NDArray[np.intp]:
    """The segments (raster indices) holding any True 8 x 8 block of a [block row, block
    col] mask (:attr:`JpegLayout.blocks_shape`)."""
    return np.flatnonzero(segment_hits(layout, blocks))


def segment_hits(layout: JpegLayout, blocks: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """Per segment (raster order), whether it holds any True block of a [block row,
    block col] mask (:attr:`JpegLayout.blocks_shape`: a segment is ``mcu_h_px / 8``
    block rows by ``interval * mcu_w_px / 8`` block columns)."""
    shape = layout.blocks_shape
    if blocks.shape != shape:
        raise ParameterError("blocks", f"must be {shape[0]} x {shape[1]}, got {blocks.shape}")
    flags = np.ascontiguousarray(blocks, dtype=bool)
    v = layout.mcu_h_px // _BLOCK_PX
    if v > 1:  # an MCU row's block rows OR-ed into one
        stacked = flags.reshape(layout.mcu_rows, v, shape[1])
        flags = stacked[:, 0].copy()
        for j in range(1, v):
            flags |= stacked[:, j]
    per_seg = flags.reshape(layout.mcu_rows * layout.per_row, -1)
    k = per_seg.shape[1]  # blocks to a segment's row
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
    return _splice(layout, segments).tobytes()


def _max_segments(layout: JpegLayout) -> int:
    """The most segments one above another in a splice (its height is a 16-bit field)."""
    return min(_MAX_SEGMENTS, 65535 // layout.mcu_h_px)


def _splice(layout: JpegLayout, segments: NDArray[np.intp], across: int = 1) -> NDArray[np.uint8]:
    """:func:`splice`, ``across`` segments to a row (``len(segments)`` a multiple)."""
    seg_w, seg_h = layout.segment_px
    seg = np.asarray(segments, dtype=np.intp)
    n = len(seg)
    most = _max_segments(layout) * across
    if not 0 < n <= most or n % across:
        raise ParameterError("segments", f"must number 1..{most}, {across} to a row, got {n}")
    out = _spliced(
        np.frombuffer(layout.data, dtype=np.uint8),
        layout.starts,
        layout.ends,
        seg,
        layout.sof_size_at,
        n // across * seg_h,
        across * seg_w,
    )
    if out.size == 0:
        raise ParameterError("segments", f"must be 0..{len(layout.starts) - 1}")
    return out


@kernel
def _spliced(
    data: NDArray[np.uint8],
    starts: NDArray[np.intp],
    ends: NDArray[np.intp],
    seg: NDArray[np.intp],
    sof_at: int,
    height_px: int,
    width_px: int,
) -> NDArray[np.uint8]:
    """The bytes of a splice: the header up to the scan (``starts[0]`` bytes) with the
    frame's size rewritten, each segment's data after an ``RSTn`` renumbered in the
    splice's order (0..7 in turn), EOI; empty when a segment is not one of the layout's."""
    n_all = starts.size
    head = starts[0]
    total = head + 2 * seg.size  # the restart markers and EOI
    for j in range(seg.size):
        if not 0 <= seg[j] < n_all:
            return np.zeros(0, dtype=np.uint8)
        total += ends[seg[j]] - starts[seg[j]]
    out = np.empty(total, dtype=np.uint8)
    for i in range(np.uint64(head)):  # unsigned offsets: see _put_segments
        out[i] = data[i]
    out[sof_at] = (height_px >> 8) & 0xFF
    out[sof_at + 1] = height_px & 0xFF
    out[sof_at + 2] = (width_px >> 8) & 0xFF
    out[sof_at + 3] = width_px & 0xFF
    o = head
    for j in range(seg.size):
        if j:
            out[o] = 0xFF
            out[o + 1] = 0xD0 + ((j - 1) & 7)
            o += 2
        a = np.uint64(starts[seg[j]])
        m = np.uint64(ends[seg[j]] - starts[seg[j]])
        at = np.uint64(o)
        for i in range(m):
            out[at + i] = data[a + i]
        o += ends[seg[j]] - starts[seg[j]]
    out[o] = 0xFF
    out[o + 1] = 0xD9
    return out


def _decoded(
    layout: JpegLayout, segments: NDArray[np.intp], reduction: int = 1
) -> Iterator[tuple[NDArray[np.intp], NDArray[np.uint8], int]]:
    """The given segments decoded (at 1/``reduction``: 1, or 2, 4, 8 by libjpeg's DCT
    scaling), as ``(segments', pixels, across)`` per splice: each splice's rows hold
    ``across`` segments side by side (about :data:`_ROW_PX` wide at full size: the
    decoder's cost per output line, not per segment, is what narrow segments one to a
    row pay for), the last row filled up with its last segment again; ``segments'`` in
    the pixels' order, so padded too."""
    flags = cv2.IMREAD_GRAYSCALE if reduction == 1 else _REDUCED_FLAGS[reduction]
    seg_w, seg_h = layout.segment_px
    out_w, out_h = seg_w // reduction, seg_h // reduction
    segments = np.asarray(segments, dtype=np.intp)
    across = max(1, _ROW_PX // seg_w)
    per_splice = _max_segments(layout) * across
    for k in range(0, len(segments), per_splice):
        part = segments[k : k + per_splice]
        a = min(across, len(part))
        pad = -len(part) % a
        if pad:
            part = np.concatenate((part, np.full(pad, part[-1], dtype=np.intp)))
        img = _imdecode(_splice(layout, part, a), flags)
        if img.shape != (len(part) // a * out_h, a * out_w):
            raise DecodeError(len(layout.data))
        yield part, img, a


def decode_segments(layout: JpegLayout, segments: NDArray[np.intp]) -> NDArray[np.uint8]:
    """The given segments (ascending raster indices) decoded, one MCU row each:
    ``(len(segments) * seg_h, seg_w)`` (:attr:`JpegLayout.segment_px`). Raises
    :class:`~vision.errors.DecodeError` when they do not decode."""
    seg_w, seg_h = layout.segment_px
    out = np.empty((len(segments) * seg_h, seg_w), dtype=np.uint8)
    done = 0
    for part, pixels, across in _decoded(layout, segments):
        # only the last splice is padded: its extra segments are not copied
        at = np.arange(done, min(done + len(part), len(segments)), dtype=np.intp)
        _put_segments(out, 1, at, pixels, across, seg_h, seg_w)
        done += len(at)
    return out


def decode_into(layout: JpegLayout, canvas: NDArray[np.uint8], segments: NDArray[np.intp]) -> None:
    """Decode the given segments (ascending raster indices) into their place in a
    :func:`blank_canvas` (in place; what is there already stays where no segment is
    given). Raises :class:`~vision.errors.DecodeError` when they do not decode."""
    _check_canvas(layout, canvas)
    seg_w, seg_h = layout.segment_px
    for part, pixels, across in _decoded(layout, segments):
        _put_segments(canvas, layout.per_row, part, pixels, across, seg_h, seg_w)


@kernel
def _put_segments(
    canvas: NDArray[np.uint8],
    per_row: int,
    at: NDArray[np.intp],
    pixels: NDArray[np.uint8],
    across: int,
    seg_h: int,
    seg_w: int,
) -> None:
    """Copy the segments of ``pixels`` (``across`` to a row, in raster order) to their
    places ``at`` in ``canvas`` (``per_row`` to a row), as many as ``at`` holds."""
    # Row by row over the flat arrays with unsigned offsets: no negative-index check per
    # byte, so the copy is vectorised (a slice assignment checks for overlap, slower); in
    # 8-byte words where the widths allow (a segment's row is 4 of them at beambench's
    # interval: a third less time than byte by byte, whose loop is vectorised for longer
    # rows than these).
    if seg_w % 8 == 0 and canvas.shape[1] % 8 == 0 and pixels.shape[1] % 8 == 0:
        _put_words(
            canvas.ravel().view(np.uint64),
            canvas.shape[1] // 8,
            per_row,
            at,
            pixels.ravel().view(np.uint64),
            pixels.shape[1] // 8,
            across,
            seg_h,
            seg_w // 8,
        )
        return
    _put_words(
        canvas.ravel(),
        canvas.shape[1],
        per_row,
        at,
        pixels.ravel(),
        pixels.shape[1],
        across,
        seg_h,
        seg_w,
    )


@kernel
def _put_words(
    dst: NDArray[Any],
    dst_w: int,
    per_row: int,
    at: NDArray[np.intp],
    src: NDArray[Any],
    src_w: int,
    across: int,
    seg_h: int,
    seg_w: int,
) -> None:
    """:func:`_put_segments` on the images as flat arrays of words (8-byte words, or
    bytes where the widths are no multiple of 8), ``dst_w``, ``src_w`` and ``seg_w`` of
    them to a row."""
    # a run of segments side by side in both (the next in raster order, in the same
    # row of each) is copied as one: rows the run's width (a band's rows are tens of
    # segments wide), the copy's loop long enough to be worth its vector form
    row_d = np.uint64(dst_w)
    row_s = np.uint64(src_w)
    j = 0
    while j < at.size:
        r0 = at[j] // per_row * seg_h
        c0 = at[j] % per_row * seg_w
        pr = j // across * seg_h
        pc = j % across * seg_w
        end = j + 1
        while (
            end < at.size
            and at[end] == at[end - 1] + 1
            and at[end] % per_row != 0
            and end % across != 0
        ):
            end += 1
        width = np.uint64((end - j) * seg_w)
        for y in range(seg_h):
            a = np.uint64(r0 + y) * row_d + np.uint64(c0)
            b = np.uint64(pr + y) * row_s + np.uint64(pc)
            for x in range(width):
                dst[a + x] = src[b + x]
        j = end


def _check_canvas(layout: JpegLayout, canvas: NDArray[np.uint8]) -> None:
    seg_w, seg_h = layout.segment_px
    if canvas.shape != (layout.mcu_rows * seg_h, layout.per_row * seg_w):
        raise ParameterError("canvas", f"must be the layout's blank_canvas, got {canvas.shape}")
    if not canvas.flags.c_contiguous or canvas.dtype != np.uint8:
        raise ParameterError("canvas", "must be a C-contiguous uint8 array (a blank_canvas)")


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
    _check_canvas(layout, canvas)
    seg = np.array(segments, dtype=np.intp)  # writable: one compiled form of the kernel
    if seg.size and not (0 <= seg.min() and seg.max() < len(layout.starts)):
        raise ParameterError("segments", f"must be 0..{len(layout.starts) - 1}")
    if strip.size != seg.size * seg_h * seg_w:
        raise ParameterError("strip", f"must hold {seg.size} segments of {seg_h} x {seg_w}")
    pixels = np.ascontiguousarray(strip, dtype=np.uint8).reshape(-1, seg_w)
    _put_segments(canvas, layout.per_row, seg, pixels, 1, seg_h, seg_w)


def fill_segments(
    layout: JpegLayout, canvas: NDArray[np.uint8], hit: NDArray[np.bool_], fill: int
) -> None:
    """Set the segments of a :func:`blank_canvas` where ``hit`` (one flag a segment, raster
    order) to ``fill`` (in place): a canvas used again is blanked where it was decoded, a
    fraction of a new one's cost."""
    seg_w, seg_h = layout.segment_px
    _check_canvas(layout, canvas)
    flags = np.asarray(hit)
    if flags.dtype != np.bool_ or flags.shape != (len(layout.starts),):
        raise ParameterError("hit", f"must be {len(layout.starts)} bools, got {flags.shape}")
    if not 0 <= fill <= 255:
        raise ParameterError("fill", f"must be 0..255, got {fill!r}")
    _fill_segments(canvas, layout.per_row, np.ascontiguousarray(flags), int(fill), seg_h, seg_w)


@kernel
def _fill_segments(
    canvas: NDArray[np.uint8],
    per_row: int,
    hit: NDArray[np.bool_],
    fill: int,
    seg_h: int,
    seg_w: int,
) -> None:
    """Set the segments where ``hit`` of ``canvas`` (``per_row`` to a row) to ``fill``,
    each run of them in a row at once."""
    value = np.uint8(fill)
    for row in range(hit.size // per_row):
        first = row * per_row
        j = 0
        while j < per_row:
            if not hit[first + j]:
                j += 1
                continue
            end = j + 1
            while end < per_row and hit[first + end]:
                end += 1
            for y in range(row * seg_h, row * seg_h + seg_h):
                canvas[y, j * seg_w : end * seg_w] = value  # a row's run: one memset
            j = end


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


def _imdecode(
    data: bytes | NDArray[np.uint8], flags: int = cv2.IMREAD_GRAYSCALE
) -> NDArray[np.uint8]:
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
    "fill_segments",
    "image_of",
    "jpeg_layout",
    "paste",
    "segment_hits",
    "segments_covering",
    "segments_of_blocks",
    "splice",
]


_REDUCED_FLAGS = {
    2: cv2.IMREAD_REDUCED_GRAYSCALE_2,
    4: cv2.IMREAD_REDUCED_GRAYSCALE_4,
    8: cv2.IMREAD_REDUCED_GRAYSCALE_8,
}


def reduced_canvas_shape(layout: JpegLayout, reduction: int) -> tuple[int, int]:
    """The shape of :func:`decode_reduced_into`'s canvas: the JPEG's MCU rows and
    columns (its size rounded up to whole segments) at 1/``reduction``."""
    seg_w, seg_h = layout.segment_px
    return layout.mcu_rows * seg_h // reduction, layout.per_row * seg_w // reduction


def decode_reduced_into(
    layout: JpegLayout, canvas: NDArray[np.uint8], segments: NDArray[np.intp], reduction: int
) -> None:
    """Decode the given segments (ascending raster indices) at 1/``reduction`` (2, 4 or
    8: libjpeg's DCT scaling, each 8 x 8 block decoded alone to ``8 / reduction`` px a
    side, so the pixels are those of :func:`decode_reduced` of the whole JPEG) into their
    place in a canvas of :func:`reduced_canvas_shape` (in place; what is there already
    stays where no segment is given). The splices hold several segments to a row, as
    :func:`decode_into`'s do. Raises :class:`~vision.errors.DecodeError` when they do
    not decode."""
    if reduction not in _REDUCED_FLAGS:
        raise ParameterError("reduction", f"must be 2, 4 or 8, got {reduction!r}")
    shape = reduced_canvas_shape(layout, reduction)
    if canvas.shape != shape or canvas.dtype != np.uint8 or not canvas.flags.c_contiguous:
        raise ParameterError("canvas", f"must be a C-contiguous uint8 array of {shape}")
    seg_w, seg_h = layout.segment_px
    for part, img, a in _decoded(layout, segments, reduction):
        _put_segments(canvas, layout.per_row, part, img, a, seg_h // reduction, seg_w // reduction)


def replaced_segments(layout: JpegLayout, segments: NDArray[np.intp], other: JpegLayout) -> bytes:
    """The bytes of ``layout``'s JPEG with the entropy-coded data of the given segments
    (ascending raster indices) replaced, in turn, by that of ``other``'s first
    ``len(segments)`` segments; everything else (the header, the other segments, every
    restart marker, whose numbers stay) as it was. Both must be coded with the same
    tables for the result to decode as meant (the caller's to check)."""
    seg = np.asarray(segments, dtype=np.intp)
    if seg.size > len(other.starts):
        raise ParameterError("segments", f"must number at most {len(other.starts)}")
    if seg.size and not (0 <= seg.min() and seg.max() < len(layout.starts)):
        raise ParameterError("segments", f"must be 0..{len(layout.starts) - 1}")
    if seg.size > 1 and np.any(np.diff(seg) <= 0):
        raise ParameterError("segments", "must be ascending")
    return _replaced(
        np.frombuffer(layout.data, dtype=np.uint8),
        layout.starts,
        layout.ends,
        seg,
        np.frombuffer(other.data, dtype=np.uint8),
        other.starts,
        other.ends,
    ).tobytes()


@kernel
def _replaced(
    data: NDArray[np.uint8],
    starts: NDArray[np.intp],
    ends: NDArray[np.intp],
    seg: NDArray[np.intp],
    new: NDArray[np.uint8],
    new_starts: NDArray[np.intp],
    new_ends: NDArray[np.intp],
) -> NDArray[np.uint8]:
    """:func:`replaced_segments`' bytes: ``data`` with segment ``seg[j]`` (its
    ``starts``..``ends``) replaced by ``new``'s segment ``j``."""
    total = data.size
    for j in range(seg.size):
        total += (new_ends[j] - new_starts[j]) - (ends[seg[j]] - starts[seg[j]])
    out = np.empty(total, dtype=np.uint8)
    at = 0  # in data
    o = 0  # in out
    for j in range(seg.size + 1):
        stop = starts[seg[j]] if j < seg.size else data.size
        out[o : o + stop - at] = data[at:stop]
        o += stop - at
        if j < seg.size:
            m = new_ends[j] - new_starts[j]
            out[o : o + m] = new[new_starts[j] : new_ends[j]]
            o += m
            at = ends[seg[j]]
    return out


__all__ += ["decode_reduced_into", "reduced_canvas_shape", "replaced_segments"]
