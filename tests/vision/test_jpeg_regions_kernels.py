"""The compiled kernels of vision.jpeg_regions against the numpy forms they replaced (kept
here as the reference): the same layouts, the same bytes, the same pixels, on valid and
damaged JPEGs alike."""

from __future__ import annotations

import math
import struct

import numpy as np
import pytest

import vision.jpeg_regions as jr
from vision.codec import MAX_SIDE_PX, decode, encode
from vision.errors import ParameterError
from vision.jpeg_regions import (
    JpegLayout,
    blank_canvas,
    decode_into,
    decode_segments,
    fill_segments,
    jpeg_layout,
    paste,
    splice,
)


def _layout_numpy(data: bytes) -> tuple[int, int, int, int, int, np.ndarray, np.ndarray] | None:
    """jpeg_layout's numpy form (before the kernel): (width, height, interval, offset of
    the frame size, offset of the scan, starts, ends), or None."""
    if data[:2] != b"\xff\xd8":
        return None
    i = 2
    interval = 0
    size: tuple[int, int] | None = None
    sof_at = -1
    n = len(data)
    while True:
        while i < n and data[i] == 0xFF and i + 1 < n and data[i + 1] == 0xFF:
            i += 1
        if i + 4 > n or data[i] != 0xFF:
            return None
        marker = data[i + 1]
        (length,) = struct.unpack(">H", data[i + 2 : i + 4])
        if length < 2 or i + 2 + length > n:
            return None
        body = data[i + 4 : i + 2 + length]
        if marker in (0xC0, 0xC1):
            if len(body) < 6 or body[5] != 1:
                return None
            height, width = struct.unpack(">HH", body[1:5])
            size = (width, height)
            sof_at = i + 5
        elif marker in (0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF):
            return None
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
    mcu_cols = math.ceil(width / 8)
    mcu_rows = math.ceil(height / 8)
    if mcu_cols % interval:
        return None
    n_seg = mcu_cols // interval * mcu_rows
    buf = np.frombuffer(data, dtype=np.uint8)
    ff = np.flatnonzero(buf[scan_at:-1] == 0xFF) + scan_at
    marks = ff[buf[ff + 1] != 0]
    kinds = buf[marks + 1]
    is_rst = (kinds & 0xF8) == 0xD0
    end_of_scan = np.flatnonzero(~is_rst)
    if end_of_scan.size == 0 or kinds[end_of_scan[0]] != 0xD9:
        return None
    rst = marks[: end_of_scan[0]]
    if rst.size != n_seg - 1:
        return None
    numbers = kinds[: rst.size]
    if rst.size and (numbers[0] != 0xD0 or np.any(((numbers[1:] - numbers[:-1]) & 7) != 1)):
        return None
    starts = np.empty(n_seg, dtype=np.intp)
    starts[0] = scan_at
    starts[1:] = rst + 2
    ends = np.empty(n_seg, dtype=np.intp)
    ends[:-1] = rst
    ends[-1] = int(marks[end_of_scan[0]])
    return width, height, interval, sof_at, scan_at, starts, ends


def _scene(h: int, w: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:h, 0:w]
    img = 90 + 60 * np.sin(xx / 11.0 + yy / 17.0) + rng.normal(0, 20, (h, w))
    return np.clip(img, 0, 255).astype(np.uint8)


def _same_layout(data: bytes) -> bool:
    """Whether jpeg_layout agrees with the numpy form on ``data``; True if it has one."""
    want = _layout_numpy(data)
    got = jpeg_layout(data)
    if want is None:
        assert got is None
        return False
    assert got is not None
    width, height, interval, sof_at, scan_at, starts, ends = want
    assert (got.width_px, got.height_px, got.interval) == (width, height, interval)
    assert (got.sof_size_at, got.header) == (sof_at, data[:scan_at])
    assert got.per_row == math.ceil(width / 8) // interval
    assert got.mcu_rows == math.ceil(height / 8)
    np.testing.assert_array_equal(got.starts, starts)
    np.testing.assert_array_equal(got.ends, ends)
    assert got.starts.dtype == got.ends.dtype == np.intp
    return True


@pytest.mark.parametrize(
    ("h", "w", "quality", "interval"),
    [(8, 8, 90, 1), (9, 17, 50, 3), (100, 130, 97, 1), (240, 320, 60, 8), (480, 640, 95, 16)],
)
def test_layout_is_the_numpy_forms(h: int, w: int, quality: int, interval: int) -> None:
    """Every size (a single block, partial MCUs, lengths not a multiple of 8 bytes),
    every byte of the scan looked at: a layout equal field for field."""
    data = encode(_scene(h, w, h * w), "jpeg", quality, restart_interval_mcu=interval)
    assert _same_layout(data)
    for cut in range(1, 10):  # the file's end in every position of its last word
        _same_layout(data[:-cut])
        _same_layout(data[:-cut] + b"\xff\xd9")


def test_layout_of_damaged_jpegs_is_the_numpy_forms() -> None:
    """Flipped bits, bytes set to 0xFF, restart markers renumbered or replaced, cuts,
    insertions, fill bytes before markers: None or the same layout, as before."""
    data = encode(_scene(120, 256, 3), "jpeg", 85, restart_interval_mcu=4)
    rng = np.random.default_rng(19)
    rst = [j for j in range(len(data) - 1) if data[j] == 0xFF and 0xD0 <= data[j + 1] <= 0xD7]
    kept = 0
    for trial in range(600):
        d = bytearray(data)
        kind = trial % 6
        if kind == 0:
            for _ in range(int(rng.integers(1, 4))):
                p = int(rng.integers(len(d)))
                d[p] ^= 1 << int(rng.integers(8))
        elif kind == 1:
            for _ in range(int(rng.integers(1, 4))):
                d[int(rng.integers(len(d)))] = 0xFF
        elif kind == 2:
            j = rst[int(rng.integers(len(rst)))]
            d[j + 1] = int(rng.choice([0xD0, 0xD7, 0xD9, 0xC4, 0x00, 0xFF, int(rng.integers(256))]))
        elif kind == 3:
            d = d[: int(rng.integers(len(d)))]
        elif kind == 4:
            p = int(rng.integers(len(d)))
            d[p:p] = rng.integers(0, 256, int(rng.integers(1, 20)), dtype=np.uint8).tobytes()
        else:  # fill bytes before a header marker (legal) or a lost marker byte
            p = int(rng.integers(2, 200))
            d[p:p] = b"\xff" * int(rng.integers(1, 4))
        kept += _same_layout(bytes(d))
    assert 0 < kept < 600  # both outcomes seen
    for short in (b"", b"\xff", b"\xff\xd8", b"\xff\xd8\xff", data[:2] + b"\xff\xda\x00\x02"):
        assert not _same_layout(short)


def _splice_numpy(layout: JpegLayout, segments: np.ndarray, across: int = 1) -> bytes:
    """_splice's numpy form (before the kernel)."""
    seg_w, seg_h = layout.segment_px
    seg = np.asarray(segments, dtype=np.intp)
    n = len(seg)
    head = bytearray(layout.header)
    struct.pack_into(">HH", head, layout.sof_size_at, n // across * seg_h, across * seg_w)
    brk = np.flatnonzero(seg[1:] != seg[:-1] + 1) + 1
    lo = layout.starts[seg[np.concatenate(([0], brk))]] - 2
    lo[0] += 2
    hi = layout.ends[seg[np.concatenate((brk - 1, [n - 1]))]]
    scan = memoryview(layout.data)
    out = bytearray().join(
        [head, *[scan[a:b] for a, b in zip(lo.tolist(), hi.tolist(), strict=True)], b"\xff\xd9"]
    )
    if n > 1:
        lens = layout.ends[seg[:-1]] - layout.starts[seg[:-1]]
        at = len(head) + np.cumsum(lens) + 2 * np.arange(1, n) - 1
        np.frombuffer(out, dtype=np.uint8)[at] = 0xD0 + (np.arange(n - 1) & 7)
    return bytes(out)


def _paste_numpy(layout: JpegLayout, canvas: np.ndarray, segments: np.ndarray, strip) -> None:
    """paste's numpy form (before the kernel)."""
    seg_w, seg_h = layout.segment_px
    grid = canvas.reshape(layout.mcu_rows, seg_h, layout.per_row, seg_w).transpose(0, 2, 1, 3)
    grid[segments // layout.per_row, segments % layout.per_row] = strip.reshape(
        len(segments), seg_h, seg_w
    )


@pytest.mark.parametrize("interval", [1, 2, 4, 16])
def test_splices_are_the_numpy_forms_bytes(interval: int) -> None:
    """Single segments, runs, gaps, the first and the last, repeats (the padding of a
    splice's last row), several to a row: the same bytes, which decode."""
    h, w = 64, 8 * interval * 6
    layout = jpeg_layout(encode(_scene(h, w, interval), "jpeg", 80, restart_interval_mcu=interval))
    assert layout is not None
    n_all = len(layout.starts)
    rng = np.random.default_rng(interval)
    cases = [np.array([0]), np.array([n_all - 1]), np.arange(n_all), np.array([0, 1, 2, 5, 6, 9])]
    for n in (1, 2, 3, 7, 8, 9, 17, n_all // 2):
        cases.append(np.sort(rng.choice(n_all, size=n, replace=False)))
    for seg in cases:
        assert splice(layout, seg) == _splice_numpy(layout, seg)
        for across in (2, 3):
            if seg[-1] == 0:
                # segment 0 repeated: the numpy form copied the SOS header's last two
                # bytes for its marker (no 0xFF); _decoded never pads a single segment
                continue
            part = np.concatenate((seg, np.full(-len(seg) % across, seg[-1])))
            got = jr._splice(layout, part, across).tobytes()
            assert got == _splice_numpy(layout, part, across)
    assert decode(splice(layout, np.arange(n_all))).shape == (8 * n_all, 8 * interval)
    for bad in (np.array([-1]), np.array([0, n_all])):
        with pytest.raises(ParameterError, match="segments"):
            splice(layout, bad)


@pytest.mark.parametrize("interval", [1, 3, 16])
def test_pasted_and_decoded_segments_are_the_numpy_forms(interval: int) -> None:
    """paste and decode_into put every segment where the numpy form's fancy indexing put
    it, nothing else changed (strips in any memory order)."""
    h, w = 77, 8 * interval * 5 - 3
    data = encode(_scene(h, w, 7 * interval), "jpeg", 90, restart_interval_mcu=interval)
    layout = jpeg_layout(data)
    assert layout is not None
    full = decode(data)
    n_all = len(layout.starts)
    seg_w = 8 * interval
    rng = np.random.default_rng(interval)
    for n in (1, 2, 5, n_all):
        seg = np.sort(rng.choice(n_all, size=n, replace=False))
        strip = rng.integers(0, 256, (8 * n, seg_w), dtype=np.uint8)
        for s in (strip, np.asfortranarray(strip)):
            want = blank_canvas(layout, 17)
            _paste_numpy(layout, want, seg, s)
            got = blank_canvas(layout, 17)
            paste(layout, got, seg, s)
            np.testing.assert_array_equal(got, want)
        want = blank_canvas(layout, 3)
        _paste_numpy(layout, want, seg, decode_segments(layout, seg))
        covered = np.zeros(want.shape, dtype=bool)
        _paste_numpy(layout, covered, seg, np.ones((8 * n, seg_w), dtype=bool))
        np.testing.assert_array_equal(want[:h, :w][covered[:h, :w]], full[covered[:h, :w]])
        got = blank_canvas(layout, 3)
        decode_into(layout, got, seg)
        np.testing.assert_array_equal(got, want)
    canvas = blank_canvas(layout, 0)
    with pytest.raises(ParameterError, match="segments"):
        paste(layout, canvas, np.array([n_all]), np.zeros((8, seg_w), np.uint8))
    with pytest.raises(ParameterError, match="strip"):
        paste(layout, canvas, np.array([0]), np.zeros((16, seg_w), np.uint8))
    with pytest.raises(ParameterError, match="canvas"):
        decode_into(layout, np.asfortranarray(canvas), np.array([0]))


@pytest.mark.parametrize("interval", [1, 4, 16])
def test_filled_segments_are_the_numpy_forms(interval: int) -> None:
    """fill_segments sets the flagged segments (runs of them and single ones, the rows'
    ends) to the value, every other pixel as it was."""
    h, w = 45, 8 * interval * 6
    layout = jpeg_layout(encode(_scene(h, w, 3 * interval), "jpeg", 90, interval))
    assert layout is not None
    n_all = len(layout.starts)
    seg_w = 8 * interval
    rng = np.random.default_rng(interval + 5)
    for density in (0.0, 0.1, 0.5, 1.0):
        hit = rng.random(n_all) < density
        canvas = rng.integers(0, 256, (8 * layout.mcu_rows, layout.per_row * seg_w), np.uint8)
        want = canvas.copy()
        blocks = want.reshape(layout.mcu_rows, 8, layout.per_row, seg_w)
        rows, cols = np.divmod(np.flatnonzero(hit), layout.per_row)
        blocks[rows, :, cols, :] = 201
        fill_segments(layout, canvas, hit, 201)
        np.testing.assert_array_equal(canvas, want)
    canvas = blank_canvas(layout, 0)
    with pytest.raises(ParameterError, match="hit"):
        fill_segments(layout, canvas, np.ones(n_all + 1, dtype=bool), 1)
    with pytest.raises(ParameterError, match="fill"):
        fill_segments(layout, canvas, np.ones(n_all, dtype=bool), 256)
    with pytest.raises(ParameterError, match="canvas"):
        fill_segments(layout, canvas[:8], np.ones(n_all, dtype=bool), 1)
