"""The recording's reduced frames made from the measured region (``RegionPreviews``): each
reduced block is this frame's or the last whole frame's, exactly, and every block under
the measured beam and hub (this frame's and the last whole frame's) is this frame's.

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
    WHOLE_EVERY_FRAMES,
    RegionPreviews,
    region_blocks,
)
from vision import FrameMeasurement
from vision.codec import preview
from vision.jpeg_regions import jpeg_layout

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
    return cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_GRAYSCALE)


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
def test_each_block_is_this_frame_or_the_last_whole_one(
    r: int, interval: int, failures: bool, colour: str | None
) -> None:
    shower = RegionPreviews(r)
    frames = [_jpeg(100 + k, interval, colour=colour) for k in range(WHOLE_EVERY_FRAMES + 3)]
    layout = jpeg_layout(frames[0])
    mcu_w = 16 if colour in ("4:2:0", "4:2:2") else 8
    assert layout is not None and layout.segment_px[0] == interval * mcu_w
    angles = [0.9 + 0.05 * k for k in range(len(frames))]
    oks = [True] * len(frames)
    if failures:
        oks[1] = oks[2] = False  # not measured: shown whole, not kept as the whole frame
    last_whole = None
    last_angle = math.nan
    kinds = []
    for k, (data, angle, ok) in enumerate(zip(frames, angles, oks, strict=True)):
        out, encoding, scale = shower.show(data, "jpeg", _measured(angle, ok))
        assert encoding == "jpeg" and scale == 1.0 / r
        got, mine = _decoded(out), _decoded(preview(data, r))
        assert got.shape == mine.shape == (math.ceil(H / r), math.ceil(W / r))
        if np.array_equal(got, mine):
            kinds.append("whole")
            if ok:
                last_whole, last_angle = got, angle
            continue
        kinds.append("region")
        assert last_whole is not None
        gb, mb, lb = _blocks(got), _blocks(mine), _blocks(last_whole)
        this = np.all(gb == mb, axis=(2, 3))
        old = np.all(gb == lb, axis=(2, 3))
        assert np.all(this | old), f"frame {k}: a block from neither frame"
        # the measured beam and hub of this frame and of the last whole frame: this frame's
        shape = layout.blocks_shape  # (ceil(H / 8), W // 8) gray, whole MCUs colour
        for a in (angle, last_angle):
            under = region_blocks(_measured(a), shape)
            assert under is not None
            red = np.zeros(this.shape, bool)
            rows, cols = np.nonzero(under)
            rows, cols = rows // r, cols // r
            keep = (rows < red.shape[0]) & (cols < red.shape[1])
            red[rows[keep], cols[keep]] = True
            assert np.all(this[red]), f"frame {k}: the region shows another frame"
        assert 0.05 < np.mean(this) < 0.8  # most of the frame is the last whole one
    if failures:
        assert kinds[:4] == ["whole", "whole", "whole", "region"]
    # whole at the start and then every WHOLE_EVERY_FRAMES-th frame since the last
    first = kinds.index("region")
    assert kinds[first + WHOLE_EVERY_FRAMES - 1] == "whole"
    assert kinds.count("whole") == 2 + (2 if failures else 0)
    assert shower.whole_frames == kinds.count("whole")


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
