"""``beambench bench process``: processing a run, where the time goes and how right it is.

A run of the built-in synthetic bench (60 s, or 10 s with ``--quick``: 400 Hz DAQ,
15 frames/s 2048x1536 JPEG) is captured first (not timed as processing), then processed
as ``beambench process --rrd`` does: read the log, calibrate from the registration
object, decode and measure every frame on all cores while a thread reconstructs from
the strains and simulates, align the clocks, write the results file, stream everything to
an ``.rrd``.
Each step's wall time is printed with the errors against the synthetic truth.
The split of the frame step into JPEG decoding and measuring comes from timing both on
a sample of frames in one process. The frame step is then timed again side by side, the
frames decoded in parts (only the segments measured, as ``process`` does) and whole
(before), passes alternating, with the per bench minute each gives.
"""

from __future__ import annotations

import math
import os
import tempfile
import time
from pathlib import Path

import numpy as np

TARGET_S_PER_MINUTE = 30.0  # the processing issue: a 60 s run in at most 30 s on 2 cores


def _decode_share(log_path: Path, calibration: object, stations: tuple[float, ...]) -> float:
    """Fraction of the per-frame time spent decoding the JPEG in parts, as ``process``
    does (20 frames, one process): the reader's time less the measurement's on the
    whole decoded frame."""
    from daq.log import iter_frames
    from vision import Calibration, Measurer, decode
    from vision.regions import RegionReader

    assert isinstance(calibration, Calibration)
    measurer = Measurer(calibration, stations_m=stations)
    reader = RegionReader(measurer)
    t_read = t_meas = 0.0
    for k, frame in enumerate(iter_frames(log_path)):
        if k > 20:
            break
        image = decode(frame.data)
        if k == 0:  # a warm-up: each sets up its sampling plans on its first frame
            reader.measure(frame.data)
            measurer.measure(image)
            continue
        t0 = time.perf_counter()
        reader.measure(frame.data)
        t1 = time.perf_counter()
        measurer.measure(image)
        t2 = time.perf_counter()
        t_read += t1 - t0
        t_meas += t2 - t1
    return max(t_read - t_meas, 0.0) / t_read if t_read > 0 else math.nan


def _frame_step_side_by_side(
    log_path: Path, calibration: object, stations: tuple[float, ...], passes: int
) -> tuple[float, float, float]:
    """The frame step's wall time (s, the fastest of ``passes`` each, alternating) with
    the frames decoded in parts and whole, and the largest difference between the two
    in hub angle (rad) or tip lateral (m) over the run's frames."""
    from daq.log import iter_frames
    from pipelines.process.frames import measure_frames
    from vision import Calibration

    assert isinstance(calibration, Calibration)
    frames = list(iter_frames(log_path))
    best = {True: math.inf, False: math.inf}
    out = {}
    for _ in range(passes):
        for parts in (True, False):
            t0 = time.perf_counter()
            out[parts] = measure_frames(
                frames, calibration, stations_m=stations, decode_parts=parts
            )
            best[parts] = min(best[parts], time.perf_counter() - t0)
    diff = 0.0
    for a, b in zip(out[True], out[False], strict=True):
        ma, mb = a.measurement, b.measurement
        if ma.ok != mb.ok:
            diff = math.inf
        elif ma.ok:
            diff = max(
                diff,
                abs(ma.hub_angle_rad - mb.hub_angle_rad),
                abs(ma.tip_lateral_m - mb.tip_lateral_m),
            )
    return best[True], best[False], diff


def run(quick: bool) -> int:
    from pipelines.demo import capture_synthetic, truth_notes
    from pipelines.process.run import process_run, write_processed
    from pipelines.review.overlays import FramePreviews, stream_processed
    from pipelines.review.viewer import open_viewer
    from pipelines.rig import load_rig

    duration_s = 10.0 if quick else 60.0
    rig = load_rig()
    with tempfile.TemporaryDirectory(prefix="beambench-bench-") as tmp:
        log_path = Path(tmp) / "run.mcap"
        t0 = time.perf_counter()
        devices = capture_synthetic(rig, log_path, duration_s)
        capture_s = time.perf_counter() - t0
        size_mb = log_path.stat().st_size / 1e6

        t0 = time.perf_counter()
        # the recording's frames are reduced in a thread while the frames are measured
        previews = FramePreviews(log_path, 2).start()
        processed = process_run(log_path)
        write_processed(processed, Path(tmp) / "results.nc")
        t = processed.timings
        t1 = time.perf_counter()
        viewer = open_viewer("beambench-bench", rrd_path=Path(tmp) / "run.rrd")
        stream_processed(processed, log_path, viewer, frame_reduction=2, previews=previews)
        viewer.close()
        t.viewer_s = time.perf_counter() - t1
        total_s = time.perf_counter() - t0
        stations = tuple(float(x) for x in rig.gauges.positions_m)
        share = _decode_share(log_path, processed.calibration, stations)
        parts_s, whole_s, diff = _frame_step_side_by_side(
            log_path, processed.calibration, stations, passes=2
        )
        notes = truth_notes(processed, devices)

    ds = processed.results
    n_frames = ds.sizes["frame_time"]
    print(
        f"processing {duration_s:g} s of the synthetic bench ({n_frames} frames, "
        f"{ds.sizes['time']} DAQ samples, log {size_mb:.0f} MB) on {os.cpu_count()} cores"
    )
    print(f"(capture with rendering, not counted: {capture_s:.1f} s)")
    # The model side runs in a thread during the frames (its rows are inside theirs).
    rows = [
        ("read log", t.read_s),
        ("calibrate (registration)", t.calibrate_s),
        (f"frames: JPEG decode, in parts (~{share:.0%})", t.measure_s * share),
        (f"frames: measure (~{1 - share:.0%})", t.measure_s * (1 - share)),
        ("  during the frames: strain reconstruction", -t.strain_s),
        ("  during the frames: free-decay search", -t.damping_s),
        (f"  during the frames: simulate ({ds.attrs['sim_model']})", -t.simulate_s),
        ("wait for the simulation after the frames", t.model_wait_s),
        ("simulate again at the frames' tolerance", t.resimulate_s),
        ("align clocks", t.align_s),
        ("write results", t.write_s),
        ("  during the frames: the .rrd's frames at 1/2 size", -previews.wall_s),
        ("Rerun .rrd (after the frames)", t.viewer_s),
    ]
    print(f"{'step':46s} | {'wall s':>7s} | share")
    print("-" * 66)
    for name, sec in rows:
        if sec < 0:  # overlapped: shown, not a share of the total
            print(f"{name:46s} | {-sec:7.2f} |   (overlapped)")
        else:
            print(f"{name:46s} | {sec:7.2f} | {sec / total_s:5.1%}")
    print("-" * 66)
    per_minute = total_s * 60.0 / duration_s
    verdict = "meets" if per_minute <= TARGET_S_PER_MINUTE else "misses"
    print(
        f"{'total':46s} | {total_s:7.2f} |  = {per_minute:.1f} s per bench minute "
        f"({verdict} the {TARGET_S_PER_MINUTE:g} s target)"
    )
    print(f"frames per second through decode + measure: {n_frames / t.measure_s:.1f}")
    # the same run with the frame step as timed side by side: parts (now) and whole (before)
    rest_s = total_s - t.measure_s
    print(
        f"frame step side by side (fastest of 2 passes each, alternating): decoded in parts "
        f"{parts_s:.2f} s, whole {whole_s:.2f} s; per bench minute "
        f"{(rest_s + parts_s) * 60.0 / duration_s:.1f} s in parts, "
        f"{(rest_s + whole_s) * 60.0 / duration_s:.1f} s whole; parts - whole at most "
        f"{diff:.2g} (rad or m)"
    )
    print("errors against the synthetic truth:")
    for line in notes:
        print(f"  {line}")
    for key in (
        "tip_lateral_image_vs_sim_rms_m",
        "tip_lateral_strain_vs_sim_rms_m",
        "image_tip_lateral_sd_rms_m",
        "sim_tip_error_estimate_m",
    ):
        v = float(ds.attrs.get(key, np.nan))
        print(f"  {key}: {v * 1e3:.3f} mm")
    return 0
