"""Screenshots of the Rerun review for the README: the demo's processed run and its raw replay,
as Rerun's web viewer draws them in headless Chromium (WebGL on SwiftShader, no GPU).

    python sample_data/screenshots.py [DEMO_DIR]      (make screenshots)

DEMO_DIR holds ``run.mcap`` and ``run.rrd`` from ``beambench demo`` (made when missing).
Needs Debian's chromium (``apt-get install chromium``); writes sample_data/review-*.png.
"""

from __future__ import annotations

import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path

HERE = Path(__file__).resolve().parent
BEAMBENCH = [sys.executable, "-m", "pipelines.cli"]
CHROMIUM_FLAGS = [
    "--headless",
    "--no-sandbox",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
    "--window-size=1800,1100",
    "--virtual-time-budget=90000",
]


def _free_port() -> int:
    while True:
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = int(s.getsockname()[1])
        with socket.socket() as s:
            try:
                s.bind(("127.0.0.1", port + 1))
                return port
            except OSError:
                continue


def shoot(rrd: Path, png: Path) -> None:
    port = _free_port()
    server = subprocess.Popen(
        [*BEAMBENCH, "view", str(rrd), "--web", "--port", str(port)],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert server.stdout is not None
        url = server.stdout.readline().split()[3] + "&renderer=webgl"
        for _ in range(50):
            try:
                urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=1).close()
                break
            except OSError:
                time.sleep(0.2)
        with tempfile.TemporaryDirectory() as profile:
            subprocess.run(
                [
                    "chromium",
                    *CHROMIUM_FLAGS,
                    f"--user-data-dir={profile}",
                    f"--screenshot={png}",
                    url,
                ],
                check=True,
                capture_output=True,
                timeout=400,
            )
        print(f"wrote {png}")
    finally:
        server.send_signal(signal.SIGINT)
        server.wait(timeout=20)


def main() -> int:
    demo = Path(sys.argv[1]) if len(sys.argv) > 1 else Path("demo-out")
    if not (demo / "run.rrd").is_file():
        subprocess.run([*BEAMBENCH, "demo", "--out", str(demo)], check=True)
    raw = demo / "replay.rrd"
    subprocess.run([*BEAMBENCH, "replay", str(demo / "run.mcap"), "--rrd", str(raw)], check=True)
    shoot(demo / "run.rrd", HERE / "review-processed.png")
    shoot(raw, HERE / "review-replay.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
