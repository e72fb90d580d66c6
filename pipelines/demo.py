"""The main job on the built-in synthetic bench: capture -> process -> Rerun -> report.

Because the bench is synthetic, the truth is known: the report also states how far the
camera measurement and the time alignment are from it.
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from pipelines.acquire.capture import capture_run
from pipelines.acquire.synthetic import CAMERA_CLOCK_OFFSET_S, SyntheticDevices, build_synthetic
from pipelines.process.run import Processed, process_run, write_processed
from pipelines.review.overlays import stream_processed
from pipelines.review.report import PLOTS, REPORT_NAME, write_report
from pipelines.review.viewer import open_viewer
from pipelines.rig import Rig

log = logging.getLogger(__name__)

LOG_NAME = "run.mcap"
RESULTS_NAME = "results.nc"
RRD_NAME = "run.rrd"
# every file the demo writes into its folder (the log's partial name while it is captured)
OUTPUT_NAMES = (
    LOG_NAME,
    LOG_NAME + ".partial",
    RESULTS_NAME,
    RRD_NAME,
    REPORT_NAME,
    *PLOTS.values(),
)


def _stderr_progress(label: str) -> Callable[[float, float], None] | None:

    if not sys.stderr.isatty():
        return None

    def show(done_s: float, total_s: float) -> None:
        frac = min(1.0, done_s / total_s)
        bar = "#" * round(30 * frac)
        sys.stderr.write(f"\r{label:<12} [{bar:<30}] {done_s:6.1f}/{total_s:.1f} s")
        if frac >= 1.0:
            sys.stderr.write("\n")
        sys.stderr.flush()

    return show


def capture_synthetic(rig: Rig, out: Path, duration_s: float) -> SyntheticDevices:
    """Capture into ``out`` (replacing a previous demo's log only once the new one is
    complete)."""
    devices = build_synthetic(rig, duration_s)
    partial = out.with_name(out.name + ".partial")
    with contextlib.suppress(FileNotFoundError):
        partial.unlink()
    capture_run(
        rig,
        devices.daq,
        devices.camera,
        partial,
        duration_s,
        realtime=False,
        camera_info=devices.camera_info,
        progress=_stderr_progress("capture"),
    )
    os.replace(partial, out)
    return devices


def truth_notes(processed: Processed, devices: SyntheticDevices) -> list[str]:
    """How far the measurement is from the synthetic bench's truth."""
    ds = processed.results
    cam = devices.camera
    bench = devices.bench
    seq = np.array([f.sequence for f in processed.frames])
    # exposure mid-points on the bench's clock; the results count from t_zero_ns
    t_true = np.array([cam.true_exposure_start_s(int(k)) for k in seq]) + 0.5 * cam.exposure_s
    t_zero_s = float(ds.attrs.get("t_zero_ns", 0)) * 1e-9
    ok = ds["frame_ok"].values.astype(bool)
    notes = []
    dt_err = ds["frame_time"].values - (t_true - t_zero_s)
    notes.append(
        "Synthetic truth: camera clock offset "
        f"{CAMERA_CLOCK_OFFSET_S * 1e3:.1f} ms with "
        f"{bench.rig.synthetic.clock_drift_ppm:g} ppm drift"
        + (
            f", frames stamped {latency * 1e3:.1f} ms after mid-exposure"
            if (latency := bench.rig.synthetic.stamp_latency_s)
            else ""
        )
        + "; frame times after alignment "
        f"are within {np.max(np.abs(dt_err)) * 1e3:.3f} ms of the true exposure mid-points "
        f"(RMS {np.sqrt(np.mean(dt_err**2)) * 1e3:.3f} ms)."
    )
    if ok.any():
        true_tip = bench.truth.tip_lateral_m(t_true[ok])
        err = ds["tip_lateral"].values[ok] - true_tip
        hub_true = bench.truth.hub_angle_plane_rad(t_true[ok])
        hub_err = np.angle(np.exp(1j * (ds["hub_angle_image"].values[ok] - hub_true)))
        notes.append(
            f"Image measurement against the synthetic truth over {int(ok.sum())} frames: "
            f"tip lateral RMS {np.sqrt(np.mean(err**2)) * 1e3:.3f} mm "
            f"(max {np.max(np.abs(err)) * 1e3:.3f} mm); hub angle RMS "
            f"{math.degrees(float(np.sqrt(np.mean(hub_err**2)))):.4f} deg."
        )
    return notes


def run_demo(rig: Rig, out: Path, *, duration_s: float = 20.0) -> dict[str, Path]:
    """Run the whole job; return the outputs by label."""
    timings: dict[str, float] = {}
    log_path = out / LOG_NAME
    t0 = time.perf_counter()
    devices = capture_synthetic(rig, log_path, duration_s)
    timings["capture"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    processed = process_run(log_path)
    results_path = out / RESULTS_NAME
    write_processed(processed, results_path)
    timings["process"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    rrd_path = out / RRD_NAME
    viewer = open_viewer("beambench-demo", rrd_path=rrd_path)
    try:
        stream_processed(processed, log_path, viewer)
    except BaseException:
        viewer.abort()
        raise
    viewer.close()
    timings["rerun"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    notes = truth_notes(processed, devices)
    step = ", ".join(f"{k} {v:.1f} s" for k, v in timings.items())
    notes.append(f"Wall time: {step}.")
    report = write_report(
        processed.results,
        out,
        title=f"beambench demo: {duration_s:g} s on the synthetic bench",
        notes=notes,
    )
    timings["report"] = time.perf_counter() - t0
    return {"log": log_path, "results": results_path, "rerun": rrd_path, "report": report}
