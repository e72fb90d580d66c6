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


def _frame(seed: int, hub_m: tuple[float, float], bar, gradient: float = 0.15):  # type: ignore[no-untyped-def]
    """A static frame by other hands: (measurement, truth state)."""
    rng = np.random.default_rng(seed)
    cam = random_camera(rng)
    bench = Bench(cam, hub_length_m=hub_m[0], hub_width_m=hub_m[1], hub_bar=bar, gradient=gradient)
    states, mid = exposure(rng, 0.0)
    image = render(bench, states, rng)
    cal = Calibration(cam.px(SQUARE_CORNERS_M), SQUARE_CORNERS_M, cam.K, cam.dist)
    return Measurer(cal).measure(image), mid


def _errors(m, mid) -> tuple[float, float]:  # type: ignore[no-untyped-def]
    """A measurement's hub angle (rad, wrapped) and tip lateral (m) errors against the
    truth state ``mid`` (the exposure's middle)."""
    _, _, tip_lat, _ = mid.centre_line()
    d_hub = (m.hub_angle_rad - mid.hub_angle_rad + math.pi) % (2 * math.pi) - math.pi
    return d_hub, m.tip_lateral_m - tip_lat


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
        d_hub, d_tip = _errors(m, mid)
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
        m, mid = _frame(seed, (0.068, 0.051), bar)
        assert m.ok, f"{seed}: {m.reason}"
        d_hub, d_tip = _errors(m, mid)
        lines.append(
            f"{seed}: hub {d_hub / m.hub_angle_std_rad:+.1f} sd, "
            f"tip {d_tip / m.tip_lateral_std_m:+.1f} sd"
        )
        assert abs(d_hub) <= 3 * m.hub_angle_std_rad, "\n".join(lines)
        assert abs(d_tip) <= 3 * m.tip_lateral_std_m, "\n".join(lines)


@pytest.mark.slow
def test_a_hub_width_the_frame_did_not_measure_is_not_reported_as_measured() -> None:
    """A bar as bright as the hub against part of a long edge: the edge steps, and the
    hub's width is not measured: NaN, with no uncertainty, the width the measurement
    searched with kept apart. The frames: the block's root alone (the joint fit dropped
    the hub's edges; the frame reported the rough locator's 51.04 mm as measured), a
    200 x 40 mm bar's root alone (its long edges' own fit, 43.0 mm), the stepped part
    kept in one run of residuals (lag-1 correlation 0.98: 42.5 mm), and left out (19 %
    of the edge beyond the biweight's reach; the fit took the bar's edge: 46.0 mm)."""
    frames = [
        (70, (0.068, 0.051), (0.007, 0.039, 0.009, -1)),
        (80, (0.2, 0.04), (0.03, 0.12, 0.006, 1)),
        (81, (0.2, 0.04), (0.06, 0.15, 0.005, -1)),
        (90, (0.2, 0.04), (0.01, 0.16, 0.006, 1)),
    ]
    for seed, hub, bar in frames:
        m, mid = _frame(seed, hub, bar)
        assert m.ok, f"{seed}: {m.reason}"
        assert math.isnan(m.hub_width_m) and math.isnan(m.hub_width_std_m), (seed, m.hub_width_m)
        assert m.hub_width_located_m > hub[1], (seed, m.hub_width_located_m)
        d_hub, _ = _errors(m, mid)
        assert abs(d_hub) <= 3 * m.hub_angle_std_rad, (seed, d_hub, m.hub_angle_std_rad)


@pytest.mark.slow
def test_the_hubs_width_is_measured_within_its_stated_uncertainty() -> None:
    """Hubs of other sizes than beambench's 200 x 40 mm, drawn by other hands: every
    frame measures the width from the hub's two long edges, within 3 of its stated
    standard uncertainty (the two edges' offsets through the joint fit's covariance:
    6-15 um here, errors -27..+14 um, up to 2.8 sd). On 40 more such frames (seeds
    300-339, 3 in 1 smeared 20 mm) 2 went to 3.1 sd: their errors lean 10 um narrow
    (0.02 px, the edge estimator on these edges), which the noise-only sd leaves out."""
    lines = []
    for k, hub in enumerate([(0.15, 0.045), (0.068, 0.051), (0.12, 0.032)] * 3):
        m, _ = _frame(200 + k, hub, None, gradient=0.05 * k)
        assert m.ok, f"{k}: {m.reason}"
        err = m.hub_width_m - hub[1]
        lines.append(f"{k}: {err * 1e6:+.1f} um ({err / m.hub_width_std_m:+.1f} sd)")
        assert 0 < m.hub_width_std_m < 1e-4, "\n".join(lines)
        assert abs(err) <= 3 * m.hub_width_std_m, "\n".join(lines)
