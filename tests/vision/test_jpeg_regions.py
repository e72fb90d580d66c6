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


def _assert_broken_markers_give_no_layout(data: bytes, segment: int) -> None:
    """``data`` has a layout; with the restart marker after ``segment`` lost (its two
    bytes cut out) or renumbered, or the file cut short, it has none."""
    layout = jpeg_layout(data)
    assert layout is not None
    at = int(layout.ends[segment])
    assert jpeg_layout(data[:at] + data[at + 2 :]) is None
    swapped = bytearray(data)
    swapped[at + 1] ^= 0x01
    assert jpeg_layout(bytes(swapped)) is None
    assert jpeg_layout(data[: len(data) // 2]) is None


def test_jpegs_that_cannot_be_split_have_no_layout() -> None:
    img = _scene(240, 320, seed=5)
    assert jpeg_layout(encode(img, "jpeg", 90, restart_interval_mcu=0)) is None  # no DRI
    assert jpeg_layout(encode(img, "png")) is None
    ok, prog = cv2.imencode(
        ".jpg", img, [cv2.IMWRITE_JPEG_PROGRESSIVE, 1, cv2.IMWRITE_JPEG_RST_INTERVAL, 4]
    )
    assert ok and jpeg_layout(bytes(prog)) is None
    # colour with Y sampled 4 x 1 (4:1:1): an MCU of 32 x 8 px, not split
    colour = cv2.imencode(
        ".jpg",
        np.dstack([img] * 3),
        [
            cv2.IMWRITE_JPEG_RST_INTERVAL,
            1,
            cv2.IMWRITE_JPEG_SAMPLING_FACTOR,
            cv2.IMWRITE_JPEG_SAMPLING_FACTOR_411,
        ],
    )[1]
    assert jpeg_layout(bytes(colour)) is None
    # an interval that does not divide the 40-MCU row: segments wrap rows
    assert jpeg_layout(encode(img, "jpeg", 90, restart_interval_mcu=7)) is None
    data = encode(img, "jpeg", 90, restart_interval_mcu=8)
    assert jpeg_layout(data) is not None
    _assert_broken_markers_give_no_layout(data, 10)
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


# -- colour (YCbCr) JPEGs: a colour camera's, decoded gray as their Y component ---------


def _colour_scene(h: int, w: int, seed: int) -> np.ndarray:
    """A BGR image whose three channels hold different textures (so the chroma blocks
    differ from the luma's) and a bright slanted bar, with noise."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:h, 0:w]
    b = 70 + 50 * np.sin(xx / 13.0) * np.cos(yy / 7.0)
    g = 110 + 40 * np.cos(xx / 5.0 + yy / 11.0)
    r = 90 + 60 * np.sin(yy / 3.0 - xx / 29.0)
    img = np.dstack([b, g, r]) + rng.normal(0, 12, (h, w, 3))
    img[np.abs((yy - 0.3 * xx) - h / 2) < 7] = (250, 200, 230)
    return np.clip(img, 0, 255).astype(np.uint8)


# OpenCV's sampling factors (Y's H x V): 4:2:0 is its default
_CV_SAMPLING = {
    "4:2:0": (cv2.IMWRITE_JPEG_SAMPLING_FACTOR_420, (2, 2)),
    "4:2:2": (cv2.IMWRITE_JPEG_SAMPLING_FACTOR_422, (2, 1)),
    "4:4:4": (cv2.IMWRITE_JPEG_SAMPLING_FACTOR_444, (1, 1)),
    "4:4:0": (cv2.IMWRITE_JPEG_SAMPLING_FACTOR_440, (1, 2)),
}
# Pillow's ``subsampling``: 0 is 4:4:4, 1 is 4:2:2, 2 is 4:2:0
_PIL_SAMPLING = {"4:4:4": (0, (1, 1)), "4:2:2": (1, (2, 1)), "4:2:0": (2, (2, 2))}


def _colour_jpeg(
    img: np.ndarray, encoder: str, sampling: str, interval: int | None, quality: int
) -> tuple[bytes, tuple[int, int]]:
    """``img`` (BGR) as a colour JPEG by OpenCV or Pillow, a restart marker every
    ``interval`` MCUs (None: every MCU row, Pillow's ``restart_marker_rows``); and Y's
    sampling factors (H, V)."""
    if encoder == "opencv":
        params = [cv2.IMWRITE_JPEG_QUALITY, quality, cv2.IMWRITE_JPEG_RST_INTERVAL, interval]
        if sampling != "default":
            params += [cv2.IMWRITE_JPEG_SAMPLING_FACTOR, _CV_SAMPLING[sampling][0]]
        ok, buf = cv2.imencode(".jpg", img, params)
        assert ok
        return bytes(buf), _CV_SAMPLING["4:2:0" if sampling == "default" else sampling][1]
    from PIL import Image

    out = io.BytesIO()
    marks = {"restart_marker_rows": 1} if interval is None else {"restart_marker_blocks": interval}
    sub, hv = _PIL_SAMPLING[sampling]
    Image.fromarray(img[:, :, ::-1]).save(out, "JPEG", quality=quality, subsampling=sub, **marks)
    return out.getvalue(), hv


def _put_reduced(
    layout, segments: np.ndarray, strip: np.ndarray, r: int, shape: tuple[int, int]
) -> tuple[np.ndarray, np.ndarray]:
    """A reduced splice's segments (one to a row) in their place in an image ``shape``,
    and where they are."""
    seg_w, seg_h = layout.segment_px[0] // r, layout.segment_px[1] // r
    canvas = np.zeros((layout.mcu_rows * seg_h, layout.per_row * seg_w), np.uint8)
    placed = np.zeros(canvas.shape, bool)
    for j, s in enumerate(segments.tolist()):
        row, col = divmod(s, layout.per_row)
        at = np.s_[row * seg_h : (row + 1) * seg_h, col * seg_w : (col + 1) * seg_w]
        canvas[at] = strip[j * seg_h : (j + 1) * seg_h]
        placed[at] = True
    return canvas[: shape[0], : shape[1]], placed[: shape[0], : shape[1]]


@pytest.mark.parametrize(
    ("encoder", "sampling", "h", "w", "interval", "quality"),
    [
        ("opencv", "default", 1538, 2050, 1, 90),  # not whole MCUs; 129 MCUs to a row
        ("opencv", "default", 1536, 2048, RST_INTERVAL_MCU, 90),  # the camera driver's
        ("opencv", "default", 1538, 2050, 43, 75),
        ("opencv", "4:2:2", 483, 645, 41, 85),  # 41 MCUs of 16 x 8 to a row
        ("opencv", "4:4:4", 483, 645, 3, 95),  # 81 MCUs of 8 x 8
        ("opencv", "4:4:0", 483, 645, 27, 80),  # 81 MCUs of 8 x 16
        ("opencv", "4:2:0", 101, 203, 13, 90),
        ("pillow", "4:2:0", 1538, 2050, 3, 90),
        ("pillow", "4:2:2", 483, 645, None, 85),  # a restart marker every MCU row
        ("pillow", "4:4:4", 483, 645, 27, 70),
        ("pillow", "4:2:0", 101, 203, None, 60),
    ],
)
def test_colour_segments_decode_to_the_full_gray_decodes_pixels(
    encoder: str, sampling: str, h: int, w: int, interval: int | None, quality: int
) -> None:
    """YCbCr JPEGs by two encoders, every sampling of Y by 1 or 2 each way, sizes not a
    multiple of the MCU, several intervals: any set of segments decodes bit for bit as
    the whole gray decode shows those pixels; a splice's 1/2 and 1/4 decodes as the
    whole reduced decode."""
    img = _colour_scene(h, w, seed=h + w + quality)
    data, (hs, vs) = _colour_jpeg(img, encoder, sampling, interval, quality)
    full = decode(data)
    assert full.shape == (h, w)
    layout = jpeg_layout(data)
    assert layout is not None
    mcu_w, mcu_h = 8 * hs, 8 * vs
    assert (layout.mcu_w_px, layout.mcu_h_px) == (mcu_w, mcu_h)
    k = -(-w // mcu_w) if interval is None else interval
    assert (layout.width_px, layout.height_px, layout.interval) == (w, h, k)
    assert layout.per_row * k == -(-w // mcu_w) and layout.mcu_rows == -(-h // mcu_h)
    assert layout.segment_px == (k * mcu_w, mcu_h)
    assert layout.blocks_shape == (layout.mcu_rows * vs, layout.per_row * k * hs)
    n_seg = len(layout.starts)
    assert n_seg == layout.per_row * layout.mcu_rows
    rng = np.random.default_rng(w + k)
    for _ in range(3):
        mask = np.zeros((h, w), dtype=bool)
        for _ in range(3):
            r0, c0 = int(rng.integers(0, h - 5)), int(rng.integers(0, w - 5))
            mask[r0 : r0 + int(rng.integers(1, 200)), c0 : c0 + int(rng.integers(1, 300))] = True
        segs = segments_covering(layout, mask)
        got = decode_region(layout, segs, fill=0)
        # the segments' pixels: the mask's, and nothing outside the segments touched
        canvas = blank_canvas(layout, 0)
        seg_w, seg_h = layout.segment_px
        paste(layout, canvas, segs, np.ones((seg_h * len(segs), seg_w), np.uint8))
        covered = canvas[:h, :w] == 1
        assert covered[mask].all()
        np.testing.assert_array_equal(got[covered], full[covered])
        np.testing.assert_array_equal(got[~covered], 0)
    everything = decode_region(layout, np.arange(n_seg), fill=0)
    np.testing.assert_array_equal(everything, full)
    # reduced: a splice of some segments (one to a row) as the whole reduced decode
    segs = np.sort(rng.choice(n_seg, size=min(n_seg, 60), replace=False))
    spliced = splice(layout, segs)
    for r in (2, 4):
        whole = decode_reduced(data, r)
        placed, where = _put_reduced(layout, segs, decode_reduced(spliced, r), r, whole.shape)
        assert where.any()
        np.testing.assert_array_equal(placed[where], whole[where])


def test_colour_segment_hits_are_the_segments_holding_a_block() -> None:
    """A segment of a colour JPEG is ``interval * H`` blocks across and ``V`` down: hit
    exactly when one of them is set, for every sampling."""
    img = _colour_scene(70, 8 * 2 * 4 * 3, seed=3)
    for sampling in ("4:2:0", "4:2:2", "4:4:4", "4:4:0"):
        data, (hs, vs) = _colour_jpeg(img, "opencv", sampling, 4, 80)
        layout = jpeg_layout(data)
        assert layout is not None
        rows, cols = layout.blocks_shape
        across, down = 4 * hs, vs
        rng = np.random.default_rng(hs * 10 + vs)
        for density in (0.0, 0.02, 0.3, 1.0):
            blocks = rng.random((rows, cols)) < density
            expected = [
                bool(blocks[r * down : (r + 1) * down, c * across : (c + 1) * across].any())
                for r in range(layout.mcu_rows)
                for c in range(layout.per_row)
            ]
            for mask in (blocks, np.asfortranarray(blocks), blocks.astype(np.uint8)):
                assert segment_hits(layout, mask).tolist() == expected
        if (hs, vs) != (1, 1):  # a mask of MCUs, not of blocks
            with pytest.raises(ValueError, match="blocks"):
                segment_hits(layout, np.zeros((layout.mcu_rows, layout.per_row * 4), dtype=bool))
        if vs == 2:  # the image's own 9 block rows are not the 5 MCU rows' 10
            assert rows == 10
            with pytest.raises(ValueError, match="blocks"):
                segment_hits(layout, np.zeros((-(-70 // 8), cols), dtype=bool))


def _set_component_ids(data: bytes, ids: bytes) -> bytes:
    """A 3-component JPEG with its components' IDs replaced in the frame and scan
    headers."""
    out = bytearray(data)
    sof = data.index(b"\xff\xc0")
    sos = data.index(b"\xff\xda")
    for c in range(3):
        out[sof + 10 + 3 * c] = ids[c]
        out[sos + 5 + 2 * c] = ids[c]
    return bytes(out)


def test_colour_jpegs_that_cannot_be_split_have_no_layout() -> None:
    """Colour JPEGs whose gray decode is not their first component's blocks alone, or
    whose MCUs are not 8 or 16 px a side: no layout (decoded whole)."""
    from PIL import Image

    img = _colour_scene(96, 128, seed=4)
    data, _ = _colour_jpeg(img, "opencv", "default", 2, 90)
    assert jpeg_layout(data) is not None
    # RGB by the components' IDs ("R", "G", "B"), or IJG's big-gamut YCC (1, 0x22, 0x23):
    # with a JFIF marker, as here, libjpeg-turbo (OpenCV's) still takes them for YCbCr but
    # IJG's libjpeg 9 goes by the IDs; refused where either would not decode Y alone
    assert jpeg_layout(_set_component_ids(data, b"RGB")) is None
    assert jpeg_layout(_set_component_ids(data, b"\x01\x22\x23")) is None
    assert jpeg_layout(_set_component_ids(data, b"\x04\x05\x06")) is not None  # YCbCr
    # an Adobe marker (APP14) saying YCbCr (transform 1): split, bit for bit; saying RGB
    # (0) or YCCK (2), or too short to say: not split (here too the JFIF marker wins for
    # libjpeg-turbo, not for libjpeg 9)
    for transform, split in ((1, True), (0, False), (2, False), (None, False)):
        body = b"Adobe\x00\x64\x00\x00\x00\x00" + (b"" if transform is None else bytes([transform]))
        adobe = data[:2] + b"\xff\xee" + (len(body) + 2).to_bytes(2, "big") + body + data[2:]
        layout = jpeg_layout(adobe)
        assert (layout is not None) == split, transform
        if layout is not None:
            everything = decode_region(layout, np.arange(len(layout.starts)), fill=0)
            np.testing.assert_array_equal(everything, decode(adobe))
    rgb = Image.fromarray(img[:, :, ::-1])
    for kw in (
        {"keep_rgb": True},  # RGB: an Adobe marker saying no colour transform
        {"subsampling": 2},
    ):
        out = io.BytesIO()
        rgb.save(out, "JPEG", quality=90, restart_marker_blocks=2, **kw)
        assert (jpeg_layout(out.getvalue()) is None) == ("keep_rgb" in kw)
    cmyk = io.BytesIO()
    rgb.convert("CMYK").save(cmyk, "JPEG", quality=90, restart_marker_blocks=2)
    assert b"\xff\xdd" in cmyk.getvalue() and jpeg_layout(cmyk.getvalue()) is None
    # Y sampled 4 x 1 (4:1:1), progressive, no restart interval
    for params in (
        [cv2.IMWRITE_JPEG_SAMPLING_FACTOR, cv2.IMWRITE_JPEG_SAMPLING_FACTOR_411],
        [cv2.IMWRITE_JPEG_PROGRESSIVE, 1],
    ):
        ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_RST_INTERVAL, 1, *params])
        assert ok and jpeg_layout(bytes(buf)) is None
    ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 90])
    assert ok and jpeg_layout(bytes(buf)) is None
    # an interval that does not divide the row of 8 MCUs of 16 x 16
    ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_RST_INTERVAL, 3])
    assert ok and jpeg_layout(bytes(buf)) is None
    # the scan of one component (Y alone) in a 3-component frame: another scan follows
    sos = data.index(b"\xff\xda")
    one = bytearray(data)
    one[sos + 2 : sos + 4] = (6 + 2).to_bytes(2, "big")
    one[sos + 4] = 1
    one[sos + 7 : sos + 12] = b""
    one[sos + 7 : sos + 7] = b"\x00\x3f\x00"
    assert jpeg_layout(bytes(one)) is None
    _assert_broken_markers_give_no_layout(data, 5)


def test_colour_headers_damaged_give_no_layout_a_decode_error_or_the_whole_decode() -> None:
    """Bytes of a colour JPEG's headers (frame, scan, tables, APP markers) overwritten at
    random: no layout, a decode error, or every segment decoded bit for bit as the damaged
    JPEG's whole decode (never another picture than libjpeg's own of those bytes)."""
    img = _colour_scene(120, 256, seed=5)
    seen = {"none": 0, "error": 0, "same": 0}
    for sampling in ("4:2:0", "4:2:2", "4:4:0"):
        data, _ = _colour_jpeg(img, "opencv", sampling, 2, 85)
        layout = jpeg_layout(data)
        assert layout is not None
        head = len(layout.header)
        rng = np.random.default_rng(len(sampling) + head)
        for _ in range(120):
            bad = bytearray(data)
            for _ in range(int(rng.integers(1, 3))):
                bad[int(rng.integers(2, head))] = int(rng.integers(0, 256))
            damaged = jpeg_layout(bytes(bad))
            if damaged is None:
                seen["none"] += 1
                continue
            try:
                parts = decode_region(damaged, np.arange(len(damaged.starts)), fill=0)
            except DecodeError:
                seen["error"] += 1
                continue
            np.testing.assert_array_equal(parts, decode(bytes(bad)))
            seen["same"] += 1
    assert min(seen.values()) > 0, seen
