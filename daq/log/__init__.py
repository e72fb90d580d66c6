"""The run log (MCAP, format version 1): write, read, summarize and recover.

``shared/design.md`` "Run log (MCAP), version 1" is the contract. This module gathers
the public names; the work is in ``format`` (topics, schemas, encodings), ``writer``,
``reader``, ``summary`` and ``recover``. ``mcap`` is imported in this sub-package only.
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
from daq.log.reader import (
    ChannelStats,
    RunLog,
    iter_frames,
    opens_as_log,
    read_run,
    scan_log,
)
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
    "opens_as_log",
    "read_run",
    "recover_log",
    "scan_log",
    "summarize_log",
]
