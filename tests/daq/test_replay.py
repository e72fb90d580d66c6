"""Replay merges samples, frames and events in log-time order, filtered and paced."""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import numpy as np
import pytest

from daq.clock import CallableClock, ManualClock
from daq.errors import DaqInputError
from daq.log import LogWriter, read_run
from daq.records import Event, Frame, SampleBlock
from daq.replay import LogReplay, replay_records

JPEG = bytes.fromhex(
    "ffd8ffc0000b080030004003011100ffd9"  # SOI, SOF0 48 x 64, EOI: enough for the header
)


def _log(path: Path) -> tuple[SampleBlock, list[Frame], list[Event]]:
    n = 400
    seq = np.concatenate([np.arange(0, 200), np.arange(210, 410)])  # a gap of 10 samples
    rng = np.random.default_rng(0)
    samples = SampleBlock(
        seq * 2_500_000,
        rng.normal(size=n),
        rng.normal(size=(n, 4)) * 1e-4,  # m/m: strains beyond 1 are refused as damage
        rng.normal(size=(n, 5)),
        0,
    )
    frames = [Frame(33_000_000 + k * 66_666_667, k, JPEG, "jpeg", 64, 48) for k in range(15)]
    events = [
        Event(0, "info", "start", ""),
        Event(500_000_000, "warning", "dropped_samples", "10"),
        Event(1_025_000_000, "info", "stop", ""),
    ]
    with LogWriter(path, rig_json=json.dumps({}), run_info={}) as w:
        w.write_event(events[0])
        w.write_samples(
            SampleBlock(
                samples.t_ns[:200],
                samples.rocker_angle_rad[:200],
                samples.strain[:200],
                samples.raw_volts[:200],
                0,
            )
        )
        w.write_samples(
            SampleBlock(
                samples.t_ns[200:],
                samples.rocker_angle_rad[200:],
                samples.strain[200:],
                samples.raw_volts[200:],
                210,
            )
        )
        for f in frames:
            w.write_frame(f)
        for e in events[1:]:
            w.write_event(e)
    return samples, frames, events


def test_records_come_back_in_log_time_order(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    samples, frames, events = _log(path)
    records = list(replay_records(path))
    blocks = [r for r in records if isinstance(r, SampleBlock)]
    assert [r for r in records if isinstance(r, Frame)] == frames
    assert [r for r in records if isinstance(r, Event)] == events
    joined = SampleBlock.concatenate(blocks)
    assert joined == SampleBlock(
        samples.t_ns, samples.rocker_angle_rad, samples.strain, samples.raw_volts, 0
    )
    assert all(len(b) <= 40 for b in blocks)
    # no block spans the sequence gap; sequences continue correctly after it
    for b in blocks:
        assert np.all(np.diff(b.t_ns) == 2_500_000)
    after = next(b for b in blocks if b.t_ns[0] >= 210 * 2_500_000)
    assert after.first_sequence == after.t_ns[0] // 2_500_000
    # strict order: a record never comes before one with an earlier time
    last = [int(r.t_ns[-1]) if isinstance(r, SampleBlock) else r.t_ns for r in records]
    first = [int(r.t_ns[0]) if isinstance(r, SampleBlock) else r.t_ns for r in records]
    assert all(first[i + 1] >= last[i] for i in range(len(records) - 1))


def test_topic_and_window_filters(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    _log(path)
    only_frames = list(
        replay_records(path, topics=["/camera/image"], start_ns=100_000_000, end_ns=300_000_000)
    )
    assert [f.sequence for f in only_frames if isinstance(f, Frame)] == [2, 3, 4]
    assert len(only_frames) == 3
    samples = list(replay_records(path, topics="/daq/samples", end_ns=100_000_000))
    assert sum(len(b) for b in samples if isinstance(b, SampleBlock)) == 40
    with pytest.raises(ValueError, match="topics"):
        list(replay_records(path, topics=["/bogus"]))
    assert read_run(path, topics=["/events"]).samples == SampleBlock.empty()


def test_pacing_follows_the_log_clock(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    _, _, events = _log(path)
    span_s = (events[-1].t_ns - events[0].t_ns) * 1e-9  # the first and last records
    for speed in (1.0, 4.0):
        clock = ManualClock()
        list(replay_records(path, speed=speed, clock=clock))
        assert clock.now_ns() * 1e-9 == pytest.approx(span_s / speed, abs=1e-6)
    clock = ManualClock()
    list(replay_records(path, speed=None, clock=clock))
    assert clock.now_ns() == 0
    with pytest.raises(ValueError, match="speed"):
        list(replay_records(path, speed=0.0))


def _time_ns(record: SampleBlock | Frame | Event) -> int:
    return int(record.t_ns[-1]) if isinstance(record, SampleBlock) else record.t_ns


def test_each_paced_record_comes_when_the_clock_reaches_its_log_time(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    _log(path)
    clock = ManualClock(start_ns=5_000)
    records = LogReplay(path).records(speed=2.0, clock=clock)
    first = next(records)
    for record in records:
        due_ns = 5_000 + (_time_ns(record) - _time_ns(first)) / 2.0
        assert abs(clock.now_ns() - due_ns) <= 1  # ns rounding of each sleep
    with pytest.raises(DaqInputError, match="speed"):
        next(LogReplay(path).records(speed=float("nan")))


def test_a_callable_clock_paces_with_the_callers_sleep(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    _, _, events = _log(path)
    now = [100.0]
    sleeps: list[float] = []

    def sleep(s: float) -> None:
        sleeps.append(s)
        now[0] += s

    list(replay_records(path, speed=4.0, clock=CallableClock(lambda: now[0], sleep)))
    span_s = (events[-1].t_ns - events[0].t_ns) * 1e-9
    assert sum(sleeps) == pytest.approx(span_s / 4.0, abs=1e-6)
    assert len(sleeps) > 20 and min(sleeps) > 0  # never asked to sleep for nothing


def test_the_opened_log_is_read_once_and_replays_the_same_records(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    samples, frames, events = _log(path)
    replay = LogReplay(path)
    assert replay.run.frame_count == len(frames) and replay.run.events == events
    assert len(replay.run.samples) == len(samples)
    once = list(replay.records())
    assert once == list(replay.records()) == list(replay_records(path))
    with pytest.raises(DaqInputError, match="max_block_samples"):
        LogReplay(path, max_block_samples=0)


def test_unlimited_blocks_end_only_at_gaps_frames_and_events(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    _, frames, events = _log(path)
    alone = list(replay_records(path, topics="/daq/samples", max_block_samples=None))
    assert [len(b) for b in alone if isinstance(b, SampleBlock)] == [200, 200]  # the gap
    records = list(replay_records(path, max_block_samples=None))
    blocks = [r for r in records if isinstance(r, SampleBlock)]
    assert SampleBlock.concatenate(blocks) == SampleBlock.concatenate(alone)
    for a, b in itertools.pairwise(blocks):
        gap = b.first_sequence != a.first_sequence + len(a)
        between = [r for r in [*frames, *events] if a.t_ns[-1] <= r.t_ns < b.t_ns[0]]
        assert gap or between, (a.first_sequence, b.first_sequence)
    assert [r for r in records if not isinstance(r, SampleBlock)] == sorted(
        [*frames, *events], key=lambda r: (r.t_ns, isinstance(r, Frame))
    )
