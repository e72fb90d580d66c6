"""The clamped centre-line fit on synthetic edge points of known shape."""

from __future__ import annotations

import math

import numpy as np

from vision.centreline import correlation_inflation, fit_centreline

L_M, W_M = 0.835, 0.01905


def _edges(shape, rng, sigma_m=0.0, n=700):
    a = np.linspace(0.03, 0.81, n)
    b = shape(a)
    left = np.column_stack([a, b + W_M / 2 + sigma_m * rng.standard_normal(n)])
    right = np.column_stack([a, b - W_M / 2 + sigma_m * rng.standard_normal(n)])
    return left, right


def _static_tip_load(a):
    # Euler-Bernoulli cantilever under a tip load: w = w_L (3 (a/L)^2 - (a/L)^3) / 2.
    x = a / L_M
    return 0.05 * (3 * x**2 - x**3) / 2


def test_a_cantilever_shape_is_recovered_exactly() -> None:
    left, right = _edges(_static_tip_load, np.random.default_rng(0))
    fit = fit_centreline(left, right, 8, 0.81)
    assert not isinstance(fit, str)
    a = np.linspace(0.0, 0.81, 50)
    # A cubic lies in the clamped basis: only rounding remains.
    np.testing.assert_allclose(fit.centre(a), _static_tip_load(a), atol=1e-12)
    # Normal equations: rounding at cond(A)^2 * eps, ~1e-8 for this basis.
    assert abs(fit.width - W_M) < 1e-12 and abs(fit.root_slope_rad) < 1e-8


def test_reported_tip_uncertainty_matches_the_scatter() -> None:
    rng = np.random.default_rng(1)
    sigma = 1e-4  # 0.1 mm per edge point
    errs, sds = [], []
    for _ in range(150):
        left, right = _edges(_static_tip_load, rng, sigma)
        fit = fit_centreline(left, right, 8, 0.81)
        assert not isinstance(fit, str)
        errs.append(float(fit.centre(np.array([0.81]))[0] - _static_tip_load(0.81)))
        sds.append(fit.tip_sd)
    ratio = float(np.std(errs) / np.mean(sds))
    # 150 samples: the sample std is within ~12 % (2 sigma) of the true one.
    assert 0.8 < ratio < 1.2, ratio


def test_clutter_points_beside_an_edge_are_rejected() -> None:
    rng = np.random.default_rng(2)
    left, right = _edges(_static_tip_load, rng, 5e-5)
    # A bright bar 3 mm beside the left edge over 10 % of the beam took those points.
    hit = (left[:, 0] > 0.4) & (left[:, 0] < 0.48)
    left[hit, 1] += 3e-3
    fit = fit_centreline(left, right, 8, 0.81)
    assert not isinstance(fit, str)
    assert len(fit.left) <= len(left) - hit.sum()
    err = abs(float(fit.centre(np.array([0.81]))[0] - _static_tip_load(0.81)))
    assert err < 3 * fit.tip_sd, (err, fit.tip_sd)


def test_too_few_points_give_a_reason() -> None:
    left, right = _edges(_static_tip_load, np.random.default_rng(3), n=8)
    assert fit_centreline(left, right, 8, 0.81) == "beam edges too ragged"


def test_correlation_inflation_of_a_first_order_process() -> None:
    rng = np.random.default_rng(4)
    rho = 0.5
    x = np.zeros(20000)
    for i in range(1, len(x)):
        x[i] = rho * x[i - 1] + rng.standard_normal()
    assert math.isclose(correlation_inflation(x), (1 + rho) / (1 - rho), rel_tol=0.1)
    assert correlation_inflation(rng.standard_normal(20000)) < 1.05
