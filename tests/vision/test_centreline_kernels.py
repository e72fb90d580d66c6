"""The centre-line fit's compiled kernels against the numpy forms they replaced (kept here,
only as the reference): equal to rounding and equal in every decision.

Tolerances: a kernel sums in another order than numpy (BLAS's dot against BLAS's gemm,
loops against pairwise sums): each sum of N terms differs by at most ~N eps of the sum of
the terms' magnitudes, ~1e-12 relative for the N ~ 2000 points here; solutions of the
normal equations add cond(gram) to that, kept small by the well-conditioned test bases.
Medians, selections and the inliers are decisions: equal exactly."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.typing import NDArray

from vision import centreline as cl
from vision.sampling import median


# -- the numpy forms replaced (the reference) -------------------------------------------
def _basis_t_ref(u: NDArray[np.float64], degree: int) -> NDArray[np.float64]:
    x = 2.0 * u - 1.0
    v = np.empty((degree - 1, len(u)))
    v[0] = x * 0 + 1
    if degree > 2:
        v[1] = x
    for i in range(2, degree - 1):
        v[i] = (v[i - 1] * x * (2 * i - 1) - v[i - 2] * (i - 1)) / i
    v *= u * u
    return v


def _wlstsq_ref(a_t: NDArray[np.float64], b: NDArray[np.float64], w: NDArray[np.float64]):
    aw = a_t * w
    return np.linalg.solve(aw @ a_t.T, aw @ b)


def _group_scales_ref(r, groups, keep, sig) -> None:
    for g in groups:
        rg = r[g] if keep is None else r[g][keep[g]]
        if len(rg):
            sig[g] = 1.4826 * median(np.abs(rg), overwrite_input=True) + 1e-12
        else:
            sig[g] = 1.0


def _irls_ref(a_t, b, groups, inliers=None):
    n_all = len(b)
    w = np.ones(n_all)
    keep = np.ones(n_all, dtype=bool)
    sig = np.ones(n_all)
    given = inliers is not None
    if given:
        keep = np.asarray(inliers, dtype=bool).copy()
        r = b - _wlstsq_ref(a_t, b, keep.astype(np.float64)) @ a_t
        _group_scales_ref(r, groups, keep, sig)
    for it in range(0 if given else 5):
        coef = _wlstsq_ref(a_t, b, w / sig**2)
        r = b - coef @ a_t
        _group_scales_ref(r, groups, None if it == 0 else keep, sig)
        z = r / (cl.TUKEY_C * sig)
        inside = np.abs(z) < 1.0
        w = np.where(inside, (1.0 - z * z) ** 2, 0.0)
        if it >= 2 and bool((inside == keep).all()):
            break
        keep = inside
    return keep, sig


def _final_ref(a_t, b, groups, keep, sig, p_beam):
    wk = np.zeros(len(b))
    r = b - _wlstsq_ref(a_t, b, np.where(keep, 1.0 / sig**2, 0.0)) @ a_t
    for g in groups:
        kg = keep[g]
        nk = int(np.count_nonzero(kg))
        dof = max(nk - (p_beam if g.start == 0 else 2), 1)
        v = float(np.sum(r[g][kg] ** 2)) / dof if nk else 1.0
        wk[g][kg] = 1.0 / max(v, 1e-18)
    aw = a_t * wk
    gram = aw @ a_t.T
    coef = np.linalg.solve(gram, aw @ b)
    return coef, b - coef @ a_t, np.linalg.inv(gram)


def _long_run_max_ref(spans, max_lag=cl.LONG_RUN_LAGS):
    spans = [x for x in spans if len(x) >= 8]
    if not spans:
        return 1.0
    n_max = max(len(x) for x in spans)
    size = 1 << math.ceil(math.log2(n_max + min(max_lag, n_max // 4) + 1))
    stack = np.zeros((len(spans), size))
    for i, x in enumerate(spans):
        stack[i, : len(x)] = x
    f = np.fft.rfft(stack, axis=1)
    acov = np.fft.irfft(f * np.conj(f), size, axis=1)
    best = 1.0
    for i, x in enumerate(spans):
        den = float(acov[i, 0])
        if den <= 0:
            continue
        k_max = int(min(max_lag, len(x) // 4))
        bart = 1.0 - np.arange(1, k_max + 1) / (k_max + 1.0)
        best = max(best, 1.0 + 2.0 * float(bart @ acov[i, 1 : k_max + 1]) / den)
    return best


def _orthonormalise_ref(rows, n_first):
    q = np.empty_like(rows)
    k = 0
    kept_first = 0
    for i in range(len(rows)):
        v = rows[i]
        norm0 = float(np.sqrt(v @ v))
        if norm0 == 0.0:
            continue
        for _ in range(2):
            if k:
                v -= (q[:k] @ v) @ q[:k]
        norm = float(np.sqrt(v @ v))
        if norm <= 1e-9 * norm0:
            continue
        q[k] = v / norm
        k += 1
        kept_first += i < n_first
    return q[:k], kept_first


# -- test problems: a joint fit's design (beam edges, hub edges), sizes not beambench's --
def _joint_problem(rng, nl=517, nr=503, nha=61, nhb=59, degree=7, outliers=0.04):
    n_beam = nl + nr
    n_all = n_beam + nha + nhb
    p = degree - 1
    n_coef = 4 + p
    a = np.concatenate(
        [
            np.sort(rng.uniform(0.02, 0.7, nl)),
            np.sort(rng.uniform(0.02, 0.7, nr)),
            np.sort(rng.uniform(-0.08, 0.0, nha)),
            np.sort(rng.uniform(-0.08, 0.0, nhb)),
        ]
    )
    a_t = np.zeros((n_coef, n_all))
    a_t[0, :nl], a_t[0, nl:n_beam] = 0.5, -0.5
    a_t[1] = a + 0.043
    a_t[2, n_beam : n_beam + nha] = 1.0
    a_t[3, n_beam + nha :] = 1.0
    a_t[4:, :n_beam] = cl._basis_t(a[:n_beam] / 0.7, degree)
    coef = np.concatenate([[0.021, 0.003, 0.011, -0.009], 0.01 * rng.standard_normal(p)])
    b = coef @ a_t + 2e-5 * rng.standard_normal(n_all)
    bad = rng.random(n_all) < outliers
    b[bad] += rng.uniform(-3e-3, 3e-3, int(bad.sum()))
    lo = np.zeros(n_coef, dtype=np.int64)
    hi = np.full(n_coef, n_beam, dtype=np.int64)
    hi[1] = n_all
    lo[2], hi[2] = n_beam, n_beam + nha
    lo[3], hi[3] = n_beam + nha, n_all
    groups = [slice(0, n_beam), slice(n_beam, n_all)]
    ends = np.array([n_beam, n_all], dtype=np.int64)
    return a_t, b, lo, hi, groups, ends


def test_basis_kernel_is_numpys_legendre_recurrence_exactly() -> None:
    rng = np.random.default_rng(11)
    for degree in (2, 3, 5, 8, 11):
        for n in (0, 1, 7, 1333):
            u = rng.uniform(-0.1, 1.2, n)
            np.testing.assert_array_equal(cl._basis_t(u, degree), _basis_t_ref(u, degree))


def test_lu_kernels_solve_and_invert_as_numpy_does() -> None:
    rng = np.random.default_rng(5)
    for k in (1, 2, 6, 11):
        m = rng.standard_normal((k, k)) + 3 * np.eye(k)
        rhs = rng.standard_normal(k)
        lu, piv, ok = cl._lu_k(m)
        assert ok
        np.testing.assert_allclose(cl._lu_solve_k(lu, piv, rhs), np.linalg.solve(m, rhs), 1e-12)
        np.testing.assert_allclose(cl._lu_inv_k(lu, piv), np.linalg.inv(m), 1e-12, 1e-14)
    # a zero column: singular, where LAPACK's LU reports it (np.linalg raises)
    m = rng.standard_normal((4, 4))
    m[:, 2] = 0.0
    assert not cl._lu_k(m)[2]
    a_t = rng.standard_normal((3, 20))
    a_t[1] = 0.0  # a design row of zeros: a zero row and column in the normal matrix
    with pytest.raises(np.linalg.LinAlgError):
        cl._wlstsq(a_t, np.ones(20), np.ones(20))


def test_normal_equations_on_the_nonzero_ranges_equal_the_full_products() -> None:
    rng = np.random.default_rng(6)
    a_t, b, lo, hi, _, _ = _joint_problem(rng)
    w = rng.random(len(b))
    w[rng.random(len(b)) < 0.1] = 0.0
    k = len(a_t)
    gram, rhs = np.empty((k, k)), np.empty(k)
    cl._normal_k(a_t, lo, hi, b, w, gram, rhs)
    aw = a_t * w
    ref_g, ref_r = aw @ a_t.T, aw @ b
    scale = np.sqrt(np.outer(np.diag(ref_g), np.diag(ref_g)))
    assert np.all(np.abs(gram - ref_g) <= 1e-12 * scale)
    assert np.all(np.abs(rhs - ref_r) <= 1e-12 * np.sqrt(np.diag(ref_g) * float(w @ b**2)))
    coef = rng.standard_normal(k)
    np.testing.assert_allclose(
        cl._residuals_k(a_t, lo, hi, b, coef), b - coef @ a_t, rtol=0, atol=1e-13
    )


@pytest.mark.parametrize("seed", range(6))
def test_irls_kernel_keeps_the_same_points_as_the_numpy_loop(seed: int) -> None:
    rng = np.random.default_rng(100 + seed)
    a_t, b, lo, hi, groups, ends = _joint_problem(
        rng, nl=300 + 37 * seed, nr=290 + 41 * seed, outliers=0.02 + 0.02 * seed
    )
    keep_ref, sig_ref = _irls_ref(a_t, b, groups)
    keep, sig = np.ones(len(b), dtype=bool), np.ones(len(b))
    assert cl._irls_k(a_t, lo, hi, b, ends, keep, False, sig)
    np.testing.assert_array_equal(keep, keep_ref)
    np.testing.assert_allclose(sig, sig_ref, rtol=1e-10)
    assert 0 < np.count_nonzero(~keep) < 0.2 * len(b)
    # another fit's inliers: the scales from one fit to them
    given = keep_ref.copy()
    given[::17] = False
    keep_ref2, sig_ref2 = _irls_ref(a_t, b, groups, given)
    keep2, sig2 = given.copy(), np.ones(len(b))
    assert cl._irls_k(a_t, lo, hi, b, ends, keep2, True, sig2)
    np.testing.assert_array_equal(keep2, keep_ref2)
    np.testing.assert_allclose(sig2, sig_ref2, rtol=1e-10)
    # the final fit on them
    coef, r, inv, ok = cl._final_k(a_t, lo, hi, b, ends, keep, sig, a_t.shape[0] - 2)
    coef_ref, r_ref, inv_ref = _final_ref(a_t, b, groups, keep, sig, a_t.shape[0] - 2)
    assert ok
    np.testing.assert_allclose(coef, coef_ref, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(r, r_ref, rtol=0, atol=1e-12)
    np.testing.assert_allclose(inv, inv_ref, rtol=1e-9, atol=1e-9 * np.abs(inv_ref).max())


def test_span_statistics_against_the_transform_and_the_lag1_form() -> None:
    rng = np.random.default_rng(7)
    n = 900
    x = np.convolve(rng.standard_normal(n + 4), np.ones(5) / 5, "valid")
    keep = rng.random(n) > 0.1
    ends = np.array([311, 620, 627, n], dtype=np.int64)  # a span of 7: too short to count
    infl, rho = cl._span_stats_k(x, keep, ends, cl.LONG_RUN_LAGS)
    spans = [x[i:j][keep[i:j]] for i, j in zip([0, *ends[:-1]], ends, strict=True)]
    assert math.isclose(infl, _long_run_max_ref(spans), rel_tol=1e-12)
    assert math.isclose(rho, max(cl.lag1_correlation(s) for s in spans[:2]), rel_tol=1e-12)
    assert math.isclose(cl.long_run_inflation_max(spans), infl, rel_tol=1e-15)
    # all zero, too short, empty: 1 (and the lag-1 form's 0)
    z = np.zeros(40)
    assert cl._span_stats_k(z, np.ones(40, bool), np.array([20, 40]), 64) == (1.0, 0.0)
    assert cl.long_run_inflation_max([np.ones(7), np.zeros(0)]) == 1.0


def test_orthonormalise_kernel_against_the_numpy_gram_schmidt() -> None:
    rng = np.random.default_rng(8)
    u = np.sort(rng.uniform(0, 1, 777))
    x = np.vstack([np.ones_like(u), u, cl._basis_t(u, 6), cl._basis_t(u, 9)])
    x[4] = 0.0  # a zero row: skipped
    q_ref, k_ref = _orthonormalise_ref(x.copy(), 7)
    q, k = cl._orthonormalise(x.copy(), 7)
    assert k == k_ref and q.shape == q_ref.shape  # the same rows dropped
    np.testing.assert_allclose(q, q_ref, rtol=0, atol=1e-10)
    np.testing.assert_allclose(q @ q.T, np.eye(len(q)), rtol=0, atol=1e-13)


def test_free_slope_kernel_against_the_gathered_least_squares() -> None:
    rng = np.random.default_rng(9)
    n = 1234
    u = np.sort(rng.uniform(0.03, 1.0, n))
    ab = np.vstack([np.where(np.arange(n) % 2, 0.5, -0.5), np.ones(n), u, cl._basis_t(u, 7)])
    y = 0.01 * u**2 + 1e-5 * rng.standard_normal(n)
    kb = rng.random(n) > 0.07
    slope, s2, inv22, ok = cl._free_slope_k(ab, y, kb)
    abk, yb = ab[:, kb], y[kb]
    gram = abk @ abk.T
    free = np.linalg.solve(gram, abk @ yb)
    res = yb - free @ abk
    assert ok
    # Normal equations: each solution within ~cond(gram) eps |x| of the exact one (the
    # SVD's least squares); this basis has cond(gram) ~1e7, so the slope, a small
    # coefficient, agrees with numpy's to ~1e-7 of itself, both as near the exact.
    exact = np.linalg.lstsq(abk.T, yb, rcond=None)[0]
    bound = 10 * np.linalg.cond(gram) * np.finfo(float).eps * float(np.linalg.norm(exact))
    assert abs(free[2] - exact[2]) <= bound  # the reference meets it
    assert abs(slope - exact[2]) <= bound
    assert math.isclose(s2, float(res @ res) / (len(yb) - len(free)), rel_tol=1e-9)
    assert math.isclose(inv22, float(np.linalg.inv(gram)[2, 2]), rel_tol=1e-9)


def _modes_ref(x, n_modes, derivative=0):
    beta, sigma, big = cl._mode_constants(n_modes)
    bx = beta[:, None] * x[None, :]
    grow = np.exp(bx - beta[:, None])
    decay = np.exp(-bx)
    b_, s_ = big[:, None], sigma[:, None]
    if derivative == 0:
        return 0.5 * (b_ * grow + (1 + s_) * decay) - np.cos(bx) + s_ * np.sin(bx)
    return beta[:, None] * (0.5 * (b_ * grow - (1 + s_) * decay) + np.sin(bx) + s_ * np.cos(bx))


@pytest.mark.parametrize("n_modes", [1, 3, 6, 8])
def test_modes_kernel_against_the_numpy_formula(n_modes: int) -> None:
    # Each term within a few ulp of numpy's (e^-bx as e^-beta / e^(bx - beta): 2 ulp);
    # the terms are O(1) (O(beta) for the slope) before they cancel: a few 1e-16 of that.
    x = np.concatenate([[0.0, 1.0], np.random.default_rng(n_modes).uniform(-0.05, 1.2, 999)])
    for d in (0, 1):
        scale = cl._mode_constants(n_modes)[0][:, None] ** d
        got, ref = cl.cantilever_modes_t(x, n_modes, d), _modes_ref(x, n_modes, d)
        assert np.all(np.abs(got - ref) <= 1e-14 * scale)
    assert cl.cantilever_modes_t(np.zeros(0), 3).shape == (3, 0)


def test_joint_kernel_statuses_are_the_numpy_checks() -> None:
    rng = np.random.default_rng(12)
    a_t, b, lo, hi, _, ends = _joint_problem(rng, nl=211, nr=205, nha=23, nhb=21)
    n_beam, n_all = 211 + 205, len(b)
    span_ends = np.array([211, n_beam, n_beam + 23, n_all], dtype=np.int64)
    u = a_t[1, :n_beam] - 0.043
    p_shape = a_t.shape[0] - 4
    keep, sig = np.ones(n_all, dtype=bool), np.ones(n_all)
    out = cl._joint_k(a_t, lo, hi, b, ends, span_ends, keep, False, sig, p_shape, 11, u)
    assert out[0] == 0 and np.isfinite(out[6])
    # another fit's inliers that leave one hub edge 2 points: status 2 (drop the hub)
    given = np.ones(n_all, dtype=bool)
    given[n_beam + 23 + 2 :] = False
    out = cl._joint_k(a_t, lo, hi, b, ends, span_ends, given, True, sig, p_shape, 11, u)
    assert out[0] == 2
    # ... and a right edge 10 points, below a minimum of 11: status 1 (too ragged)
    given = np.ones(n_all, dtype=bool)
    given[211 + 10 : n_beam] = False
    out = cl._joint_k(a_t, lo, hi, b, ends, span_ends, given, True, sig, p_shape, 11, u)
    assert out[0] == 1
    given[211 + 10] = True  # 11: enough; given inliers, no free-slope check
    out = cl._joint_k(a_t, lo, hi, b, ends, span_ends, given, True, sig, p_shape, 11, u)
    assert out[0] == 0 and math.isnan(out[6])
    # a design row of zeros: singular, status 3 (np.linalg would raise)
    a0 = a_t.copy()
    a0[5] = 0.0
    keep = np.ones(n_all, dtype=bool)
    assert cl._joint_k(a0, lo, hi, b, ends, span_ends, keep, False, sig, p_shape, 11, u)[0] == 3


def test_given_inliers_that_leave_a_hub_edge_two_points_fit_without_the_hub() -> None:
    rng = np.random.default_rng(13)
    a = np.sort(rng.uniform(0.02, 0.7, 300))
    shape = 0.004 * (a / 0.7) ** 2
    left = np.column_stack([a, shape + 0.009 + 2e-5 * rng.standard_normal(300)])
    right = np.column_stack([a, shape - 0.009 + 2e-5 * rng.standard_normal(300)])
    hub_x = np.linspace(-0.06, -0.01, 40)
    hub_a = np.column_stack([hub_x, 0.011 + 2e-5 * rng.standard_normal(40)])
    hub_b = np.column_stack([hub_x[:20], -0.011 + 2e-5 * rng.standard_normal(20)])
    given = np.ones(660, dtype=bool)
    given[642:] = False  # the second hub edge: 2 of its 20 points
    with_hub = cl.fit_clamped_joint(left, right, hub_a, hub_b, 7, 0.7, 0.05, inliers=given)
    none = np.zeros((0, 2))
    without = cl.fit_clamped_joint(left, right, none, none, 7, 0.7, 0.05)
    assert not isinstance(with_hub, str) and not isinstance(without, str)
    assert math.isnan(with_hub.hub_width) and math.isnan(without.hub_width)
    assert with_hub.rotation_rad == without.rotation_rad
    assert with_hub.fit.tip_sd == without.fit.tip_sd
