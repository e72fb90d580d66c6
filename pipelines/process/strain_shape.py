"""Beam deflection reconstructed from the four surface strains (paper §5.1.3).

The paper fits the measured curvature along the beam and integrates it twice with the
clamped boundary conditions (w(0) = w'(0) = 0). In the static test the bending moment
is linear in x, so a linear curvature fit is exact. In the dynamic case the inertial
loading is distributed and unknown, so the curvature is expanded in the curvatures of
the first clamped-free modes instead, which also satisfy the free-end conditions
(zero moment and shear at the tip) that a polynomial fit ignores.

Surface strain on the +lateral face (z = +t/2): eps = -z w'', so w'' = -eps / z.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]

# w(s) = int_0^s (s - xi) kappa(xi) dxi by Gauss-Legendre: exact to rounding for the
# smooth curvature bases used here (polynomials, clamped-free modes up to the 4th).
_GAUSS_X, _GAUSS_W = np.polynomial.legendre.leggauss(64)


@dataclass(frozen=True)
class StrainShape:
    """A linear map from the gauge strains to the lateral deflection at stations.

    Build it with ``linear_curvature_shape`` (the paper's static estimate) or
    ``modal_curvature_shape`` (the dynamic generalisation), then call
    ``lateral_m(strain)``.

    Attributes
    ----------
    gauge_positions_m : (G,) distances from the clamp.
    stations_m : (S,) where the deflection is returned (the last one is the tip).
    operator : (S, G) deflection per unit strain.
    basis : description of the curvature basis.
    """

    gauge_positions_m: FloatArray
    stations_m: FloatArray
    operator: FloatArray
    basis: str
    condition: float = field(default=float("nan"))

    def lateral_m(self, strain: ArrayLike) -> FloatArray:
        """Lateral deflection (N, S) [m] from surface strains (N, G) [m/m]; NaN rows stay NaN."""
        eps = np.asarray(strain, dtype=float)
        if eps.ndim == 1:
            eps = eps[None, :]
        if eps.shape[-1] != self.gauge_positions_m.size:
            raise ValueError(
                f"strain must have {self.gauge_positions_m.size} gauges in its last axis, "
                f"got shape {eps.shape}"
            )
        return np.asarray(eps @ self.operator.T, dtype=float)

    def tip_lateral_m(self, strain: ArrayLike) -> FloatArray:
        """Lateral tip deflection (N,) [m]."""
        return self.lateral_m(strain)[:, -1]


def _validate(gauge_positions_m: ArrayLike, length_m: float, surface_offset_m: float) -> FloatArray:
    x = np.asarray(gauge_positions_m, dtype=float)
    if x.ndim != 1 or x.size < 2:
        raise ValueError(f"gauge_positions_m must list at least 2 gauges, got {x!r}")
    if not np.all(np.isfinite(x)) or np.any(x < 0.0) or np.any(x >= length_m):
        raise ValueError(f"gauge_positions_m must lie on the beam [0, {length_m}), got {x!r}")
    if not surface_offset_m > 0.0:
        raise ValueError(f"surface_offset_m must be positive, got {surface_offset_m!r}")
    return x


def _build(
    curvature: Callable[[FloatArray], FloatArray],
    n_terms: int,
    gauge_x: FloatArray,
    length_m: float,
    surface_offset_m: float,
    stations_m: ArrayLike | None,
    basis: str,
) -> StrainShape:
    if n_terms > gauge_x.size:
        raise ValueError(f"cannot fit {n_terms} curvature terms to {gauge_x.size} gauges")
    stations = (
        np.linspace(0.0, length_m, 21) if stations_m is None else np.asarray(stations_m, float)
    )
    shapes = np.zeros((stations.size, n_terms))  # (S, n): deflection per coefficient
    for k, s in enumerate(stations):
        xi = 0.5 * s * (_GAUSS_X + 1.0)
        shapes[k] = (0.5 * s * _GAUSS_W * (s - xi)) @ curvature(xi)
    at_gauges = curvature(gauge_x)  # (G, n): curvature per coefficient
    # w'' = -eps / z  ->  coefficients c = pinv(K) (-eps / z)
    pinv = np.linalg.pinv(at_gauges)
    operator = shapes @ pinv * (-1.0 / surface_offset_m)
    return StrainShape(
        gauge_positions_m=gauge_x,
        stations_m=stations,
        operator=operator,
        basis=basis,
        condition=float(np.linalg.cond(at_gauges)),
    )


def linear_curvature_shape(
    gauge_positions_m: ArrayLike,
    length_m: float,
    surface_offset_m: float,
    *,
    stations_m: ArrayLike | None = None,
) -> StrainShape:
    """The paper's static estimate: a straight-line least-squares fit of curvature along
    the beam, integrated twice from the clamp. Exact for a tip load (M = P (L - x))."""
    x = _validate(gauge_positions_m, length_m, surface_offset_m)
    return _build(
        lambda s: np.column_stack([np.ones_like(s), s]),
        2,
        x,
        length_m,
        surface_offset_m,
        stations_m,
        "linear curvature (paper §5.1.3)",
    )


def modal_curvature_shape(
    gauge_positions_m: ArrayLike,
    length_m: float,
    surface_offset_m: float,
    mode_curvature: Callable[[FloatArray, int], FloatArray],
    *,
    n_modes: int = 3,
    stations_m: ArrayLike | None = None,
) -> StrainShape:
    """Curvature expanded in the first ``n_modes`` clamped-free mode curvatures.

    ``mode_curvature(x_m, i)`` returns the second derivative of mode ``i`` (1-based)
    at ``x_m`` (any normalisation).
    """
    x = _validate(gauge_positions_m, length_m, surface_offset_m)
    if n_modes < 1:
        raise ValueError(f"n_modes must be at least 1, got {n_modes!r}")

    def curvature(s: FloatArray) -> FloatArray:
        return np.column_stack([mode_curvature(s, i) for i in range(1, n_modes + 1)])

    return _build(
        curvature,
        n_modes,
        x,
        length_m,
        surface_offset_m,
        stations_m,
        f"{n_modes} clamped-free mode curvatures",
    )
