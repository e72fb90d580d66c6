"""The centre-line fit's compiled kernels against the numpy forms they replaced (kept here,
only as the reference): equal to rounding and equal in every decision.

Tolerances: a kernel sums in another order than numpy (BLAS's dot against BLAS's gemm,
loops against pairwise sums): each sum of N terms differs by at most ~N eps of the sum of
the terms' magnitudes, ~1e-12 relative for the N ~ 2000 points here; solutions of the
normal equations add cond(gram) to that, kept small by the well-conditioned test bases.
Medians, selections and the inliers are decisions: equal exactly."""

from __future__ import annotations

import math
from collections.abc import Callable

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


def _irls_ref(a_t, b, groups, inliers=None, hub_edges=()):
    """The inliers and scales, or None where a solve would have a hub edge (the slices
    ``hub_edges``) with fewer than ``cl.MIN_HUB_EDGE`` points."""
    n_all = len(b)
    w = np.ones(n_all)
    keep = np.ones(n_all, dtype=bool)
    sig = np.ones(n_all)
    given = inliers is not None

    def hub_short() -> bool:
        return any(np.count_nonzero(keep[h]) < cl.MIN_HUB_EDGE for h in hub_edges)

    if given:
        keep = np.asarray(inliers, dtype=bool).copy()
        if hub_short():
            return None
        r = b - _wlstsq_ref(a_t, b, keep.astype(np.float64)) @ a_t
        _group_scales_ref(r, groups, keep, sig)
    for it in range(0 if given else 5):
        if hub_short():
            return None
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


def _span_ends(a_t, lo, hi):
    """:func:`_joint_problem`'s edges' ends: the left edge's (where the width's row turns
    negative), the beam's, each hub edge's (its offset row's range)."""
    nl = int(np.argmax(a_t[0] < 0))
    return np.array([nl, hi[0], hi[2], hi[3]], dtype=np.int64)


def test_basis_kernel_is_numpys_legendre_recurrence_exactly() -> None:
    rng = np.random.default_rng(11)
    for degree in (2, 3, 5, 8, 11):
        for n in (0, 1, 7, 1333):
            u = rng.uniform(-0.1, 1.2, n)
            np.testing.assert_array_equal(cl._basis_t(u, degree), _basis_t_ref(u, degree))


def test_basis_kernel_is_the_legvander_basis_exactly() -> None:
    # (the fit's end covariance takes its one-point basis from the kernel)
    rng = np.random.default_rng(12)
    for degree in (2, 3, 5, 8, 11):
        for n in (1, 7, 1333):
            u = rng.uniform(-0.1, 1.2, n)
            np.testing.assert_array_equal(cl._basis_t(u, degree), cl._basis(u, degree).T)


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
    span_ends = _span_ends(a_t, lo, hi)
    keep_ref, sig_ref = _irls_ref(a_t, b, groups)
    keep, sig = np.ones(len(b), dtype=bool), np.ones(len(b))
    assert cl._irls_k(a_t, lo, hi, b, ends, span_ends, keep, False, sig) == 0
    np.testing.assert_array_equal(keep, keep_ref)
    np.testing.assert_allclose(sig, sig_ref, rtol=1e-10)
    assert 0 < np.count_nonzero(~keep) < 0.2 * len(b)
    # another fit's inliers: the scales from one fit to them
    given = keep_ref.copy()
    given[::17] = False
    keep_ref2, sig_ref2 = _irls_ref(a_t, b, groups, given)
    keep2, sig2 = given.copy(), np.ones(len(b))
    assert cl._irls_k(a_t, lo, hi, b, ends, span_ends, keep2, True, sig2) == 0
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


def test_a_hub_edge_the_biweight_empties_is_status_2_as_in_the_numpy_loop() -> None:
    """A hub edge whose points lie in two runs 4 mm apart (a bar against half its
    length): the hub's scale comes from the other, straight edge (more points), and
    after the first solve every point of the stepped edge lies beyond the cut. The next
    solve would have no point to fix that edge's offset (singular: the numpy loop
    raises); the kernel stops before it with status 2 (the hub's edges not lines), as
    the numpy loop with the same rule does."""
    rng = np.random.default_rng(14)
    a_t, b, lo, hi, groups, ends = _joint_problem(rng, nha=67, nhb=53)
    span_ends = _span_ends(a_t, lo, hi)
    edge_b = np.arange(span_ends[2], span_ends[3])
    b[edge_b[a_t[1, edge_b] > 0.003]] -= 4e-3  # its half nearer the clamp (a > -0.04)
    hub_edges = (slice(span_ends[1], span_ends[2]), slice(span_ends[2], span_ends[3]))
    with pytest.raises(np.linalg.LinAlgError):
        _irls_ref(a_t, b, groups)
    assert _irls_ref(a_t, b, groups, hub_edges=hub_edges) is None
    keep, sig = np.ones(len(b), dtype=bool), np.ones(len(b))
    assert cl._irls_k(a_t, lo, hi, b, ends, span_ends, keep, False, sig) == 2
    assert np.count_nonzero(keep[edge_b]) == 0  # what the solve would have had
    n_beam = int(span_ends[1])
    u = a_t[1, :n_beam] - 0.043
    p_shape = a_t.shape[0] - 4
    keep = np.ones(len(b), dtype=bool)
    out = cl._joint_k(a_t, lo, hi, b, ends, span_ends, keep, False, sig, p_shape, 11, u)
    assert out[0] == 2
    # another fit's inliers with none of that edge's points: status 2, not singular
    given = np.ones(len(b), dtype=bool)
    given[edge_b] = False
    out = cl._joint_k(a_t, lo, hi, b, ends, span_ends, given, True, sig, p_shape, 11, u)
    assert out[0] == 2


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


# -- the joint fit's glue: the numpy form around the kernel (the reference) -------------
def _fit_joint_ref(
    left: NDArray[np.float64],
    right: NDArray[np.float64],
    hub_a: NDArray[np.float64],
    hub_b: NDArray[np.float64],
    degree: int,
    amax: float,
    clamp_from_pivot: float,
    modal: cl._Modes | None,
    edge_slope: Callable[[NDArray[np.float64]], NDArray[np.float64]] | None = None,
    inliers: NDArray[np.bool_] | None = None,
) -> cl.JointFit | str:
    """cl._fit_joint as it was in numpy around the kernel (the reference)."""
    nl, nr = len(left), len(right)
    nh = len(hub_a) + len(hub_b)
    use_hub = len(hub_a) >= 5 and len(hub_b) >= 5
    if not use_hub:
        hub_a, hub_b, nh = np.zeros((0, 2)), np.zeros((0, 2)), 0
    p_shape = degree - 1 if modal is None else modal.n
    n_beam = nl + nr
    if min(nl, nr) < degree + 4:
        return "beam edges too ragged"
    a_all = np.concatenate([left[:, 0], right[:, 0], hub_a[:, 0], hub_b[:, 0]])
    b = np.concatenate([left[:, 1], right[:, 1], hub_a[:, 1], hub_b[:, 1]])
    n_all = n_beam + nh
    n_coef = 2 + (2 if use_hub else 0) + p_shape
    a_t = np.zeros((n_coef, n_all))
    a_t[0, :nl], a_t[0, nl:n_beam] = 0.5, -0.5  # width
    if edge_slope is not None:  # half the width along the normal: 1 / cos(theta) across
        a_t[0, :n_beam] *= np.sqrt(1.0 + np.asarray(edge_slope(a_all[:n_beam])) ** 2)
    a_t[1] = a_all + clamp_from_pivot  # the axis's turn
    if use_hub:
        a_t[2, n_beam : n_beam + len(hub_a)] = 1.0
        a_t[3, n_beam + len(hub_a) :] = 1.0
    u = a_all[:n_beam] / amax
    if modal is None:
        a_t[n_coef - p_shape :, :n_beam] = cl._basis_t(u, degree)
    else:
        a_t[n_coef - p_shape :, :n_beam] = modal.basis_t(a_all[:n_beam])
        # The modes give the linear theory's deflection, int theta; an edge point lies
        # at int sin theta: the difference (~theta^3 / 6 per length, micrometres) added.
        b[:n_beam] += modal.correction(a_all[:n_beam])
    # The groups (the beam's edges, the hub's) by their ends; each group's scale and
    # the inliers chosen in one kernel (:func:`_joint_k`).
    ends = np.array([n_beam, n_all] if use_hub else [n_beam], dtype=np.int64)
    # Where each row of the design matrix is not 0: the width and the shape on the
    # beam's edges, the turn everywhere, each hub offset on its edge.
    lo = np.zeros(n_coef, dtype=np.int64)
    hi = np.full(n_coef, n_beam, dtype=np.int64)
    hi[1] = n_all
    if use_hub:
        lo[2], hi[2] = n_beam, n_beam + len(hub_a)
        lo[3], hi[3] = n_beam + len(hub_a), n_all
    keep = np.ones(n_all, dtype=bool)
    sig = np.ones(n_all)
    given = inliers is not None and len(inliers) == n_all
    if given:  # another fit's inliers: each group's scale from one fit to them
        keep = np.array(inliers, dtype=bool)
    span_ends = [nl, n_beam] + ([n_beam + len(hub_a), n_all] if use_hub else [])
    status, coef, r, gram_inv, infl, edge_rho, free2, s2_free, inv22 = cl._joint_k(
        a_t,
        lo,
        hi,
        b,
        ends,
        np.array(span_ends, dtype=np.int64),
        keep,
        given,
        sig,
        p_shape,
        degree + 4,
        u,
    )
    if status == 3:
        return "beam edges too few to fit the beam's shape"
    if status == 1:
        return "beam edges too ragged"
    if status == 2:  # the hub's edges are not straight lines: the beam's root alone
        empty = np.zeros((0, 2))
        return _fit_joint_ref(
            left,
            right,
            empty,
            empty,
            degree,
            amax,
            clamp_from_pivot,
            modal,
            edge_slope,
        )
    # With the inliers came the final fit (each group at its own variance, from its
    # residuals), the largest long-run inflation over the edges' inlier residuals and
    # the beam edges' largest lag-1 correlation.
    cov = gram_inv * infl
    g_tip = np.zeros(n_coef)
    if modal is None:
        g_tip[n_coef - p_shape :] = cl._tip_gradient(degree)[2:]
    else:
        g_tip[n_coef - p_shape :] = modal.basis_t(np.array([amax]))[:, 0]
    tip_sd = math.sqrt(max(float(g_tip @ cov @ g_tip), 0.0))

    def end_cov() -> tuple[float, float]:
        # The slope at a_max, by a difference of the shape functions (a step of 1e-6 of
        # the beam: the difference's own error ~1e-10 of the slope).
        h = 1e-6 * amax
        g_in = np.zeros(n_coef)
        if modal is None:
            g_in[n_coef - p_shape :] = cl._basis(np.array([1.0 - h / amax]), degree)[0]
        else:
            g_in[n_coef - p_shape :] = modal.basis_t(np.array([amax - h]))[:, 0]
        g_slope = (g_tip - g_in) / h
        return float(g_tip @ cov @ g_slope), float(g_slope @ cov @ g_slope)

    # The clamped prior's check, as in fit_centreline: the beam's inliers alone with a
    # free offset and a free slope at the root (not for a reference on another fit's
    # inliers, whose root is that fit's to check), fitted in :func:`_joint_k`: its rows
    # (width, offset, slope, shape) over the beam's points, the outliers at weight 0.
    kb = keep[:n_beam]
    n_kb = int(np.count_nonzero(kb))
    yb = b[:n_beam][kb]
    slope, slope_sd = math.nan, math.nan
    if not given:
        slope = free2 / amax
        slope_sd = math.sqrt(max(inv22 * s2_free * infl, 0.0)) / amax
    centre: cl.CentreLine | cl.ModalCentreLine
    if modal is None:
        centre = cl.CentreLine(cl._to_power(degree).T @ coef[n_coef - p_shape :], amax)
    else:
        centre = modal.centre(coef[n_coef - p_shape :])
    rb = r[:n_beam][kb]
    fit = cl.CentreFit(
        centre=centre,
        left=left[keep[:nl]],
        right=right[keep[nl:n_beam]],
        width=float(coef[0]),
        # np.mean's sum and division, without its dispatch
        rms=math.sqrt(float(np.add.reduce(rb * rb)) / len(rb)),
        tip_sd=tip_sd,
        root_slope_rad=slope,
        root_slope_sd_rad=slope_sd,
        edge_rho=edge_rho,
        outlier_fraction=1.0 - n_kb / n_beam,
        end_cov=end_cov,
    )
    shape_chi2, shape_dof = math.nan, 0
    if modal is not None and not given:  # a reference on another fit's inliers: none
        # The modes against the modes and the polynomial together, on the beam's inliers
        # (its own width, turn and shape): the residual's components along the extra
        # shapes, orthonormalised against the modes', are independent N(0, sigma^2)
        # when the modes hold the shape, however near the two spaces lie.
        # The rows gathered row-major: each row's products then run over contiguous
        # memory (half the time of the column-major gather's strided rows; the same
        # algorithm, its rounding in another order).
        n_m = 2 + p_shape
        x = np.empty((n_m + degree - 1, n_beam))
        x[0] = a_t[0, :n_beam]
        x[1] = a_t[1, :n_beam]
        x[2:n_m] = a_t[n_coef - p_shape :, :n_beam]
        cl._basis_t(u, degree, out=x[n_m:])
        q, n_m = cl._orthonormalise(x.compress(kb, axis=1), n_m)
        proj = q @ yb
        extra = proj[n_m:]
        shape_dof = len(extra)
        rss_u = float(yb @ yb - proj @ proj)
        s2_u = max(rss_u, 1e-30) / max(n_kb - len(q), 1)
        shape_chi2 = float(extra @ extra) / (s2_u * infl)
    if use_hub:
        rh = r[n_beam:][keep[n_beam:]]
        hub = (abs(float(coef[2] - coef[3])), 0.5 * float(coef[2] + coef[3]))
        hub_rms = math.sqrt(float(np.add.reduce(rh * rh)) / len(rh))
    else:
        hub, hub_rms = (math.nan, math.nan), math.nan
    return cl.JointFit(
        rotation_rad=float(coef[1]),
        rotation_sd_rad=math.sqrt(max(float(cov[1, 1]), 0.0)),
        fit=fit,
        hub_width=hub[0],
        hub_offset=hub[1],
        hub_rms=hub_rms,
        shape_chi2=shape_chi2,
        shape_dof=shape_dof,
        inliers=keep,
    )


def _joint_fit_problem(rng, nl, nr, nh):
    """Edges of a bent beam (a clamped quartic and a swing, not beambench's shapes) with
    outliers, and ``nh`` points on each hub edge."""
    amax = 0.74
    al, ar = np.sort(rng.uniform(0.03, amax, nl)), np.sort(rng.uniform(0.03, amax, nr))

    def shape(a):
        return 0.05 * (a / amax) ** 2 - 0.02 * (a / amax) ** 4 + 0.002 * (a + 0.04)

    left = np.column_stack([al, shape(al) + 0.008 + 3e-5 * rng.standard_normal(nl)])
    right = np.column_stack([ar, shape(ar) - 0.008 + 3e-5 * rng.standard_normal(nr)])
    for pts in (left, right):
        bad = rng.random(len(pts)) < 0.03
        pts[bad, 1] += rng.uniform(-2e-3, 2e-3, int(bad.sum()))
    hx = np.sort(rng.uniform(-0.09, -0.01, nh))
    hub_a = np.column_stack([hx, 0.002 * (hx + 0.04) + 0.012 + 3e-5 * rng.standard_normal(nh)])
    hub_b = np.column_stack([hx, 0.002 * (hx + 0.04) - 0.012 + 3e-5 * rng.standard_normal(nh)])
    return left, right, hub_a, hub_b, amax


def _assert_same_fit(got, ref) -> None:
    assert not isinstance(got, str) and not isinstance(ref, str)
    np.testing.assert_array_equal(got.inliers, ref.inliers)
    np.testing.assert_array_equal(got.fit.left, ref.fit.left)
    np.testing.assert_array_equal(got.fit.right, ref.fit.right)
    assert got.shape_dof == ref.shape_dof
    # sums in another order: ~1e-12 relative (the module's tolerance note), and the
    # solutions' cond(gram) on that
    for name in ("rotation_rad", "rotation_sd_rad", "hub_width", "hub_offset", "hub_rms"):
        np.testing.assert_allclose(getattr(got, name), getattr(ref, name), rtol=1e-10)
    for name in (
        "width",
        "rms",
        "tip_sd",
        "root_slope_rad",
        "root_slope_sd_rad",
        "edge_rho",
        "outlier_fraction",
    ):
        np.testing.assert_allclose(getattr(got.fit, name), getattr(ref.fit, name), rtol=1e-10)
    # The shape test's extra components are what is left of the polynomial's shapes
    # after the modes', which lie near them: the rounding of the projections grows by
    # the ratio of the rows' norms to what is left (up to ~1e3 here).
    np.testing.assert_allclose(got.shape_chi2, ref.shape_chi2, rtol=1e-8)
    a = np.linspace(0.0, 0.8, 9)
    np.testing.assert_allclose(got.fit.centre(a), ref.fit.centre(a), rtol=1e-10, atol=1e-14)
    assert got.fit.end_cov is not None and ref.fit.end_cov is not None
    np.testing.assert_allclose(got.fit.end_cov(), ref.fit.end_cov(), rtol=1e-9)


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("nh", [0, 40])
def test_fit_joint_kernel_against_the_numpy_glue(seed: int, nh: int) -> None:
    """:func:`_fit_joint` (the design, the statistics and the shape test in
    ``_fit_joint_core``) against its numpy form: the polynomial with and without the edges'
    slope, the modes along a first fit's centre line and without one, and the
    references on the modes' inliers (the polynomial, two more modes)."""
    rng = np.random.default_rng(300 + seed)
    left, right, ha, hb, amax = _joint_fit_problem(rng, 431 + 7 * seed, 419, nh)
    cfp, length, deg = 0.047, 0.79, 7 + seed
    poly = cl._fit_joint(left, right, ha, hb, deg, amax, cfp, None)
    _assert_same_fit(poly, _fit_joint_ref(left, right, ha, hb, deg, amax, cfp, None))
    assert not isinstance(poly, str)
    slope = poly.fit.centre.deriv
    args = (left, right, ha, hb, deg, amax, cfp)
    _assert_same_fit(cl._fit_joint(*args, None, slope), _fit_joint_ref(*args, None, slope))
    for along in (None, cl.arc_map(poly.fit.centre, amax)):
        modal = cl._Modes(4, length, amax, along)
        got = cl._fit_joint(*args, modal, slope)
        _assert_same_fit(got, _fit_joint_ref(*args, modal, slope))
        assert not isinstance(got, str) and math.isfinite(got.shape_chi2)
        more = cl._Modes(6, length, amax, along)
        for shape in (None, more):
            _assert_same_fit(
                cl._fit_joint(*args, shape, slope, got.inliers),
                _fit_joint_ref(*args, shape, slope, got.inliers),
            )


def test_centre_line_kernel_is_numpys_polyval_exactly() -> None:
    """:class:`CentreLine`'s value and slope (``_centre_k``) against the numpy form they
    replaced (``np.clip`` and ``polyval``): the same operations, equal exactly, inside,
    past both ends (the linear extension), at the ends, and NaN through."""
    from numpy.polynomial import polynomial as pw

    rng = np.random.default_rng(21)
    for degree in (2, 5, 9):
        coef = rng.standard_normal(degree + 1) * 0.01
        amax = 0.61 + 0.1 * rng.random()
        line = cl.CentreLine(coef, amax)
        a = np.concatenate([rng.uniform(-0.2, 0.9, 300), [0.0, -0.0, amax, np.nan]])
        ac = np.clip(a, 0.0, amax)
        u = ac / amax
        value = pw.polyval(u, line.coef) + (a - ac) * pw.polyval(u, line.dcoef)
        np.testing.assert_array_equal(line(a), value)
        np.testing.assert_array_equal(line.deriv(a), pw.polyval(u, line.dcoef))
        grid = a[:300].reshape(20, 15)  # any shape, as numpy's
        np.testing.assert_array_equal(line(grid), value[:300].reshape(20, 15))


def test_arc_kernels_are_the_numpy_forms_exactly() -> None:
    """``arc_length``, ``stations_to_a`` and ``_arc_map`` (their trapezoid sums in
    kernels) against the numpy forms they replaced, on a polynomial and a modal centre
    line: equal exactly (numpy's cumulative sums run in order, its trapezoid's sum is
    reproduced pairwise)."""
    rng = np.random.default_rng(22)
    lines = [
        cl.CentreLine(np.array([0.0, 0.0, 0.09, -0.04, 0.01]), 0.78),
        cl.ModalCentreLine(np.array([0.05, -0.004, 0.001]), 0.83, 0.79),
    ]
    for line in lines:
        for a_end in (0.8, 0.83 + 0.01 * rng.random()):
            a = np.linspace(0.0, a_end, cl._ARC_SAMPLES)
            want = float(np.trapezoid(np.sqrt(1.0 + line.deriv(a) ** 2), a))
            assert cl.arc_length(line, a_end) == want
            st = np.array([0.0, 0.2, 0.41, 0.6])
            a = np.linspace(0.0, max(a_end, float(st.max()) + 0.01), cl._ARC_SAMPLES)
            ds = np.sqrt(1.0 + line.deriv(a) ** 2)
            s = np.concatenate([[0.0], np.cumsum(0.5 * (ds[1:] + ds[:-1]) * np.diff(a))])
            np.testing.assert_array_equal(cl.stations_to_a(line, st, a_end), np.interp(st, s, a))
            got = cl._arc_map(line, a_end)
            if isinstance(line, cl.ModalCentreLine):
                a, s, slope = line._a, line._s, line._slope
            else:
                a = np.linspace(0.0, 1.1 * a_end, 401)
                slope = line.deriv(a)
                ds = np.sqrt(1.0 + slope**2)
                s = np.concatenate([[0.0], np.cumsum(0.5 * (ds[1:] + ds[:-1]) * np.diff(a))])
            th = np.arctan(slope)
            f = th - np.sin(th)
            corr = np.concatenate([[0.0], np.cumsum(0.5 * (f[1:] + f[:-1]) * np.diff(s))])
            np.testing.assert_array_equal(got.a, a)
            np.testing.assert_array_equal(got.s, s)
            np.testing.assert_array_equal(got.corr, corr)


def test_hub_straightness_kernel_against_the_numpy_form() -> None:
    """The hub edges' straightness (:func:`vision.centreline._hub_straightness`): each
    edge's fraction of points left out and its kept residuals' lag-1 correlation along
    it, against numpy's sort and dot products; an edge stepping out over a third of it
    correlates near 1, noise alone near 0."""
    rng = np.random.default_rng(41)
    for k in range(40):
        na, nb = int(rng.integers(2, 120)), int(rng.integers(2, 120))
        turn, c, offs = rng.normal(0, 1e-3), rng.uniform(0, 0.01), np.array([0.02, -0.02])
        pts, rs = [], []
        for n, h in ((na, offs[0]), (nb, offs[1])):
            a = rng.permutation(-np.linspace(0.01, 0.2, n)) if k % 2 else -np.linspace(0.01, 0.2, n)
            r = rng.normal(0, 2e-5, n) + (np.where(a < -0.13, 4e-3, 0.0) if k % 3 == 0 else 0.0)
            pts.append(np.column_stack([a, h + turn * (a + c) + r]))
            rs.append(r)
        keep = rng.uniform(size=na + nb) > (0.2 if k % 4 == 0 else 0.0)
        out, rho = cl._hub_straightness(pts[0], pts[1], keep, turn, c, offs)
        want_out, want_rho, start = 0.0, -1.0, 0
        for p, r in zip(pts, rs, strict=True):
            kk = keep[start : start + len(p)]
            start += len(p)
            want_out = max(want_out, 1.0 - np.count_nonzero(kk) / len(p))
            rk = r[kk][np.argsort(p[kk, 0], kind="stable")]
            want_rho = max(want_rho, cl.lag1_correlation(rk))
        assert out == pytest.approx(want_out, abs=1e-15), k
        assert rho == pytest.approx(want_rho, rel=1e-9, abs=1e-12), k
        if k % 3 == 0 and min(na, nb) > 40 and k % 4:
            assert rho > 0.9, (k, rho)


def test_arc_length_is_numpys_trapezoid_exactly() -> None:
    """The arc length's kernel against ``np.trapezoid`` of ``sqrt(1 + slope^2)``, for a
    polynomial centre line and a modal one, over several ends."""
    rng = np.random.default_rng(13)
    for _ in range(5):
        poly = cl.CentreLine(rng.normal(0, 0.05, 9), 0.8)
        modal = cl.ModalCentreLine(rng.normal(0, 0.02, 4), 0.835, 0.8)
        for centre in (poly, modal):
            for end in (0.3, 0.8, 0.86):
                a = cl.linspace(0.0, end, cl._ARC_SAMPLES)
                want = float(np.trapezoid(np.sqrt(1.0 + centre.deriv(a) ** 2), a))
                assert cl.arc_length(centre, end) == want


def test_arc_length_and_stations_share_their_slope_samples() -> None:
    """The arc length and the stations' axis coordinates from the slope samples kept
    on the centre line equal their fresh numpy forms, in either order, for ends the
    stations lie within and beyond."""
    rng = np.random.default_rng(14)
    stations = np.array([0.005, 0.204, 0.403, 0.603])
    for end in (0.8, 0.5):
        for first in ("arc", "stations"):
            centre = cl.CentreLine(rng.normal(0, 0.05, 9), 0.8)
            a = cl.linspace(0.0, max(end, float(stations.max()) + 0.01), cl._ARC_SAMPLES)
            y = np.sqrt(1.0 + centre.deriv(a) ** 2)
            s = np.concatenate([[0.0], np.cumsum(0.5 * (y[1:] + y[:-1]) * np.diff(a))])
            want_st = np.interp(stations, s, a)
            a2 = cl.linspace(0.0, end, cl._ARC_SAMPLES)
            want_arc = float(np.trapezoid(np.sqrt(1.0 + centre.deriv(a2) ** 2), a2))
            order = ("arc", "stations") if first == "arc" else ("stations", "arc")
            for what in order:
                if what == "arc":
                    assert cl.arc_length(centre, end) == want_arc
                else:
                    np.testing.assert_array_equal(cl.stations_to_a(centre, stations, end), want_st)
