"""beambench recover from the command line."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from daq.fakes import FakeStrainDaq
from daq.log import read_run
from pipelines.acquire.capture import capture_run
from pipelines.cli import main
from pipelines.rig import load_rig

RIG = load_rig()


def test_recover_command(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "run.mcap"
    daq = FakeStrainDaq(
        RIG.gauges,
        RIG.potentiometer,
        RIG.daq,
        strain_fn=lambda t: np.zeros((len(t), 4)),
        angle_fn=lambda t: 0 * t + 1,
    )
    capture_run(RIG, daq, None, out, 1.0, realtime=False)
    data = out.read_bytes()
    broken = tmp_path / "broken.mcap"
    broken.write_bytes(data[: len(data) - 100])  # the footer and summary are gone
    fixed = tmp_path / "fixed.mcap"
    assert main(["recover", str(broken), "--out", str(fixed)]) == 0
    text = capsys.readouterr().out
    assert "recovered" in text and "/daq/samples" in text
    assert read_run(fixed).samples == read_run(out).samples
    # never overwrites
    before = fixed.read_bytes()
    assert main(["recover", str(broken), "--out", str(fixed)]) == 2
    assert "already exists" in capsys.readouterr().err
    assert fixed.read_bytes() == before
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"nope")
    assert main(["recover", str(junk), "--out", str(tmp_path / "j.mcap")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: {junk}: not an MCAP file") and "try beambench" not in err
    assert not (tmp_path / "j.mcap").exists()
