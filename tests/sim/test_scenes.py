"""Scenes: free decay against Eq. 37, the linkage report, model availability."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from sim import scenes
from sim.beam import BeamProperties
from sim.config import BeamConfig, DampingConfig, DriveConfig, LinkageConfig
from sim.drives import SinusoidDrive
from sim.models.modal import simulate_modal

GAUGES = (0.005, 0.204, 0.403, 0.603)


def test_free_decay_decrement_matches_the_mode_1_damping_ratio_and_identification_inverts_it() -> (
    None
):
    run = scenes.free_decay(
        BeamConfig(), DampingConfig(), mass_kg=0.1, duration_s=5.0, gauge_positions_m=GAUGES
    )
    ex = run.extras
    # the released beam rings in mode 1: zeta from the decrement = Eq. 37 for mode 1
    assert ex["damping_ratio"] == pytest.approx(ex["damping_ratio_mode1_eq37"], rel=0.01)
    assert ex["identified_a0_per_s"] == pytest.approx(0.00087, rel=1e-3)
    assert run.result.tip_lateral_m[0] == pytest.approx(ex["initial_tip_m"], rel=1e-9)
    p = 0.1 * 9.80665
    beam = BeamProperties.from_config(BeamConfig())
    linear = p * beam.length_m**3 / (3 * beam.bending_stiffness_n_m2)
    assert -ex["initial_tip_m"] == pytest.approx(linear, rel=1e-3)  # 4 modes: 0.1 % low


def test_reciprocating_tip_converges_in_n_modes() -> None:
    beam = BeamProperties.from_config(BeamConfig())
    t = np.arange(0.0, 4.0, 1.0 / 200.0)
    tips = {
        n: simulate_modal(
            beam, SinusoidDrive(), t, n_modes=n, a0_per_s=0.1, a1_s=0.1, rtol=1e-9
        ).tip_lateral_m
        for n in (1, 2, 3, 4, 8)
    }
    errors = [np.abs(tips[n] - tips[8]).max() for n in (1, 2, 3, 4)]
    assert all(b < 0.5 * a for a, b in itertools.pairwise(errors))
    assert errors[-1] < 1e-4 * np.abs(tips[8]).max()


def test_linkage_scene_reports_true_and_paper_extrema() -> None:
    info = scenes.linkage(LinkageConfig())
    assert info["grashof"] == "crank-rocker"
    assert info["rocker_min_rad"] < info["paper_rocker_min_rad"]
    assert info["rocker_max_rad"] > info["paper_rocker_max_rad"]
    assert info["rocker_at_paper_crank_angles_rad"] == pytest.approx(
        [info["paper_rocker_min_rad"], info["paper_rocker_max_rad"]], abs=1e-5
    )
    assert math.degrees(info["transmission_angle_min_rad"]) == pytest.approx(52.527, abs=1e-3)


def test_fourbar_drive_scene_and_static_scene() -> None:
    run = scenes.reciprocating(
        LinkageConfig(),
        BeamConfig(),
        DriveConfig(),
        drive="fourbar",
        duration_s=2.0,
        gauge_positions_m=GAUGES,
    )
    assert run.result.model == "modal"
    hub = run.result.hub_angle_rad
    assert hub.max() - hub.min() < 1.56  # within the true stroke, 88.9 deg
    st = scenes.static(BeamConfig(), mass_kg=0.149, model="auto", gauge_positions_m=GAUGES)
    assert st.result.model == "static-elastica"
    assert -st.result.tip_lateral_m[0] * 1e3 == pytest.approx(80.23, abs=0.01)
    with pytest.raises(ValueError, match="mass_kg"):
        scenes.static(BeamConfig(), mass_kg=-1.0)
