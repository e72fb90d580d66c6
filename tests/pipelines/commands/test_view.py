"""beambench view: the web viewer for a recording answers on 127.0.0.1 and stops on Ctrl-C;
bad input is one error line."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest

from pipelines.cli import main
from pipelines.review.viewer import open_viewer

ROOT = Path(__file__).resolve().parents[3]


def _free_port_pair() -> int:
    """A port P with P and P + 1 free on 127.0.0.1."""
    for _ in range(50):
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        if port >= 65535:
            continue
        with socket.socket() as s:
            try:
                s.bind(("127.0.0.1", port + 1))
            except OSError:
                continue
        return port
    raise RuntimeError("no free port pair")


@pytest.fixture
def recording(tmp_path: Path) -> Path:
    path = tmp_path / "run.rrd"
    with open_viewer("beambench-test", rrd_path=path) as viewer:
        t = np.arange(40) / 400.0
        viewer.log_samples(t, np.sin(t), np.zeros((t.size, 4)))
    return path


@pytest.mark.slow
def test_the_web_viewer_answers_within_10_s_and_stops_on_ctrl_c(recording: Path) -> None:
    port = _free_port_pair()
    cli = [sys.executable, "-m", "pipelines.cli"]
    proc = subprocess.Popen(
        [*cli, "view", str(recording), "--web", "--port", str(port)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
        # a child started from a background job inherits SIGINT ignored; restore it
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    try:
        deadline = time.monotonic() + 10.0
        status = None
        while time.monotonic() < deadline and status is None:
            try:
                with urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=1) as r:
                    status = r.status
                    page = r.read(2000).decode("utf-8", "replace")
            except OSError:
                time.sleep(0.2)
        assert status == 200, "the web viewer did not answer within 10 s"
        assert "rerun" in page.lower()
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=15)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 0, err
    assert f"http://127.0.0.1:{port}/?url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3A{port + 1}" in out
    assert out.strip().endswith("stopped")
    with pytest.raises(OSError):  # the port is free again: nothing left running
        urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=1)


def test_a_file_that_is_no_recording_is_one_error_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    junk = tmp_path / "run.mcap"
    junk.write_bytes(b"\x89MCAP0\r\n")
    assert main(["view", str(junk)]) == 2
    assert capsys.readouterr().err == f"error: {junk}: not a Rerun recording (.rrd)\n"
    assert main(["view", str(tmp_path / "missing.rrd")]) == 2
    assert "no such file" in capsys.readouterr().err


def test_a_port_in_use_is_refused_before_anything_starts(
    recording: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        assert main(["view", str(recording), "--web", "--port", str(port)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: web viewer port") and "choose another --port" in err
