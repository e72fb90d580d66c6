"""Replay: a run log back as the records the drivers produced, in log-time order."""

from __future__ import annotations

import heapq
import os
from collections.abc import Iterable, Iterator
from typing import Any

import numpy as np

from daq.clock import Clock, MonotonicClock
from daq.errors import DaqInputError
from daq.log.format import TOPIC_CAMERA_INFO, TOPIC_EVENTS, TOPIC_IMAGE, TOPIC_SAMPLES, TOPICS
from daq.log.reader import iter_frames, read_run
from daq.records import Event, Frame, SampleBlock

Record = SampleBlock | Frame | Event


def replay_records(
    path: str | os.PathLike[str],
    *,
    speed: float | None = None,
    topics: Iterable[str] | None = None,
    start_ns: int | None = None,
    end_ns: int | None = None,
    max_block_samples: int = 40,
    clock: Clock | None = None,
) -> Iterator[Record]:
    """Yield ``SampleBlock``, ``Frame`` and ``Event`` records merged in log-time order.

    Parameters
    ----------
    path : str or Path
    speed : float or None
        ``None``: as fast as possible. Otherwise pace the records so that ``speed``
        seconds of run time pass per second of wall time (1.0 = real time).
    topics : iterable of str, optional
        Any of ``/daq/samples``, ``/camera/image``, ``/events`` (default: all three).
    start_ns, end_ns : int, optional
        Half-open log-time window, ns.
    max_block_samples : int
        Longest sample block yielded; blocks also end at a sequence gap and before any
        frame or event with a later-or-equal time, so the order is strict.
    clock : Clock
        Used for pacing (injectable for tests).

    Frames are read lazily; samples and events are loaded first (they are small).
    """
    if speed is not None and not (np.isfinite(speed) and speed > 0):
        raise DaqInputError(f"speed must be a positive number or None, got {speed!r}")
    if max_block_samples < 1:
        raise DaqInputError(f"max_block_samples must be >= 1, got {max_block_samples!r}")
    want = (
        list(TOPICS) if topics is None else ([topics] if isinstance(topics, str) else list(topics))
    )
    unknown = sorted(set(want) - set(TOPICS))
    if unknown:
        raise DaqInputError(f"topics: unknown topic {unknown[0]!r}; expected some of {TOPICS}")
    run = read_run(
        path,
        topics=[t for t in want if t in (TOPIC_SAMPLES, TOPIC_EVENTS)] or [TOPIC_CAMERA_INFO],
        start_ns=start_ns,
        end_ns=end_ns,
    )
    others: list[Iterator[tuple[int, int, Any]]] = []
    if TOPIC_EVENTS in want:
        others.append((e.t_ns, 0, e) for e in run.events)
    if TOPIC_IMAGE in want:
        others.append((f.t_ns, 1, f) for f in iter_frames(path, start_ns=start_ns, end_ns=end_ns))
    merged = heapq.merge(*others, key=lambda item: (item[0], item[1]))
    samples = run.samples if TOPIC_SAMPLES in want else SampleBlock.empty()
    blocks = _sample_blocks(samples, run.sample_sequences, max_block_samples)
    pacer = _Pacer(speed, clock or MonotonicClock())
    pending: SampleBlock | None = next(blocks, None)
    for t_ns, _, record in merged:
        while pending is not None and int(pending.t_ns[0]) <= t_ns:
            cut = int(np.searchsorted(pending.t_ns, t_ns, side="right"))
            head = pending.slice(0, cut) if cut < len(pending) else pending
            pacer.wait(int(head.t_ns[-1]))
            yield head
            pending = pending.slice(cut, len(pending)) if cut < len(pending) else next(blocks, None)
        pacer.wait(t_ns)
        yield record
    while pending is not None:
        pacer.wait(int(pending.t_ns[-1]))
        yield pending
        pending = next(blocks, None)


def _sample_blocks(
    samples: SampleBlock, sequences: np.ndarray, max_block: int
) -> Iterator[SampleBlock]:
    n = len(samples)
    if n == 0:
        return
    breaks: Any = np.flatnonzero(np.diff(sequences) != 1) + 1 if len(sequences) == n else []
    starts = [0, *[int(b) for b in breaks]]
    ends = [*starts[1:], n]
    for s, e in zip(starts, ends, strict=True):
        seq0 = int(sequences[s]) if len(sequences) == n else samples.first_sequence + s
        for i in range(s, e, max_block):
            j = min(i + max_block, e)
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
