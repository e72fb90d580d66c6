"""A measured hub-angle trace as a drive the stiff solvers integrate cheaply and accurately.

:class:`sim.drives.TraceDrive` puts a cubic smoothing spline through every sample: its third
derivative jumps at each 2.5 ms knot (400 Hz), so the acceleration the beam feels has a kink
there and an error-controlled implicit solver crawls (radau5 took 34.5 s for 6 s of the
demo run, against ~0.03 s per simulated second on the smooth Eq. 53 drive). And the noise
it passes between the crank's harmonics shakes the simulated tip.

:class:`FittedTraceDrive` fits a model with few parameters instead, by least squares:

- **harmonics** of a fundamental frequency fitted to the trace (the crank's; the bench
  turns at ~0.92 Hz and the rocker's harmonics matter to ~10-20 Hz): a periodic run is
  described by a few numbers, the noise between the harmonics is rejected, and the fit has
  no ends to treat (it is the same function at every cycle). It keeps the harmonics whose
  power the trace resolves above its noise (:func:`_harmonics_kept`);
- plus a **quintic least-squares B-spline** of what the harmonics leave (a crank speed that
  drifts, a start or stop), knots equally spaced, the spacing chosen from
  :data:`KNOT_SPACINGS_S`, or no spline at all, by generalised cross-validation (GCV,
  ``n RSS / (n - p)^2`` with ``p`` parameters: each candidate is a linear least-squares
  fit, so its trace is ``p``);
- or, when GCV prefers it (the trace does not repeat), the quintic spline alone.

Quintic: angle, rate and acceleration are continuous with two more continuous derivatives,
so the forcing is smooth between knots tens of milliseconds apart. A least-squares spline
has no end conditions (a smoothing spline's natural ends force the acceleration to zero);
its last knot interval is fitted from the samples inside it only.

On the demo run (20 s, pot noise 0.23 mrad RMS after the anti-alias filter) it keeps 10
harmonics and no spline: the acceleration is within 0.031 rad/s^2 RMS of the four-bar's
(TraceDrive: 0.51, of 18.6 RMS), and the simulated tip within 0.007 mm RMS of the one the
true drive gives (TraceDrive: 0.041 mm, max 0.13; both with the modal model).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sim.drives import finite_trace
from sim.errors import SimInputError

FloatArray = NDArray[np.float64]

SPLINE_DEGREE = 5
# aliases summed in spline_passband's denominator each side (sinc^12 beyond them: < 1e-16)
SPLINE_ALIASES = 30
# Candidate knot spacings, s: 20 ms (the trace's bandwidth far beyond the beam's second
# mode, ~23 Hz) to 1 s (only a drift left for the spline).
KNOT_SPACINGS_S = (0.02, 0.03, 0.04, 0.05, 0.07, 0.1, 0.15, 0.2, 0.3, 0.5, 1.0)
# Harmonics are tried up to this frequency, Hz, and at most this many of them.
MAX_HARMONIC_HZ = 40.0
MAX_HARMONICS = 40
# The fundamental is found if the trace holds at least this many of its periods.
MIN_CYCLES = 3.0
# A harmonic is kept if noise alone would give its power with at most this probability
# (over all candidates).
HARMONIC_FALSE_ALARM = 0.01
UNRESOLVED_RUN = 3
# the decay of the harmonics' powers beyond the kept ones: fitted to this many of the last
# kept, and no slower than this ratio per harmonic (see _dropped_power)
DECAY_FIT_HARMONICS = 4
MAX_DECAY_RATIO = 0.7
# Harmonics used while the fundamental frequency is refined.
FREQUENCY_SEARCH_HARMONICS = 6


def _gcv(rss: float, n: int, p: int) -> float:
    return n * rss / (n - p) ** 2 if p < n else math.inf


def _bspline_basis(knots: FloatArray, span: NDArray[np.intp], x: FloatArray) -> FloatArray:
    """The ``SPLINE_DEGREE + 1`` B-splines that are nonzero on each knot interval
    ``[knots[span], knots[span + 1])``, at the points ``x`` in it: (k + 1, n), the first
    row the B-spline starting ``k`` knots before ``span`` (Cox-de Boor, vectorised over
    the points: Piegl and Tiller's ``BasisFuns``)."""
    k = SPLINE_DEGREE
    n_b = np.zeros((k + 1, x.size))
    n_b[0] = 1.0
    left = np.empty((k + 1, x.size))
    right = np.empty((k + 1, x.size))
    for d in range(1, k + 1):
        left[d] = x - knots[span + 1 - d]
        right[d] = knots[span + d] - x
        saved = np.zeros(x.size)
        for r in range(d):
            temp = n_b[r] / (right[r + 1] + left[d - r])
            n_b[r] = saved + right[r + 1] * temp
            saved = left[d - r] * temp
        n_b[d] = saved
    return n_b


# The uniform quintic B-spline's pieces: on a knot interval with local coordinate u in
# [0, 1), its six nonzero B-splines are [1, u, .., u^5] @ this (rows: powers; columns: the
# B-spline starting five intervals before first): M_ij = C(k, i) sum_{l >= j} (-1)^(l - j)
# C(k + 1, l - j) (k - l)^(k - i) / k!
_UNIFORM_QUINTIC = (
    np.array(
        [
            [1.0, 26.0, 66.0, 26.0, 1.0, 0.0],
            [-5.0, -50.0, 0.0, 50.0, 5.0, 0.0],
            [10.0, 20.0, -60.0, 20.0, 10.0, 0.0],
            [-10.0, 20.0, 0.0, -20.0, 10.0, 0.0],
            [5.0, -20.0, 30.0, -20.0, 5.0, 0.0],
            [-1.0, 5.0, -10.0, 10.0, -5.0, 1.0],
        ]
    )
    / 120.0
)


def _uniform_bspline_basis(
    knots: FloatArray, interval: NDArray[np.intp], x: FloatArray, spacing_s: float, n_int: int
) -> FloatArray:
    """:func:`_bspline_basis` for :func:`_lsq_spline`'s knots (``n_int`` intervals
    ``spacing_s`` apart from ``knots[k]``, the ends clamped, the last stretched): where the
    interval's 2 k surrounding knots are uniform, the uniform B-spline's polynomial pieces
    (one product, a third of the recursion's time; the same values to rounding), near the
    ends the recursion."""
    k = SPLINE_DEGREE
    span = interval + k
    u = (x - knots[span]) / spacing_s
    powers = np.empty((k + 1, x.size))
    powers[0] = 1.0
    for d in range(1, k + 1):
        np.multiply(powers[d - 1], u, out=powers[d])
    basis = _UNIFORM_QUINTIC.T @ powers
    # the B-splines on interval j use knots j + 1 .. j + 2 k: uniform for k - 1 <= j <=
    # n_int - 1 - k
    edge = (interval < k - 1) | (interval > n_int - 1 - k)
    if edge.any():
        basis[:, edge] = _bspline_basis(knots, span[edge], x[edge])
    return basis


def _lsq_spline(
    t: FloatArray, y: FloatArray, spacing_s: float
) -> tuple[Any, int, FloatArray] | None:
    """Quintic least-squares B-spline with knots ``spacing_s`` apart (the last interval
    stretched to end at ``t[-1]``) of ``y`` (``(n,)``, or ``(n, m)``: a spline of each
    column, fitted together), its number of coefficients and its values at ``t``; None
    when the samples do not support it (a gap wider than a knot interval, too few
    samples).

    By the banded normal equations, as scipy's ``make_lsq_spline(method="norm-eq")`` (the
    same Cholesky factorisation of the same matrix; only the order of the sums differs,
    coefficients within 1e-12 of it): each sample's six nonzero B-splines once, the
    products summed per knot interval. scipy's took 2.5-16 ms a fit on a minute at 400 Hz
    (longer the more knots) and 1.6 ms more for the values; this 3.5-5."""
    from scipy.interpolate import BSpline
    from scipy.linalg import cho_solve_banded, cholesky_banded

    k = SPLINE_DEGREE
    n_int = max(1, math.floor((t[-1] - t[0]) / spacing_s))
    inner = t[0] + spacing_s * np.arange(1, n_int)
    knots = np.r_[np.full(k + 1, t[0]), inner, np.full(k + 1, t[-1])]
    p = knots.size - k - 1
    if p >= t.size:
        return None
    # Schoenberg-Whitney: every knot interval needs samples (the trace may have gaps)
    counts = np.histogram(t, bins=np.r_[t[0], inner, t[-1]])[0]
    if np.any(counts < 1):
        return None
    two_d = y.ndim == 2
    ys = y if two_d else y[:, None]
    interval = np.searchsorted(inner, t, side="right")  # 0 .. n_int - 1, non-decreasing
    basis = _uniform_bspline_basis(knots, interval, t, spacing_s, n_int)
    starts = np.searchsorted(interval, np.arange(n_int))
    # (k + 1, n): the sums over the samples run along each B-spline's contiguous values
    gram = np.add.reduceat(basis[:, None, :] * basis[None, :, :], starts, axis=2)
    proj = np.add.reduceat(basis[:, None, :] * ys.T[None, :, :], starts, axis=2)
    # the lower band of B^T B (row d: the d-th subdiagonal) and B^T y: interval j adds
    # its (k + 1) x (k + 1) block at the coefficients j .. j + k
    band = np.zeros((k + 1, p))
    rhs = np.zeros((p, ys.shape[1]))
    for a in range(k + 1):
        rhs[a : a + n_int] += proj[a].T
        for d in range(k + 1 - a):
            band[d, a : a + n_int] += gram[a, a + d]
    try:
        coef = cho_solve_banded((cholesky_banded(band, lower=True), True), rhs)
    except (ValueError, np.linalg.LinAlgError):
        return None
    # each sample's k + 1 coefficients, (n, m, k + 1), in one gather
    window = np.lib.stride_tricks.sliding_window_view(coef, k + 1, axis=0)[interval]
    values = np.einsum("an,nma->nm", basis, window)
    if not two_d:
        coef, values = coef[:, 0], values[:, 0]
    return BSpline.construct_fast(knots, coef, k), p, values


def _best_splines(
    t: FloatArray, ys: FloatArray, p_others: list[int]
) -> list[tuple[Any, int, float, float]]:
    """For each column of ``ys`` (``(n, m)``), the GCV-best spline (None: no spline), its
    coefficients, spacing and RSS; ``p_others[j]`` parameters are already spent on the
    rest of column ``j``'s model. The columns share each spacing's fit (one factorisation
    of the normal equations, one evaluation of the basis): each column's coefficients
    and values are those a fit of that column alone gives, bit for bit (tested)."""
    from scipy.interpolate import BSpline

    n = t.size
    best: list[tuple[Any, int, float, float]] = []
    best_gcv: list[float] = []
    for j, p_other in enumerate(p_others):
        best.append((None, 0, math.inf, float(np.sum(ys[:, j] ** 2))))
        best_gcv.append(_gcv(best[j][3], n, p_other) if p_other > 0 else math.inf)
    for h in KNOT_SPACINGS_S:
        fit = _lsq_spline(t, ys, h)
        if fit is None:
            continue
        spline, p, values = fit
        for j, p_other in enumerate(p_others):
            rss = float(np.sum((values[:, j] - ys[:, j]) ** 2))
            g = _gcv(rss, n, p_other + p)
            if g < best_gcv[j]:
                column = BSpline.construct_fast(
                    spline.t, np.ascontiguousarray(spline.c[:, j]), spline.k
                )
                best[j], best_gcv[j] = (column, p, h, rss), g
    return best


def _harmonic_basis(tc: FloatArray, omega: float, n_harm: int) -> FloatArray:
    """Columns 1, cos(w t), sin(w t), cos(2 w t), ... (``2 n_harm + 1`` of them).

    The m-th harmonic as the m-th power of exp(i w t) (a running product: a sixth of the
    time of a cosine and a sine of every phase, 18 ms for 40 harmonics of a minute at
    400 Hz). Its rounding grows as m: 40 harmonics within 1e-14 of the cosines, which
    carry the rounding of the phase m w t itself (up to 7e3 rad there: 1e-12)."""
    z = np.empty((n_harm, tc.size), dtype=complex)
    z[0] = np.exp(1j * (omega * tc))
    for m in range(1, n_harm):
        np.multiply(z[m - 1], z[0], out=z[m])
    cols = np.empty((tc.size, 2 * n_harm + 1))
    cols[:, 0] = 1.0
    cols[:, 1::2] = z.real.T
    cols[:, 2::2] = z.imag.T
    return cols


def _projections(basis: FloatArray, y: FloatArray) -> FloatArray:
    """``Q^T y`` for ``basis = Q R``, by the normal equations: ``R`` is the Cholesky
    factor of ``basis^T basis`` (harmonics over several periods are nearly orthogonal, so
    it is well conditioned). ``cumsum(result**2)`` is the explained sum of squares of the
    nested models made of the first columns."""
    from scipy.linalg import cho_factor, solve_triangular

    upper, _ = cho_factor(basis.T @ basis, lower=False)
    return np.asarray(solve_triangular(upper, basis.T @ y, trans="T", lower=False))


def _welch(t: FloatArray, resid: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The one-sided PSD (rad^2/Hz) of a residual sampled at times ``t`` (resampled onto
    a uniform grid: the trace may have gaps), Welch with 2 s segments: (frequencies, PSD)."""
    from scipy.signal import welch

    dt = float(t[-1] - t[0]) / (t.size - 1)
    grid = np.linspace(t[0], t[-1], t.size)
    f, pxx = welch(np.interp(grid, t, resid), fs=1.0 / dt, nperseg=min(t.size, round(2.0 / dt)))
    return np.asarray(f, dtype=float), np.asarray(pxx, dtype=float)


def _noise_psd(t: FloatArray, resid: FloatArray, f_max_hz: float, n_fitted: int) -> float:
    """The noise's mean one-sided PSD (rad^2/Hz) below ``f_max_hz``, from the residual of
    a fit of ``n_fitted`` parameters in that band (Welch, 2 s segments): the noise where
    the harmonics are, whatever the anti-alias filter did above (the pot's noise after a
    150 Hz filter is white below it, not up to 200 Hz). The band holds ``2 f_max T``
    degrees of freedom of which the fit took ``n_fitted`` (6 % over 16 cycles): the
    residual's PSD is scaled up by that share."""
    f, pxx = _welch(t, resid)
    band = (f > 0) & (f <= f_max_hz)
    psd = float(np.mean(pxx[band])) if band.any() else float(np.mean(pxx[1:]))
    dof = 2.0 * f_max_hz * float(t[-1] - t[0])
    return psd / max(1.0 - n_fitted / dof, 0.5)


def spline_passband(f_hz: ArrayLike, spacing_s: float) -> FloatArray:
    """The share of a sinusoid's power at ``f_hz`` that a least-squares spline of degree
    :data:`SPLINE_DEGREE` with knots ``spacing_s`` apart keeps (dense samples, away from
    the ends): the orthogonal projection onto the cardinal splines has the response
    ``|b(v)|^2 / sum_j |b(v + j)|^2`` at ``v = f h``, with ``b(v) = sinc(v)^(k + 1)`` the
    B-spline's Fourier transform (Unser, Aldroubi & Eden 1993). It is ~1 below
    ``1 / (2 h)``, ~0 above, and its integral over ``f >= 0`` is ``1 / (2 h)``: the band
    a spline of ``T / h`` coefficients fills."""
    v = np.asarray(f_hz, dtype=float) * spacing_s
    power = 2 * (SPLINE_DEGREE + 1)
    alias = np.sum(
        [np.sinc(v + j) ** power for j in range(-SPLINE_ALIASES, SPLINE_ALIASES + 1)], axis=0
    )
    return np.asarray(np.sinc(v) ** power / alias, dtype=float)


def _white_psd_above(t: FloatArray, resid: FloatArray, band_hz: float) -> float:
    """The residual's mean one-sided PSD (rad^2/Hz) between ``1.5 band_hz`` and a quarter
    of the sample rate (Welch, 2 s segments): the noise's level beyond what a fit of
    bandwidth ``band_hz`` took out of it, below the anti-alias filter's roll-off (the
    DAQ's filter passes 0.375 of the rate), where the potentiometer's noise is white. NaN
    when that band is empty."""
    f, pxx = _welch(t, resid)
    rate_hz = (t.size - 1) / float(t[-1] - t[0])
    band = (f >= 1.5 * band_hz) & (f <= 0.25 * rate_hz)
    return float(np.mean(pxx[band])) if band.any() else math.nan


def _harmonics_kept(
    coef: FloatArray, omega: float, t: FloatArray, resid: FloatArray
) -> tuple[int, float]:
    """How many harmonics to keep: up to the highest one whose fitted power stands out of
    the noise, at a false-alarm probability of :data:`HARMONIC_FALSE_ALARM` over all
    the candidates.

    Each fitted coefficient carries the noise's variance ``V = S / T`` (S: the one-sided
    PSD at the harmonics, T: the trace's span), so a harmonic of pure noise has a fitted
    power ``(a^2 + b^2) / 2`` distributed as ``V`` times a unit exponential: it exceeds
    ``V ln(M / alpha)`` with probability ``alpha / M`` for each of M candidates. A harmonic
    below that is not resolved and is dropped; its acceleration (its amplitude times
    ``(m omega)^2``) would be mostly noise. GCV on the angle keeps too many: on a four-bar
    whose harmonics decay slowly it kept 23 where 13 resolve them, with a 4x larger
    acceleration error. Returns the number kept and ``V`` (rad^2)."""
    m_max = (coef.size - 1) // 2
    span = float(t[-1] - t[0])
    v = _noise_psd(t, resid, m_max * omega / (2.0 * math.pi), coef.size) / span
    power = 0.5 * (coef[1::2] ** 2 + coef[2::2] ** 2)
    resolved = power > v * math.log(m_max / HARMONIC_FALSE_ALARM)
    # up to the last resolved harmonic before UNRESOLVED_RUN unresolved ones in a row (a
    # symmetric linkage's even harmonics may vanish; noise far above the last real
    # harmonic must not pull in everything below it)
    kept = 1
    for m in range(1, m_max + 1):
        if resolved[m - 1]:
            kept = m
        elif m - kept >= UNRESOLVED_RUN:
            break
    return kept, v


def _dropped_power(power: FloatArray, kept: int, var: float) -> FloatArray:
    """Estimated powers (rad^2) of the harmonics above the kept ones, up to the last fitted.

    Their fitted powers are mostly noise, so they are extrapolated instead: a linkage's
    angle is an analytic periodic function of the crank angle, whose harmonics decay
    geometrically; the ratio is fitted to the last :data:`DECAY_FIT_HARMONICS` kept ones
    (their powers less the noise's share V), at most :data:`MAX_DECAY_RATIO`."""
    m = np.arange(1, power.size + 1)
    last = np.arange(max(0, kept - DECAY_FIT_HARMONICS), kept)
    p = power[last] - var
    good = p > 0
    if good.sum() >= 2:
        slope, icpt = np.polyfit(m[last][good], np.log(p[good]), 1)
        ratio = min(math.exp(float(slope)), MAX_DECAY_RATIO)
        p_kept = math.exp(float(icpt + slope * kept))
    else:
        ratio, p_kept = MAX_DECAY_RATIO, max(float(power[kept - 1]) - var, var)
    return np.asarray(p_kept * ratio ** (m[kept:] - kept), dtype=float)


def _fundamental(tc: FloatArray, y: FloatArray) -> float | None:
    """The fundamental angular frequency (rad/s) of a trace that repeats, or None.

    The windowed spectrum's peak, refined by least squares over +-1 bin with
    :data:`FREQUENCY_SEARCH_HARMONICS` harmonics."""
    from scipy.optimize import minimize_scalar

    span = float(tc[-1] - tc[0])
    dt = span / (tc.size - 1)
    # resample onto a uniform grid for the FFT (the trace may have gaps)
    grid = np.linspace(tc[0], tc[-1], tc.size)
    yg = np.interp(grid, tc, y)
    yg = yg - np.polyval(np.polyfit(grid, yg, 1), grid)
    spec = np.abs(np.fft.rfft(yg * np.hanning(yg.size)))
    freq = np.fft.rfftfreq(yg.size, dt)
    k = int(np.argmax(spec[1:])) + 1
    if freq[k] * span < MIN_CYCLES:
        return None
    n_h = max(1, min(FREQUENCY_SEARCH_HARMONICS, int(MAX_HARMONIC_HZ / freq[k])))

    def rss(omega: float) -> float:
        basis = _harmonic_basis(tc, omega, n_h)
        return float(y @ y) - float(np.sum(_projections(basis, y) ** 2))

    df = freq[1]
    lo, hi = 2.0 * math.pi * (freq[k] - df), 2.0 * math.pi * (freq[k] + df)
    found = minimize_scalar(rss, bounds=(lo, hi), method="bounded", options={"xatol": 1e-7})
    return float(found.x)


class FittedTraceDrive:
    """A measured hub-angle trace (e.g. the 400 Hz potentiometer) as harmonics of its
    fundamental plus a quintic least-squares spline, the model chosen by GCV (see the
    module docstring). Same interface as :class:`sim.drives.TraceDrive`.

    Parameters
    ----------
    t_s : (N,) sample times, strictly increasing, s.
    angle_rad : (N,) hub angle, rad; NaN marks a missing sample.

    Attributes
    ----------
    settings : dict: ``kind`` (``"harmonics"``, ``"harmonics+spline"`` or ``"spline"``),
        ``harmonics``, ``fundamental_hz``, ``knot_spacing_s`` (NaN: no spline),
        ``n_parameters``, ``residual_rms_rad`` (the fit's residual, ~ the trace's noise).
    """

    def __init__(self, t_s: ArrayLike, angle_rad: ArrayLike) -> None:
        t, y = finite_trace(t_s, angle_rad, 2 * (SPLINE_DEGREE + 1))
        self.t_min_s = float(t[0])
        self.t_max_s = float(t[-1])
        self._t_ref_s = 0.5 * (self.t_min_s + self.t_max_s)
        tc = t - self._t_ref_s
        n = t.size

        # the harmonics first, so that the spline of their residual shares each spacing's
        # fit with the spline alone (:func:`_best_splines`)
        omega = _fundamental(tc, y)
        if omega is not None:
            m_max = max(1, min(MAX_HARMONICS, int(2.0 * math.pi * MAX_HARMONIC_HZ / omega)))
            basis = _harmonic_basis(tc, omega, m_max)
            full = np.linalg.solve(basis.T @ basis, basis.T @ y)
            m_best, coef_var = _harmonics_kept(full, omega, t, y - basis @ full)
            b = basis[:, : 2 * m_best + 1]
            coef = np.linalg.solve(b.T @ b, b.T @ y)
            resid = y - b @ coef
            p_h = 2 * m_best + 2  # the frequency is a parameter too
            fits = _best_splines(t, np.column_stack((y, resid)), [0, p_h])
        else:
            fits = _best_splines(t, y[:, None], [0])

        # the spline alone
        spline, p_s, h_s, rss_s = fits[0]
        best_gcv = _gcv(rss_s, n, p_s) if spline is not None else math.inf
        self._omega = 0.0
        # the harmonics' noise (see harmonic_uncertainty); NaN without harmonics; with a
        # spline on top, from the residual of both (below)
        self.coefficient_var_rad2 = math.nan
        self.dropped_power_rad2 = np.zeros(0)
        self._coef = np.zeros(1)  # the spline carries the mean
        self._spline = spline
        kind, n_harm, h_best, p_best, rss_best = "spline", 0, h_s, p_s, rss_s

        if omega is not None:
            r_spline, r_p, r_h, r_rss = fits[1]
            g = _gcv(r_rss, n, p_h + r_p)
            if g < best_gcv:
                best_gcv = g
                self._omega, self._coef, self._spline = omega, coef, r_spline
                n_harm, h_best, p_best, rss_best = m_best, r_h, p_h + r_p, r_rss
                kind = "harmonics" if r_spline is None else "harmonics+spline"
                self.coefficient_var_rad2 = coef_var
                power = 0.5 * (full[1::2] ** 2 + full[2::2] ** 2)
                self.dropped_power_rad2 = _dropped_power(power, m_best, coef_var)
        if self._spline is None and kind == "spline":
            raise SimInputError("angle_rad", "no spline could be fitted to the trace")
        self._n_harm = n_harm
        w = self._omega * np.arange(1, n_harm + 1)
        ca, cb = self._coef[1::2], self._coef[2::2]
        self._w = w
        # cosine and sine coefficients of the angle, the rate and the acceleration
        self._ab = ((ca, cb), (w * cb, -w * ca), (-w * w * ca, -w * w * cb))
        self._last: tuple[float, FloatArray, FloatArray] | None = None
        self._last_many: tuple[FloatArray, FloatArray, FloatArray] | None = None
        self._d1 = self._spline.derivative(1) if self._spline is not None else None
        self._d2 = self._spline.derivative(2) if self._spline is not None else None
        self.settings: dict[str, Any] = {
            "kind": kind,
            "harmonics": n_harm,
            "fundamental_hz": self._omega / (2.0 * math.pi) if n_harm else math.nan,
            "knot_spacing_s": h_best if math.isfinite(h_best) else math.nan,
            "n_parameters": p_best,
            "residual_rms_rad": math.sqrt(rss_best / max(n - p_best, 1)),
        }
        # the spline's noise (see spline_uncertainty); NaN without a spline
        self.spline_noise_psd_rad2_hz = math.nan
        if self._spline is not None:
            resid = y - self._harmonics(t, 0) - self._spline(t)
            band_hz = 0.5 / h_best
            self.spline_noise_psd_rad2_hz = _white_psd_above(t, resid, band_hz)
            if n_harm:
                # the harmonics' residual held what the spline then took (a drifting
                # crank): their noise is the pot's white noise, and the spline carries
                # what lies beyond them within its band
                self.coefficient_var_rad2 = self.spline_noise_psd_rad2_hz / (
                    self.t_max_s - self.t_min_s
                )
                self.dropped_power_rad2 = np.zeros(0)

    def time_scale_s(self) -> float:
        """The shortest time scale of the fitted motion, s: the period of the highest kept
        harmonic and the spline's knot spacing, the shorter (see
        :func:`sim.drives.drive_time_scale_s`)."""
        scale = math.inf
        if self._n_harm:
            scale = 2.0 * math.pi / (self._omega * self._n_harm)
        if self._spline is not None:
            scale = min(scale, float(self.settings["knot_spacing_s"]))
        return scale

    def harmonic_uncertainty(self) -> tuple[float, int, float, FloatArray] | None:
        """What the fit leaves uncertain, for a harmonic fit (None for a spline alone):
        ``(fundamental rad/s, harmonics kept, V, dropped)``: each kept harmonic's cosine and
        sine coefficients carry the noise's variance ``V`` (rad^2), and ``dropped`` (rad^2)
        are the powers of the harmonics above the kept ones, extrapolated from the kept
        ones' decay (:func:`_dropped_power`): an estimate of what was left out."""
        if self._n_harm == 0:
            return None
        return self._omega, self._n_harm, self.coefficient_var_rad2, self.dropped_power_rad2

    def spline_uncertainty(self) -> tuple[float, float] | None:
        """What the spline leaves uncertain (None without a spline): ``(h, S)``, its knot
        spacing (s) and the noise's one-sided PSD ``S`` (rad^2/Hz) it was fitted through.

        The spline passes the noise's PSD times :func:`spline_passband` (``p / T``
        coefficients per second pass a variance ``S p / T``, as a band ``1 / (2 h)`` wide
        would). ``S`` is measured on the residual above that band
        (:func:`_white_psd_above`), where the spline took nothing out of the noise."""
        if self._spline is None:
            return None
        return float(self.settings["knot_spacing_s"]), self.spline_noise_psd_rad2_hz

    def _check(self, t_s: ArrayLike) -> FloatArray:
        t = np.asarray(t_s, dtype=float)
        span = self.t_max_s - self.t_min_s
        # min/max once: the solvers call with one time at a time, thousands of times
        lo, hi = (float(t), float(t)) if t.ndim == 0 else (float(t.min()), float(t.max()))
        if lo < self.t_min_s - 1e-9 * span or hi > self.t_max_s + 1e-9 * span:
            raise SimInputError(
                "t_s", f"must lie within the trace, [{self.t_min_s!r}, {self.t_max_s!r}] s"
            )
        return t

    def _cos_sin(self, t: FloatArray) -> tuple[FloatArray, FloatArray]:
        # the solvers ask for the rate and the acceleration at the same times: one time
        # at a time (the adaptive ones) or every stage time of a run at once (the batched
        # linear Radau), so the last times' cos and sin are kept
        if t.ndim == 0:
            if self._last is not None and self._last[0] == float(t):
                return self._last[1], self._last[2]
        elif self._last_many is not None and np.array_equal(self._last_many[0], t):
            return self._last_many[1], self._last_many[2]
        phase = np.multiply.outer(t - self._t_ref_s, self._w)
        c, s = np.cos(phase), np.sin(phase)
        if t.ndim == 0:
            self._last = (float(t), c, s)
        else:
            self._last_many = (t.copy(), c, s)
        return c, s

    def _harmonics(self, t: FloatArray, order: int) -> FloatArray:
        if self._n_harm == 0:
            return np.full(t.shape, self._coef[0] if order == 0 else 0.0)
        c, s = self._cos_sin(t)
        a, b = self._ab[order]
        out = c @ a + s @ b
        return np.asarray(self._coef[0] + out if order == 0 else out)

    def angle(self, t_s: ArrayLike) -> FloatArray:
        t = self._check(t_s)
        out = self._harmonics(t, 0)
        return out if self._spline is None else out + self._spline(t)

    def rate(self, t_s: ArrayLike) -> FloatArray:
        t = self._check(t_s)
        out = self._harmonics(t, 1)
        return out if self._d1 is None else out + self._d1(t)

    def accel(self, t_s: ArrayLike) -> FloatArray:
        t = self._check(t_s)
        out = self._harmonics(t, 2)
        return out if self._d2 is None else out + self._d2(t)

    def rate_accel(self, t_s: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """:meth:`rate` and :meth:`accel` at the same times in one call, bit for bit theirs
        (the fixed-step FE beam asks for both at every stage time: one check and one
        cosine and sine of the phases instead of two, without the kept times' lookup)."""
        t = self._check(t_s)
        if self._n_harm == 0:
            rate, accel = np.zeros(t.shape), np.zeros(t.shape)
        else:
            phase = np.multiply.outer(t - self._t_ref_s, self._w)
            c, s = np.cos(phase), np.sin(phase)
            (a1, b1), (a2, b2) = self._ab[1], self._ab[2]
            rate, accel = np.asarray(c @ a1 + s @ b1), np.asarray(c @ a2 + s @ b2)
        if self._d1 is not None and self._d2 is not None:
            rate, accel = rate + self._d1(t), accel + self._d2(t)
        return rate, accel
