"""Exudyn's ANCF cable (the ``bench sim`` peer) against closed forms and beambench's FE.

Exudyn is a dev dependency, so these run in ``make test``: an independent code checks the
simulator there, not only in ``bench sim``.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from pipelines.bench.peers_exudyn import (
    first_frequency_hz,
    simulate_exudyn,
    simulate_fe_kelvin_voigt,
    static_tip_deflection_m,
)
from sim.beam import BeamProperties, spin_up_beam
from sim.config import BeamConfig
from sim.drives import SinusoidDrive, SpinUpDrive
from sim.models.fe import simulate_fe

RIG = BeamProperties.from_config(BeamConfig())


@pytest.mark.parametrize("n_elements", [1, 2, 4])
def test_static_tip_deflection_is_pl3_over_3ei(n_elements: int) -> None:
    # a tip-loaded cantilever bends as a cubic, which the Hermite cable holds exactly:
    # no discretisation error; at delta/L = 1e-4 the geometric nonlinearity is ~(delta/L)^2
    # = 1e-8 (measured 1.0e-8 .. 1.3e-8 for 1 .. 8 elements)
    L, EI = RIG.length_m, RIG.bending_stiffness_n_m2
    force = 1e-4 * 3.0 * EI / L**2
    exact = force * L**3 / (3.0 * EI)
    tip = static_tip_deflection_m(RIG, force, n_elements)
    assert tip == pytest.approx(-exact, rel=5e-8)


def test_first_frequency_converges_to_the_closed_form_at_fourth_order() -> None:
    L, EI, rho_a = RIG.length_m, RIG.bending_stiffness_n_m2, RIG.mass_per_length_kg_m
    exact = 1.87510407**2 * math.sqrt(EI / (rho_a * L**4)) / (2.0 * math.pi)
    errs = [first_frequency_hz(RIG, n) / exact - 1.0 for n in (2, 4, 8)]
    # cubic Hermite elements: eigenvalue error ~ h^4 (measured 4.8e-4, 3.3e-5, 2.1e-6)
    assert errs[-1] == pytest.approx(0.0, abs=3e-6)
    assert all(e > 0.0 for e in errs)  # consistent mass, conforming: from above
    rates = [math.log2(a / b) for a, b in itertools.pairwise(errs)]
    assert all(3.6 < r < 4.4 for r in rates), rates


@pytest.mark.slow
def test_spin_up_tip_follows_beambench_fe_to_the_discretisation_error() -> None:
    # undamped, so both codes model the same beam: the difference must shrink with
    # Exudyn's step and elements (measured 4.3e-4, 1.1e-4 of the 0.40 m peak at
    # (4 el., 10 ms), (8 el., 5 ms); beambench's 6-element reference is ~1e-5 off itself)
    t = np.linspace(0.0, 20.0, 401)
    drive = SpinUpDrive(4.0)
    ref = simulate_fe(spin_up_beam(), drive, t, n_elements=6, rtol=1e-7, atol=1e-10)
    peak = float(np.max(np.abs(ref.tip_lateral_m)))
    errs = []
    for n, h in [(4, 0.01), (8, 0.005)]:
        res = simulate_exudyn(spin_up_beam(), drive, t, n_elements=n, step_s=h)
        errs.append(float(np.max(np.abs(res.tip_lateral_m - ref.tip_lateral_m))) / peak)
    assert errs[0] < 1e-3
    assert errs[1] < 0.5 * errs[0] and errs[1] < 2.5e-4, errs


@pytest.mark.slow
def test_reciprocating_tip_agrees_with_beambench_fe_of_the_same_damping_law() -> None:
    # Exudyn's damping is strain-rate damping (a1 EA, a1 EI); beambench's FE with that law
    # is the yardstick. Exudyn's own convergence on this scene (2 s, last second): 2 el. /
    # 5 ms is 1.1e-4 off, 4 el. / 1 ms 3.6e-6 (the same on 5 s), so the finer run must
    # agree to 2e-5 and sit well inside the coarse one's error.
    t = np.linspace(0.0, 2.0, 401)
    drive = SinusoidDrive(0.7669, 4.970)
    window = t >= 1.0
    same_law = simulate_fe_kelvin_voigt(RIG, drive, t, n_elements=6, a1_s=0.1, rtol=1e-9)
    amp = float(np.max(np.abs(same_law.tip_lateral_m[window])))

    def rel(res_tip: np.ndarray, ref_tip: np.ndarray) -> float:
        return float(np.max(np.abs(res_tip[window] - ref_tip[window]))) / amp

    coarse = simulate_exudyn(RIG, drive, t, n_elements=2, step_s=0.005, a1_s=0.1)
    fine = simulate_exudyn(RIG, drive, t, n_elements=4, step_s=0.001, a1_s=0.1)
    e_coarse = rel(coarse.tip_lateral_m, same_law.tip_lateral_m)
    e_fine = rel(fine.tip_lateral_m, same_law.tip_lateral_m)
    assert e_coarse < 5e-4
    assert e_fine < 2e-5 and e_fine < 0.2 * e_coarse, (e_coarse, e_fine)
    # and the Eq. 28 model differs by its geometric damping term, ~1.3e-2 of the tip:
    # (measured 1.26e-2), a model difference far above either discretisation error
    eq28 = simulate_fe(RIG, drive, t, n_elements=6, a0_per_s=0.0, a1_s=0.1, rtol=1e-9)
    assert 5e-3 < rel(same_law.tip_lateral_m, eq28.tip_lateral_m) < 3e-2


def test_output_times_off_the_step_grid_are_refused() -> None:
    with pytest.raises(ValueError, match="step grid"):
        simulate_exudyn(
            RIG, SinusoidDrive(), np.array([0.0, 0.01, 0.0125]), n_elements=2, step_s=0.005
        )
