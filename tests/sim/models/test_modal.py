"""The modal beam on a prescribed hub: energy balance, rotating-beam frequencies, spin-up
(with and without stiffening), an independent integration, the rigid baseline."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla
from scipy.integrate import cumulative_simpson, solve_ivp

from sim.beam import BeamProperties, spin_up_beam
from sim.config import BeamConfig
from sim.drives import SinusoidDrive, SpinUpDrive
from sim.models.modal import ModalModel, integrate_modal, simulate_modal
from sim.models.rigid import simulate_rigid
from sim.modes import mode_shapes

BEAM = BeamProperties.from_config(BeamConfig())
GAUGES = [0.005, 0.204, 0.403, 0.603]


@pytest.mark.parametrize("tip_mass_kg", [0.0, 0.05])
def test_energy_balance_with_damping_off_on_the_reciprocating_scene(tip_mass_kg: float) -> None:
    """Work done by the hub torque = change of kinetic + strain energy."""
    drive = SinusoidDrive()
    model = ModalModel.build(BEAM, 4, tip_mass_kg=tip_mass_kg)
    t = np.linspace(0.0, 2.0, 8001)
    q, qd, _ = integrate_modal(model, drive, t, rtol=1e-10, atol=1e-15)
    qdd = model.accelerations(drive, t, q, qd)
    power = drive.rate(t) * model.hub_torque_n_m(drive, t, q, qd, qdd)
    work = cumulative_simpson(power, x=t, initial=0.0)
    energy = model.kinetic_energy_j(drive, t, q, qd) + model.strain_energy_j(q)
    elastic_part = energy - 0.5 * drive.rate(t) ** 2 * model.integrals.hub_inertia_kg_m2
    assert np.abs(elastic_part).max() > 1e-3  # the beam does carry energy
    assert np.abs(work - (energy - energy[0])).max() < 1e-7 * np.abs(energy).max()
    # a sign error in the stiffening term would break the balance
    wrong = ModalModel.build(BEAM, 4, tip_mass_kg=tip_mass_kg)
    object.__setattr__(wrong.integrals, "centrifugal", -wrong.integrals.centrifugal)
    q2, qd2, _ = integrate_modal(wrong, drive, t, rtol=1e-10, atol=1e-15)
    e2 = model.kinetic_energy_j(drive, t, q2, qd2) + model.strain_energy_j(q2)
    p2 = drive.rate(t) * model.hub_torque_n_m(
        drive, t, q2, qd2, wrong.accelerations(drive, t, q2, qd2)
    )
    w2 = cumulative_simpson(p2, x=t, initial=0.0)
    assert np.abs(w2 - (e2 - e2[0])).max() > 1e3 * np.abs(work - (energy - energy[0])).max()


def test_rotating_beam_frequency_converges_to_the_tabulated_value() -> None:
    """Uniform cantilever spinning about its root at Omega = sqrt(EI / rhoA L^4):
    out-of-plane 3.6816, in-plane sqrt(3.6816^2 - 1) (Wright et al. 1982)."""
    beam = BeamProperties(1.0, 0.0, 1.0, 1.0, 1.0)
    first = []
    for n in (1, 2, 4, 8):
        mi = ModalModel.build(beam, n).integrals
        w = np.sqrt(sla.eigh(mi.stiffness + mi.centrifugal - mi.mass, mi.mass, eigvals_only=True))
        first.append(w[0])
    assert np.all(np.diff(first) < 0)  # Rayleigh-Ritz: from above
    assert first[-1] == pytest.approx(np.sqrt(3.6816**2 - 1.0), abs=1e-4)


def test_spin_up_with_stiffening_is_bounded_and_converges_in_n_modes() -> None:
    beam = spin_up_beam()
    t = np.linspace(0.0, 30.0, 1501)
    tips = {
        n: simulate_modal(beam, SpinUpDrive(4.0), t, n_modes=n, rtol=1e-6).tip_lateral_m
        for n in (2, 3, 5)
    }
    peak = np.abs(tips[5]).max()
    assert 0.1 < peak < 1.0  # bounded, of the order of the known ~0.4 m
    d23 = np.abs(tips[2] - tips[3]).max()
    d35 = np.abs(tips[3] - tips[5]).max()
    assert d35 < 0.2 * d23
    assert d35 < 1e-3 * peak
    # steady spin at 4 rad/s: the beam settles near its rigid position (no damping: it
    # oscillates about it with a small amplitude)
    assert np.abs(tips[5][t > 20.0]).max() < 0.05 * peak


def test_spin_up_without_stiffening_diverges() -> None:
    beam = spin_up_beam()
    t = np.linspace(0.0, 30.0, 1501)
    res = simulate_modal(beam, SpinUpDrive(4.0), t, n_modes=3, stiffening=False, rtol=1e-6)
    assert np.abs(res.tip_lateral_m).max() > 1e3 * beam.length_m


def test_batched_radau_matches_an_independent_integration() -> None:
    drive = SinusoidDrive()
    model = ModalModel.build(BEAM, 3, a0_per_s=0.1, a1_s=0.1)
    t = np.linspace(0.0, 0.8, 321)
    res = simulate_modal(
        BEAM,
        drive,
        t,
        n_modes=3,
        a0_per_s=0.1,
        a1_s=0.1,
        rtol=1e-9,
        atol=1e-14,
        gauge_positions_m=GAUGES,
    )

    def rhs(tt: float, x: np.ndarray) -> np.ndarray:
        q, qd = x[None, :3], x[None, 3:]
        return np.concatenate([x[3:], model.accelerations(drive, np.array([tt]), q, qd)[0]])

    a0, a1, _ = model.first_order_parts()

    def jac(tt: float, _x: np.ndarray) -> np.ndarray:
        return a0 + float(drive.rate(tt)) ** 2 * a1

    sol = solve_ivp(
        rhs, (0.0, 0.8), np.zeros(6), method="Radau", jac=jac, t_eval=t, rtol=1e-12, atol=1e-16
    )
    tip = sol.y[:3].T @ model.integrals.tip_shape
    assert np.abs(res.tip_lateral_m - tip).max() < 1e-8 * np.abs(tip).max()
    assert res.settings["error_estimate_m"] < 1e-9 * np.abs(tip).max()
    # strain sign: a beam lagging toward -lateral near the clamp reads positive strain
    assert np.sign(res.strain[100, 0]) == -np.sign(res.tip_lateral_m[100])
    assert (res.tip_longitudinal_m <= 0.0).all()


def test_reciprocating_tip_amplitude_and_rigid_baseline() -> None:
    drive = SinusoidDrive()
    t = np.arange(0.0, 6.0, 1.0 / 400.0)
    res = simulate_modal(
        BEAM, drive, t, a0_per_s=0.1, a1_s=0.1, rtol=1e-6, gauge_positions_m=GAUGES
    )
    steady = np.abs(res.tip_lateral_m[t > 3.0]).max()
    assert steady == pytest.approx(0.031, abs=0.002)  # the "about 31 mm"
    rigid = simulate_rigid(BEAM, drive, t, gauge_positions_m=GAUGES)
    assert not rigid.tip_lateral_m.any() and not rigid.strain.any()
    assert rigid.hub_angle_rad == pytest.approx(drive.angle(t))
    assert rigid.strain.shape == (t.size, 4)


def test_bad_inputs_name_the_parameter() -> None:
    t = np.linspace(0, 1, 11)
    with pytest.raises(ValueError, match="n_modes"):
        simulate_modal(BEAM, SinusoidDrive(), t, n_modes=0)
    with pytest.raises(ValueError, match="t_eval_s"):
        simulate_modal(BEAM, SinusoidDrive(), t[::-1])
    with pytest.raises(ValueError, match="gauge_positions_m"):
        simulate_modal(BEAM, SinusoidDrive(), t, gauge_positions_m=[2.0])
    with pytest.raises(TypeError, match="drive"):
        simulate_rigid(BEAM, object(), t)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="a1_s"):
        simulate_modal(BEAM, SinusoidDrive(), t, a1_s=-1.0)


def test_energy_balance_with_damping_on_accounts_for_the_dissipation() -> None:
    """W_hub = dE + int q'^T C(t) q' dt with C = a0 M + a1 (K + theta'^2 G) (Eq. 28, K_T)."""
    drive = SinusoidDrive()
    model = ModalModel.build(BEAM, 3, a0_per_s=0.1, a1_s=0.1)
    t = np.linspace(0.0, 2.0, 8001)
    q, qd, _ = integrate_modal(model, drive, t, rtol=1e-10, atol=1e-15)
    qdd = model.accelerations(drive, t, q, qd)
    power = drive.rate(t) * model.hub_torque_n_m(drive, t, q, qd, qdd)
    c_t = model.damping[None] + (drive.rate(t) ** 2)[:, None, None] * model.rotation_damping[None]
    loss = cumulative_simpson(np.einsum("ki,kij,kj->k", qd, c_t, qd), x=t, initial=0.0)
    work = cumulative_simpson(power, x=t, initial=0.0)
    energy = model.kinetic_energy_j(drive, t, q, qd) + model.strain_energy_j(q)
    assert loss[-1] > 1e-3 * np.abs(energy).max()
    assert np.abs(work - loss - (energy - energy[0])).max() < 1e-7 * np.abs(energy).max()
    assert np.abs(model.rotation_damping).max() > 0.0


def test_station_foreshortening_is_the_integral_and_kept_read_only() -> None:
    """D(s) = int_0^s Phi' Phi'^T: against a plain trapezoid sum on a fine grid; the kept
    matrices of an earlier call (a damping fit simulates one beam a hundred times) are
    read-only and are the ones of the stations asked for, not of earlier ones."""
    from sim.models.modal import station_foreshortening_matrices

    length, n = 0.835, 4
    stations = np.array([0.0, 0.2, 0.61, length])
    d = station_foreshortening_matrices(length, stations, n)
    for s, got in zip(stations, d, strict=True):
        x = np.linspace(0.0, s, 20001)
        slope = mode_shapes(x, length, n, 1)
        want = np.trapezoid(slope[:, :, None] * slope[:, None, :], x, axis=0)
        np.testing.assert_allclose(got, want, rtol=1e-7, atol=1e-9)
    assert station_foreshortening_matrices(length, stations.copy(), n) is d
    assert not d.flags.writeable
    other = station_foreshortening_matrices(length, stations[::-1].copy(), n)
    np.testing.assert_array_equal(other, d[::-1])
    assert station_foreshortening_matrices(length, stations, n - 1).shape == (4, n - 1, n - 1)
