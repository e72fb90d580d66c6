"""Where a campaign's tasks run: an embedded ``distributed.LocalCluster`` sized to the
machine, or a lab cluster started with the standard ``dask scheduler`` /
``dask worker tcp://...`` commands.

Embedded workers are processes with one thread each (the per-run pipeline holds the GIL
in its Python steps), listening on 127.0.0.1 only, with no dashboard (it needs bokeh and
a port). Connecting gives up after :data:`CONNECT_TIMEOUT_S` with a ``BeambenchError``
naming the address, never a hang.

A scheduler lost mid-way is a :class:`SchedulerLost` within seconds, never a wait for
answers that will not come: one that dies closes its connection and Dask cancels every
future (reason ``scheduler-connection-lost``); one that stops answering (a hung process,
a host gone without closing its sockets) is asked who it is every
:data:`PROBE_INTERVAL_S` while nothing finishes and declared lost when it does not
answer within :data:`PROBE_TIMEOUT_S`.
"""

from __future__ import annotations

import contextlib
import logging
import os
from collections.abc import Iterable, Iterator
from typing import Any

from pipelines.errors import BeambenchError

CONNECT_TIMEOUT_S = 5.0
PROBE_INTERVAL_S = 5.0
# Dask's own bound for an unresponsive connection (distributed.comm.timeouts.tcp)
PROBE_TIMEOUT_S = 30.0
LOST_REASON = "scheduler-connection-lost"


class SchedulerLost(BeambenchError):
    """The scheduler died or stopped answering while tasks were under way."""


def completed(client: Any, futures: Iterable[Any]) -> Iterator[Any]:
    """``futures`` as each finishes (like ``distributed.as_completed``), raising
    :class:`SchedulerLost` when the scheduler is gone. A future cancelled for another
    reason is yielded as it is (its ``result()`` raises ``CancelledError``)."""
    from distributed import wait
    from distributed.client import FuturesCancelledError

    pending = set(futures)
    while pending:
        try:
            done, pending = wait(pending, timeout=PROBE_INTERVAL_S, return_when="FIRST_COMPLETED")
        except TimeoutError:
            _probe(client)
            continue
        except FuturesCancelledError as exc:
            if any(g.reason == LOST_REASON for g in exc.error_groups) or client.status != "running":
                raise _lost(client) from None
            done = {f for f in pending if f.status != "pending"}
            pending -= done
        yield from done


def outcome_of(client: Any, future: Any) -> tuple[Any, BaseException | None]:
    """A finished future's ``(result, None)``, or ``(None, its exception)`` (a
    ``CancelledError`` when it was cancelled). Fetching a result from a scheduler that
    died meanwhile is :class:`SchedulerLost`."""
    from concurrent.futures import CancelledError

    try:
        return future.result(), None
    except CancelledError as exc:  # distributed's FutureCancelledError
        if client.status != "running" or getattr(exc, "reason", "") == LOST_REASON:
            raise _lost(client) from None
        return None, exc
    except OSError as exc:  # distributed's CommClosedError: the result was not fetched
        if client.status != "running" or type(exc).__module__.startswith("distributed"):
            raise _lost(client) from None
        return None, exc
    except Exception as exc:  # the task's own exception, re-raised here by Dask
        return None, exc


def _close_lost(client: Any) -> None:
    """Close a client whose scheduler is gone; closing may itself time out talking to it,
    which changes nothing for the error being raised."""
    with contextlib.suppress(TimeoutError, OSError):
        client.close(timeout=CONNECT_TIMEOUT_S)


def _probe(client: Any) -> None:
    if client.status != "running":
        raise _lost(client)
    try:
        client.sync(client.scheduler.identity, callback_timeout=PROBE_TIMEOUT_S)
    except (OSError, TimeoutError):
        raise _lost(client, f"no answer within {PROBE_TIMEOUT_S:g} s") from None


def quiet_dask_logs() -> dict[str, int]:
    """Raise every ``distributed`` logger of this process to CRITICAL; their previous
    levels by name. (Dask configures some of its loggers' levels itself: each is raised,
    not only the parent.)"""
    levels = {}
    for name in ["distributed", *logging.root.manager.loggerDict]:
        if name == "distributed" or name.startswith("distributed."):
            log = logging.getLogger(name)
            levels[name] = log.level
            log.setLevel(logging.CRITICAL)
    return levels


def _quiet_workers(client: Any) -> None:
    """Quiet the embedded workers' Dask loggers before they are stopped.

    A worker stopping while its heartbeat to the scheduler is under way logs the closed
    connection at ERROR with a traceback ("Failed to communicate with scheduler during
    heartbeat", dask/distributed#7105, open): the worker stops its periodic callbacks but
    not one already running, then closes its connections under it. The workers share this
    process's stderr, so a finished campaign could end in thirty lines of someone else's
    traceback. Their stopping is not the user's business; with ``-v`` it is left as is.
    A worker that does not answer within :data:`CONNECT_TIMEOUT_S` is stopped regardless.
    """
    if logging.getLogger().isEnabledFor(logging.INFO) or client.status != "running":
        return
    # the function's own errors are ignored by Dask (on_error); a worker or scheduler
    # that does not answer in time, or whose connection closes, is stopped regardless
    with contextlib.suppress(OSError, TimeoutError):
        client.run(quiet_dask_logs, on_error="ignore", callback_timeout=CONNECT_TIMEOUT_S)


def _lost(client: Any, how: str = "connection closed") -> SchedulerLost:
    # Dask's client now logs its reconnection attempts and their cancellation at ERROR;
    # the SchedulerLost line says it all.
    quiet_dask_logs()
    address = getattr(client.scheduler, "address", "?")
    return SchedulerLost(f"lost the scheduler {address} ({how})")


@contextlib.contextmanager
def open_client(scheduler: str | None = None, workers: int | None = None) -> Iterator[Any]:
    """A ``distributed.Client`` on ``scheduler`` (``tcp://host:port``) or, when ``None``,
    on an embedded cluster of ``workers`` processes (default: one per core)."""
    from distributed import Client, LocalCluster

    # Dask's own INFO lines (scheduler and worker start and stop) are not the user's
    # business unless asked for (-v).
    dask_log = logging.getLogger("distributed")
    if not logging.getLogger().isEnabledFor(logging.INFO):
        dask_log.setLevel(logging.ERROR)
    if workers is not None and workers < 1:
        raise BeambenchError(f"--workers must be at least 1, got {workers}")
    if scheduler is not None:
        if workers is not None:
            raise BeambenchError("--workers sizes the embedded cluster; not with --scheduler")
        try:
            client = Client(scheduler, timeout=CONNECT_TIMEOUT_S, set_as_default=False)
        except (OSError, TimeoutError, ValueError) as exc:
            raise BeambenchError(
                f"--scheduler {scheduler}: cannot connect within {CONNECT_TIMEOUT_S:g} s "
                f"({type(exc).__name__}: {exc})"
            ) from None
        try:
            yield client
        except SchedulerLost:
            _close_lost(client)
            raise
        else:
            client.close()
        return
    n = workers if workers is not None else (os.cpu_count() or 1)
    cluster = LocalCluster(
        n_workers=n,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        scheduler_port=0,
        dashboard_address=None,
        # the scheduler's HTTP server (health, metrics) runs even without a dashboard; on
        # Dask's default port 8787 a second campaign on the machine warned it was taken
        scheduler_kwargs={"dashboard": False, "dashboard_address": "127.0.0.1:0"},
        silence_logs=logging.ERROR,
    )
    levels: dict[str, int] = {}
    try:
        client = Client(cluster, set_as_default=False)
        try:
            yield client
        finally:
            _quiet_workers(client)
            client.close()
    finally:
        if not logging.getLogger().isEnabledFor(logging.INFO):
            levels = quiet_dask_logs()  # the nannies here race the same way
        cluster.close()
        for name, level in levels.items():
            logging.getLogger(name).setLevel(level)
