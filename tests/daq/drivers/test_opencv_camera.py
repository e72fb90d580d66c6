"""OpenCV camera sources for real: a video file and a folder of stills in tmp_path."""

from __future__ import annotations

import os
from io import BytesIO
from pathlib import Path

import cv2
import numpy as np
import pytest
from PIL import Image

from daq.drivers.opencv_camera import StillFolderCamera, VideoFileCamera, open_camera
from daq.errors import DeviceError
from daq.protocols import Camera


def _write_video(path: Path, n: int, fps: float, w: int = 96, h: int = 64) -> None:
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), fps, (w, h))
    assert writer.isOpened()
    for k in range(n):
        writer.write(np.full((h, w, 3), 20 + 10 * k, np.uint8))
    writer.release()


def test_video_file_frames_times_and_content(tmp_path: Path) -> None:
    path = tmp_path / "run.avi"
    _write_video(path, 12, 15.0)
    cam = open_camera(str(path), width_px=96, height_px=64, frame_rate_hz=15.0)
    assert isinstance(cam, VideoFileCamera) and isinstance(cam, Camera)
    frames = []
    with cam:
        while (f := cam.read_frame(1.0)) is not None:
            frames.append(f)
    assert [f.sequence for f in frames] == list(range(12))
    np.testing.assert_allclose([f.t_ns for f in frames], np.arange(12) * 1e9 / 15.0, atol=1)
    assert all((f.width_px, f.height_px, f.encoding) == (96, 64, "jpeg") for f in frames)
    means = [
        cv2.imdecode(np.frombuffer(f.data, np.uint8), cv2.IMREAD_GRAYSCALE).mean() for f in frames
    ]
    np.testing.assert_allclose(means, 20 + 10 * np.arange(12), atol=3)


def test_stills_folder_in_capture_time_order(tmp_path: Path) -> None:
    folder = tmp_path / "stills"
    folder.mkdir()
    # names in the opposite order to the EXIF times
    for name, when, sub in (
        ("a.jpg", "2005:03:14 15:09:28", "5"),
        ("b.JPG", "2005:03:14 15:09:27", None),
        ("c.jpeg", "2005:03:14 15:09:26", "75"),
    ):
        img = Image.new("RGB", (40, 30), (ord(name[0]), 0, 0))
        exif = Image.Exif()
        ifd = exif.get_ifd(0x8769)
        ifd[0x9003] = when
        if sub:
            ifd[0x9291] = sub
        buf = BytesIO()
        img.save(buf, "JPEG", exif=exif.tobytes())
        (folder / name).write_bytes(buf.getvalue())
    (folder / "notes.txt").write_text("ignored")
    cam = open_camera(str(folder), width_px=1, height_px=1, frame_rate_hz=1.0)
    assert isinstance(cam, StillFolderCamera)
    with cam:
        frames = [cam.read_frame(1.0) for _ in range(4)]
        assert cam.describe()["time_source"] == ["exif"]
    assert frames[3] is None
    got = [f for f in frames if f is not None]
    assert [f.data for f in got] == [
        (folder / n).read_bytes() for n in ("c.jpeg", "b.JPG", "a.jpg")
    ]
    assert [f.t_ns for f in got] == [0, 250_000_000, 1_750_000_000]
    assert [(f.width_px, f.height_px, f.sequence) for f in got] == [
        (40, 30, 0),
        (40, 30, 1),
        (40, 30, 2),
    ]


def test_stills_without_exif_use_the_file_time(tmp_path: Path) -> None:
    for i, t in enumerate((1000.0, 1000.5, 999.0)):
        p = tmp_path / f"img{i}.png"
        ok = cv2.imwrite(str(p), np.full((10, 20), i * 50, np.uint8))
        assert ok
        os.utime(p, (t, t))
    with StillFolderCamera(tmp_path) as cam:
        got = [cam.read_frame(1.0) for _ in range(3)]
    assert [f.t_ns for f in got if f] == [0, 1_000_000_000, 1_500_000_000]
    assert [f.encoding for f in got if f] == ["png"] * 3


def test_bad_camera_sources_raise_device_errors(tmp_path: Path) -> None:
    with pytest.raises(DeviceError, match="not a camera index"):
        open_camera(str(tmp_path / "nothing"), width_px=1, height_px=1, frame_rate_hz=1)
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(DeviceError, match=r"no \.jpg"):
        StillFolderCamera(empty).start()
    broken = tmp_path / "broken.avi"
    broken.write_bytes(b"not a video")
    with pytest.raises(DeviceError, match=r"broken\.avi"):
        VideoFileCamera(broken).start()


def test_frames_carry_restart_markers_at_the_interval_the_processing_splits() -> None:
    # daq may not import vision; the two constants are kept equal here. A gray frame the
    # driver writes is split by vision's reader at its own interval.
    from daq.drivers.opencv_camera import JPEG_RST_INTERVAL_MCU, _encode
    from vision.codec import RST_INTERVAL_MCU
    from vision.jpeg_regions import jpeg_layout

    assert JPEG_RST_INTERVAL_MCU == RST_INTERVAL_MCU
    gray = np.random.default_rng(3).integers(0, 255, (64, 96), dtype=np.uint8)
    layout = jpeg_layout(_encode(gray, "jpeg", 90))
    assert layout is not None and layout.interval == RST_INTERVAL_MCU
    # a colour frame carries the markers too (its MCU is 16 x 16 px), and is decoded whole
    colour = _encode(np.dstack([gray] * 3), "jpeg", 90)
    dri = colour.index(b"\xff\xdd\x00\x04")
    assert int.from_bytes(colour[dri + 4 : dri + 6], "big") == RST_INTERVAL_MCU
    assert jpeg_layout(colour) is None
