"""Measure every camera frame of a run on all cores.

Frames are decoded and measured in worker processes, forked by a fork server that has
imported vision and loaded its compiled kernels once (:func:`_context`; spawned where the
platform has none), each building its ``vision.Measurer`` once, so only the encoded
bytes cross process boundaries. Results come back in frame order. Each worker decodes through a
``vision.regions.RegionReader``: of a JPEG with restart markers (beambench's capture
writes them) only the parts the measurement reads, with the same result; other frames
whole.

A worker that dies (killed, out of memory, its resource tracker gone) or a pool that stops
making progress is a :class:`WorkerError` within seconds, never a wait without end: the
main process polls the workers while it waits and kills what is left when it gives up.
"""

from __future__ import annotations

import collections
import functools
import itertools
import logging
import math
import multiprocessing
import os
import signal
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures import TimeoutError as FutureTimeout
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pipelines.errors import BeambenchError
from vision import Calibration, FrameMeasurement, Measurer
from vision.calibration_error import frame_calibration_sd
from vision.jit import cached as kernels_cached
from vision.regions import RegionReader

log = logging.getLogger(__name__)

# How often the main process looks at its workers while it waits for a result, s.
POLL_S = 0.5
# No chunk of frames finished for this long while every worker lives: the pool is stuck.
# A chunk takes ~0.05 s; the fork server (or a spawned worker) imports numpy, OpenCV and
# vision in a second or so, longer on a loaded machine, so the first results may take
# this long.
STALL_TIMEOUT_S = 120.0
CHUNK_FRAMES = 4


class WorkerError(BeambenchError):
    """A frame-measuring worker process died or the pool stopped making progress."""


_reader: RegionReader | None = None
_reader_token: str | None = None
_tokens = itertools.count()


@dataclass(frozen=True)
class MeasuredFrame:
    t_ns: int
    sequence: int
    measurement: FrameMeasurement
    # the frame's logged bytes, on the frames given to ``on_measured`` only
    # (:func:`measure_frames`): the workers do not send them back, and the frames it
    # returns do not keep them
    data: bytes | None = field(default=None, repr=False, compare=False)


# what a worker's reader is built from: (calibration, stations, method, tip uncertainty
# limit, decode in parts), with a token naming one call of measure_frames
_Setup = tuple[str, tuple[Calibration, tuple[float, ...], str, float | None, bool]]
# frames as sent to a worker: (t_ns, sequence, bytes) each
_Items = list[tuple[int, int, bytes]]


#: How much lower the frame workers' scheduling priority is than the main process's
#: (``nice`` increment). The main process's threads (feeding the workers, the
#: recording's previews, the simulation) then run when they have work and the workers
#: take the rest: with both at one priority the previews thread, held back on the busy
#: cores, finished ~0.3-0.6 s after the frames on one core while the other idled (60 s
#: run, region previews); now the run ends on both cores measuring frames.
WORKER_NICE = 5


def _init_worker() -> None:
    # Ctrl-C reaches the whole process group: the main process stops the run and the
    # workers with it (:func:`_abandon`); a worker interrupted on its own printed a
    # "Process ...:" line and a traceback over the run's one "error: interrupted".
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        os.nice(WORKER_NICE)
    except (AttributeError, OSError):  # pragma: no cover - a platform without nice
        pass
    # One thread per worker: the workers already use every core.
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    try:
        import cv2

        cv2.setNumThreads(1)
    except ImportError:  # pragma: no cover - opencv is a dependency
        pass


def _reader_for(setup: _Setup) -> RegionReader:
    """This worker's reader for ``setup``, built at its first chunk (a worker may be
    started before the calibration is known: :class:`StartedWorkers`)."""
    global _reader, _reader_token
    token, (calibration, stations_m, method, limit, decode_parts) = setup
    if _reader is None or _reader_token != token:
        measurer = measurer_for(calibration, stations_m, method, limit)
        _reader = RegionReader(measurer, parts=decode_parts)
        _reader_token = token
    return _reader


def measurer_for(
    calibration: Calibration,
    stations_m: tuple[float, ...] | None,
    method: str,
    max_tip_uncertainty_m: float | None,
) -> Measurer:
    """A ``vision.Measurer``; ``None`` leaves vision's default stations or tip
    uncertainty limit."""
    kwargs: dict[str, Any] = {"method": method}
    if stations_m is not None:
        kwargs["stations_m"] = stations_m
    if max_tip_uncertainty_m is not None:
        kwargs["max_tip_uncertainty_m"] = max_tip_uncertainty_m
    return Measurer(calibration, **kwargs)


def _measure_chunk(setup: _Setup, items: list[tuple[int, int, bytes]]) -> list[MeasuredFrame]:
    reader = _reader_for(setup)
    return [MeasuredFrame(t_ns, seq, reader.measure(data)) for t_ns, seq, data in items]


def _ready() -> int:
    """A task for a worker started ahead: it has imported this module (and vision,
    numpy, OpenCV with it) by the time it runs this."""
    return os.getpid()


class StartedWorkers:
    """Frame-measuring worker processes started before the frames are measured
    (:func:`start_workers`): the fork server spends its first second or so importing
    numpy, OpenCV and vision and loading the kernels (each spawned worker, where there is
    no fork server), which then overlaps the reading of the log. Hand it to
    :func:`measure_frames` (which then owns it), or :meth:`close` it.

    The workers are asked for in a thread of their own (``starter``): a pool's first
    worker is only handed over once the fork server has done its imports, and this
    process reads the log meanwhile instead of waiting for them."""

    def __init__(
        self,
        pool: ProcessPoolExecutor,
        n_workers: int,
        kernels_cached: bool = True,
    ) -> None:
        self.pool: ProcessPoolExecutor | None = pool
        self.n_workers = n_workers
        # whether vision's kernels were cached when the workers started: by the frames,
        # the calibration may have compiled a few of them, so the cache is no longer
        # empty while most of the measurement's kernels are still to be compiled
        self.kernels_cached = kernels_cached
        self._starter: threading.Thread | None = None  # set by start_workers
        self.start_error: OSError | None = None  # set by the starter when it failed

    def join(self) -> StartedWorkers:
        """Wait until every worker was asked for (the fork server's imports done)."""
        if self._starter is not None:
            self._starter.join()
            self._starter = None
        return self

    def take(self) -> ProcessPoolExecutor | None:
        """The pool, once its workers were asked for; None when they could not be
        started (:func:`measure_frames` then tries again, and says why it cannot)."""
        self.join()
        pool, self.pool = self.pool, None
        if pool is not None and self.start_error is not None:
            _abandon(pool)
            return None
        return pool

    def close(self) -> None:
        """Stop the workers if :func:`measure_frames` did not take them (safe to repeat)."""
        if (pool := self.take()) is not None:
            _abandon(pool)


#: What the fork server imports before it forks a worker (:func:`_context`).
PRELOAD = "pipelines.process.worker_preload"


def _context() -> multiprocessing.context.BaseContext:
    """Workers are forked by a fork server where the platform has one, else spawned;
    never forked from this process: a fork copies the threads of Rerun and the log reader
    half-way through whatever they hold, and the children can hang. The fork server is
    a fresh interpreter, started at the first pool of this process and kept for the
    next, that imports :data:`PRELOAD` (vision and its compiled kernels) once: each
    worker starts with them loaded instead of spending ~0.7 CPU s on them."""
    if "forkserver" not in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("spawn")
    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload([PRELOAD])
    return ctx


def stop_fork_server() -> None:
    """Stop the workers' fork server if this process started one; the next pool starts
    another. For ``bench process``: each of its passes then starts one, as a ``process``
    command does, and the server's CPU with its workers' (it reaps them) is counted in
    this process's children's usage once it has stopped."""
    from multiprocessing import forkserver

    stop = getattr(forkserver._forkserver, "_stop", None)  # CPython's, for its own tests
    if stop is not None:
        stop()


def _new_pool(n_workers: int) -> ProcessPoolExecutor:
    return ProcessPoolExecutor(
        max_workers=n_workers, mp_context=_context(), initializer=_init_worker
    )


def start_workers(workers: int | None = None) -> StartedWorkers | None:
    """``workers`` (default: one a core) frame-measuring processes, being started from
    now on (in a thread: :class:`StartedWorkers`); None for one worker (the frames are
    then measured in this process) or when they cannot be started (:func:`measure_frames`
    then tries again, and says why it cannot)."""
    n_workers = workers if workers is not None else (os.cpu_count() or 1)
    if n_workers <= 1 or _cannot_spawn() is not None:
        return None
    cached = kernels_cached()
    try:
        pool = _new_pool(n_workers)
    except OSError:
        return None
    started = StartedWorkers(pool, n_workers, cached)

    def ask() -> None:
        try:
            for _ in range(n_workers):  # the pool starts a worker per task waiting
                pool.submit(_ready)
        except OSError as exc:
            started.start_error = exc

    started._starter = threading.Thread(target=ask, name="frame-workers-start", daemon=True)
    started._starter.start()
    return started


def measure_frames(
    frames: Iterable[Any],
    calibration: Calibration,
    *,
    stations_m: tuple[float, ...],
    method: str = "default",
    workers: int | None = None,
    progress: Callable[[int], None] | None = None,
    max_tip_uncertainty_m: float | None = None,
    decode_parts: bool = True,
    on_measured: Callable[[list[MeasuredFrame]], None] | None = None,
    started: StartedWorkers | None = None,
) -> list[MeasuredFrame]:
    """Measure ``frames`` (objects with ``t_ns``, ``sequence``, ``data``) in order;
    ``max_tip_uncertainty_m`` (default: vision's) refuses frames whose stated tip lateral
    uncertainty exceeds it. ``decode_parts=False`` decodes every frame whole (the same
    results, slower: the comparison ``bench process`` prints). ``on_measured`` is given
    the measured frames as they come, in order, each with its bytes as read (``data``:
    e.g. the recording's previews, made while the rest are measured, without reading
    the log again).

    ``workers`` defaults to the number of cores; 1 measures in this process. Workers are
    not forked from this process (:func:`_context`), so a script calling this needs the
    usual ``if __name__ == "__main__":`` guard.
    ``started``: workers started ahead (:func:`start_workers`, then ``workers`` is
    theirs), taken over and stopped with the rest.
    """
    pool = started.take() if started is not None else None
    cold = None
    if started is not None:
        workers = started.n_workers
        cold = not started.kernels_cached
    try:
        return _measure_frames(
            frames, calibration, stations_m, method, workers, progress,
            max_tip_uncertainty_m, decode_parts, on_measured, pool, cold,
        )  # fmt: skip
    finally:
        if pool is not None:
            _abandon(pool)  # stopped already, unless no frame needed it (a no-op then)


def _measure_frames(
    frames: Iterable[Any],
    calibration: Calibration,
    stations_m: tuple[float, ...],
    method: str,
    workers: int | None,
    progress: Callable[[int], None] | None,
    max_tip_uncertainty_m: float | None,
    decode_parts: bool,
    on_measured: Callable[[list[MeasuredFrame]], None] | None,
    started_pool: ProcessPoolExecutor | None,
    cold: bool | None = None,
) -> list[MeasuredFrame]:
    n_workers = workers if workers is not None else (os.cpu_count() or 1)
    limit = max_tip_uncertainty_m
    done = _progress(progress, on_measured)
    items: Iterator[tuple[int, int, bytes]] = (
        (int(f.t_ns), int(f.sequence), bytes(f.data)) for f in frames
    )
    if n_workers <= 1:
        return _measure_here(items, calibration, stations_m, method, done, limit, decode_parts)
    chunks = _chunks(items)
    first = next(chunks, None)
    if first is None:
        return []
    if (why := _cannot_spawn()) is not None:
        # Checked before any pool exists: a pool whose workers and resource tracker die
        # at exec leaves semaphores whose finalizers write to the dead tracker's pipe at
        # exit ("Exception ignored ... BrokenPipeError" after the run's own warning).
        log.warning(
            "cannot start frame-measuring worker processes (%s); measuring in this process",
            why,
        )
        rest = itertools.chain(first, itertools.chain.from_iterable(chunks))
        return _measure_here(rest, calibration, stations_m, method, done, limit, decode_parts)
    here: list[MeasuredFrame] = []
    if (not kernels_cached()) if cold is None else cold:
        # a fresh kernel cache (a first run, or vision changed): the first chunk measured
        # here compiles the kernels once, and the workers load them, instead of each
        # worker compiling them at once
        here = _measure_here(first, calibration, stations_m, method, done, limit, decode_parts)
        first = next(chunks, None)
        if first is None:
            return here
    setup: _Setup = (
        f"{os.getpid()}-{next(_tokens)}",
        (calibration, stations_m, method, limit, decode_parts),
    )
    measure_chunk = functools.partial(_measure_chunk, setup)
    pool = started_pool
    try:
        if pool is None:
            pool = _new_pool(n_workers)
        head = pool.submit(measure_chunk, first)
    except OSError as exc:
        # no worker could be started (e.g. a user who cannot execute the interpreter's
        # real path, so neither the workers nor their resource tracker start): measure
        # here, as --workers 1 does, and say so
        if pool is not None:
            _abandon(pool)
        log.warning(
            "cannot start frame-measuring worker processes (%s); measuring in this process",
            exc,
        )
        rest = itertools.chain(first, itertools.chain.from_iterable(chunks))
        return here + _measure_here(
            rest, calibration, stations_m, method, done, limit, decode_parts
        )
    out: list[MeasuredFrame] = []
    # the chunks handed to the pool before its first result: measured here if no worker
    # ever answers (workers that die at start, e.g. a user who cannot execute the
    # interpreter: the pool starts but each worker's exec fails)
    unanswered: list[_Items] = [first]
    ok = False
    try:
        for sent, chunk in _pooled(
            pool, measure_chunk, (first, head), chunks, in_flight=4 * n_workers, sent=unanswered
        ):
            out.extend(chunk)
            unanswered.clear()  # answered: a later death is an error, not a fallback
            if done:
                done(_with_data(chunk, sent))
        ok = True
    except WorkerError as exc:
        if out:
            raise
        _abandon(pool)
        log.warning("%s; measuring in this process instead", exc)
        rest = itertools.chain(*unanswered, itertools.chain.from_iterable(chunks))
        return here + _measure_here(
            rest, calibration, stations_m, method, done, limit, decode_parts
        )
    finally:
        if ok:
            pool.shutdown(wait=True)
        else:
            _abandon(pool)
    return here + out


def _cannot_spawn() -> str | None:
    """Why this user cannot start the interpreter a spawned worker runs, or None. (A
    user other than the interpreter's owner may lack search permission on its real
    path, e.g. a Python under /root, mode 0700, reached through a readable symlink.)"""
    from multiprocessing import spawn

    exe = os.fsdecode(spawn.get_executable() or "")
    if not os.access(exe, os.X_OK):
        return f"this user cannot execute {exe}"
    return None


def _progress(
    progress: Callable[[int], None] | None,
    on_measured: Callable[[list[MeasuredFrame]], None] | None,
) -> Callable[[list[MeasuredFrame]], None] | None:
    """One call per batch of measured frames: the count to ``progress``, the frames to
    ``on_measured``."""
    if progress is None and on_measured is None:
        return None

    def done(frames: list[MeasuredFrame]) -> None:
        if on_measured is not None:
            on_measured(frames)
        if progress is not None:
            progress(len(frames))

    return done


def _measure_here(
    items: Iterable[tuple[int, int, bytes]],
    calibration: Calibration,
    stations_m: tuple[float, ...],
    method: str,
    progress: Callable[[list[MeasuredFrame]], None] | None,
    max_tip_uncertainty_m: float | None = None,
    decode_parts: bool = True,
) -> list[MeasuredFrame]:
    measurer = measurer_for(calibration, stations_m, method, max_tip_uncertainty_m)
    reader = RegionReader(measurer, parts=decode_parts)
    out = []
    for t_ns, seq, data in items:
        out.append(MeasuredFrame(t_ns, seq, reader.measure(data)))
        if progress:
            progress(_with_data(out[-1:], [(t_ns, seq, data)]))
    return out


def _with_data(frames: list[MeasuredFrame], items: _Items) -> list[MeasuredFrame]:
    """The measured ``frames`` with the bytes they were measured from (``items``, the
    same frames in the same order)."""
    return [
        MeasuredFrame(f.t_ns, f.sequence, f.measurement, data)
        for f, (_, _, data) in zip(frames, items, strict=True)
    ]


def _chunks(items: Iterator[tuple[int, int, bytes]]) -> Iterator[list[tuple[int, int, bytes]]]:
    while chunk := list(itertools.islice(items, CHUNK_FRAMES)):
        yield chunk


def _pooled(
    pool: ProcessPoolExecutor,
    measure_chunk: Callable[[list[tuple[int, int, bytes]]], list[MeasuredFrame]],
    head: tuple[_Items, Future[list[MeasuredFrame]]],
    chunks: Iterator[_Items],
    *,
    in_flight: int,
    sent: list[_Items],
) -> Iterator[tuple[_Items, list[MeasuredFrame]]]:
    """(chunk, results of ``measure_chunk`` on it) in order, ``head`` (a chunk and its
    future) first, at most ``in_flight`` chunks queued (the frames' bytes stay bounded),
    each wait watched by :func:`_wait`."""
    pending: collections.deque[tuple[_Items, Future[list[MeasuredFrame]]]]
    pending = collections.deque([head])
    try:
        for chunk in chunks:
            sent.append(chunk)  # the caller clears it at each result
            pending.append((chunk, pool.submit(measure_chunk, chunk)))
            if len(pending) >= in_flight:
                items, future = pending.popleft()
                yield items, _wait(pool, future)
        while pending:
            items, future = pending.popleft()
            yield items, _wait(pool, future)
    except (BrokenProcessPool, OSError) as exc:
        raise WorkerError(
            f"a frame-measuring worker process died ({exc}); measuring stopped. "
            "Run again, or with --workers 1 to measure in the main process"
        ) from None


def _wait(pool: ProcessPoolExecutor, future: Future[list[MeasuredFrame]]) -> list[MeasuredFrame]:
    started = time.monotonic()
    while True:
        try:
            return future.result(timeout=POLL_S)
        except FutureTimeout:
            pass
        dead = [p for p in _workers(pool) if p.exitcode is not None]
        if dead:
            p = dead[0]
            raise WorkerError(
                f"a frame-measuring worker process (pid {p.pid}) died with exit code "
                f"{p.exitcode}; measuring stopped. Run again, or with --workers 1 to "
                "measure in the main process"
            )
        if time.monotonic() - started > STALL_TIMEOUT_S:
            raise WorkerError(
                f"the frame-measuring workers finished nothing in {STALL_TIMEOUT_S:g} s; "
                "measuring stopped. Run again, or with --workers 1 to measure in the main "
                "process"
            )


def _workers(pool: ProcessPoolExecutor) -> list[Any]:
    # the executor's own process table: the only handle on its workers' liveness
    return list((getattr(pool, "_processes", None) or {}).values())


def _abandon(pool: ProcessPoolExecutor) -> None:
    """Stop a failed pool without waiting on workers that may never answer."""
    workers = _workers(pool)
    # the queue's feeder thread may be blocked writing frames to workers that are gone
    # (the parent holds the pipe's other end, so the write never fails): without this the
    # executor's exit handler joins it and the interpreter never exits
    call_queue = getattr(pool, "_call_queue", None)
    if call_queue is not None:
        call_queue.cancel_join_thread()
    manager = getattr(pool, "_executor_manager_thread", None)  # shutdown forgets it
    pool.shutdown(wait=False, cancel_futures=True)
    for p in workers:
        if p.exitcode is None:
            p.kill()
    for p in workers:
        p.join(timeout=5.0)
    # with every worker gone, this process's end of the queue's pipe must be closed too: a
    # feeder blocked on a full pipe then fails (EPIPE) and finishes, so the executor's exit
    # handler, which joins it, returns and the interpreter exits. The executor's own
    # thread closes it when it finds the pool broken (CPython gh-94777), at a moment of its
    # choosing: closing it here at the same time raced it (both saw it open; the second
    # close failed with EBADF, or could have closed a descriptor the number was reused
    # for). So that thread is waited for first, and the pipe closed here only if it did not.
    if manager is not None:
        manager.join(timeout=5.0)
    reader = getattr(call_queue, "_reader", None)
    if reader is not None and not reader.closed:
        try:
            reader.close()
        except OSError:  # closed by the executor's thread after all (it was stuck)
            pass


# The longitudinal tip is the distance along the axis from the clamp's face to the tip's
# face, each found by an edge moment across a few lines: each is taken to be as
# uncertain as one point of the beam's fitted edges (the moment is less efficient than
# the fitted edge; averaging a few lines gives that back), so the two faces together
# sqrt(2) times the edges' RMS residual. Checked against the truth with the true
# registration: within 3 sigma in every frame of the vision bench's nominal, hard,
# hard-low, blur, short-hub, low-30 and low-60 sets (8 frames each, at most 2.4 sigma).
# Calibration errors are left out here, as in vision's own uncertainties; they are one
# error common to all frames, added by :func:`stated_sds`.
LONGITUDINAL_SD_PER_EDGE_RMS = math.sqrt(2.0)


def tip_longitudinal_sd_m(m: FrameMeasurement) -> float:
    """Standard uncertainty of a frame's longitudinal tip deflection (m), from its edge
    fits' RMS residual (vision states the hub angle's and the lateral tip's itself)."""
    if not m.ok or not math.isfinite(m.edge_rms_m):
        return math.nan
    return LONGITUDINAL_SD_PER_EDGE_RMS * float(m.edge_rms_m)


def stated_sds(
    m: FrameMeasurement, calibration: Calibration | None
) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """A frame's standard uncertainties (hub angle rad, tip lateral m, tip longitudinal
    m): the total, and the calibration's share of it. The calibration's error is one
    error common to all frames of a run (:mod:`vision.calibration_error`), independent
    of each frame's noise: the two add in quadrature. Without a calibration (or one that
    states no covariance) its share is zero."""
    noise = (m.hub_angle_std_rad, m.tip_lateral_std_m, tip_longitudinal_sd_m(m))
    if not m.ok:
        return (math.nan,) * 3, (math.nan,) * 3
    if calibration is None:
        return noise, (0.0, 0.0, 0.0)
    c = frame_calibration_sd(calibration, m)
    cal = (c.hub_angle_rad, c.tip_lateral_m, c.tip_longitudinal_m)
    total = tuple(math.hypot(a, b) for a, b in zip(noise, cal, strict=True))
    return (total[0], total[1], total[2]), cal


def as_arrays(
    frames: list[MeasuredFrame], calibration: Calibration | None = None
) -> dict[str, np.ndarray]:
    """Columns of the measured frames (NaN where a frame gave no measurement). The
    standard uncertainties include the ``calibration``'s error when it is given
    (:func:`stated_sds`); its share alone is in the ``calibration_*`` columns."""
    n = len(frames)
    s = max((f.measurement.stations_m.size for f in frames), default=0)
    sd_keys = ("hub_angle_sd_rad", "tip_lateral_sd_m", "tip_longitudinal_sd_m")
    cols: dict[str, np.ndarray] = {
        "t_ns": np.array([f.t_ns for f in frames], dtype=np.int64),
        "ok": np.array([f.measurement.ok for f in frames], dtype=bool),
        "hub_angle_rad": np.full(n, np.nan),
        "tip_lateral_m": np.full(n, np.nan),
        "tip_longitudinal_m": np.full(n, np.nan),
        **{k: np.full(n, np.nan) for k in sd_keys},
        **{f"calibration_{k}": np.full(n, np.nan) for k in sd_keys},
        "lateral_at_stations_m": np.full((n, s), np.nan),
    }
    for i, f in enumerate(frames):
        m = f.measurement
        if m.ok:
            cols["hub_angle_rad"][i] = m.hub_angle_rad
            cols["tip_lateral_m"][i] = m.tip_lateral_m
            cols["tip_longitudinal_m"][i] = m.tip_longitudinal_m
            total, cal = stated_sds(m, calibration)
            for k, t, c in zip(sd_keys, total, cal, strict=True):
                cols[k][i] = t
                cols[f"calibration_{k}"][i] = c
            cols["lateral_at_stations_m"][i, : m.lateral_at_stations_m.size] = (
                m.lateral_at_stations_m
            )
    return cols
