"""The compiled kernels of vision.jpeg_regions against the numpy forms they replaced (kept
here as the reference): the same layouts, the same bytes, the same pixels, on valid and
damaged JPEGs alike."""

from __future__ import annotations

import math
import struct

import numpy as np
import pytest

from vision.codec import MAX_SIDE_PX, encode
from vision.jpeg_regions import jpeg_layout


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
