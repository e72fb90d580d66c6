"""beambench replay: stream a raw run log to Rerun, without processing.

Samples (rocker angle and strains), camera frames (as recorded, no overlays) and events
go to the same entity paths and timelines as a processed run (``pipelines.review.viewer``), on
seconds since the first DAQ sample (the processed run's time base).
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from pipelines.commands._viewer_args import add_viewer_arguments
from pipelines.errors import BeambenchError

if TYPE_CHECKING:
    # rerun, xarray and mcap take seconds to import: only when replay runs, not for
    # every ``beambench`` invocation (the CLI imports every command module).
    from daq.log import RunLog
    from daq.records import Frame
    from pipelines.progress import Progress
    from pipelines.review.viewer import RunViewer

HELP = "stream a raw run log to Rerun without processing"

APP_ID = "beambench"
TICK_S = 0.1  # run time sent per step when pacing


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("log", metavar="RUN.mcap")
    p.add_argument(
        "--speed",
        default="max",
        metavar="X|max",
        help="replay at X times real time, or 'max' for as fast as possible (default)",
    )
    add_viewer_arguments(p)
    p.epilog = (
        "Without --rrd, --spawn or --connect the recording is saved as RUN.rrd beside the "
        "log. An existing .rrd is replaced only when the replay succeeds."
    )


@dataclass(frozen=True)
class ReplaySummary:
    """What a replay sent."""

    samples: int
    frames: int
    events: int
    duration_s: float


def parse_speed(text: str) -> float | None:
    """``"max"`` -> None (no pacing); otherwise a positive finite factor."""
    if text.strip().lower() == "max":
        return None
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value) or value <= 0:
        raise BeambenchError(f"--speed must be a positive number or 'max', got {text!r}")
    return value


def replay_log(
    log_path: str | Path,
    viewer: RunViewer,
    *,
    speed: float | None = None,
    sleep: Callable[[float], None] = time.sleep,
    monotonic: Callable[[], float] = time.monotonic,
    progress: bool | None = None,
) -> ReplaySummary:
    """Stream a run log into ``viewer``.

    Parameters
    ----------
    log_path : the MCAP run log.
    viewer : where to send it (see ``pipelines.review.viewer.open_viewer``).
    speed : replay at ``speed`` times real time; None sends everything at once.
    sleep, monotonic : the clock used for pacing (injectable for tests).
    progress : draw a progress bar (default: only on a terminal).

    Raises
    ------
    daq.errors.LogError
        The log is missing, truncated or not a beambench log.
    """
    from daq.log import iter_frames, read_run
    from pipelines.progress import Progress

    run = read_run(log_path)
    s = run.samples
    t0_ns = int(s.t_ns[0]) if len(s) else min((e.t_ns for e in run.events), default=0)
    t_s = (s.t_ns - t0_ns).astype(np.float64) * 1e-9
    ev_t_s = np.array([(e.t_ns - t0_ns) * 1e-9 for e in run.events], dtype=np.float64)
    frames = iter_frames(log_path)
    n_frames = 0
    end_s = float(max(t_s[-1] if t_s.size else 0.0, ev_t_s.max(initial=0.0)))
    with Progress("replay", total=run.frame_count or None, enabled=progress) as bar:
        if speed is None:
            viewer.log_samples(t_s, s.rocker_angle_rad, s.strain)
            viewer.log_events(run.events, t0_ns=t0_ns)
            for frame in frames:
                _log_frame(viewer, frame, t0_ns)
                n_frames += 1
                bar.update(1)
        else:
            n_frames = _paced(viewer, run, t_s, ev_t_s, frames, t0_ns, speed, sleep, monotonic, bar)
    return ReplaySummary(len(s), n_frames, len(run.events), end_s)


def _log_frame(viewer: RunViewer, frame: Frame, t0_ns: int) -> float:
    t = (frame.t_ns - t0_ns) * 1e-9
    viewer.log_frame(t, frame.data, frame.encoding, None, frame_index=frame.sequence)
    return t


def _paced(
    viewer: RunViewer,
    run: RunLog,
    t_s: np.ndarray,
    ev_t_s: np.ndarray,
    frames: Iterator[Frame],
    t0_ns: int,
    speed: float,
    sleep: Callable[[float], None],
    monotonic: Callable[[], float],
    bar: Progress,
) -> int:
    """Send the log in steps of TICK_S of run time, each when the wall clock reaches it."""
    s = run.samples
    events = run.events
    pending: Frame | None = next(frames, None)
    n_frames = 0
    start_wall = monotonic()
    begin = min(0.0, float(t_s[0]) if t_s.size else 0.0)
    step = 0
    while True:
        hi = begin + (step + 1) * TICK_S
        lo_i, hi_i = np.searchsorted(t_s, [begin + step * TICK_S, hi])
        if hi_i > lo_i:
            viewer.log_samples(t_s[lo_i:hi_i], s.rocker_angle_rad[lo_i:hi_i], s.strain[lo_i:hi_i])
        due = [
            e
            for e, te in zip(events, ev_t_s, strict=True)
            if begin + step * TICK_S <= te < hi or (step == 0 and te < begin)
        ]
        if due:
            viewer.log_events(due, t0_ns=t0_ns)
        while pending is not None and (pending.t_ns - t0_ns) * 1e-9 < hi:
            _log_frame(viewer, pending, t0_ns)
            n_frames += 1
            bar.update(1)
            pending = next(frames, None)
        done = hi_i >= t_s.size and pending is None and not (ev_t_s >= hi).any()
        if done:
            return n_frames
        step += 1
        wait = start_wall + (hi - begin) / speed - monotonic()
        if wait > 0:
            sleep(wait)


def _default_rrd(log_path: Path) -> Path:
    return log_path.with_suffix(".rrd")


def run(args: argparse.Namespace) -> int:
    from daq.errors import LogError
    from pipelines.review.viewer import open_viewer

    log_path = Path(args.log)
    speed = parse_speed(args.speed)
    if not log_path.is_file():
        raise BeambenchError(f"{log_path}: no such run log")
    rrd = Path(args.rrd) if args.rrd else None
    if rrd is None and not args.spawn and not args.connect:
        rrd = _default_rrd(log_path)
    if rrd is not None:
        if rrd.suffix.lower() != ".rrd":
            raise BeambenchError(f"--rrd {rrd}: the recording file must end in .rrd")
        if not rrd.parent.is_dir():
            raise BeambenchError(f"--rrd {rrd}: folder {rrd.parent} does not exist")
    try:
        viewer = open_viewer(APP_ID, rrd_path=rrd, spawn=bool(args.spawn), connect_url=args.connect)
    except (ValueError, OSError, RuntimeError) as exc:
        raise BeambenchError(f"cannot open the Rerun destination: {exc}") from None
    try:
        with viewer:
            summary = replay_log(log_path, viewer, speed=speed)
    except LogError as exc:
        raise BeambenchError(str(exc)) from None
    where = str(rrd) if rrd is not None else (args.connect or "a spawned viewer")
    print(
        f"replayed {summary.samples} samples, {summary.frames} frames and {summary.events} "
        f"events ({summary.duration_s:.1f} s of run) -> {where}"
    )
    return 0
