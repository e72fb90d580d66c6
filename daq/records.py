"""Acquisition records: what devices produce and what the run log stores.

Frozen dataclasses of numpy arrays. Every time is an ``int64`` count of nanoseconds on
the run clock (zero = the DAQ's first sample), the same clock MCAP ``log_time`` uses.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

N_GAUGES = 4
N_CHANNELS = 5  # potentiometer, then gauges 1-4
EVENT_LEVELS = ("info", "warning", "error")


def _as_array(name: str, value: Any, dtype: Any, shape_tail: tuple[int, ...]) -> np.ndarray:
    arr = np.ascontiguousarray(value, dtype=dtype)
    if arr.ndim != 1 + len(shape_tail) or arr.shape[1:] != shape_tail:
        want = "(N" + "".join(f", {s}" for s in shape_tail) + ")"
        raise ValueError(f"{name} must have shape {want}, got {arr.shape}")
    arr.setflags(write=False)
    return arr


def _check_times(name: str, value: Any) -> np.ndarray:
    arr = np.asarray(value)
    if arr.dtype.kind not in "iu":
        raise TypeError(f"{name} must hold integer nanoseconds, got dtype {arr.dtype}")
    return _as_array(name, arr, np.int64, ())


@dataclass(frozen=True, eq=False)
class RawBlock:
    """One block from a strain DAQ at its acquisition rate, before filtering.

    Attributes
    ----------
    t_ns : ndarray of int64, shape (N,)
        Sample times on the run clock, ns.
    volts : ndarray of float64, shape (N, 5)
        Potentiometer volts, then the four bridge output volts (gauge order).
    first_sequence : int
        Index of the first sample since the start of acquisition; a jump between
        consecutive blocks means samples were lost.
    clipped_channels : tuple of int
        Channels (0 = potentiometer, 1-4 = gauges) that hit the ADC range in this block.
    events : tuple of Event
        What the device itself reported with this block (overruns, lost samples).
    """

    t_ns: np.ndarray
    volts: np.ndarray
    first_sequence: int
    clipped_channels: tuple[int, ...] = ()
    events: tuple[Event, ...] = ()

    def __post_init__(self) -> None:
        t = _check_times("t_ns", self.t_ns)
        v = _as_array("volts", self.volts, np.float64, (N_CHANNELS,))
        if len(v) != len(t):
            raise ValueError(f"volts has {len(v)} rows but t_ns has {len(t)} samples")
        if self.first_sequence < 0:
            raise ValueError(f"first_sequence must be >= 0, got {self.first_sequence!r}")
        object.__setattr__(self, "t_ns", t)
        object.__setattr__(self, "volts", v)
        object.__setattr__(self, "first_sequence", int(self.first_sequence))

    def __len__(self) -> int:
        return len(self.t_ns)


@dataclass(frozen=True, eq=False)
class SampleBlock:
    """Samples of the 400 Hz stream (after anti-alias filtering and decimation).

    Attributes
    ----------
    t_ns : ndarray of int64, shape (N,)
        Sample times on the run clock, ns (filter group delay already removed).
    rocker_angle_rad : ndarray, shape (N,)
        Rocker (hub) angle from the potentiometer, rad.
    strain : ndarray, shape (N, 4)
        Surface strain (m/m) of the four gauges, ordered by distance from the clamp.
    raw_volts : ndarray, shape (N, 5)
        The filtered volts they came from: potentiometer, then gauges 1-4.
    first_sequence : int
        Output-sample index of the first row (consecutive rows count up by one unless
        samples were dropped; a block never spans a drop in a log read back).
    """

    t_ns: np.ndarray
    rocker_angle_rad: np.ndarray
    strain: np.ndarray
    raw_volts: np.ndarray
    first_sequence: int

    def __post_init__(self) -> None:
        t = _check_times("t_ns", self.t_ns)
        a = _as_array("rocker_angle_rad", self.rocker_angle_rad, np.float64, ())
        s = _as_array("strain", self.strain, np.float64, (N_GAUGES,))
        v = _as_array("raw_volts", self.raw_volts, np.float64, (N_CHANNELS,))
        for name, arr in (("rocker_angle_rad", a), ("strain", s), ("raw_volts", v)):
            if len(arr) != len(t):
                raise ValueError(f"{name} has {len(arr)} rows but t_ns has {len(t)} samples")
        if self.first_sequence < 0:
            raise ValueError(f"first_sequence must be >= 0, got {self.first_sequence!r}")
        object.__setattr__(self, "t_ns", t)
        object.__setattr__(self, "rocker_angle_rad", a)
        object.__setattr__(self, "strain", s)
        object.__setattr__(self, "raw_volts", v)
        object.__setattr__(self, "first_sequence", int(self.first_sequence))

    def __len__(self) -> int:
        return len(self.t_ns)

    def __eq__(self, other: object) -> bool:
        """Bit-identical arrays and the same first sequence."""
        if not isinstance(other, SampleBlock):
            return NotImplemented
        return (
            self.first_sequence == other.first_sequence
            and np.array_equal(self.t_ns, other.t_ns)
            and _bits_equal(self.rocker_angle_rad, other.rocker_angle_rad)
            and _bits_equal(self.strain, other.strain)
            and _bits_equal(self.raw_volts, other.raw_volts)
        )

    __hash__ = None  # type: ignore[assignment]

    def slice(self, start: int, stop: int) -> SampleBlock:
        """Rows ``start:stop`` (``first_sequence`` advanced by ``start``)."""
        return SampleBlock(
            self.t_ns[start:stop],
            self.rocker_angle_rad[start:stop],
            self.strain[start:stop],
            self.raw_volts[start:stop],
            self.first_sequence + start,
        )

    @staticmethod
    def empty() -> SampleBlock:
        return SampleBlock(
            np.zeros(0, np.int64),
            np.zeros(0),
            np.zeros((0, N_GAUGES)),
            np.zeros((0, N_CHANNELS)),
            0,
        )

    @staticmethod
    def concatenate(blocks: Sequence[SampleBlock]) -> SampleBlock:
        """Join blocks in order; ``first_sequence`` is the first block's."""
        blocks = [b for b in blocks if len(b)]
        if not blocks:
            return SampleBlock.empty()
        return SampleBlock(
            np.concatenate([b.t_ns for b in blocks]),
            np.concatenate([b.rocker_angle_rad for b in blocks]),
            np.concatenate([b.strain for b in blocks]),
            np.concatenate([b.raw_volts for b in blocks]),
            blocks[0].first_sequence,
        )


def _bits_equal(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and bool(np.array_equal(a.view(np.uint64), b.view(np.uint64)))


@dataclass(frozen=True)
class Frame:
    """One encoded camera image.

    Attributes
    ----------
    t_ns : int
        Mid-exposure time on the run clock, ns (as the camera reports it).
    sequence : int
        The camera's frame counter; a jump means frames were dropped.
    data : bytes
        The encoded image (``encoding``).
    encoding : str
        ``"jpeg"`` or ``"png"``.
    width_px, height_px : int
        Image size; images are indexed ``[row, col]``.
    """

    t_ns: int
    sequence: int
    data: bytes = field(repr=False)
    encoding: str
    width_px: int
    height_px: int

    def __post_init__(self) -> None:
        if self.encoding not in ("jpeg", "png"):
            raise ValueError(f"encoding must be 'jpeg' or 'png', got {self.encoding!r}")
        if not isinstance(self.data, bytes | bytearray | memoryview):
            raise TypeError(f"data must be bytes, got {type(self.data).__name__}")
        if self.width_px <= 0 or self.height_px <= 0:
            raise ValueError(f"width_px and height_px must be positive, got {self.width_px!r}")
        if self.sequence < 0:
            raise ValueError(f"sequence must be >= 0, got {self.sequence!r}")
        object.__setattr__(self, "data", bytes(self.data))
        object.__setattr__(self, "t_ns", int(self.t_ns))


@dataclass(frozen=True)
class Event:
    """Something the run should remember: start, stop, drops, overruns, clipping, errors.

    ``level`` is ``"info"``, ``"warning"`` or ``"error"``; ``name`` is a short key such as
    ``"start"``, ``"stop"``, ``"dropped_samples"``, ``"dropped_frames"``, ``"overrun"``,
    ``"clipping"``, ``"device_error"``.
    """

    t_ns: int
    level: str
    name: str
    message: str

    def __post_init__(self) -> None:
        if self.level not in EVENT_LEVELS:
            raise ValueError(f"level must be one of {EVENT_LEVELS}, got {self.level!r}")
        if not self.name:
            raise ValueError("name must be a non-empty string")
        object.__setattr__(self, "t_ns", int(self.t_ns))


def sample_times_ns(first_sequence: int, n: int, rate_hz: float) -> np.ndarray:
    """Times (int64 ns) of samples ``first_sequence .. first_sequence + n - 1`` at ``rate_hz``.

    Exact integer arithmetic when ``rate_hz`` divides 1e9 into whole nanoseconds.
    """
    seq = np.arange(first_sequence, first_sequence + n, dtype=np.int64)
    period_ns = 1e9 / rate_hz
    if abs(period_ns - round(period_ns)) < 1e-9:
        return seq * np.int64(round(period_ns))
    return np.rint(seq * period_ns).astype(np.int64)
