"""Strain-based deflection against beam theory."""

from __future__ import annotations

import numpy as np
import pytest

from pipelines.process.strain_shape import linear_curvature_shape, modal_curvature_shape

L = 0.835
Z = 0.003175 / 2
EI = 6.89e10 * 5.08095e-11
GAUGES = np.array([0.005, 0.204, 0.403, 0.603])
LAMBDAS = (1.87510407, 4.69409113, 7.85475744, 10.99554073)


def _mode(x: np.ndarray, i: int, d: int) -> np.ndarray:
    """Clamped-free mode i (Eq. 8.4) and its d-th derivative, written out independently."""
    lam = LAMBDAS[i - 1]
    k = lam / L
    s = (np.cosh(lam) + np.cos(lam)) / (np.sinh(lam) + np.sin(lam))
    kx = k * x
    funcs = {
        0: np.cosh(kx) - np.cos(kx) - s * (np.sinh(kx) - np.sin(kx)),
        2: k**2 * (np.cosh(kx) + np.cos(kx) - s * (np.sinh(kx) + np.sin(kx))),
    }
    return funcs[d]


def test_linear_fit_recovers_the_tip_load_deflection_exactly() -> None:
    p_n = 0.149 * 9.80665
    # tip load toward -lateral: w'' = -P (L - x) / EI; gauges on the +lateral face
    strain = Z * p_n * (L - GAUGES) / EI
    shape = linear_curvature_shape(GAUGES, L, Z, stations_m=np.linspace(0, L, 11))
    w = shape.lateral_m(strain)[0]
    x = shape.stations_m
    exact = -p_n * x**2 * (3 * L - x) / (6 * EI)
    np.testing.assert_allclose(w, exact, rtol=1e-9, atol=1e-15)
    assert shape.tip_lateral_m(strain)[0] == pytest.approx(-p_n * L**3 / (3 * EI), rel=1e-9)


def test_modal_fit_recovers_a_combination_of_modes() -> None:
    coeffs = np.array([[0.03, -0.002, 0.0004], [-0.01, 0.001, 0.0]])
    strain = np.stack([-Z * sum(c[j] * _mode(GAUGES, j + 1, 2) for j in range(3)) for c in coeffs])
    shape = modal_curvature_shape(
        GAUGES, L, Z, lambda x, i: _mode(x, i, 2), n_modes=3, stations_m=[0.2, 0.5, L]
    )
    w = shape.lateral_m(strain)
    for row, c in zip(w, coeffs, strict=True):
        exact = sum(c[j] * _mode(shape.stations_m, j + 1, 0) for j in range(3))
        np.testing.assert_allclose(row, exact, rtol=1e-9, atol=1e-12)


def test_noise_is_not_amplified_beyond_the_fit_conditioning() -> None:
    rng = np.random.default_rng(1)
    shape = modal_curvature_shape(GAUGES, L, Z, lambda x, i: _mode(x, i, 2), n_modes=2)
    noise = rng.normal(0.0, 2e-6, size=(20000, 4))
    tip_sd = float(np.std(shape.tip_lateral_m(noise)))
    # 2 microstrain of gauge noise must stay below 1 % of the ~31 mm tip amplitude
    assert tip_sd < 3.1e-4
    assert np.isfinite(shape.condition)


@pytest.mark.parametrize(
    ("gauges", "words"),
    [([0.1], "at least 2"), ([0.1, 0.9], "on the beam"), ([0.1, np.nan], "on the beam")],
)
def test_bad_gauge_positions(gauges: list[float], words: str) -> None:
    with pytest.raises(ValueError, match=words):
        linear_curvature_shape(gauges, L, Z)


def test_more_terms_than_gauges_is_refused() -> None:
    with pytest.raises(ValueError, match="cannot fit 5"):
        modal_curvature_shape(GAUGES, L, Z, lambda x, i: _mode(x, min(i, 4), 2), n_modes=5)
