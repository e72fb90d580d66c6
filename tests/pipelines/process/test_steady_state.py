"""The periodic steady state copied over a run equals the run simulated to its end."""

from __future__ import annotations

import math

import numpy as np

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
