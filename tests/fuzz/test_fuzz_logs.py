"""Run logs, damaged: cut short at any byte, bytes flipped. ``beambench info`` on each
either exits 2 with one error line or prints what the undamaged log holds (a damaged log
read as if whole is the corruption the contract forbids).

Kept apart from the other fuzz modules: the log reader's verification (chunk and data
CRCs, message contents) is another change (issue #16's log half); cases this module finds
are the reader's to fix.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.fuzz.contract import CASES, Case, report, rng, run_cases


@pytest.fixture(scope="module")
def small_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Half a second of DAQ samples from the fake DAQ (no camera), written by capture."""
    from daq.fakes import FakeStrainDaq
    from pipelines.acquire.capture import capture_run
    from pipelines.rig import load_rig

    rig = load_rig()
    out = tmp_path_factory.mktemp("fuzz-log") / "run.mcap"
    daq = FakeStrainDaq(
        rig.gauges,
        rig.potentiometer,
        rig.daq,
        strain_fn=lambda t: 1e-4 * np.sin(2 * np.pi * 1.3 * t)[:, None] * np.ones((1, 4)),
        angle_fn=lambda t: 1.7 + 0.5 * np.sin(2 * np.pi * 0.9 * t),
    )
    capture_run(rig, daq, None, out, 0.5, realtime=False)
    return out


def mutate(r: Any, data: bytes) -> tuple[bytes, str]:
    if r.random() < 0.4:
        n = r.randrange(len(data))
        return data[:n], f"cut to {n} of {len(data)} bytes"
    out = bytearray(data)
    at = [r.randrange(len(out)) for _ in range(r.randint(1, 3))]
    for i in at:
        out[i] ^= 1 << r.randrange(8)
    return bytes(out), f"bits flipped at bytes {at}"


def test_fuzz_damaged_logs(tmp_path: Path, small_log: Path) -> None:
    from pipelines.cli import main

    r = rng("logs")
    data = small_log.read_bytes()
    cases = []
    for i in range(CASES):
        damaged, what = mutate(r, data)
        path = tmp_path / f"log{i}.mcap"
        path.write_bytes(damaged)
        cases.append(Case(["info", str(path)], what, [str(path)]))
    # what `info` prints for the undamaged log, its own path replaced by the case's
    import contextlib
    import io

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert main(["info", str(small_log)]) == 0
    whole = buf.getvalue().split("\n", 1)[1]  # past the line naming the file and its size

    def same_as_whole(stdout: str) -> str | None:
        body = stdout.split("\n", 1)[1] if "\n" in stdout else ""
        if body != whole:
            return "exit 0 with contents that differ from the undamaged log's"
        return None

    for c in cases:
        c.check_ok = same_as_whole
    problems, counts = run_cases(cases, tmp_path)
    report("logs", problems, counts)
