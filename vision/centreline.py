"""The beam's centre line in the hub frame, fitted to both edges with the clamp's
boundary conditions.

A clamped beam leaves its clamp along the clamp's axis: in the hub frame (``a`` along the
hub axis from the clamp, ``b`` across it) its deflection has ``w'(0) = 0``, and a beam of
constant width has two edges that are the centre line offset by half the width. So one
shape is fitted to both edges at once,

    b(a) = o_edge + sum_k c_k u^2 P_k(2 u - 1),   u = a / a_max,  k = 0 .. degree - 2,

(``o_edge``: one constant per edge; the centre's offset is their mean, the width their
difference) by iteratively reweighted least squares with Tukey's biweight, so points on
clutter beside the beam do not pull it. The basis is a polynomial of ``degree`` with no
constant-slope term: that is the clamped-tangent prior. A second fit with a free slope
at the root checks the prior (a hub measured askew shows as a slope there).

:func:`fit_clamped_joint` can instead fit the beam's physical shape space: the first few
clamped-free (cantilever) modes, which have ``w(0) = w'(0) = 0`` and, at the free end,
zero moment and shear (``w'' = w''' = 0``). A real beam's deflection is the static
response to its distributed (inertial and applied) load, whose content in mode ``i``
falls as ``1 / beta_i^4``: five modes hold a smooth load's response to micrometres, with
about half the generic polynomial's noise on the axis. The measurer checks the physical
fit against the generic one and falls back on the latter when they disagree.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property, lru_cache
from typing import Any

import numpy as np
from numpy.polynomial import Legendre, Polynomial
from numpy.typing import NDArray

from vision.jit import kernel
from vision.sampling import median, median_nonnegative, numpy_sum

#: Tukey biweight tuning constant (95 % efficiency under Gaussian noise), in robust sigmas.
TUKEY_C = 4.685
#: The fewest points a hub edge keeps to be fitted as a straight line along the axis (its
#: offset from one, the line checked by the rest): fewer, at the end or in any pass of
#: the biweight (where its points may all fall beyond the cut and leave its offset
#: undetermined), and :func:`fit_clamped_joint` fits the beam's root alone.
MIN_HUB_EDGE = 3


class CentreLine:
    """Centre line ``b(a)`` on ``[0, a_max]`` as a power series in ``u = a / a_max``, with
    a linear extension past both ends (the tip is found just beyond the last edge point)."""

    def __init__(self, coef_u: NDArray[np.float64], amax: float) -> None:
        self.coef = np.ascontiguousarray(coef_u, dtype=np.float64)
        self.amax = float(amax)
        # d/da of the series in u = a / amax (numpy.polynomial's polyder, without its
        # generic machinery: this is built once per frame).
        self.dcoef = self.coef[1:] * np.arange(1, len(self.coef)) / self.amax
        self._arc_maps: dict[float, ArcMap] = {}  # arc_map's, by end
        self._slopes: dict[float, tuple[NDArray[np.float64], NDArray[np.float64]]] = {}

    def __call__(self, a: NDArray[np.float64]) -> NDArray[np.float64]:
        return self._eval(a, True)

    def deriv(self, a: NDArray[np.float64]) -> NDArray[np.float64]:
        return self._eval(a, False)

    def _eval(self, a: NDArray[np.float64], value: bool) -> NDArray[np.float64]:
        """The series (``value``) or its slope at ``a`` (:func:`_centre_k`)."""
        a = np.asarray(a, dtype=np.float64)
        flat = np.ascontiguousarray(a.reshape(-1))
        return _centre_k(flat, self.coef, self.dcoef, self.amax, value).reshape(a.shape)


# -- the physical shape space: clamped-free modes ---------------------------------------
@lru_cache(maxsize=4)
def cantilever_eigenvalues(n_modes: int) -> tuple[float, ...]:
    """``beta_i L`` of the first ``n_modes`` clamped-free modes: roots of
    ``cos(x) cosh(x) = -1`` (1.8751, 4.6941, 7.8548, ...), by Newton's method from the
    asymptote ``(i - 1/2) pi`` on ``cos(x) + 1 / cosh(x) = 0``."""
    out = []
    for i in range(1, n_modes + 1):
        x = (i - 0.5) * math.pi
        for _ in range(50):
            f = math.cos(x) + 1.0 / math.cosh(x)
            df = -math.sin(x) - math.tanh(x) / math.cosh(x)
            step = f / df
            x -= step
            if abs(step) < 1e-15 * x:
                break
        out.append(x)
    return tuple(out)


@lru_cache(maxsize=8)
def _mode_constants(n_modes: int) -> tuple[NDArray[np.float64], ...]:
    """``beta``, ``sigma`` and ``(1 - sigma) e^beta`` of the first ``n_modes`` modes, as
    :func:`cantilever_modes_t` uses them (read-only arrays)."""
    beta, sigma, big = [], [], []
    for b in cantilever_eigenvalues(n_modes):
        den = math.sinh(b) + math.sin(b)
        beta.append(b)
        sigma.append((math.cosh(b) + math.cos(b)) / den)
        one_minus = (math.sin(b) - math.cos(b) - math.exp(-b)) / den  # 1 - sigma
        big.append(one_minus * math.exp(b))
    out = tuple(np.array(v) for v in (beta, sigma, big))
    for v in out:
        v.setflags(write=False)
    return out


def cantilever_modes_t(
    x: NDArray[np.float64], n_modes: int, derivative: int = 0
) -> NDArray[np.float64]:
    """(n_modes, N) clamped-free mode shapes (or their ``derivative``-th derivative in
    ``x``, 0 or 1) at ``x = s / L``, normalised to 2 at the free end:
    ``cosh(bx) - cos(bx) - sigma (sinh(bx) - sin(bx))``, its growing and decaying
    exponentials taken apart so the higher modes keep their digits (:func:`_modes_k`)."""
    x = np.asarray(x, dtype=np.float64)
    if derivative not in (0, 1):
        raise ValueError(f"derivative must be 0 or 1, got {derivative}")
    beta, sigma, big = _mode_constants(n_modes)
    return _modes_k(np.ascontiguousarray(x, dtype=np.float64), beta, sigma, big, derivative)


@lru_cache(maxsize=16)
def _slope_modes(
    n_modes: int, beam_length: float, s_end: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The arc lengths ``s`` (m) a :class:`ModalCentreLine` is tabulated at, 0 ..
    ``s_end``, and the modes' slopes ``phi_k'(s / L)`` there (read-only): the same for
    every frame of a beam whose edges end short of its length."""
    s = np.linspace(0.0, s_end, ModalCentreLine._N)
    modes = cantilever_modes_t(s / beam_length, n_modes, 1)
    s.setflags(write=False)
    modes.setflags(write=False)
    return s, modes


class ModalCentreLine:
    """Centre line ``b(a)`` of an inextensible beam whose slope angle at arc length ``s``
    from the clamp is ``theta(s) = sum_k c_k phi_k'(s / L) / L`` (clamped-free modes: the
    linear theory's ``w' = theta``); the point at ``s`` lies at ``a(s) = int cos theta``,
    ``b(s) = int sin theta`` (the renderer's kinematics, and a real beam's). Tabulated on
    ``s`` and read at ``a`` (to ~1e-8 m), with a linear extension past ``amax`` like
    :class:`CentreLine`."""

    _N = 1601

    def __init__(self, coef: NDArray[np.float64], beam_length: float, amax: float) -> None:
        self.coef = np.asarray(coef, dtype=np.float64)
        self.beam_length = float(beam_length)
        self.amax = float(amax)
        self._arc_maps: dict[float, ArcMap] = {}  # arc_map's, by end
        self._slopes: dict[float, tuple[NDArray[np.float64], NDArray[np.float64]]] = {}

    @cached_property
    def _tables(self) -> tuple[NDArray[np.float64], ...]:
        # Tabulated at first use: a modal fit that its shape test refuses is never read.
        s, modes = _slope_modes(
            len(self.coef), self.beam_length, 1.1 * max(self.amax, self.beam_length)
        )
        th = (self.coef @ modes) / self.beam_length
        ds = np.diff(s)
        c, sn = np.cos(th), np.sin(th)
        a = np.concatenate([[0.0], np.cumsum(0.5 * (c[1:] + c[:-1]) * ds)])
        b = np.concatenate([[0.0], np.cumsum(0.5 * (sn[1:] + sn[:-1]) * ds)])
        return s, a, b, np.tan(th)

    @property
    def _s(self) -> NDArray[np.float64]:
        return self._tables[0]

    @property
    def _a(self) -> NDArray[np.float64]:
        return self._tables[1]

    @property
    def _b(self) -> NDArray[np.float64]:
        return self._tables[2]

    @property
    def _slope(self) -> NDArray[np.float64]:
        return self._tables[3]

    @cached_property
    def _b_end(self) -> float:
        return float(np.interp(self.amax, self._a, self._b))

    @cached_property
    def _d_end(self) -> float:
        return float(np.interp(self.amax, self._a, self._slope))

    def s_of_a(self, a: NDArray[np.float64]) -> NDArray[np.float64]:
        """Arc length from the clamp of the point at axis coordinate ``a``."""
        return np.asarray(np.interp(a, self._a, self._s))

    def __call__(self, a: NDArray[np.float64]) -> NDArray[np.float64]:
        a = np.asarray(a, dtype=np.float64)
        ac = np.clip(a, 0.0, self.amax)
        return np.asarray(np.interp(ac, self._a, self._b) + (a - ac) * self._d_end)

    def deriv(self, a: NDArray[np.float64]) -> NDArray[np.float64]:
        ac = np.clip(np.asarray(a, dtype=np.float64), 0.0, self.amax)
        return np.asarray(np.interp(ac, self._a, self._slope))


def arc_map(centre: CentreLine | ModalCentreLine, a_end: float) -> ArcMap:
    """Arc length and the large-slope correction along ``centre`` as functions of ``a``
    (tabulated to 1.1 ``a_end``). Kept on ``centre`` by ``a_end``: a frame's modal fit
    and its more-modes reference ask for the same one (a centre line's coefficients are
    not changed after it is made)."""
    cached = centre._arc_maps.get(a_end)
    if cached is None:
        if len(centre._arc_maps) >= 8:
            centre._arc_maps.clear()
        cached = centre._arc_maps[a_end] = _arc_map(centre, a_end)
    return cached


def _arc_map(centre: CentreLine | ModalCentreLine, a_end: float) -> ArcMap:
    """:func:`arc_map`, computed."""
    if isinstance(centre, ModalCentreLine):
        # (the tables' arc lengths are shared and read-only: a writable copy, so that
        # the kernel below compiles for one kind of array)
        a, s, slope = centre._a, centre._s.copy(), centre._slope
    else:
        a = linspace(0.0, 1.1 * a_end, 401)
        slope = centre.deriv(a)
        s = _cumulative_k(a, slope, True)
    th = np.arctan(slope)
    return ArcMap(a, s, _cumulative_k(s, th - np.sin(th), False))


@dataclass
class ArcMap:
    """Along a centre line, tabulated at axis coordinates ``a``: the arc length ``s``
    and ``corr = int_0^s (theta - sin theta)``, what the linear theory's deflection
    ``int theta`` exceeds the lateral position ``int sin theta`` by."""

    a: NDArray[np.float64]
    s: NDArray[np.float64]
    corr: NDArray[np.float64]

    def __call__(self, a: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.asarray(np.interp(a, self.a, self.s))

    def correction(self, a: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.asarray(np.interp(a, self.a, self.corr))


@dataclass
class CentreFit:
    """Result of :func:`fit_centreline` (hub frame, m).

    ``left``/``right``: the inlier edge points (N, 2) (a, b); ``width``: distance between
    the edges; ``rms``: RMS residual of the inliers; ``tip_sd``: standard uncertainty of
    the centre line at ``a_max`` (noise only, inflated for residuals correlated along the
    edge); ``root_slope_rad``: the slope at the clamp of a fit without the clamped prior
    (NaN for :func:`fit_clamped_joint`'s reference on another fit's ``inliers``).
    """

    centre: CentreLine | ModalCentreLine
    left: NDArray[np.float64]
    right: NDArray[np.float64]
    width: float
    rms: float
    tip_sd: float
    root_slope_rad: float
    #: standard uncertainty of ``root_slope_rad`` (NaN where not computed).
    root_slope_sd_rad: float = math.nan
    #: the largest lag-1 correlation of the residuals along either beam edge (NaN where
    #: not computed): near 1 when the edges depart from the fitted shape in runs (a shifted
    #: image block, an occlusion), not in noise.
    edge_rho: float = math.nan
    #: the fraction of the beam's edge points the biweight rejected (NaN where not
    #: computed).
    outlier_fraction: float = math.nan
    #: the covariance of the centre line's lateral (m) with its slope at ``a_max``, and
    #: the slope's variance, computed on demand (only the final fit's is asked for), for
    #: a tip found beyond the last edge point along the tangent (None: not computed).
    end_cov: Callable[[], tuple[float, float]] | None = field(
        default=None, repr=False, compare=False
    )

    def extrapolation_var(self, ext: float) -> float:
        """What the slope adds to the lateral's variance at ``a_max + ext`` along the end's
        tangent (m^2; 0 where ``end_cov`` is not computed)."""
        if self.end_cov is None:
            return 0.0
        cov_bs, var_s = self.end_cov()
        return 2.0 * ext * cov_bs + ext * ext * var_s

    def tip_sd_beyond(self, ext: float) -> float:
        """Standard uncertainty of the lateral at ``a_max + ext`` along the end's tangent."""
        return math.sqrt(max(self.tip_sd**2 + self.extrapolation_var(ext), 0.0))


@lru_cache(maxsize=8)
def _to_power(degree: int) -> NDArray[np.float64]:
    """(degree - 1, degree + 1): power-series coefficients in u of u^2 P_k(2u - 1)."""
    out = np.zeros((degree - 1, degree + 1))
    for k in range(degree - 1):
        p = Legendre.basis(k, domain=[0.0, 1.0]).convert(kind=Polynomial).coef
        out[k, 2 : 2 + len(p)] = p
    return out


@lru_cache(maxsize=8)
def _tip_gradient(degree: int) -> NDArray[np.float64]:
    """d centre(a_max) / d coefficients (the two edge offsets, then the shape)."""
    return np.concatenate([[0.5, 0.5], _basis(np.array([1.0]), degree)[0]])


def _basis(u: NDArray[np.float64], degree: int) -> NDArray[np.float64]:
    """(N, degree - 1) clamped shape functions u^2 P_k(2u - 1)."""
    leg = np.polynomial.legendre.legvander(2.0 * u - 1.0, degree - 2)
    return np.asarray(leg * (u * u)[:, None])


def _basis_t(
    u: NDArray[np.float64], degree: int, out: NDArray[np.float64] | None = None
) -> NDArray[np.float64]:
    """:func:`_basis` transposed, (degree - 1, N), built in that layout (numpy's own
    Legendre recurrence, so the same values); into ``out`` (C-contiguous) when given."""
    v = np.empty((degree - 1, len(u))) if out is None else out
    _basis_k(np.ascontiguousarray(u, dtype=np.float64), degree, v)
    return v


def lag1_correlation(res: NDArray[np.float64]) -> float:
    """Lag-1 autocorrelation of residuals ``res`` ordered along an edge (0 for fewer than
    4 or all zero)."""
    if len(res) < 4:
        return 0.0
    den = float(res @ res)
    return float(res[1:] @ res[:-1]) / den if den > 0 else 0.0


@kernel
def lag1_sums(res: NDArray[np.float64], n: int) -> tuple[float, float]:
    """The sums behind the lag-1 correlation of the first ``n`` residuals ``res``
    (ordered along an edge), in order: ``(sum r_i^2, sum r_i r_(i-1))``; the compiled
    kernels' form of :func:`lag1_correlation` (which numpy sums in another order)."""
    den, num = 0.0, 0.0
    for i in range(n):
        den += res[i] * res[i]
        if i:
            num += res[i] * res[i - 1]
    return den, num


def correlation_inflation(res: NDArray[np.float64]) -> float:
    """Variance factor for the mean of residuals ``res`` (ordered along an edge) that are
    correlated from one scan line to the next (JPEG blocks, interpolated plateaus):
    ``(1 + rho) / (1 - rho)`` for lag-1 correlation ``rho``, at least 1."""
    if len(res) < 4:
        return 1.0
    den = float(res @ res)
    if den <= 0:
        return 1.0
    rho = float(res[1:] @ res[:-1]) / den
    rho = min(max(rho, 0.0), 0.9)
    return (1.0 + rho) / (1.0 - rho)


#: Lags (scan lines) over which :func:`long_run_inflation` sums the residuals'
#: autocorrelation (at most a quarter of the edge's points).
LONG_RUN_LAGS = 64


def long_run_inflation(res: NDArray[np.float64], max_lag: int = LONG_RUN_LAGS) -> float:
    """Variance factor for smooth weighted sums (a fit's coefficients) of residuals
    ``res`` ordered along an edge: their spectral density at low frequency over their
    variance, ``1 + 2 sum_k (1 - k / (K + 1)) rho_k`` over lags ``k = 1 .. K`` (Bartlett's
    window, ``K = min(max_lag, N / 4)``), at least 1.

    The lag-1 form of :func:`correlation_inflation`, ``(1 + rho_1) / (1 - rho_1)``, is
    exact for a first-order process, but an edge nearly along the pixel grid leaves the
    edge estimator's pixel-phase error in the residuals: a slow periodic wave (``rho_1``
    near 0.8) whose lobes cancel in any smooth sum over several of its periods, which
    the lag-1 form counts as a ninefold variance. Summing the measured correlations
    over many lags counts what does not cancel."""
    return long_run_inflation_max([np.asarray(res, dtype=np.float64)], max_lag)


def long_run_inflation_max(spans: list[NDArray[np.float64]], max_lag: int = LONG_RUN_LAGS) -> float:
    """The largest :func:`long_run_inflation` over residual ``spans`` (one per edge),
    each by direct sums over the lags (a kernel)."""
    best = 1.0
    for x in spans:
        best = max(best, _long_run_k(np.ascontiguousarray(x, dtype=np.float64), max_lag))
    return best


def fit_centreline(
    left: NDArray[np.float64], right: NDArray[np.float64], degree: int, amax: float
) -> CentreFit | str:
    """Fit the clamped centre line to the two edges (N, 2) (a, b), hub frame, m.

    Returns a :class:`CentreFit`, or the reason (str) when the edges cannot carry it."""
    nl, nr = len(left), len(right)
    p = degree + 1
    if min(nl, nr) < p + 3:
        return "beam edges too ragged"
    u = np.concatenate([left[:, 0], right[:, 0]]) / amax
    b = np.concatenate([left[:, 1], right[:, 1]])
    # The design matrix transposed, (coefficients, points): weighting and products then
    # run along the points (with the points first each step loops over a short row).
    a_t = np.empty((degree + 1, nl + nr))
    a_t[0, :nl], a_t[0, nl:] = 1.0, 0.0
    a_t[1] = 1.0 - a_t[0]
    a_t[2:] = _basis_t(u, degree)
    w = np.ones(len(b))
    coef = np.zeros(a_t.shape[0])
    sig = math.inf
    # The biweight only chooses the inliers (the final fit below weighs them equally),
    # so the iterations stop once two in a row keep the same points.
    keep = np.ones(len(b), dtype=bool)
    for it in range(4):
        coef = _wlstsq(a_t, b, w)
        r = b - coef @ a_t
        if it == 0:
            sig = 1.4826 * median(np.abs(r)) + 1e-12
        else:
            sig = 1.4826 * median(np.abs(r[keep])) + 1e-12
        z = r / (TUKEY_C * sig)
        inside = np.abs(z) < 1.0
        w = np.where(inside, (1.0 - z * z) ** 2, 0.0)
        if it >= 2 and np.array_equal(inside, keep):
            break
        keep = inside
    if keep[:nl].sum() < p + 3 or keep[nl:].sum() < p + 3:
        return "beam edges too ragged"
    # Final fit: inliers, equal weights (the biweight only chose them). Its normal
    # matrix also gives the covariance, and bordered with the root-slope column, the
    # free-slope check below.
    ak, bk, uk = a_t[:, keep], b[keep], u[keep]
    gram, rhs = ak @ ak.T, ak @ bk
    coef = np.linalg.solve(gram, rhs)
    r = b - coef @ a_t
    dof = max(int(keep.sum()) - a_t.shape[0], 1)
    s2 = float(np.sum(r[keep] ** 2)) / dof
    infl = max(correlation_inflation(r[:nl][keep[:nl]]), correlation_inflation(r[nl:][keep[nl:]]))
    cov = np.linalg.inv(gram) * s2 * infl
    g = _tip_gradient(degree)
    tip_sd = math.sqrt(max(float(g @ cov @ g), 0.0))
    # The prior's check: the same inliers with a free slope at the root.
    p1 = gram.shape[0]
    gram_f = np.empty((p1 + 1, p1 + 1))
    gram_f[:p1, :p1] = gram
    gram_f[:p1, p1] = gram_f[p1, :p1] = ak @ uk
    gram_f[p1, p1] = uk @ uk
    slope = float(np.linalg.solve(gram_f, np.append(rhs, uk @ bk))[-1]) / amax
    centre_u = _to_power(degree).T @ coef[2:]
    centre_u[0] += 0.5 * (coef[0] + coef[1])
    return CentreFit(
        centre=CentreLine(centre_u, amax),
        left=left[keep[:nl]],
        right=right[keep[nl:]],
        width=float(coef[0] - coef[1]),
        rms=math.sqrt(float(np.mean(r[keep] ** 2))),
        tip_sd=tip_sd,
        root_slope_rad=slope,
    )


def _orthonormal_rows(x: NDArray[np.float64], n_first: int) -> tuple[NDArray[np.float64], int]:
    """Orthonormal rows spanning the rows of ``x`` (K, N), in order, by Gram-Schmidt run
    twice (orthogonal to rounding however near the rows lie; a kernel on a few long rows,
    where LAPACK's threaded QR stalls on a busy host). A row with
    less than 1e-9 of its norm left is dropped; also how many of the first ``n_first``
    rows were kept."""
    return _orthonormalise(np.array(x, dtype=np.float64), n_first)


def _orthonormalise(rows: NDArray[np.float64], n_first: int) -> tuple[NDArray[np.float64], int]:
    """:func:`_orthonormal_rows` on a float64 array of the caller's that it overwrites
    (no copy)."""
    q, k, kept_first = _orthonormalise_k(np.ascontiguousarray(rows), n_first)
    return q[:k], kept_first


def _wlstsq(a_t: NDArray[np.float64], b: NDArray[np.float64], w: NDArray[np.float64]) -> NDArray:
    """Weighted least squares with the design matrix transposed (coefficients, points).

    Normal equations of a small, well-conditioned basis (Legendre on [0, 1]), solved by
    LU with partial pivoting as ``np.linalg.solve`` does (:func:`_wls_k`): a tenth of the
    cost of an SVD solve, which matters at a frame rate."""
    k, n = a_t.shape
    lo, hi = np.zeros(k, dtype=np.int64), np.full(k, n, dtype=np.int64)
    coef, ok = _wls_k(
        np.ascontiguousarray(a_t), lo, hi, b, np.ascontiguousarray(w, dtype=np.float64)
    )
    if not ok:
        raise np.linalg.LinAlgError("Singular matrix")
    return coef


# -- compiled kernels (vision.jit): a fit is a few kernel calls, not hundreds of numpy
# calls. Each is the numpy form it replaced written out as loops (tests/vision/
# test_centreline_kernels.py keeps that form as the reference): the same products, the
# same decisions; only the order of the sums differs (rounding).


@kernel
def _dot_k(x: NDArray[np.float64], y: NDArray[np.float64]) -> float:
    """``x @ y`` (BLAS's dot, as numpy's ``@`` of two vectors calls it; 0 when empty)."""
    if x.shape[0] == 0:
        return 0.0
    return float(np.dot(x, y))


@kernel
def _normal_k(
    a_t: NDArray[np.float64],
    lo: NDArray[np.int64],
    hi: NDArray[np.int64],
    b: NDArray[np.float64],
    w: NDArray[np.float64],
    gram: NDArray[np.float64],
    rhs: NDArray[np.float64],
) -> None:
    """``aw = a_t * w``; ``gram = aw @ a_t.T``, ``rhs = aw @ b`` (into the arguments),
    where row ``i`` of ``a_t`` is 0 outside ``lo[i] .. hi[i]`` (the products of those
    exact zeros are left out of the sums: the same sums)."""
    k, n = a_t.shape
    aw = np.empty(n)
    for i in range(k):
        # each loop on views from 0 (numba then drops its negative-index check: SIMD)
        l, h = lo[i], hi[i]
        x, y, z = a_t[i, l:h], w[l:h], aw[l:h]
        for m in range(h - l):
            z[m] = x[m] * y[m]
        for j in range(i + 1):
            m0, m1 = max(lo[i], lo[j]), min(hi[i], hi[j])
            gram[i, j] = gram[j, i] = _dot_k(aw[m0:m1], a_t[j, m0:m1]) if m0 < m1 else 0.0
        rhs[i] = _dot_k(aw[lo[i] : hi[i]], b[lo[i] : hi[i]])


@kernel
def _lu_k(g: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.int64], bool]:
    """LU factors of ``g`` with partial pivoting (LAPACK getrf's algorithm, as
    ``np.linalg.solve`` and ``inv`` use it); False where a pivot is exactly 0 (where
    LAPACK reports the matrix singular)."""
    k = g.shape[0]
    lu = g.copy()
    piv = np.arange(k)
    for c in range(k):
        p = c
        best = abs(lu[c, c])
        for r in range(c + 1, k):
            if abs(lu[r, c]) > best:
                best = abs(lu[r, c])
                p = r
        if best == 0.0:
            return lu, piv, False
        if p != c:
            for j in range(k):
                t = lu[c, j]
                lu[c, j] = lu[p, j]
                lu[p, j] = t
            t2 = piv[c]
            piv[c] = piv[p]
            piv[p] = t2
        for r in range(c + 1, k):
            f = lu[r, c] / lu[c, c]
            lu[r, c] = f
            for j in range(c + 1, k):
                lu[r, j] -= f * lu[c, j]
    return lu, piv, True


@kernel
def _lu_solve_k(
    lu: NDArray[np.float64], piv: NDArray[np.int64], rhs: NDArray[np.float64]
) -> NDArray[np.float64]:
    """``g^-1 rhs`` from :func:`_lu_k`'s factors."""
    k = lu.shape[0]
    x = np.empty(k)
    for i in range(k):
        x[i] = rhs[piv[i]]
    for i in range(k):
        s = x[i]
        for j in range(i):
            s -= lu[i, j] * x[j]
        x[i] = s
    for i in range(k - 1, -1, -1):
        s = x[i]
        for j in range(i + 1, k):
            s -= lu[i, j] * x[j]
        x[i] = s / lu[i, i]
    return x


@kernel
def _lu_inv_k(lu: NDArray[np.float64], piv: NDArray[np.int64]) -> NDArray[np.float64]:
    """``g^-1`` from :func:`_lu_k`'s factors (column by column, as ``np.linalg.inv``
    solves for the identity)."""
    k = lu.shape[0]
    out = np.empty((k, k))
    e = np.zeros(k)
    for c in range(k):
        e[c] = 1.0
        col = _lu_solve_k(lu, piv, e)
        e[c] = 0.0
        for i in range(k):
            out[i, c] = col[i]
    return out


@kernel
def _residuals_k(
    a_t: NDArray[np.float64],
    lo: NDArray[np.int64],
    hi: NDArray[np.int64],
    b: NDArray[np.float64],
    coef: NDArray[np.float64],
) -> NDArray[np.float64]:
    """``b - coef @ a_t`` (``a_t``'s rows 0 outside ``lo .. hi``, as in :func:`_normal_k`)."""
    k, n = a_t.shape
    fit = np.zeros(n)
    for i in range(k):
        c = coef[i]
        l, h = lo[i], hi[i]
        x, z = a_t[i, l:h], fit[l:h]
        for m in range(h - l):
            z[m] += c * x[m]
    r = np.empty(n)
    for m in range(n):
        r[m] = b[m] - fit[m]
    return r


@kernel
def _wls_k(
    a_t: NDArray[np.float64],
    lo: NDArray[np.int64],
    hi: NDArray[np.int64],
    b: NDArray[np.float64],
    w: NDArray[np.float64],
) -> tuple[NDArray[np.float64], bool]:
    """:func:`_wlstsq`: the weighted normal equations solved by LU (False: singular)."""
    k = a_t.shape[0]
    gram = np.empty((k, k))
    rhs = np.empty(k)
    _normal_k(a_t, lo, hi, b, w, gram, rhs)
    lu, piv, ok = _lu_k(gram)
    if not ok:
        return np.full(k, np.nan), False
    return _lu_solve_k(lu, piv, rhs), True


@kernel
def _group_scales_k(
    r: NDArray[np.float64],
    ends: NDArray[np.int64],
    keep: NDArray[np.bool_],
    use_keep: bool,
    sig: NDArray[np.float64],
) -> None:
    """:func:`_group_scales` for the groups ``[0, ends[0])``, ``[ends[0], ends[1])``..."""
    buf = np.empty(r.shape[0])
    start = 0
    for end in ends:
        n = 0
        # (every point written, the kept ones counted: no branch a point, here and in
        # the kernels below; a left-out point's value is overwritten by the next)
        for m in range(start, end):
            buf[n] = abs(r[m])
            n += int(keep[m]) if use_keep else 1
        # (counted by the values' bits: a quickselect's compares on noise are coin
        # flips, half its time in mispredicted branches; the same value)
        s = 1.4826 * median_nonnegative(buf[:n]) + 1e-12 if n else 1.0
        for m in range(start, end):
            sig[m] = s
        start = end


@kernel
def _irls_k(
    a_t: NDArray[np.float64],
    lo: NDArray[np.int64],
    hi: NDArray[np.int64],
    b: NDArray[np.float64],
    ends: NDArray[np.int64],
    span_ends: NDArray[np.int64],
    keep: NDArray[np.bool_],
    given: bool,
    sig: NDArray[np.float64],
) -> int:
    """:func:`_fit_joint`'s choice of inliers: ``keep`` (another fit's when ``given``,
    else chosen here) and each group's scale ``sig`` (written into the arguments).
    Tukey's biweight, up to five solves, stopping once two in a row keep the same
    points. Returns a status as :func:`_joint_k`'s: 0; 2 where a solve would have a
    hub edge (spans 3 and 4 of ``span_ends``) with fewer than :data:`MIN_HUB_EDGE`
    points (all its points beyond the biweight's cut leave its offset undetermined:
    the normal matrix singular); 3 where a solve met a singular matrix."""
    n = b.shape[0]
    w = np.ones(n)
    if given:
        if _hub_edge_short_k(keep, span_ends):
            return 2
        for m in range(n):
            w[m] = 1.0 if keep[m] else 0.0
        coef, ok = _wls_k(a_t, lo, hi, b, w)
        _group_scales_k(_residuals_k(a_t, lo, hi, b, coef), ends, keep, given, sig)
        return 0 if ok else 3
    for m in range(n):
        keep[m] = True
        sig[m] = 1.0
    wk = np.empty(n)
    inside = np.empty(n, dtype=np.bool_)
    for it in range(5):
        # the points weighed (not 0) in this solve: the kept ones
        if _hub_edge_short_k(keep, span_ends):
            return 2
        for m in range(n):
            wk[m] = w[m] / (sig[m] * sig[m])
        coef, ok = _wls_k(a_t, lo, hi, b, wk)
        if not ok:
            return 3
        r = _residuals_k(a_t, lo, hi, b, coef)
        _group_scales_k(r, ends, keep, it != 0, sig)
        changed = 0
        for m in range(n):
            z = r[m] / (TUKEY_C * sig[m])
            ins = abs(z) < 1.0
            inside[m] = ins
            t = 1.0 - z * z
            w[m] = t * t if ins else 0.0
            changed += ins != keep[m]
        if it >= 2 and changed == 0:
            break
        for m in range(n):
            keep[m] = inside[m]
    return 0


@kernel
def _hub_edge_short_k(keep: NDArray[np.bool_], span_ends: NDArray[np.int64]) -> bool:
    """Whether a hub edge (spans 3 and 4 of ``span_ends``, where there are) keeps fewer
    than :data:`MIN_HUB_EDGE` points."""
    for s in range(2, span_ends.shape[0]):
        cnt = 0
        for m in range(span_ends[s - 1], span_ends[s]):
            cnt += int(keep[m])
        if cnt < MIN_HUB_EDGE:
            return True
    return False


@kernel
def _final_k(
    a_t: NDArray[np.float64],
    lo: NDArray[np.int64],
    hi: NDArray[np.int64],
    b: NDArray[np.float64],
    ends: NDArray[np.int64],
    keep: NDArray[np.bool_],
    sig: NDArray[np.float64],
    p_beam: int,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], bool]:
    """:func:`_fit_joint`'s final fit: the inliers at ``1 / sig^2``, then each group at
    the variance of its residuals (``p_beam`` coefficients for the first group's degrees
    of freedom, 2 for the others). Returns the coefficients, the residuals, the inverse
    normal matrix, and False where a solve met a singular matrix."""
    k, n = a_t.shape
    w = np.empty(n)
    for m in range(n):
        w[m] = 1.0 / (sig[m] * sig[m]) if keep[m] else 0.0
    coef, ok = _wls_k(a_t, lo, hi, b, w)
    if not ok:
        return coef, b.copy(), np.full((k, k), np.nan), False
    r = _residuals_k(a_t, lo, hi, b, coef)
    start = 0
    for g in range(ends.shape[0]):
        end = ends[g]
        nk = 0
        ss = 0.0
        for m in range(start, end):
            if keep[m]:
                nk += 1
                ss += r[m] * r[m]
        dof = max(nk - (p_beam if g == 0 else 2), 1)
        v = ss / dof if nk else 1.0
        wv = 1.0 / max(v, 1e-18)
        for m in range(start, end):
            w[m] = wv if keep[m] else 0.0
        start = end
    gram = np.empty((k, k))
    rhs = np.empty(k)
    _normal_k(a_t, lo, hi, b, w, gram, rhs)
    lu, piv, ok = _lu_k(gram)
    if not ok:
        return coef, r, np.full((k, k), np.nan), False
    coef = _lu_solve_k(lu, piv, rhs)
    return coef, _residuals_k(a_t, lo, hi, b, coef), _lu_inv_k(lu, piv), True


@kernel
def _long_run_k(x: NDArray[np.float64], max_lag: int) -> float:
    """:func:`long_run_inflation` of one edge's residuals ``x`` by direct sums over the
    lags (the definition; 1 for fewer than 8 points or all zero)."""
    n = x.shape[0]
    if n < 8:
        return 1.0
    den = _dot_k(x, x)
    if den <= 0:
        return 1.0
    k_max = min(max_lag, n // 4)
    # all lags' sums x[m] x[m + lag] in one pass over m (the lags innermost: SIMD)
    acov = np.zeros(k_max)
    for m in range(n - 1):
        xm = x[m]
        top = min(k_max, n - 1 - m)
        y, z = x[m + 1 : m + 1 + top], acov[:top]
        for j in range(top):
            z[j] += xm * y[j]
    s = 0.0
    for lag in range(1, k_max + 1):
        s += (1.0 - lag / (k_max + 1.0)) * acov[lag - 1]
    return max(1.0 + 2.0 * s / den, 1.0)


@kernel
def _lag1_k(x: NDArray[np.float64]) -> float:
    """:func:`lag1_correlation`."""
    n = x.shape[0]
    if n < 4:
        return 0.0
    den = _dot_k(x, x)
    return _dot_k(x[1:], x[: n - 1]) / den if den > 0 else 0.0


@kernel
def _span_stats_k(
    r: NDArray[np.float64], keep: NDArray[np.bool_], ends: NDArray[np.int64], max_lag: int
) -> tuple[float, float]:
    """Over the spans ``[0, ends[0])``, ``[ends[0], ends[1])``...: their kept residuals'
    largest :func:`long_run_inflation` and the first two's largest
    :func:`lag1_correlation`."""
    buf = np.empty(r.shape[0])
    infl = 1.0
    rho = -np.inf
    start = 0
    for s in range(ends.shape[0]):
        n = 0
        for m in range(start, ends[s]):
            buf[n] = r[m]
            n += int(keep[m])
        infl = max(infl, _long_run_k(buf[:n], max_lag))
        if s < 2:
            rho = max(rho, _lag1_k(buf[:n]))
        start = ends[s]
    return infl, rho


@kernel
def _free_slope_k(
    ab: NDArray[np.float64], y: NDArray[np.float64], keep: NDArray[np.bool_]
) -> tuple[float, float, float, bool]:
    """The free-root-slope check's least squares on the rows ``ab`` at the points
    ``keep``: the third coefficient, the residual variance, and the third diagonal
    element of the inverse normal matrix (False: singular)."""
    k, n = ab.shape
    w = np.empty(n)
    n_k = 0
    for m in range(n):
        w[m] = 1.0 if keep[m] else 0.0
        n_k += int(keep[m])
    gram = np.empty((k, k))
    rhs = np.empty(k)
    lo, hi = np.zeros(k, dtype=np.int64), np.full(k, n, dtype=np.int64)
    _normal_k(ab, lo, hi, y, w, gram, rhs)
    lu, piv, ok = _lu_k(gram)
    if not ok:
        return np.nan, np.nan, np.nan, False
    free = _lu_solve_k(lu, piv, rhs)
    r = _residuals_k(ab, lo, hi, y, free)
    ss = 0.0
    for m in range(n):
        if keep[m]:
            ss += r[m] * r[m]
    e = np.zeros(k)
    e[2] = 1.0
    return free[2], ss / max(n_k - k, 1), _lu_solve_k(lu, piv, e)[2], True


@kernel
def _joint_k(
    a_t: NDArray[np.float64],
    lo: NDArray[np.int64],
    hi: NDArray[np.int64],
    b: NDArray[np.float64],
    ends: NDArray[np.int64],
    span_ends: NDArray[np.int64],
    keep: NDArray[np.bool_],
    given: bool,
    sig: NDArray[np.float64],
    p_shape: int,
    min_edge: int,
    u: NDArray[np.float64],
) -> tuple[
    int,
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.float64],
    float,
    float,
    float,
    float,
    float,
]:
    """:func:`_fit_joint`'s arithmetic in one call: the inliers (:func:`_irls_k`), the
    edges' checks, the final fit (:func:`_final_k`), the span statistics
    (:func:`_span_stats_k`) and, unless ``given``, the free-root-slope check
    (:func:`_free_slope_k` on the width, an offset, ``u`` and the shape rows, the last
    ``p_shape`` of ``a_t``, over the beam's points). Returns a status (0: fitted; 1: a
    beam edge keeps fewer than ``min_edge`` points; 2: a hub edge (spans 3 and 4) fewer
    than :data:`MIN_HUB_EDGE`, at the end or in any solve of :func:`_irls_k`; 3: a
    singular normal matrix, which the hub's edges, each of at least that many points,
    cannot make: the beam's edges' points too few or too bunched), the coefficients,
    the residuals, the inverse normal matrix, the long-run inflation, the edges' lag-1
    correlation, and the free slope's coefficient, residual variance and inverse-normal
    element (NaN if given)."""
    k = a_t.shape[0]
    nan = np.nan
    empty2 = np.empty((0, 0))
    status = _irls_k(a_t, lo, hi, b, ends, span_ends, keep, given, sig)
    if status != 0:
        return status, b, b, empty2, nan, nan, nan, nan, nan
    start = 0
    for s in range(span_ends.shape[0]):
        cnt = 0
        for m in range(start, span_ends[s]):
            cnt += int(keep[m])
        if cnt < (min_edge if s < 2 else MIN_HUB_EDGE):
            return 1 if s < 2 else 2, b, b, empty2, nan, nan, nan, nan, nan
        start = span_ends[s]
    coef, r, inv, ok = _final_k(a_t, lo, hi, b, ends, keep, sig, p_shape + 2)
    if not ok:
        return 3, b, b, empty2, nan, nan, nan, nan, nan
    infl, rho = _span_stats_k(r, keep, span_ends, LONG_RUN_LAGS)
    free2, s2_free, inv22 = nan, nan, nan
    if not given:
        n_beam = span_ends[1]
        ab = np.empty((3 + p_shape, n_beam))
        for m in range(n_beam):
            ab[0, m] = a_t[0, m]
            ab[1, m] = 1.0
            ab[2, m] = u[m]
        for i in range(p_shape):
            src, dst = a_t[k - p_shape + i], ab[3 + i]
            for m in range(n_beam):
                dst[m] = src[m]
        free2, s2_free, inv22, ok = _free_slope_k(ab, b[:n_beam], keep[:n_beam])
        if not ok:
            return 3, b, b, empty2, nan, nan, nan, nan, nan
    return 0, coef, r, inv, infl, rho, free2, s2_free, inv22


@kernel
def _orthonormalise_k(
    rows: NDArray[np.float64], n_first: int
) -> tuple[NDArray[np.float64], int, int]:
    """:func:`_orthonormalise`: the orthonormal rows (the first ``k`` of the result),
    ``k``, and how many of the first ``n_first`` rows were kept."""
    n_rows, n = rows.shape
    q = np.empty((n_rows, n))
    c = np.empty(n_rows)
    t = np.empty(n)
    k = 0
    kept_first = 0
    for i in range(n_rows):
        v = rows[i]
        norm0 = math.sqrt(_dot_k(v, v))
        if norm0 == 0.0:
            continue
        for _ in range(2):
            if k:
                for j in range(k):
                    c[j] = _dot_k(q[j], v)
                t.fill(0.0)
                for j in range(k):
                    cj = c[j]
                    for m in range(n):
                        t[m] += cj * q[j, m]
                for m in range(n):
                    v[m] -= t[m]
        norm = math.sqrt(_dot_k(v, v))
        if norm <= 1e-9 * norm0:
            continue
        for m in range(n):
            q[k, m] = v[m] / norm
        k += 1
        if i < n_first:
            kept_first += 1
    return q, k, kept_first


@kernel
def _basis_k(u: NDArray[np.float64], degree: int, out: NDArray[np.float64]) -> None:
    """:func:`_basis_t` into ``out`` (degree - 1, N): numpy's Legendre recurrence on
    ``x = 2 u - 1`` row by row, each row then times ``u^2`` (the same operations)."""
    n = u.shape[0]
    x, uu = np.empty(n), np.empty(n)
    for m in range(n):
        x[m] = 2.0 * u[m] - 1.0
        uu[m] = u[m] * u[m]
    leg = np.empty((degree - 1, n))  # the Legendre rows, unscaled
    for i in range(degree - 1):
        row = leg[i]
        if i == 0:
            for m in range(n):
                row[m] = 1.0
        elif i == 1:
            for m in range(n):
                row[m] = x[m]
        else:
            p1, p0 = leg[i - 1], leg[i - 2]
            a, c = 2 * i - 1, i - 1
            for m in range(n):
                row[m] = (p1[m] * x[m] * a - p0[m] * c) / i
        dst = out[i]
        for m in range(n):
            dst[m] = row[m] * uu[m]


@kernel
def _modes_k(
    x: NDArray[np.float64],
    beta: NDArray[np.float64],
    sigma: NDArray[np.float64],
    big: NDArray[np.float64],
    derivative: int,
) -> NDArray[np.float64]:
    """:func:`cantilever_modes_t`, element by element: ``cosh(bx) - sigma sinh(bx)`` as
    ``((1 - sigma) e^beta e^(bx - beta) + (1 + sigma) e^-bx) / 2``, with ``e^-bx`` as
    ``e^-beta / e^(bx - beta)`` (one exponential a point, within 2 ulp of its own)."""
    out = np.empty((beta.shape[0], x.shape[0]))
    for i in range(beta.shape[0]):
        bi, s, g = beta[i], sigma[i], big[i]
        e_b = math.exp(-bi)
        row = out[i]
        for m in range(x.shape[0]):
            bx = bi * x[m]
            grow = math.exp(bx - bi)
            decay = e_b / grow
            c, sn = math.cos(bx), math.sin(bx)
            if derivative == 0:
                row[m] = 0.5 * (g * grow + (1 + s) * decay) - c + s * sn
            else:
                row[m] = bi * (0.5 * (g * grow - (1 + s) * decay) + sn + s * c)
    return out


@kernel
def _polyval_k(c: NDArray[np.float64], x: float) -> float:
    """``numpy.polynomial.polynomial.polyval(x, c)`` at one point: Horner's rule from the
    highest power, the same operations in the same order (0 for no coefficients)."""
    n = c.shape[0]
    if n == 0:
        return x * 0.0
    acc = c[n - 1] + x * 0.0
    for i in range(n - 2, -1, -1):
        acc = c[i] + acc * x
    return acc


@kernel
def _centre_k(
    a: NDArray[np.float64],
    coef: NDArray[np.float64],
    dcoef: NDArray[np.float64],
    amax: float,
    value: bool,
) -> NDArray[np.float64]:
    """:class:`CentreLine` at ``a`` (``value``: the series, extended linearly past both
    ends; else its slope ``dcoef``): ``a`` clipped to ``0 .. amax`` as ``np.clip`` does
    (NaN stays NaN), ``u = a / amax``, each series by :func:`_polyval_rows_k`."""
    n = a.shape[0]
    u, beyond = np.empty(n), np.empty(n)
    for m in range(n):
        x = a[m]
        ac = x
        if x < 0.0:
            ac = 0.0
        elif x > amax:
            ac = amax
        u[m] = ac / amax
        beyond[m] = x - ac
    d = np.empty(n)
    _polyval_rows_k(dcoef, u, d)
    if not value:
        return d
    out = np.empty(n)
    _polyval_rows_k(coef, u, out)
    for m in range(n):
        out[m] = out[m] + beyond[m] * d[m]
    return out


@kernel
def _polyval_rows_k(
    c: NDArray[np.float64], x: NDArray[np.float64], out: NDArray[np.float64]
) -> None:
    """:func:`_polyval_k` at every point of ``x``, into ``out``: each point's operations
    the same, in the same order, but the coefficients in the outer loop and the points
    in the inner one, which runs in SIMD (a third of the time on a beam's points)."""
    n, n_x = c.shape[0], x.shape[0]
    if n == 0:
        for m in range(n_x):
            out[m] = x[m] * 0.0
        return
    top = c[n - 1]
    for m in range(n_x):
        out[m] = top + x[m] * 0.0
    for i in range(n - 2, -1, -1):
        ci = c[i]
        for m in range(n_x):
            out[m] = ci + out[m] * x[m]


def linspace(start: float, stop: float, num: int) -> NDArray[np.float64]:
    """``np.linspace(start, stop, num)`` of two float64 scalars, element for element the
    same (:func:`_linspace_k`; numpy's own call costs several times the values for the
    few hundred a measurement asks for, a dozen times a frame)."""
    if num < 0:
        raise ValueError(f"Number of samples, {num}, must be non-negative.")
    return _linspace_k(float(start), float(stop), int(num))


@kernel
def _linspace_k(start: float, stop: float, num: int) -> NDArray[np.float64]:
    """:func:`linspace`: numpy's operations, ``i * step + start`` (``(i / div) * delta
    + start`` where the step underflows to 0), the last value ``stop``."""
    out = np.empty(num)
    div = num - 1
    delta = stop - start
    if div > 0:
        step = delta / div
        for i in range(num):
            out[i] = (i / div * delta if step == 0 else i * step) + start
        out[num - 1] = stop
    else:
        for i in range(num):
            out[i] = i * delta + start
    return out


#: Trapezoid samples along the centre line for arc lengths: the rule's error,
#: ``L h^2 max|f''| / 12`` with ``f = sqrt(1 + b'^2)``, is below 1e-7 m for the beam's
#: curvatures (|b''| < 1 /m, |b'| < 0.2 over 0.85 m).
_ARC_SAMPLES = 801


def arc_length(centre: CentreLine | ModalCentreLine, a_end: float) -> float:
    """Length of the centre line from the clamp to ``a_end`` (m)."""
    a, slope = _slope_samples(centre, a_end)
    return _arc_trapezoid_k(a, slope)


def _slope_samples(
    centre: CentreLine | ModalCentreLine, a_end: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``a = linspace(0, a_end, _ARC_SAMPLES)`` and the centre line's slope there, kept
    on ``centre`` by ``a_end``: a frame's arc length and its stations ask for the same
    ones (a centre line is not changed after it is made; callers only read them, and
    they stay writable so that the kernels given them compile for one kind of array)."""
    got = centre._slopes.get(a_end)
    if got is None:
        if len(centre._slopes) >= 8:
            centre._slopes.clear()
        a = linspace(0.0, a_end, _ARC_SAMPLES)
        slope = np.ascontiguousarray(centre.deriv(a), dtype=np.float64)
        got = centre._slopes[a_end] = (a, slope)
    return got


@kernel
def _arc_trapezoid_k(x: NDArray[np.float64], slope: NDArray[np.float64]) -> float:
    """``np.trapezoid(np.sqrt(1.0 + slope**2), x)``: numpy's operations per interval,
    ``diff(x) * (y[1:] + y[:-1]) / 2.0``, summed as numpy sums (:func:`numpy_sum`)."""
    n = x.shape[0]
    if n < 2:
        return 0.0
    v = np.empty(n - 1)
    prev = math.sqrt(1.0 + slope[0] * slope[0])
    for i in range(1, n):
        cur = math.sqrt(1.0 + slope[i] * slope[i])
        v[i - 1] = (x[i] - x[i - 1]) * (cur + prev) / 2.0
        prev = cur
    return numpy_sum(v, n - 1)


def stations_to_a(
    centre: CentreLine | ModalCentreLine, stations: NDArray[np.float64], a_end: float
) -> NDArray[np.float64]:
    """Axis coordinate of the material points at arc lengths ``stations`` from the clamp."""
    a, slope = _slope_samples(centre, max(a_end, float(stations.max()) + 0.01))
    return np.interp(stations, _cumulative_k(a, slope, True), a)


@kernel
def _cumulative_k(x: NDArray[np.float64], y: NDArray[np.float64], arc: bool) -> NDArray[np.float64]:
    """The cumulative trapezoid integral of ``y`` (``arc``: of ``sqrt(1 + y^2)``) over
    ``x`` from 0, as ``concatenate([[0], cumsum(0.5 * (y[1:] + y[:-1]) * diff(x))])``
    (numpy's cumulative sum runs in order: equal exactly)."""
    n = x.shape[0]
    out = np.empty(n)
    if n == 0:
        return out
    out[0] = 0.0
    prev = math.sqrt(1.0 + y[0] * y[0]) if arc else y[0]
    for i in range(1, n):
        cur = math.sqrt(1.0 + y[i] * y[i]) if arc else y[i]
        step = 0.5 * (cur + prev) * (x[i] - x[i - 1])
        out[i] = step if i == 1 else out[i - 1] + step
        prev = cur
    return out


@dataclass
class JointFit:
    """Result of :func:`fit_clamped_joint` (hub frame of the trial axis, m).

    ``rotation_rad``: the turn of the trial axis (about the pivot) that the data ask
    for, and ``rotation_sd_rad`` its standard uncertainty; ``fit``: the centre line in
    the turned frame (its ``tip_sd`` includes the axis's uncertainty); ``hub_width`` and
    ``hub_offset``: the hub edges' distance apart and their mid-line's offset from the
    pivot's line (NaN without hub edges); ``hub_rms``: their RMS residual;
    ``hub_width_sd``: the width's standard uncertainty (the two offsets' difference
    through the fit's covariance; NaN without hub edges)."""

    rotation_rad: float
    rotation_sd_rad: float
    fit: CentreFit
    hub_width: float
    hub_offset: float
    hub_rms: float
    #: The modal fit's check (NaN for the polynomial, and for a fit to another's
    #: ``inliers``, a reference): the beam's residual sum of squares
    #: that the generic polynomial's ``shape_dof`` extra shapes remove, over the residual
    #: variance (inflated for correlation): chi-squared with ``shape_dof`` degrees of
    #: freedom when the modes hold the shape.
    shape_chi2: float = math.nan
    shape_dof: int = 0
    #: Which points (the beam's left, right, then the hub's edges, as given) the fit
    #: kept (None where not recorded).
    inliers: NDArray[np.bool_] | None = None
    hub_width_sd: float = math.nan
    #: Whether the hub's edges are the straight lines the fit takes them for (computed
    #: when called: a frame asks its final fit only): the larger of the two edges'
    #: fractions of points the biweight left out, and the larger of their kept
    #: residuals' lag-1 correlations along them (NaN, NaN without hub edges).
    hub_straightness: Callable[[], tuple[float, float]] = lambda: (math.nan, math.nan)


def fit_clamped_joint(
    left: NDArray[np.float64],
    right: NDArray[np.float64],
    hub_a: NDArray[np.float64],
    hub_b: NDArray[np.float64],
    degree: int,
    amax: float,
    clamp_from_pivot: float,
    *,
    modes: int = 0,
    beam_length: float = math.nan,
    along: CentreLine | ModalCentreLine | None = None,
    edge_slope: Callable[[NDArray[np.float64]], NDArray[np.float64]] | None = None,
    inliers: NDArray[np.bool_] | None = None,
    memo: PointsMemo | None = None,
) -> JointFit | str:
    """The hub's axis and the clamped centre line, fitted together.

    The beam leaves the clamp along the hub's axis (``w'(0) = 0``) at the clamp, which
    lies on the axis ``clamp_from_pivot`` (m) from the pivot: in the frame of a trial
    axis through the pivot (``a`` from the clamp along it, ``b`` across), a turn of the
    true axis by a small ``delta`` moves every point's ``b`` by ``delta (a +
    clamp_from_pivot)``. So the beam's edges (``left``, ``right``: (N, 2) (a, b)) are

        b = delta (a + c) +- width / 2 + sum_k c_k u^2 P_k(2 u - 1),   u = a / amax,

    and the hub's long edges (``hub_a``, ``hub_b``: (M, 2), M may be 0), straight lines
    along the axis at their own offsets, ``b = delta (a + c) + h_edge``. The beam's edges
    fix the axis through the root's position relative to the pivot; the hub's edges,
    when long, add their direction. One weighted least-squares fit (each group weighed
    by its own scatter; Tukey's biweight chooses the inliers, as in
    :func:`fit_centreline`). Linear in ``delta`` to first order: the caller turns the
    axis by ``rotation_rad`` and fits again until the turn vanishes.

    With ``modes`` > 0 the shape is the first ``modes`` clamped-free modes of a beam of
    ``beam_length`` (m) instead of the polynomial: ``w(s) = sum_k c_k phi_k(s / L)`` at
    the arc length ``s`` of each edge point along ``along`` (a previous fit's centre
    line; without it, ``s`` is taken from a first fit: two fits). The result's
    ``shape_chi2`` then tests the modes against the modes and the polynomial together.

    ``edge_slope``: the centre line's slope ``db/da`` at axis coordinates ``a`` (a
    previous fit's or a rough one's; None: 0). A beam's edges lie half its width either
    side of the centre line along its normal, so at slope angle ``theta`` an edge point
    at ``a`` lies ``(width / 2) / cos(theta)`` across the axis from the centre line at
    the same ``a`` (to ``b'' (w/2)^2 sin^2(theta) / 2``, the same for both edges:
    micrometres): the width's column carries ``sqrt(1 + slope^2)``. A beam swinging
    155 mm at its tip (slope 0.28) has edges 0.4 mm further apart across the axis there
    than at its root, which a constant width leaves in the residuals, in runs.

    ``inliers``: another fit's :attr:`JointFit.inliers` on the same points (the modal
    fit's, for its polynomial and more-modes references): taken instead of choosing them
    again, one fit instead of up to six (ignored where that fit dropped the hub's edges);
    such a reference has no shape test and no free root slope (NaN: the fit whose
    inliers it takes checks its root).

    ``memo``: a :class:`PointsMemo` shared by fits of the same beam points (``left``,
    ``right`` and ``amax`` the same): what they compute from the points alone (the
    shapes at them, the edges' slope, the modes' correction) is computed once.

    Returns a :class:`JointFit`, or the reason (str) when the edges cannot carry it."""

    def fit(
        shape: _Modes | None,
        slope: Callable[[NDArray[np.float64]], NDArray[np.float64]] | None,
        taken: NDArray[np.bool_] | None,
    ) -> JointFit | str:
        return _fit_joint(
            left, right, hub_a, hub_b, degree, amax, clamp_from_pivot, shape, slope, taken, memo
        )

    if modes <= 0:
        return fit(None, edge_slope, inliers)
    if not (math.isfinite(beam_length) and beam_length > 0):
        raise ValueError(f"beam_length must be positive with modes, got {beam_length!r}")
    if along is None:
        first = fit(_Modes(modes, beam_length, amax, None), edge_slope, None)
        if isinstance(first, str):
            return first
        along = first.fit.centre
    shape = _Modes(modes, beam_length, amax, arc_map(along, amax))
    return fit(shape, along.deriv if edge_slope is not None else None, inliers)


class PointsMemo:
    """What :func:`fit_clamped_joint` computes from a set of beam points alone (the
    polynomial's and the modes' shapes at them, the edges' slope there, the modes'
    correction), kept for other fits of the same points (a modal fit's references:
    the polynomial on its inliers, two more modes). Each entry is keyed by what it
    depends on besides the points (the objects themselves held, so that a key's
    ``id`` stays theirs); every array is the caller's to read, never to write."""

    def __init__(self) -> None:
        self._entries: dict[tuple[Any, ...], tuple[Any, NDArray[np.float64]]] = {}

    def get(
        self, key: tuple[Any, ...], owner: Any, make: Callable[[], NDArray[np.float64]]
    ) -> NDArray[np.float64]:
        """The entry of ``key`` (``owner``: the object whose ``id`` the key holds, or
        None), made by ``make`` the first time."""
        hit = self._entries.get(key)
        if hit is None or hit[0] is not owner:
            hit = self._entries[key] = (owner, make())
        return hit[1]

    def modes(self, shape: _Modes, a: NDArray[np.float64]) -> NDArray[np.float64]:
        """``shape.basis_t(a)`` at the memo's points ``a``: a fit of more modes on the
        same arc lengths computes only the modes it adds (each mode's row is computed
        alone: the same values)."""
        along = shape.along
        base = (shape.beam_length, id(along))
        x = self.get(("modes_x", *base), along, lambda: shape.modes_x(a))
        key = ("modes", shape.n, *base)
        hit = self._entries.get(key)
        if hit is not None and hit[0] is along:
            return hit[1]
        have = [
            k[1]
            for k, v in self._entries.items()
            if k[0] == "modes" and k[2:] == base and v[0] is along and k[1] < shape.n
        ]
        if have:
            first = max(have)
            rows = np.concatenate(
                [self._entries[("modes", first, *base)][1], _modes_rows(x, first, shape.n)]
            )
        else:
            rows = _modes_rows(x, 0, shape.n)
        self._entries[key] = (along, rows)
        return rows


def _modes_rows(x: NDArray[np.float64], first: int, last: int) -> NDArray[np.float64]:
    """Rows ``first .. last - 1`` of ``cantilever_modes_t(x, last)`` (each mode's row
    from its own constants: the first modes' constants are the same for any count)."""
    beta, sigma, big = _mode_constants(last)
    return _modes_k(
        np.ascontiguousarray(x, dtype=np.float64), beta[first:], sigma[first:], big[first:], 0
    )


@dataclass
class _Modes:
    """The modal shape space of :func:`fit_clamped_joint` (``along``: each point's arc
    length from its ``a``; None: the arc length taken as ``a``)."""

    n: int
    beam_length: float
    amax: float
    along: ArcMap | None

    def basis_t(self, a: NDArray[np.float64]) -> NDArray[np.float64]:
        return cantilever_modes_t(self.modes_x(a), self.n)

    def modes_x(self, a: NDArray[np.float64]) -> NDArray[np.float64]:
        """The modes' argument ``s / L`` at axis coordinates ``a``."""
        s = a if self.along is None else self.along(a)
        return np.asarray(s / self.beam_length, dtype=np.float64)

    def correction(self, a: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.zeros_like(a) if self.along is None else self.along.correction(a)

    def centre(self, coef: NDArray[np.float64]) -> ModalCentreLine:
        return ModalCentreLine(coef, self.beam_length, self.amax)


def _fit_joint(
    left: NDArray[np.float64],
    right: NDArray[np.float64],
    hub_a: NDArray[np.float64],
    hub_b: NDArray[np.float64],
    degree: int,
    amax: float,
    clamp_from_pivot: float,
    modal: _Modes | None,
    edge_slope: Callable[[NDArray[np.float64]], NDArray[np.float64]] | None = None,
    inliers: NDArray[np.bool_] | None = None,
    memo: PointsMemo | None = None,
) -> JointFit | str:
    """:func:`fit_clamped_joint` in the polynomial (``modal`` None) or modal shape space:
    the shapes, the edges' slope and the modes' correction at the beam's points here
    (from ``memo`` when given), the design, the fit and its statistics in three kernels
    (:func:`_fit_joint_core`)."""
    nl, nr = len(left), len(right)
    use_hub = len(hub_a) >= 5 and len(hub_b) >= 5
    if not use_hub:
        hub_a = hub_b = _NO_POINTS
    if min(nl, nr) < degree + 4:
        return "beam edges too ragged"
    a_beam = np.concatenate([left[:, 0], right[:, 0]])
    n_beam = nl + nr
    n_all = n_beam + len(hub_a) + len(hub_b)
    given = inliers is not None and len(inliers) == n_all
    keep = np.array(inliers, dtype=bool) if given else np.ones(n_all, dtype=bool)
    if memo is None:
        memo = PointsMemo()

    def poly_shape() -> NDArray[np.float64]:
        return _basis_t(a_beam / amax, degree)

    if modal is None:
        shape = memo.get(("poly", degree, amax), None, poly_shape)
        corr, extra, g_shape = _NO_VALUES, _NO_ROWS, _tip_gradient(degree)[2:]
    else:
        along = modal.along
        shape = memo.modes(modal, a_beam)
        # The modes give the linear theory's deflection, int theta; an edge point lies
        # at int sin theta: the difference (~theta^3 / 6 per length, micrometres) added.
        corr = (
            _NO_VALUES
            if along is None
            else memo.get(("corr", id(along)), along, lambda: along.correction(a_beam))
        )
        # the shape test's extra shapes (none for a reference on another fit's inliers)
        extra = _NO_ROWS if given else memo.get(("poly", degree, amax), None, poly_shape)
        g_shape = modal.basis_t(np.array([amax]))[:, 0]
    # Half the width along the normal: 1 / cos(theta) across the axis.
    slope = (
        _NO_VALUES
        if edge_slope is None
        else memo.get(
            ("slope", edge_slope),
            None,
            lambda: np.asarray(edge_slope(a_beam), dtype=np.float64),
        )
    )
    (
        status,
        coef,
        cov,
        tip_sd,
        n_kb,
        rms,
        hub_rms,
        free2,
        s2_free,
        inv22,
        infl,
        edge_rho,
        shape_chi2,
        shape_dof,
    ) = _fit_joint_core(
        np.ascontiguousarray(left, dtype=np.float64),
        np.ascontiguousarray(right, dtype=np.float64),
        np.ascontiguousarray(hub_a, dtype=np.float64),
        np.ascontiguousarray(hub_b, dtype=np.float64),
        float(clamp_from_pivot),
        float(amax),
        shape,
        np.ascontiguousarray(slope),
        corr,
        keep,
        given,
        degree + 4,
        extra,
        np.ascontiguousarray(g_shape, dtype=np.float64),
    )
    if status == 3:  # not the hub's edges (status 2): the beam's too few or bunched
        return "beam edges too few to fit the beam's shape"
    if status == 1:
        return "beam edges too ragged"
    if status == 2:  # the hub's edges are not straight lines: the beam's root alone
        return _fit_joint(
            left,
            right,
            _NO_POINTS,
            _NO_POINTS,
            degree,
            amax,
            clamp_from_pivot,
            modal,
            edge_slope,
            None,
            memo,
        )
    n_coef = len(coef)
    p_shape = len(g_shape)

    def end_cov() -> tuple[float, float]:
        # The slope at a_max, by a difference of the shape functions (a step of 1e-6 of
        # the beam: the difference's own error ~1e-10 of the slope).
        h = 1e-6 * amax
        g_tip, g_in = np.zeros(n_coef), np.zeros(n_coef)
        g_tip[n_coef - p_shape :] = g_shape
        if modal is None:
            # (the kernel's recurrence: :func:`_basis`'s values, without legvander's calls)
            g_in[n_coef - p_shape :] = _basis_t(np.array([1.0 - h / amax]), degree)[:, 0]
        else:
            g_in[n_coef - p_shape :] = modal.basis_t(np.array([amax - h]))[:, 0]
        g_slope = (g_tip - g_in) / h
        return float(g_tip @ cov @ g_slope), float(g_slope @ cov @ g_slope)

    # The clamped prior's check (not for a reference on another fit's inliers, whose
    # root is that fit's to check): the free root slope from the kernel.
    slope_rad, slope_sd = math.nan, math.nan
    if not given:
        slope_rad = free2 / amax
        slope_sd = math.sqrt(max(inv22 * s2_free * infl, 0.0)) / amax
    centre: CentreLine | ModalCentreLine
    if modal is None:
        centre = CentreLine(_to_power(degree).T @ coef[n_coef - p_shape :], amax)
    else:
        centre = modal.centre(coef[n_coef - p_shape :])
    # (np.compress: the rows a 2-D boolean index gives, in a quarter of its time)
    fit = CentreFit(
        centre=centre,
        left=np.compress(keep[:nl], left, axis=0),
        right=np.compress(keep[nl:n_beam], right, axis=0),
        width=float(coef[0]),
        rms=rms,
        tip_sd=tip_sd,
        root_slope_rad=slope_rad,
        root_slope_sd_rad=slope_sd,
        edge_rho=edge_rho,
        outlier_fraction=1.0 - n_kb / n_beam,
        end_cov=end_cov,
    )

    def straightness() -> tuple[float, float]:
        if not use_hub:
            return math.nan, math.nan
        return _hub_straightness(
            np.ascontiguousarray(hub_a, dtype=np.float64),
            np.ascontiguousarray(hub_b, dtype=np.float64),
            keep[n_beam:],
            float(coef[1]),
            float(clamp_from_pivot),
            np.ascontiguousarray(coef[2:4], dtype=np.float64),
        )

    if use_hub:
        var_w = float(cov[2, 2] + cov[3, 3] - 2.0 * cov[2, 3])
        hub = (abs(float(coef[2] - coef[3])), 0.5 * float(coef[2] + coef[3]))
        hub_w_sd = math.sqrt(max(var_w, 0.0))
    else:
        hub, hub_w_sd = (math.nan, math.nan), math.nan
    return JointFit(
        rotation_rad=float(coef[1]),
        rotation_sd_rad=math.sqrt(max(float(cov[1, 1]), 0.0)),
        fit=fit,
        hub_width=hub[0],
        hub_offset=hub[1],
        hub_rms=hub_rms,
        shape_chi2=shape_chi2,
        shape_dof=shape_dof,
        inliers=keep,
        hub_width_sd=hub_w_sd,
        hub_straightness=straightness,
    )


@kernel
def _hub_straightness(
    hub_a: NDArray[np.float64],
    hub_b: NDArray[np.float64],
    keep: NDArray[np.bool_],
    turn: float,
    clamp_from_pivot: float,
    offsets: NDArray[np.float64],
) -> tuple[float, float]:
    """Of the hub's two edges fitted as straight lines (``turn`` and their ``offsets``,
    ``keep``: their points' inliers, edge a's first): the larger fraction of an edge's
    points left out, and the larger lag-1 correlation of an edge's kept residuals
    ordered along it (:func:`lag1_correlation`). Image noise leaves out next to none
    and correlates little; an edge that steps (a bar lying against part of it) leaves
    out the part that steps, or, kept, gives residuals in one run."""
    out, rho = 0.0, -1.0
    start = 0
    for edge in range(2):
        pts = hub_a if edge == 0 else hub_b
        n = pts.shape[0]
        # the kept residuals ordered along the edge (a stable insertion sort: the
        # points come nearly in order)
        u, r = np.empty(n), np.empty(n)
        m = 0
        for i in range(n):
            if not keep[start + i]:
                continue
            ui = pts[i, 0]
            ri = pts[i, 1] - turn * (ui + clamp_from_pivot) - offsets[edge]
            j = m
            while j > 0 and u[j - 1] > ui:
                u[j], r[j] = u[j - 1], r[j - 1]
                j -= 1
            u[j], r[j] = ui, ri
            m += 1
        start += n
        out = max(out, 1.0 - m / max(n, 1))
        if m < 4:
            rho = max(rho, 0.0)
            continue
        den, num = lag1_sums(r, m)
        rho = max(rho, num / den if den > 0 else 0.0)
    return out, rho


#: Empties for :func:`_fit_joint`: no points, no values, no rows (writable, as every
#: array its kernel is given: one compiled form).
_NO_POINTS = np.zeros((0, 2))
_NO_VALUES = np.zeros(0)
_NO_ROWS = np.zeros((0, 0))


def _fit_joint_core(
    left: NDArray[np.float64],
    right: NDArray[np.float64],
    hub_a: NDArray[np.float64],
    hub_b: NDArray[np.float64],
    clamp_from_pivot: float,
    amax: float,
    shape: NDArray[np.float64],
    slope: NDArray[np.float64],
    corr: NDArray[np.float64],
    keep: NDArray[np.bool_],
    given: bool,
    min_edge: int,
    extra: NDArray[np.float64],
    g_shape: NDArray[np.float64],
) -> tuple[Any, ...]:
    """:func:`_fit_joint`'s design and arithmetic, three kernels in a row: the design
    matrix transposed (:func:`_design_k`), the fit (:func:`_joint_k`; ``keep``: the
    inliers, another fit's when ``given``, written in place) and its statistics
    (:func:`_after_k`), then the modal shape test (``extra``: the polynomial's shapes
    at the beam's points; none, or ``given``: no test). (Three calls, not one kernel
    calling the others: a kernel's compilation optimises again all it calls, and
    :func:`_joint_k` is most of the package's.) Returns (status of :func:`_joint_k`,
    coefficients, covariance, tip sd, inliers on the beam, beam RMS, hub RMS (NaN: no
    hub), free slope's coefficient, residual variance and inverse-normal element,
    inflation, lag-1 correlation, shape chi-squared (NaN: no test), its degrees of
    freedom)."""
    a_t, b, u, lo, hi, ends, span_ends = _design_k(
        left, right, hub_a, hub_b, clamp_from_pivot, amax, shape, slope, corr
    )
    status, coef, r, gram_inv, infl, rho, free2, s2_free, inv22 = _joint_k(
        a_t, lo, hi, b, ends, span_ends, keep, given, np.ones(len(b)), len(shape), min_edge, u
    )
    nan = math.nan
    if status != 0:
        return status, coef, gram_inv, nan, 0, nan, nan, nan, nan, nan, nan, nan, nan, 0
    cov, tip_sd, n_kb, rms, hub_rms = _after_k(
        a_t, r, gram_inv, infl, keep, len(left), len(right), g_shape
    )
    chi2, dof = math.nan, 0
    if len(extra) and not given:
        # The modes against the modes and the polynomial together, on the beam's
        # inliers (its own width, turn and shape): the residual's components along the
        # extra shapes, orthonormalised against the modes', are independent
        # N(0, sigma^2) when the modes hold the shape, however near the two spaces lie.
        # The rows gathered row-major: each row's products then run over contiguous
        # memory (half the time of the column-major gather's strided rows).
        n_beam, p_shape = len(u), len(g_shape)
        x, yb = _test_rows_k(a_t, extra, keep, b, n_beam, p_shape)
        q, n_m = _orthonormalise(x, 2 + p_shape)
        proj = q @ yb
        extra_proj = proj[n_m:]
        dof = len(extra_proj)
        rss_u = float(yb @ yb - proj @ proj)
        s2_u = max(rss_u, 1e-30) / max(n_kb - len(q), 1)
        chi2 = float(extra_proj @ extra_proj) / (s2_u * infl)
    return (0, coef, cov, tip_sd, n_kb, rms, hub_rms, free2, s2_free, inv22, infl, rho, chi2, dof)


@kernel
def _test_rows_k(
    a_t: NDArray[np.float64],
    extra: NDArray[np.float64],
    keep: NDArray[np.bool_],
    b: NDArray[np.float64],
    n_beam: int,
    p_shape: int,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """:func:`_fit_joint_core`'s shape test's rows at the beam's inliers (``keep``'s
    first ``n_beam``): the width's and the turn's rows of ``a_t``, its last ``p_shape``
    (the shape's), then the ``extra`` rows; and the data ``b`` there (copies), gathered
    through the inliers' indices (a third less time than testing ``keep`` in each row's
    loop)."""
    idx = np.empty(n_beam, dtype=np.int64)
    n_k = 0
    for m in range(n_beam):
        idx[n_k] = m  # (overwritten by the next point when this one is left out)
        n_k += int(keep[m])
    n_a = a_t.shape[0]
    n_m = 2 + p_shape
    x = np.empty((n_m + extra.shape[0], n_k))
    yb = np.empty(n_k)
    for r in range(x.shape[0]):
        if r < 2:
            src = a_t[r]
        elif r < n_m:
            src = a_t[n_a - p_shape + r - 2]
        else:
            src = extra[r - n_m]
        dst = x[r]
        for k in range(n_k):
            dst[k] = src[idx[k]]
    for k in range(n_k):
        yb[k] = b[idx[k]]
    return x, yb


@kernel
def _design_k(
    left: NDArray[np.float64],
    right: NDArray[np.float64],
    hub_a: NDArray[np.float64],
    hub_b: NDArray[np.float64],
    clamp_from_pivot: float,
    amax: float,
    shape: NDArray[np.float64],
    slope: NDArray[np.float64],
    corr: NDArray[np.float64],
) -> tuple[
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.int64],
    NDArray[np.int64],
    NDArray[np.int64],
    NDArray[np.int64],
]:
    """:func:`_fit_joint`'s design: the design matrix transposed (the width's row
    ``+-1/2 sqrt(1 + slope^2)`` on the beam's edges, the turn's ``a +
    clamp_from_pivot`` everywhere, the hub edges' offsets (none when ``hub_a`` is
    empty), the ``shape`` rows on the beam's edges), the data ``b`` (plus ``corr`` on
    the beam's edges; ``slope``, ``corr`` empty: none), ``u = a / amax`` on the beam,
    each row's nonzero range (``lo``, ``hi``), the groups' and the edges' ends."""
    nl, nr = left.shape[0], right.shape[0]
    n_beam = nl + nr
    n_ha, n_hb = hub_a.shape[0], hub_b.shape[0]
    use_hub = n_ha > 0
    n_all = n_beam + n_ha + n_hb
    p_shape = shape.shape[0]
    n_coef = (4 if use_hub else 2) + p_shape
    first = n_coef - p_shape
    a_t = np.zeros((n_coef, n_all))
    b = np.empty(n_all)
    u = np.empty(n_beam)
    for m in range(n_all):
        if m < nl:
            a, y = left[m, 0], left[m, 1]
        elif m < n_beam:
            a, y = right[m - nl, 0], right[m - nl, 1]
        elif m < n_beam + n_ha:
            a, y = hub_a[m - n_beam, 0], hub_a[m - n_beam, 1]
        else:
            a, y = hub_b[m - n_beam - n_ha, 0], hub_b[m - n_beam - n_ha, 1]
        a_t[1, m] = a + clamp_from_pivot
        b[m] = y
        if m < n_beam:
            u[m] = a / amax
            w = 0.5 if m < nl else -0.5
            if slope.shape[0]:
                w *= math.sqrt(1.0 + slope[m] * slope[m])
            a_t[0, m] = w
            if corr.shape[0]:
                b[m] += corr[m]
    for i in range(p_shape):
        src, dst = shape[i], a_t[first + i]
        for m in range(n_beam):
            dst[m] = src[m]
    lo = np.zeros(n_coef, dtype=np.int64)
    hi = np.full(n_coef, n_beam, dtype=np.int64)
    hi[1] = n_all
    ends = np.empty(2 if use_hub else 1, dtype=np.int64)
    span_ends = np.empty(4 if use_hub else 2, dtype=np.int64)
    ends[0] = n_beam
    span_ends[0], span_ends[1] = nl, n_beam
    if use_hub:
        for m in range(n_beam, n_beam + n_ha):
            a_t[2, m] = 1.0
        for m in range(n_beam + n_ha, n_all):
            a_t[3, m] = 1.0
        lo[2], hi[2] = n_beam, n_beam + n_ha
        lo[3], hi[3] = n_beam + n_ha, n_all
        ends[1] = n_all
        span_ends[2], span_ends[3] = n_beam + n_ha, n_all
    return a_t, b, u, lo, hi, ends, span_ends


@kernel
def _after_k(
    a_t: NDArray[np.float64],
    r: NDArray[np.float64],
    gram_inv: NDArray[np.float64],
    infl: float,
    keep: NDArray[np.bool_],
    nl: int,
    nr: int,
    g_shape: NDArray[np.float64],
) -> tuple[NDArray[np.float64], float, int, float, float]:
    """:func:`_fit_joint`'s statistics from the fit (residuals ``r``, inverse normal
    matrix, inflation, inliers ``keep``): the covariance ``gram^-1 infl``, the tip's
    standard uncertainty along the shape gradient ``g_shape`` (the shape's rows are
    the last of ``a_t``), the beam's inliers' count and RMS residual, and the hub's
    (NaN: none)."""
    nan = np.nan
    n_coef, n_all = a_t.shape
    p_shape = g_shape.shape[0]
    first = n_coef - p_shape
    n_beam = nl + nr
    use_hub = n_all > n_beam
    cov = gram_inv * infl
    # g cov g over the shape's block (the tip gradient is 0 on the other coefficients)
    tip_var = 0.0
    for i in range(p_shape):
        s = 0.0
        for j in range(p_shape):
            s += g_shape[j] * cov[first + j, first + i]
        tip_var += s * g_shape[i]
    n_kb = 0
    ss = 0.0
    for m in range(n_beam):
        if keep[m]:
            n_kb += 1
            ss += r[m] * r[m]
    rms = math.sqrt(ss / n_kb)
    hub_rms = nan
    if use_hub:
        n_kh = 0
        ss = 0.0
        for m in range(n_beam, n_all):
            if keep[m]:
                n_kh += 1
                ss += r[m] * r[m]
        hub_rms = math.sqrt(ss / n_kh)
    return cov, math.sqrt(max(tip_var, 0.0)), n_kb, rms, hub_rms
