"""Assumed modes with the geometric nonlinearity of an inextensible beam, to third order.

The linear modal model (``sim.models.modal``) keeps the Lagrangian to second order in the modal
amplitudes q; its error against a geometrically exact beam grows like (deflection / L)^2
(0.43 % on the bench's tip at the paper's drive, 0.11 % at half the stroke). This model keeps
the Lagrangian to fourth order, so the equations are exact to third order in q.

A point at arc length s from the clamp sits at (r + s + u, w) in the hub frame with
w = sum Phi_i q_i and the inextensibility u = int_0^s (sqrt(1 - w'^2) - 1) = u2 + u4,
u2 = -1/2 int w'^2, u4 = -1/8 int w'^4; the curvature is w'' / sqrt(1 - w'^2), so
V = 1/2 int EI w''^2 (1 + w'^2). With R = r + s, the kinetic energy
T = 1/2 int rhoA [(u' - theta' w)^2 + (w' + theta' (R + u))^2] adds to the linear model's

- T3 = theta' int rhoA (w_t u2 - w u2_t): Coriolis coupling through the foreshortening and
  its Euler counterpart; gives rhoA [theta'' (Phi u2 + w D q) + 2 theta' (Phi u2_t + w_t D q)];
- T4 = int rhoA [u2_t^2 / 2 + theta'^2 (u2^2 / 2 + R u4)]: axial inertia of the
  foreshortening, and the centrifugal force on the pulled-in and the quartic stretch terms;
- V4 = 1/2 int EI w''^2 w'^2: the exact curvature's cubic stiffening,

where D(s) = int_0^s Phi' Phi'^T (so u2 = -q^T D q / 2). They are assembled from tensors
(A_ijk = int rhoA Phi_i D_jk, F_abcd = int rhoA D_ab D_cd, H = int N Phi'^4, S = sym int EI
Phi''^2 Phi'^2). Damping per Eq. 28 with the tangent stiffness (``damping_law="paper"``)
also includes the tangent of V4 and the geometric stiffness of the first-order axial force;
the Kelvin-Voigt law (``"material"``) is the gradient of the dissipation
1/2 a1 int EI kappa_t^2 of the exact curvature instead.

The nonlinear terms are small, so the solution is a fixed-point iteration on the whole
trajectory: each pass is one batched Radau IIA solve (``sim.solvers.linear_radau``) of the
linear model with the nonlinear force of the previous pass, at the stage times, as forcing; the
step grid is the one the linear model's error control accepted.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sim.beam import BeamProperties
from sim.checks import check_simulation_inputs
from sim.drives import Drive
from sim.errors import SolverError
from sim.models.modal import ModalModel, modal_result
from sim.modes import gauss_points, mode_shapes
from sim.result import SimResult
from sim.solvers.linear_radau import radau_grid, solve_ltv
from sim.solvers.radau_iia import C

FloatArray = NDArray[np.float64]


def _cumulative_slope_matrices(length_m: float, x: FloatArray, n: int) -> FloatArray:
    """D(x_k) = int_0^x_k Phi' Phi'^T for each point, (P, n, n)."""
    out = np.zeros((x.size, n, n))
    for k, s in enumerate(x):
        if s <= 0.0:
            continue
        xs, ws = gauss_points(float(s), n_panels=max(2, int(np.ceil(8 * s / length_m))), order=16)
        d = mode_shapes(np.minimum(xs, length_m), length_m, n, 1)
        out[k] = (d.T * ws) @ d
    return out


def _symmetrise4(t: FloatArray) -> FloatArray:
    perms = list(itertools.permutations(range(4)))
    out = np.zeros_like(t)
    for p in perms:
        out += np.transpose(t, p)
    return out / len(perms)


def _quad(t3: FloatArray, x: FloatArray, y: FloatArray) -> FloatArray:
    """einsum("ijk,nj,nk->ni") as one matrix product."""
    n = t3.shape[0]
    outer = (x[:, :, None] * y[:, None, :]).reshape(x.shape[0], n * n)
    out: FloatArray = outer @ t3.reshape(n, n * n).T
    return out


def _cubic(t4: FloatArray, x: FloatArray, y: FloatArray, z: FloatArray) -> FloatArray:
    """einsum("ijkl,nj,nk,nl->ni") as one matrix product."""
    n = t4.shape[0]
    outer = (x[:, :, None, None] * y[:, None, :, None] * z[:, None, None, :]).reshape(
        x.shape[0], n**3
    )
    out: FloatArray = outer @ t4.reshape(n, n**3).T
    return out


@dataclass(frozen=True)
class NonlinearModalTerms:
    """Tensors of the third-order terms (see the module docstring)."""

    a: FloatArray  # (n, n, n)
    f: FloatArray  # (n, n, n, n)
    h: FloatArray  # (n, n, n, n), symmetric
    s: FloatArray  # (n, n, n, n), symmetric
    a1_s: float
    #: third-order damping a1 d(i, j, k, l) qd_j q_k q_l: the tangent of V4 (paper law) or
    #: the gradient of the Kelvin-Voigt dissipation of the exact curvature (material law)
    d: FloatArray  # (n, n, n, n)
    damping_law: str = "paper"

    @classmethod
    def build(cls, model: ModalModel) -> NonlinearModalTerms:
        beam, n = model.beam, model.n_modes
        L, r, rho = beam.length_m, beam.hub_offset_m, beam.mass_per_length_kg_m
        x, w = gauss_points(L, n_panels=max(8, 2 * n), order=16)
        phi = mode_shapes(x, L, n)
        dphi = mode_shapes(x, L, n, 1)
        ddphi = mode_shapes(x, L, n, 2)
        d = _cumulative_slope_matrices(L, x, n)
        mu = rho * w
        if model.tip_mass_kg > 0.0:
            phi = np.vstack([phi, mode_shapes([L], L, n)])
            d = np.concatenate([d, _cumulative_slope_matrices(L, np.array([L]), n)])
            mu = np.append(mu, model.tip_mass_kg)
        a = np.einsum("p,pi,pjk->ijk", mu, phi, d)
        f = np.einsum("p,pab,pcd->abcd", mu, d, d)
        axial = rho * ((r * L + 0.5 * L * L) - (r * x + 0.5 * x * x)) + model.tip_mass_kg * (r + L)
        h = np.einsum("p,pa,pb,pc,pd->abcd", w * axial, dphi, dphi, dphi, dphi)
        p4 = np.einsum(
            "p,pa,pb,pc,pd->abcd", w * beam.bending_stiffness_n_m2, ddphi, ddphi, dphi, dphi
        )
        s = _symmetrise4(p4)
        if model.damping_law == "paper":
            d = 6.0 * s
        else:
            # dissipation 1/2 a1 int EI kappa_t^2, kappa = w'' (1 + w'^2 / 2): the force
            # a1 int EI kappa_t dkappa/dq to third order is
            # a1 int EI (w_t'' w'^2 Phi_i'' + w_t'' w'' w' Phi_i' + w'' w' w_t' Phi_i'')
            d = p4 + np.einsum("jkil->ijkl", p4) + np.einsum("iklj->ijkl", p4)
        return cls(a, f, h, s, model.a1_s, d, model.damping_law)

    def force(
        self,
        q: FloatArray,
        qd: FloatArray,
        qdd: FloatArray,
        rate: FloatArray,
        acc: FloatArray,
    ) -> FloatArray:
        """Nonlinear generalised force on the left-hand side of the equations, (N, n)."""
        a, f, h, s = self.a, self.f, self.h, self.s
        f_i = np.transpose(f, (2, 0, 1, 3))  # f_i[i, j, k, l] = f[j, k, i, l]
        a_t = np.transpose(a, (1, 0, 2))  # a_t[i, j, k] = a[j, i, k]
        e3 = acc[:, None] * (-0.5 * _quad(a, q, q) + _quad(a_t, q, q)) + 2.0 * rate[:, None] * (
            -_quad(a, q, qd) + _quad(a_t, qd, q)
        )
        e4a = _cubic(f_i, qd, qd, q) + _cubic(f_i, q, qdd, q)
        e4b = -0.5 * (rate**2)[:, None] * _cubic(f_i, q, q, q)
        e4c = 0.5 * (rate**2)[:, None] * _cubic(h, q, q, q)
        ev4 = 2.0 * _cubic(s, q, q, q)
        damp = self.a1_s * _cubic(self.d, qd, q, q)
        if self.damping_law == "paper":
            # a1 K_sigma(N1) q': the geometric stiffness of the first-order axial force
            # N1(s) = int_s^L rhoA (2 theta' w_t + theta'' w) in the tangent stiffness of
            # Eq. 28 (the material law has no axial force in its damping)
            a_k = np.transpose(a, (1, 0, 2))  # a_k[i, k, j] = a[k, i, j]
            damp = damp + self.a1_s * (
                2.0 * rate[:, None] * _quad(a_k, qd, qd) + acc[:, None] * _quad(a_k, q, qd)
            )
        out: FloatArray = e3 + e4a + e4b + e4c + ev4 + damp
        return out

    def energy_parts(
        self, q: FloatArray, qd: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """Fourth-order additions to T_a, T_b, T_c (T = T_a + theta' T_b + theta'^2 T_c) and
        to V, each (N,)."""
        a, f, h, s = self.a, self.f, self.h, self.s
        ta = 0.5 * np.einsum("abcd,na,nb,nc,nd->n", f, q, qd, q, qd)
        tb = -0.5 * np.einsum("ijk,ni,nj,nk->n", a, qd, q, q) + np.einsum(
            "ijk,ni,nj,nk->n", a, q, q, qd
        )
        q4f = np.einsum("abcd,na,nb,nc,nd->n", f, q, q, q, q)
        q4h = np.einsum("abcd,na,nb,nc,nd->n", h, q, q, q, q)
        tc = 0.125 * (q4f - q4h)
        v = 0.5 * np.einsum("abcd,na,nb,nc,nd->n", s, q, q, q, q)
        return ta, tb, tc, v


def _eom_qdd(
    model: ModalModel,
    q: FloatArray,
    qd: FloatArray,
    rate: FloatArray,
    acc: FloatArray,
    extra: FloatArray,
) -> FloatArray:
    mi = model.integrals
    force = (
        -qd @ model.damping.T
        - (rate**2)[:, None] * (qd @ model.rotation_damping.T)
        - q @ mi.stiffness.T
        - (rate**2)[:, None] * (q @ model.rotation_stiffness.T)
        - acc[:, None] * mi.euler[None, :]
        - extra
    )
    out: FloatArray = np.asarray(np.linalg.solve(mi.mass, force.T).T, dtype=float)
    return out


def integrate_modal_nonlinear(
    model: ModalModel,
    terms: NonlinearModalTerms,
    drive: Drive,
    t_s: FloatArray,
    *,
    rtol: float,
    atol: float,
    initial_q: ArrayLike | None = None,
    initial_qdot: ArrayLike | None = None,
    max_iterations: int = 30,
) -> tuple[FloatArray, FloatArray, dict[str, Any]]:
    """q, q' (N, n) at ``t_s`` and solver information."""
    n = model.n_modes
    x0 = np.zeros(2 * n)
    if initial_q is not None:
        x0[:n] = np.asarray(initial_q, dtype=float).reshape(n)
    if initial_qdot is not None:
        x0[n:] = np.asarray(initial_qdot, dtype=float).reshape(n)
    a0m, a1m, f1 = model.first_order_parts()

    def coefficients(ts: FloatArray) -> tuple[FloatArray, FloatArray]:
        rate = np.asarray(drive.rate(ts), dtype=float)
        acc = np.asarray(drive.accel(ts), dtype=float)
        return a0m[None] + (rate**2)[:, None, None] * a1m[None], acc[:, None] * f1[None]

    weights = np.concatenate([np.abs(model.integrals.tip_shape), np.zeros(n)])
    p1 = float(np.sqrt(model.integrals.stiffness[0, 0] / model.integrals.mass[0, 0]))
    h0 = min(0.02, 0.5 / p1) * (max(rtol, 1e-12) / 1e-4) ** 0.2
    grid_info: list[Any] = []
    _, est, h = solve_ltv(
        coefficients,
        t_s,
        x0,
        error_weights=weights,
        rtol=rtol,
        atol=atol,
        h_initial=h0,
        grid_out=grid_info,
    )
    grid, out_index = grid_info
    n_steps = grid.size - 1
    stage_t = (grid[:-1, None] + np.diff(grid)[:, None] * C[None, :]).ravel()
    rate = np.asarray(drive.rate(stage_t), dtype=float)
    acc = np.asarray(drive.accel(stage_t), dtype=float)
    minv = np.linalg.inv(model.integrals.mass)
    stages = np.empty((n_steps, 3, 2 * n))
    extra = np.zeros((n_steps, 3, 2 * n))
    cache: dict[int, Any] = {}
    states = radau_grid(coefficients, grid, x0, None, stages, cache)
    e_nl = np.zeros((stage_t.size, n))
    tol = atol + rtol * float(np.max(np.abs(states @ weights)))
    change = np.inf
    iterations = 0
    for iterations in range(1, max_iterations + 1):  # noqa: B007
        y = stages.reshape(-1, 2 * n)
        q, qd = y[:, :n], y[:, n:]
        qdd = _eom_qdd(model, q, qd, rate, acc, e_nl)
        e_nl = terms.force(q, qd, qdd, rate, acc)
        extra[:, :, n:] = -(e_nl @ minv.T).reshape(n_steps, 3, n)
        new_states = radau_grid(coefficients, grid, x0, extra, stages, cache)
        change = float(np.max(np.abs((new_states - states) @ weights)))
        states = new_states
        if change <= 0.1 * tol:
            break
    else:
        raise SolverError(
            "nonlinear modal iteration",
            f"no convergence in {max_iterations} passes (last change {change:.3g} m); "
            "the deflection is too large for this model",
        )
    out = states[out_index]
    info = {
        "error_estimate_m": est + change,
        "step_s": h,
        "iterations": iterations,
        "method": "radau-iia-3 batched, step halving, fixed-point on the nonlinear terms",
    }
    return out[:, :n], out[:, n:], info


def simulate_modal_nonlinear(
    beam: BeamProperties,
    drive: Drive,
    t_eval_s: ArrayLike,
    *,
    n_modes: int = 4,
    a0_per_s: float = 0.0,
    a1_s: float = 0.0,
    gauge_positions_m: Sequence[float] | ArrayLike = (),
    n_stations: int = 21,
    rtol: float = 1e-8,
    atol: float = 1e-12,
    tip_mass_kg: float = 0.0,
    initial_q: ArrayLike | None = None,
    initial_qdot: ArrayLike | None = None,
    damping_law: str = "paper",
) -> SimResult:
    """Like :func:`sim.models.modal.simulate_modal` (always with stiffening), with the geometric
    nonlinearity to third order; ``model="modal-nonlinear"``. Station longitudinal
    deflections include the quartic foreshortening -1/8 int w'^4. ``damping_law``:
    ``"paper"`` (a1 times the tangent stiffness, its geometric part and the tangent of V4
    included) or ``"material"`` (a1 times the strain rates of the exact curvature)."""
    t, gauges, stations = check_simulation_inputs(
        beam, drive, t_eval_s, gauge_positions_m, n_stations
    )
    model = ModalModel.build(
        beam,
        n_modes,
        a0_per_s=a0_per_s,
        a1_s=a1_s,
        tip_mass_kg=tip_mass_kg,
        damping_law=damping_law,
    )
    terms = NonlinearModalTerms.build(model)
    start = time.perf_counter()
    q, _qd, info = integrate_modal_nonlinear(
        model, terms, drive, t, rtol=rtol, atol=atol, initial_q=initial_q, initial_qdot=initial_qdot
    )
    wall = time.perf_counter() - start
    res = modal_result(
        model,
        drive,
        t,
        q,
        gauges,
        stations,
        wall,
        info,
        rtol=rtol,
        atol=atol,
        name="modal-nonlinear",
    )
    # -1/8 int_0^s w'^4 at the stations: Gauss points per station interval, summed up
    g, gw = np.polynomial.legendre.leggauss(8)
    half = 0.5 * np.diff(stations)
    xs = (stations[:-1, None] + half[:, None] * (g[None, :] + 1.0)).ravel()
    ws = (half[:, None] * gw[None, :]).ravel()
    wp = q @ mode_shapes(xs, beam.length_m, n_modes, 1).T
    per_interval = ((wp**4) * ws).reshape(t.size, stations.size - 1, g.size).sum(axis=2)
    quartic = np.concatenate(
        [np.zeros((t.size, 1)), -0.125 * np.cumsum(per_interval, axis=1)], axis=1
    )
    lon = res.station_longitudinal_m + quartic
    return SimResult(
        **{
            **res.__dict__,
            "station_longitudinal_m": lon,
            "tip_longitudinal_m": lon[:, -1].copy(),
        }
    )
