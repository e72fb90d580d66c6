"""What a review shows, computed before Rerun sees it: residuals, Fig. 11's axes, the
magnified difference between the measured and the simulated beam."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pipelines.results.dataset import make_results
from pipelines.review.display import fig11_axes, nice_step, run_view
from pipelines.review.overlays import magnified_difference
from pipelines.rig import Rig


@pytest.mark.parametrize(
    ("span", "step"), [(88.9, 20.0), (46.0, 10.0), (3.0, 0.5), (0.07, 0.02), (1000.0, 200.0)]
)
def test_nice_steps_give_about_six_ticks(span: float, step: float) -> None:
    assert nice_step(span) == pytest.approx(step)
    assert 3 <= span / nice_step(span) <= 10


def test_fig11_axes_number_the_data_range_in_degrees_and_mm() -> None:
    # the bench's loop: hub 62-151 deg, tip -23..+23 mm (view y = -mm)
    axes = fig11_axes([62.0, -23.0], [151.0, 23.0])
    deg = [lab for lab in axes.tick_labels if lab.endswith("°")]
    mm = [lab for lab in axes.tick_labels if lab.endswith("mm")]
    assert deg == ["80°", "100°", "120°", "140°"]
    assert mm == ["20 mm", "10 mm", "0 mm", "-10 mm", "-20 mm"]
    x0, x1, y0, y1 = axes.bounds
    assert x0 < 62 and x1 > 151 and y0 < -23 and y1 > 23  # the loop is inside the view
    assert x1 - x0 < 1.5 * (151 - 62)  # and fills it (origin 0 deg is not in view)
    # the tick numbers sit under/left of the data, inside the view
    for (x, y), label in zip(axes.tick_positions, axes.tick_labels, strict=True):
        assert x0 <= x <= x1 and y0 <= y <= y1, label


def test_residuals_are_measured_minus_simulated_after_the_simulation_settles() -> None:
    fs = 400.0
    t = np.arange(0, 6.0, 1 / fs)
    tip = 0.02 * np.sin(5.8 * t)
    strain = 3e-4 * np.outer(np.sin(5.8 * t), [1.0, 0.7, 0.45, 0.2])
    idx = np.arange(0, t.size, 25)
    ds = make_results(
        time_s=t,
        rocker_angle_rad=0.77 * np.sin(5.8 * t),
        strain=strain + 2e-6,
        gauge_m=[0.005, 0.204, 0.403, 0.603],
        frame_time_s=t[idx],
        hub_angle_image_rad=0.77 * np.sin(5.8 * t[idx]),
        tip_lateral_m=tip[idx] + 1e-4,
        tip_longitudinal_m=np.zeros(idx.size),
        frame_ok=np.ones(idx.size, dtype=bool),
        tip_lateral_strain_m=tip - 3e-4,
        sim_tip_lateral_m=tip,
        sim_strain=strain,
        attrs={
            "source_log": "run.mcap",
            "rig_json": Rig().to_json(),
            "software_version": "test",
            "sim_model": "modal",
            "sim_settings": {},
            "camera_to_daq_offset_s": 0.0,
            "settle_time_s": 1.0,
        },
    )
    view = run_view(ds)
    late, late_frames = t >= 1.0, t[idx] >= 1.0
    assert np.all(np.isnan(view.strain_residual[~late]))
    np.testing.assert_allclose(view.strain_residual[late], 2e-6, atol=1e-15)
    np.testing.assert_allclose(view.tip_strain_minus_sim_m[late], -3e-4, atol=1e-15)
    assert np.all(np.isnan(view.tip_image_minus_sim_m[~late_frames]))
    np.testing.assert_allclose(view.tip_image_minus_sim_m[late_frames], 1e-4, atol=1e-12)
    assert "| simulated beam (line and station dots) | green |" in view.summary_markdown


def test_the_magnified_difference_is_the_offset_times_the_gain_about_the_simulated_beam() -> None:
    hub = math.radians(100.0)
    axis = np.array([math.cos(hub), math.sin(hub)])
    normal = np.array([-axis[1], axis[0]])
    clamp = 0.05 * axis
    stations = np.linspace(0.0, 0.8, 21)
    sim_lat = 0.03 * (stations / 0.8) ** 2
    sim = (stations, sim_lat, np.zeros_like(stations))
    s = np.linspace(0.1, 0.7, 13)
    offset = 2e-4 * s  # the measured beam lies up to 0.14 mm beside the simulated one
    measured = clamp + np.outer(s, axis) + np.outer(0.03 * (s / 0.8) ** 2 + offset, normal)
    shown = magnified_difference(measured, clamp, hub, sim, gain=20.0)
    rel = shown - clamp
    np.testing.assert_allclose(rel @ axis, s, atol=1e-12)
    sim_at = 0.03 * (s / 0.8) ** 2
    np.testing.assert_allclose(rel @ normal - sim_at, 20.0 * offset, rtol=1e-6, atol=1e-9)
    # points beyond the simulated beam are dropped, not extrapolated
    beyond = np.vstack([measured, clamp + 0.9 * axis])
    assert magnified_difference(beyond, clamp, hub, sim, gain=20.0).shape == shown.shape


def test_the_overlays_cubic_is_scipys_not_a_knot_spline() -> None:
    from scipy.interpolate import CubicSpline

    from pipelines.review.overlays import not_a_knot_cubic

    rng = np.random.default_rng(19)
    for n in (2, 3, 4, 5, 9, 21, 33):
        for _ in range(20):
            x = np.cumsum(rng.uniform(0.005, 0.2, n))  # uneven spacing
            y = rng.normal(scale=0.01, size=n)
            at = np.concatenate([rng.uniform(x[0], x[-1], 25), x])
            want = CubicSpline(x, y)(at)
            got = not_a_knot_cubic(x, y, at)
            assert got.shape == want.shape
            np.testing.assert_allclose(got, want, rtol=0, atol=1e-12 * np.max(np.abs(y)))
