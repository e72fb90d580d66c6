"""Restart-segment splicing: parts of a JPEG decoded alone, bit for bit as a full decode."""

from __future__ import annotations

import io

import cv2
import numpy as np
import pytest

from vision.codec import RST_INTERVAL_MCU, decode, encode
from vision.errors import DecodeError
from vision.jpeg_regions import (
    blank_canvas,
    decode_reduced,
    decode_region,
    decode_segments,
    jpeg_layout,
    paste,
    segment_hits,
    segments_covering,
    segments_of_blocks,
    splice,
)


def _scene(h: int, w: int, seed: int) -> np.ndarray:
    """Texture, a bright slanted bar and noise: every segment holds different data."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:h, 0:w]
    img = 50 + 30 * np.sin(xx / 37.0) * np.cos(yy / 23.0) + rng.normal(0, 6, (h, w))
    img[np.abs((yy - 0.4 * xx) - h / 3) < 9] = 225
    return np.clip(img, 0, 255).astype(np.uint8)


@pytest.mark.parametrize(
    ("h", "w", "quality", "interval"),
    [
        (480, 640, 90, 16),
        (483, 645, 75, 1),  # not whole MCUs: the last row and column are partial
        (600, 1024, 95, 32),
        (256, 384, 60, 48),  # 48 MCUs per row: one segment per row
        (1536, 2048, 90, RST_INTERVAL_MCU),
    ],
)
def test_spliced_segments_decode_to_the_full_decodes_pixels(
    h: int, w: int, quality: int, interval: int
) -> None:
    img = _scene(h, w, seed=h + w)
    data = encode(img, "jpeg", quality, restart_interval_mcu=interval)
    full = decode(data)
    layout = jpeg_layout(data)
    assert layout is not None
    assert (layout.width_px, layout.height_px, layout.interval) == (w, h, interval)
    assert len(layout.starts) == layout.per_row * layout.mcu_rows
    rng = np.random.default_rng(w)
    for _ in range(3):
        mask = np.zeros((h, w), dtype=bool)
        for _ in range(3):
            r0, c0 = int(rng.integers(0, h - 20)), int(rng.integers(0, w - 20))
            mask[r0 : r0 + int(rng.integers(5, 200)), c0 : c0 + int(rng.integers(5, 300))] = True
        segs = segments_covering(layout, mask)
        got = decode_region(layout, segs, fill=0)
        assert got.shape == full.shape
        np.testing.assert_array_equal(got[mask], full[mask])
        # nothing outside the segments is touched
        covered = np.zeros((h, w), dtype=bool)
        canvas = blank_canvas(layout, 0)
        paste(layout, canvas, segs, np.full((8 * len(segs), 8 * interval), 1, np.uint8))
        covered = canvas[:h, :w] == 1
        assert covered[mask].all()
        np.testing.assert_array_equal(got[~covered], 0)
    # every segment: the whole image
    everything = decode_region(layout, np.arange(len(layout.starts)), fill=0)
    np.testing.assert_array_equal(everything, full)


@pytest.mark.parametrize("interval", [1, 2, 3, 4, 8, 16, 24])
def test_segment_hits_are_the_segments_holding_a_block(interval: int) -> None:
    """Every interval (the word-wise paths for 1, 2, 4 and multiples of 8 MCUs, the
    general one otherwise), from a mask in any memory order: a segment is hit exactly
    when one of its blocks is set."""
    w = 8 * interval * 3
    data = encode(_scene(40, w, seed=interval), "jpeg", 80, restart_interval_mcu=interval)
    layout = jpeg_layout(data)
    assert layout is not None and layout.per_row == 3
    rng = np.random.default_rng(interval)
    for density in (0.0, 0.02, 0.3, 1.0):
        blocks = rng.random((5, 3 * interval)) < density
        expected = [
            bool(blocks[r, c * interval : (c + 1) * interval].any())
            for r in range(5)
            for c in range(3)
        ]
        for mask in (blocks, np.asfortranarray(blocks), blocks.astype(np.uint8)):
            assert segment_hits(layout, mask).tolist() == expected
        np.testing.assert_array_equal(segments_of_blocks(layout, blocks), np.flatnonzero(expected))
    with pytest.raises(ValueError, match="blocks"):
        segment_hits(layout, np.zeros((5, 2), dtype=bool))


@pytest.mark.parametrize("interval", [1, 4, 16])
def test_segments_decoded_side_by_side_and_in_several_splices(monkeypatch, interval) -> None:
    """Segments narrower than a splice's row are decoded several to a row (the last row
    filled up with a repeat); a splice taller than a JPEG may be (here: 2 rows) is split
    in several. The pixels are the full decode's, in the segments' order."""
    import vision.jpeg_regions as jr

    h, w = 72, 8 * interval * 5
    img = _scene(h, w, seed=interval)
    data = encode(img, "jpeg", 85, restart_interval_mcu=interval)
    full = decode(data)
    layout = jpeg_layout(data)
    assert layout is not None
    monkeypatch.setattr(jr, "_MAX_SEGMENTS", 2)
    monkeypatch.setattr(jr, "_ROW_PX", 8 * interval * 3)  # 3 segments to a row
    rng = np.random.default_rng(interval)
    for n in (1, 2, 5, 6, 7, 13, len(layout.starts)):
        segs = np.sort(rng.choice(len(layout.starts), size=n, replace=False))
        strip = decode_segments(layout, segs).reshape(n, 8, 8 * interval)
        for k, s in enumerate(segs.tolist()):
            r, c = divmod(s, layout.per_row)
            want = full[8 * r : 8 * r + 8, 8 * interval * c : 8 * interval * (c + 1)]
            np.testing.assert_array_equal(strip[k], want)
    np.testing.assert_array_equal(decode_region(layout, np.arange(len(layout.starts)), 0), full)


def test_other_decoders_read_our_jpegs() -> None:
    """Restart markers are baseline JPEG: OpenCV, its reduced decodes and Pillow read them,
    the same pixels as without markers."""
    img = _scene(480, 640, seed=4)
    with_rst = encode(img, "jpeg", 90)
    without = encode(img, "jpeg", 90, restart_interval_mcu=0)
    assert with_rst != without
    np.testing.assert_array_equal(decode(with_rst), decode(without))
    np.testing.assert_array_equal(decode_reduced(with_rst, 4), decode_reduced(without, 4))
    pil = pytest.importorskip("PIL.Image")
    with pil.open(io.BytesIO(with_rst)) as im:
        assert im.size == (640, 480)
        np.testing.assert_array_equal(np.asarray(im.convert("L")), decode(without))
    assert cv2.imdecode(np.frombuffer(with_rst, np.uint8), cv2.IMREAD_UNCHANGED).shape == (480, 640)


def test_jpegs_that_cannot_be_split_have_no_layout() -> None:
    img = _scene(240, 320, seed=5)
    assert jpeg_layout(encode(img, "jpeg", 90, restart_interval_mcu=0)) is None  # no DRI
    assert jpeg_layout(encode(img, "png")) is None
    ok, prog = cv2.imencode(
        ".jpg", img, [cv2.IMWRITE_JPEG_PROGRESSIVE, 1, cv2.IMWRITE_JPEG_RST_INTERVAL, 4]
    )
    assert ok and jpeg_layout(bytes(prog)) is None
    colour = cv2.imencode(".jpg", np.dstack([img] * 3), [cv2.IMWRITE_JPEG_RST_INTERVAL, 4])[1]
    assert jpeg_layout(bytes(colour)) is None
    # an interval that does not divide the 40-MCU row: segments wrap rows
    assert jpeg_layout(encode(img, "jpeg", 90, restart_interval_mcu=7)) is None
    data = encode(img, "jpeg", 90, restart_interval_mcu=8)
    assert jpeg_layout(data) is not None
    # a restart marker lost (its two bytes cut out), renumbered, or the file cut short
    layout = jpeg_layout(data)
    assert layout is not None
    at = int(layout.ends[10])
    assert jpeg_layout(data[:at] + data[at + 2 :]) is None
    swapped = bytearray(data)
    swapped[at + 1] ^= 0x01
    assert jpeg_layout(bytes(swapped)) is None
    assert jpeg_layout(data[: len(data) // 2]) is None
    assert jpeg_layout(b"") is None
    assert jpeg_layout(data[:300]) is None


def test_damaged_segments_are_a_decode_error_or_damage_in_that_segment_only() -> None:
    """A segment whose bytes are garbage: the splice either fails to decode (the
    package's DecodeError) or decodes with damage in that segment's pixels alone."""
    img = _scene(480, 640, seed=6)
    data = encode(img, "jpeg", 90)
    layout = jpeg_layout(data)
    assert layout is not None
    full = decode(data)
    seen_error = seen_damage = False
    for seed in range(40):
        bad = bytearray(data)
        s = 30 + seed
        a, b = int(layout.starts[s]), int(layout.ends[s])
        junk = np.random.default_rng(seed).integers(0, 256, b - a, dtype=np.uint8)
        junk[junk == 0xFF] = 0x7F  # no markers: the segment's length stays
        bad[a:b] = junk.tobytes()
        lay = jpeg_layout(bytes(bad))
        assert lay is not None
        segs = np.array([s - 1, s, s + 1])
        try:
            got = decode_region(lay, segs, fill=0)
        except DecodeError:
            seen_error = True
            continue
        region = np.zeros_like(full, dtype=bool)
        seg_w, seg_h = lay.segment_px
        for k in (s - 1, s + 1):
            r, c = divmod(k, lay.per_row)
            region[seg_h * r : seg_h * r + seg_h, seg_w * c : seg_w * c + seg_w] = True
        np.testing.assert_array_equal(got[region], full[region])
        seen_damage = seen_damage or bool(np.any(got != full))
    assert seen_damage or seen_error


def test_segment_count_and_reduced_decode_limits() -> None:
    img = _scene(240, 320, seed=7)
    data = encode(img, "jpeg", 90, restart_interval_mcu=8)
    layout = jpeg_layout(data)
    assert layout is not None
    with pytest.raises(ValueError, match="mask_px"):
        segments_covering(layout, np.zeros((10, 10), dtype=bool))
    with pytest.raises(ValueError, match="segments"):
        splice(layout, np.zeros(0, dtype=np.intp))
    assert decode_segments(layout, np.zeros(0, dtype=np.intp)).shape == (0, 64)
    with pytest.raises(ValueError, match="reduction"):
        decode_reduced(data, 3)
    with pytest.raises(DecodeError):
        decode_reduced(b"\xff\xd8 not a jpeg", 2)
    small = decode_reduced(data, 8)
    assert small.shape == (30, 40)


def test_marker_cost_is_small_at_the_capture_quality() -> None:
    """The markers' cost in bytes: 2 per segment and the padding to a byte, and the DC
    predictor restarting (the first block of a segment codes its DC in full); on a
    rendered 2048 x 1536 frame at quality 90 about 4 % (12 % at 75, measured in the
    README)."""
    img = _scene(1536, 2048, seed=8)
    with_rst = len(encode(img, "jpeg", 90))
    without = len(encode(img, "jpeg", 90, restart_interval_mcu=0))
    n_seg = (2048 // 8 // RST_INTERVAL_MCU) * (1536 // 8)
    assert with_rst > without
    # each segment costs its 2 marker bytes, under a byte of padding and a few bits of DC
    assert with_rst - without < n_seg * 6
