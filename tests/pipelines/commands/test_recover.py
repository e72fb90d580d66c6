"""beambench recover from the command line."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from foxglove_schemas_protobuf.Log_pb2 import Log
from mcap.writer import Writer
from mcap_protobuf.schema import build_file_descriptor_set

from daq.fakes import FakeStrainDaq
from daq.log import LogWriter, read_run
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


def _foreign_log(path: Path, samples: list[bytes], *, finish: bool) -> None:
    """A log as another recorder writes it (the mcap library directly), finished or
    killed after a flush; ``samples`` are the /daq/samples payloads at 250 Hz."""
    with open(path, "wb") as f:
        w = Writer(f, chunk_size=1024, enable_data_crcs=True)
        w.start(profile="beambench", library="another-recorder 1.0")
        sid = w.register_schema("beambench.DaqSample", "jsonschema", b"{}")
        cid = w.register_channel("/daq/samples", "json", sid)
        fds = build_file_descriptor_set(Log).SerializeToString()
        lid = w.register_channel(
            "/events", "protobuf", w.register_schema("foxglove.Log", "protobuf", fds)
        )
        w.add_metadata("rig", {"json": RIG.to_json()})
        w.add_metadata("run", {"run_id": "x"})
        w.add_message(lid, 0, Log(name="start", message="").SerializeToString(), 0, 0)
        for k, data in enumerate(samples):
            w.add_message(cid, k * 4_000_000, data, 0, k)
        if finish:
            w.finish()
        else:  # killed after a flush: the chunk is written, no summary or footer
            w.flush()


def _sample(k: int, angle: object = 0.5) -> bytes:
    t = k * 4_000_000
    return json.dumps(
        {
            "timestamp": {"sec": t // 10**9, "nsec": t % 10**9},
            "rocker_angle_rad": angle,
            "strain": [1e-5] * 4,
            "raw_volts": [1.0] * 5,
        }
    ).encode()


def _refused(argv: list[str], out: Path, capsys: pytest.CaptureFixture[str], problem: str) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: ") and problem in err, err
    assert "try beambench recover" not in err
    assert not out.exists()
    assert not [p for p in out.parent.iterdir() if p.name.startswith(f".{out.name}")]


def test_recover_refuses_what_restores_nothing_usable(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    broken = tmp_path / "broken.mcap"
    out = tmp_path / "fixed.mcap"
    args = ["recover", str(broken), "--out", str(out)]
    # killed before its first flush: only the header and metadata (0 messages)
    with LogWriter(broken, rig_json=RIG.to_json(), run_info={"run_id": "r"}):
        pass
    data = broken.read_bytes()
    header_end = data.index(b"\x0f\x04\x00\x00\x00\x00\x00\x00\x00")  # the DataEnd record
    broken.write_bytes(data[:header_end])
    _refused(args, out, capsys, "nothing to recover: no message survived")
    # events but no /daq/samples
    _foreign_log(broken, [], finish=False)
    _refused(args, out, capsys, "no /daq/samples message survived")
    # samples whose contents were damaged before they were written: recover cannot mend
    _foreign_log(broken, [_sample(0), _sample(1, True), _sample(2)], finish=False)
    _refused(args, out, capsys, "does not read back: bad /daq/samples message (sequence 1")
    # a complete log whose rig record changed: the data-section CRC shows it
    _foreign_log(broken, [_sample(k) for k in range(20)], finish=True)
    good = broken.read_bytes()
    at = good.index(b"warmup_s") + 12
    broken.write_bytes(good[:at] + bytes([good[at] ^ 1]) + good[at + 1 :])
    _refused(args, out, capsys, "data-section CRC fails but every chunk passes its own")
    # the same log undamaged and cut: restored, and the output reads back verified
    broken.write_bytes(good[: len(good) - 30])
    assert main(args) == 0
    assert "verified" in capsys.readouterr().out
    assert len(read_run(out, require_samples=True).samples) == 20
