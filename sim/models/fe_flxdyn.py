"""FLXDYN's planar beam element (paper §3, Eqs. 29-33), with chained element frames.

Each element i carries three coordinates ``(Delta4, Delta5, Delta6) = (a_i, b_i, c_i)``:
elongation, lateral deflection and rotation of its outboard end, in a frame attached to
its inboard end; that frame is rotated by the sum of the inboard elements' end rotations
(``beta_i = c_1 + ... + c_{i-1}``) and sits at the inboard element's tip. Within an
element the deformation is interpolated by Eq. 29 (``u = x/L a``) and Eq. 30 (cubic
Hermite for ``w``). Kinematics, inertia (consistent mass, Kane's generalized inertia forces
with the hub's centrifugal, Coriolis and Euler terms) are exact for these coordinates; the
element's internal force is Eq. 21 with the local stiffness of Eqs. 31-33.

The printed matrices are "right halves" (columns 4-6). Built out to 6x6 by symmetry and
the rigid-body modes (:func:`element_stiffness_6x6`): Eq. 31 is the textbook elastic
stiffness and checks out (symmetric, three rigid-body modes in its null space). In Eq. 32
the bending part is the textbook geometric stiffness P/L [6/5, L/10, 2L^2/15, -L^2/30]; the
axial entries ``+-3/L`` are the *tangent* of the axial energy with the quadratic strain term
1/2 u'^2 of Eq. 50 (the secant would be 3/(2L)). Both are kept as printed (the axial strain
here is ~1e-7, so the factor is immaterial). No sign error was found in Eqs. 31-32 once
the right halves are completed with the symmetric left halves; the one consequence worth
knowing is that ``f = (K_e + K_sigma(P)) Delta`` with ``P = EA/L Delta4`` is not the gradient
of an energy (the axial force has no ``1/2 int w'^2`` membrane term), so the element is not
exactly conservative: energy balance holds only to O(P w'^2 / EA), and the elongation of a
bent element's centre line is not resisted within the element (small element rotations
are assumed, as the paper says under Eq. 50; refinement removes it).

Physics worth knowing on the bench: P is the *elastic* elongation's force. With the paper's
a1 = 0.1 s the axial coordinate is a Kelvin-Voigt element with time constant a1, so the
tension that stiffens each element lags the centrifugal load (whose main frequency,
2 x 4.97 rad/s, is 1/a1): FLXDYN's stiffening is weaker and late. The exact formulation
stiffens with the total axial force. That shifts the reciprocating tip by about 1.3 %;
``FlxdynSystem(..., viscous_tension=True)`` adds the viscous part to P and the two then
agree to the element's O(h^2) discretisation error.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from sim.beam import BeamProperties

FloatArray = NDArray[np.float64]

N_GAUSS = 4
_J2 = np.array([[0.0, -1.0], [1.0, 0.0]])


def element_stiffness_6x6(ea: float, ei: float, le: float, p: float) -> FloatArray:
    """Full 6x6 ``K_e + K_sigma(P)`` of the element (dofs u1 w1 th1 u2 w2 th2), whose
    columns 4-6 are the printed Eqs. 31 and 32."""
    ke = np.array(
        [
            [ea / le, 0, 0, -ea / le, 0, 0],
            [0, 12 * ei / le**3, 6 * ei / le**2, 0, -12 * ei / le**3, 6 * ei / le**2],
            [0, 6 * ei / le**2, 4 * ei / le, 0, -6 * ei / le**2, 2 * ei / le],
            [-ea / le, 0, 0, ea / le, 0, 0],
            [0, -12 * ei / le**3, -6 * ei / le**2, 0, 12 * ei / le**3, -6 * ei / le**2],
            [0, 6 * ei / le**2, 2 * ei / le, 0, -6 * ei / le**2, 4 * ei / le],
        ]
    )
    kg = p * np.array(
        [
            [3 / le, 0, 0, -3 / le, 0, 0],
            [0, 6 / (5 * le), 1 / 10, 0, -6 / (5 * le), 1 / 10],
            [0, 1 / 10, 2 * le / 15, 0, -1 / 10, -le / 30],
            [-3 / le, 0, 0, 3 / le, 0, 0],
            [0, -6 / (5 * le), -1 / 10, 0, 6 / (5 * le), -1 / 10],
            [0, 1 / 10, -le / 30, 0, -1 / 10, 2 * le / 15],
        ]
    )
    return ke + kg


def _shape(xi: FloatArray, le: float) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Eq. 30 lateral shape functions (N5, N6), their x-derivatives and second derivatives."""
    n5 = 3 * xi**2 - 2 * xi**3
    n6 = le * (xi**3 - xi**2)
    d5 = (6 * xi - 6 * xi**2) / le
    d6 = 3 * xi**2 - 2 * xi
    dd5 = 6 / le**2 - 12 * xi / le**2  # Eq. 52
    dd6 = 6 * xi / le - 2 / le
    return np.stack([n5, n6]), np.stack([d5, d6]), np.stack([dd5, dd6]), xi


def _rot(beta: FloatArray) -> FloatArray:
    c, s = np.cos(beta), np.sin(beta)
    return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)


class FlxdynBeam:
    """Kinematics, inertia and internal forces of ``n_elements`` FLXDYN elements."""

    def __init__(self, beam: BeamProperties, n_elements: int) -> None:
        self.beam = beam
        self.ne = n_elements
        self.n_q = 3 * n_elements
        self.le = beam.length_m / n_elements
        le, rho_a = self.le, beam.mass_per_length_kg_m
        ea, ei = beam.axial_stiffness_n, beam.bending_stiffness_n_m2
        self.ea, self.ei = ea, ei
        xg, wg = np.polynomial.legendre.leggauss(N_GAUSS)
        xi = 0.5 * (xg + 1.0)
        # quadrature points of all elements
        self.q_el = np.repeat(np.arange(n_elements), N_GAUSS)
        self.q_xi = np.tile(xi, n_elements)
        self.q_w = np.tile(0.5 * wg * le * rho_a, n_elements)
        # element mass (3x3, coordinates a, b, c with the inboard end held)
        self.m_el = (
            rho_a
            * le
            * np.array(
                [
                    [1 / 3, 0, 0],
                    [0, 156 / 420, -22 * le / 420],
                    [0, -22 * le / 420, 4 * le**2 / 420],
                ]
            )
        )

    # -- internal forces ------------------------------------------------------------------
    def k_total(self, q: FloatArray) -> FloatArray:
        """Per-element ``K_T = K_e + K_sigma(P)`` on (a, b, c): (ne, 3, 3)."""
        le, ea, ei = self.le, self.ea, self.ei
        p = ea / le * q[0::3]
        k = np.zeros((self.ne, 3, 3))
        k[:, 0, 0] = ea / le + 3 * p / le
        k[:, 1, 1] = 12 * ei / le**3 + 6 * p / (5 * le)
        k[:, 1, 2] = k[:, 2, 1] = -6 * ei / le**2 - p / 10
        k[:, 2, 2] = 4 * ei / le + 2 * p * le / 15
        return k

    def internal_force(self, q: FloatArray) -> FloatArray:
        """Eq. 21: ``(K_e + K_sigma(P)) Delta`` per element, (n_q,)."""
        k = self.k_total(q)
        return np.einsum("eij,ej->ei", k, q.reshape(self.ne, 3)).ravel()

    def internal_tangent(self, q: FloatArray) -> FloatArray:
        """Derivative of :meth:`internal_force` (block diagonal, not symmetric)."""
        k = self.k_total(q)
        d = q.reshape(self.ne, 3)
        le, ea = self.le, self.ea
        dp = ea / le  # dP/da
        kt = k.copy()
        kt[:, 0, 0] += dp * 3 / le * d[:, 0]
        kt[:, 1, 0] += dp * (6 / (5 * le) * d[:, 1] - d[:, 2] / 10)
        kt[:, 2, 0] += dp * (-d[:, 1] / 10 + 2 * le / 15 * d[:, 2])
        out = np.zeros((self.n_q, self.n_q))
        for e in range(self.ne):
            out[3 * e : 3 * e + 3, 3 * e : 3 * e + 3] = kt[e]
        return out

    def block(self, blocks: FloatArray) -> FloatArray:
        out = np.zeros((self.n_q, self.n_q))
        for e in range(self.ne):
            out[3 * e : 3 * e + 3, 3 * e : 3 * e + 3] = blocks[e]
        return out

    # -- kinematics -----------------------------------------------------------------------
    def kinematics(
        self, q: FloatArray, qd: FloatArray, el: NDArray[np.intp], xi: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """Hub-frame position p (P, 2), Jacobian dp/dq (P, 2, n_q), velocity (P, 2) and the
        velocity-product acceleration ``(dJ/dt) qdot`` (P, 2) at points (element, xi)."""
        ne, le = self.ne, self.le
        qq = q.reshape(ne, 3)
        qv = qd.reshape(ne, 3)
        beta = np.concatenate([[0.0], np.cumsum(qq[:, 2])[:-1]])
        betad = np.concatenate([[0.0], np.cumsum(qv[:, 2])[:-1]])
        rot = _rot(beta)  # (ne, 2, 2)
        chord = np.stack([le + qq[:, 0], qq[:, 1]], -1)  # (ne, 2)
        chord_g = np.einsum("eij,ej->ei", rot, chord)
        nodes = np.concatenate([[[self.beam.hub_offset_m, 0.0]], chord_g], 0).cumsum(0)
        chord_rate = np.einsum("eij,ej->ei", rot, qv[:, :2])  # R_j (a_dot, b_dot)
        # nodal velocities: O_{j+1}dot = O_j dot + R_j (ad, bd) + betad_j J R_j chord_j
        node_v = np.concatenate(
            [[[0.0, 0.0]], chord_rate + betad[:, None] * (chord_g @ _J2.T)], 0
        ).cumsum(0)
        nsh, _, _, _ = _shape(xi, le)
        loc = np.stack([xi * (le + qq[el, 0]), nsh[0] * qq[el, 1] + nsh[1] * qq[el, 2]], -1)
        loc_d = np.stack([xi * qv[el, 0], nsh[0] * qv[el, 1] + nsh[1] * qv[el, 2]], -1)
        r_el = rot[el]
        loc_g = np.einsum("pij,pj->pi", r_el, loc)
        p = nodes[el] + loc_g
        npts = el.size
        jac = np.zeros((npts, 2, self.n_q))
        idx = np.arange(npts)
        jac[idx, :, 3 * el] = r_el[:, :, 0] * xi[:, None]
        jac[idx, :, 3 * el + 1] = r_el[:, :, 1] * nsh[0][:, None]
        jac[idx, :, 3 * el + 2] = r_el[:, :, 1] * nsh[1][:, None]
        v = node_v[el] + np.einsum("pij,pj->pi", r_el, loc_d) + betad[el, None] * (loc_g @ _J2.T)
        gam = betad[el, None] * (np.einsum("pij,pj->pi", r_el, loc_d) @ _J2.T)
        for j in range(ne - 1):
            m = el > j
            if not np.any(m):
                continue
            jac[m, :, 3 * j] = rot[j, :, 0]
            jac[m, :, 3 * j + 1] = rot[j, :, 1]
            arm = p[m] - nodes[j + 1]
            jac[m, :, 3 * j + 2] = arm @ _J2.T
            gam[m] += betad[j] * (chord_rate[j] @ _J2.T) + qv[j, 2] * (
                (v[m] - node_v[j + 1]) @ _J2.T
            )
        return p, jac, v, gam

    def static_residual_and_tangent(
        self, q: FloatArray, tip_force_n: float
    ) -> tuple[FloatArray, FloatArray]:
        """Residual ``f_int - J_tip^T F`` of the tip load toward -lateral, and its tangent
        (internal part analytic, load part by central differences)."""
        el = np.array([self.ne - 1])
        xi = np.array([1.0])
        force = np.array([0.0, -tip_force_n])
        zero = np.zeros(self.n_q)

        def load(qq: FloatArray) -> FloatArray:
            _, jac, _, _ = self.kinematics(qq, zero, el, xi)
            return jac[0].T @ force

        res = self.internal_force(q) - load(q)
        kt = self.internal_tangent(q)
        eps = 1e-7
        for k in range(self.n_q):
            dq = np.zeros(self.n_q)
            dq[k] = eps
            kt[:, k] -= (load(q + dq) - load(q - dq)) / (2 * eps)
        return res, kt


class FlxdynSystem:
    """Kane's equations of the chained FLXDYN elements on the prescribed hub (Eq. 36).

    State ``y = [q, qdot]``. ``M(q) qddot = -int rhoA J^T (gamma + 2 Omega J v + alpha J p
    - Omega^2 p) - f_int - (a0 M_e + a1 K_T) qdot`` with the element mass ``M_e`` and
    ``K_T`` of Eqs. 31-33 on each element's relative rates (Eq. 28).
    """

    def __init__(
        self,
        beam: BeamProperties,
        n_elements: int,
        drive: object,
        a0: float,
        a1: float,
        viscous_tension: bool = False,
    ) -> None:
        self.viscous_tension = viscous_tension
        self.fe = FlxdynBeam(beam, n_elements)
        self.drive = drive
        self.a0 = a0
        self.a1 = a1
        self.nq = self.fe.n_q
        self.n_state = 2 * self.nq
        self.m_el_full = self.fe.block(np.broadcast_to(self.fe.m_el, (n_elements, 3, 3)))

    def _hub(self, t: float) -> tuple[float, float]:
        return float(self.drive.rate(t)), float(self.drive.accel(t))  # type: ignore[attr-defined]

    def _mass_and_forces(self, t: float, y: FloatArray) -> tuple[FloatArray, FloatArray]:
        fe = self.fe
        q, qd = y[: self.nq], y[self.nq :]
        om, al = self._hub(t)
        p, jac, v, gam = fe.kinematics(q, qd, fe.q_el, fe.q_xi)
        acc0 = gam + 2 * om * (v @ _J2.T) + al * (p @ _J2.T) - om * om * p
        mass = np.einsum("p,pai,paj->ij", fe.q_w, jac, jac)
        gen = np.einsum("p,pai,pa->i", fe.q_w, jac, acc0)
        k_t = fe.k_total(q)
        damp = self.a0 * np.einsum("ij,ej->ei", fe.m_el, qd.reshape(-1, 3)) + self.a1 * np.einsum(
            "eij,ej->ei", k_t, qd.reshape(-1, 3)
        )
        rhs = -gen - fe.internal_force(q) - damp.ravel()
        if self.viscous_tension and self.a1 != 0.0:
            # Eq. 33 takes P from the elastic elongation alone, so with a1 > 0 the tension
            # that stiffens the element creeps behind the centrifugal load (Kelvin-Voigt,
            # time constant a1). Optionally add the viscous part a1 EA/L dDelta4/dt to P.
            pv = self.a1 * fe.ea / fe.le * qd[0::3]
            qq = q.reshape(-1, 3)
            le = fe.le
            rhs[1::3] -= pv * (6 / (5 * le) * qq[:, 1] - qq[:, 2] / 10)
            rhs[2::3] -= pv * (-qq[:, 1] / 10 + 2 * le / 15 * qq[:, 2])
        return mass, rhs

    def rhs(self, t: float, y: FloatArray) -> FloatArray:
        mass, rhs = self._mass_and_forces(t, y)
        return np.concatenate([y[self.nq :], np.linalg.solve(mass, rhs)])

    def jac(self, t: float, y: FloatArray) -> FloatArray:
        """Jacobian with the stiff parts exact (stiffness, damping, mass); the velocity-
        product and hub terms, small next to them, are left out (simplified Newton)."""
        fe = self.fe
        q = y[: self.nq]
        om, _ = self._hub(t)
        mass, _ = self._mass_and_forces(t, y)
        minv = np.linalg.inv(mass)
        k = fe.internal_tangent(q)
        c = self.a0 * self.m_el_full + self.a1 * fe.block(fe.k_total(q))
        n = self.nq
        out = np.zeros((2 * n, 2 * n))
        out[:n, n:] = np.eye(n)
        out[n:, :n] = -minv @ k + om * om * np.eye(n)
        out[n:, n:] = -minv @ c
        return out

    def initial_state(self) -> FloatArray:
        return np.zeros(self.n_state)

    def sample(self, y_hist: FloatArray, s_m: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Hub-frame positions (T, S, 2) and [axial strain (Eq. 51), curvature (Eq. 52)]."""
        fe = self.fe
        s = np.asarray(s_m, dtype=float)
        el = np.clip((s / fe.le).astype(np.intp), 0, fe.ne - 1)
        xi = s / fe.le - el
        _, _, dd, _ = _shape(xi, fe.le)
        zero = np.zeros(self.nq)
        pos = np.empty((y_hist.shape[0], s.size, 2))
        eps = np.empty((y_hist.shape[0], s.size, 2))
        for k, y in enumerate(y_hist):
            q = y[: self.nq]
            pos[k], _, _, _ = fe.kinematics(q, zero, el, xi)
            qq = q.reshape(fe.ne, 3)
            eps[k, :, 0] = qq[el, 0] / fe.le
            eps[k, :, 1] = dd[0] * qq[el, 1] + dd[1] * qq[el, 2]
        return pos, eps
