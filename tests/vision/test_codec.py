from __future__ import annotations

import numpy as np
import pytest

from vision.codec import decode, encode
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
