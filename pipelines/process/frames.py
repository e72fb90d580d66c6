"""Measure every camera frame of a run on all cores.

Frames are decoded and measured in worker processes, each building its
``vision.Measurer`` once (initializer), so only the encoded bytes cross process
boundaries. Results come back in frame order.
"""

from __future__ import annotations

import logging
import multiprocessing
import os
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np

from vision import Calibration, FrameMeasurement, Measurer, decode

log = logging.getLogger(__name__)

_measurer: Measurer | None = None


@dataclass(frozen=True)
class MeasuredFrame:
    t_ns: int
    sequence: int
    measurement: FrameMeasurement


def _init_worker(calibration: Calibration, stations_m: tuple[float, ...], method: str) -> None:
    global _measurer
    # One thread per worker: the workers already use every core.
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    try:
        import cv2

        cv2.setNumThreads(1)
    except ImportError:  # pragma: no cover - opencv is a dependency
        pass
    _measurer = Measurer(calibration, stations_m=stations_m, method=method)


def _measure_one(item: tuple[int, int, bytes]) -> MeasuredFrame:
    t_ns, seq, data = item
    assert _measurer is not None
    return MeasuredFrame(t_ns, seq, _measure_bytes(_measurer, data))


def _measure_bytes(measurer: Measurer, data: bytes) -> FrameMeasurement:
    try:
        image = decode(data)
    except ValueError as exc:
        return FrameMeasurement(ok=False, reason=f"cannot decode frame: {exc}")
    return measurer.measure(image)


def measure_frames(
    frames: Iterable[Any],
    calibration: Calibration,
    *,
    stations_m: tuple[float, ...],
    method: str = "default",
    workers: int | None = None,
    progress: Callable[[int], None] | None = None,
) -> list[MeasuredFrame]:
    """Measure ``frames`` (objects with ``t_ns``, ``sequence``, ``data``) in order.

    ``workers`` defaults to the number of cores; 1 measures in this process. Workers are
    spawned, so a script calling this needs the usual ``if __name__ == "__main__":`` guard.
    """
    n_workers = workers if workers is not None else (os.cpu_count() or 1)
    items: Iterator[tuple[int, int, bytes]] = (
        (int(f.t_ns), int(f.sequence), bytes(f.data)) for f in frames
    )
    out: list[MeasuredFrame] = []
    if n_workers <= 1:
        measurer = Measurer(calibration, stations_m=stations_m, method=method)
        for t_ns, seq, data in items:
            out.append(MeasuredFrame(t_ns, seq, _measure_bytes(measurer, data)))
            if progress:
                progress(1)
        return out
    # Spawned, not forked: a fork copies the threads of rerun and the log reader
    # half-way through whatever they hold, and the children can hang.
    with ProcessPoolExecutor(
        max_workers=n_workers,
        mp_context=multiprocessing.get_context("spawn"),
        initializer=_init_worker,
        initargs=(calibration, stations_m, method),
    ) as pool:
        for result in pool.map(_measure_one, items, chunksize=4):
            out.append(result)
            if progress:
                progress(1)
    return out


def as_arrays(frames: list[MeasuredFrame]) -> dict[str, np.ndarray]:
    """Columns of the measured frames (NaN where a frame gave no measurement)."""
    n = len(frames)
    s = max((f.measurement.stations_m.size for f in frames), default=0)
    cols: dict[str, np.ndarray] = {
        "t_ns": np.array([f.t_ns for f in frames], dtype=np.int64),
        "ok": np.array([f.measurement.ok for f in frames], dtype=bool),
        "hub_angle_rad": np.full(n, np.nan),
        "tip_lateral_m": np.full(n, np.nan),
        "tip_longitudinal_m": np.full(n, np.nan),
        "lateral_at_stations_m": np.full((n, s), np.nan),
    }
    for i, f in enumerate(frames):
        m = f.measurement
        if m.ok:
            cols["hub_angle_rad"][i] = m.hub_angle_rad
            cols["tip_lateral_m"][i] = m.tip_lateral_m
            cols["tip_longitudinal_m"][i] = m.tip_longitudinal_m
            cols["lateral_at_stations_m"][i, : m.lateral_at_stations_m.size] = (
                m.lateral_at_stations_m
            )
    return cols
