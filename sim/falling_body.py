"""Seed 001's worked problem: a cantilever B clamped in a rigid body RB that falls under
gravity in a vertical plane (Kane's equations, Eqs. 8.10-8.36).

Generalised coordinates: q1, q2 (the position of RB's mass centre CR in the fixed frame,
horizontal and vertical), q3 (RB's angle), q_{3+i} (modal amplitudes of B, clamped-free
shapes of ``sim.modes``, m). Generalised speeds u1, u2 (CR's velocity in RB's axes), u3
(RB's angular velocity), u_{3+i} = q'_{3+i} (Eqs. 8.10-8.16). A point of B at x from the
clamp Q (at b from CR along RB's x axis) moves with

    v_P = (u1 - u3 y) i + (u2 + (b + x) u3 + y') j,  y = sum Phi_i q_{3+i}     (8.18)

The generalised inertia forces (8.22-8.23) are formed from these partial velocities by
Gauss quadrature along B (so every coupling term of (8.23) is included, none hand-copied);
internal forces are -H q (8.31-8.32), gravity per (8.33-8.34). As in the chapter, the beam
has no foreshortening (no geometric stiffening): fine for a free body, whose spin is slow
against the beam's frequencies. The model conserves linear momentum up to gravity, angular
momentum about the system mass centre and energy exactly, which the tests check.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.integrate import solve_ivp

from sim.beam import BeamProperties
from sim.errors import IntegrationError, SimInputError
from sim.modes import gauss_points, modal_integrals, mode_shapes

FloatArray = NDArray[np.float64]

STANDARD_GRAVITY_M_S2 = 9.80665


@dataclass(frozen=True)
class FallingBody:
    """RB (mass, central moment of inertia, CR-to-clamp distance b) carrying the cantilever.

    Defaults (seed 001 gives no numbers): a 1 kg body with 0.01 kg m^2, b = 0.05 m.
    """

    beam: BeamProperties
    body_mass_kg: float = 1.0
    body_inertia_kg_m2: float = 0.01
    clamp_offset_m: float = 0.05
    n_modes: int = 2
    gravity_m_s2: float = STANDARD_GRAVITY_M_S2

    def __post_init__(self) -> None:
        for name in ("body_mass_kg", "body_inertia_kg_m2"):
            v = getattr(self, name)
            if not math.isfinite(v) or v <= 0.0:
                raise SimInputError(name, f"must be a positive finite number, got {v!r}")
        for name in ("clamp_offset_m", "gravity_m_s2"):
            v = getattr(self, name)
            if not math.isfinite(v) or v < 0.0:
                raise SimInputError(name, f"must be a non-negative finite number, got {v!r}")
        if isinstance(self.n_modes, bool) or not isinstance(self.n_modes, int) or self.n_modes < 1:
            raise SimInputError("n_modes", f"must be a positive integer, got {self.n_modes!r}")

    # -- quadrature data ----------------------------------------------------------------------
    def _quadrature(self) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        L = self.beam.length_m
        x, w = gauss_points(L, n_panels=max(8, 2 * self.n_modes), order=16)
        phi = mode_shapes(x, L, self.n_modes)
        k = modal_integrals(
            L, 0.0, self.beam.mass_per_length_kg_m, self.beam.bending_stiffness_n_m2, self.n_modes
        ).stiffness
        return x, w * self.beam.mass_per_length_kg_m, phi, k

    @property
    def total_mass_kg(self) -> float:
        return self.body_mass_kg + self.beam.mass_kg

    def _partials(self, x: FloatArray, phi: FloatArray, y: FloatArray) -> FloatArray:
        """Partial velocities of the beam points in RB axes, shape (P, 2, 3 + n)."""
        n = self.n_modes
        j = np.zeros((x.size, 2, 3 + n))
        j[:, 0, 0] = 1.0
        j[:, 0, 2] = -y
        j[:, 1, 1] = 1.0
        j[:, 1, 2] = self.clamp_offset_m + x
        j[:, 1, 3:] = phi
        return j

    def rhs(
        self, state: FloatArray, quad: tuple[FloatArray, FloatArray, FloatArray, FloatArray]
    ) -> FloatArray:
        """d/dt of [q1, q2, q3, eta (n), u1, u2, u3, eta' (n)]."""
        x, wm, phi, k = quad
        n = self.n_modes
        q3 = state[2]
        eta = state[3 : 3 + n]
        u = state[3 + n :]
        u1, u2, u3 = u[0], u[1], u[2]
        y = phi @ eta
        yd = phi @ u[3:]
        jac = self._partials(x, phi, y)
        mass = np.einsum("p,pai,paj->ij", wm, jac, jac)
        mass[0, 0] += self.body_mass_kg
        mass[1, 1] += self.body_mass_kg
        mass[2, 2] += self.body_inertia_kg_m2
        # Acceleration terms that do not multiply u' (from 8.21).
        rem = np.stack(
            [-u2 * u3 - (self.clamp_offset_m + x) * u3 * u3 - 2.0 * u3 * yd, u3 * u1 - u3 * u3 * y],
            axis=1,
        )
        g_body = -self.gravity_m_s2 * np.array([math.sin(q3), math.cos(q3)])
        force = np.einsum("p,pai,a->i", wm, jac, g_body) - np.einsum("p,pai,pa->i", wm, jac, rem)
        force[:2] += self.body_mass_kg * (g_body - np.array([-u2 * u3, u3 * u1]))
        force[3:] -= k @ eta
        ud = np.linalg.solve(mass, force)
        c3, s3 = math.cos(q3), math.sin(q3)
        qd = np.concatenate([[u1 * c3 - u2 * s3, u1 * s3 + u2 * c3, u3], u[3:]])
        return np.concatenate([qd, ud])

    def simulate(
        self,
        t_eval_s: ArrayLike,
        initial_state: ArrayLike,
        *,
        rtol: float = 1e-10,
        atol: float = 1e-12,
    ) -> FallingBodyRun:
        """Integrate (DOP853) from ``initial_state`` at ``t_eval_s[0]``.

        Parameters
        ----------
        t_eval_s : (N,) output times, s.
        initial_state : (6 + 2 n,) [q1, q2 (m), q3 (rad), eta (m), u1, u2 (m/s), u3 (rad/s),
            eta' (m/s)].
        """
        t = np.asarray(t_eval_s, dtype=float)
        x0 = np.asarray(initial_state, dtype=float).reshape(-1)
        if x0.shape != (6 + 2 * self.n_modes,) or not np.all(np.isfinite(x0)):
            raise SimInputError("initial_state", f"must be {6 + 2 * self.n_modes} finite numbers")
        if t.ndim != 1 or t.size < 2 or np.any(np.diff(t) <= 0.0):
            raise SimInputError("t_eval_s", "must be a strictly increasing 1-D array of >= 2 times")
        quad = self._quadrature()
        start = time.perf_counter()
        sol = solve_ivp(
            lambda _t, s: self.rhs(s, quad),
            (float(t[0]), float(t[-1])),
            x0,
            method="DOP853",
            t_eval=t,
            rtol=rtol,
            atol=atol,
        )
        wall = time.perf_counter() - start
        if not sol.success:
            t_fail = float(sol.t[-1]) if sol.t.size else float(t[0])
            raise IntegrationError("DOP853", t_fail, f"falling body: {sol.message}")
        return FallingBodyRun(self, t, sol.y.T.copy(), wall)


@dataclass(frozen=True)
class FallingBodyRun:
    """States (N, 6 + 2n) of a falling-body run and the conserved quantities."""

    system: FallingBody
    time_s: FloatArray
    states: FloatArray
    wall_time_s: float

    def _points(self) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
        """Per time: inertial positions (N, P, 2) and velocities of beam points, CR position
        and velocity (N, 2), beam point masses (P,)."""
        sys_ = self.system
        x, wm, phi, _ = sys_._quadrature()
        n = sys_.n_modes
        s = self.states
        q3 = s[:, 2]
        eta, u = s[:, 3 : 3 + n], s[:, 3 + n :]
        y = eta @ phi.T
        yd = u[:, 3:] @ phi.T
        c, sn = np.cos(q3)[:, None], np.sin(q3)[:, None]
        bx = sys_.clamp_offset_m + x[None, :]
        rx, ry = bx, y
        vx = u[:, 0:1] - u[:, 2:3] * y
        vy = u[:, 1:2] + bx * u[:, 2:3] + yd
        pos = np.stack([s[:, 0:1] + c * rx - sn * ry, s[:, 1:2] + sn * rx + c * ry], axis=-1)
        vel = np.stack([c * vx - sn * vy, sn * vx + c * vy], axis=-1)
        cr = s[:, 0:2]
        vcr = np.stack(
            [u[:, 0] * c[:, 0] - u[:, 1] * sn[:, 0], u[:, 0] * sn[:, 0] + u[:, 1] * c[:, 0]],
            axis=-1,
        )
        return pos, vel, cr, vcr, wm

    def mass_centre_m(self) -> FloatArray:
        pos, _, cr, _, wm = self._points()
        mr = self.system.body_mass_kg
        return (mr * cr + np.einsum("p,npa->na", wm, pos)) / self.system.total_mass_kg

    def linear_momentum_kg_m_s(self) -> FloatArray:
        _, vel, _, vcr, wm = self._points()
        return self.system.body_mass_kg * vcr + np.einsum("p,npa->na", wm, vel)

    def angular_momentum_kg_m2_s(self) -> FloatArray:
        """About the system mass centre, (N,)."""
        pos, vel, cr, vcr, wm = self._points()
        c = self.mass_centre_m()
        mr = self.system.body_mass_kg
        n = self.system.n_modes
        u3 = self.states[:, 5 + n]
        d_cr = cr - c
        h = self.system.body_inertia_kg_m2 * u3 + mr * (
            d_cr[:, 0] * vcr[:, 1] - d_cr[:, 1] * vcr[:, 0]
        )
        d = pos - c[:, None, :]
        return h + np.einsum("p,np->n", wm, d[..., 0] * vel[..., 1] - d[..., 1] * vel[..., 0])

    def energy_j(self) -> FloatArray:
        """Kinetic + elastic + gravitational energy, (N,)."""
        _, vel, _, vcr, wm = self._points()
        sys_ = self.system
        n = sys_.n_modes
        _, _, _, k = sys_._quadrature()
        u3 = self.states[:, 5 + n]
        eta = self.states[:, 3 : 3 + n]
        kinetic = (
            0.5 * sys_.body_mass_kg * np.sum(vcr**2, axis=1) + 0.5 * sys_.body_inertia_kg_m2 * u3**2
        )
        kinetic = kinetic + 0.5 * np.einsum("p,npa->n", wm, vel**2)
        elastic = 0.5 * np.einsum("ni,ij,nj->n", eta, k, eta)
        grav = sys_.total_mass_kg * sys_.gravity_m_s2 * self.mass_centre_m()[:, 1]
        return kinetic + elastic + grav

    def modal_amplitudes_m(self) -> FloatArray:
        n = self.system.n_modes
        return self.states[:, 3 : 3 + n]
