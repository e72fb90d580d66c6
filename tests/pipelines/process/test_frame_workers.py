"""Frame-measuring workers that die are an error within seconds, never a wait without end;
and ``process`` works for a user who is not root."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import tempfile
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from pipelines.process import frames as frames_module
from pipelines.process.frames import WorkerError, measure_frames
from vision import Calibration
from vision.codec import encode

ROOT = Path(__file__).resolve().parents[3]
IMG = [[100.0, 120.0], [410.0, 90.0], [450.0, 400.0], [80.0, 380.0]]
PLANE = [[0.0, 0.0], [0.1, 0.0], [0.1, -0.1], [0.0, -0.1]]
CAL = Calibration(np.array(IMG), np.array(PLANE))


def _frames(n: int) -> list[SimpleNamespace]:
    # blank frames: each is measured (and fails: no beam) in a few milliseconds
    data = encode(np.full((96, 128), 40, np.uint8), "png")
    return [SimpleNamespace(t_ns=k * 66_666_667, sequence=k, data=data) for k in range(n)]


def _children(kind: str, parent: int | None = None) -> list[int]:
    """The child processes of ``parent`` (default: this process) whose command line
    contains ``kind``."""
    me = str(os.getpid() if parent is None else parent)
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
            cmdline = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode()
        except OSError:
            continue
        if stat[stat.rindex(")") + 2 :].split()[1] == me and kind in cmdline:
            found.append(int(entry.name))
    return found


def _workers() -> list[int]:
    """This process's frame workers: forked by its fork server (which stays, for the next
    pool), or spawned where the platform has no fork server."""
    forked = [
        pid
        for server in _children("multiprocessing.forkserver")
        for pid in _children("multiprocessing.forkserver", parent=server)
    ]
    return forked + _children("multiprocessing.spawn")


def test_workers_measure_in_order() -> None:
    out = measure_frames(_frames(30), CAL, stations_m=(0.2, 0.4), workers=2)
    assert [f.sequence for f in out] == list(range(30))
    assert not any(f.measurement.ok for f in out)  # blank frames: no beam in them
    assert _workers() == []  # the pool is gone


@pytest.mark.parametrize("workers", [1, 2])
def test_the_measured_frames_are_handed_on_in_order(workers: int) -> None:
    got: list[int] = []
    counted: list[int] = []
    out = measure_frames(
        _frames(23),
        CAL,
        stations_m=(0.2,),
        workers=workers,
        progress=counted.append,
        on_measured=lambda fs: got.extend(f.sequence for f in fs),
    )
    assert got == [f.sequence for f in out] == list(range(23))
    assert sum(counted) == 23


@pytest.mark.parametrize("workers", [1, 2])
def test_the_frames_handed_on_carry_their_bytes_and_those_returned_do_not(workers: int) -> None:
    frames = [
        SimpleNamespace(
            t_ns=k * 1000, sequence=k, data=encode(np.full((96, 128), k, np.uint8), "png")
        )
        for k in range(9)
    ]
    handed: list[Any] = []
    out = measure_frames(frames, CAL, stations_m=(0.2,), workers=workers, on_measured=handed.extend)
    assert [(f.sequence, f.data) for f in handed] == [(f.sequence, f.data) for f in frames]
    assert [f.measurement for f in handed] == [f.measurement for f in out]
    assert all(f.data is None for f in out)


@pytest.mark.parametrize("poll_s", [frames_module.POLL_S, 1e6])
def test_a_worker_killed_mid_run_is_an_error(
    poll_s: float, monkeypatch: pytest.MonkeyPatch
) -> None:
    # poll 1e6 s: the executor's own BrokenProcessPool must be turned into the error too
    monkeypatch.setattr(frames_module, "POLL_S", poll_s)
    done = []

    def kill_a_worker(n: int) -> None:
        done.append(n)
        if len(done) == 1:
            workers = _workers()
            assert workers, "no worker process found"
            os.kill(workers[0], signal.SIGKILL)

    with pytest.raises(WorkerError, match=r"worker process .*died"):
        measure_frames(_frames(400), CAL, stations_m=(0.2,), workers=2, progress=kill_a_worker)
    assert sum(done) < 400
    assert _workers() == []  # what was left was stopped


def test_a_stuck_pool_is_an_error(monkeypatch: pytest.MonkeyPatch) -> None:
    # workers alive but answering nothing: once the first frames are in, stop every worker
    # (SIGSTOP) and give the pool no more time
    stopped: list[int] = []

    def stop_workers(n: int) -> None:
        if not stopped:
            monkeypatch.setattr(frames_module, "STALL_TIMEOUT_S", 0.0)
            for pid in _workers():
                os.kill(pid, signal.SIGSTOP)
                stopped.append(pid)

    try:
        with pytest.raises(WorkerError, match="finished nothing"):
            measure_frames(_frames(400), CAL, stations_m=(0.2,), workers=2, progress=stop_workers)
    finally:
        for pid in stopped:  # killed by the pool already; a no-op unless it failed
            try:
                os.kill(pid, signal.SIGCONT)
            except ProcessLookupError:
                pass
    assert stopped


def _as_nobody() -> list[str] | None:
    """A command prefix running as user ``nobody``, or None when that cannot work here."""
    if os.geteuid() != 0:
        return []  # already not root
    setpriv = shutil.which("setpriv")
    if setpriv is None:
        return None
    prefix = [setpriv, "--reuid=nobody", "--regid=nogroup", "--clear-groups"]
    probe = subprocess.run(
        [*prefix, sys.executable, "-c", "import pipelines, numpy, cv2"],
        capture_output=True,
        timeout=120,
        cwd="/",
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )
    return prefix if probe.returncode == 0 else None


@pytest.mark.slow
def test_process_as_a_user_who_is_not_root(request: pytest.FixtureRequest) -> None:
    prefix = _as_nobody()
    if prefix is None:
        pytest.skip(
            f"cannot run as user nobody here: the interpreter {sys.executable} or the "
            "project is not readable by nobody (e.g. a Python under /root, mode 0700)"
        )
    out_dir = Path(tempfile.mkdtemp(prefix="beambench-nobody-"))
    request.addfinalizer(lambda: shutil.rmtree(out_dir, ignore_errors=True))
    out_dir.chmod(0o777)
    log = out_dir / "run.mcap"  # a folder every user can enter (pytest's is root's only)
    shutil.copy(ROOT / "sample_data" / "run-6s.mcap", log)
    log.chmod(0o644)
    proc = subprocess.run(
        [
            *prefix,
            sys.executable,
            "-m",
            "pipelines.cli",
            "process",
            str(log),
            "--out",
            str(out_dir / "r.nc"),
            "--workers",
            "2",
        ],
        capture_output=True,
        text=True,
        timeout=600,
        cwd=out_dir,
        env={**os.environ, "PYTHONPATH": str(ROOT), "HOME": str(out_dir)},
    )
    assert proc.returncode == 0, proc.stderr
    assert (out_dir / "r.nc").is_file()
    assert "frames measured" in proc.stdout
    # where this user cannot execute the interpreter's real path (a Python under /root,
    # mode 0700, reached through setpriv's exec), no worker starts: the frames are measured
    # in the main process with one warning line instead of a traceback or a hang
    # (the sample log was recorded before some rig keys existed: pipelines.rig warns for
    # each, as it should; only the frame workers' warnings are checked here)
    warnings = [x for x in proc.stderr.splitlines() if x.startswith("WARNING pipelines.process")]
    assert all("measuring in this process" in x for x in warnings)
    # and nothing else: no "Exception ignored ... BrokenPipeError" from a dead resource
    # tracker's pipe, no multiprocessing UserWarning, at most the one fallback warning
    others = [x for x in proc.stderr.splitlines() if not x.startswith("WARNING pipelines.rig")]
    assert others == warnings and len(warnings) <= 1, proc.stderr


KILL_AND_EXIT = """
import os, signal, sys
sys.path.insert(0, sys.argv[1])
from tests.pipelines.process.test_frame_workers import CAL, _frames, _workers
from pipelines.process.frames import WorkerError, measure_frames

def kill(n):
    if not getattr(kill, "done", False):
        kill.done = True
        os.kill(_workers()[0], signal.SIGKILL)

try:
    measure_frames(_frames(400), CAL, stations_m=(0.2,), workers=2, progress=kill)
except WorkerError as exc:
    print("worker error:", exc)
"""


def test_the_interpreter_exits_after_a_worker_died() -> None:
    # the hang was at exit: the executor's exit handler joined a queue feeder
    # blocked on a pipe to dead workers. A subprocess that does not exit is a timeout here.
    proc = subprocess.run(
        [sys.executable, "-c", KILL_AND_EXIT, str(ROOT)],
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )
    assert proc.returncode == 0, proc.stderr
    assert "worker error: a frame-measuring worker process" in proc.stdout


def test_workers_started_ahead_measure_the_frames_and_stop() -> None:
    from pipelines.process.frames import start_workers

    started = start_workers(2)
    assert started is not None and started.pool is not None
    ahead = set(started.pool.submit(os.getpid).result(timeout=120) for _ in range(4))
    ahead |= {p.pid for p in frames_module._workers(started.pool)}
    seen: set[int] = set()
    out = measure_frames(
        _frames(17),
        CAL,
        stations_m=(0.2,),
        started=started,
        on_measured=lambda fs: seen.update(_workers()),
    )
    assert [f.sequence for f in out] == list(range(17))
    assert seen and seen <= ahead  # no other worker was started
    assert started.pool is None  # taken over
    started.close()  # a no-op now
    assert _workers() == []
    # started and never used (the run stopped before its frames): stopped by close()
    unused = start_workers(2)
    assert unused is not None
    # asked for in a thread (start_workers returns at once): forked once asked for
    assert unused.join() is unused and _workers()
    unused.close()
    unused.close()
    assert _workers() == []
    assert start_workers(1) is None  # one worker: the frames are measured here


def test_workers_stopped_while_starting_leave_the_executor_finished() -> None:
    # a run refused while its workers still import (a damaged log) stops them at once.
    # The executor's own thread closes the call queue's pipe when it finds them killed;
    # closing it here as well, at the same moment, failed with EBADF once in CI. The stop
    # waits for that thread, so on return it is finished and the pipe closed, once.
    from pipelines.process.frames import start_workers

    for _ in range(3):
        started = start_workers(2)
        assert started is not None and started.pool is not None
        pool: Any = started.join().pool  # the executor's internals, untyped here
        call_queue, manager = pool._call_queue, pool._executor_manager_thread
        started.close()
        assert not manager.is_alive()
        assert call_queue._reader.closed
    assert _workers() == []


def _spy_measured_here(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """The sequence numbers of the frames measured in this process (not by the workers),
    filled in as they are."""
    here: list[int] = []
    real = frames_module._measure_here

    def spy(items, *args, **kwargs):  # type: ignore[no-untyped-def]
        got = real(items, *args, **kwargs)
        here.extend(f.sequence for f in got)
        return got

    monkeypatch.setattr(frames_module, "_measure_here", spy)
    return here


def test_a_fresh_kernel_cache_measures_the_first_frames_here(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # a cold cache: the first chunk is measured in this process (compiling the kernels
    # once), the rest by the workers; the same frames, in order, handed on once each
    monkeypatch.setattr(frames_module, "kernels_cached", lambda: False)
    here = _spy_measured_here(monkeypatch)
    handed: list[int] = []
    out = measure_frames(
        _frames(13),
        CAL,
        stations_m=(0.2,),
        workers=2,
        on_measured=lambda fs: handed.extend(f.sequence for f in fs),
    )
    assert here == list(range(frames_module.CHUNK_FRAMES))
    assert [f.sequence for f in out] == handed == list(range(13))
    # a run of one chunk never starts the pool
    assert [f.sequence for f in measure_frames(_frames(3), CAL, stations_m=(0.2,), workers=2)] == [
        0,
        1,
        2,
    ]
    assert _workers() == []


def test_a_cache_cold_when_the_workers_started_measures_the_first_frames_here(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # the calibration (between the workers' start and the frames) compiles a few kernels:
    # the cache is no longer empty, yet most of the measurement's kernels are still to be
    # compiled. What counts is the cache when the workers started: the first chunk is
    # measured here then (compiled once), not by each worker at once
    state = {"cached": False}
    monkeypatch.setattr(frames_module, "kernels_cached", lambda: state["cached"])
    here = _spy_measured_here(monkeypatch)
    started = frames_module.start_workers(2)
    assert started is not None and not started.kernels_cached
    state["cached"] = True  # the calibration compiled some
    out = measure_frames(_frames(9), CAL, stations_m=(0.2,), started=started)
    assert here == list(range(frames_module.CHUNK_FRAMES))
    assert [f.sequence for f in out] == list(range(9))
    # workers started with a warm cache measure every frame themselves
    here.clear()
    started = frames_module.start_workers(2)
    assert started is not None and started.kernels_cached
    out = measure_frames(_frames(9), CAL, stations_m=(0.2,), started=started)
    assert here == [] and [f.sequence for f in out] == list(range(9))
    assert _workers() == []


def _kernels_in_this_worker() -> tuple[int, int]:
    """(kernels Python may call whose cache holds them, of those already loaded) in the
    calling process."""
    from vision.jit import _entry_kernels

    cached = [k for k in _entry_kernels() if k._cache._cache_file._load_index()]
    return len(cached), sum(1 for k in cached if k.overloads)


@pytest.mark.skipif(
    "forkserver" not in __import__("multiprocessing").get_all_start_methods(),
    reason="no fork server on this platform: workers are spawned and load their own",
)
def test_workers_start_with_the_cached_kernels_loaded() -> None:
    # the fork server loads vision's cached kernels once; each worker forked from it has
    # them before its first frame instead of loading them itself (~0.4 s a worker)
    from vision.sampling import bilinear_points

    frames_module.stop_fork_server()  # a server started by an earlier test loaded less
    bilinear_points(np.zeros((4, 4), np.uint8), np.ones((1, 2)))  # at least this one is cached
    started = frames_module.start_workers(2)
    assert started is not None and started.pool is not None
    try:
        cached, loaded = started.pool.submit(_kernels_in_this_worker).result(timeout=120)
    finally:
        started.close()
    assert cached >= 1 and loaded == cached
    assert _workers() == []


def _priority() -> int:
    return os.getpriority(os.PRIO_PROCESS, 0)


def test_workers_run_at_a_lower_priority_than_the_main_process() -> None:
    # the main process's threads (previews, simulation, feeding the workers) run first
    # when they have work, so the run does not end on one core finishing them
    started = frames_module.start_workers(2)
    assert started is not None and started.pool is not None
    try:
        worker = started.pool.submit(_priority).result(timeout=120)
    finally:
        started.close()
    assert worker == min(_priority() + frames_module.WORKER_NICE, 19)


def _sigint_ignored() -> bool:
    return signal.getsignal(signal.SIGINT) == signal.SIG_IGN


def test_workers_leave_ctrl_c_to_the_main_process() -> None:
    # Ctrl-C reaches the process group: the main process stops the run and its workers;
    # a worker interrupted itself printed "Process ...:" and a traceback under the run's
    # "error: interrupted"
    started = frames_module.start_workers(2)
    assert started is not None and started.pool is not None
    try:
        assert started.pool.submit(_sigint_ignored).result(timeout=120)
    finally:
        started.close()
    assert not _sigint_ignored()  # this process's own Ctrl-C is untouched


class _SlowPool:
    """An executor whose workers are handed over only when ``go`` is set (a fork server
    still importing), or never (``fail``: they cannot start)."""

    def __init__(self, fail: bool = False) -> None:
        import threading

        self.go = threading.Event()
        self.fail = fail
        self.asked = 0
        self.stopped = False

    def submit(self, fn: Any) -> None:
        self.go.wait(timeout=60)
        if self.fail:
            raise OSError("no worker could start")
        self.asked += 1

    def shutdown(self, wait: bool = True, cancel_futures: bool = False) -> None:
        self.stopped = True


def test_starting_the_workers_does_not_wait_for_them(monkeypatch: pytest.MonkeyPatch) -> None:
    # the fork server hands a pool its first worker only after its imports (~1 s): the
    # run reads its log meanwhile, so start_workers returns at once and take() waits
    pool = _SlowPool()
    monkeypatch.setattr(frames_module, "_new_pool", lambda n: pool)
    started = frames_module.start_workers(2)
    assert started is not None and pool.asked == 0  # returned while the server imports
    pool.go.set()
    assert started.take() is pool and pool.asked == 2
    # workers that could not start: the pool is stopped and measure_frames starts its own
    failing = _SlowPool(fail=True)
    monkeypatch.setattr(frames_module, "_new_pool", lambda n: failing)
    started = frames_module.start_workers(2)
    assert started is not None
    failing.go.set()
    assert started.take() is None and failing.stopped


def test_a_file_that_is_no_log_starts_no_workers(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # stopping workers half started waits for the fork server's imports (~0.8 s): a
    # file that does not open as a log is refused before any is started
    from pipelines.errors import BeambenchError
    from pipelines.process import run as run_module

    asked: list[int | None] = []
    monkeypatch.setattr(run_module, "start_workers", lambda n=None: asked.append(n))
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"not a log")
    with pytest.raises(BeambenchError, match=r"junk\.mcap: not an MCAP file"):
        run_module.process_run(junk, workers=2)
    assert asked == []
