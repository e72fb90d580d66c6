"""The clamped centre-line fit on synthetic edge points of known shape."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vision.centreline import (
    correlation_inflation,
    fit_centreline,
    fit_clamped_joint,
    long_run_inflation,
    long_run_inflation_max,
)

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


# -- the cantilever's mode space -----------------------------------------------------
def _stepped_hub(rng, step_m):
    """A 180 mm hub's edges, the second seen 3 mm further out over its half nearer the
    clamp (a bar lying against it there) and over its outer 175 mm only."""
    ha, hb = _hub_edges(rng, 3e-5, length_m=0.18, n=150)
    hb = hb[5:].copy()
    hb[hb[:, 0] > -0.09, 1] -= step_m
    return ha, hb


def test_a_hub_edge_the_biweight_empties_leaves_the_beams_root_alone() -> None:
    """The stepped hub edge: the straight one (more points) sets the hub's scale, and
    after the first solve every point of the stepped one lies beyond the cut. Its offset
    then has no point (formerly a singular matrix, raised: the frame refused as
    "measurement failed"); the fit is the beam's root alone, as for a hub whose edges
    are not straight lines: the same fit, stating its own uncertainty."""
    none = np.zeros((0, 2))
    turns, sds = [], []
    for seed in range(3):
        rng = np.random.default_rng(40 + seed)
        left, right = _edges(_static_tip_load, rng, 3e-5)
        ha, hb = _stepped_hub(rng, 3e-3)
        trial = math.radians(0.5 * seed)
        pts = [_turned(p, trial) for p in (left, right, ha, hb)]
        fit = fit_clamped_joint(*pts, 8, 0.81, CLAMP_M)
        root = fit_clamped_joint(*pts[:2], none, none, 8, 0.81, CLAMP_M)
        assert not isinstance(fit, str) and not isinstance(root, str)
        assert math.isnan(fit.hub_width) and math.isnan(fit.hub_rms)
        assert fit.rotation_rad == root.rotation_rad
        assert fit.rotation_sd_rad == root.rotation_sd_rad and fit.fit.tip_sd == root.fit.tip_sd
        # the trial axis is `trial` off the truth: the turn back within 3 stated sd
        turns.append(fit.rotation_rad + trial)
        sds.append(fit.rotation_sd_rad)
    assert np.all(np.abs(turns) <= 3 * np.array(sds)), (turns, sds)
    # another fit's inliers keeping none of the stepped edge's points: the root alone
    rng = np.random.default_rng(40)
    left, right = _edges(_static_tip_load, rng, 3e-5)
    ha, hb = _stepped_hub(rng, 3e-3)
    given = np.ones(len(left) + len(right) + len(ha) + len(hb), dtype=bool)
    given[-len(hb) :] = False
    fit = fit_clamped_joint(left, right, ha, hb, 8, 0.81, CLAMP_M, inliers=given)
    root = fit_clamped_joint(left, right, none, none, 8, 0.81, CLAMP_M)
    assert not isinstance(fit, str) and not isinstance(root, str)
    assert math.isnan(fit.hub_width) and fit.rotation_rad == root.rotation_rad


def test_beam_edges_that_cannot_fix_the_shape_give_a_reason_not_an_error() -> None:
    """Edge points all at the clamp (a = 0), where every shape function is 0: the shape
    is undetermined, the normal matrix exactly singular. A reason, as for edges too
    ragged (formerly numpy's "Singular matrix" raised), with the hub's edges or not."""
    rng = np.random.default_rng(44)
    left, right = _edges(lambda a: 0.0 * a, rng, 3e-5, n=40)
    left[:, 0] = right[:, 0] = 0.0
    ha, hb = _hub_edges(rng, 3e-5)
    for hub in ((ha, hb), (np.zeros((0, 2)), np.zeros((0, 2)))):
        got = fit_clamped_joint(left, right, *hub, 8, 0.81, CLAMP_M)
        assert got == "beam edges too few to fit the beam's shape"


def test_cantilever_modes_are_clamped_and_free() -> None:
    """beta_i L are the roots of cos cosh = -1 (Blevins' table: 1.87510, 4.69409,
    7.85476, 10.99554, 14.13717); each shape has w = w' = 0 at the clamp and zero
    moment and shear (w'' = w''' = 0) at the free end, and they are orthonormal."""
    from vision.centreline import cantilever_eigenvalues, cantilever_modes_t

    beta = np.array(cantilever_eigenvalues(5))
    np.testing.assert_allclose(beta, [1.87510, 4.69409, 7.85476, 10.99554, 14.13717], atol=6e-6)
    np.testing.assert_allclose(np.cos(beta) * np.cosh(beta), -1.0, atol=1e-9)
    x = np.linspace(0.0, 1.0, 20001)
    h = x[1]
    phi, dphi = cantilever_modes_t(x, 5), cantilever_modes_t(x, 5, 1)
    np.testing.assert_allclose(phi[:, 0], 0.0, atol=1e-12)
    np.testing.assert_allclose(dphi[:, 0], 0.0, atol=1e-12)
    # w'' and w''' at the free end by one-sided differences of w' (error ~ h beta^3).
    d2 = (3 * dphi[:, -1] - 4 * dphi[:, -2] + dphi[:, -3]) / (2 * h)
    d3 = (dphi[:, -1] - 2 * dphi[:, -2] + dphi[:, -3]) / h**2
    assert np.all(np.abs(d2) < 1e-3 * beta**2), d2
    assert np.all(np.abs(d3) < 1e-2 * beta**3), d3
    gram = np.trapezoid(phi[:, None, :] * phi[None, :, :], x, axis=2)
    np.testing.assert_allclose(gram, np.eye(5), atol=1e-6)


def _material_edges(pose, rng, sigma_m, n=700):
    """Edge points of a rendered-truth pose (lateral at arc length, inextensible)."""
    s = pose.stations_m
    lon = s + pose.longitudinal_m
    a = np.linspace(0.03, 0.81, n)
    b = np.interp(a, lon, pose.lateral_m)
    left = np.column_stack([a, b + W_M / 2 + sigma_m * rng.standard_normal(n)])
    right = np.column_stack([a, b - W_M / 2 + sigma_m * rng.standard_normal(n)])
    return left, right, (lambda q: np.interp(q, lon, pose.lateral_m))


def _load_pose(rng, tip_m=0.035):
    """A reciprocating cantilever's shape: the static response to its inertial load, the
    hub's acceleration's (linear from the pivot) and its vibration's (mode i's shape
    times beta_i^4, modes 1-3), integrated by the renderer from the free end."""
    from vision.centreline import cantilever_eigenvalues, cantilever_modes_t
    from vision.synthetic.scene import BeamPose

    amp = rng.uniform(-1, 1, 3) * np.array([1.0, 0.15, 0.04])
    accel = rng.uniform(-1, 1)
    beta4 = np.array(cantilever_eigenvalues(3)) ** 4

    def load(s):
        x = s / L_M
        return 8.0 * accel * (CLAMP_M / L_M + x) + (amp * beta4) @ cantilever_modes_t(x, 3)

    return BeamPose.from_load(0.0, L_M, load, tip_m)


def _joint_modes(left, right, trial_rad, modes=4):
    turn = trial_rad
    empty = np.zeros((0, 2))
    for _ in range(8):
        pts = [_turned(p, turn) for p in (left, right)]
        fit = fit_clamped_joint(*pts, empty, empty, 8, 0.81, CLAMP_M, modes=modes, beam_length=L_M)
        assert not isinstance(fit, str)
        turn += fit.rotation_rad
        if abs(fit.rotation_rad) < 1e-13:
            break
    return fit, turn


def test_a_loaded_cantilevers_shape_and_axis_are_recovered_by_the_modes() -> None:
    """The renderer's physical shapes (the response to the inertial load, integrated from
    the free end: not built from modes) lie in four modes to a micrometre: noise-free edges
    seen from an axis 0.2 deg off give the axis back to 1.5e-5 rad."""
    rng = np.random.default_rng(5)
    for _ in range(3):
        pose = _load_pose(rng)
        left, right, truth = _material_edges(pose, rng, 0.0)
        fit, turn = _joint_modes(left, right, math.radians(0.2))
        # What four modes leave of the hub acceleration's static response (its modal
        # series converges as beta^-5) turns the axis by up to ~1e-5 rad, a fifth of
        # the noise's on 0.03 mm edges (test below); the shape to a micrometre.
        assert abs(turn) < 1.5e-5, turn
        a = np.linspace(0.03, 0.81, 60)
        err = np.max(np.abs(fit.fit.centre(a) - truth(a)))
        assert err < 1.5e-5 * (0.81 + CLAMP_M) + 1e-6, err
        assert fit.shape_dof == 7


def test_modal_uncertainty_matches_the_scatter_and_the_shape_test_holds() -> None:
    """120 noisy draws of physical shapes: the modal axis and tip scatter as stated, at
    about half the polynomial's axis uncertainty or less, and the shape test's statistic is
    chi-squared with its degrees of freedom (mean 7, 0.999 quantile 24.3). A shape
    without a free end (the tip-load cubic's shear) fails the test."""
    rng = np.random.default_rng(6)
    sigma = 3e-5
    axis, sd_axis, tip, sd_tip, chi2, sd_poly = [], [], [], [], [], []
    for _ in range(120):
        pose = _load_pose(rng)
        left, right, truth = _material_edges(pose, rng, sigma)
        fit, turn = _joint_modes(left, right, 0.0)
        axis.append(turn)
        sd_axis.append(fit.rotation_sd_rad)
        tip.append(float(fit.fit.centre(np.array([0.81]))[0] - truth(0.81)))
        sd_tip.append(fit.fit.tip_sd)
        chi2.append(fit.shape_chi2)
        poly = fit_clamped_joint(left, right, np.zeros((0, 2)), np.zeros((0, 2)), 8, 0.81, CLAMP_M)
        assert not isinstance(poly, str)
        sd_poly.append(poly.rotation_sd_rad)
    for err, sd in ((axis, sd_axis), (tip, sd_tip)):
        ratio = float(np.std(err) / np.mean(sd))
        assert 0.8 < ratio < 1.2, ratio
    assert np.mean(sd_axis) < 0.6 * np.mean(sd_poly)
    # chi2(7): mean 7, sd of the mean of 120 ~ 0.34.
    assert 6.0 < np.mean(chi2) < 8.0, np.mean(chi2)
    assert np.max(chi2) < 30.0
    left, right = _edges(_static_tip_load, rng, sigma)
    fit, _ = _joint_modes(left, right, 0.0)
    assert fit.shape_chi2 > 24.3, fit.shape_chi2  # beyond chi2(7)'s 0.999 quantile


def test_long_run_inflation_counts_what_does_not_cancel() -> None:
    """A first-order process keeps (nearly) its lag-1 factor; a slow periodic wave (an
    edge's pixel-phase error, rho_1 ~ 0.8) whose lobes cancel in a smooth sum is not
    counted as the lag-1 form's ninefold variance."""
    rng = np.random.default_rng(5)
    rho = 0.5
    x = np.zeros(20000)
    for i in range(1, len(x)):
        x[i] = rho * x[i - 1] + rng.standard_normal()
    # Bartlett's window at 64 lags leaves ~4/64 of the sum's tail: within 10 %.
    assert math.isclose(long_run_inflation(x), (1 + rho) / (1 - rho), rel_tol=0.1)
    assert long_run_inflation(rng.standard_normal(20000)) < 1.1
    wave = np.sin(2 * np.pi * np.arange(800) / 12.0) + 0.2 * rng.standard_normal(800)
    assert correlation_inflation(wave) > 7.0
    assert long_run_inflation(wave) < 1.5


def test_long_run_inflation_of_each_length_against_direct_sums() -> None:
    """Edges of different lengths sum different numbers of lags (``K = min(64, N / 4)``,
    Bartlett's window over ``K`` cached per ``K``): each factor, asked for in an order
    that revisits lengths, equals the autocorrelations summed directly (an independent
    code: no transform), and the many-span form is their largest."""
    rng = np.random.default_rng(23)
    spans = []
    for n, rho in ((1000, 0.6), (40, 0.3), (200, -0.2), (36, 0.7), (1000, 0.1)):
        x = np.zeros(n)
        for i in range(1, n):
            x[i] = rho * x[i - 1] + rng.standard_normal()
        spans.append(x)

    def direct(x: np.ndarray) -> float:
        k_max = min(64, len(x) // 4)
        den = float(x @ x)
        acf = [float(x[k:] @ x[:-k]) / den for k in range(1, k_max + 1)]
        weights = [1.0 - k / (k_max + 1.0) for k in range(1, k_max + 1)]
        return max(1.0, 1.0 + 2.0 * sum(w * r for w, r in zip(weights, acf, strict=True)))

    for x in spans + spans[::-1]:
        assert math.isclose(long_run_inflation(x), direct(x), rel_tol=1e-12, abs_tol=1e-12)
    assert math.isclose(long_run_inflation_max(spans), max(direct(x) for x in spans), rel_tol=1e-12)


def _normal_edges(slope_of_a, b_of_a, half_w, n=800):
    """Edge points half the width either side of a centre line along its normal, read
    (as an edge scan does) at the a of each point."""
    a = np.linspace(0.03, 0.81, n)
    th = np.arctan(slope_of_a(a))
    out = []
    for side in (1.0, -1.0):
        pa = a - side * half_w * np.sin(th)
        pb = b_of_a(a) + side * half_w * np.cos(th)
        out.append(np.column_stack([pa, pb]))
    return out


def test_a_steep_beams_edges_are_its_centre_line_offset_along_the_normal() -> None:
    """A tip 155 mm aside (slope 0.28 at the tip: the synthetic bench at 2.35 Hz): its
    edges lie (w/2) / cos(theta) across the axis from its centre line, 0.4 mm more at
    the tip than at the root. With a constant width the fit leaves that in the
    residuals, in runs (which the damaged-frame check refuses); with the edges' slope
    the residuals vanish and the centre line is the true one."""
    tip = 0.155

    def b_of_a(a):
        x = a / L_M
        return tip * (3 * x**2 - x**3) / 2

    def slope(a):
        x = a / L_M
        return tip * (6 * x - 3 * x**2) / (2 * L_M)

    left, right = _normal_edges(slope, b_of_a, W_M / 2)
    none = np.zeros((0, 2))
    plain = fit_clamped_joint(left, right, none, none, 8, 0.81, CLAMP_M)
    steep = fit_clamped_joint(left, right, none, none, 8, 0.81, CLAMP_M, edge_slope=slope)
    assert not isinstance(plain, str) and not isinstance(steep, str)
    assert plain.fit.rms > 2e-5 and plain.fit.edge_rho > 0.95
    # What remains: the curvature's (w/2)^2 sin^2(theta) b'' / 2, the same on both
    # edges, below 2 micrometres here.
    assert steep.fit.rms < 1e-6
    a = np.linspace(0.05, 0.81, 20)
    np.testing.assert_allclose(steep.fit.centre(a), b_of_a(a), atol=3e-6)
    assert abs(steep.fit.width - W_M) < 1e-6


def test_orthonormal_rows_span_the_rows_in_order_against_numpy_qr() -> None:
    """The modal fit's shape test projects on orthonormal rows: checked against LAPACK's
    QR (an independent code) on rows unlike the fit's (random, one nearly and one
    exactly dependent), the dependent one dropped and the first rows counted."""
    from vision.centreline import _orthonormal_rows

    rng = np.random.default_rng(41)
    x = rng.standard_normal((9, 1300))
    x[3] = x[1] + 1e-6 * rng.standard_normal(1300)  # nearly dependent: kept
    x[6] = 2.0 * x[0] - x[2]  # dependent: dropped
    q, n_first = _orthonormal_rows(x, 4)
    assert q.shape == (8, 1300) and n_first == 4
    np.testing.assert_allclose(q @ q.T, np.eye(8), atol=1e-13)
    # Row k of q spans what rows 0..k add, in order: the same as QR's columns up to sign.
    kept = np.delete(x, 6, axis=0)
    ref, r = np.linalg.qr(kept.T)
    sign = np.sign(np.diag(r))
    np.testing.assert_allclose(q, (ref * sign).T, atol=1e-9)
    # Every row of x lies in their span.
    np.testing.assert_allclose((x @ q.T) @ q, x, atol=1e-10 * np.abs(x).max())
    q0, n0 = _orthonormal_rows(np.zeros((2, 5)), 2)
    assert q0.shape[0] == 0 and n0 == 0


@pytest.mark.parametrize("modes", [0, 4])
def test_the_lateral_beyond_the_last_edge_point_states_its_scatter(modes: int) -> None:
    """The tip lies beyond the last edge point along the tangent there (``ext``): over
    noise draws, the scatter of the centre line's value plus ``ext`` times its slope at
    ``a_max`` lies within what :meth:`CentreFit.tip_sd_beyond` states, for the polynomial
    and the modes (the polynomial's own sd at ``a_max`` fell short)."""
    ext, draws, sigma = 0.03, 400, 0.05e-3
    kw = {"modes": modes, "beam_length": L_M} if modes else {}
    values, stated, own = [], [], []
    for k in range(draws):
        rng = np.random.default_rng(100 + k)
        left, right = _edges(_static_tip_load, rng, sigma, n=400)
        ha, hb = _hub_edges(rng, sigma, length_m=0.2, n=100)
        fit = fit_clamped_joint(left, right, ha, hb, 8, 0.81, CLAMP_M, **kw)
        assert not isinstance(fit, str)
        c = fit.fit.centre
        at = np.array([0.81])
        values.append(float(c(at)[0]) + ext * float(c.deriv(at)[0]))
        stated.append(fit.fit.tip_sd_beyond(ext))
        own.append(fit.fit.tip_sd)
    scatter = float(np.std(values, ddof=1))
    # The sd of a sample sd from 400 draws is ~3.5 % of it: 4 sd of that. (The value's
    # own sd alone gave the polynomial 1.16 of it: the slope's share over 30 mm.)
    assert scatter < 1.14 * float(np.mean(stated)), (scatter, np.mean(stated), np.mean(own))


def test_arc_maps_are_kept_per_centre_line_and_end() -> None:
    """``arc_map`` keeps its table on the centre line, by end: asked again for the same
    end it gives the same table; another end, or another centre line with the same end,
    gets its own, equal to one computed afresh."""
    from vision.centreline import CentreLine, _arc_map, arc_map

    bent = CentreLine(np.array([0.0, 0.0, 0.08, -0.03]), 0.8)
    straight = CentreLine(np.array([0.0, 0.0, 0.0, 0.0]), 0.8)
    first = arc_map(bent, 0.8)
    assert arc_map(bent, 0.8) is first
    for centre, end in ((bent, 0.7), (straight, 0.8), (bent, 0.8)):
        got, fresh = arc_map(centre, end), _arc_map(centre, end)
        for name in ("a", "s", "corr"):
            np.testing.assert_array_equal(getattr(got, name), getattr(fresh, name))
    assert arc_map(straight, 0.8).s[-1] < first.s[-1]  # the bent line is the longer
    assert arc_map(bent, 0.7).a[-1] < first.a[-1]


def _same_fit(a, b) -> None:
    """Two :class:`JointFit` results equal bit for bit (their numbers and centre lines)."""
    assert not isinstance(a, str) and not isinstance(b, str)
    for name in ("rotation_rad", "rotation_sd_rad", "hub_width", "hub_offset", "hub_rms"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    np.testing.assert_array_equal(a.shape_chi2, b.shape_chi2)
    np.testing.assert_array_equal(a.inliers, b.inliers)
    for name in ("width", "rms", "tip_sd", "root_slope_rad", "edge_rho", "outlier_fraction"):
        np.testing.assert_array_equal(getattr(a.fit, name), getattr(b.fit, name))
    at = np.linspace(0.0, 0.85, 37)
    np.testing.assert_array_equal(a.fit.centre(at), b.fit.centre(at))
    np.testing.assert_array_equal(a.fit.centre.deriv(at), b.fit.centre.deriv(at))
    np.testing.assert_array_equal(a.fit.extrapolation_var(0.02), b.fit.extrapolation_var(0.02))


def test_fits_sharing_a_points_memo_are_the_fits_without_it() -> None:
    """A modal fit and its references (the polynomial on its inliers, two more modes)
    sharing a :class:`PointsMemo` of their points give what each gives alone, bit for
    bit (the more-modes fit computes only the modes it adds)."""
    from vision.centreline import PointsMemo, cantilever_modes_t

    rng = np.random.default_rng(21)
    for k in range(3):
        pose = _load_pose(rng)
        left, right, _ = _material_edges(pose, rng, 3e-5)
        ha, hb = _hub_edges(rng, 3e-5, length_m=0.2, n=80) if k else (np.zeros((0, 2)),) * 2
        poly = fit_clamped_joint(left, right, ha, hb, 8, 0.81, CLAMP_M)
        assert not isinstance(poly, str)
        along, slope = poly.fit.centre, poly.fit.centre.deriv
        kw = {"along": along, "edge_slope": slope, "beam_length": L_M}
        memo = PointsMemo()
        modal = fit_clamped_joint(left, right, ha, hb, 8, 0.81, CLAMP_M, modes=4, memo=memo, **kw)
        _same_fit(modal, fit_clamped_joint(left, right, ha, hb, 8, 0.81, CLAMP_M, modes=4, **kw))
        assert not isinstance(modal, str)
        ref_kw = {"edge_slope": slope, "inliers": modal.inliers}
        ref = fit_clamped_joint(left, right, ha, hb, 8, 0.81, CLAMP_M, memo=memo, **ref_kw)
        _same_fit(ref, fit_clamped_joint(left, right, ha, hb, 8, 0.81, CLAMP_M, **ref_kw))
        more_kw = {**kw, "inliers": modal.inliers}
        more = fit_clamped_joint(
            left, right, ha, hb, 8, 0.81, CLAMP_M, modes=6, memo=memo, **more_kw
        )
        _same_fit(
            more, fit_clamped_joint(left, right, ha, hb, 8, 0.81, CLAMP_M, modes=6, **more_kw)
        )
    # six modes from four and two: the same rows as six at once
    x = np.linspace(0.0, 1.1, 501)
    np.testing.assert_array_equal(
        np.concatenate([cantilever_modes_t(x, 4), cantilever_modes_t(x, 6)[4:]]),
        cantilever_modes_t(x, 6),
    )
