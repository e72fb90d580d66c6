"""What a run log holds, per topic: counts, rates, sequence and time gaps, duration, and
the events that report a problem (``beambench info`` prints it)."""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

import numpy as np

from daq.log.format import TOPIC_EVENTS
from daq.log.reader import ChannelStats, read_run, scan_log


@dataclass(frozen=True)
class ChannelSummary:
    """One topic of a log.

    Attributes
    ----------
    topic, schema, encoding : str
        Channel topic, schema name and message encoding.
    count : int
        Messages on the topic.
    rate_hz : float or None
        ``(count - 1) / span`` over the log-time span; None for fewer than 2 messages
        or a zero span.
    sequence_gaps, missing : int
        Jumps in the sequence numbers and the messages they skip (0 for ``/events``).
    time_gaps : int
        Steps between log times longer than 1.5 x the median step (0 for ``/events``).
    largest_gap_s : float or None
        Longest step between log times, s (None for ``/events`` and < 2 messages).
    """

    topic: str
    schema: str
    encoding: str
    count: int
    rate_hz: float | None = None
    sequence_gaps: int = 0
    missing: int = 0
    time_gaps: int = 0
    largest_gap_s: float | None = None


@dataclass(frozen=True)
class LogSummary:
    """A run log at a glance (:func:`summarize_log`).

    Attributes
    ----------
    path : str
        The log, as given.
    library : str
        The MCAP header's writing library.
    size_bytes, chunks : int
        File size and number of chunks.
    run_id, start_utc, acquisition_rate_hz
        As the ``run`` metadata record holds them (None when absent).
    backends : tuple
        ``(backend_daq, backend_camera)`` from the ``run`` record.
    duration_s : float
        From the first to the last message of any topic, s.
    channels : tuple of ChannelSummary
        One per topic, by topic name.
    problems : dict of str to int
        Count of events above ``info`` level (drops, overruns, clipping, device
        errors), by event name.
    """

    path: str
    library: str
    size_bytes: int
    chunks: int
    run_id: Any
    start_utc: Any
    backends: tuple[Any, Any]
    acquisition_rate_hz: Any
    duration_s: float
    channels: tuple[ChannelSummary, ...]
    problems: dict[str, int]


def summarize_log(path: str | os.PathLike[str]) -> LogSummary:
    """Per-topic counts, rates, sequence and time gaps, problem events and duration.

    Raises
    ------
    LogError
        Missing, truncated, corrupt or not a beambench log.
    """
    stats, meta = scan_log(path)
    run = read_run(path, topics=[TOPIC_EVENTS])
    channels = tuple(_channel(st) for _, st in sorted(stats.items()))
    starts = [int(st.log_time_ns.min()) for st in stats.values() if len(st.log_time_ns)]
    ends = [int(st.log_time_ns.max()) for st in stats.values() if len(st.log_time_ns)]
    problems: dict[str, int] = {}
    for ev in run.events:
        if ev.level != "info":
            problems[ev.name] = problems.get(ev.name, 0) + 1
    info = run.run_info
    return LogSummary(
        path=os.fspath(path),
        library=meta["library"],
        size_bytes=meta["size_bytes"],
        chunks=meta["chunks"],
        run_id=info.get("run_id"),
        start_utc=info.get("start_utc"),
        backends=(info.get("backend_daq"), info.get("backend_camera")),
        acquisition_rate_hz=info.get("acquisition_rate_hz"),
        duration_s=(max(ends) - min(starts)) * 1e-9 if starts else 0.0,
        channels=channels,
        problems=problems,
    )


def _channel(st: ChannelStats) -> ChannelSummary:
    n = len(st.log_time_ns)
    names = (st.topic, st.schema_name, st.message_encoding, n)
    if n < 2:
        return ChannelSummary(*names)
    order = np.argsort(st.log_time_ns, kind="stable")
    t = st.log_time_ns[order]
    span_s = (t[-1] - t[0]) * 1e-9
    rate_hz = float((n - 1) / span_s) if span_s > 0 else None
    if st.topic == TOPIC_EVENTS:  # events come when they happen: no stream to have gaps
        return ChannelSummary(*names, rate_hz)
    dt = np.diff(t)
    dseq = np.diff(st.sequence[order])
    median = float(np.median(dt))
    return ChannelSummary(
        *names,
        rate_hz,
        sequence_gaps=int(np.count_nonzero(dseq > 1)),
        missing=int(np.sum(dseq[dseq > 1] - 1)),
        time_gaps=int(np.count_nonzero(dt > 1.5 * median)) if median > 0 else 0,
        largest_gap_s=float(dt.max()) * 1e-9,
    )
