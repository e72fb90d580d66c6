"""The recording's reduced frames made from the measured region (``RegionPreviews``): every
reduced block near the measured beam and hub is this frame's, exactly, and each other
block an earlier frame's since the last whole one, exactly, clear of that frame's beam
and hub (no ghost), the whole frame's region decoded once.

The frames are noise written by ``cv2`` directly (not beambench's renderer or codec
defaults): 960 x 632 px, a restart marker every 6 MCUs, quality 77, each frame different
everywhere, so a block taken from the wrong frame cannot pass; gray, and colour (BGR
noise, each channel its own, at OpenCV's sampling factors: the previews are of the gray
decode, the Y component).
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from pipelines.review.previews import (
    MARGIN_PX,
    WHOLE_EVERY_FRAMES,
    RegionPreviews,
    region_blocks,
)
from vision import FrameMeasurement
from vision.codec import preview
from vision.jpeg_regions import (
    JpegLayout,
    jpeg_layout,
    reduced_canvas_shape,
    segments_of_blocks,
)

W, H = 960, 632  # the reduced frame's segments do not tile it: encoded whole
PX_M = 2000.0  # px per m along the fabricated centre lines


_SAMPLING = {
    "4:1:1": cv2.IMWRITE_JPEG_SAMPLING_FACTOR_411,
    "4:2:0": cv2.IMWRITE_JPEG_SAMPLING_FACTOR_420,
    "4:2:2": cv2.IMWRITE_JPEG_SAMPLING_FACTOR_422,
    "4:4:0": cv2.IMWRITE_JPEG_SAMPLING_FACTOR_440,
    "4:4:4": cv2.IMWRITE_JPEG_SAMPLING_FACTOR_444,
}


def _jpeg(
    seed: int, interval: int = 6, size: tuple[int, int] = (W, H), colour: str | None = None
) -> bytes:
    """A gray JPEG of noise, or (``colour``: the sampling) a colour one."""
    rng = np.random.default_rng(seed)
    w, h = size
    shape = (h, w) if colour is None else (h, w, 3)
    image = cv2.GaussianBlur(rng.integers(0, 256, shape, dtype=np.uint8), (5, 5), 1.5)
    params = [cv2.IMWRITE_JPEG_QUALITY, 77, cv2.IMWRITE_JPEG_RST_INTERVAL, interval]
    if colour is not None:
        params += [cv2.IMWRITE_JPEG_SAMPLING_FACTOR, _SAMPLING[colour]]
    ok, buf = cv2.imencode(".jpg", image, params)
    assert ok
    return bytes(buf)


def _measured(
    angle_rad: float, ok: bool = True, back: tuple[float, float] = (300.0, 100.0)
) -> FrameMeasurement:
    """A measurement that places a hub from ``back`` and a beam on from it."""
    if not ok:
        return FrameMeasurement(ok=False, reason="too noisy")
    origin = np.array(back)
    clamp = origin + 80.0 * np.array([math.cos(angle_rad), math.sin(angle_rad)])
    s = np.linspace(0.0, 400.0, 12)
    line = clamp + s[:, None] * np.array([math.cos(angle_rad), math.sin(angle_rad)])
    line[:, 0] += 0.0002 * s**2  # bent
    return FrameMeasurement(
        ok=True,
        hub_line_px=np.vstack([origin, clamp]),
        centreline_px=line,
        centreline_plane_m=line / PX_M,
        hub_width_m=30.0 / PX_M,
        beam_width_m=10.0 / PX_M,
    )


def _blocks(image: np.ndarray) -> np.ndarray:
    """[block row, block col, 8, 8] of a reduced image (cut to whole blocks)."""
    h, w = (image.shape[0] // 8) * 8, (image.shape[1] // 8) * 8
    return image[:h, :w].reshape(h // 8, 8, w // 8, 8).transpose(0, 2, 1, 3)


def _decoded(data: bytes) -> np.ndarray:
    image = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_GRAYSCALE)
    assert image is not None
    return np.asarray(image)


def _near(m: FrameMeasurement, rows: int, cols: int, block_px: int) -> np.ndarray:
    """The blocks ([rows, cols] of ``block_px`` full-size px a side) with a pixel within
    :data:`MARGIN_PX` of the measured hub's or beam's edges, less a pixel: from distances
    to the lines drawn thin at full size (``region_blocks`` must hold at least these)."""
    hub, line = np.asarray(m.hub_line_px), np.asarray(m.centreline_px)
    h, w = max(rows * block_px, H + 64), max(cols * block_px, W + 64)
    near = np.zeros((h, w), bool)
    for pts, width in ((hub, m.hub_search_width_m), (line, m.beam_width_m)):
        half = (0.5 * width * PX_M if math.isfinite(width) else 0.0) + MARGIN_PX
        image = np.full((h, w), 255, np.uint8)
        fixed = np.round(pts * 16).astype(np.int32).reshape(-1, 1, 2)
        cv2.polylines(image, [fixed], False, 0, 1, cv2.LINE_8, shift=4)
        near |= cv2.distanceTransform(image, cv2.DIST_L2, cv2.DIST_MASK_PRECISE) <= half - 1
    cut = near[: rows * block_px, : cols * block_px]
    return np.asarray(cut.reshape(rows, block_px, cols, block_px).any(axis=(1, 3)))


@pytest.mark.parametrize(
    ("r", "interval", "failures", "colour"),
    [
        (2, 6, False, None),
        (4, 8, False, None),
        (2, 6, True, None),
        (2, 3, False, "4:2:0"),  # segments of 48 x 16 px, 40 MCU rows (632 px: 39.5)
        (4, 4, True, "4:2:0"),  # the camera driver's: 64 x 16 px
        (2, 3, False, "4:2:2"),  # 48 x 8 px
        (2, 6, False, "4:4:0"),  # 48 x 16 px
        (4, 8, False, "4:4:4"),  # 64 x 8 px
    ],
)
def test_each_block_is_this_frames_or_an_earlier_ones_clear_of_its_beam(
    r: int, interval: int, failures: bool, colour: str | None
) -> None:
    shower = RegionPreviews(r)
    frames = [_jpeg(100 + k, interval, colour=colour) for k in range(WHOLE_EVERY_FRAMES + 3)]
    layout = jpeg_layout(frames[0])
    mcu_w = 16 if colour in ("4:2:0", "4:2:2") else 8
    assert layout is not None and layout.segment_px[0] == interval * mcu_w
    oks = [True] * len(frames)
    if failures:
        oks[1] = oks[2] = False  # not measured: shown whole, not kept as the whole frame
    # the beam swings on, faster in turn: its earlier places are left behind
    measured = [_measured(0.9 + 0.02 * k * k, ok) for k, ok in enumerate(oks)]
    mine = [_blocks(_decoded(preview(data, r))) for data in frames]
    rows, cols = mine[0].shape[:2]
    near = [_near(m, rows, cols, 8 * r) if m.ok else None for m in measured]
    last_whole = -1
    kinds = []
    for k, (data, m) in enumerate(zip(frames, measured, strict=True)):
        out, encoding, scale = shower.show(data, "jpeg", m)
        assert encoding == "jpeg" and scale == 1.0 / r
        got = _decoded(out)
        assert got.shape == (math.ceil(H / r), math.ceil(W / r))
        gb = _blocks(got)
        if np.array_equal(gb, mine[k]):
            kinds.append("whole")
            if m.ok:
                last_whole = k
            continue
        kinds.append("region")
        assert 0 <= last_whole and k - last_whole < WHOLE_EVERY_FRAMES
        this = np.all(gb == mine[k], axis=(2, 3))
        # the measured beam and hub, and a margin about them: this frame's
        assert np.all(this[near[k]]), f"frame {k}: the region shows another frame"
        # every other block is an earlier frame's since the last whole one, clear of
        # that frame's beam and hub: no ghost of them
        clear = this.copy()
        for j in range(last_whole, k):
            near_j = near[j]
            if near_j is not None:
                clear |= np.all(gb == mine[j], axis=(2, 3)) & ~near_j
        assert np.all(clear), f"frame {k}: a block from no frame, or an old beam's"
        assert 0.02 < np.mean(this) < 0.8  # most of the frame is earlier frames'
    # whole at the start and then every WHOLE_EVERY_FRAMES-th frame (measured or not)
    assert [k for k, kind in enumerate(kinds) if kind == "whole"] == (
        [0, 1, 2, WHOLE_EVERY_FRAMES] if failures else [0, WHOLE_EVERY_FRAMES]
    )
    assert shower.whole_frames == kinds.count("whole")


def _segments_under(layout: JpegLayout, region: np.ndarray, r: int) -> int:
    """How many segments hold any of the reduced blocks given ([row, col] of the 1/``r``
    image's 8 x 8 blocks)."""
    rows, cols = layout.blocks_shape
    full = np.repeat(np.repeat(region, r, axis=0), r, axis=1)[:rows, :cols]
    return len(segments_of_blocks(layout, full))


@pytest.mark.parametrize(("r", "interval", "colour"), [(2, 6, None), (4, 4, "4:2:0")])
def test_a_moved_beam_leaves_no_ghost_and_its_old_place_is_decoded_once(
    r: int, interval: int, colour: str | None
) -> None:
    frames = [_jpeg(500 + k, interval, colour=colour) for k in range(5)]
    layout = jpeg_layout(frames[0])
    assert layout is not None
    before, after = _measured(0.4), _measured(1.4)  # the beam moved by a radian
    shower = RegionPreviews(r)
    shown = [
        _blocks(_decoded(shower.show(d, "jpeg", before if k == 0 else after)[0]))
        for k, d in enumerate(frames)
    ]
    assert shower.whole_frames == 1 and shower.region_frames == len(frames) - 1
    mine = [_blocks(_decoded(preview(d, r))) for d in frames]
    rows, cols = mine[0].shape[:2]
    canvas_rows, canvas_cols = reduced_canvas_shape(layout, r)
    grid = (math.ceil(canvas_rows / 8), canvas_cols // 8)
    now = region_blocks(after, grid, 8 * r)
    then = region_blocks(before, grid, 8 * r)
    assert now is not None and then is not None
    # where the beam was and is no longer: the first frame after shows it, then that
    # frame's pixels stay (where no segment of this frame's region is decoded again),
    # never the whole frame's beam
    left = _near(before, rows, cols, 8 * r) & ~now[:rows, :cols]
    assert left.sum() > 20
    for k in range(1, len(frames)):
        this, first = (np.all(shown[k] == mine[j], axis=(2, 3))[left] for j in (k, 1))
        assert np.all(this | first), f"frame {k}"
        assert np.mean(first) > 0.5
        assert not np.any(np.all(shown[k] == mine[0], axis=(2, 3))[left]), f"frame {k}"
    # the whole frame's region decoded once, on the first frame after it
    n = len(layout.starts)
    decoded = [round(f * n) for f in shower.region_fraction]
    alone, both = _segments_under(layout, now, r), _segments_under(layout, now | then, r)
    assert alone < both
    assert decoded == [both] + [alone] * (len(frames) - 2)


def test_frames_it_cannot_decode_in_parts_are_whole() -> None:
    # no restart markers; markers every 5 MCUs (cuts a 1/2 block); PNG; whole mode
    cases = [
        (RegionPreviews(2), _jpeg(7, interval=0), "jpeg"),
        (RegionPreviews(2), _jpeg(7, interval=5), "jpeg"),
        (RegionPreviews(4), _jpeg(7, interval=6), "jpeg"),
        (RegionPreviews(2, whole=True), _jpeg(7), "jpeg"),
        (RegionPreviews(2), _jpeg(7, interval=5, colour="4:4:4"), "jpeg"),  # 40 px segments
        (RegionPreviews(4), _jpeg(7, interval=3, colour="4:2:0"), "jpeg"),  # 48 px
        (RegionPreviews(2), _jpeg(7, interval=6, colour="4:1:1"), "jpeg"),  # not split
    ]
    png = bytes(cv2.imencode(".png", _decoded(_jpeg(8)))[1])
    cases.append((RegionPreviews(2), png, "png"))
    for shower, data, encoding in cases:
        for k in range(3):
            out, _, _ = shower.show(data, encoding, _measured(1.0 + 0.1 * k))
            assert out == preview(data, shower.reduction)
        assert shower.region_frames == 0


def test_a_region_needs_the_beam_and_hub_placed() -> None:
    shape = (79, 120)
    assert region_blocks(FrameMeasurement(ok=False), shape) is None
    m = _measured(1.0)
    under = region_blocks(m, shape)
    assert under is not None and 0 < under.mean() < 0.5
    # the margin reaches past the beam's edges: a block beside the tip is in
    tip = np.asarray(m.centreline_px)[-1]
    assert under[int(tip[1] // 8), int((tip[0] + 40) // 8)]
    assert not under[0, -1]
    # every block within the margin, at any block size, and not many more
    for block_px in (8, 16, 32):
        rows, cols = math.ceil(H / block_px), math.ceil(W / block_px)
        for angle in np.linspace(0.0, 2 * math.pi, 13):
            m = _measured(float(angle))
            near = _near(m, rows, cols, block_px)
            got = region_blocks(m, (rows, cols), block_px)
            assert got is not None and np.all(got[near]), (block_px, angle)
            assert got.sum() < 1.6 * near.sum(), (block_px, angle)
    with pytest.raises(ValueError, match="reduction"):
        RegionPreviews(3)


@pytest.mark.parametrize(
    ("r", "colour", "size", "interval"),
    [
        (2, None, (1024, 640), 8),
        (4, None, (1024, 640), 8),
        (2, "4:2:0", (1024, 640), 4),
        (4, "4:2:0", (1024, 640), 4),
        # the reduced frame not whole blocks (510 x 318, 255 x 159), the region at its
        # right and bottom edges: the encoder's padding there is its edge's pixels
        (2, None, (1020, 636), 2),
        (4, None, (1020, 636), 4),
    ],
)
def test_the_region_spliced_into_the_whole_frame_is_the_whole_frame_encoded(
    r: int,
    colour: str | None,
    size: tuple[int, int],
    interval: int,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # at 1/r the reduced frame's restart segments tile it, so only the segments the
    # region touches are encoded again
    frames = [_jpeg(300 + k, interval, size, colour) for k in range(8)]
    back = (300.0, 100.0) if size == (1024, 640) else (640.0, 330.0)
    measured = [_measured(0.5 + 0.07 * k, back=back) for k in range(len(frames))]
    spliced, whole = RegionPreviews(r), RegionPreviews(r)
    a = [spliced.show(d, "jpeg", m) for d, m in zip(frames, measured, strict=True)]
    assert spliced.spliced_frames == spliced.region_frames == len(frames) - 1
    import pipelines.review.previews as previews

    monkeypatch.setattr(previews, "_respliced", lambda *args: None)
    b = [whole.show(d, "jpeg", m) for d, m in zip(frames, measured, strict=True)]
    assert whole.spliced_frames == 0 and whole.region_frames == len(frames) - 1
    assert a == b


def test_the_region_drawn_in_its_box_is_the_region_drawn_whole(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # the lines are drawn in the box that holds them alone: the same blocks as drawn in
    # the whole mask, for lines inside, across the edges, far outside, short and long,
    # thin and thick
    import pipelines.review.previews as previews

    rng = np.random.default_rng(11)
    cases = []
    for k in range(300):
        w, h = int(rng.integers(200, 1400)), int(rng.integers(200, 1000))
        block_px = int(rng.choice([8, 16, 32]))
        spread = [1.0, 1.6, 4.0, 40.0][k % 4]  # where the hub is, in frame sizes
        start = np.array([w, h]) * (rng.random(2) * spread - (spread - 1) / 2)
        angle = rng.random() * 2 * math.pi
        along = np.array([math.cos(angle), math.sin(angle)])
        s = np.linspace(0.0, rng.random() * 1.2 * max(w, h), int(rng.choice([2, 3, 40])))
        line = start + s[:, None] * along + rng.normal(0.0, 3.0, (s.size, 2))
        px_m = 10 ** rng.uniform(2, 4)
        m = FrameMeasurement(
            ok=True,
            hub_line_px=np.vstack([start - 80.0 * along, start]),
            centreline_px=line,
            centreline_plane_m=line / px_m,
            hub_width_m=rng.random() * 60.0 / px_m,
            beam_width_m=float(rng.choice([rng.random() * 30.0, 3000.0, math.nan])) / px_m,
        )
        cases.append((m, (math.ceil(h / block_px), math.ceil(w / block_px)), block_px))
    boxed = [region_blocks(m, shape, block_px) for m, shape, block_px in cases]
    monkeypatch.setattr(previews, "_drawn_box", lambda lines, h, w, k: (0, h, 0, w))
    whole = [region_blocks(m, shape, block_px) for m, shape, block_px in cases]
    assert any(b is not None and b.any() for b in boxed)
    assert any(b is not None and not b.any() for b in boxed)  # some wholly outside
    for b, a in zip(boxed, whole, strict=True):
        assert a is not None and b is not None and np.array_equal(a, b)


@pytest.mark.parametrize("extra_words", [0, 3])
def test_segments_are_stacked_side_by_side_in_order(extra_words: int) -> None:
    # the segments to encode again, ``across`` to a row in the order given, from a
    # canvas as wide as its segments or wider
    from pipelines.review.previews import _stacked

    rows, per_row, words, across = 7, 5, 2, 3
    rng = np.random.default_rng(5)
    canvas = rng.integers(0, 256, (rows * 8, (per_row * words + extra_words) * 8), np.uint8)
    part = np.array([0, 3, 4, 9, 17, 18, 30, 34, 34], np.intp)
    got = _stacked(canvas, part, across, rows, per_row, words)
    seg_w = words * 8
    for n, s in enumerate(part.tolist()):
        r, c = divmod(s, per_row)
        want = canvas[r * 8 : r * 8 + 8, c * seg_w : (c + 1) * seg_w]
        g, a = divmod(n, across)
        assert np.array_equal(got[g * 8 : g * 8 + 8, a * seg_w : (a + 1) * seg_w], want)
    assert got.shape == (part.size // across * 8, across * seg_w) and got.flags.c_contiguous


def test_blocks_are_copied_whole_and_alone() -> None:
    from pipelines.review.previews import _copy_blocks

    rng = np.random.default_rng(6)
    src = rng.integers(0, 256, (6 * 8, 9 * 8), np.uint8)
    for contiguous in (True, False):
        dst = rng.integers(0, 256, src.shape, np.uint8)
        before = dst.copy()
        blocks = rng.random((6, 9)) < 0.3
        if contiguous:
            _copy_blocks(dst, src, blocks)
        else:  # the 4-d indexing, for arrays that are views
            wide = np.zeros((dst.shape[0], dst.shape[1] + 8), np.uint8)
            wide[:, :-8] = dst
            _copy_blocks(wide[:, :-8], src, blocks)
            dst = wide[:, :-8]
        mask = np.repeat(np.repeat(blocks, 8, axis=0), 8, axis=1)
        assert np.array_equal(dst[mask], src[mask])
        assert np.array_equal(dst[~mask], before[~mask])
