"""The clamped centre-line fit on synthetic edge points of known shape."""

from __future__ import annotations

import math

import numpy as np

from vision.centreline import correlation_inflation, fit_centreline, fit_clamped_joint

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


# -- the hub's axis fitted with the clamped shape (pivot at a = -CLAMP_M) --------------
CLAMP_M = 0.008


def _turned(points, turn_rad):
    """Hub-frame points (a, b) as seen in the frame of an axis turned by ``turn_rad``
    about the pivot."""
    x, y = points[:, 0] + CLAMP_M, points[:, 1]
    c, s = math.cos(turn_rad), math.sin(turn_rad)
    return np.column_stack([c * x + s * y - CLAMP_M, -s * x + c * y])


def _hub_edges(rng, sigma_m, length_m=0.05, width_m=0.051, n=45):
    a = np.linspace(-length_m - 0.001, -0.001, n)  # the hub lies behind the clamp
    return tuple(
        np.column_stack([a, np.full(n, side * width_m / 2) + sigma_m * rng.standard_normal(n)])
        for side in (1.0, -1.0)
    )


def _joint(left, right, ha, hb, trial_rad):
    """Fit as the measurer does: turn the trial axis by what the fit asks until it
    asks for nothing; returns the fit and the axis's total turn from the truth."""
    turn = trial_rad
    for _ in range(8):
        pts = [_turned(p, turn) for p in (left, right, ha, hb)]
        fit = fit_clamped_joint(*pts, 8, 0.81, CLAMP_M)
        assert not isinstance(fit, str)
        turn += fit.rotation_rad
        if abs(fit.rotation_rad) < 1e-13:
            break
    return fit, turn


def test_the_axis_and_a_cantilever_shape_are_recovered_exactly() -> None:
    """Noise-free edges of a cubic (in the clamped basis) seen from an axis 0.3 deg off:
    the fit turns the axis back onto the truth and recovers the shape."""
    left, right = _edges(_static_tip_load, np.random.default_rng(0))
    ha, hb = _hub_edges(np.random.default_rng(0), 0.0)
    for hub in ((ha, hb), (np.zeros((0, 2)), np.zeros((0, 2)))):
        fit, turn = _joint(left, right, *hub, math.radians(0.3))
        assert abs(turn) < 1e-11, turn
        a = np.linspace(0.0, 0.81, 50)
        np.testing.assert_allclose(fit.fit.centre(a), _static_tip_load(a), atol=1e-10)
        assert abs(fit.fit.width - W_M) < 1e-10
    assert abs(fit.hub_width - 0.051) < 1e-10 or math.isnan(fit.hub_width)


def test_stated_axis_and_tip_uncertainties_match_the_scatter() -> None:
    """150 noisy frames of edge points: the scatter of the axis and of the tip about the
    truth is what the fit states (the sample std within ~12 %, 2 sigma, of the true one);
    a 50 mm hub's edges add to what the beam's root tells."""
    rng = np.random.default_rng(3)
    sigma = 3e-5  # 0.03 mm per edge point, as on the rendered bench
    axis, tip, sd_axis, sd_tip, sd_root = [], [], [], [], []
    for _ in range(150):
        left, right = _edges(_static_tip_load, rng, sigma)
        ha, hb = _hub_edges(rng, sigma)
        fit, turn = _joint(left, right, ha, hb, 0.0)
        axis.append(turn)
        sd_axis.append(fit.rotation_sd_rad)
        tip.append(float(fit.fit.centre(np.array([0.81]))[0] - _static_tip_load(0.81)))
        sd_tip.append(fit.fit.tip_sd)
        root = fit_clamped_joint(left, right, np.zeros((0, 2)), np.zeros((0, 2)), 8, 0.81, CLAMP_M)
        assert not isinstance(root, str)
        sd_root.append(root.rotation_sd_rad)
    for err, sd in ((axis, sd_axis), (tip, sd_tip)):
        ratio = float(np.std(err) / np.mean(sd))
        assert 0.8 < ratio < 1.2, ratio
    assert np.mean(sd_axis) < 0.95 * np.mean(sd_root)
