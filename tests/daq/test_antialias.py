"""Anti-alias design meets the spec; streaming equals one-shot; tones; delay correction."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from daq.antialias import AntiAliasDecimator, design_antialias, filter_and_decimate
from daq.config import DaqConfig
from daq.records import RawBlock, sample_times_ns

CFG = DaqConfig()
FS = 2000.0


def _raw(x: np.ndarray, first: int = 0) -> RawBlock:
    return RawBlock(sample_times_ns(first, len(x), FS), x, first)


def _tone(f_hz: float, n: int, phase: float = 0.3) -> np.ndarray:
    t = np.arange(n) / FS
    x = np.zeros((n, 5))
    x[:, :] = np.sin(2 * np.pi * f_hz * t + phase)[:, None]
    return x


def test_design_meets_the_pass_and_stop_band_spec() -> None:
    d = design_antialias(CFG, FS)
    assert d.decimation == 5
    _, h = signal.sosfreqz(d.sos, worN=[1.0, 100.0, 150.0, 200.0, 300.0, 999.0], fs=FS)
    gain_db = 20 * np.log10(np.abs(h))
    assert gain_db[0] == pytest.approx(0.0, abs=1e-6)
    assert gain_db[2] >= -1.0 - 1e-9  # pass band edge
    assert gain_db[3] <= -40.0 + 1e-9  # stop band edge
    assert np.all(gain_db[4:] <= -40.0)
    # the minimum order: one less cannot meet both edges
    lower = signal.butter(d.order - 1, d.cutoff_hz, output="sos", fs=FS)
    _, hl = signal.sosfreqz(lower, worN=[150.0, 200.0], fs=FS)
    gl = 20 * np.log10(np.abs(hl))
    assert gl[0] < -1.0 or gl[1] > -40.0


def test_rates_that_do_not_decimate_evenly_are_refused() -> None:
    with pytest.raises(ValueError, match="acquisition_rate_hz"):
        design_antialias(CFG, 2083.333)
    with pytest.raises(ValueError, match="acquisition_rate_hz"):
        design_antialias(CFG, 400.0)  # below twice the stop band


def test_chunked_equals_one_shot_for_random_block_sizes() -> None:
    d = design_antialias(CFG, FS)
    rng = np.random.default_rng(7)
    x = rng.normal(size=(4003, 5)) + np.array([2.0, 0.0, 1e-3, -1e-3, 0.0])
    whole = filter_and_decimate(d, _raw(x, first=3))
    for trial in range(5):
        dec = AntiAliasDecimator(d, 5)
        cuts = np.sort(rng.choice(np.arange(1, len(x)), size=20 + 10 * trial, replace=False))
        parts_t, parts_v, firsts = [], [], []
        for a, b in zip([0, *cuts], [*cuts, len(x)], strict=True):
            out = dec.process(sample_times_ns(3 + a, b - a, FS), x[a:b], 3 + a)
            parts_t.append(out.t_ns)
            parts_v.append(out.volts)
            if len(out.t_ns):
                firsts.append(out.first_sequence)
        np.testing.assert_array_equal(np.concatenate(parts_t), whole.t_ns)
        np.testing.assert_allclose(np.concatenate(parts_v), whole.volts, rtol=0, atol=1e-12)
        assert firsts[0] == whole.first_sequence
        assert np.all(
            np.concatenate(parts_t) % 2_500_000 == (2_500_000 - d.group_delay_ns) % 2_500_000
        )


def _amplitude(y: np.ndarray, t_s: np.ndarray, f_hz: float) -> float:
    a = np.column_stack([np.sin(2 * np.pi * f_hz * t_s), np.cos(2 * np.pi * f_hz * t_s)])
    coef, *_ = np.linalg.lstsq(a, y, rcond=None)
    return float(np.hypot(*coef))


def test_100_hz_passes_within_1_db() -> None:
    d = design_antialias(CFG, FS)
    out = filter_and_decimate(d, _raw(_tone(100.0, 8000)))
    keep = slice(200, None)  # after the start-up transient
    t = out.t_ns[keep] * 1e-9
    amp = _amplitude(out.volts[keep, 2], t, 100.0)
    assert 10 ** (-1 / 20) <= amp <= 1.0 + 1e-9


def test_300_hz_is_at_least_40_db_down_after_decimation() -> None:
    """300 Hz at the acquisition rate would alias to 100 Hz in the 400 Hz stream."""
    d = design_antialias(CFG, FS)
    out = filter_and_decimate(d, _raw(_tone(300.0, 8000)))
    y = out.volts[200:, 1]
    rms = float(np.sqrt(np.mean(y**2)))
    assert rms * np.sqrt(2) <= 10 ** (-40 / 20)


def test_group_delay_is_removed_from_the_timestamps() -> None:
    """A 1 Hz sine read back at the corrected times matches the sine at those times."""
    d = design_antialias(CFG, FS)
    n = 6000
    t_in = np.arange(n) / FS
    x = np.repeat(np.sin(2 * np.pi * 1.0 * t_in)[:, None], 5, axis=1)
    out = filter_and_decimate(d, _raw(x))
    t_out = out.t_ns * 1e-9
    err = np.abs(out.volts[100:, 0] - np.sin(2 * np.pi * t_out[100:]))
    uncorrected = 2 * np.pi * d.group_delay_s  # error slope without the correction
    assert d.group_delay_s > 0.005
    assert err.max() < 1e-3 * uncorrected
    assert np.all(out.t_ns >= 0)


def test_a_dropped_block_restarts_the_filter_instead_of_ringing() -> None:
    """Carrying the filter state across a lost block feeds it a jump: the output would
    ring for ~0.1 s. After a gap the filter restarts settled on the new data and withholds
    its settling time, so every emitted sample is as good as in a gapless stream."""
    d = design_antialias(CFG, FS)
    n_block = 200
    x = _tone(1.0, 40 * n_block)  # 1 Hz: the bench's motion
    full = AntiAliasDecimator(d)
    gappy = AntiAliasDecimator(d)
    ref, out = [], []
    for k in range(40):
        raw = _raw(x[k * n_block : (k + 1) * n_block], k * n_block)
        ref.append(full.process(raw.t_ns, raw.volts, raw.first_sequence))
        if k != 12:  # block 12 is lost
            out.append(gappy.process(raw.t_ns, raw.volts, raw.first_sequence))
    ref_t = np.concatenate([b.t_ns for b in ref])
    ref_v = np.concatenate([b.volts[:, 0] for b in ref])
    got_t = np.concatenate([b.t_ns for b in out])
    got_v = np.concatenate([b.volts[:, 0] for b in out])
    # nothing is emitted from the gap until the settling time after it has passed
    t_restart = 13 * n_block / FS - d.group_delay_s
    after = got_t * 1e-9 > 12 * n_block / FS
    assert got_t[after][0] * 1e-9 >= t_restart + d.settle_s() - 1.0 / FS
    assert 0.02 < d.settle_s() < 0.1
    # what is emitted matches the gapless stream: within the settling criterion
    # (1e-3 of slope x group delay, slope 2 pi here)
    common = np.isin(ref_t, got_t)
    assert np.abs(got_v - ref_v[common]).max() < 1e-3 * 2 * np.pi * d.group_delay_s
