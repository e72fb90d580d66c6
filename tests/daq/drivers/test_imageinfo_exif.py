"""Image headers and EXIF capture times, against files written by OpenCV and Pillow."""

from __future__ import annotations

from datetime import datetime
from io import BytesIO

import cv2
import numpy as np
import pytest
from PIL import Image

from daq.drivers.exif import exif_datetime_original
from daq.imageinfo import image_encoding, image_size_px


@pytest.mark.parametrize("ext", [".jpg", ".png"])
@pytest.mark.parametrize("shape", [(48, 64, 3), (7, 300), (1536, 2048, 3)])
def test_image_size_from_the_header(ext: str, shape: tuple[int, ...]) -> None:
    ok, buf = cv2.imencode(ext, np.zeros(shape, np.uint8))
    assert ok
    data = buf.tobytes()
    assert image_encoding(data) == ("jpeg" if ext == ".jpg" else "png")
    assert image_size_px(data) == (shape[1], shape[0])  # (width, height)


def test_progressive_jpeg_and_junk() -> None:
    buf = BytesIO()
    Image.new("RGB", (33, 21)).save(buf, "JPEG", progressive=True)
    assert image_size_px(buf.getvalue()) == (33, 21)
    with pytest.raises(ValueError, match="not a JPEG or PNG"):
        image_size_px(b"GIF89a....")


def _jpeg_with_exif(when: str | None, subsec: str | None = None, tag: int = 0x9003) -> bytes:
    img = Image.new("RGB", (16, 8))
    exif = Image.Exif()
    if when is not None:
        if tag == 0x9003:
            ifd = exif.get_ifd(0x8769)
            ifd[0x9003] = when
            if subsec is not None:
                ifd[0x9291] = subsec
        else:
            exif[tag] = when
    buf = BytesIO()
    img.save(buf, "JPEG", exif=exif.tobytes())
    return buf.getvalue()


def test_exif_datetime_original() -> None:
    assert exif_datetime_original(_jpeg_with_exif("2005:03:14 15:09:26")) == datetime(
        2005, 3, 14, 15, 9, 26
    )
    assert exif_datetime_original(_jpeg_with_exif("2005:03:14 15:09:26", "25")) == datetime(
        2005, 3, 14, 15, 9, 26, 250000
    )
    # IFD0 DateTime is the fallback
    assert exif_datetime_original(_jpeg_with_exif("2004:01:02 03:04:05", tag=0x0132)) == (
        datetime(2004, 1, 2, 3, 4, 5)
    )
    assert exif_datetime_original(_jpeg_with_exif(None)) is None
    assert exif_datetime_original(_jpeg_with_exif("garbage")) is None
    assert exif_datetime_original(b"not an image") is None
