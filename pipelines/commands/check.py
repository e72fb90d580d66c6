"""beambench check: preflight before a run (the devices recorded for a few seconds, judged)."""

from __future__ import annotations

import argparse
from pathlib import Path

from pipelines.commands._args import add_rig_argument, rig_from_args
from pipelines.errors import BeambenchError

EXIT_FAILED_CHECK = 1


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_rig_argument(p)
    p.add_argument("--backend", choices=("fake", "hardware"), default="fake")
    p.add_argument(
        "--duration",
        type=float,
        default=3.0,
        metavar="S",
        help="seconds recorded for the checks (default 3: more than two crank cycles)",
    )
    p.epilog = (
        "Exit status 0 when nothing failed (warnings allowed), 1 when a check failed, 2 on "
        "bad input."
    )


def run(args: argparse.Namespace) -> int:
    from pipelines.acquire.capture import capture_run
    from pipelines.acquire.preflight import run_preflight

    if not 1.0 <= args.duration <= 60.0:
        raise BeambenchError(f"--duration must be between 1 and 60 s, got {args.duration:g}")
    rig = rig_from_args(args)

    def record(path: Path, duration_s: float) -> None:
        if args.backend == "hardware":
            from pipelines.commands.capture import hardware_devices

            daq_device, camera, info = hardware_devices(rig)
            realtime = True
        else:
            from pipelines.acquire.synthetic import build_synthetic

            devices = build_synthetic(rig, duration_s)
            daq_device, camera, info = devices.daq, devices.camera, devices.camera_info
            realtime = False
        capture_run(rig, daq_device, camera, path, duration_s, realtime=realtime, camera_info=info)

    result = run_preflight(rig, record, args.duration)
    where = args.rig or "the shipped rig"
    print(f"preflight of {where} ({args.backend} devices, {args.duration:g} s recorded):")
    for line in result.table():
        print(line)
    if result.failed:
        print("not ready: fix what failed before recording")
        return EXIT_FAILED_CHECK
    print("ready to record")
    return 0
