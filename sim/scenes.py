"""The simulator's scenes: what ``beambench sim SCENE`` runs, as plain functions.

Each scene takes the bench's configuration dataclasses (``sim.config``) and returns a
:class:`SceneRun`: the :class:`SimResult` and the scene's extra numbers. A scene that does
not run the requested model raises :class:`sim.errors.ModelNotAvailable` rather than
substituting another model.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sim.beam import BeamProperties, spin_up_beam
from sim.checks import check_non_negative, check_positive
from sim.config import BeamConfig, DampingConfig, DriveConfig, LinkageConfig
from sim.damping import (
    damping_ratio_from_log_decrement,
    identify_equal_coefficients,
    log_decrement,
    modal_damping_ratio,
)
from sim.drives import Drive, FixedDrive, FourBarDrive, SinusoidDrive, SpinUpDrive
from sim.errors import ModelNotAvailable, SimInputError
from sim.falling_body import STANDARD_GRAVITY_M_S2, FallingBody
from sim.four_bar import (
    PAPER_CRANK_AT_MAX_RAD,
    PAPER_CRANK_AT_MIN_RAD,
    PAPER_ROCKER_MAX_RAD,
    PAPER_ROCKER_MIN_RAD,
    FourBar,
)
from sim.models.fe import solve_static_fe
from sim.models.modal import ModalModel, modal_result, simulate_modal
from sim.models.registry import check_model, simulate
from sim.models.rigid import simulate_rigid
from sim.modes import clamped_free_eigenvalues, mode_shapes, natural_frequencies_rad_s
from sim.result import SimResult
from sim.statics import solve_static_elastica, solve_static_modal

FloatArray = NDArray[np.float64]

SCENE_MODAL_RTOL = 1e-6


@dataclass(frozen=True)
class SceneRun:
    result: SimResult
    extras: dict[str, Any] = field(default_factory=dict)


def _scene_tol(model: str, rtol: float | None) -> float | None:
    """The scenes run the modal model at rtol 1e-6 unless told otherwise (the model's own
    default is 1e-8); the other models keep their own defaults (fe rtol 1e-6, auto tol 1e-4)."""
    if rtol is None and model == "modal":
        return SCENE_MODAL_RTOL
    return rtol


def _times(duration_s: float, rate_hz: float) -> FloatArray:
    check_positive("duration_s", duration_s)
    check_positive("output_rate_hz", rate_hz)
    n = round(duration_s * rate_hz)
    if n < 1:
        raise SimInputError("duration_s", f"{duration_s!r} is shorter than one output interval")
    return np.arange(n + 1) / rate_hz


def reciprocating(
    linkage: LinkageConfig,
    beam: BeamConfig,
    drive_config: DriveConfig,
    *,
    drive: str = "paper",
    a0_per_s: float = 0.1,
    a1_s: float = 0.1,
    duration_s: float = 10.0,
    model: str = "modal",
    gauge_positions_m: Sequence[float] = (),
    output_rate_hz: float = 400.0,
    n_modes: int = 4,
    rtol: float | None = None,
    nonlinear: bool = False,
    damping_law: str = "paper",
) -> SceneRun:
    """The bench's reciprocating beam from rest: the paper's sinusoid (Eq. 53) or the
    four-bar's true output at ``linkage.crank_frequency_hz``; ``damping_law`` as
    :class:`sim.models.registry.ModelSettings`."""
    props = BeamProperties.from_config(beam)
    hub: Drive
    if drive == "paper":
        hub = SinusoidDrive(drive_config.paper_amplitude_rad, drive_config.paper_omega_rad_s)
    elif drive == "fourbar":
        hub = FourBarDrive(
            FourBar.from_config(linkage), 2.0 * math.pi * linkage.crank_frequency_hz, about="mid"
        )
    else:
        raise SimInputError("drive", f"must be 'paper' or 'fourbar', got {drive!r}")
    t = _times(duration_s, output_rate_hz)
    res = simulate(
        model,
        props,
        hub,
        t,
        a0_per_s=a0_per_s,
        a1_s=a1_s,
        gauge_positions_m=gauge_positions_m,
        n_modes=n_modes,
        tol=_scene_tol(model, rtol),
        nonlinear=nonlinear,
        damping_law=damping_law,
    )
    extras = {"drive": drive, "a0_per_s": a0_per_s, "a1_s": a1_s, "damping_law": damping_law}
    return SceneRun(res, extras)


def static(
    beam: BeamConfig,
    *,
    mass_kg: float,
    model: str = "auto",
    gauge_positions_m: Sequence[float] = (),
    gravity_m_s2: float = STANDARD_GRAVITY_M_S2,
    n_modes: int = 10,
) -> SceneRun:
    """Equilibrium under a tip weight ``mass_kg * g`` acting toward -lateral (Table 2).

    ``modal``: linear, ``n_modes`` modes (tip within 1e-4 of PL^3/3EI at 10 modes);
    ``fe``: geometrically nonlinear finite elements (``sim.models.fe.solve_static_fe``);
    ``auto``: the exact elastica (nonlinear, closed form); ``rigid``: no deflection.
    """
    check_non_negative("mass_kg", mass_kg)
    props = BeamProperties.from_config(beam)
    force = mass_kg * gravity_m_s2
    if check_model(model) == "modal":
        res = solve_static_modal(props, force, n_modes=n_modes, gauge_positions_m=gauge_positions_m)
    elif model == "fe":
        res = solve_static_fe(props, force, gauge_positions_m=gauge_positions_m)
    elif model == "auto":
        res = solve_static_elastica(props, force, gauge_positions_m=gauge_positions_m)
    else:
        res = simulate_rigid(props, FixedDrive(), np.zeros(1), gauge_positions_m=gauge_positions_m)
    linear = force * props.length_m**3 / (3.0 * props.bending_stiffness_n_m2)
    return SceneRun(res, {"mass_kg": mass_kg, "tip_force_n": force, "linear_tip_m": linear})


def free_decay(
    beam: BeamConfig,
    damping: DampingConfig,
    *,
    mass_kg: float = 0.1,
    a0_per_s: float | None = None,
    a1_s: float | None = None,
    duration_s: float = 10.0,
    model: str = "modal",
    gauge_positions_m: Sequence[float] = (),
    output_rate_hz: float = 400.0,
    n_modes: int = 4,
    target_log_decrement: float | None = None,
    gauge_index: int = 1,
) -> SceneRun:
    """The tip released from rest from the static shape under ``mass_kg`` (hub held still);
    the log decrement of the strain at gauge ``gauge_index`` (gauge 2, as §5.2.1), its
    damping ratio, and the equal a0 = a1 that reproduces ``target_log_decrement`` (default:
    the simulated decrement, a round trip)."""
    if check_model(model) in ("fe", "rigid"):
        raise ModelNotAvailable(
            model, "free-decay", "a released beam is wired for the modal model only"
        )
    check_positive("mass_kg", mass_kg)
    a0 = damping.free_decay_a0_per_s if a0_per_s is None else a0_per_s
    a1 = damping.free_decay_a1_s if a1_s is None else a1_s
    gauges = list(gauge_positions_m)
    if not gauges:
        raise SimInputError(
            "gauge_positions_m", "must not be empty: the free-decay scene needs them"
        )
    if not 0 <= gauge_index < len(gauges):
        raise SimInputError(
            "gauge_index", f"{gauge_index!r} is not one of the {len(gauges)} gauges"
        )
    props = BeamProperties.from_config(beam)
    force = mass_kg * STANDARD_GRAVITY_M_S2
    mi = ModalModel.build(props, n_modes).integrals
    q0 = np.linalg.solve(mi.stiffness, -force * mi.tip_shape)
    t = _times(duration_s, output_rate_hz)
    hub = FixedDrive()

    def run(a0_: float, a1_: float) -> SimResult:
        return simulate_modal(
            props,
            hub,
            t,
            n_modes=n_modes,
            a0_per_s=a0_,
            a1_s=a1_,
            gauge_positions_m=gauges,
            initial_q=q0,
            rtol=1e-5,
            atol=1e-12,
        )

    res = run(a0, a1)
    signal = res.strain[:, gauge_index]
    delta = log_decrement(t, signal)
    zeta = damping_ratio_from_log_decrement(delta)
    target = delta if target_log_decrement is None else target_log_decrement
    w1 = float(
        natural_frequencies_rad_s(
            1, props.length_m, props.bending_stiffness_n_m2, props.mass_per_length_kg_m
        )[0]
    )
    upper = 0.4 / w1  # zeta_1 ~ 0.2: still enough peaks to measure a decrement
    ident = identify_equal_coefficients(
        lambda a: (t, run(a, a).strain[:, gauge_index]), target, lower=1e-7, upper=upper
    )
    extras = {
        "log_decrement": delta,
        "damping_ratio": zeta,
        "damping_ratio_mode1_eq37": float(modal_damping_ratio(a0, a1, w1)),
        "identified_a0_per_s": ident,
        "identified_a1_s": ident,
        "target_log_decrement": target,
        "initial_tip_m": float(mi.tip_shape @ q0),
    }
    return SceneRun(res, extras)


def spin_up(
    *,
    omega_rad_s: float = 4.0,
    ramp_s: float = 15.0,
    duration_s: float = 30.0,
    model: str = "modal",
    n_modes: int = 6,
    stiffening: bool = True,
    output_rate_hz: float = 100.0,
    rtol: float | None = None,
    nonlinear: bool = False,
) -> SceneRun:
    """The Kane / Simo-Vu-Quoc spin-up beam (``sim.beam.spin_up_beam``, no hub offset)."""
    beam = spin_up_beam()
    hub = SpinUpDrive(omega_rad_s, ramp_s)
    t = _times(duration_s, output_rate_hz)
    res = simulate(
        model,
        beam,
        hub,
        t,
        n_modes=n_modes,
        tol=_scene_tol(model, rtol),
        # without stiffening it is seed 001's linear model: ``nonlinear`` does not apply
        nonlinear=nonlinear and stiffening,
        stiffening=stiffening,
    )
    return SceneRun(res, {"omega_rad_s": omega_rad_s, "ramp_s": ramp_s})


def falling_body(
    beam: BeamConfig,
    *,
    duration_s: float = 2.0,
    n_modes: int = 2,
    gauge_positions_m: Sequence[float] = (),
    output_rate_hz: float = 400.0,
    initial_tip_m: float = 0.01,
    initial_spin_rad_s: float = 1.0,
) -> SceneRun:
    """Seed 001's worked problem with the bench's beam: RB released with a spin and the beam
    bent in its first mode; gravity -y."""
    props = BeamProperties.from_config(beam)
    body = FallingBody(props, n_modes=n_modes)
    t = _times(duration_s, output_rate_hz)
    x0 = np.zeros(6 + 2 * n_modes)
    x0[3] = initial_tip_m / 2.0  # Phi_1(L) = 2
    x0[5 + n_modes] = initial_spin_rad_s
    run = body.simulate(t, x0)
    eta = run.modal_amplitudes_m()
    gauges = np.asarray(gauge_positions_m, dtype=float)
    stations = np.linspace(0.0, props.length_m, 21)
    model = ModalModel.build(props, n_modes)
    res = modal_result(
        model,
        FixedDrive(),
        t,
        eta,
        gauges,
        stations,
        run.wall_time_s,
        {"method": "DOP853"},
        rtol=1e-10,
        atol=1e-12,
        name="falling-body",
    )
    # The hub angle here is the body's angle, not a prescribed one.
    res = SimResult(**{**res.__dict__, "hub_angle_rad": run.states[:, 2].copy()})
    energy = run.energy_j()
    ang = run.angular_momentum_kg_m2_s()
    extras = {
        "energy_drift_j": float(np.ptp(energy)),
        "angular_momentum_drift_kg_m2_s": float(np.ptp(ang)),
        "mass_centre_m": run.mass_centre_m(),
    }
    return SceneRun(res, extras)


def modes(beam: BeamConfig, *, n_modes: int = 6, n_stations: int = 41) -> dict[str, Any]:
    """Clamped-free eigenvalues, natural frequencies and shapes of the bench's beam."""
    props = BeamProperties.from_config(beam)
    start = time.perf_counter()
    lam = clamped_free_eigenvalues(n_modes)
    w = natural_frequencies_rad_s(
        n_modes, props.length_m, props.bending_stiffness_n_m2, props.mass_per_length_kg_m
    )
    x = np.linspace(0.0, props.length_m, n_stations)
    shapes = mode_shapes(x, props.length_m, n_modes).T
    return {
        "eigenvalue": lam,
        "frequency_rad_s": w,
        "stations_m": x,
        "shapes": shapes,
        "wall_time_s": time.perf_counter() - start,
    }


def linkage(config: LinkageConfig) -> dict[str, Any]:
    """The four-bar's true extrema, Grashof class and transmission angle range, with the
    paper's printed extrema (Eqs. 10-11) for contrast. Angles in the frame of Eqs. 1-2."""
    fb = FourBar.from_config(config)
    ext = fb.extrema()
    mu_min, mu_max = fb.transmission_angle_range_rad()
    return {
        "rocker_min_rad": ext.rocker_min_rad,
        "crank_at_min_rad": ext.crank_at_min_rad,
        "rocker_max_rad": ext.rocker_max_rad,
        "crank_at_max_rad": ext.crank_at_max_rad,
        "rocker_range_rad": ext.range_rad,
        "grashof": fb.grashof,
        "transmission_angle_min_rad": mu_min,
        "transmission_angle_max_rad": mu_max,
        "paper_rocker_min_rad": PAPER_ROCKER_MIN_RAD,
        "paper_crank_at_min_rad": PAPER_CRANK_AT_MIN_RAD,
        "paper_rocker_max_rad": PAPER_ROCKER_MAX_RAD,
        "paper_crank_at_max_rad": PAPER_CRANK_AT_MAX_RAD,
        "rocker_at_paper_crank_angles_rad": [
            float(fb.rocker_angle_rad(PAPER_CRANK_AT_MIN_RAD)),
            float(fb.rocker_angle_rad(PAPER_CRANK_AT_MAX_RAD)),
        ],
    }
