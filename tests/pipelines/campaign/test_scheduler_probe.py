"""A scheduler that stops answering without closing its connection (a hung process, a
host gone) is a SchedulerLost after the probe's timeout, not a wait without end: a real
``dask scheduler`` stopped with SIGSTOP, a task that no worker will ever run."""

from __future__ import annotations

import json
import logging
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

import pipelines.campaign.cluster as cluster
from pipelines.campaign.cluster import SchedulerLost, completed

pytestmark = pytest.mark.slow

BIN = Path(sys.executable).parent


def test_a_scheduler_that_stops_answering_is_lost(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, request: pytest.FixtureRequest
) -> None:
    from distributed import Client

    # SchedulerLost quiets Dask's loggers for the rest of the process (the CLI's); not
    # for the tests after this one
    names = [n for n in logging.root.manager.loggerDict if n.startswith("distributed")]
    levels = {n: logging.getLogger(n).level for n in ["distributed", *names]}
    request.addfinalizer(lambda: [logging.getLogger(n).setLevel(v) for n, v in levels.items()])
    sched_file = tmp_path / "scheduler.json"
    proc = subprocess.Popen(
        [
            *(str(BIN / "dask"), "scheduler", "--host", "127.0.0.1", "--port", "0"),
            *("--no-dashboard", "--scheduler-file", str(sched_file)),
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        deadline = time.monotonic() + 60
        while not sched_file.exists() and time.monotonic() < deadline:
            time.sleep(0.1)
        address = json.loads(sched_file.read_text())["address"]
        monkeypatch.setattr(cluster, "PROBE_INTERVAL_S", 0.5)
        monkeypatch.setattr(cluster, "PROBE_TIMEOUT_S", 2.0)
        client = Client(address, timeout=10, set_as_default=False)
        try:
            with client.as_current():
                future = client.submit(sum, [1, 2], pure=False)  # no worker: never runs
                os.kill(proc.pid, signal.SIGSTOP)
                lost = f"lost the scheduler {address} \\(no answer within 2 s\\)"
                with pytest.raises(SchedulerLost, match=lost):
                    for _ in completed(client, [future]):
                        pass
        finally:
            os.kill(proc.pid, signal.SIGKILL)
            cluster._close_lost(client)
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.wait()
