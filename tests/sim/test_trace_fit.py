"""FittedTraceDrive: a potentiometer trace as a smooth drive, against the analytic four-bar.

The trace is made the way the bench makes it, but not with beambench's defaults: a
four-bar of other proportions at another crank speed, its angle sampled at 2 kHz with
white noise, the anti-alias Butterworth and the decimation to 400 Hz of ``daq.antialias``
(with its group-delay correction). The errors are predicted from that physics: the
noise a least-squares harmonic fit passes, the harmonics it leaves out, the filter's own
distortion of the harmonics it keeps.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from scipy import signal

from daq.antialias import AntiAliasDecimator, design_antialias
from daq.config import DaqConfig
from sim.drives import Drive, FourBarDrive, SinusoidDrive, TraceDrive
from sim.errors import SimInputError
from sim.four_bar import FourBar
from sim.trace_fit import FittedTraceDrive, spline_passband

FS_ACQ_HZ = 2000.0
NOISE_RAD = 6e-4  # at 2 kHz, before the filter (the bench's pot: 0.5 mV ~ 5.9e-4 rad)
CRANK_HZ = 0.81
FOUR_BAR = FourBar(0.35, 0.05, 0.335, 0.07)  # not the bench's 0.34/0.045/0.33/0.065


def _measured(
    duration_s: float, seed: int, angle_of_t: object = None
) -> tuple[np.ndarray, np.ndarray, FourBarDrive, Any]:
    """400 Hz samples of the four-bar angle as the DAQ delivers them, the true drive on
    the output clock, and the anti-alias filter's design (its group delay the DAQ
    removed)."""
    true = FourBarDrive(FOUR_BAR, 2 * math.pi * CRANK_HZ, about="absolute", crank_phase_rad=1.1)
    design = design_antialias(DaqConfig(), FS_ACQ_HZ)
    n = round((duration_s + 0.5) * FS_ACQ_HZ)
    t_acq = np.arange(n) / FS_ACQ_HZ
    rng = np.random.default_rng(seed)
    clean = true.angle(t_acq) if angle_of_t is None else angle_of_t(t_acq)  # type: ignore[operator]
    volts = (clean + rng.normal(0.0, NOISE_RAD, n))[:, None]
    out = AntiAliasDecimator(design, 1).process(np.round(t_acq * 1e9).astype(np.int64), volts, 0)
    return out.t_ns * 1e-9, out.volts[:, 0], true, design


def _harmonics(n_harm: int) -> np.ndarray:
    """Amplitudes (rad) of the four-bar angle's harmonics 1..n_harm (exact, by FFT of the
    closed form over one crank turn)."""
    psi = np.linspace(0.0, 2 * math.pi, 4096, endpoint=False)
    spec = np.fft.rfft(FOUR_BAR.rocker_angle_rad(psi)) / 2048
    return np.abs(spec[1 : n_harm + 1])


def _predicted_rms(order: int, kept: int, span_s: float, design: object) -> float:
    """RMS error of the ``order``-th derivative of a least-squares fit of ``kept``
    harmonics: the noise it passes (per coefficient variance S / T with S the noise's
    one-sided PSD), the harmonics beyond ``kept``, the anti-alias filter's gain and
    residual phase at the kept ones (its group delay at 1 Hz is removed by the DAQ)."""
    w = 2 * math.pi * CRANK_HZ
    m = np.arange(1, 61)
    amp = _harmonics(60)
    psd = NOISE_RAD**2 / (FS_ACQ_HZ / 2)
    f = m * CRANK_HZ
    _, h = signal.sosfreqz(design.sos, worN=f, fs=FS_ACQ_HZ)  # type: ignore[attr-defined]
    h = h * np.exp(2j * math.pi * f * design.group_delay_s)  # type: ignore[attr-defined]
    weight = (m * w) ** (2 * order)
    noise = np.sum(weight[:kept] * psd / span_s)
    truncation = np.sum(weight[kept:] * amp[kept:] ** 2 / 2)
    filt = np.sum(weight[:kept] * amp[:kept] ** 2 * np.abs(h[:kept] - 1) ** 2 / 2)
    return math.sqrt(noise + truncation + filt)


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x**2)))


def test_fitted_drive_errors_on_a_filtered_noisy_four_bar_trace() -> None:
    t, y, true, design = _measured(20.0, seed=11)
    d = FittedTraceDrive(t, y)
    assert isinstance(d, Drive)
    s = d.settings
    assert s["kind"] == "harmonics"  # a periodic run: GCV wants no spline on top
    assert s["fundamental_hz"] == pytest.approx(CRANK_HZ, rel=1e-6)
    # the residual is the noise after the filter: white PSD over its ~150 Hz pass band
    # (the Butterworth's equivalent noise bandwidth, from its own response)
    ff, hh = signal.sosfreqz(design.sos, worN=20000, fs=FS_ACQ_HZ)
    enbw_hz = float(np.trapezoid(np.abs(hh) ** 2, ff))
    sigma_out = NOISE_RAD * math.sqrt(enbw_hz / (FS_ACQ_HZ / 2))
    assert s["residual_rms_rad"] == pytest.approx(sigma_out, rel=0.05)
    kept = int(s["harmonics"])
    span = float(t[-1] - t[0])
    # each harmonic coefficient's noise variance: the in-band PSD (white before the filter,
    # which is flat below 40 Hz) over the span; Welch over ~19 segments resolves it to ~5 %
    found = d.harmonic_uncertainty()
    assert found is not None and found[1] == kept
    assert found[2] == pytest.approx(NOISE_RAD**2 / (FS_ACQ_HZ / 2) / span, rel=0.1)
    inside = (t > t[0] + 0.25) & (t < t[-1] - 0.25)
    ends = ~inside
    for order, name in enumerate(("angle", "rate", "accel")):
        err = getattr(d, name)(t) - getattr(true, name)(t)
        bound = _predicted_rms(order, kept, span, design)
        # RMS of a few weighted Gaussian coefficients (dominated by the top harmonics):
        # within twice its expectation with ~99.7 % probability; the ends are no worse
        # (a harmonic fit has no end conditions)
        assert _rms(err[inside]) < 2.0 * bound, (name, _rms(err[inside]), bound)
        assert _rms(err[ends]) < 2.0 * bound, (name, _rms(err[ends]), bound)


def test_fitted_drive_beats_the_smoothing_spline_it_replaces() -> None:
    t, y, true, _ = _measured(8.0, seed=12)
    fitted = FittedTraceDrive(t, y)
    spline = TraceDrive(t, y)
    inside = (t > t[0] + 0.5) & (t < t[-1] - 0.5)
    for name in ("rate", "accel"):
        e_fit = _rms((getattr(fitted, name)(t) - getattr(true, name)(t))[inside])
        e_spl = _rms((getattr(spline, name)(t) - getattr(true, name)(t))[inside])
        assert e_fit < e_spl, name


def test_a_trace_that_does_not_repeat_gets_a_spline() -> None:
    # the crank speeding up by 30 % over the run: not one fundamental frequency
    w0 = 2 * math.pi * CRANK_HZ
    duration = 10.0

    def phase(t: np.ndarray) -> np.ndarray:
        return w0 * (t + 0.15 * t**2 / duration)

    def angle(t: np.ndarray) -> np.ndarray:
        return 0.7 * np.sin(phase(np.asarray(t, float)))

    t, y, _, _ = _measured(duration, seed=13, angle_of_t=angle)
    d = FittedTraceDrive(t, y)
    assert d.settings["kind"] in ("spline", "harmonics+spline")
    h = 1e-4
    inside = (t > t[0] + 0.5) & (t < t[-1] - 0.5)
    tt = t[inside]
    acc_true = (angle(tt + h) - 2 * angle(tt) + angle(tt - h)) / h**2
    spline = TraceDrive(t, y)
    e_fit = _rms(d.accel(tt) - acc_true)
    assert e_fit < _rms(spline.accel(tt) - acc_true)
    # the fit's own consistency: rate and accel are its derivatives
    g = 1e-5
    mid = tt[::50]
    assert d.rate(mid) == pytest.approx((d.angle(mid + g) - d.angle(mid - g)) / (2 * g), abs=1e-6)
    assert d.accel(mid) == pytest.approx((d.rate(mid + g) - d.rate(mid - g)) / (2 * g), abs=1e-4)


def test_fitted_drive_bridges_a_gap_and_refuses_what_it_cannot_fit() -> None:
    rng = np.random.default_rng(14)
    t = np.arange(0.0, 6.0, 1.0 / 400.0)
    true = SinusoidDrive(0.7669, 4.970)
    y = true.angle(t) + rng.normal(0.0, 2e-4, t.size)
    y[800:860] = np.nan  # 0.15 s lost
    d = FittedTraceDrive(t, y)
    gap = t[800:860]
    assert np.abs(d.accel(gap) - true.accel(gap)).max() < 0.01 * 0.7669 * 4.970**2
    with pytest.raises(SimInputError, match="t_s must lie within"):
        d.angle(7.0)
    with pytest.raises(SimInputError, match="finite samples"):
        FittedTraceDrive(t[:5], y[:5])
    with pytest.raises(SimInputError, match="length of t_s"):
        FittedTraceDrive(t, y[:-1])


@pytest.mark.parametrize("spacing_s", [0.02, 0.1, 0.5])
def test_the_spline_passband_is_what_a_least_squares_spline_keeps(spacing_s: float) -> None:
    """spline_passband's closed form against least-squares quintic splines actually fitted
    to sinusoids (dense samples, the middle of the span), and its integral: a band of
    1 / (2 h)."""
    from scipy.interpolate import make_lsq_spline

    f_edge = 0.5 / spacing_s
    assert np.trapezoid(
        spline_passband(np.linspace(0, 4 * f_edge, 40001), spacing_s), dx=4 * f_edge / 40000
    ) == pytest.approx(f_edge, rel=1e-4)
    span = 60 * spacing_s
    t = np.linspace(0.0, span, 6000)
    inner = np.arange(1, 60) * spacing_s
    knots = np.r_[np.zeros(6), inner, np.full(6, span)]
    mid = (t > 0.3 * span) & (t < 0.7 * span)
    for v in (0.1, 0.3, 0.45, 0.5, 0.55, 0.7):
        f = v / spacing_s
        kept = []
        for phase in np.linspace(0, np.pi, 8, endpoint=False):
            y = np.cos(2 * np.pi * f * t + phase)
            fit = make_lsq_spline(t, y, knots, 5)(t)
            # the share of power kept: |response|^2 where the fit is a scaled copy
            kept.append(np.sum(fit[mid] * y[mid]) / np.sum(y[mid] ** 2))
        assert np.mean(kept) == pytest.approx(spline_passband(f, spacing_s), abs=0.02), v


def test_splines_fitted_together_are_each_ones_alone_bit_for_bit() -> None:
    # the spline alone and the spline of the harmonics' residual share each spacing's
    # fit (one factorisation, one evaluation); each column must be what a fit of it
    # alone (a 1-D trace) gives, bit for bit, and that the least-squares spline scipy's
    # make_lsq_spline gives (the same normal equations summed in another order: to
    # rounding), with the same choices
    from scipy.interpolate import BSpline, make_lsq_spline

    from sim.trace_fit import SPLINE_DEGREE, _best_splines, _gcv, _lsq_spline

    rng = np.random.default_rng(23)
    t = np.cumsum(rng.uniform(0.002, 0.003, size=3000))  # uneven, ~7.5 s
    a = np.sin(2.1 * t) + 0.3 * np.sin(7.3 * t) + 1e-3 * rng.normal(size=t.size)
    b = 0.01 * np.sin(0.4 * t) + 2e-4 * rng.normal(size=t.size)
    together = _best_splines(t, np.column_stack((a, b)), [0, 9])
    for y, p_other, got in ((a, 0, together[0]), (b, 9, together[1])):
        # the best spacing as a fit of this column alone finds it
        best, best_g = None, (_gcv(float(np.sum(y**2)), t.size, p_other) if p_other else math.inf)
        for h in (0.02, 0.03, 0.04, 0.05, 0.07, 0.1, 0.15, 0.2, 0.3, 0.5, 1.0):
            fit = _lsq_spline(t, y, h)
            assert fit is not None
            alone = BSpline.construct_fast(fit[0].t, fit[0].c, SPLINE_DEGREE)
            scipy_fit = make_lsq_spline(t, y, fit[0].t, SPLINE_DEGREE, method="norm-eq")
            scale = np.max(np.abs(scipy_fit.c))
            assert np.max(np.abs(alone.c - scipy_fit.c)) <= 1e-12 * scale
            assert np.max(np.abs(fit[2] - scipy_fit(t))) <= 1e-12 * np.max(np.abs(y))
            rss = float(np.sum((fit[2] - y) ** 2))
            assert rss == pytest.approx(float(np.sum((scipy_fit(t) - y) ** 2)), rel=1e-11)
            g = _gcv(rss, t.size, p_other + fit[1])
            if g < best_g:
                best, best_g = (alone, fit[1], h, rss), g
        assert best is not None and got[0] is not None
        assert got[1:] == best[1:]  # coefficients, spacing, RSS (exactly)
        assert np.array_equal(got[0].t, best[0].t) and np.array_equal(got[0].c, best[0].c)
        assert np.array_equal(got[0](t).view(np.int64), best[0](t).view(np.int64))
        d2 = got[0].derivative(2)(t)
        assert np.array_equal(d2.view(np.int64), best[0].derivative(2)(t).view(np.int64))


def test_the_kept_cos_and_sin_are_the_times_asked_for() -> None:
    """The rate and the acceleration at the same times share one cos and sin (the batched
    solver asks for both at every stage time of a run); other times, of the same shape or
    changed in place, are computed afresh: every value bit for bit a fresh drive's."""
    t, y, _, _ = _measured(8.0, seed=14)
    d, fresh = FittedTraceDrive(t, y), FittedTraceDrive(t, y)
    ts = np.linspace(t[0] + 0.5, t[-1] - 0.5, 3001)
    other = ts[::-1].copy()
    for times in (ts, ts, other, ts[:-1], ts[0]):
        for name in ("rate", "accel", "angle"):
            np.testing.assert_array_equal(getattr(d, name)(times), getattr(fresh, name)(times))
            fresh = FittedTraceDrive(t, y)
    inplace = ts.copy()
    before = d.rate(inplace)
    inplace += 0.1
    after = d.rate(inplace)
    assert not np.array_equal(before, after)
    np.testing.assert_array_equal(after, FittedTraceDrive(t, y).rate(inplace))


def test_the_harmonic_basis_is_the_cosines_and_sines_to_rounding() -> None:
    """The harmonics as powers of exp(i w t) (a running product): within the rounding of
    the phases m w t themselves, on a minute at 400 Hz with 40 harmonics of 0.92 Hz
    (measured 1.3e-12 from numpy's cos and sin of the phases, each ~6e-13 from the
    exact values)."""
    from sim.trace_fit import _harmonic_basis

    tc = np.arange(-12000, 12000) / 400.0
    w = 2.0 * math.pi * 0.92
    basis = _harmonic_basis(tc, w, 40)
    phase = np.outer(tc, w * np.arange(1, 41))
    assert np.array_equal(basis[:, 0], np.ones(tc.size))
    assert np.max(np.abs(basis[:, 1::2] - np.cos(phase))) < 3e-12
    assert np.max(np.abs(basis[:, 2::2] - np.sin(phase))) < 3e-12
    one = _harmonic_basis(tc, w, 1)  # a single harmonic: no product at all
    exact = np.column_stack((np.cos(w * tc), np.sin(w * tc)))
    np.testing.assert_allclose(one[:, 1:], exact, rtol=0.0, atol=1e-15)


def test_rate_and_accel_in_one_call_are_each_ones_bit_for_bit() -> None:
    """``rate_accel`` (what the fixed-step FE beam's hub terms call) gives :meth:`rate` and
    :meth:`accel` exactly, for harmonics and for a spline, and the beam driven through it
    moves as through the two calls, bit for bit."""
    from sim.beam import BeamProperties
    from sim.config import BeamConfig
    from sim.models.fe import simulate_fe

    t, y, _, _ = _measured(8.0, seed=14)
    chirp = 0.3 * np.sin(0.7 * t + 0.05 * t**2)
    for drive in (FittedTraceDrive(t, y), FittedTraceDrive(t, chirp)):
        ts = np.linspace(t[0] + 0.5, t[-1] - 0.5, 501)
        for times in (ts, ts[:5], ts[3]):
            rate, accel = drive.rate_accel(times)
            assert np.array_equal(rate, drive.rate(times))
            assert np.array_equal(accel, drive.accel(times))

    class TwoCalls:  # the same drive without rate_accel
        def __init__(self, inner: FittedTraceDrive) -> None:
            self.angle, self.rate, self.accel = inner.angle, inner.rate, inner.accel

    drive = FittedTraceDrive(t, y)
    beam = BeamProperties.from_config(BeamConfig())
    times = np.linspace(t[0], t[0] + 0.5, 51)
    kw: dict[str, Any] = {"n_elements": 2, "a0_per_s": 0.1, "a1_s": 0.1, "method": "radau5"}
    one = simulate_fe(beam, drive, times, fixed_step_s=0.025, stages=5, rtol=1e-7, atol=1e-7, **kw)
    two = simulate_fe(
        beam, TwoCalls(drive), times, fixed_step_s=0.025, stages=5, rtol=1e-7, atol=1e-7, **kw
    )
    assert np.array_equal(one.station_lateral_m, two.station_lateral_m)
