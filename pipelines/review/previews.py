"""The recording's reduced frames, most of them made without decoding the whole frame.

A reduced frame (:func:`vision.codec.preview`) costs a DCT-scaled decode of the whole
JPEG (its entropy decoding is most of a full decode's time: a 1/2 decode costs about as
much as a 1/8 one) and a JPEG encode: about 9 ms a frame, as much as measuring it. Most
of a frame is still background. :class:`RegionPreviews` therefore makes

- a **whole frame** (every pixel this frame's, exactly :func:`vision.codec.preview`'s)
  for the first frame, then every :data:`WHOLE_EVERY_FRAMES`-th frame (one a second at 15
  frames/s), every frame not measured, and every frame it cannot decode in parts (no
  restart markers, PNG, another size);
- **between them**, the last whole frame with the region of the measured beam and hub
  (their centre lines, :data:`MARGIN_PX` beyond their edges, and the same region of the
  last whole frame, so its beam leaves no ghost) replaced by this frame's pixels: only
  the JPEG's restart segments under that region are decoded (:mod:`vision.jpeg_regions`,
  at the reduced size), and of the reduced frame only the restart segments the
  region touches are encoded again, spliced between the last whole frame's own: the
  same bytes as encoding the whole reduced frame (tested), in a fraction of the time.

The JPEG may be gray or YCbCr colour (a colour camera's; previews, like the measurement,
are of the gray image: its Y component), its restart segments ``interval`` MCUs of
8 x 8 or 16 x 16 (4:2:0), 16 x 8 or 8 x 16 px each (:class:`vision.jpeg_regions.JpegLayout`).
The region is whole 8 x 8 blocks of the reduced image, so its pixels come out exactly as
this frame's whole preview shows them and the rest exactly as the last whole frame's
(tested). What lies outside the region (the registration object, anything else in view)
is up to a second old on those frames: the recording's summary says so.

``whole=True`` makes every frame whole (``--frame-previews whole``).
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from vision import FrameMeasurement
from vision.codec import encode, preview
from vision.jpeg_regions import (
    JpegLayout,
    decode_reduced,
    decode_reduced_into,
    jpeg_layout,
    reduced_canvas_shape,
    replaced_segments,
    segments_of_blocks,
)

#: A whole frame at least this often (frames): one a second at the bench's 15 frames/s.
WHOLE_EVERY_FRAMES = 15
#: The region reaches this far (full-size px) beyond the beam's and the hub's edges.
MARGIN_PX = 48.0
#: The preview's JPEG quality (:func:`vision.codec.preview`'s default).
QUALITY = 85
_BLOCK = 8
#: Re-encoded segments go side by side in rows about this wide (px).
_ROW_PX = 1024

PREVIEW_MODES = ("region", "whole")

#: What the recording's summary says of frames made by :class:`RegionPreviews`.
REGION_NOTE = (
    "Frames at 1/{r} size: one a second, and every frame not measured, is shown whole; "
    "on the frames between, only the measured beam and hub ({m:g} px about them) are "
    "that frame's pixels, the rest is the last whole frame's "
    "(`--frame-previews whole` shows every frame whole)."
)


def region_note(reduction: int) -> str:
    return REGION_NOTE.format(r=reduction, m=MARGIN_PX)


@dataclass
class _Whole:
    """The last whole frame: its reduced image (padded to whole segments), the
    full-size blocks of its region, and its size."""

    canvas: NDArray[np.uint8]
    blocks: NDArray[np.bool_]
    size: tuple[int, int]  # full size (width, height)
    segment_px: tuple[int, int]  # the frames' segments (width, height), full size
    encoded: JpegLayout | None  # its preview's segments (None: encoded whole each time)


class RegionPreviews:
    """Reduced frames of a run, in order (:meth:`show` keeps the last whole frame)."""

    def __init__(self, reduction: int, *, whole: bool = False) -> None:
        if reduction not in (2, 4):
            raise ValueError(f"reduction must be 2 or 4, got {reduction!r}")
        self.reduction = reduction
        self.whole = bool(whole)
        self._last: _Whole | None = None
        self._since = 0
        self.whole_frames = 0
        self.region_frames = 0
        self.region_fraction: list[float] = []
        self.spliced_frames = 0  # region frames encoded in part (:func:`_respliced`)

    def show(
        self, data: bytes, encoding: str, m: FrameMeasurement | None
    ) -> tuple[bytes, str, float]:
        """The frame as the recording shows it: (JPEG bytes, "jpeg", pixel scale)."""
        r = self.reduction
        if self.whole or m is None or not m.ok or encoding not in ("jpeg", "jpg"):
            # shown whole and not kept (no region): no use for the segments' layout
            return self._whole(data, None, None)
        layout = jpeg_layout(bytes(data))
        if layout is not None and layout.segment_px[0] % (_BLOCK * r):
            layout = None  # its segments would cut the reduced image's blocks
        blocks = None
        if layout is not None:
            blocks = region_blocks(m, layout.blocks_shape)
        last = self._last
        size = (layout.width_px, layout.height_px) if layout is not None else None
        if (
            blocks is None
            or last is None
            or self._since + 1 >= WHOLE_EVERY_FRAMES
            or last.size != size
            or last.segment_px != layout.segment_px  # type: ignore[union-attr]
        ):
            return self._whole(data, layout, blocks)
        assert layout is not None
        region = _reduced_blocks(blocks | last.blocks, r)
        segments = segments_of_blocks(layout, region)
        canvas = last.canvas.copy()
        if segments.size:
            decode_reduced_into(layout, canvas, segments, r)
        self._since += 1
        self.region_frames += 1
        self.region_fraction.append(segments.size / (layout.per_row * layout.mcu_rows))
        out = None
        if last.encoded is not None:
            changed = _grouped(_segment_blocks(layout, segments), r)
            out = _respliced(last.encoded, canvas, changed)
            self.spliced_frames += out is not None
        if out is None:
            h, w = math.ceil(layout.height_px / r), math.ceil(layout.width_px / r)
            out = encode(np.ascontiguousarray(canvas[:h, :w]), "jpeg", QUALITY)
        return out, "jpeg", 1.0 / r

    def _whole(
        self, data: bytes, layout: JpegLayout | None, blocks: NDArray[np.bool_] | None
    ) -> tuple[bytes, str, float]:
        r = self.reduction
        if layout is None or blocks is None:
            # not kept as the last whole frame: its region is unknown (not measured), or
            # it cannot be decoded in parts
            self.whole_frames += 1
            return whole_preview(data, r)
        image = decode_reduced(bytes(data), r)
        self.whole_frames += 1
        canvas = np.zeros(reduced_canvas_shape(layout, r), np.uint8)
        canvas[: image.shape[0], : image.shape[1]] = image
        # the bytes preview() gives: the same reduced decode, encoded the same way
        out = encode(image, "jpeg", QUALITY)
        size = (layout.width_px, layout.height_px)
        self._last = _Whole(canvas, blocks, size, layout.segment_px, jpeg_layout(out))
        self._since = 0
        return out, "jpeg", 1.0 / r


def whole_preview(data: bytes, reduction: int) -> tuple[bytes, str, float]:
    """A frame shown whole (:func:`vision.codec.preview`), as :meth:`RegionPreviews.show`
    gives it; depends on nothing but the frame (previews made in several threads)."""
    return preview(bytes(data), reduction), "jpeg", 1.0 / reduction


def region_blocks(m: FrameMeasurement, shape: tuple[int, int]) -> NDArray[np.bool_] | None:
    """The full-size 8 x 8 blocks ([block row, block col], ``shape``: a layout's
    :attr:`~vision.jpeg_regions.JpegLayout.blocks_shape`) within
    :data:`MARGIN_PX` of the measured hub's and beam's edges (their centre lines, each
    widened by its measured width), or None when the measurement does not place them."""
    hub = np.asarray(m.hub_line_px, float)
    line = np.asarray(m.centreline_px, float)
    plane = np.asarray(m.centreline_plane_m, float)
    if (
        hub.shape != (2, 2)
        or line.ndim != 2
        or line.shape[0] < 2
        or plane.shape != line.shape
        or not (np.all(np.isfinite(hub)) and np.all(np.isfinite(line)))
    ):
        return None
    # px per m along the centre line (no calibration needed: it holds both)
    len_px = float(np.sum(np.hypot(*np.diff(line, axis=0).T)))
    len_m = float(np.sum(np.hypot(*np.diff(plane, axis=0).T)))
    if not (len_m > 0 and math.isfinite(len_px / len_m)):
        return None
    px_m = len_px / len_m
    widths = {"hub": m.hub_search_width_m, "beam": m.beam_width_m}
    mask = np.zeros(shape, np.uint8)
    for name, pts in (("hub", hub), ("beam", line)):
        w = widths[name]
        half_px = (0.5 * w * px_m if math.isfinite(w) else 0.0) + MARGIN_PX
        # a thick polyline with round ends, in blocks, a block of slack all round
        thick = min(2 * math.ceil(half_px / _BLOCK) + 3, 32767)
        blk = np.clip(pts / _BLOCK * 16.0, -(2**27), 2**27).round().astype(np.int32)
        cv2.polylines(mask, [blk.reshape(-1, 1, 2)], False, 1, thickness=thick, shift=4)
    return mask.astype(bool)


def _grouped(blocks: NDArray[np.bool_], r: int) -> NDArray[np.bool_]:
    """The blocks of the 1/``r`` image (``r`` x ``r`` full-size blocks each, from the
    origin) holding any of the given full-size blocks."""
    rows, cols = blocks.shape
    pad = np.zeros((-(-rows // r) * r, -(-cols // r) * r), bool)
    pad[:rows, :cols] = blocks
    out = pad[::r, ::r].copy()
    for i in range(r):
        for j in range(r):
            if i or j:
                out |= pad[i::r, j::r]
    return out


def _reduced_blocks(blocks: NDArray[np.bool_], r: int) -> NDArray[np.bool_]:
    """Full-size blocks grown to whole blocks of the 1/``r`` image, so no reduced block
    mixes two frames."""
    rows, cols = blocks.shape
    grown = _grouped(blocks, r)
    return np.repeat(np.repeat(grown, r, axis=0), r, axis=1)[:rows, :cols]


def _segment_blocks(layout: JpegLayout, segments: NDArray[np.intp]) -> NDArray[np.bool_]:
    """The full-size 8 x 8 blocks of the given segments (``layout.blocks_shape``)."""
    hit = np.zeros(layout.mcu_rows * layout.per_row, dtype=bool)
    hit[segments] = True
    seg_w, seg_h = layout.segment_px
    grid = hit.reshape(layout.mcu_rows, layout.per_row)
    return np.repeat(np.repeat(grid, seg_h // _BLOCK, axis=0), seg_w // _BLOCK, axis=1)


def _respliced(
    whole: JpegLayout, canvas: NDArray[np.uint8], changed: NDArray[np.bool_]
) -> bytes | None:
    """The JPEG of ``canvas`` (reduced, padded; what lies past the image's edges is
    overwritten), given the JPEG of an earlier canvas (``whole``, its restart segments)
    that differs only in the ``changed`` blocks ([block row, block col] of the reduced
    image): the segments holding changed blocks encoded again (side by side, the same
    tables), the others taken as they were. A baseline scan's segments are independent
    (the DC predictions reset at each restart), so this is the bytes of encoding the
    whole canvas; None when the tables came out different (then the caller encodes the
    whole)."""
    seg_w, seg_h = whole.segment_px
    if seg_h != _BLOCK:  # our own gray encode's: one 8 x 8 block an MCU
        return None
    rows, cols = whole.mcu_rows, whole.per_row * whole.interval
    if changed.shape[0] < rows or changed.shape[1] < cols:
        return None
    if canvas.shape[0] < rows * _BLOCK or canvas.shape[1] < cols * _BLOCK:
        return None
    redo = segments_of_blocks(whole, changed[:rows, :cols])
    if redo.size == 0:
        return whole.data
    # past the image's right and bottom edges, its last column and row again: what the
    # encoder pads a part block with (not what the canvas holds there)
    h, w = whole.height_px, whole.width_px
    if h < rows * _BLOCK:
        canvas[h : rows * _BLOCK, : cols * _BLOCK] = canvas[h - 1, : cols * _BLOCK]
    if w < cols * _BLOCK:
        canvas[: rows * _BLOCK, w : cols * _BLOCK] = canvas[: rows * _BLOCK, w - 1 : w]
    # the segments side by side, about _ROW_PX wide (the encoder's cost is per row, as
    # the decoder's), the last row filled up with its last segment again
    across = min(max(1, _ROW_PX // seg_w), redo.size)
    part = redo
    if redo.size % across:
        part = np.concatenate((redo, np.full(-redo.size % across, redo[-1], dtype=np.intp)))
    grid = canvas[: rows * _BLOCK, : cols * _BLOCK].reshape(rows, _BLOCK, whole.per_row, seg_w)
    segs = grid.transpose(0, 2, 1, 3)[part // whole.per_row, part % whole.per_row]
    stack = np.ascontiguousarray(
        segs.reshape(-1, across, _BLOCK, seg_w).transpose(0, 2, 1, 3).reshape(-1, across * seg_w)
    )
    new = jpeg_layout(encode(stack, "jpeg", QUALITY, restart_interval_mcu=whole.interval))
    if new is None or new.starts.size != part.size:
        return None
    head = bytearray(whole.header)
    struct.pack_into(">HH", head, whole.sof_size_at, *stack.shape)
    if bytes(head) != new.header:
        return None
    # the changed segments' bytes replaced, everything between them (the unchanged
    # segments and every restart marker, whose numbers stay) kept as it was
    return replaced_segments(whole, redo, new)
