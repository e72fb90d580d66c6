"""The coefficients of the 3-stage Radau IIA method (order 5 at the step ends, L-stable,
stiffly accurate), once for both integrators: :mod:`sim.solvers.radau` (adaptive, nonlinear)
and :mod:`sim.solvers.linear_radau` (batched, linear time-varying).

- :data:`C` the nodes (the last is 1: the new point is a stage), :data:`A` the collocation
  matrix ``a_ij = int_0^{c_i} l_j(s) ds`` (``l_j`` the Lagrange basis on ``C``), computed
  from that definition (it agrees with Hairer and Wanner's closed form, Table IV.5.6, to
  rounding; the tests check it);
- for the simplified Newton of scipy's ``Radau``: the eigenvalues of ``A^-1``
  (:data:`MU_REAL`, :data:`MU_COMPLEX`), the transformation :data:`T` with its inverse
  :data:`TI` that block-diagonalises it, the embedded error estimate's :data:`E` and the
  dense output's :data:`P` (scipy/integrate/_ivp/radau.py);
- :func:`tableau` the same nodes, collocation matrix and dense output for any number of
  stages ``s`` (order ``2 s - 1`` at the step ends, stage order ``s``), from the same
  definitions: the fixed-step integrator's higher orders (:func:`sim.solvers.radau.radau5`).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

_S6 = math.sqrt(6.0)

C = np.array([(4.0 - _S6) / 10.0, (4.0 + _S6) / 10.0, 1.0])


def _collocation_matrix(c: FloatArray = C) -> FloatArray:
    """a_ij = int_0^{c_i} l_j(s) ds, l_j the Lagrange basis polynomial of node j."""
    s = c.size
    a = np.empty((s, s))
    for j in range(s):
        others = [c[m] for m in range(s) if m != j]
        coef = np.poly(others) / np.prod([c[j] - o for o in others])
        prim = np.polyint(coef)
        a[:, j] = np.polyval(prim, c) - np.polyval(prim, 0.0)
    return a


A = _collocation_matrix()
E = np.array([-13 - 7 * _S6, -13 + 7 * _S6, -1.0]) / 3
MU_REAL = 3 + 3 ** (2 / 3) - 3 ** (1 / 3)
MU_COMPLEX = 3 + 0.5 * (3 ** (1 / 3) - 3 ** (2 / 3)) - 0.5j * (3 ** (5 / 6) + 3 ** (7 / 6))
T = np.array(
    [
        [0.09443876248897524, -0.14125529502095421, 0.03002919410514742],
        [0.25021312296533332, 0.20412935229379994, -0.38294211275726192],
        [1.0, 1.0, 0.0],
    ]
)
TI = np.array(
    [
        [4.17871859155190428, 0.32768282076106237, 0.52337644549944951],
        [-4.17871859155190428, -0.32768282076106237, 0.47662355450055044],
        [0.50287263494578682, -2.57192694985560522, 0.59603920482822492],
    ]
)
TI_REAL = TI[0]
TI_COMPLEX = TI[1] + 1j * TI[2]
P = np.array(
    [
        [13 / 3 + 7 * _S6 / 3, -23 / 3 - 22 * _S6 / 3, 10 / 3 + 5 * _S6],
        [13 / 3 - 7 * _S6 / 3, -23 / 3 + 22 * _S6 / 3, 10 / 3 - 5 * _S6],
        [1 / 3, -8 / 3, 10 / 3],
    ]
)


#: the stage counts :func:`tableau` offers (order 5, 7, 9)
STAGES = (3, 4, 5)


def tableau(stages: int) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Radau IIA with ``stages`` stages: nodes ``c`` (s,), collocation matrix ``a`` (s, s)
    and the dense output's ``p`` (s, s), with ``y(t + x h) = y + (Z^T p) [x, .., x^s]``
    for the stage increments ``Z`` (s, n).

    The nodes are the zeros of ``P_s(2x - 1) - P_{s-1}(2x - 1)`` (Legendre polynomials;
    the last is 1), ``a`` as :data:`A` (the collocation conditions), and ``p`` the
    inverse of the Vandermonde matrix ``c_i^k`` (k = 1 .. s), transposed: the collocation
    polynomial through ``(0, 0)`` and the stages. Three stages give :data:`C`, :data:`A`,
    :data:`P` themselves (those constants, bit for bit, so the default integrator does not
    move)."""
    if stages not in STAGES:
        raise ValueError(f"stages must be one of {STAGES}, got {stages!r}")
    if stages == 3:
        return C, A, P
    coef = np.zeros(stages + 1)
    coef[stages], coef[stages - 1] = 1.0, -1.0
    c = np.sort(np.polynomial.legendre.legroots(coef).real)
    c = 0.5 * (c + 1.0)
    c[-1] = 1.0
    vander = c[:, None] ** np.arange(1, stages + 1)[None, :]
    return c, _collocation_matrix(c), np.asarray(np.linalg.inv(vander).T, dtype=np.float64)
