"""Cameras through OpenCV: a V4L2/UVC device, a video file, or a folder of stills.

``cv2`` is imported inside the functions that need it. Every source delivers encoded
frames (JPEG or PNG) stamped on the run clock:

- device: the V4L2 driver's buffer timestamp when OpenCV exposes it, otherwise the host
  clock at delivery, relative to ``start()`` (run-clock zero is the DAQ's start: start
  the camera right after the DAQ);
- video file: frame index / the file's frame rate, from the first frame;
- stills folder (the paper's still camera): EXIF DateTimeOriginal, else file mtime,
  relative to the first still; files are delivered in time order, as they are (no
  re-encoding). Matching these clocks to the DAQ is the processing's job (dial zeros).
"""

from __future__ import annotations

import logging
import os
import time
from pathlib import Path
from types import TracebackType
from typing import Any

from daq.drivers.exif import exif_datetime_original
from daq.errors import DaqInputError, DeviceError
from daq.imageinfo import image_encoding, image_size_px
from daq.records import Frame

log = logging.getLogger(__name__)

STILL_SUFFIXES = (".jpg", ".jpeg", ".png")
#: A restart marker every this many MCUs in the JPEGs written: the processing decodes only
#: the segments between markers that it measures (vision's codec writes the same interval,
#: ``vision.codec.RST_INTERVAL_MCU``; other JPEG readers are unaffected). 4 MCUs: 32 px of
#: an 8-row band of a gray frame; of a colour frame (what OpenCV gives for a colour camera:
#: YCbCr, 4:2:0) 64 px of a 16-row band, of which the processing decodes the gray (Y) alone.
JPEG_RST_INTERVAL_MCU = 4


def _encode(image: Any, encoding: str, jpeg_quality: int) -> bytes:
    import cv2

    if encoding == "jpeg":
        params = [cv2.IMWRITE_JPEG_QUALITY, int(jpeg_quality)]
        params += [cv2.IMWRITE_JPEG_RST_INTERVAL, JPEG_RST_INTERVAL_MCU]
        ok, buf = cv2.imencode(".jpg", image, params)
    else:
        ok, buf = cv2.imencode(".png", image)
    if not ok:
        raise DeviceError(f"OpenCV could not encode a frame as {encoding}")
    return bytes(buf.tobytes())


class _Base:
    backend = "opencv"

    def __enter__(self) -> Any:
        self.start()  # type: ignore[attr-defined]
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.stop()  # type: ignore[attr-defined]


class VideoFileCamera(_Base):
    """Frames of a video file, stamped ``k / fps`` from the first frame (a file carries
    no exposure times), re-encoded as ``encoding``."""

    def __init__(
        self, path: str | os.PathLike[str], *, encoding: str = "jpeg", jpeg_quality: int = 90
    ) -> None:
        if encoding not in ("jpeg", "png"):
            raise DaqInputError(f"encoding must be 'jpeg' or 'png', got {encoding!r}")
        self.path = Path(path)
        self.encoding = encoding
        self.jpeg_quality = jpeg_quality
        self._cap: Any = None
        self._k = 0
        self.frame_rate_hz = 0.0

    def describe(self) -> dict[str, object]:
        return {
            "backend": self.backend,
            "device": "video file",
            "path": str(self.path),
            "frame_rate_hz": self.frame_rate_hz,
            "encoding": self.encoding,
        }

    def start(self) -> None:
        import cv2

        if not self.path.is_file():
            raise DeviceError(f"{self.path}: no such video file")
        cap = cv2.VideoCapture(str(self.path))
        if not cap.isOpened():
            raise DeviceError(f"{self.path}: OpenCV cannot open this video")
        fps = float(cap.get(cv2.CAP_PROP_FPS))
        if not fps > 0:
            cap.release()
            raise DeviceError(f"{self.path}: the video has no frame rate")
        self._cap, self.frame_rate_hz, self._k = cap, fps, 0

    def read_frame(self, timeout_s: float) -> Frame | None:
        if self._cap is None:
            raise DeviceError("VideoFileCamera: read_frame before start()")
        ok, image = self._cap.read()
        if not ok:
            return None
        k = self._k
        self._k += 1
        h, w = image.shape[:2]
        data = _encode(image, self.encoding, self.jpeg_quality)
        return Frame(round(k * 1e9 / self.frame_rate_hz), k, data, self.encoding, w, h)

    def stop(self) -> None:
        if self._cap is not None:
            self._cap.release()
            self._cap = None


def still_time_s(path: Path) -> tuple[float, str]:
    """(capture time as POSIX seconds, "exif" or "mtime") of a still image file.
    EXIF time has no zone: it is read as local time, only differences matter here."""
    data = path.read_bytes()
    when = exif_datetime_original(data) if image_encoding(data) == "jpeg" else None
    if when is not None:
        return when.timestamp(), "exif"
    return path.stat().st_mtime, "mtime"


class StillFolderCamera(_Base):
    """The stills of a folder (``*.jpg``, ``*.jpeg``, ``*.png``) in capture-time order,
    stamped relative to the first; the file bytes are passed on unchanged."""

    def __init__(self, folder: str | os.PathLike[str]) -> None:
        self.folder = Path(folder)
        self._files: list[tuple[float, Path, str]] = []
        self._k = 0

    def describe(self) -> dict[str, object]:
        sources = sorted({s for _, _, s in self._files})
        return {
            "backend": self.backend,
            "device": "folder of stills",
            "path": str(self.folder),
            "frames": len(self._files),
            "time_source": sources,
            "frame_rate_hz": None,
        }

    def start(self) -> None:
        if not self.folder.is_dir():
            raise DeviceError(f"{self.folder}: no such folder of stills")
        files = [p for p in self.folder.iterdir() if p.suffix.lower() in STILL_SUFFIXES]
        if not files:
            raise DeviceError(f"{self.folder}: no .jpg/.jpeg/.png stills in the folder")
        timed = []
        for p in files:
            t, source = still_time_s(p)
            timed.append((t, p, source))
        self._files = sorted(timed, key=lambda item: (item[0], item[1].name))
        self._k = 0

    def read_frame(self, timeout_s: float) -> Frame | None:
        if self._k >= len(self._files):
            return None
        t, path, _ = self._files[self._k]
        data = path.read_bytes()
        encoding = image_encoding(data)
        if encoding is None:
            raise DeviceError(f"{path}: not a JPEG or PNG image")
        try:
            w, h = image_size_px(data)
        except DaqInputError as exc:
            raise DeviceError(f"{path}: {exc}") from None
        t0 = self._files[0][0]
        frame = Frame(round((t - t0) * 1e9), self._k, data, encoding, w, h)
        self._k += 1
        return frame

    def stop(self) -> None:
        self._k = len(self._files)


class VideoDeviceCamera(_Base):
    """A V4L2/UVC camera. ``read_frame`` blocks in the driver (``timeout_s`` is not
    enforceable through OpenCV); not exercised without a camera."""

    def __init__(
        self,
        device: int | str,
        *,
        width_px: int,
        height_px: int,
        frame_rate_hz: float,
        encoding: str = "jpeg",
        jpeg_quality: int = 90,
    ) -> None:
        self.device = device
        self.width_px = width_px
        self.height_px = height_px
        self.frame_rate_hz = frame_rate_hz
        self.encoding = encoding
        self.jpeg_quality = jpeg_quality
        self._cap: Any = None
        self._k = 0
        self._zero_ns = 0
        self._driver_zero_ms: float | None = None

    def describe(self) -> dict[str, object]:
        return {
            "backend": self.backend,
            "device": f"V4L2 {self.device}",
            "frame_rate_hz": self.frame_rate_hz,
            "width_px": self.width_px,
            "height_px": self.height_px,
            "encoding": self.encoding,
        }

    def start(self) -> None:
        import cv2

        cap = cv2.VideoCapture(self.device, cv2.CAP_V4L2)
        if not cap.isOpened():
            raise DeviceError(f"camera {self.device!r}: OpenCV cannot open it (V4L2)")
        cap.set(cv2.CAP_PROP_FRAME_WIDTH, self.width_px)
        cap.set(cv2.CAP_PROP_FRAME_HEIGHT, self.height_px)
        cap.set(cv2.CAP_PROP_FPS, self.frame_rate_hz)
        actual = float(cap.get(cv2.CAP_PROP_FPS))
        if actual > 0:
            self.frame_rate_hz = actual
        self._cap, self._k = cap, 0
        self._zero_ns = time.monotonic_ns()
        self._driver_zero_ms = None

    def read_frame(self, timeout_s: float) -> Frame | None:
        import cv2

        if self._cap is None:
            raise DeviceError("VideoDeviceCamera: read_frame before start()")
        ok, image = self._cap.read()
        host_ns = time.monotonic_ns() - self._zero_ns
        if not ok:
            raise DeviceError(f"camera {self.device!r}: read failed")
        driver_ms = float(self._cap.get(cv2.CAP_PROP_POS_MSEC))
        if driver_ms > 0:
            if self._driver_zero_ms is None:  # tie the driver clock to the host at frame 0
                self._driver_zero_ms = driver_ms - host_ns * 1e-6
            t_ns = round((driver_ms - self._driver_zero_ms) * 1e6)
        else:
            t_ns = host_ns
        h, w = image.shape[:2]
        frame = Frame(
            max(0, t_ns),
            self._k,
            _encode(image, self.encoding, self.jpeg_quality),
            self.encoding,
            w,
            h,
        )
        self._k += 1
        return frame

    def stop(self) -> None:
        if self._cap is not None:
            self._cap.release()
            self._cap = None


def open_camera(
    device: str,
    *,
    width_px: int,
    height_px: int,
    frame_rate_hz: float,
    encoding: str = "jpeg",
    jpeg_quality: int = 90,
) -> Any:
    """The rig's ``camera.device``: a V4L2 index or ``/dev/video*`` path, a video file,
    or a folder of stills."""
    p = Path(device)
    if device.isdigit() or device.startswith("/dev/video"):
        return VideoDeviceCamera(
            int(device) if device.isdigit() else device,
            width_px=width_px,
            height_px=height_px,
            frame_rate_hz=frame_rate_hz,
            encoding=encoding,
            jpeg_quality=jpeg_quality,
        )
    if p.is_dir():
        return StillFolderCamera(p)
    if p.is_file():
        return VideoFileCamera(p, encoding=encoding, jpeg_quality=jpeg_quality)
    raise DeviceError(f"camera.device {device!r}: not a camera index, video file or folder")
