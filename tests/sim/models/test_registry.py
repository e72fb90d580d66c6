"""The model registry: one signature for every model, each entry the model's own function."""

from __future__ import annotations

import numpy as np
import pytest

from sim.beam import BeamProperties
from sim.config import BeamConfig
from sim.drives import SinusoidDrive
from sim.errors import SimError, SimInputError
from sim.models.fe import simulate_fe
from sim.models.modal import simulate_modal
from sim.models.modal_nonlinear import simulate_modal_nonlinear
from sim.models.registry import MODELS, simulate
from sim.models.rigid import simulate_rigid

BEAM = BeamProperties.from_config(BeamConfig())
DRIVE = SinusoidDrive(0.7669, 4.970)
GAUGES = (0.005, 0.204)


def test_the_names_are_the_command_lines() -> None:
    assert MODELS == ("auto", "rigid", "modal", "fe")


def test_each_entry_runs_its_model_with_the_same_settings() -> None:
    t = np.linspace(0.0, 0.5, 51)
    damping = {"a0_per_s": 0.1, "a1_s": 0.1}
    pairs = [
        (
            simulate(
                "modal", BEAM, DRIVE, t, n_modes=3, tol=1e-6, gauge_positions_m=GAUGES, **damping
            ),
            simulate_modal(
                BEAM, DRIVE, t, n_modes=3, rtol=1e-6, gauge_positions_m=GAUGES, **damping
            ),
        ),
        (
            simulate("modal", BEAM, DRIVE, t, nonlinear=True, **damping),
            simulate_modal_nonlinear(BEAM, DRIVE, t, **damping),
        ),
        (
            simulate("fe", BEAM, DRIVE, t[:11], n_stations=5, **damping),
            simulate_fe(BEAM, DRIVE, t[:11], n_stations=5, **damping),
        ),
        (
            simulate("rigid", BEAM, DRIVE, t, gauge_positions_m=GAUGES, **damping),
            simulate_rigid(BEAM, DRIVE, t, gauge_positions_m=GAUGES),
        ),
    ]
    for ours, theirs in pairs:
        assert ours.model == theirs.model
        np.testing.assert_array_equal(ours.strain, theirs.strain)
        np.testing.assert_array_equal(ours.station_lateral_m, theirs.station_lateral_m)
        assert ours.settings == theirs.settings


def test_no_tolerance_leaves_each_model_at_its_own_default() -> None:
    t = np.linspace(0.0, 0.2, 21)
    assert simulate("modal", BEAM, DRIVE, t).settings["rtol"] == 1e-8
    assert simulate("fe", BEAM, DRIVE, t[:3], a1_s=0.1).settings["rtol"] == 1e-6
    auto = simulate("auto", BEAM, DRIVE, t, tol=1e-2)
    assert auto.model.startswith("auto:") and auto.settings["auto_tol"] == 1e-2


def test_unknown_names_and_contradictory_settings_are_refused() -> None:
    t = np.linspace(0.0, 0.2, 3)
    with pytest.raises(SimInputError, match="model must be one of auto, rigid, modal, fe"):
        simulate("linear", BEAM, DRIVE, t)
    with pytest.raises(ValueError, match="nonlinear"):  # a SimInputError is a ValueError
        simulate("modal", BEAM, DRIVE, t, nonlinear=True, stiffening=False)
    with pytest.raises(SimError):
        simulate("fe", BEAM, DRIVE, t, tol=-1.0)
