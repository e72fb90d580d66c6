"""``auto`` picks modal where the physics is linear enough and exact FE where it is not,
and its recorded estimate bounds the real error against a converged reference."""

from __future__ import annotations

import numpy as np
import pytest

from sim.beam import BeamProperties, spin_up_beam
from sim.config import BeamConfig
from sim.drives import SinusoidDrive, SpinUpDrive
from sim.models.fe import simulate_fe
from sim.models.model_choice import simulate_auto


def _rel_err(a: np.ndarray, ref: np.ndarray) -> float:
    return float(np.max(np.abs(a - ref)) / np.max(np.abs(ref)))


@pytest.mark.slow
def test_paper_scene_picks_modal_and_the_estimate_bounds_the_error() -> None:
    beam = BeamProperties.from_config(BeamConfig())
    drive = SinusoidDrive(0.7669, 4.970)
    t = np.linspace(0.0, 2.6, 261)
    res = simulate_auto(beam, drive, t, tol=1e-2, a0_per_s=0.1, a1_s=0.1)
    assert res.settings["auto_choice"].startswith("modal")
    assert res.model.startswith("auto:modal")
    ref = simulate_fe(beam, drive, t, n_elements=6, a0_per_s=0.1, a1_s=0.1, rtol=1e-9, atol=1e-12)
    real = _rel_err(res.tip_lateral_m, ref.tip_lateral_m)
    assert real <= res.settings["auto_error_estimate"] <= 1e-2
    assert "nonlinear" in res.settings["auto_parts"]


@pytest.mark.slow
def test_large_deflection_scene_picks_nonlinear_fe() -> None:
    beam = spin_up_beam()
    drive = SpinUpDrive(10.0)
    t = np.linspace(0.0, 10.0, 101)
    res = simulate_auto(beam, drive, t, tol=1e-2)
    assert res.settings["auto_choice"].startswith("fe-corot")
    assert res.settings["auto_error_estimate"] <= 1e-2
    ref = simulate_fe(beam, drive, t, n_elements=8, rtol=1e-8, atol=1e-10)
    real = _rel_err(res.tip_lateral_m, ref.tip_lateral_m)
    assert real <= res.settings["auto_error_estimate"]
    assert np.max(np.abs(ref.tip_lateral_m)) > 0.05 * beam.length_m  # really large


def test_tol_is_validated() -> None:
    beam = spin_up_beam()
    with pytest.raises(ValueError, match="tol"):
        simulate_auto(beam, SpinUpDrive(4.0), np.linspace(0.0, 1.0, 3), tol=0.0)
