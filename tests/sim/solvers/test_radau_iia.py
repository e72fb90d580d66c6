"""The one Radau IIA coefficient table (``sim.solvers.radau_iia``) against its definitions."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.solvers.radau_iia import MU_COMPLEX, MU_REAL, TI, A, C, P, T, tableau

S6 = math.sqrt(6.0)
CLOSED_FORM_A = np.array(  # Hairer and Wanner, Table IV.5.6
    [
        [(88 - 7 * S6) / 360, (296 - 169 * S6) / 1800, (-2 + 3 * S6) / 225],
        [(296 + 169 * S6) / 1800, (88 + 7 * S6) / 360, (-2 - 3 * S6) / 225],
        [(16 - S6) / 36, (16 + S6) / 36, 1 / 9],
    ]
)


def test_matrix_is_the_closed_form_and_collocation_conditions_hold() -> None:
    np.testing.assert_allclose(A, CLOSED_FORM_A, rtol=0.0, atol=1e-15)
    # C(3): sum_j a_ij c_j^(k-1) = c_i^k / k, k = 1..3 (collocation at the three nodes)
    for k in (1, 2, 3):
        np.testing.assert_allclose(A @ C ** (k - 1), C**k / k, rtol=0.0, atol=1e-15)
    # stiffly accurate: the weights are the last row, a quadrature of order 2s - 1 = 5
    for k in range(1, 6):
        assert A[2] @ C ** (k - 1) == pytest.approx(1.0 / k, abs=1e-15)


def test_transformation_block_diagonalises_the_inverse_matrix() -> None:
    np.testing.assert_allclose(TI @ T, np.eye(3), atol=1e-14)
    block = TI @ np.linalg.inv(A) @ T
    expected = np.array(
        [
            [MU_REAL, 0.0, 0.0],
            [0.0, MU_COMPLEX.real, -MU_COMPLEX.imag],
            [0.0, MU_COMPLEX.imag, MU_COMPLEX.real],
        ]
    )
    np.testing.assert_allclose(block, expected, atol=1e-12)


def test_the_three_stage_tableau_is_the_constants_bit_for_bit() -> None:
    c, a, p = tableau(3)
    assert c is C and a is A and p is P


@pytest.mark.parametrize("stages", [4, 5])
def test_more_stages_satisfy_the_radau_iia_conditions(stages: int) -> None:
    c, a, p = tableau(stages)
    s = stages
    # Radau nodes: increasing in (0, 1], the last 1, and the left Radau quadrature's
    # weights (the last row of a) exact for polynomials of degree 2 s - 2 (order 2 s - 1)
    assert np.all(np.diff(c) > 0.0) and c[0] > 0.0 and c[-1] == 1.0
    for k in range(1, 2 * s):
        assert a[-1] @ c ** (k - 1) == pytest.approx(1.0 / k, abs=1e-14)
    # C(s): collocation at every node, sum_j a_ij c_j^(k-1) = c_i^k / k
    for k in range(1, s + 1):
        np.testing.assert_allclose(a @ c ** (k - 1), c**k / k, rtol=0.0, atol=1e-14)
    # the dense output: stage increments of y + sum_k q_k x^k give back q
    q = np.random.default_rng(4).standard_normal((2, s))
    z = (q @ (c[None, :] ** np.arange(1, s + 1)[:, None])).T  # (s, 2)
    np.testing.assert_allclose(z.T @ p, q, rtol=0.0, atol=1e-12)
    # L-stable: the stability function R(inf) = 1 - b^T a^-1 1 vanishes (stiffly accurate)
    assert 1.0 - a[-1] @ np.linalg.solve(a, np.ones(s)) == pytest.approx(0.0, abs=1e-12)


def test_other_stage_counts_are_refused() -> None:
    with pytest.raises(ValueError, match="stages"):
        tableau(6)
