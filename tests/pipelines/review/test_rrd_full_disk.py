"""A Rerun recording that cannot be written (a full disk) is the command's one
``error:`` line and exit 2: Rerun's own logger adds nothing, no temporary is left, an
earlier recording of that name is unchanged.

Rerun's file writer is Rust: a monkeypatched ``os.fsync`` does not reach it. Its writes
are stopped instead by what stops any process's writes: a file-size limit
(``RLIMIT_FSIZE``, EFBIG; CPython ignores SIGXFSZ), and where this process may mount one,
a small tmpfs (ENOSPC, the reason named)."""

from __future__ import annotations

import os
import resource
import subprocess
import sys
import uuid
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[3]
SAMPLE = ROOT / "sample_data" / "run-6s.mcap"
LIMIT_BYTES = 256 * 1024  # the sample's recording is megabytes


def _replay(rrd: Path, limit_bytes: int | None = None) -> subprocess.CompletedProcess[str]:
    def limit() -> None:
        if limit_bytes is not None:
            resource.setrlimit(resource.RLIMIT_FSIZE, (limit_bytes, limit_bytes))

    env = {k: v for k, v in os.environ.items() if k != "RUST_LOG"}
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    return subprocess.run(
        [sys.executable, "-m", "pipelines.cli", "replay", str(SAMPLE), "--rrd", str(rrd)],
        capture_output=True,
        text=True,
        timeout=300,
        env=env,
        preexec_fn=limit,
    )


def _check_one_error_line(proc: subprocess.CompletedProcess[str], rrd: Path) -> None:
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.startswith(f"error: {rrd}: cannot write (")
    assert proc.stderr.count("\n") == 1, proc.stderr  # nothing from Rerun's logger
    assert rrd.read_bytes() == b"an earlier recording"
    assert sorted(p.name for p in rrd.parent.iterdir()) == [rrd.name]  # no temporary


def test_a_recording_whose_writes_stop_is_one_error_line(tmp_path: Path) -> None:
    rrd = tmp_path / "run.rrd"
    rrd.write_bytes(b"an earlier recording")
    _check_one_error_line(_replay(rrd, LIMIT_BYTES), rrd)


def test_a_full_disk_under_the_recording_is_named(tmp_path: Path) -> None:
    small = tmp_path / "small"
    small.mkdir()
    mount = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", "size=300k", f"bb-{uuid.uuid4().hex[:8]}", str(small)],
        capture_output=True,
    )
    if mount.returncode != 0:
        pytest.skip(f"cannot mount a small tmpfs here ({mount.stderr.strip()!r})")
    try:
        rrd = small / "run.rrd"
        rrd.write_bytes(b"an earlier recording")
        proc = _replay(rrd)
        _check_one_error_line(proc, rrd)
        assert "(No space left on device)" in proc.stderr
    finally:
        subprocess.run(["umount", str(small)], check=True)
