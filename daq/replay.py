"""Replay: a run log back as the records the drivers produced, in log-time order,
optionally paced to the wall clock (the one replay engine; ``beambench replay`` sends
its records to Rerun)."""

from __future__ import annotations

import heapq
import os
from collections.abc import Iterable, Iterator
from typing import Any

import numpy as np

from daq.clock import Clock, MonotonicClock
from daq.errors import DaqInputError
from daq.log.format import TOPIC_CAMERA_INFO, TOPIC_EVENTS, TOPIC_IMAGE, TOPIC_SAMPLES, TOPICS
from daq.log.reader import RunLog, iter_frames, read_run
from daq.records import Event, Frame, SampleBlock

Record = SampleBlock | Frame | Event

BLOCK_SAMPLES = 40  # longest sample block by default: 0.1 s at 400 Hz


class LogReplay:
    """A run log opened for replay: samples, events and metadata read (:attr:`run`),
    frames read lazily by :meth:`records`.

    Parameters
    ----------
    path : str or Path
    topics : iterable of str, optional
        Any of ``/daq/samples``, ``/camera/image``, ``/events`` (default: all three).
    start_ns, end_ns : int, optional
        Half-open log-time window, ns.
    max_block_samples : int or None
        Longest sample block yielded (None: no limit); blocks also end at a sequence gap
        and before any frame or event with a later-or-equal time, so the order is strict.

    Raises
    ------
    DaqInputError
        An unknown topic or a block length below 1.
    LogError
        Missing, truncated, corrupt or not a beambench log.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        topics: Iterable[str] | None = None,
        start_ns: int | None = None,
        end_ns: int | None = None,
        max_block_samples: int | None = BLOCK_SAMPLES,
    ) -> None:
        if max_block_samples is not None and max_block_samples < 1:
            raise DaqInputError(f"max_block_samples must be >= 1, got {max_block_samples!r}")
        if topics is None:
            want = list(TOPICS)
        else:
            want = [topics] if isinstance(topics, str) else list(topics)
        unknown = sorted(set(want) - set(TOPICS))
        if unknown:
            raise DaqInputError(f"topics: unknown topic {unknown[0]!r}; expected some of {TOPICS}")
        self.path = path
        self.topics = want
        self.start_ns = start_ns
        self.end_ns = end_ns
        self.max_block_samples = max_block_samples
        self.run: RunLog = read_run(
            path,
            topics=[t for t in want if t in (TOPIC_SAMPLES, TOPIC_EVENTS)] or [TOPIC_CAMERA_INFO],
            start_ns=start_ns,
            end_ns=end_ns,
        )

    def records(
        self, *, speed: float | None = None, clock: Clock | None = None
    ) -> Iterator[Record]:
        """Yield ``SampleBlock``, ``Frame`` and ``Event`` records merged in log-time order.

        Parameters
        ----------
        speed : float or None
            ``None``: as fast as possible. Otherwise each record is yielded when the wall
            clock reaches its log time, scaled so that ``speed`` seconds of run time pass
            per second of wall time (1.0 = real time); a sample block waits for its last
            sample.
        clock : Clock
            Used for pacing (injectable for tests; default the monotonic clock).
        """
        _check_speed(speed)
        run = self.run
        others: list[Iterator[tuple[int, int, Any]]] = []
        if TOPIC_EVENTS in self.topics:
            others.append((e.t_ns, 0, e) for e in run.events)
        if TOPIC_IMAGE in self.topics:
            frames = iter_frames(self.path, start_ns=self.start_ns, end_ns=self.end_ns)
            others.append((f.t_ns, 1, f) for f in frames)
        merged = heapq.merge(*others, key=lambda item: (item[0], item[1]))
        samples = run.samples if TOPIC_SAMPLES in self.topics else SampleBlock.empty()
        blocks = _sample_blocks(samples, run.sample_sequences, self.max_block_samples)
        pacer = _Pacer(speed, clock or MonotonicClock())
        pending: SampleBlock | None = next(blocks, None)
        for t_ns, _, record in merged:
            while pending is not None and int(pending.t_ns[0]) <= t_ns:
                cut = int(np.searchsorted(pending.t_ns, t_ns, side="right"))
                head = pending.slice(0, cut) if cut < len(pending) else pending
                pacer.wait(int(head.t_ns[-1]))
                yield head
                pending = (
                    pending.slice(cut, len(pending)) if cut < len(pending) else next(blocks, None)
                )
            pacer.wait(t_ns)
            yield record
        while pending is not None:
            pacer.wait(int(pending.t_ns[-1]))
            yield pending
            pending = next(blocks, None)


def replay_records(
    path: str | os.PathLike[str],
    *,
    speed: float | None = None,
    topics: Iterable[str] | None = None,
    start_ns: int | None = None,
    end_ns: int | None = None,
    max_block_samples: int | None = BLOCK_SAMPLES,
    clock: Clock | None = None,
) -> Iterator[Record]:
    """Yield the records of a run log merged in log-time order: ``LogReplay(path, ...)
    .records(speed=..., clock=...)`` in one call (see :class:`LogReplay`).

    Frames are read lazily; samples and events are loaded first (they are small).
    """
    _check_speed(speed)  # a bad argument is refused before the file is read
    replay = LogReplay(
        path,
        topics=topics,
        start_ns=start_ns,
        end_ns=end_ns,
        max_block_samples=max_block_samples,
    )
    yield from replay.records(speed=speed, clock=clock)


def _check_speed(speed: float | None) -> None:
    if speed is not None and not (np.isfinite(speed) and speed > 0):
        raise DaqInputError(f"speed must be a positive number or None, got {speed!r}")


def _sample_blocks(
    samples: SampleBlock, sequences: np.ndarray, max_block: int | None
) -> Iterator[SampleBlock]:
    n = len(samples)
    if n == 0:
        return
    breaks: Any = np.flatnonzero(np.diff(sequences) != 1) + 1 if len(sequences) == n else []
    starts = [0, *[int(b) for b in breaks]]
    ends = [*starts[1:], n]
    for s, e in zip(starts, ends, strict=True):
        seq0 = int(sequences[s]) if len(sequences) == n else samples.first_sequence + s
        step = e - s if max_block is None else max_block
        for i in range(s, e, step):
            j = min(i + step, e)
            yield SampleBlock(
                samples.t_ns[i:j],
                samples.rocker_angle_rad[i:j],
                samples.strain[i:j],
                samples.raw_volts[i:j],
                seq0 + (i - s),
            )


class _Pacer:
    def __init__(self, speed: float | None, clock: Clock) -> None:
        self.speed = speed
        self.clock = clock
        self._t0_log: int | None = None
        self._t0_wall = 0

    def wait(self, t_ns: int) -> None:
        if self.speed is None:
            return
        if self._t0_log is None:
            self._t0_log = t_ns
            self._t0_wall = self.clock.now_ns()
            return
        due = self._t0_wall + (t_ns - self._t0_log) / self.speed
        self.clock.sleep_s((due - self.clock.now_ns()) * 1e-9)
