"""Where a campaign's tasks run: an embedded ``distributed.LocalCluster`` sized to the
machine, or a lab cluster started with the standard ``dask scheduler`` /
``dask worker tcp://...`` commands.

Embedded workers are processes with one thread each (the per-run pipeline holds the GIL
in its Python steps), listening on 127.0.0.1 only, with no dashboard (it needs bokeh and
a port). Connecting gives up after :data:`CONNECT_TIMEOUT_S` with a ``BeambenchError``
naming the address, never a hang.
"""

from __future__ import annotations

import contextlib
import logging
import os
from collections.abc import Iterator
from typing import Any

from pipelines.errors import BeambenchError

CONNECT_TIMEOUT_S = 5.0


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
        finally:
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
        silence_logs=logging.ERROR,
    )
    try:
        client = Client(cluster, set_as_default=False)
        try:
            yield client
        finally:
            client.close()
    finally:
        cluster.close()
