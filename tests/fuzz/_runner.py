"""Run ``beambench`` command lines in one process, each as the console script would
(``pipelines.cli.main``), and report per case: exit status, stdout, stderr, whether an
exception escaped (a traceback), whether it overran its time, and whether any input
file changed. Usage: ``python _runner.py CASES.json RESULTS.json``.

One process for many cases keeps a fuzz run fast; the caller runs it under a timeout, so a
hang in C code (which the per-case alarm cannot interrupt) is caught as well.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import logging
import os
import signal
import sys
import tempfile
import traceback
from pathlib import Path
from typing import Any


class CaseTimeout(BaseException):
    """Raised by the alarm: the case overran its time."""


def _alarm(signum: int, frame: Any) -> None:
    raise CaseTimeout


def _digest(path: str) -> str | None:
    try:
        return hashlib.sha256(Path(path).read_bytes()).hexdigest()
    except OSError:
        return None


def run_case(case: dict[str, Any], timeout_s: int) -> dict[str, Any]:
    from pipelines.cli import main

    before = {p: _digest(p) for p in case.get("inputs", [])}
    out, err = io.StringIO(), io.StringIO()
    logging.root.handlers.clear()  # main() attaches its handler to this case's stderr
    result: dict[str, Any] = {"traceback": None, "timeout": False}
    # what C libraries write to file descriptor 2 (libpng, libjpeg) is the user's stderr too
    fd_err = tempfile.TemporaryFile()
    saved = os.dup(2)
    os.dup2(fd_err.fileno(), 2)
    signal.alarm(timeout_s)
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                result["rc"] = int(main(case["argv"]) or 0)
            except SystemExit as exc:
                result["rc"] = exc.code if isinstance(exc.code, int) else 1
    except CaseTimeout:
        result["timeout"] = True
        result["rc"] = None
    except BaseException:
        result["traceback"] = traceback.format_exc()
        result["rc"] = None
    finally:
        signal.alarm(0)
        os.dup2(saved, 2)
        os.close(saved)
    fd_err.seek(0)
    result["stdout"] = out.getvalue()
    result["stderr"] = fd_err.read().decode("utf-8", "replace") + err.getvalue()
    fd_err.close()
    result["changed"] = [p for p, h in before.items() if _digest(p) != h]
    return result


def main() -> int:
    cases = json.loads(Path(sys.argv[1]).read_text())
    timeout_s = int(sys.argv[3]) if len(sys.argv) > 3 else 60
    signal.signal(signal.SIGALRM, _alarm)
    results = [run_case(c, timeout_s) for c in cases]
    Path(sys.argv[2]).write_text(json.dumps(results))
    return 0


if __name__ == "__main__":
    sys.exit(main())
