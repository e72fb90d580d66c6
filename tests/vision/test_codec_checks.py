"""The codec checks what the decoder would only complain about on stderr: a PNG's chunk
CRCs and its end, and a header's claimed size, before decoding."""

from __future__ import annotations

import numpy as np
import pytest

from vision.codec import decode, encode
from vision.errors import CorruptImageError

IMAGE = (np.arange(48 * 64) % 251).astype(np.uint8).reshape(48, 64)


def test_a_whole_png_decodes_exactly() -> None:
    np.testing.assert_array_equal(decode(encode(IMAGE, "png")), IMAGE)


def test_a_flipped_bit_fails_the_chunk_crc() -> None:
    data = bytearray(encode(IMAGE, "png"))
    data[len(data) // 2] ^= 0x04
    with pytest.raises(CorruptImageError, match="IDAT chunk at byte 33 fails its CRC"):
        decode(bytes(data))


@pytest.mark.parametrize("cut", [9, 30, -13, -1])
def test_a_png_cut_short_is_refused(cut: int) -> None:
    data = encode(IMAGE, "png")
    with pytest.raises(CorruptImageError, match=r"runs past the end|before its IEND"):
        decode(data[:cut])
