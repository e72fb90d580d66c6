"""beambench capture: record a run to an MCAP log."""

from __future__ import annotations

import argparse
import math
import shutil
from pathlib import Path
from typing import Any

from pipelines.commands._args import add_rig_argument, add_viewer_arguments, rig_from_args
from pipelines.errors import BeambenchError
from pipelines.paths import check_writable_output, refuse_aliases
from pipelines.progress import Progress
from pipelines.rig import Rig

# Work is bounded before it starts (the error names the estimated cost):
MAX_CAPTURE_S = 4 * 3600.0  # a long session at the bench
# the synthetic bench simulates the whole run up front and renders every frame (~55 ms a
# 3 MP frame on one core): an hour is 54,000 frames and about 25 min of rendering
MAX_SYNTHETIC_CAPTURE_S = 3600.0
# log bytes per camera pixel (measured: 275 MB for 900 frames of 2048 x 1536 JPEG at
# quality 90, 0.1 B/px; PNG of the same frames ~0.6 B/px) and per DAQ sample (5 channels
# as float64 with time and sequence in the message, and the index)
LOG_BYTES_PER_PX = {"jpeg": 0.1, "png": 0.6}
LOG_BYTES_PER_SAMPLE = 80.0
RENDER_S_PER_MPX = 0.018


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--duration",
        metavar="S",
        type=float,
        required=True,
        help=f"seconds (at most {MAX_CAPTURE_S:g} s = 4 h with --backend hardware, "
        f"{MAX_SYNTHETIC_CAPTURE_S:g} s with the synthetic bench; the estimated log must fit "
        "on the disk)",
    )
    p.add_argument("--out", metavar="RUN.mcap", required=True, help="log file to write")
    add_rig_argument(p)
    p.add_argument("--backend", choices=("fake", "hardware"), default="fake")
    p.add_argument("--realtime", action="store_true", help="pace the fake like the hardware")
    add_viewer_arguments(p, frame_reduction_default=4)
    p.add_argument(
        "--view-rate",
        type=float,
        default=3.0,
        metavar="HZ",
        help="with a live view: camera frames shown (and measured) per second, at most "
        "(default 3; the log keeps every frame)",
    )


def camera_info_from_rig(rig: Rig) -> dict[str, Any]:
    """``/camera/info`` content from the rig's nominal intrinsics (principal point at the
    image centre, OpenCV plumb_bob distortion)."""
    from vision.camera import camera_matrix

    cam = rig.camera
    return {
        "width": cam.width_px,
        "height": cam.height_px,
        "K": camera_matrix(cam.focal_length_px, cam.width_px, cam.height_px).ravel().tolist(),
        "D": list(cam.distortion),
        "distortion_model": "plumb_bob",
    }


def estimate_log_bytes(rig: Rig, duration_s: float) -> float:
    """The log a capture of ``duration_s`` writes, bytes (frames and DAQ samples)."""
    cam = rig.camera
    frame_bytes = cam.width_px * cam.height_px * LOG_BYTES_PER_PX[cam.encoding]
    return duration_s * (
        cam.frame_rate_hz * frame_bytes + rig.daq.output_rate_hz * LOG_BYTES_PER_SAMPLE
    )


def check_capture_cost(rig: Rig, duration_s: float, backend: str, out: Path) -> None:
    """Refuse a capture beyond the limits of ``--help`` or the free disk, before any work."""
    log_bytes = estimate_log_bytes(rig, duration_s)
    frames = duration_s * rig.camera.frame_rate_hz
    cost = f"{frames:.3g} frames, a log of about {_human_bytes(log_bytes)}"
    limit = MAX_CAPTURE_S if backend == "hardware" else MAX_SYNTHETIC_CAPTURE_S
    if duration_s > limit:
        if backend != "hardware":
            mpx = rig.camera.width_px * rig.camera.height_px / 1e6
            cost += f" and about {frames * mpx * RENDER_S_PER_MPX / 2 / 3600:.3g} h of rendering"
        raise BeambenchError(
            f"--duration {duration_s:g} s would record {cost}; at most {limit:g} s "
            f"({limit / 3600:g} h) is captured with --backend {backend}"
        )
    folder = out.absolute().parent
    check_writable_output(out, "--out")
    free = shutil.disk_usage(folder).free
    if log_bytes > free:
        raise BeambenchError(
            f"--duration {duration_s:g} s would record {cost}; {folder} has "
            f"{_human_bytes(free)} free"
        )


def _human_bytes(n: float) -> str:
    for unit in ("B", "kB", "MB", "GB", "TB", "PB"):
        if n < 1000 or unit == "PB":
            return f"{n:.3g} {unit}"
        n /= 1000
    raise AssertionError  # pragma: no cover


def hardware_devices(rig: Rig) -> tuple[Any, Any, dict[str, Any]]:
    """NI-DAQmx strain DAQ and an OpenCV camera (device, video file or stills folder)."""
    from daq.drivers.nidaq import NiStrainDaq, check_nidaqmx
    from daq.drivers.opencv_camera import open_camera
    from daq.errors import DriverUnavailableError

    try:
        check_nidaqmx()
    except DriverUnavailableError as exc:
        raise BeambenchError(f"--backend hardware: {exc}") from None
    daq_device = NiStrainDaq(rig.gauges, rig.potentiometer, rig.daq)
    camera = open_camera(
        rig.camera.device,
        width_px=rig.camera.width_px,
        height_px=rig.camera.height_px,
        frame_rate_hz=rig.camera.frame_rate_hz,
        encoding=rig.camera.encoding,
        jpeg_quality=rig.camera.jpeg_quality,
    )
    return daq_device, camera, camera_info_from_rig(rig)


def open_live_view(args: argparse.Namespace, rig: Rig, camera_info: dict[str, Any] | None) -> Any:
    """The live view the arguments ask for (``--rrd``, ``--spawn`` or ``--connect``), or None."""
    if not (args.rrd or args.spawn or args.connect):
        return None
    if not (math.isfinite(args.view_rate) and 0 < args.view_rate <= rig.camera.frame_rate_hz):
        raise BeambenchError(
            f"--view-rate must be in (0, {rig.camera.frame_rate_hz:g}] frames/s, "
            f"got {args.view_rate:g}"
        )
    from pipelines.review.live import LiveView
    from pipelines.review.viewer import open_viewer

    try:
        viewer = open_viewer(
            "beambench-capture",
            rrd_path=args.rrd,
            spawn=bool(args.spawn),
            connect_url=args.connect,
            layout="live",
        )
    except (ValueError, OSError, RuntimeError) as exc:
        raise BeambenchError(f"cannot open the live view: {exc}") from None
    return LiveView(
        viewer,
        rig,
        frame_rate_hz=args.view_rate,
        frame_reduction=args.frame_reduction,
        camera_info=camera_info,
    )


def run(args: argparse.Namespace) -> int:
    from pipelines.acquire.capture import capture_run

    refuse_aliases({"--out": args.out, "--rrd": args.rrd}, {"--rig": args.rig})
    rig = rig_from_args(args)
    if not math.isfinite(args.duration) or args.duration <= 0:
        raise BeambenchError(
            f"--duration must be a positive number of seconds, got {args.duration}"
        )
    check_capture_cost(rig, args.duration, args.backend, Path(args.out))
    if args.backend == "fake":
        from pipelines.acquire.synthetic import make_synthetic_devices

        daq_device, camera, camera_info = make_synthetic_devices(
            rig, args.duration, realtime=args.realtime, seed=rig.synthetic.seed
        )
    else:
        daq_device, camera, camera_info = hardware_devices(rig)
    live = open_live_view(args, rig, camera_info)
    try:
        with Progress("capture", total=args.duration) as bar:

            def progress(done_s: float, total_s: float) -> None:
                bar.update(done_s - bar.done)

            s = capture_run(
                rig,
                daq_device,
                camera,
                args.out,
                args.duration,
                realtime=args.realtime or args.backend == "hardware",
                camera_info=camera_info,
                progress=progress if bar.enabled else None,
                monitor=live,
            )
    finally:
        if live is not None:
            stats = live.close()
            live.viewer.close()
    if live is not None:
        print(
            f"  live view: {stats.frames_shown} frames shown ({stats.frames_measured} "
            f"measured), {stats.sample_blocks} sample blocks, {stats.dropped} dropped by "
            "the view (none by the log)"
        )
    print(f"wrote {s.out_path} ({s.log_bytes / 1e6:.2f} MB), run {s.run_id}")
    print(
        f"  {s.samples} samples at {rig.daq.output_rate_hz:g} Hz (acquired at "
        f"{s.acquisition_rate_hz:g} Hz), {s.frames} frames, {s.events} events"
    )
    print(
        f"  dropped samples {s.dropped_samples}, dropped frames {s.dropped_frames}, "
        f"overruns {s.overruns}, clipping {s.clipping_events}, device errors {s.device_errors}"
    )
    print(f"  wall {s.wall_time_s:.2f} s, CPU {s.cpu_time_s:.2f} s")
    return 0
