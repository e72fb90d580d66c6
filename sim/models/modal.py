"""Assumed-modes model of a cantilever on a hub with prescribed rotation.

The hub turns by the prescribed angle theta(t) about a fixed pivot; the beam is clamped at
``hub_offset_m`` = r from the pivot. In the hub frame a material point at distance x from the
clamp sits at (r + x + u(x), w(x)), with w = sum_i Phi_i(x) q_i (clamped-free modes of
``sim.modes``) and the inextensible foreshortening u(x) = -1/2 int_0^x w'^2. Keeping the
kinetic energy to second order in q (which is exact for the linear equations) gives

    M q'' + C q' + [K + theta'^2 (G - M)] q = -theta'' b

with M, K, b, G of :class:`sim.modes.ModalIntegrals`:

- ``-theta'' b``: the Euler (tangential) load -rhoA theta'' (r + x) on every point;
- ``-theta'^2 M q``: centrifugal softening (the centrifugal force on the lateral offset w);
- ``+theta'^2 G q``: centrifugal (geometric) stiffening from the axial force
  N(x) = theta'^2 int_x^L rhoA (r + s) ds acting on the slope, i.e. the work of N on the
  foreshortening u. Seed 001 leaves it out (its velocity field has no u), which makes the
  model go unstable once theta' exceeds the first natural frequency: ``stiffening=False``
  reproduces that classic failure.
- Coriolis: the lateral Coriolis force -2 rhoA theta' u' is second order in q for an
  inextensible beam (u is), and the axial Coriolis force 2 rhoA theta' w' only changes N by
  a term of first order, whose effect on the lateral equation (N w'')' is second order; so
  neither appears in the linear equations.

Damping acts on the elastic deformation rates, C = a0 M + a1 K_d, with one of two laws
(``damping_law``, :data:`sim.config.DAMPING_LAWS`):

- ``"paper"`` (default): Eq. 28 / FLXDYN, K_d = K_T the tangent stiffness, elastic K plus
  the geometric stiffness theta'^2 G of the current axial (centrifugal) force, so C varies
  in time. That is the paper's model and the ``"paper"`` law of the finite elements.
- ``"material"``: Kelvin-Voigt, a1 times the material stiffness acting on the strain rates,
  bending and axial. The bending part is a1 K q' (the dissipation 1/2 a1 int EI w_t''^2).
  The axial part changes nothing here: the beam is inextensible to this order and the axial
  force N = EA (eps + a1 eps') is fixed by the axial balance (the centrifugal load), however
  it splits into an elastic and a viscous part; the lateral equation sees N through the
  geometric stiffness theta'^2 G, which stays, but no a1 G in the damping. So C = a0 M + a1 K,
  constant.

It matters: on the bench (a1 = 0.1 s, first mode overdamped) the two laws move the tip by
1.2 %. ``damping_geometric=False`` is the older spelling of the material law. Without
stiffening there is no G anywhere and the laws agree.

The equations are linear in q with time-varying coefficients; they are integrated with the
batched Radau IIA scheme of ``sim.solvers.linear_radau`` with step halving until the
estimated tip error meets rtol (relative to the largest tip deflection) + atol.
"""

from __future__ import annotations

import functools
import logging
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sim.beam import BeamProperties
from sim.checks import (
    check_choice,
    check_non_negative,
    check_positive,
    check_simulation_inputs,
)
from sim.config import DAMPING_LAWS
from sim.drives import Drive
from sim.errors import SimInputError
from sim.modes import ModalIntegrals, gauss_points, modal_integrals, mode_shapes
from sim.result import SimResult
from sim.solvers.linear_radau import solve_ltv

FloatArray = NDArray[np.float64]

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class ModalModel:
    """The matrices of the modal equations (see the module docstring)."""

    beam: BeamProperties
    n_modes: int
    stiffening: bool
    a0_per_s: float
    a1_s: float
    tip_mass_kg: float
    integrals: ModalIntegrals
    damping_geometric: bool = True

    @property
    def damping_law(self) -> str:
        """``"paper"`` (a1 K_T, geometric stiffness included) or ``"material"`` (a1 K)."""
        return "paper" if self.damping_geometric else "material"

    @classmethod
    def build(
        cls,
        beam: BeamProperties,
        n_modes: int,
        *,
        stiffening: bool = True,
        a0_per_s: float = 0.0,
        a1_s: float = 0.0,
        tip_mass_kg: float = 0.0,
        damping_geometric: bool = True,
        damping_law: str = "paper",
    ) -> ModalModel:
        """The model; ``damping_law="material"`` or ``damping_geometric=False`` damps with
        the elastic K alone (the material law, see the module docstring)."""
        law = check_choice("damping_law", damping_law, DAMPING_LAWS)
        if isinstance(n_modes, bool) or not isinstance(n_modes, int | np.integer) or n_modes < 1:
            raise SimInputError("n_modes", f"must be a positive integer, got {n_modes!r}")
        integrals = modal_integrals(
            beam.length_m,
            beam.hub_offset_m,
            beam.mass_per_length_kg_m,
            beam.bending_stiffness_n_m2,
            int(n_modes),
            tip_mass_kg=check_non_negative("tip_mass_kg", tip_mass_kg),
        )
        return cls(
            beam,
            int(n_modes),
            bool(stiffening),
            check_non_negative("a0_per_s", a0_per_s),
            check_non_negative("a1_s", a1_s),
            float(tip_mass_kg),
            integrals,
            bool(damping_geometric) and law == "paper",
        )

    @property
    def damping(self) -> FloatArray:
        """The constant part of C: a0 M + a1 K."""
        return self.a0_per_s * self.integrals.mass + self.a1_s * self.integrals.stiffness

    @property
    def rotation_damping(self) -> FloatArray:
        """The coefficient of theta'^2 in C: a1 G (geometric part of K_T), or zero."""
        if self.stiffening and self.damping_geometric:
            return self.a1_s * self.integrals.centrifugal
        return np.zeros_like(self.integrals.mass)

    @property
    def rotation_stiffness(self) -> FloatArray:
        """The coefficient of theta'^2 in the stiffness: G - M (or -M without stiffening)."""
        g = self.integrals.centrifugal if self.stiffening else 0.0
        return g - self.integrals.mass

    def first_order_parts(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        """(A0, A1, f1) with x' = (A0 + theta'^2 A1) x + theta'' f1, x = [q, q']."""
        n = self.n_modes
        minv = np.linalg.inv(self.integrals.mass)
        a0 = np.zeros((2 * n, 2 * n))
        a0[:n, n:] = np.eye(n)
        a0[n:, :n] = -minv @ self.integrals.stiffness
        a0[n:, n:] = -minv @ self.damping
        a1 = np.zeros((2 * n, 2 * n))
        a1[n:, :n] = -minv @ self.rotation_stiffness
        a1[n:, n:] = -minv @ self.rotation_damping
        f1 = np.zeros(2 * n)
        f1[n:] = -minv @ self.integrals.euler
        return a0, a1, f1

    def accelerations(
        self, drive: Drive, t_s: FloatArray, q: FloatArray, qd: FloatArray
    ) -> FloatArray:
        """q'' (N, n) from the equations of motion at states (N, n)."""
        rate = np.asarray(drive.rate(t_s), dtype=float)
        acc = np.asarray(drive.accel(t_s), dtype=float)
        mi = self.integrals
        force = (
            -qd @ self.damping.T
            - (rate**2)[:, None] * (qd @ self.rotation_damping.T)
            - q @ mi.stiffness.T
            - (rate**2)[:, None] * (q @ self.rotation_stiffness.T)
            - acc[:, None] * mi.euler[None, :]
        )
        out: FloatArray = np.asarray(np.linalg.solve(mi.mass, force.T).T, dtype=float)
        return out

    def kinetic_energy_j(
        self, drive: Drive, t_s: FloatArray, q: FloatArray, qd: FloatArray
    ) -> FloatArray:
        """T of beam (and tip mass) to second order in q, J, shape (N,)."""
        rate = np.asarray(drive.rate(t_s), dtype=float)
        mi = self.integrals
        quad_qd = np.einsum("ki,ij,kj->k", qd, mi.mass, qd)
        quad_q = np.einsum("ki,ij,kj->k", q, mi.mass - mi.centrifugal, q)
        return 0.5 * (quad_qd + rate**2 * (quad_q + mi.hub_inertia_kg_m2)) + rate * (qd @ mi.euler)

    def strain_energy_j(self, q: FloatArray) -> FloatArray:
        """Bending strain energy 1/2 q^T K q, J, shape (N,)."""
        return 0.5 * np.einsum("ki,ij,kj->k", q, self.integrals.stiffness, q)

    def hub_torque_n_m(
        self, drive: Drive, t_s: FloatArray, q: FloatArray, qd: FloatArray, qdd: FloatArray
    ) -> FloatArray:
        """Torque the hub must apply to follow the prescribed angle, N m, shape (N,):
        d/dt (dT / d theta')."""
        rate = np.asarray(drive.rate(t_s), dtype=float)
        acc = np.asarray(drive.accel(t_s), dtype=float)
        mi = self.integrals
        jm = mi.mass - mi.centrifugal
        inertia = mi.hub_inertia_kg_m2 + np.einsum("ki,ij,kj->k", q, jm, q)
        return acc * inertia + 2.0 * rate * np.einsum("ki,ij,kj->k", q, jm, qd) + qdd @ mi.euler


def integrate_modal(
    model: ModalModel,
    drive: Drive,
    t_s: FloatArray,
    *,
    rtol: float,
    atol: float,
    initial_q: ArrayLike | None = None,
    initial_qdot: ArrayLike | None = None,
) -> tuple[FloatArray, FloatArray, dict[str, Any]]:
    """Modal coordinates q, q' (N, n) at ``t_s`` (state given at ``t_s[0]``) and solver info."""
    n = model.n_modes
    x0 = np.zeros(2 * n)
    for name, value, sl in (
        ("initial_q", initial_q, slice(0, n)),
        ("initial_qdot", initial_qdot, slice(n, 2 * n)),
    ):
        if value is not None:
            v = np.asarray(value, dtype=float).reshape(-1)
            if v.shape != (n,) or not np.all(np.isfinite(v)):
                raise SimInputError(name, f"must be {n} finite modal amplitudes (m), got {value!r}")
            x0[sl] = v
    check_positive("rtol", rtol)
    check_positive("atol", atol)
    a0, a1, f1 = model.first_order_parts()

    def coefficients(ts: FloatArray) -> tuple[FloatArray, FloatArray]:
        rate = np.asarray(drive.rate(ts), dtype=float)
        acc = np.asarray(drive.accel(ts), dtype=float)
        return a0[None] + (rate**2)[:, None, None] * a1[None], acc[:, None] * f1[None]

    weights = np.concatenate([np.abs(model.integrals.tip_shape), np.zeros(n)])
    # First guess of the step: a fraction of the first mode's period or 20 ms.
    p1 = float(np.sqrt(model.integrals.stiffness[0, 0] / model.integrals.mass[0, 0]))
    h0 = min(0.02, 0.5 / p1) * (max(rtol, 1e-12) / 1e-4) ** 0.2
    states, est, h = solve_ltv(
        coefficients, t_s, x0, error_weights=weights, rtol=rtol, atol=atol, h_initial=h0
    )
    info = {"error_estimate_m": est, "step_s": h, "method": "radau-iia-3 batched, step halving"}
    return states[:, :n], states[:, n:], info


def station_foreshortening_matrices(
    length_m: float, stations_m: FloatArray, n_modes: int
) -> FloatArray:
    """D(s) = int_0^s Phi_i' Phi_j' dx for each station, shape (S, n, n) (1/m); read-only
    (kept for the next simulation of the same beam: a damping fit runs a hundred)."""
    stations = np.ascontiguousarray(stations_m, dtype=float)
    return _foreshortening(float(length_m), stations.tobytes(), stations.shape, int(n_modes))


@functools.lru_cache(maxsize=16)
def _foreshortening(
    length_m: float, stations: bytes, shape: tuple[int, ...], n_modes: int
) -> FloatArray:
    stations_m = np.frombuffer(stations, dtype=float).reshape(shape)
    out = np.zeros((stations_m.size, n_modes, n_modes))
    for k, s in enumerate(stations_m):
        if s <= 0.0:
            continue
        x, w = gauss_points(float(s), n_panels=max(4, n_modes), order=16)
        d = mode_shapes(np.minimum(x, length_m), length_m, n_modes, 1)
        out[k] = (d.T * w) @ d
    out.setflags(write=False)
    return out


def simulate_modal(
    beam: BeamProperties,
    drive: Drive,
    t_eval_s: ArrayLike,
    *,
    n_modes: int = 4,
    stiffening: bool = True,
    a0_per_s: float = 0.0,
    a1_s: float = 0.0,
    gauge_positions_m: Sequence[float] | ArrayLike = (),
    n_stations: int = 21,
    rtol: float = 1e-8,
    atol: float = 1e-12,
    tip_mass_kg: float = 0.0,
    initial_q: ArrayLike | None = None,
    initial_qdot: ArrayLike | None = None,
    damping_geometric: bool = True,
    damping_law: str = "paper",
) -> SimResult:
    """Simulate the beam with ``n_modes`` clamped-free modes on the prescribed hub.

    Parameters
    ----------
    beam : beam properties (hub offset r = ``beam.hub_offset_m``).
    drive : prescribed hub angle theta(t) (only its rate and acceleration load the beam).
    t_eval_s : (N,) output times, s; the initial state is at ``t_eval_s[0]``.
    n_modes : number of assumed modes.
    stiffening : include the centrifugal (geometric) stiffening; ``False`` = seed 001.
    a0_per_s, a1_s : proportional damping C = a0 M + a1 K_d (Eq. 28).
    gauge_positions_m : (G,) gauge distances from the clamp, m.
    n_stations : equally spaced shape stations, clamp and tip included.
    rtol, atol : tolerance on the tip deflection: estimated max error <= atol (m) +
        rtol * max |tip deflection|.
    tip_mass_kg : point mass at the tip.
    initial_q, initial_qdot : (n_modes,) initial modal amplitudes (m) and rates (m/s).
    damping_geometric : ``False`` is the same as ``damping_law="material"``.
    damping_law : ``"paper"`` (default): K_d = K_T includes the geometric stiffness
        theta'^2 G (Eq. 28); ``"material"``: Kelvin-Voigt, K_d = K (module docstring).

    Returns
    -------
    SimResult with model ``"modal"``; strain = theta'^2 N(x)/EA - z w''(x) (the linear part
    of Eq. 50 with the centrifugal axial strain), z = ``beam.surface_offset_m``.
    """
    t, gauges, stations = check_simulation_inputs(
        beam, drive, t_eval_s, gauge_positions_m, n_stations
    )
    model = ModalModel.build(
        beam,
        n_modes,
        stiffening=stiffening,
        a0_per_s=a0_per_s,
        a1_s=a1_s,
        tip_mass_kg=tip_mass_kg,
        damping_geometric=damping_geometric,
        damping_law=damping_law,
    )
    start = time.perf_counter()
    q, _qd, info = integrate_modal(
        model, drive, t, rtol=rtol, atol=atol, initial_q=initial_q, initial_qdot=initial_qdot
    )
    wall = time.perf_counter() - start
    return modal_result(model, drive, t, q, gauges, stations, wall, info, rtol=rtol, atol=atol)


def modal_result(
    model: ModalModel,
    drive: Drive,
    t: FloatArray,
    q: FloatArray,
    gauges: FloatArray,
    stations: FloatArray,
    wall_time_s: float,
    info: dict[str, Any],
    *,
    rtol: float,
    atol: float,
    name: str = "modal",
) -> SimResult:
    """Assemble a :class:`SimResult` from modal coordinates q (N, n)."""
    beam, n = model.beam, model.n_modes
    L = beam.length_m
    phi_st = mode_shapes(stations, L, n)
    d_st = station_foreshortening_matrices(L, stations, n)
    station_lat = q @ phi_st.T
    station_lon = -0.5 * np.einsum("ki,sij,kj->ks", q, d_st, q)
    curvature = q @ mode_shapes(gauges, L, n, 2).T if gauges.size else np.zeros((t.size, 0))
    rate = np.asarray(drive.rate(t), dtype=float)
    r = beam.hub_offset_m
    axial_per_rate2 = beam.mass_per_length_kg_m * (
        (r * L + 0.5 * L * L) - (r * gauges + 0.5 * gauges**2)
    ) + model.tip_mass_kg * (r + L)
    axial = (rate**2)[:, None] * axial_per_rate2[None, :] / beam.axial_stiffness_n
    strain = axial - beam.surface_offset_m * curvature
    settings: dict[str, Any] = {
        "n_modes": n,
        "stiffening": model.stiffening,
        "a0_per_s": model.a0_per_s,
        "a1_s": model.a1_s,
        "tip_mass_kg": model.tip_mass_kg,
        "rtol": rtol,
        "atol": atol,
        "damping_law": model.damping_law,
        "damping_stiffness": (
            "tangent K + theta'^2 G"
            if model.stiffening and model.damping_geometric
            else "elastic K"
        ),
        **info,
    }
    return SimResult(
        time_s=t,
        hub_angle_rad=np.asarray(drive.angle(t), dtype=float).reshape(t.shape),
        tip_lateral_m=station_lat[:, -1].copy(),
        tip_longitudinal_m=station_lon[:, -1].copy(),
        stations_m=stations,
        station_lateral_m=station_lat,
        station_longitudinal_m=station_lon,
        gauge_positions_m=gauges,
        strain=strain,
        model=name,
        wall_time_s=wall_time_s,
        settings=settings,
    )
