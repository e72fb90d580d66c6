"""Clamped-free modes against the known eigenvalues and the orthogonality relations."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.modes import (
    clamped_free_eigenvalues,
    modal_integrals,
    mode_shapes,
    natural_frequencies_rad_s,
)


def test_eigenvalues_match_the_tabulated_roots() -> None:
    lam = clamped_free_eigenvalues(3)
    assert lam == pytest.approx([1.87510407, 4.69409113, 7.85475744], abs=5e-9)
    high = clamped_free_eigenvalues(40)
    assert np.all(np.abs(np.cos(high) * np.cosh(high) + 1.0) <= 1e-12 * np.cosh(high))
    # asymptote (i - 1/2) pi, with the correction decaying like exp(-lambda)
    i = np.arange(1, 41)
    assert np.abs(high - (i - 0.5) * math.pi)[10:].max() < 1e-9


def test_shapes_satisfy_boundary_conditions_and_orthogonality_for_high_modes() -> None:
    n = 30
    L = 0.835
    at = mode_shapes([0.0, L], L, n)
    assert at[0] == pytest.approx(np.zeros(n), abs=1e-12)
    assert np.abs(at[1]) == pytest.approx(2.0 * np.ones(n), rel=1e-12)
    assert mode_shapes([0.0], L, n, 1)[0] == pytest.approx(np.zeros(n), abs=1e-9)
    lam = clamped_free_eigenvalues(n)
    scale2 = (lam / L) ** 2
    assert mode_shapes([L], L, n, 2)[0] / scale2 == pytest.approx(np.zeros(n), abs=1e-9)
    assert mode_shapes([L], L, n, 3)[0] / scale2 / (lam / L) == pytest.approx(np.zeros(n), abs=1e-9)
    mi = modal_integrals(L, 0.0, 1.0, 1.0, n)
    assert mi.mass / L == pytest.approx(np.eye(n), abs=1e-12)  # Eq. 8.8
    k_expected = np.diag(lam**4 / L**3)  # Eq. 8.9 with EI = 1
    assert np.abs(mi.stiffness - k_expected).max() < 1e-12 * k_expected.max()


def test_shape_derivatives_match_finite_differences() -> None:
    L, n = 2.0, 8
    x = np.linspace(0.1, 1.9, 17)
    h = 1e-5
    for order in (1, 2, 3, 4):
        fd = (mode_shapes(x + h, L, n, order - 1) - mode_shapes(x - h, L, n, order - 1)) / (2 * h)
        exact = mode_shapes(x, L, n, order)
        assert exact == pytest.approx(fd, rel=1e-6, abs=1e-6 * np.abs(exact).max())
    # the beam equation: Phi'''' = (lambda / L)^4 Phi
    lam = clamped_free_eigenvalues(n)
    assert mode_shapes(x, L, n, 4) == pytest.approx(
        mode_shapes(x, L, n) * (lam / L) ** 4, rel=1e-9, abs=1e-9
    )


def test_natural_frequencies_eq_8_7() -> None:
    w = natural_frequencies_rad_s(2, 0.835, 3.5007745, 0.16259)
    assert w[0] == pytest.approx(
        (1.87510407 / 0.835) ** 2 * math.sqrt(3.5007745 / 0.16259), rel=1e-8
    )
    assert w[0] / (2 * math.pi) == pytest.approx(3.724, abs=1e-3)
