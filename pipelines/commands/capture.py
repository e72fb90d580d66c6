"""beambench capture: record a run to an MCAP log."""

from __future__ import annotations

import argparse
import math
from typing import Any

from pipelines.commands._args import add_rig_argument, rig_from_args
from pipelines.errors import BeambenchError
from pipelines.paths import refuse_aliases
from pipelines.progress import Progress
from pipelines.rig import Rig

HELP = "record a run (DAQ + camera) to a synchronized MCAP log"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--duration", metavar="S", type=float, required=True, help="seconds")
    p.add_argument("--out", metavar="RUN.mcap", required=True, help="log file to write")
    add_rig_argument(p)
    p.add_argument("--backend", choices=("fake", "hardware"), default="fake")
    p.add_argument("--realtime", action="store_true", help="pace the fake like the hardware")


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


def run(args: argparse.Namespace) -> int:
    from pipelines.acquire.capture import capture_run

    refuse_aliases({"--out": args.out}, {"--rig": args.rig})
    rig = rig_from_args(args)
    if not math.isfinite(args.duration) or args.duration <= 0:
        raise BeambenchError(
            f"--duration must be a positive number of seconds, got {args.duration}"
        )
    if args.backend == "fake":
        from pipelines.acquire.synthetic import make_synthetic_devices

        daq_device, camera, camera_info = make_synthetic_devices(
            rig, args.duration, realtime=args.realtime, seed=rig.synthetic.seed
        )
    else:
        daq_device, camera, camera_info = hardware_devices(rig)
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
