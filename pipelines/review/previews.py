"""The recording's reduced frames, most of them made without decoding the whole frame.

A reduced frame (:func:`vision.codec.preview`) costs a DCT-scaled decode of the whole
JPEG (its entropy decoding is most of a full decode's time: a 1/2 decode costs about as
much as a 1/8 one) and a JPEG encode: about 9 ms a frame, as much as measuring it. Most
of a frame is still background. :class:`RegionPreviews` therefore makes

- a **whole frame** (every pixel this frame's, exactly :func:`vision.codec.preview`'s)
  for the first frame, then every :data:`WHOLE_EVERY_FRAMES`-th frame (one a second at 15
  frames/s), every frame not measured, and every frame it cannot decode in parts (no
  restart markers, PNG, another size);
- **between them**, a background with the region of the measured beam and hub (their
  centre lines, :data:`MARGIN_PX` beyond their edges) replaced by this frame's pixels:
  only the JPEG's restart segments under that region are decoded
  (:mod:`vision.jpeg_regions`, at the reduced size), and of the reduced frame only the
  restart segments that differ from the last whole frame are encoded again, spliced
  between the last whole frame's own: the same bytes as encoding the whole reduced
  frame (tested), in a fraction of the time.

The background is the last whole frame, its region (where its beam and hub are) taken
over block by block from the frames after it where theirs are not: a block that may
still show an earlier beam is decoded again on each frame until one shows it clear of
its own, then kept. So no beam leaves a ghost, and the last whole frame's region is
decoded about once, not on every frame after it. The region is drawn at a quarter of a
reduced block and taken block by block, a few px wider than it is. (A bench minute's
region frames decode 6.8 % of the segments each: 9.2 % with the region drawn in whole
blocks with a block and a half to spare, 12.3 % when the whole frame's region was also
decoded on every frame.)

The JPEG may be gray or YCbCr colour (a colour camera's; previews, like the measurement,
are of the gray image: its Y component), its restart segments ``interval`` MCUs of
8 x 8 or 16 x 16 (4:2:0), 16 x 8 or 8 x 16 px each (:class:`vision.jpeg_regions.JpegLayout`).
The region is whole 8 x 8 blocks of the reduced image, so its pixels come out exactly as
this frame's whole preview shows them and each other block exactly as one earlier
frame's since the last whole one, clear of that frame's beam and hub (tested). What lies
outside the region (the registration object, anything else in view) is up to
:data:`WHOLE_EVERY_FRAMES` frames old on those frames: the recording's summary says so.

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

#: A frame as the recording shows it: (JPEG bytes, or None for a frame that does not
#: decode; "jpeg"; its pixel scale).
Shown = tuple[bytes | None, str, float]

#: What the recording's summary says of frames made by :class:`RegionPreviews`.
REGION_NOTE = (
    "Frames at 1/{r} size: one a second, and every frame not measured, is shown whole; "
    "on the frames between, only the measured beam and hub ({m:g} px about them) are "
    "that frame's pixels, the rest is up to a second old (the last whole frame's, or a "
    "later frame's where the beam had left) "
    "(`--frame-previews whole` shows every frame whole)."
)


def region_note(reduction: int) -> str:
    return REGION_NOTE.format(r=reduction, m=MARGIN_PX)


@dataclass(frozen=True)
class _Grid:
    """The reduced image's 8 x 8 blocks ("reduced blocks", ``8 r`` full-size px a side)
    against a JPEG's restart segments: a segment is ``per_seg`` reduced blocks wide and
    ``1 / stack`` of one tall (``stack`` segment rows to a row of reduced blocks)."""

    rows: int  # reduced blocks
    cols: int
    per_seg: int  # reduced blocks across a segment
    stack: int  # segment rows to a reduced block's row
    mcu_rows: int
    canvas_rows: int  # the reduced canvas (reduced_canvas_shape), px

    @classmethod
    def of(cls, layout: JpegLayout, r: int) -> _Grid:
        seg_w, seg_h = layout.segment_px
        canvas_rows, canvas_cols = reduced_canvas_shape(layout, r)
        return cls(
            rows=-(-canvas_rows // _BLOCK),
            cols=canvas_cols // _BLOCK,
            per_seg=seg_w // (_BLOCK * r),
            stack=_BLOCK * r // seg_h,
            mcu_rows=layout.mcu_rows,
            canvas_rows=canvas_rows,
        )

    @property
    def shape(self) -> tuple[int, int]:
        return self.rows, self.cols


@dataclass
class _Background:
    """The last whole frame, with the blocks of its region that later frames have shown
    free of their beam and hub replaced by those frames' pixels."""

    canvas: NDArray[np.uint8]  # reduced, whole segments and whole 8 x 8 blocks (padded)
    dirty: NDArray[np.bool_]  # reduced blocks that may show an earlier frame's beam
    moved: NDArray[np.bool_]  # reduced blocks changed since the whole frame
    grid: _Grid
    size: tuple[int, int]  # full size (width, height)
    segment_px: tuple[int, int]  # the frames' segments (width, height), full size
    encoded: JpegLayout | None  # the whole frame's preview (None: encoded whole each time)


class RegionPreviews:
    """Reduced frames of a run, in order (:meth:`show` keeps the background)."""

    def __init__(self, reduction: int, *, whole: bool = False) -> None:
        if reduction not in (2, 4):
            raise ValueError(f"reduction must be 2 or 4, got {reduction!r}")
        self.reduction = reduction
        self.whole = bool(whole)
        self._last: _Background | None = None
        self._since = 0  # frames since the last whole frame kept
        self.whole_frames = 0
        self.region_frames = 0
        self.region_fraction: list[float] = []
        self.spliced_frames = 0  # region frames encoded in part (:func:`_respliced`)

    def show(self, data: bytes, encoding: str, m: FrameMeasurement | None) -> Shown:
        """The frame as the recording shows it: (JPEG bytes, "jpeg", pixel scale); no
        bytes (None) for a frame that does not decode."""
        r = self.reduction
        self._since += 1
        if self.whole or m is None or not m.ok or encoding not in ("jpeg", "jpg"):
            # shown whole and not kept (no region): no use for the segments' layout
            return self._whole(data, None, None, None)
        layout = jpeg_layout(bytes(data))
        if layout is not None and layout.segment_px[0] % (_BLOCK * r):
            layout = None  # its segments would cut the reduced image's blocks
        if layout is None:
            return self._whole(data, None, None, None)
        last = self._last
        size = (layout.width_px, layout.height_px)
        same = last is not None and last.size == size and last.segment_px == layout.segment_px
        grid = last.grid if same and last is not None else _Grid.of(layout, r)
        region = region_blocks(m, grid.shape, _BLOCK * r)
        if region is None or last is None or not same or self._since >= WHOLE_EVERY_FRAMES:
            return self._whole(data, layout, region, grid)
        # this frame's region and the blocks that may still show an earlier beam, in
        # whole segments (and whole reduced blocks)
        cells = _any_across(region | last.dirty, grid.per_seg)
        hit = np.repeat(cells, grid.stack, axis=0) if grid.stack > 1 else cells
        segments = np.flatnonzero(hit[: grid.mcu_rows])
        decoded = np.repeat(cells, grid.per_seg, axis=1) if grid.per_seg > 1 else cells
        canvas = last.canvas.copy()
        try:
            decode_reduced_into(layout, canvas[: grid.canvas_rows], segments, r)
        except ValueError:  # a damaged segment: the frame as it decodes whole, if it does
            return self._whole(data, None, None, None)
        # the background takes this frame's pixels where an earlier beam may have been
        # and this frame's is not
        clean = last.dirty & ~region
        if clean.any():
            _copy_blocks(last.canvas, canvas, clean)
            last.dirty &= region
            last.moved |= clean
        self.region_frames += 1
        self.region_fraction.append(segments.size / (layout.per_row * layout.mcu_rows))
        out = None
        if last.encoded is not None:
            out = _respliced(last.encoded, canvas, decoded | last.moved)
            self.spliced_frames += out is not None
        if out is None:
            h, w = math.ceil(layout.height_px / r), math.ceil(layout.width_px / r)
            out = encode(np.ascontiguousarray(canvas[:h, :w]), "jpeg", QUALITY)
        return out, "jpeg", 1.0 / r

    def _whole(
        self,
        data: bytes,
        layout: JpegLayout | None,
        region: NDArray[np.bool_] | None,
        grid: _Grid | None,
    ) -> Shown:
        r = self.reduction
        self.whole_frames += 1
        if layout is None or region is None or grid is None:
            # not kept as the background: its region is unknown (not measured), or it
            # cannot be decoded in parts
            return whole_preview(data, r)
        try:
            image = decode_reduced(bytes(data), r)
        except ValueError:  # not kept as the background: shown as it decodes, if it does
            return whole_preview(data, r)
        canvas = np.zeros((grid.rows * _BLOCK, grid.cols * _BLOCK), np.uint8)
        canvas[: image.shape[0], : image.shape[1]] = image
        # the bytes preview() gives: the same reduced decode, encoded the same way
        out = encode(image, "jpeg", QUALITY)
        self._last = _Background(
            canvas=canvas,
            dirty=region,
            moved=np.zeros(grid.shape, bool),
            grid=grid,
            size=(layout.width_px, layout.height_px),
            segment_px=layout.segment_px,
            encoded=jpeg_layout(out),
        )
        self._since = 0
        return out, "jpeg", 1.0 / r


def whole_preview(data: bytes, reduction: int) -> Shown:
    """A frame shown whole (:func:`vision.codec.preview`), as :meth:`RegionPreviews.show`
    gives it; depends on nothing but the frame (previews made in several threads). A
    frame that does not decode (another recorder's damaged JPEG in an intact log: its
    measurement says so) is shown without an image: None for its bytes."""
    try:
        return preview(bytes(data), reduction), "jpeg", 1.0 / reduction
    except ValueError:  # vision's DecodeError and the size checks
        return None, "jpeg", 1.0 / reduction


#: A centre line is drawn through fewer points, none further than this (drawn px) from it.
_SIMPLIFY_PX = 0.25
#: The region is drawn at this many px a block's side (a block's row of them a 32-bit
#: word), then taken block by block.
_DRAWN_PER_BLOCK = 4


def region_blocks(
    m: FrameMeasurement, shape: tuple[int, int], block_px: int = _BLOCK
) -> NDArray[np.bool_] | None:
    """The blocks of ``block_px`` full-size px a side ([block row, block col] from the
    origin, ``shape`` of them: 8 for a layout's
    :attr:`~vision.jpeg_regions.JpegLayout.blocks_shape`, ``8 r`` for the 8 x 8 blocks of
    the 1/``r`` image) within :data:`MARGIN_PX` of the measured hub's and beam's edges
    (their centre lines, each widened by its measured width), or None when the
    measurement does not place them."""
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
    # drawn at _DRAWN_PER_BLOCK px a block: a block is in where any of its px is (each a
    # fraction of a block: what the thick line's width is rounded to costs little)
    k = _DRAWN_PER_BLOCK
    unit = block_px / k  # full-size px per drawn px
    rows, cols = shape
    lines: list[tuple[NDArray[np.int32], int]] = []  # (points, 1/16 drawn px; thickness)
    for name, pts in (("hub", hub), ("beam", line)):
        w = widths[name]
        half_px = (0.5 * w * px_m if math.isfinite(w) else 0.0) + MARGIN_PX
        # drawn px (i, j) is centred at (j, i); a long centre line through fewer points
        # (its hundreds: as many thick segments and round joints to draw), widened by as
        # much as they leave it
        at = np.clip(pts / unit - 0.5, -(2**23), 2**23).astype(np.float32).reshape(-1, 1, 2)
        slack = 0.0
        if at.shape[0] > 2:
            at = np.asarray(cv2.approxPolyDP(at, _SIMPLIFY_PX, False), np.float32)
            slack = _SIMPLIFY_PX
        # a thick polyline with round joints and ends: every drawn px the widened line
        # touches (its centre within half a diagonal, 0.71, of it). The thickness odd,
        # 2 n + 1: the sides lie n + 1 from the line, the joints' circles (centred on
        # whole px, 0.71 off at most) reach n + 1 from their centre, n + 0.29 from it
        n = math.ceil(half_px / unit + slack + 0.71 - 0.29 + 0.05)
        lines.append(((at * 16.0).round().astype(np.int32), min(2 * n + 1, 32767)))
    out = np.zeros(shape, bool)
    box = _drawn_box(lines, rows * k, cols * k, k)
    if box is None:
        return out  # nothing drawn within the frame
    # drawn in that box alone (whole blocks), moved by whole drawn px: the same px as in
    # the whole mask (OpenCV draws in integers from the points' differences; the box
    # cuts no line the whole mask does not), its memory a fraction of the whole's
    y0, y1, x0, x1 = box
    mask = np.zeros((y1 - y0, x1 - x0), np.uint8)
    to_box = np.array([x0 * 16, y0 * 16], np.int32)
    for fixed, thickness in lines:
        cv2.polylines(mask, [fixed - to_box], False, 1, thickness=thickness, shift=4)
    # a block where any of its drawn px is: a block's row of them is one word, its
    # rows' words OR-ed
    words = mask.view(np.uint32).reshape((y1 - y0) // k, k, (x1 - x0) // k)
    out[y0 // k : y1 // k, x0 // k : x1 // k] = (
        words[:, 0] | words[:, 1] | words[:, 2] | words[:, 3]
    ) != 0
    return out


def _drawn_box(
    lines: list[tuple[NDArray[np.int32], int]], height: int, width: int, k: int
) -> tuple[int, int, int, int] | None:
    """Rows ``y0:y1`` and columns ``x0:x1`` of a ``height`` x ``width`` mask (multiples
    of ``k``) that hold every px of the thick polylines ``lines`` (points in 1/16 px,
    thickness), 3 px to spare, in whole ``k`` x ``k`` blocks; None when none is in it."""
    y0 = x0 = 2**31
    y1 = x1 = -(2**31)
    for fixed, thickness in lines:
        reach = thickness // 2 + 3  # a side, a round end: within half the thickness
        xy = fixed.reshape(-1, 2)
        lo, hi = xy.min(axis=0) >> 4, (xy.max(axis=0) + 15) >> 4
        x0, y0 = min(x0, int(lo[0]) - reach), min(y0, int(lo[1]) - reach)
        x1, y1 = max(x1, int(hi[0]) + reach + 1), max(y1, int(hi[1]) + reach + 1)
    x0, y0 = max(0, x0) // k * k, max(0, y0) // k * k
    x1, y1 = min(width, -(-x1 // k) * k), min(height, -(-y1 // k) * k)
    if x1 <= x0 or y1 <= y0:
        return None
    return y0, y1, x0, x1


_UINT_OF_BYTES = {2: np.uint16, 4: np.uint32, 8: np.uint64}


def _any_across(blocks: NDArray[np.bool_], k: int) -> NDArray[np.bool_]:
    """Whether any of each ``k`` blocks side by side is set ([row, col // k])."""
    if k == 1:
        return blocks
    if k in _UINT_OF_BYTES and blocks.flags.c_contiguous:
        return np.asarray(blocks.view(_UINT_OF_BYTES[k]) != 0)
    return np.asarray(blocks.reshape(blocks.shape[0], -1, k).any(axis=2))


def _copy_blocks(dst: NDArray[np.uint8], src: NDArray[np.uint8], blocks: NDArray[np.bool_]) -> None:
    """Copy the 8 x 8 blocks set in ``blocks`` from ``src`` to ``dst`` (whole blocks
    both, in place)."""
    rows, cols = blocks.shape
    whole = (rows * _BLOCK, cols * _BLOCK)
    if dst.shape == src.shape == whole and dst.flags.c_contiguous and src.flags.c_contiguous:
        # a block's row of pixels is one 8-byte word: its 8 words taken by their flat
        # index (a third of the time of indexing the blocks of 4-d views)
        at = np.flatnonzero(blocks)
        i, j = at // cols, at % cols
        words = ((i * _BLOCK)[:, None] + _ROWS_OF_BLOCK) * cols + j[:, None]
        to = dst.reshape(-1).view(np.uint64)
        to[words] = src.reshape(-1).view(np.uint64)[words]
        return
    i, j = np.nonzero(blocks)
    to4 = dst.reshape(rows, _BLOCK, cols, _BLOCK).transpose(0, 2, 1, 3)
    to4[i, j] = src.reshape(rows, _BLOCK, cols, _BLOCK).transpose(0, 2, 1, 3)[i, j]


_ROWS_OF_BLOCK = np.arange(_BLOCK, dtype=np.intp)[None, :]


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
    if canvas.shape[1] % 8 or not canvas.flags.c_contiguous:
        return None  # not whole 8-byte words a row
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
    stack = _stacked(canvas, part, across, rows, whole.per_row, seg_w // 8)
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


def _stacked(
    canvas: NDArray[np.uint8],
    part: NDArray[np.intp],
    across: int,
    rows: int,
    per_row: int,
    words: int,
) -> NDArray[np.uint8]:
    """The segments ``part`` (raster indices, ``per_row`` to a row of ``rows``; one 8-px
    block row tall, ``words`` 8-byte words wide) of ``canvas`` side by side, ``across``
    to a row (``part.size`` a multiple), in 8-byte words: a quarter as many to index."""
    grid = canvas[: rows * _BLOCK].view(np.uint64)[:, : per_row * words]
    g = part.size // across
    if grid.flags.c_contiguous:
        # each segment's 8 rows by their flat index, in the stack's order, taken at once
        # (one pass: a third of the time of gathering [segment, row, word] and then
        # transposing it into rows)
        first = part // per_row * (_BLOCK * per_row) + part % per_row  # its top row
        at = first.reshape(g, 1, across) + (_ROWS_OF_BLOCK * per_row).reshape(1, _BLOCK, 1)
        rows_of = grid.reshape(rows * _BLOCK * per_row, words)
        return np.take(rows_of, at.reshape(-1), axis=0).reshape(g * _BLOCK, -1).view(np.uint8)
    segs = grid.reshape(rows, _BLOCK, per_row, words)[part // per_row, :, part % per_row]
    return np.ascontiguousarray(  # [segment, row, word] to rows of ``across`` segments
        segs.reshape(-1, across, _BLOCK, words).transpose(0, 2, 1, 3).reshape(-1, across * words)
    ).view(np.uint8)
