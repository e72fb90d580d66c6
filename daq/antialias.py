"""Anti-alias filtering and decimation of the acquisition stream.

The paper's Butterworth (pass band 150 Hz, stop band 200 Hz) only makes sense before a
400 Hz stream exists: acquire faster, filter causally at the acquisition rate, keep every
``D``-th sample. The filter state and the decimation phase carry across blocks, so a
stream filtered block by block equals the whole record filtered at once. Output times
have the filter's low-frequency group delay removed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import signal

from daq.config import DaqConfig
from daq.errors import DaqInputError
from daq.records import RawBlock

GROUP_DELAY_REFERENCE_HZ = 1.0  # the bench's motion is ~1 Hz: delay is corrected there
# Outputs are withheld after a (re)start until the start-up transient is below this
# fraction of (slope x group delay): ~45 ms for the bench's filter, 0.03 microstrain at the
# bench's fastest strain change (~4400 microstrain/s).
SETTLE_REL = 1e-3


@dataclass(frozen=True, eq=False)
class AntiAliasDesign:
    """A causal Butterworth low-pass in second-order sections, at the acquisition rate.

    Attributes
    ----------
    sos : ndarray, shape (n_sections, 6)
    order : int
    cutoff_hz : float
        -3 dB frequency.
    acquisition_rate_hz, output_rate_hz : float
    decimation : int
        ``acquisition_rate_hz / output_rate_hz``.
    group_delay_s : float
        Group delay at ``GROUP_DELAY_REFERENCE_HZ``; subtracted from output times.
    passband_hz, stopband_hz, passband_ripple_db, stopband_attenuation_db : float
        The specification it meets.
    """

    sos: np.ndarray
    order: int
    cutoff_hz: float
    acquisition_rate_hz: float
    output_rate_hz: float
    decimation: int
    group_delay_s: float
    passband_hz: float
    stopband_hz: float
    passband_ripple_db: float
    stopband_attenuation_db: float

    @property
    def group_delay_ns(self) -> int:
        return round(self.group_delay_s * 1e9)

    def settle_s(self, rel: float = SETTLE_REL) -> float:
        """Time after a (re)start for the start-up transient to fall below ``rel``.

        The filter restarts in the steady state of its first sample, as if the signal had
        been constant before; for a signal moving at slope ``v`` the output is then off by
        up to ``v * group_delay_s``, decaying with the filter's memory. This is the time
        after which a unit ramp's error stays below ``rel * group_delay_s``.
        """
        fs = self.acquisition_rate_hz
        n = max(16, round(20.0 * self.group_delay_s * fs))
        t = np.arange(n) / fs
        y, _ = signal.sosfilt(self.sos, t, zi=signal.sosfilt_zi(self.sos) * 0.0)
        err = np.abs(y - (t - self.group_delay_s))
        tail = np.maximum.accumulate(err[::-1])[::-1]
        above = np.flatnonzero(tail >= rel * self.group_delay_s)
        return float((above[-1] + 1) / fs) if above.size else 0.0

    def describe(self) -> dict[str, object]:
        """JSON-friendly summary for the run metadata."""
        return {
            "type": "butterworth lowpass, causal, second-order sections",
            "order": self.order,
            "cutoff_hz": self.cutoff_hz,
            "passband_hz": self.passband_hz,
            "stopband_hz": self.stopband_hz,
            "passband_ripple_db": self.passband_ripple_db,
            "stopband_attenuation_db": self.stopband_attenuation_db,
            "acquisition_rate_hz": self.acquisition_rate_hz,
            "output_rate_hz": self.output_rate_hz,
            "decimation": self.decimation,
            "group_delay_s": self.group_delay_s,
            "group_delay_reference_hz": GROUP_DELAY_REFERENCE_HZ,
            "timestamps": "group delay removed: t = acquisition time - group_delay_s",
            "initial_state": "steady state for the first sample",
            "restart": "after a gap the filter restarts the same way",
            "settle_s": self.settle_s(),
            "settling": "outputs within settle_s of a (re)start are not emitted",
        }


def design_antialias(config: DaqConfig, acquisition_rate_hz: float) -> AntiAliasDesign:
    """Design the anti-alias filter at the rate the hardware really runs.

    Parameters
    ----------
    config : DaqConfig
        Pass/stop band edges, ripple, attenuation and the output rate.
    acquisition_rate_hz : float
        Actual sample rate read back from the device, Hz. Must be a whole multiple of
        ``config.output_rate_hz`` and at least twice ``config.stopband_hz``.
    """
    fs = float(acquisition_rate_hz)
    if not np.isfinite(fs) or fs <= 0:
        raise DaqInputError(f"acquisition_rate_hz must be positive, got {acquisition_rate_hz!r}")
    ratio = fs / config.output_rate_hz
    decimation = round(ratio)
    if decimation < 1 or abs(ratio - decimation) > 1e-6 * ratio:
        raise DaqInputError(
            f"acquisition_rate_hz ({fs!r}) must be a whole multiple of output_rate_hz "
            f"({config.output_rate_hz!r})"
        )
    if config.stopband_hz >= 0.5 * fs:
        raise DaqInputError(
            f"acquisition_rate_hz ({fs!r}) must be more than twice stopband_hz "
            f"({config.stopband_hz!r}): the filter has to act before the rate is reduced"
        )
    order, wn = signal.buttord(
        config.passband_hz,
        config.stopband_hz,
        config.passband_ripple_db,
        config.stopband_attenuation_db,
        fs=fs,
    )
    sos = signal.butter(order, wn, btype="lowpass", output="sos", fs=fs)
    delay_s = 0.0
    for section in sos:
        _, gd = signal.group_delay((section[:3], section[3:]), w=[GROUP_DELAY_REFERENCE_HZ], fs=fs)
        delay_s += float(gd[0]) / fs  # group_delay returns samples
    return AntiAliasDesign(
        sos=sos,
        order=int(order),
        cutoff_hz=float(wn),
        acquisition_rate_hz=fs,
        output_rate_hz=float(config.output_rate_hz),
        decimation=decimation,
        group_delay_s=delay_s,
        passband_hz=config.passband_hz,
        stopband_hz=config.stopband_hz,
        passband_ripple_db=config.passband_ripple_db,
        stopband_attenuation_db=config.stopband_attenuation_db,
    )


@dataclass(frozen=True, eq=False)
class DecimatedBlock:
    """Filtered, decimated output of one input block.

    ``t_ns`` (M,) int64 on the run clock (group delay removed), ``volts`` (M, n_channels),
    ``first_sequence``: output-sample index of the first row (input sequence // D).
    """

    t_ns: np.ndarray
    volts: np.ndarray
    first_sequence: int


class AntiAliasDecimator:
    """Streaming filter + decimator with explicit carried state.

    Output samples are the filtered input samples whose acquisition sequence number is a
    multiple of ``decimation``, so the decimation phase is tied to the hardware sample
    count and survives block boundaries and dropped blocks. The filter starts in the
    steady state of the first sample (no start-up transient on the potentiometer's DC),
    and so does it again after a gap in the sequence numbers (a dropped block): carrying
    the state across the jump would ring for ~0.1 s (85 microstrain on the bench).
    Outputs within ``design.settle_s()`` of a (re)start, and those whose corrected time
    would be negative, are not emitted: the stream's gaps are honest and what is emitted
    has settled.
    """

    def __init__(self, design: AntiAliasDesign, n_channels: int = 5) -> None:
        if n_channels < 1:
            raise DaqInputError(f"n_channels must be >= 1, got {n_channels!r}")
        self.design = design
        self.n_channels = n_channels
        self._zi: np.ndarray | None = None
        self._next_sequence: int | None = None
        self._settle_n = math.ceil(design.settle_s() * design.acquisition_rate_hz)
        self._emit_from_sequence = 0

    def process(self, t_ns: np.ndarray, volts: np.ndarray, first_sequence: int) -> DecimatedBlock:
        """Filter one block and return its decimated rows.

        Parameters
        ----------
        t_ns : ndarray of int64, shape (N,)
            Input sample times, ns.
        volts : ndarray, shape (N, n_channels)
        first_sequence : int
            Acquisition index of the first input sample.
        """
        x = np.asarray(volts, dtype=np.float64)
        if x.ndim != 2 or x.shape[1] != self.n_channels:
            raise ValueError(f"volts must have shape (N, {self.n_channels}), got {x.shape}")
        if len(t_ns) != len(x):
            raise ValueError(f"t_ns has {len(t_ns)} samples but volts has {len(x)} rows")
        d = self.design.decimation
        if len(x) == 0:
            return DecimatedBlock(np.zeros(0, np.int64), x, first_sequence // d)
        if self._zi is None or first_sequence != self._next_sequence:
            zi0 = signal.sosfilt_zi(self.design.sos)  # (n_sections, 2)
            self._zi = zi0[:, :, None] * x[0][None, None, :]
            self._emit_from_sequence = first_sequence + self._settle_n
        y, self._zi = signal.sosfilt(self.design.sos, x, axis=0, zi=self._zi)
        self._next_sequence = first_sequence + len(x)
        # the first settled input whose sequence number is a multiple of d
        skip = max(0, self._emit_from_sequence - first_sequence)
        offset = skip + (-(first_sequence + skip)) % d
        keep = slice(offset, None, d)
        t_out = np.asarray(t_ns, dtype=np.int64)[keep] - np.int64(self.design.group_delay_ns)
        y_out = y[keep]
        first_out = (first_sequence + offset) // d
        valid = t_out >= 0
        if not valid.all():
            n_bad = int(np.count_nonzero(~valid))  # only ever a prefix: times increase
            t_out, y_out, first_out = t_out[n_bad:], y_out[n_bad:], first_out + n_bad
        return DecimatedBlock(t_out, np.ascontiguousarray(y_out), first_out)

    def reset(self) -> None:
        """Forget the filter state (the next block starts a new steady state)."""
        self._zi = None
        self._next_sequence = None
        self._emit_from_sequence = 0


def filter_and_decimate(design: AntiAliasDesign, block: RawBlock) -> DecimatedBlock:
    """One-shot version for a whole record (used to check the streaming path)."""
    return AntiAliasDecimator(design, block.volts.shape[1]).process(
        block.t_ns, block.volts, block.first_sequence
    )
