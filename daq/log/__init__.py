"""The run log (MCAP, format version 1): write, read, scan and recover.

``shared/design.md`` "Run log (MCAP), version 1" is the contract. This module gathers
the public names; the work is in ``log_writer``, ``log_reader`` and ``log_recover``.
"""

from __future__ import annotations

from daq.errors import LogError
from daq.log.format import (
    PROFILE,
    SAMPLE_SCHEMA,
    SAMPLE_SCHEMA_NAME,
    TOPIC_CAMERA_INFO,
    TOPIC_EVENTS,
    TOPIC_IMAGE,
    TOPIC_SAMPLES,
    TOPICS,
)
from daq.log.reader import ChannelStats, RunLog, iter_frames, read_run, scan_log
from daq.log.recover import RecoverySummary, recover_log
from daq.log.summary import ChannelSummary, LogSummary, summarize_log
from daq.log.writer import LogWriter

__all__ = [
    "PROFILE",
    "SAMPLE_SCHEMA",
    "SAMPLE_SCHEMA_NAME",
    "TOPICS",
    "TOPIC_CAMERA_INFO",
    "TOPIC_EVENTS",
    "TOPIC_IMAGE",
    "TOPIC_SAMPLES",
    "ChannelStats",
    "ChannelSummary",
    "LogError",
    "LogSummary",
    "LogWriter",
    "RecoverySummary",
    "RunLog",
    "iter_frames",
    "read_run",
    "recover_log",
    "scan_log",
    "summarize_log",
]
