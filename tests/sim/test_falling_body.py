"""Seed 001's falling body: the conservation laws of a free system under uniform gravity."""

from __future__ import annotations

import numpy as np
import pytest

from sim.beam import BeamProperties
from sim.config import BeamConfig
from sim.falling_body import STANDARD_GRAVITY_M_S2, FallingBody


def test_mass_centre_falls_at_g_and_momentum_and_energy_are_conserved() -> None:
    body = FallingBody(BeamProperties.from_config(BeamConfig()), n_modes=2)
    t = np.linspace(0.0, 0.3, 61)
    x0 = np.zeros(10)
    x0[3] = 0.01  # bent in mode 1
    x0[7], x0[8], x0[6] = 0.3, 2.0, 0.5  # CR velocity (body axes) and spin; mode 1 rate
    run = body.simulate(t, x0)
    p = run.linear_momentum_kg_m_s()
    m = body.total_mass_kg
    assert p[:, 0] == pytest.approx(p[0, 0], abs=1e-10)
    assert p[:, 1] == pytest.approx(p[0, 1] - m * STANDARD_GRAVITY_M_S2 * t, abs=1e-9)
    c = run.mass_centre_m()
    v0 = p[0] / m
    assert c[:, 1] == pytest.approx(
        c[0, 1] + v0[1] * t - 0.5 * STANDARD_GRAVITY_M_S2 * t**2, abs=1e-10
    )
    assert c[:, 0] == pytest.approx(c[0, 0] + v0[0] * t, abs=1e-10)
    h = run.angular_momentum_kg_m2_s()
    assert np.ptp(h) < 1e-9 * abs(h[0])
    e = run.energy_j()
    assert np.ptp(e) < 1e-9 * np.abs(e).max()
    # the beam really vibrates and the body really spins
    eta = run.modal_amplitudes_m()[:, 0]
    assert np.ptp(eta) > 1e-3
    assert np.ptp(run.states[:, 2]) > 0.1


def test_bad_parameters_are_refused() -> None:
    with pytest.raises(ValueError, match="body_mass_kg"):
        FallingBody(BeamProperties.from_config(BeamConfig()), body_mass_kg=0.0)
