"""``process`` outputs that cannot be written: refused before the work where the folder
refuses a file (``/proc``), one ``error:`` line naming the file after it (a full disk);
never a traceback, never a damaged earlier file or a temporary one left behind."""

from __future__ import annotations

import errno
import os
import shutil
from pathlib import Path
from typing import Any

import pytest

from pipelines.cli import main

ROOT = Path(__file__).resolve().parents[3]
SAMPLE = ROOT / "sample_data" / "run-6s.mcap"


def _one_error_line(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    assert main(argv) == 2
    captured = capsys.readouterr()
    assert captured.err.startswith("error: ") and captured.err.count("\n") == 1, captured.err
    assert "Traceback" not in captured.err
    return captured.err


@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="no /proc on this system")
@pytest.mark.parametrize("option", ["--out", "--rrd"])
def test_an_output_under_proc_is_refused_before_the_work(
    option: str, tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    import pipelines.process.run as run_module

    def no_work(*args: Any, **kwargs: Any) -> None:
        raise AssertionError("the work started")

    monkeypatch.setattr(run_module, "process_run", no_work)
    outputs = {"--out": str(tmp_path / "r.nc"), "--rrd": str(tmp_path / "r.rrd")}
    outputs[option] = f"/proc/beambench.{'nc' if option == '--out' else 'rrd'}"
    argv = ["process", str(SAMPLE), "--out", outputs["--out"], "--rrd", outputs["--rrd"]]
    err = _one_error_line(argv, capsys)
    assert f"{option} /proc/beambench" in err and "cannot write in /proc" in err
    assert list(tmp_path.iterdir()) == []


def test_a_log_that_cannot_be_read_is_one_error_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = tmp_path / "run.mcap"
    folder.mkdir()
    shutil.copy(SAMPLE, folder / "inside.mcap")
    err = _one_error_line(["process", str(folder), "--out", str(tmp_path / "r.nc")], capsys)
    assert f"{folder}: cannot be read" in err


@pytest.fixture(scope="module")
def processed() -> Any:
    from pipelines.process.run import process_run

    return process_run(SAMPLE, workers=1)


def _reuse(monkeypatch: pytest.MonkeyPatch, processed: Any) -> None:
    import pipelines.process.run as run_module

    monkeypatch.setattr(run_module, "process_run", lambda *a, **k: processed)


REAL_FSYNC = os.fsync


def _disk_full_for_temporaries(fd: int) -> None:
    """``os.fsync`` on a disk that filled up during the work: the pre-work probe passes,
    the results' temporary file meets ENOSPC."""
    if os.readlink(f"/proc/self/fd/{fd}").endswith(".tmp"):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    REAL_FSYNC(fd)


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/fd").is_dir(), reason="no /proc on this system")
def test_a_full_disk_writing_the_results_is_one_error_line(
    processed: Any,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import pipelines.atomic as atomic

    _reuse(monkeypatch, processed)
    out = tmp_path / "r.nc"
    out.write_bytes(b"an earlier result")
    monkeypatch.setattr(atomic.os, "fsync", _disk_full_for_temporaries)
    err = _one_error_line(["process", str(SAMPLE), "--out", str(out)], capsys)
    assert f"{out}: cannot write (No space left on device)" in err
    assert out.read_bytes() == b"an earlier result"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.nc"]  # no temporary left


@pytest.mark.slow
def test_a_failed_recording_is_one_error_line(
    processed: Any,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import pipelines.review.viewer as viewer_module

    _reuse(monkeypatch, processed)

    def writer_died(self: Any) -> None:
        # what rerun raises when its file writer meets a full disk
        raise RuntimeError("File-writer thread shut down prematurely")

    monkeypatch.setattr(viewer_module.RunViewer, "close", writer_died)
    out, rrd = tmp_path / "r.nc", tmp_path / "r.rrd"
    err = _one_error_line(["process", str(SAMPLE), "--out", str(out), "--rrd", str(rrd)], capsys)
    assert f"{rrd}: cannot write (File-writer thread shut down prematurely)" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.nc"]  # the .rrd's temporary gone


def test_a_calibration_with_points_outside_the_logs_frames_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import numpy as np

    from daq.log import read_run
    from vision import Calibration

    info = read_run(SAMPLE).camera_info
    assert info and info["width"] < 5000
    img = np.array([[100.0, 120.0], [410.0, 90.0], [450.0, 400.0], [80.0, 380.0]])
    plane = np.array([[0.0, 0.0], [0.1, 0.0], [0.1, -0.1], [0.0, -0.1]])
    cal = tmp_path / "cal.json"
    cal.write_text(Calibration(img + np.array([5000.0, 0.0]), plane).to_json())
    out = tmp_path / "r.nc"
    err = _one_error_line(
        ["process", str(SAMPLE), "--out", str(out), "--calibration", str(cal)], capsys
    )
    assert str(cal) in err and "registration point (5100, 120) px lies outside the 2048" in err
    assert not out.exists()


def _with_a_frame_cut(src: Path, dst: Path, frame: int) -> None:
    """``src`` copied with the ``mcap`` library, as another recorder would write it, with
    the JPEG of its ``frame``-th image cut to half: an intact log (its chunks' CRCs are of
    the bytes as written) holding a frame that does not decode."""
    from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
    from mcap.reader import make_reader
    from mcap.writer import CompressionType, Writer

    with open(src, "rb") as f, open(dst, "wb") as g:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        writer = Writer(g, compression=CompressionType.ZSTD)
        writer.start(profile=reader.get_header().profile, library="another recorder 1.0")
        schemas = {
            k: writer.register_schema(s.name, s.encoding, s.data)
            for k, s in summary.schemas.items()
        }
        channels = {
            k: writer.register_channel(
                c.topic, c.message_encoding, schemas.get(c.schema_id, 0), dict(c.metadata)
            )
            for k, c in summary.channels.items()
        }
        for record in reader.iter_metadata():
            writer.add_metadata(record.name, dict(record.metadata))
        k = 0
        for _, channel, message in reader.iter_messages(log_time_order=True):
            data = message.data
            if channel.topic == "/camera/image":
                if k == frame:
                    image = CompressedImage()
                    image.ParseFromString(data)
                    image.data = image.data[: len(image.data) // 2]
                    data = image.SerializeToString()
                k += 1
            writer.add_message(
                channels[channel.id], message.log_time, data, message.publish_time, message.sequence
            )
        writer.finish()


def test_a_frame_that_does_not_decode_is_recorded_without_an_image(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], caplog: pytest.LogCaptureFixture
) -> None:
    # it is reported not measured, the results and the recording are written (the
    # recording shows that frame without an image), and the log is left as it was
    log = tmp_path / "cut-frame.mcap"
    _with_a_frame_cut(SAMPLE, log, 20)
    before = log.read_bytes()
    out, rrd = tmp_path / "r.nc", tmp_path / "r.rrd"
    argv = ["process", str(log), "--out", str(out), "--rrd", str(rrd), "--frame-previews", "region"]
    assert main(argv) == 0
    err = capsys.readouterr().err
    assert "Traceback" not in err and "error:" not in err
    assert "1 frame(s) did not decode; the recording shows them without an image" in caplog.text
    assert "1 of " in caplog.text and "frames not measured: cannot decode frame" in caplog.text
    assert out.is_file() and rrd.is_file()
    assert log.read_bytes() == before
