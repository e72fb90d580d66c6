"""beambench process: a run log to a results file (and Rerun)."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

from pipelines.commands._args import (
    add_damping_law_argument,
    add_max_tip_uncertainty_argument,
    add_rig_argument,
    add_viewer_arguments,
    max_tip_uncertainty_m,
)
from pipelines.errors import BeambenchError
from pipelines.paths import check_writable_output, refuse_aliases, write_failed
from sim.models.registry import MODELS


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("log", metavar="RUN.mcap")
    p.add_argument("--out", metavar="RESULTS.nc", required=True)
    add_rig_argument(p)
    p.add_argument(
        "--calibration",
        metavar="CAL.json",
        default=None,
        help="registration and camera calibration (default: detect the registration "
        "object in the first frames, with the intrinsics recorded in the log)",
    )
    p.add_argument(
        "--model",
        choices=MODELS,
        default="auto",
        help="simulation model driven by the measured hub angle",
    )
    p.add_argument(
        "--sim-tol",
        type=float,
        default=None,
        metavar="REL",
        help="relative tip error --model auto aims at (default: a fifth of the image "
        "measurement's RMS tip uncertainty on the run, 1e-3 without frames)",
    )
    add_damping_law_argument(p)
    add_max_tip_uncertainty_argument(p)
    p.add_argument(
        "--fit-damping",
        action="store_true",
        help="fit the damping law's coefficients (a1; a0 if the run determines it) to the "
        "measured strains and image tip, and simulate with them",
    )
    p.add_argument("--workers", type=int, default=None, help="processes measuring frames")
    add_viewer_arguments(p)
    p.add_argument(
        "--frame-previews",
        choices=("region", "whole"),
        default="whole",
        help="reduced frames in the recording: 'whole' (default) every frame as the camera "
        "took it; 'region' each frame whole once a second and every frame not measured, "
        "and between them only the measured beam and hub as that frame's pixels over the "
        "last whole frame (where its beam has left, a later frame's; about a third of the "
        "previews' CPU)",
    )


def check_output_folder(path: Path, option: str) -> None:
    if not path.parent.exists():
        raise BeambenchError(f"{option} {path}: folder {path.parent} does not exist")
    if path.is_dir():
        raise BeambenchError(f"{option} {path}: is a folder")
    check_writable_output(path, option)


def check_readable(path: Path) -> None:
    try:
        with open(path, "rb"):
            pass
    except FileNotFoundError:
        raise BeambenchError(f"{path}: no such file") from None
    except OSError as exc:
        raise BeambenchError(f"{path}: cannot be read ({exc.strerror or exc})") from None
    if not path.is_file():
        raise BeambenchError(f"{path}: not a file")


def run(args: argparse.Namespace) -> int:
    from pipelines.process.run import process_run, write_processed
    from pipelines.rig import load_rig

    log_path = Path(args.log)
    out = Path(args.out)
    check_readable(log_path)
    refuse_aliases(
        {"--out": out, "--rrd": args.rrd},
        {"the log": log_path, "--rig": args.rig, "--calibration": args.calibration},
    )
    check_output_folder(out, "--out")
    if args.rrd:
        check_output_folder(Path(args.rrd), "--rrd")
    if args.workers is not None and args.workers < 1:
        raise BeambenchError(f"--workers must be at least 1, got {args.workers}")
    if args.sim_tol is not None and not (0.0 < args.sim_tol < 0.5):
        raise BeambenchError(f"--sim-tol must be in (0, 0.5), got {args.sim_tol}")
    limit_m = max_tip_uncertainty_m(args)
    rig = load_rig(args.rig) if args.rig else None
    cal = Path(args.calibration) if args.calibration else None
    from pipelines.process.run import MAX_TIP_UNCERTAINTY_M
    from pipelines.review.overlays import FramePreviews

    wanted = bool(args.rrd or args.spawn or args.connect)
    # the recording's reduced frames are made in a thread while the frames are measured
    previews = (
        FramePreviews(log_path, args.frame_reduction, args.frame_previews) if wanted else None
    )
    if previews is not None and previews.reduction > 1:
        previews.start()
    try:
        processed = process_run(
            log_path,
            rig=rig,
            calibration_path=cal,
            model=args.model,
            sim_tol=args.sim_tol,
            workers=args.workers,
            damping_law=args.damping_law,
            max_tip_uncertainty_m=MAX_TIP_UNCERTAINTY_M if limit_m is None else limit_m,
            fit_damping=args.fit_damping,
            on_measured=previews.feed if previews is not None else None,
        )
        try:
            write_processed(processed, out)
        except OSError as exc:
            raise write_failed(out, exc) from None
        failures = processed.failures
        if failures.total and not failures.measured:
            raise BeambenchError(
                f"{log_path}: none of the {failures.total} frames was measured; "
                f"{failures.advice()}. The DAQ-only results (strains, potentiometer, "
                f"simulation) were written to {out}"
            )
        if wanted:
            try:
                stream_to_viewer(processed, log_path, args, previews)
            except (OSError, RuntimeError) as exc:  # rerun's file writer raises RuntimeError
                raise write_failed(args.rrd or "the Rerun viewer", exc) from None
    finally:
        if previews is not None:
            previews.stop()
    print_summary(processed, out)
    return 0


def stream_to_viewer(
    processed: object, log_path: Path, args: argparse.Namespace, previews: object = None
) -> None:
    import time

    from pipelines.process.run import Processed
    from pipelines.review.overlays import FramePreviews, stream_processed
    from pipelines.review.viewer import open_viewer

    assert isinstance(processed, Processed)
    assert previews is None or isinstance(previews, FramePreviews)
    t0 = time.perf_counter()
    try:
        viewer = open_viewer(
            "beambench", rrd_path=args.rrd, spawn=args.spawn, connect_url=args.connect
        )
    except ValueError as exc:
        if previews is not None:
            previews.stop()
        raise BeambenchError(str(exc)) from None
    try:
        stream_processed(
            processed,
            log_path,
            viewer,
            frame_reduction=args.frame_reduction,
            previews=previews,
            frame_previews=args.frame_previews,
        )
        viewer.close()
    except BaseException:
        viewer.abort()
        raise
    processed.timings.viewer_s = time.perf_counter() - t0


def print_summary(processed: object, out: Path) -> None:
    from pipelines.process.run import Processed

    assert isinstance(processed, Processed)
    ds = processed.results
    a = ds.attrs
    n_ok = int(ds["frame_ok"].values.sum())
    print(f"wrote {out}")
    print(f"  frames measured {n_ok}/{ds.sizes['frame_time']}")
    off = a.get("camera_to_daq_offset_s", math.nan)
    print(f"  camera-to-DAQ offset {off * 1e3:.2f} ms ({processed.alignment.reason or 'ok'})")
    from pipelines.process.hub import hub_line

    line = hub_line(dict(a), float(json.loads(a["rig_json"])["beam"]["hub_offset_m"]))
    if line is not None:
        print(f"  {line}")
    print(f"  simulation {a['sim_model']} (solve {processed.sim.wall_time_s:.2f} s)")
    if "sim_tip_error_estimate_m" in a:
        est_mm = float(a["sim_tip_error_estimate_m"]) * 1e3
        print(
            f"  simulation's estimated tip error {est_mm:.4f} mm (tolerance: {a['sim_tol_rule']})"
        )
    for key in (
        "tip_lateral_image_vs_sim_rms_m",
        "tip_lateral_strain_vs_image_rms_m",
        "tip_lateral_strain_vs_sim_rms_m",
    ):
        if key in a:
            print(f"  {key} = {float(a[key]) * 1e3:.3f} mm")
    if "free_decay_log_decrement" in a:
        print(
            f"  free decay from {float(a['free_decay_release_s']):.3f} s: "
            f"log decrement {float(a['free_decay_log_decrement']):.4f}, "
            f"a0 = a1 = {float(a['free_decay_a0_per_s_matched']):.3g}"
        )
    for line in fitted_damping_lines(a):
        print("  " + line)
    t = processed.timings.as_dict()
    print("  time: " + ", ".join(f"{k[:-2]} {v:.2f} s" for k, v in t.items()))


def fitted_damping_lines(a: dict[str, object]) -> list[str]:
    """What ``--fit-damping`` found, for people (empty without it)."""
    if "fitted_damping_failed" in a:
        return [f"damping not fitted ({a['fitted_damping_law']} law): {a['fitted_damping_failed']}"]
    if "fitted_damping_note" in a:
        return [f"damping not fitted: {a['fitted_damping_note']}"]
    if "fitted_a1_s" not in a:
        return []

    def v(key: str) -> float:
        return float(a[key])  # type: ignore[arg-type]

    if "fitted_a0_ci95_per_s" in a:
        a0 = f"a0 = {v('fitted_a0_per_s'):.4g} +- {v('fitted_a0_ci95_per_s'):.2g} 1/s"
    else:
        a0 = f"a0 = {v('fitted_a0_per_s'):.4g} 1/s, {a['fitted_a0_note']}"
    return [
        f"fitted damping ({a['fitted_damping_law']} law): a1 = {v('fitted_a1_s'):.5g} "
        f"+- {v('fitted_a1_ci95_s'):.2g} s (95 %), {a0}",
        f"  strains sim - measured {v('fitted_strain_rms_before') * 1e6:.2f} -> "
        f"{v('fitted_strain_rms_after') * 1e6:.2f} microstrain RMS, image tip "
        f"{v('fitted_tip_rms_before_m') * 1e3:.3f} -> {v('fitted_tip_rms_after_m') * 1e3:.3f} mm "
        f"RMS over {int(v('fitted_cycles'))} cycles from {v('fitted_from_s'):.1f} s "
        f"(fit {v('fitted_wall_time_s'):.1f} s)",
    ]
