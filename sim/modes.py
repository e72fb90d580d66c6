"""Clamped-free (cantilever) beam modes: seed 001 Eqs. 8.4-8.9.

Shapes are evaluated in a form that stays accurate for large lambda: with
sigma = (cosh l + cos l) / (sinh l + sin l) = 1 - eps, the hyperbolic part
cosh a - sigma sinh a = exp(-a) + eps sinh a, and eps sinh a is formed from ratios of
exponentials that never overflow or cancel. Shapes are normalised so that
(1/L) int_0^L Phi_i^2 dx = 1 (Eq. 8.8 with m = rho L), which makes Phi_i(L) = 2 (-1)^(i+1)
and q_i a length (m).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import brentq

from sim.errors import SimInputError

FloatArray = NDArray[np.float64]


def _eigen_function(lam: float) -> float:
    # cos l cosh l + 1 = 0 divided by cosh l: bounded, same roots, no overflow.
    return math.cos(lam) + 1.0 / math.cosh(lam) if lam < 700.0 else math.cos(lam)


@lru_cache(maxsize=64)
def _eigenvalues_cached(n: int) -> tuple[float, ...]:
    out = []
    for i in range(1, n + 1):
        lo, hi = (i - 1) * math.pi, i * math.pi
        out.append(brentq(_eigen_function, lo + 1e-12, hi, xtol=1e-15, rtol=1e-15, maxiter=200))
    return tuple(out)


def clamped_free_eigenvalues(n_modes: int) -> FloatArray:
    """First ``n_modes`` roots lambda_i of cos(lambda) cosh(lambda) + 1 = 0 (Eq. 8.6).

    Returns
    -------
    (n_modes,) array: 1.87510407, 4.69409113, 7.85475744, ... -> (i - 1/2) pi.
    """
    if not isinstance(n_modes, int | np.integer) or n_modes < 1:
        raise SimInputError("n_modes", f"must be a positive integer, got {n_modes!r}")
    return np.array(_eigenvalues_cached(int(n_modes)))


def natural_frequencies_rad_s(
    n_modes: int, length_m: float, bending_stiffness_n_m2: float, mass_per_length_kg_m: float
) -> FloatArray:
    """Clamped-free natural frequencies p_i = (lambda_i / L)^2 sqrt(EI / rho A) (Eq. 8.7),
    rad/s, shape (n_modes,)."""
    lam = clamped_free_eigenvalues(n_modes)
    return (lam / length_m) ** 2 * math.sqrt(bending_stiffness_n_m2 / mass_per_length_kg_m)


def _shape_terms(lam: float, a: FloatArray, order: int) -> FloatArray:
    """d^order/da^order of cosh a - cos a - sigma (sinh a - sin a), stable for large lam."""
    sl, cl = math.sin(lam), math.cos(lam)
    em = math.exp(-lam)
    denom = 1.0 - em * em + 2.0 * sl * em  # (sinh l + sin l) * 2 exp(-l)
    num = -em + sl - cl  # eps * (sinh l + sin l)
    sigma = 1.0 - 2.0 * num * em / denom
    ea = np.exp(a - lam)
    e2a = np.exp(-2.0 * a)
    sinh_ratio = ea * (1.0 - e2a) / denom  # sinh a / (sinh l + sin l)
    cosh_ratio = ea * (1.0 + e2a) / denom
    k = order % 4
    if order % 2 == 0:
        hyp = np.exp(-a) + num * sinh_ratio
    else:
        hyp = -np.exp(-a) + num * cosh_ratio
    if k == 0:
        trig = -np.cos(a) + sigma * np.sin(a)
    elif k == 1:
        trig = np.sin(a) + sigma * np.cos(a)
    elif k == 2:
        trig = np.cos(a) - sigma * np.sin(a)
    else:
        trig = -np.sin(a) - sigma * np.cos(a)
    return hyp + trig


def mode_shapes(x_m: ArrayLike, length_m: float, n_modes: int, derivative: int = 0) -> FloatArray:
    """Clamped-free mode shapes Phi_i(x) (Eq. 8.4) or their x-derivatives.

    Parameters
    ----------
    x_m : (P,) distances from the clamp, 0 <= x <= L.
    length_m : L.
    n_modes : number of modes.
    derivative : 0..4, order of d/dx.

    Returns
    -------
    (P, n_modes) array; units 1/m^derivative (shapes are dimensionless, normalised to
    mean square 1 over the beam).
    """
    if derivative not in (0, 1, 2, 3, 4):
        raise SimInputError("derivative", f"must be 0..4, got {derivative!r}")
    x = np.atleast_1d(np.asarray(x_m, dtype=float))
    if np.any(x < -1e-12 * length_m) or np.any(x > length_m * (1.0 + 1e-12)):
        raise SimInputError("x_m", "must lie within [0, length_m]")
    lam = clamped_free_eigenvalues(n_modes)
    xi = np.clip(x / length_m, 0.0, 1.0)
    out = np.empty((x.size, n_modes))
    for i, li in enumerate(lam):
        out[:, i] = _shape_terms(float(li), li * xi, derivative) * (li / length_m) ** derivative
    return out


def gauss_points(
    length_m: float, n_panels: int = 24, order: int = 16
) -> tuple[FloatArray, FloatArray]:
    """Composite Gauss-Legendre nodes and weights on [0, L] (enough for ~40 modes to
    machine precision)."""
    g, w = np.polynomial.legendre.leggauss(order)
    edges = np.linspace(0.0, length_m, n_panels + 1)
    h = np.diff(edges)
    x = (edges[:-1, None] + 0.5 * h[:, None] * (g[None, :] + 1.0)).ravel()
    wt = (0.5 * h[:, None] * w[None, :]).ravel()
    return x, wt


@dataclass(frozen=True)
class ModalIntegrals:
    """Integrals of the assumed modes for a uniform cantilever on a hub.

    With Phi_i the normalised shapes, r the hub offset (pivot to clamp) and rho A the mass
    per length (plus an optional tip mass m_t at x = L):

    - ``mass`` M_ij = int rhoA Phi_i Phi_j + m_t Phi_i(L) Phi_j(L)  (kg)
    - ``stiffness`` K_ij = int EI Phi_i'' Phi_j''  (N/m), diagonal p_i^2 M_ii
    - ``euler`` b_i = int rhoA Phi_i (r + x) + m_t Phi_i(L) (r + L)  (kg m)
    - ``centrifugal`` G_ij = int N(x) Phi_i' Phi_j', N(x) = int_x^L rhoA (r + s) ds
      + m_t (r + L) (the axial force per unit hub rate squared; kg m)
    - ``slope`` D_ij = int Phi_i' Phi_j'  (1/m), foreshortening u(L) = -q^T D q / 2
    """

    mass: FloatArray
    stiffness: FloatArray
    euler: FloatArray
    centrifugal: FloatArray
    slope: FloatArray
    tip_shape: FloatArray
    hub_inertia_kg_m2: float


def modal_integrals(
    length_m: float,
    hub_offset_m: float,
    mass_per_length_kg_m: float,
    bending_stiffness_n_m2: float,
    n_modes: int,
    tip_mass_kg: float = 0.0,
) -> ModalIntegrals:
    """Compute the :class:`ModalIntegrals` by composite Gauss quadrature."""
    L, r, rho = length_m, hub_offset_m, mass_per_length_kg_m
    x, w = gauss_points(L, n_panels=max(8, 2 * n_modes), order=16)
    phi = mode_shapes(x, L, n_modes)
    dphi = mode_shapes(x, L, n_modes, 1)
    ddphi = mode_shapes(x, L, n_modes, 2)
    tip = mode_shapes([L], L, n_modes)[0]
    axial = rho * ((r * L + 0.5 * L * L) - (r * x + 0.5 * x * x)) + tip_mass_kg * (r + L)
    mass = rho * (phi.T * w) @ phi + tip_mass_kg * np.outer(tip, tip)
    stiffness = bending_stiffness_n_m2 * (ddphi.T * w) @ ddphi
    euler = rho * (phi.T * w) @ (r + x) + tip_mass_kg * tip * (r + L)
    centrifugal = (dphi.T * (w * axial)) @ dphi
    slope = (dphi.T * w) @ dphi
    j_hub = rho * float(np.sum(w * (r + x) ** 2)) + tip_mass_kg * (r + L) ** 2
    return ModalIntegrals(mass, stiffness, euler, centrifugal, slope, tip, j_hub)
