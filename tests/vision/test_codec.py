from __future__ import annotations

import numpy as np
import pytest

from vision.codec import decode, encode, preview
from vision.synthetic.render import render_frame
from vision.synthetic.scene import BeamPose


def test_encoding_round_trip(nominal_spec, vt) -> None:
    frame = render_frame(nominal_spec, [BeamPose.straight(4.5, vt.L_M)])
    png = decode(encode(frame.image, "png"))
    np.testing.assert_array_equal(png, frame.image)
    jpg = decode(encode(frame.image, "jpeg", quality=90))
    assert np.abs(jpg.astype(float) - frame.image).mean() < 2.0
    with pytest.raises(ValueError, match="encoding"):
        encode(frame.image, "gif")
    with pytest.raises(TypeError):
        encode(frame.image.astype(float))  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="not a readable image"):
        decode(b"not an image")


@pytest.mark.parametrize("encoding", ["jpeg", "png"])
@pytest.mark.parametrize("reduction", [2, 4])
def test_preview_is_the_image_at_a_reduced_size(encoding: str, reduction: int) -> None:
    """A preview pixel (x, y) shows the original around (r (x + 0.5) - 0.5, ...): a bright
    bar keeps its place, its level and its edges to within a preview pixel."""
    rng = np.random.default_rng(3)
    img = (40 + 10 * rng.random((480, 640))).astype(np.uint8)
    img[200:240, 96:600] = 220  # rows 200-239: centre 219.5
    data = encode(img, encoding)
    small = decode(preview(data, reduction))
    assert small.shape == (480 // reduction, 640 // reduction)
    profile = small[:, 300 // reduction].astype(float)
    bright = profile > 130
    centre = float(np.mean(np.nonzero(bright)[0]))
    assert (centre + 0.5) * reduction - 0.5 == pytest.approx(219.5, abs=reduction)
    assert np.count_nonzero(bright) == pytest.approx(40 / reduction, abs=1)
    assert float(np.median(profile[bright])) == pytest.approx(220, abs=6)
    assert len(preview(data, reduction)) < len(data)


def test_preview_refuses_a_reduction_it_cannot_make_and_bytes_that_are_no_image() -> None:
    data = encode(np.zeros((16, 16), np.uint8), "png")
    with pytest.raises(ValueError, match="reduction"):
        preview(data, 3)
    with pytest.raises(ValueError, match="image"):
        preview(b"not an image", 2)
