"""The two damping laws (``paper``: a1 K_T, ``material``: Kelvin-Voigt) in the modal models
against the exact finite-element beam with the same law, and the size of their difference."""

from __future__ import annotations

import numpy as np
import pytest

from sim.beam import BeamProperties
from sim.config import BeamConfig, DampingConfig
from sim.drives import SinusoidDrive
from sim.errors import SimInputError
from sim.models.fe import simulate_fe
from sim.models.modal import simulate_modal
from sim.models.modal_nonlinear import simulate_modal_nonlinear
from sim.models.registry import simulate

BEAM = BeamProperties.from_config(BeamConfig())
T = np.linspace(0.0, 3.0, 601)
DRIVE = SinusoidDrive(0.7669, 4.970)  # Eq. 53
WINDOW = T >= 1.0
DAMP = {"a0_per_s": 0.1, "a1_s": 0.1}


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a[WINDOW] - b[WINDOW])) / np.max(np.abs(b[WINDOW])))


@pytest.fixture(scope="module")
def fe_material() -> np.ndarray:
    res = simulate_fe(
        BEAM, DRIVE, T, n_elements=6, rtol=1e-8, atol=1e-11, damping_law="material", **DAMP
    )
    return res.tip_lateral_m


def test_nonlinear_modal_with_the_material_law_is_the_exact_beam_to_fourth_order(
    fe_material: np.ndarray,
) -> None:
    # third-order modal model with the gradient of the Kelvin-Voigt dissipation of the
    # exact curvature: what is left is O((delta/L)^4) ~ 2e-6 at delta/L = 0.037 and the FE's
    # h^4 (measured 5.6e-6 with 4 modes, 1.9e-6 with 6)
    nl = simulate_modal_nonlinear(BEAM, DRIVE, T, n_modes=6, damping_law="material", **DAMP)
    assert _rel(nl.tip_lateral_m, fe_material) < 1e-5
    # the paper law's tangent damping (a1 times the tangent of V4 and the geometric
    # stiffness of the axial force) is a different model: 3.6e-3 away
    nl_paper = simulate_modal_nonlinear(BEAM, DRIVE, T, n_modes=6, damping_law="paper", **DAMP)
    assert _rel(nl_paper.tip_lateral_m, fe_material) > 1e-3


def test_linear_modal_with_the_material_law_is_within_its_nonlinearity_estimate(
    fe_material: np.ndarray,
) -> None:
    # the linear model's error is the geometric nonlinearity, ~C (delta/L)^2 with C <= 1.5
    # (sim.models.model_choice): 2.0e-3 here, measured 4.6e-4; with the paper law the
    # modal model also misses the lag of the tension in its damping (4.4e-3 against the
    # paper-law FE), and against the material-law beam it is off by the law (1.3e-2)
    lin = simulate_modal(BEAM, DRIVE, T, n_modes=4, damping_law="material", **DAMP)
    delta_over_l = float(np.max(np.abs(fe_material[WINDOW]))) / BEAM.length_m
    assert _rel(lin.tip_lateral_m, fe_material) < 1.5 * delta_over_l**2
    paper = simulate_modal(BEAM, DRIVE, T, n_modes=4, damping_law="paper", **DAMP)
    assert _rel(paper.tip_lateral_m, fe_material) > 5e-3
    assert lin.settings["damping_law"] == "material"
    assert paper.settings["damping_law"] == "paper"


def test_the_laws_agree_without_rotation_or_without_a1() -> None:
    # the geometric damping term is a1 times the centrifugal stiffness: nothing without a1
    a = simulate_modal(BEAM, DRIVE, T, a0_per_s=0.3, damping_law="paper")
    b = simulate_modal(BEAM, DRIVE, T, a0_per_s=0.3, damping_law="material")
    np.testing.assert_array_equal(a.tip_lateral_m, b.tip_lateral_m)


@pytest.mark.parametrize("model", ["auto", "modal", "fe"])
def test_a_misspelt_law_names_the_parameter(model: str) -> None:
    with pytest.raises(SimInputError, match="damping_law"):
        simulate(model, BEAM, DRIVE, T[:5], damping_law="kelvin")
    with pytest.raises(SimInputError, match="law"):
        DampingConfig(law="Paper")
