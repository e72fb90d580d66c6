"""Segments decoded at a reduced size into their place, and segments' bytes replaced by
another JPEG's: bit for bit what the whole JPEG's reduced decode and encode give."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from vision.codec import encode
from vision.errors import ParameterError
from vision.jpeg_regions import (
    decode_reduced,
    decode_reduced_into,
    jpeg_layout,
    reduced_canvas_shape,
    replaced_segments,
)


def _noise(h: int, w: int, seed: int) -> np.ndarray:
    """Blurred noise: every segment differs from every other and from another seed's."""
    rng = np.random.default_rng(seed)
    return cv2.GaussianBlur(rng.integers(0, 256, (h, w), dtype=np.uint8), (5, 5), 1.5)


@pytest.mark.parametrize(
    ("h", "w", "interval", "reduction", "colour"),
    [
        (632, 960, 6, 2, False),  # the last MCU row partial
        (480, 1024, 4, 4, False),
        (240, 320, 40, 8, False),  # one segment an MCU row, 1/8: one px row a segment
        (632, 960, 3, 2, True),  # 4:2:0 colour (Y decoded): segments of 48 x 16 px
    ],
)
def test_segments_decoded_reduced_in_place_are_the_whole_reduced_decode(
    h: int, w: int, interval: int, reduction: int, colour: bool
) -> None:
    if colour:
        rng = np.random.default_rng(h)
        image = cv2.GaussianBlur(rng.integers(0, 256, (h, w, 3), dtype=np.uint8), (5, 5), 1.5)
        params = [cv2.IMWRITE_JPEG_QUALITY, 80, cv2.IMWRITE_JPEG_RST_INTERVAL, interval]
        ok, buf = cv2.imencode(".jpg", image, params)
        assert ok
        data = bytes(buf)
    else:
        data = encode(_noise(h, w, h + w), "jpeg", 80, restart_interval_mcu=interval)
    layout = jpeg_layout(data)
    assert layout is not None
    whole = decode_reduced(data, reduction)
    seg_w, seg_h = layout.segment_px[0] // reduction, layout.segment_px[1] // reduction
    shape = reduced_canvas_shape(layout, reduction)
    assert shape == (layout.mcu_rows * seg_h, layout.per_row * seg_w)
    n = layout.per_row * layout.mcu_rows
    rng = np.random.default_rng(n)
    # a few, many (more than a splice's row holds, not a whole number of rows), all
    for count in (3, n // 3 + 1, n):
        segments = np.sort(rng.choice(n, count, replace=False))
        canvas = np.full(shape, 7, np.uint8)
        decode_reduced_into(layout, canvas, segments, reduction)
        got = canvas[: whole.shape[0], : whole.shape[1]]
        hit = np.zeros(n, bool)
        hit[segments] = True
        grid = np.repeat(np.repeat(hit.reshape(layout.mcu_rows, -1), seg_h, 0), seg_w, 1)
        grid = grid[: whole.shape[0], : whole.shape[1]]
        assert np.array_equal(got[grid], whole[grid])
        assert np.all(got[~grid] == 7)  # what was there stays where no segment is given


def test_decode_reduced_into_refuses_a_canvas_of_another_size_or_a_reduction() -> None:
    data = encode(_noise(64, 128, 1), "jpeg", 80, restart_interval_mcu=4)
    layout = jpeg_layout(data)
    assert layout is not None
    segments = np.arange(3)
    with pytest.raises(ParameterError, match="canvas"):
        decode_reduced_into(layout, np.zeros((64, 128), np.uint8), segments, 2)
    with pytest.raises(ParameterError, match="reduction"):
        decode_reduced_into(layout, np.zeros((21, 42), np.uint8), segments, 3)


def test_segments_replaced_by_another_encodes_are_that_image_encoded() -> None:
    # two images that differ in some segments: the first's JPEG with those segments'
    # bytes replaced by the second's own encode of them (in order) is the second's JPEG
    h, w, interval = 96, 256, 4
    a = _noise(h, w, 2)
    b = a.copy()
    seg_w = 8 * interval
    per_row = w // seg_w
    redo = np.array([0, 1, 5, per_row + 2, 3 * per_row, h // 8 * per_row - 1])
    other = _noise(h, w, 3)
    for s in redo:
        r0, c0 = s // per_row * 8, s % per_row * seg_w
        b[r0 : r0 + 8, c0 : c0 + seg_w] = other[r0 : r0 + 8, c0 : c0 + seg_w]
    stack = np.vstack([b[s // per_row * 8 :][:8, s % per_row * seg_w :][:, :seg_w] for s in redo])
    old = jpeg_layout(encode(a, "jpeg", 85, restart_interval_mcu=interval))
    new = jpeg_layout(encode(stack, "jpeg", 85, restart_interval_mcu=interval))
    assert old is not None and new is not None and len(new.starts) == len(redo)
    assert replaced_segments(old, redo, new) == encode(b, "jpeg", 85, restart_interval_mcu=interval)
    assert replaced_segments(old, redo[:0], new) == old.data
    with pytest.raises(ParameterError, match="ascending"):
        replaced_segments(old, redo[::-1], new)
    with pytest.raises(ParameterError, match="at most"):
        replaced_segments(old, np.arange(len(redo) + 1), new)
    with pytest.raises(ParameterError, match="must be 0"):
        replaced_segments(old, np.array([len(old.starts)]), new)
