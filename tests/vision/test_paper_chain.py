from __future__ import annotations

import math

import numpy as np
import pytest

from vision import Measurer
from vision.errors import FrameFailure
from vision.paper_chain import measure_paper
from vision.synthetic.render import render_frame


def test_the_paper_chain_needs_only_a_calibration(nominal_spec, vt) -> None:
    """Called with the calibration, the stations and the grid resolution, it gives what
    Measurer(method="paper") gives, number for number."""
    frame = render_frame(nominal_spec, [vt.bent(math.radians(300), 0.05)])
    cal = vt.truth_calibration(frame.truth)
    measurer = Measurer(cal, method="paper")
    via = measurer.measure(frame.image)
    direct = measure_paper(
        cal, frame.image, stations_m=measurer.stations_m, resolution_m=measurer.px_m
    )
    assert via.ok and direct.ok and direct.method == "paper"
    assert direct.hub_angle_rad == via.hub_angle_rad
    assert direct.tip_lateral_m == via.tip_lateral_m
    np.testing.assert_array_equal(direct.lateral_at_stations_m, via.lateral_at_stations_m)
    np.testing.assert_array_equal(direct.centreline_px, via.centreline_px)


def test_a_frame_without_a_beam_is_a_frame_failure(nominal_spec, vt) -> None:
    frame = render_frame(nominal_spec, [vt.bent(math.radians(300), 0.0)])
    cal = vt.truth_calibration(frame.truth)
    blank = np.full_like(frame.image, 40)
    with pytest.raises(FrameFailure):
        measure_paper(cal, blank, stations_m=np.array([0.2]), resolution_m=1e-3)
