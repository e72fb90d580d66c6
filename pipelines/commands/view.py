"""beambench view: open a ``.rrd`` recording in Rerun's own viewer, native or in a browser.

The native viewer is the ``rerun`` program that comes with rerun-sdk. ``--web`` runs the same
program as a web server instead: it serves Rerun's web viewer over HTTP and the recording over
gRPC, so anybody who can reach the address opens it in a browser (``--bind 0.0.0.0`` offers it
to the lab network; the default, 127.0.0.1, to this machine only). Ctrl-C stops it.
"""

from __future__ import annotations

import argparse
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
from pathlib import Path
from urllib.parse import quote

from pipelines.errors import BeambenchError

RRD_MAGIC = b"RRF2"  # the first bytes of every .rrd file rerun writes


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("rrd", metavar="FILE.rrd")
    p.add_argument("--web", action="store_true", help="serve the web viewer instead")
    p.add_argument(
        "--port",
        type=int,
        default=9090,
        metavar="P",
        help="HTTP port of the web viewer (default 9090); the recording is served over gRPC on P+1",
    )
    p.add_argument(
        "--bind",
        default="127.0.0.1",
        metavar="ADDRESS",
        help="address the web viewer listens on (default 127.0.0.1: this machine only; "
        "0.0.0.0: every interface, e.g. for a colleague on the lab network)",
    )


def _check_recording(path: Path) -> None:
    try:
        with path.open("rb") as f:
            head = f.read(len(RRD_MAGIC))
    except FileNotFoundError:
        raise BeambenchError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise BeambenchError(f"{path}: is a folder, expected a .rrd recording") from None
    except OSError as exc:
        raise BeambenchError(f"{path}: cannot be read ({exc.strerror or exc})") from None
    if head != RRD_MAGIC:
        raise BeambenchError(f"{path}: not a Rerun recording (.rrd)")


def _check_port_free(bind: str, port: int, what: str) -> None:
    if not 1 <= port <= 65535:
        raise BeambenchError(f"--port must be in 1..65534, got {port}")
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
            s.bind((bind, port))
    except OSError as exc:
        raise BeambenchError(
            f"{what} port {port} on {bind} is not available ({exc.strerror or exc}); "
            "choose another --port"
        ) from None


def _rerun_program() -> list[str]:
    """The ``rerun`` executable installed with rerun-sdk (beside this Python's scripts)."""
    beside = Path(sys.executable).with_name("rerun")
    found = str(beside) if beside.is_file() else shutil.which("rerun")
    if found is None:
        raise BeambenchError("the 'rerun' viewer program was not found (pip install rerun-sdk)")
    return [found]


def web_url(bind: str, http_port: int, grpc_port: int) -> str:
    """The address a browser opens: the web viewer, told where the recording is served."""
    host = "127.0.0.1" if bind in ("0.0.0.0", "::") else bind
    data = f"rerun+http://{host}:{grpc_port}/proxy"
    return f"http://{host}:{http_port}/?url={quote(data, safe='')}"


def run(args: argparse.Namespace) -> int:
    path = Path(args.rrd)
    _check_recording(path)
    if not args.web:
        return subprocess.call([*_rerun_program(), str(path)])
    http_port, grpc_port = int(args.port), int(args.port) + 1
    _check_port_free(args.bind, http_port, "web viewer")
    _check_port_free(args.bind, grpc_port, "recording (gRPC)")
    cmd = [
        *_rerun_program(),
        "--serve-web",
        "--bind",
        args.bind,
        "--web-viewer-port",
        str(http_port),
        "--port",
        str(grpc_port),
        str(path),
    ]
    # the server logs as it goes: into a file, which cannot fill up and stall it like a pipe
    log = tempfile.TemporaryFile(mode="w+")
    server = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=log, text=True)
    print(f"serving {path} at {web_url(args.bind, http_port, grpc_port)}  (Ctrl-C stops)")
    sys.stdout.flush()
    try:
        code = server.wait()
    except KeyboardInterrupt:
        server.send_signal(signal.SIGINT)
        try:
            server.wait(timeout=10)
        except subprocess.TimeoutExpired:
            server.kill()
            server.wait()
        print("stopped")
        return 0
    log.seek(0)
    err = log.read().strip().splitlines()
    raise BeambenchError(f"the web viewer stopped (status {code}): {err[-1] if err else ''}")
