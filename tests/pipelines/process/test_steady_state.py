"""The periodic steady state copied over a run equals the run simulated to its end."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.typing import ArrayLike

from pipelines.process import steady_state
from pipelines.process.steady_state import simulate_steady
from sim.beam import BeamProperties
from sim.drives import SinusoidDrive
from sim.models.modal import simulate_modal
from sim.result import SimResult


def test_steady_state_copy_matches_the_whole_run() -> None:
    # not the bench: a shorter, stiffer beam driven at 1.3 Hz, lightly damped (zeta 0.05:
    # the transient decays as exp(-2.4 t), so two periods are not enough and it doubles)
    beam = BeamProperties(
        length_m=0.6,
        hub_offset_m=0.02,
        mass_per_length_kg_m=0.2,
        bending_stiffness_n_m2=5.0,
        axial_stiffness_n=4e6,
        surface_offset_m=0.0015,
    )
    drive = SinusoidDrive(0.5, 2 * math.pi * 1.3, 0.3)
    t = np.arange(0.0, 12.0, 1 / 400.0)

    def run(times: np.ndarray) -> SimResult:
        return simulate_modal(
            beam, drive, times, n_modes=3, a0_per_s=0.05, a1_s=0.002, rtol=1e-9, atol=1e-12
        )

    tol = 1e-5
    steady = simulate_steady(run, t, 1 / 1.3, 1.0, tol)
    assert steady is not None
    info = steady.settings["steady_state"]
    assert info["simulated_s"] < 0.8 * (t[-1] - t[0])  # it saved something
    assert info["simulated_s"] > 1.0 + 2.5 / 1.3  # more than the first two periods
    assert info["cycle_change_rel"] <= tol
    whole = run(t)
    np.testing.assert_array_equal(steady.time_s, t)
    np.testing.assert_allclose(steady.hub_angle_rad, whole.hub_angle_rad, atol=1e-9)
    scale = np.max(np.abs(whole.tip_lateral_m))
    # what is left of the transient after the simulated stretch is at most what the last
    # two periods still differed by (it decays); the integrator adds ~rtol
    assert np.max(np.abs(steady.tip_lateral_m - whole.tip_lateral_m)) / scale <= (
        info["cycle_change_rel"] + 1e-7
    )
    late = t > 1.0
    s_scale = np.max(np.abs(whole.strain[late]), axis=0)
    assert np.all(
        np.max(np.abs(steady.strain[late] - whole.strain[late]), axis=0) / s_scale
        <= 10 * info["cycle_change_rel"] + 1e-6
    )
    # a run too short to save anything is left to the caller
    assert simulate_steady(run, t[t < 2.5], 1 / 1.3, 1.0, tol) is None


def test_the_interpolated_period_is_within_its_stated_error(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # not the bench: a lightly damped stiff beam with gauges, driven at 1.7 Hz with its
    # third harmonic, sampled at 250 Hz: the later times are interpolated in the last
    # period; simulated at each phase (as before) when the estimate is not small enough
    beam = BeamProperties(
        length_m=0.5,
        hub_offset_m=0.03,
        mass_per_length_kg_m=0.25,
        bending_stiffness_n_m2=4.0,
        axial_stiffness_n=3e6,
        surface_offset_m=0.002,
    )
    drive = _TwoHarmonics(0.4, 2 * math.pi * 1.7)
    t = np.arange(0.0, 9.0, 1 / 250.0)

    def run(times: np.ndarray) -> SimResult:
        return simulate_modal(
            beam, drive, times, n_modes=3, a0_per_s=0.2, a1_s=0.003, rtol=1e-9, atol=1e-12,
            gauge_positions_m=(0.05, 0.2, 0.4),
        )  # fmt: skip

    tol = 1e-4
    fast = simulate_steady(run, t, 1 / 1.7, 1.0, tol)
    assert fast is not None
    info = fast.settings["steady_state"]
    assert 0.0 < info["interpolation_rel"] <= steady_state.INTERPOLATION_SHARE * tol
    assert 0.0 < info["interpolation_strain_rel"] <= steady_state.INTERPOLATION_SHARE * tol
    monkeypatch.setattr(steady_state, "INTERPOLATION_SHARE", 0.0)
    exact = simulate_steady(run, t, 1 / 1.7, 1.0, tol)
    assert exact is not None
    assert "interpolation_rel" not in exact.settings["steady_state"]
    np.testing.assert_array_equal(exact.time_s, t)
    np.testing.assert_array_equal(fast.time_s, t)
    scale = np.max(np.abs(exact.tip_lateral_m))
    for name in ("tip_lateral_m", "station_lateral_m", "station_longitudinal_m"):
        err = np.max(np.abs(getattr(fast, name) - getattr(exact, name))) / scale
        assert err <= info["interpolation_rel"], name
    gauge = np.max(np.abs(exact.strain), axis=0)
    err = np.max(np.abs(fast.strain - exact.strain), axis=0) / gauge
    assert np.all(err <= info["interpolation_strain_rel"])
    hub = np.max(np.abs(fast.hub_angle_rad - exact.hub_angle_rad))
    assert hub <= info["interpolation_rel"] * np.max(np.abs(exact.hub_angle_rad))


class _TwoHarmonics:
    """theta = a (sin w t + 0.3 sin 3 w t), with its rate and acceleration."""

    def __init__(self, a: float, w: float) -> None:
        self.a, self.w = a, w

    def angle(self, t_s: ArrayLike) -> np.ndarray:
        t = np.asarray(t_s, dtype=float)
        return self.a * (np.sin(self.w * t) + 0.3 * np.sin(3 * self.w * t))

    def rate(self, t_s: ArrayLike) -> np.ndarray:
        t, w = np.asarray(t_s, dtype=float), self.w
        return self.a * w * (np.cos(w * t) + 0.9 * np.cos(3 * w * t))

    def accel(self, t_s: ArrayLike) -> np.ndarray:
        t, w = np.asarray(t_s, dtype=float), self.w
        return -self.a * w * w * (np.sin(w * t) + 2.7 * np.sin(3 * w * t))
