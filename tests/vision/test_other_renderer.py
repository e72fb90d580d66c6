"""The measurement on frames drawn by other hands (:mod:`tests.vision.other_renderer`:
OpenCV's camera and polygons, clamped-free mode shapes, JPEG by OpenCV), so that the
renderer and the measurer do not share assumptions: every frame measured or refused
with a reason, and every measured frame's hub angle and tip lateral within 3 of its
stated standard uncertainties ("never ok with an error outside the stated uncertainty
at 3 sigma", issue #20)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.vision.other_renderer import (
    SQUARE_CORNERS_M,
    Bench,
    exposure,
    random_camera,
    render,
)
from vision import Calibration, Measurer

CASES = {
    # name: (hub length, width m), tip smear m, lighting gradient, frames, least measured
    "bar": ((0.2, 0.04), 0.0, 0.15, 5, 5),
    "block": ((0.068, 0.051), 0.0, 0.15, 5, 5),
    "bar-smear-20-even-light": ((0.2, 0.04), 0.020, 0.0, 4, 4),
    "bar-smear-20": ((0.2, 0.04), 0.020, 0.15, 8, 8),
}
#: Known to fail (none now): case -> reason, run as strict xfails.
KNOWN: dict[str, str] = {}


@pytest.mark.slow
@pytest.mark.parametrize(
    "case",
    [
        pytest.param(c, marks=pytest.mark.xfail(strict=True, reason=KNOWN[c])) if c in KNOWN else c
        for c in CASES
    ],
)
def test_frames_drawn_by_other_hands_are_measured_within_their_stated_uncertainty(
    case: str,
) -> None:
    (hub_len, hub_w), smear, gradient, n, least = CASES[case]
    rng = np.random.default_rng(sum(map(ord, case)))
    measured, lines = 0, []
    for k in range(n):
        cam = random_camera(rng)
        bench = Bench(cam, hub_length_m=hub_len, hub_width_m=hub_w, gradient=gradient)
        states, mid = exposure(rng, smear)
        image = render(bench, states, rng)
        cal = Calibration(cam.px(SQUARE_CORNERS_M), SQUARE_CORNERS_M, cam.K, cam.dist)
        m = Measurer(cal).measure(image)
        if not m.ok:
            assert m.reason, "a refused frame says why"
            lines.append(f"{k}: refused: {m.reason}")
            continue
        measured += 1
        _, _, tip_lat, _ = mid.centre_line()
        d_hub = (m.hub_angle_rad - mid.hub_angle_rad + math.pi) % (2 * math.pi) - math.pi
        d_tip = m.tip_lateral_m - tip_lat
        lines.append(
            f"{k}: hub {math.degrees(d_hub):+.4f} deg ({d_hub / m.hub_angle_std_rad:+.1f} sd), "
            f"tip {d_tip * 1e3:+.3f} mm ({d_tip / m.tip_lateral_std_m:+.1f} sd)"
        )
        assert abs(d_hub) <= 3 * m.hub_angle_std_rad, "\n".join(lines)
        assert abs(d_tip) <= 3 * m.tip_lateral_std_m, "\n".join(lines)
    assert measured >= least, "\n".join(lines)


def test_a_bar_against_a_clamp_blocks_edge_leaves_the_beams_root_alone() -> None:
    """The paper's 68 x 51 mm block with a bar as bright as it against a long edge over
    about half its length, turning with it: the edge's points step out by the bar's
    width. The joint fit's biweight left that edge no point (a singular matrix: the
    frame refused, "measurement failed"; 21 of 48 such frames, these three among them);
    the axis now comes from the beam's root alone, every frame measured within 3 of its
    stated standard uncertainties (all 48 within 1.1)."""
    lines = []
    frames = [
        (70, (0.007, 0.039, 0.009, -1)),
        (71, (0.021, 0.053, 0.011, 1)),
        (72, (0.029, 0.062, 0.007, -1)),
    ]
    for seed, bar in frames:
        rng = np.random.default_rng(seed)
        cam = random_camera(rng)
        bench = Bench(cam, hub_length_m=0.068, hub_width_m=0.051, hub_bar=bar)
        states, mid = exposure(rng, 0.0)
        image = render(bench, states, rng)
        cal = Calibration(cam.px(SQUARE_CORNERS_M), SQUARE_CORNERS_M, cam.K, cam.dist)
        m = Measurer(cal).measure(image)
        assert m.ok, f"{seed}: {m.reason}"
        _, _, tip_lat, _ = mid.centre_line()
        d_hub = (m.hub_angle_rad - mid.hub_angle_rad + math.pi) % (2 * math.pi) - math.pi
        d_tip = m.tip_lateral_m - tip_lat
        lines.append(
            f"{seed}: hub {d_hub / m.hub_angle_std_rad:+.1f} sd, "
            f"tip {d_tip / m.tip_lateral_std_m:+.1f} sd"
        )
        assert abs(d_hub) <= 3 * m.hub_angle_std_rad, "\n".join(lines)
        assert abs(d_tip) <= 3 * m.tip_lateral_std_m, "\n".join(lines)
