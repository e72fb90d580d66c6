"""beambench info on real captured logs: counts, rates, gaps and drops."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from daq.fakes import CameraFaults, DaqFaults, FakeCamera, FakeStrainDaq
from daq.log import summarize_log
from pipelines.acquire.capture import capture_run
from pipelines.cli import main
from pipelines.rig import load_rig

RIG = load_rig()
JPEG = cv2.imencode(".jpg", np.zeros((48, 64, 3), np.uint8))[1].tobytes()


def _capture(
    out: Path, daq_faults: DaqFaults | None = None, cam_faults: CameraFaults | None = None
) -> None:
    daq = FakeStrainDaq(
        RIG.gauges,
        RIG.potentiometer,
        RIG.daq,
        strain_fn=lambda t: np.zeros((len(t), 4)),
        angle_fn=lambda t: 1.8 + 0.7 * np.sin(5.78 * t),
        faults=daq_faults,
    )
    cam = FakeCamera(
        render_fn=lambda t, e: JPEG,
        width_px=64,
        height_px=48,
        frame_rate_hz=15.0,
        faults=cam_faults,
    )
    capture_run(RIG, daq, cam, out, 2.0, realtime=False)


def test_info_reports_counts_rates_and_gaps(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run.mcap"
    _capture(out, DaqFaults(drop_blocks=(4,)), CameraFaults(drop_frames=(10, 11)))
    s = summarize_log(str(out))
    ch = {c.topic: c for c in s.channels}
    samples = ch["/daq/samples"]
    # a dropped 0.1 s block costs its 40 samples and the filter's 45 ms (18 samples) of
    # settling after the restart; the run's start loses nothing: the acquisition is
    # pre-rolled by the settling (issue #16; it used to lose the same 18)
    lost = 40 + 18
    assert samples.count == 800 - lost
    assert samples.rate_hz == pytest.approx(
        400.0 * (samples.count - 1) / (samples.count - 1 + lost), rel=1e-3
    )
    assert (samples.sequence_gaps, samples.missing, samples.time_gaps) == (1, lost, 1)
    assert samples.largest_gap_s == pytest.approx((lost + 1) / 400.0)
    image = ch["/camera/image"]
    assert (image.count, image.sequence_gaps, image.missing) == (28, 1, 2)
    assert image.schema == "foxglove.CompressedImage"
    assert s.problems == {"dropped_samples": 1, "dropped_frames": 1}
    assert s.duration_s == pytest.approx(2.0, abs=0.01)
    assert main(["info", str(out)]) == 0
    text = capsys.readouterr().out
    assert "/daq/samples" in text and "beambench.DaqSample" in text
    assert "dropped_frames x1" in text


def test_info_on_a_clean_run_and_on_a_broken_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run.mcap"
    _capture(out)
    assert summarize_log(str(out)).problems == {}
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(out.read_bytes()[:5000])
    assert main(["info", str(cut)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: {cut}:") and "beambench recover" in err
    assert err.count("\n") == 1
    assert main(["info", str(tmp_path / "missing.mcap")]) == 2
    assert "no such file" in capsys.readouterr().err
