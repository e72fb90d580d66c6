"""The third-order (geometrically nonlinear) modal model: its energies against the exact
inextensible beam, its energy balance, and its agreement with the linear model at small
amplitude."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import cumulative_simpson, cumulative_trapezoid

from sim.beam import BeamProperties
from sim.config import BeamConfig
from sim.drives import SinusoidDrive
from sim.models.modal import ModalModel, simulate_modal
from sim.models.modal_nonlinear import (
    NonlinearModalTerms,
    integrate_modal_nonlinear,
    simulate_modal_nonlinear,
)
from sim.modes import mode_shapes

BEAM = BeamProperties.from_config(BeamConfig())


def _energies(model: ModalModel, terms: NonlinearModalTerms, q, qd, rate):  # type: ignore[no-untyped-def]
    mi = model.integrals
    ta, tb, tc, v4 = terms.energy_parts(q, qd)
    t_a = 0.5 * np.einsum("ni,ij,nj->n", qd, mi.mass, qd) + ta
    t_b = qd @ mi.euler + tb
    t_c = (
        0.5 * (np.einsum("ni,ij,nj->n", q, mi.mass - mi.centrifugal, q) + mi.hub_inertia_kg_m2) + tc
    )
    v = 0.5 * np.einsum("ni,ij,nj->n", q, mi.stiffness, q) + v4
    return t_a + rate * t_b + rate**2 * t_c, v, t_b + 2.0 * rate * t_c


def test_energies_match_the_exact_inextensible_beam_to_fourth_order() -> None:
    n = 3
    model = ModalModel.build(BEAM, n)
    terms = NonlinearModalTerms.build(model)
    L, r = BEAM.length_m, BEAM.hub_offset_m
    xs = np.linspace(0.0, L, 100_001)
    phi, dphi, ddphi = (mode_shapes(xs, L, n, k) for k in (0, 1, 2))
    q0 = np.array([0.05, -0.004, 0.001])
    qd0 = np.array([0.3, 0.05, -0.01])
    rate = 2.3
    residual_t, residual_v = [], []
    for eps in (1.0, 0.5):
        q, qd = eps * q0, eps * qd0
        wp, wpd = dphi @ q, dphi @ qd
        root = np.sqrt(1.0 - wp**2)
        u = cumulative_trapezoid(root - 1.0, xs, initial=0.0)
        ud = cumulative_trapezoid(-wp * wpd / root, xs, initial=0.0)
        vx = ud - rate * (phi @ q)
        vy = phi @ qd + rate * (r + xs + u)
        t_exact = 0.5 * BEAM.mass_per_length_kg_m * np.trapezoid(vx**2 + vy**2, xs)
        v_exact = 0.5 * BEAM.bending_stiffness_n_m2 * np.trapezoid((ddphi @ q / root) ** 2, xs)
        t, v, _ = _energies(model, terms, q[None], qd[None], np.array([rate]))
        residual_t.append(abs(t_exact - t[0]))
        residual_v.append(abs(v_exact - v[0]))
    # what is left is fifth (T) and sixth (V) order in the amplitude
    assert residual_t[0] / residual_t[1] > 20.0
    assert residual_v[0] / residual_v[1] > 40.0


def test_energy_balance_with_damping_off() -> None:
    drive = SinusoidDrive()
    model = ModalModel.build(BEAM, 3)
    terms = NonlinearModalTerms.build(model)
    t = np.linspace(0.0, 2.0, 4001)
    q, qd, info = integrate_modal_nonlinear(model, terms, drive, t, rtol=1e-11, atol=1e-15)
    assert info["iterations"] >= 2
    rate, acc = drive.rate(t), drive.accel(t)
    t_kin, v, p_theta = _energies(model, terms, q, qd, rate)
    energy = t_kin + v
    # hub work = int theta' dp = [theta' p] - int p theta'' dt
    work = (
        rate * p_theta - rate[0] * p_theta[0] - cumulative_simpson(p_theta * acc, x=t, initial=0.0)
    )
    scale = np.abs(energy - 0.5 * rate**2 * model.integrals.hub_inertia_kg_m2).max()
    assert np.abs(work - (energy - energy[0])).max() < 1e-6 * scale
    # and the linear model's energy, used on the nonlinear trajectory, does not balance
    lin = model.kinetic_energy_j(drive, t, q, qd) + model.strain_energy_j(q)
    p_lin = qd @ model.integrals.euler + rate * (
        np.einsum("ni,ij,nj->n", q, model.integrals.mass - model.integrals.centrifugal, q)
        + model.integrals.hub_inertia_kg_m2
    )
    w_lin = rate * p_lin - rate[0] * p_lin[0] - cumulative_simpson(p_lin * acc, x=t, initial=0.0)
    assert np.abs(w_lin - (lin - lin[0])).max() > 100 * np.abs(work - (energy - energy[0])).max()


def test_tends_to_the_linear_model_at_small_amplitude() -> None:
    t = np.arange(0.0, 3.0, 1.0 / 200.0)
    diffs = []
    for amp in (0.4, 0.2):
        drive = SinusoidDrive(amp, 4.97)
        kw = {"n_modes": 3, "a0_per_s": 0.1, "a1_s": 0.1, "rtol": 1e-9}
        lin = simulate_modal(BEAM, drive, t, **kw).tip_lateral_m  # type: ignore[arg-type]
        nl = simulate_modal_nonlinear(BEAM, drive, t, **kw)  # type: ignore[arg-type]
        assert nl.model == "modal-nonlinear"
        diffs.append(np.abs(nl.tip_lateral_m - lin).max() / np.abs(lin).max())
    assert diffs[0] / diffs[1] == pytest.approx(4.0, rel=0.15)  # relative effect ~ amplitude^2
    assert diffs[0] < 5e-3
