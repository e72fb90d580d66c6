"""Stopping the embedded cluster prints nothing of Dask's own on the user's stderr.

A worker stopped while its heartbeat to the scheduler is under way logs the closed
connection at ERROR with a traceback (dask/distributed#7105); the workers share the
command's stderr, and a finished sweep once ended in thirty such lines (CI, stop 21). The
race cannot be provoked on demand, so an error is logged the way that one is, from inside
each worker's own stopping; with ``-v`` (the root logger at INFO) it is left visible, which
also shows the injected line does reach stderr when nothing quiets it.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[3]
LINE = "simulated: heartbeat under way while the worker stops"

SCRIPT = textwrap.dedent(
    f"""
    import logging
    import sys

    from pipelines.campaign.cluster import open_client


    def race():
        # every way into Worker.close (the scheduler's close op, the nanny's stop) passes
        # through BaseWorker.close, looked up on the class when called
        from distributed.worker_state_machine import BaseWorker

        original = BaseWorker.close

        async def close(self, *args, **kwargs):
            logging.getLogger("distributed.worker").error({LINE!r})
            return await original(self, *args, **kwargs)

        BaseWorker.close = close


    if sys.argv[1] == "verbose":
        logging.basicConfig(level=logging.INFO, format="%(message)s")
    with open_client(None, 2) as client:
        assert client.run(race) == {{w: None for w in client.scheduler_info()["workers"]}}
        assert client.submit(sum, [1, 2]).result() == 3
    print("closed")
    """
)


def _run(mode: str) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    return subprocess.run(
        [sys.executable, "-c", SCRIPT, mode], env=env, capture_output=True, text=True, timeout=120
    )


def test_workers_stopping_leave_nothing_on_stderr() -> None:
    proc = _run("quiet")
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "closed"
    assert proc.stderr == ""


def test_with_verbose_logging_the_workers_stopping_is_shown() -> None:
    proc = _run("verbose")
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.count(LINE) == 2, proc.stderr
