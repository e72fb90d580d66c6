"""beambench replay: stream a raw run log to Rerun, without processing.

Samples (rocker angle and strains), camera frames (as recorded, no overlays) and events
go to the same entity paths and timelines as a processed run (``pipelines.review.viewer``), on
seconds since the first DAQ sample (the processed run's time base).
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from pipelines.commands._args import add_viewer_arguments
from pipelines.errors import BeambenchError
from pipelines.paths import refuse_aliases

if TYPE_CHECKING:
    # rerun, xarray and mcap take seconds to import: only when replay runs, not for
    # every ``beambench`` invocation (the CLI imports every command module).
    from pipelines.review.viewer import RunViewer


APP_ID = "beambench"


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
    frame_reduction: int = 1,
) -> ReplaySummary:
    """Stream a run log into ``viewer``: the records of ``daq.replay``, in log-time order.

    Parameters
    ----------
    log_path : the MCAP run log.
    viewer : where to send it (see ``pipelines.review.viewer.open_viewer``).
    speed : replay at ``speed`` times real time; None sends everything at once.
    sleep, monotonic : the clock used for pacing (injectable for tests).
    progress : draw a progress bar (default: only on a terminal).
    frame_reduction : frames at 1/N of their size (1: as logged).

    Raises
    ------
    daq.errors.LogError
        The log is missing, truncated or not a beambench log.
    """
    from daq.clock import CallableClock
    from daq.records import Frame, SampleBlock
    from daq.replay import BLOCK_SAMPLES, LogReplay
    from pipelines.progress import Progress
    from pipelines.review.overlays import displayed_frame

    # unpaced, a sample block runs from one frame or event to the next (few chunks in the
    # recording); paced, 0.1 s blocks keep the view moving
    replay = LogReplay(log_path, max_block_samples=None if speed is None else BLOCK_SAMPLES)
    run = replay.run
    s = run.samples
    t0_ns = int(s.t_ns[0]) if len(s) else min((e.t_ns for e in run.events), default=0)
    n_frames = 0
    with Progress("replay", total=run.frame_count or None, enabled=progress) as bar:
        for record in replay.records(speed=speed, clock=CallableClock(monotonic, sleep)):
            if isinstance(record, SampleBlock):
                t_s = (record.t_ns - t0_ns) * 1e-9
                viewer.log_samples(t_s, record.rocker_angle_rad, record.strain)
            elif isinstance(record, Frame):
                t = (record.t_ns - t0_ns) * 1e-9
                data, encoding, _ = displayed_frame(record.data, record.encoding, frame_reduction)
                viewer.log_frame(t, data, encoding, None, frame_index=record.sequence)
                n_frames += 1
                bar.update(1)
            else:
                viewer.log_events([record], t0_ns=t0_ns)
    ends_ns = [*s.t_ns[-1:].tolist(), *(e.t_ns for e in run.events)]
    end_s = max([0.0, *((t - t0_ns) * 1e-9 for t in ends_ns)])
    return ReplaySummary(len(s), n_frames, len(run.events), end_s)


def _default_rrd(log_path: Path) -> Path:
    return log_path.with_suffix(".rrd")


def run(args: argparse.Namespace) -> int:
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
        refuse_aliases({"--rrd": rrd}, {"the log": log_path})
        if not rrd.parent.is_dir():
            raise BeambenchError(f"--rrd {rrd}: folder {rrd.parent} does not exist")
    try:
        viewer = open_viewer(
            APP_ID, rrd_path=rrd, spawn=bool(args.spawn), connect_url=args.connect, layout="raw"
        )
    except (ValueError, OSError, RuntimeError) as exc:
        raise BeambenchError(f"cannot open the Rerun destination: {exc}") from None
    with viewer:
        summary = replay_log(log_path, viewer, speed=speed, frame_reduction=args.frame_reduction)
    where = str(rrd) if rrd is not None else (args.connect or "a spawned viewer")
    print(
        f"replayed {summary.samples} samples, {summary.frames} frames and {summary.events} "
        f"events ({summary.duration_s:.1f} s of run) -> {where}"
    )
    return 0
