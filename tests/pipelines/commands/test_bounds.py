"""Work is bounded before it starts: a request beyond the limits of ``--help`` is one
``error:`` line naming the estimated cost, exit 2, and nothing written."""

from __future__ import annotations

import shutil
import struct
import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pipelines.cli import build_parser, main
from pipelines.errors import BeambenchError
from pipelines.rig import default_rig_text
from vision.codec import MAX_SIDE_PX, decode, encode, header_size_px
from vision.errors import ImageSizeError


def _refused(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    assert main(argv) == 2
    captured = capsys.readouterr()
    err = captured.err
    assert err.startswith("error: ") and err.count("\n") == 1, err
    return err


@pytest.mark.parametrize(
    ("argv", "words"),
    [
        (["reciprocating", "--duration", "1e5"], ["4e+07 output samples", "3.9 h of solving"]),
        (["spin-up", "--omega", "1e9"], ["--omega must be at most 50 rad/s"]),
        (["reciprocating", "--rtol", "1e-30"], ["--rtol must be within 1e-10..0.1"]),
        (
            ["reciprocating", "--duration", "1000", "--output-rate", "5000"],
            ["5e+06 output samples", "at most 2e+06 output samples"],
        ),
        (["static", "--mass", "1e300"], ["--mass must be at most 10 kg"]),
        (["free-decay", "--damping", "1e300", "0"], ["--damping A0 must be at most"]),
        (["spin-up", "--output-rate", "1e9"], ["--output-rate must be at most 20000 Hz"]),
    ],
)
def test_sim_refuses_unbounded_work(
    argv: list[str], words: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "s.nc"
    err = _refused(["sim", *argv, "--out", str(out)], capsys)
    for w in words:
        assert w in err, err
    assert not out.exists()


def test_the_limits_are_in_the_help() -> None:
    parser = build_parser()
    sub = parser._subparsers._group_actions[0].choices  # type: ignore[union-attr]
    sim_help = sub["sim"].format_help()
    assert "at most 1200 s" in sim_help and "at most 50" in sim_help and "1e-10..0.1" in sim_help
    assert "at most 14400 s = 4 h" in " ".join(sub["capture"].format_help().split())


@pytest.mark.parametrize("backend", ["fake", "hardware"])
@pytest.mark.parametrize("duration", ["999999", "1e12"])
def test_capture_refuses_unbounded_durations(
    backend: str, duration: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run.mcap"
    argv = ["capture", "--duration", duration, "--out", str(out), "--backend", backend]
    err = _refused(argv, capsys)
    assert "frames, a log of about" in err and "is captured with --backend" in err
    if backend == "fake":
        assert "h of rendering" in err
    assert not out.exists()


def test_capture_refuses_a_log_that_would_not_fit_on_the_disk(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    def tiny(path: Any) -> Any:
        return shutil._ntuple_diskusage(10**9, 10**9 - 10**6, 10**6)  # type: ignore[attr-defined]

    monkeypatch.setattr(shutil, "disk_usage", tiny)
    out = tmp_path / "run.mcap"
    err = _refused(["capture", "--duration", "60", "--out", str(out)], capsys)
    # 900 frames of 2048 x 1536 JPEG at ~0.1 byte a pixel: about 283 MB
    assert "a log of about 285 MB" in err and "1 MB free" in err, err
    assert not out.exists()


def _rig_with(tmp_path: Path, section: str, key: str, value: object) -> Path:
    lines = default_rig_text().splitlines()
    data = tomllib.loads(default_rig_text())
    assert key in data[section]
    start = lines.index(next(x for x in lines if x.startswith(f"[{section}]")))
    i = next(i for i in range(start, len(lines)) if lines[i].startswith(f"{key} "))
    lines[i] = f"{key} = {value}"
    path = tmp_path / "rig.toml"
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize(
    ("section", "key", "value", "words"),
    [
        ("camera", "width_px", 20000, "[camera] width_px must be between 16 and 16384"),
        ("camera", "frame_rate_hz", 1000.0, "frame_rate_hz must be at most 158.9 frames/s"),
        ("camera", "latency_s", "nan", "[camera.latency_s] must be a finite number"),
        ("synthetic", "warmup_s", 1e9, "warmup_s must be at most 600 s"),
        ("daq", "block_duration_s", 1e9, "block_duration_s must be at most 10 s"),
    ],
)
def test_capture_refuses_a_rig_it_would_crash_on(
    section: str,
    key: str,
    value: object,
    words: str,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    rig = _rig_with(tmp_path, section, key, value)
    out = tmp_path / "run.mcap"
    err = _refused(["capture", "--duration", "1", "--rig", str(rig), "--out", str(out)], capsys)
    assert str(rig) in err and words in err, err
    assert not out.exists()


def _png_claiming(width: int, height: int) -> bytes:
    data = bytearray(encode(np.zeros((8, 8), np.uint8), "png"))
    data[16:24] = struct.pack(">II", width, height)
    return bytes(data)


def _jpeg_claiming(width: int, height: int) -> bytes:
    data = bytearray(encode(np.zeros((8, 8), np.uint8), "jpeg"))
    i = 2
    while data[i + 1] not in (0xC0, 0xC2):
        i += 2 + struct.unpack(">H", data[i + 2 : i + 4])[0]
    data[i + 5 : i + 9] = struct.pack(">HH", height, width)
    return bytes(data)


@pytest.mark.parametrize("make", [_png_claiming, _jpeg_claiming])
def test_header_size_is_read_without_decoding(make: Any) -> None:
    assert header_size_px(make(321, 123)) == (321, 123)
    with pytest.raises(ImageSizeError, match="at most 16384 px a side"):
        decode(make(MAX_SIDE_PX + 1, 10))


def test_measure_refuses_a_png_header_claiming_100000_px(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    image = tmp_path / "huge.png"
    image.write_bytes(_png_claiming(100000, 100000))
    cal = tmp_path / "cal.json"
    from vision import Calibration

    img = [[100.0, 120.0], [410.0, 90.0], [450.0, 400.0], [80.0, 380.0]]
    plane = [[0.0, 0.0], [0.1, 0.0], [0.1, -0.1], [0.0, -0.1]]
    cal.write_text(Calibration(np.array(img), np.array(plane)).to_json())
    err = _refused(["measure", str(image), "--calibration", str(cal)], capsys)
    assert f"{image}: the image header claims 100000 x 100000 px" in err


@pytest.mark.parametrize(
    ("argv", "words"),
    [
        (
            ["--crank-hz", "0.001"],
            ["--crank-hz 0.001 Hz", "67 min", "at most 1200 s a point", "from 0.00334 Hz"],
        ),
        (["--crank-hz", "0.001:1:3"], ["--crank-hz 0.001 Hz", "at most 1200 s a point"]),
        (
            ["--crank-hz", "0.5:2:5000"],
            ["5000 points would simulate", "of solving with --model auto", "6.7 h"],
        ),
        (["--crank-hz", "1", "--a1", "0.1,1e6"], ["--a1 1e+06 s: at most 10 s"]),
    ],
)
def test_sweep_refuses_unbounded_work(
    argv: list[str], words: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # refused before any cluster starts (one line, exit 2, nothing written)
    out = tmp_path / "sweep.nc"
    err = _refused(["sweep", "reciprocating", *argv, "--out", str(out)], capsys)
    for w in words:
        assert w in err, err
    assert not out.exists()


def test_a_sweep_within_the_limits_is_not_refused() -> None:
    from pipelines.commands.sweep import MAX_SWEEP_SIMULATED_S, check_sweep_cost

    check_sweep_cost([4 / (1200.0 - 3.0)], [0.1], "auto")  # the slowest point allowed
    n = int(MAX_SWEEP_SIMULATED_S // 7.0)
    check_sweep_cost([1.0] * n, [0.1], "auto")  # 7 s a point at 1 Hz
    with pytest.raises(BeambenchError, match="points would simulate"):
        check_sweep_cost([1.0] * (n + 1), [0.1], "auto")
