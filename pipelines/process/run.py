"""Processing a run: log -> frames measured -> strains reconstructed -> time aligned ->
simulated from the measured hub angle -> compared -> results file (+ Rerun).

Every step is a function of arrays; ``process_run`` only wires them together.
"""

from __future__ import annotations

import io
import json
import logging
import math
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from daq.log import LogError, iter_frames, opens_as_log, read_run
from pipelines import __version__
from pipelines.errors import BeambenchError
from pipelines.process.alignment import Alignment, estimate_offset
from pipelines.process.damping_fit import check_run_supports_fit, fit_damping_attrs
from pipelines.process.failures import FailureSummary, summarise_failures
from pipelines.process.frames import (
    MeasuredFrame,
    StartedWorkers,
    as_arrays,
    measure_frames,
    start_workers,
)
from pipelines.process.free_decay import find_free_decay, simulate_release
from pipelines.process.hub import hub_attrs, measured_hub, offset_warning
from pipelines.process.model_error import (
    PRIOR_SIM_TOL,
    ToleranceChoice,
    after_resimulation,
    check_tolerance,
    drive_tip_uncertainty_m,
    fixed_choice,
)
from pipelines.process.steady_state import simulate_steady
from pipelines.process.strain_shape import StrainShape, modal_curvature_shape
from pipelines.progress import Progress
from pipelines.results.dataset import make_results
from pipelines.results.io import write_results
from pipelines.rig import Rig, rig_from_log_record
from sim.beam import BeamProperties
from sim.modes import mode_shapes
from sim.result import SimResult
from sim.trace_fit import FittedTraceDrive
from vision import Calibration, calibration_from_registration, decode, load_calibration
from vision.calibration import check_points_in_image
from vision.calibration_error import point_covariance
from vision.jit import cached as kernels_cached

log = logging.getLogger(__name__)

# The simulation starts from rest at the first sample; with the paper's damping the
# start-up transient is gone within a second (first mode overdamped, zeta ~ 1.2).
SETTLE_S = 1.0
STRAIN_SHAPE_MODES = 3
# The relative tip error ``process`` asked of ``auto`` before issue 15 (the linear modal
# model, 0.22 mm RMS from the exact beam on the demo run: more than the image's error).
# ``process`` now asks for a fifth of the image's uncertainty by default
# (:mod:`pipelines.process.model_error`); simulator-only sweeps still use this.
SIM_TOL = 2e-2
# A frame whose stated tip lateral uncertainty exceeds this is refused (issue #20: 0.5 mm,
# ten times the bench's nominal ~0.05 mm; --max-tip-uncertainty changes it).
MAX_TIP_UNCERTAINTY_M = 0.5e-3


@dataclass
class Timings:
    """Wall time of each step [s]."""

    read_s: float = 0.0
    calibrate_s: float = 0.0
    measure_s: float = 0.0
    align_s: float = 0.0
    strain_s: float = 0.0
    damping_s: float = 0.0
    simulate_s: float = 0.0
    damping_fit_s: float = 0.0
    model_wait_s: float = 0.0
    # the CPU time of the model side's thread (strains, free decay, simulation)
    model_cpu_s: float = 0.0
    # simulating again after the frames, when they asked for a tighter tolerance
    resimulate_s: float = 0.0
    write_s: float = 0.0
    viewer_s: float = 0.0

    def as_dict(self) -> dict[str, float]:
        return dict(self.__dict__)


@dataclass
class Processed:
    """Everything a processed run produced (the results dataset and the pieces the
    viewer draws)."""

    results: xr.Dataset
    frames: list[MeasuredFrame]
    calibration: Calibration
    alignment: Alignment
    sim: SimResult
    strain_shape: StrainShape
    timings: Timings = field(default_factory=Timings)
    # the log's event records, so the viewer need not read the log a second time
    events: list[Any] = field(default_factory=list)
    # the frames that were not measured, by reason
    failures: FailureSummary = field(default_factory=lambda: FailureSummary(0, 0, []))


def load_log(path: Path) -> Any:
    try:
        return read_run(path, require_samples=True)
    except LogError as exc:
        raise BeambenchError(str(exc)) from None
    except FileNotFoundError:
        raise BeambenchError(f"{path}: no such file") from None


def calibrate(run: Any, rig: Rig, calibration_path: Path | None) -> Calibration:
    """The calibration file if given, else the registration object detected in the
    first frame that shows it (with the intrinsics recorded in the log)."""
    if calibration_path is not None:
        try:
            cal = load_calibration(calibration_path)
            info = run.camera_info or {}
            if isinstance(info.get("width"), int) and isinstance(info.get("height"), int):
                # the log's frames are this size: the registration points must be in them
                check_points_in_image(cal, info["width"], info["height"])
            return cal
        except FileNotFoundError:
            raise BeambenchError(f"{calibration_path}: no such file") from None
        except ValueError as exc:
            raise BeambenchError(f"{calibration_path}: {exc}") from None
    camera_matrix = distortion = None
    info = run.camera_info
    if info:
        camera_matrix = np.asarray(info["K"], float).reshape(3, 3)
        distortion = np.asarray(info.get("D", ()), float)
    reasons = []
    for k, frame in enumerate(iter_frames(run.path)):
        if k >= 10:
            break
        try:
            return calibration_from_registration(
                decode(frame.data),
                rig.registration,
                camera_matrix=camera_matrix,
                distortion=distortion,
                beam_length_m=rig.beam.length_m,
                beam_width_m=rig.beam.width_m,
            )
        except ValueError as exc:
            reasons.append(str(exc))
    why = reasons[0] if reasons else "the log has no camera frames"
    raise BeambenchError(
        f"{run.path}: no calibration given and the registration object was not found "
        f"in the first frames ({why}); pass --calibration CAL.json"
    )


def calibration_attrs(calibration: Calibration, cols: dict[str, np.ndarray]) -> dict[str, Any]:
    """The calibration's own error, one error common to every frame (already in each
    frame's stated sd): its standard uncertainty at the pivot (the plane's origin, along
    the plane's X and Y, m), and what it gives the frames' hub angle, tip lateral and longitudinal,
    RMS over the measured frames (0 for a calibration that states no covariance)."""
    pivot = point_covariance(calibration, np.zeros((1, 2)))[0]
    out: dict[str, Any] = {
        "calibration_pivot_x_sd_m": float(math.sqrt(pivot[0, 0])),
        "calibration_pivot_y_sd_m": float(math.sqrt(pivot[1, 1])),
        "calibration_states_covariance": int(calibration.plane_from_ideal_cov is not None),
    }
    for key in ("hub_angle_sd_rad", "tip_lateral_sd_m", "tip_longitudinal_sd_m"):
        v = cols[f"calibration_{key}"][cols["ok"]]
        out[f"calibration_{key}"] = float(np.sqrt(np.mean(v**2))) if v.size else math.nan
    return out


def strain_shape_for(rig: Rig, stations_m: np.ndarray | None = None) -> StrainShape:
    beam = rig.beam
    return modal_curvature_shape(
        rig.gauges.positions_m,
        beam.length_m,
        beam.surface_offset_m,
        lambda x, i: mode_shapes(x, beam.length_m, i, derivative=2)[:, i - 1],
        n_modes=STRAIN_SHAPE_MODES,
        stations_m=stations_m,
    )


def simulate_measured(
    rig: Rig,
    t_s: np.ndarray,
    rocker_rad: np.ndarray,
    model: str,
    tol: float = PRIOR_SIM_TOL,
    damping_law: str | None = None,
) -> SimResult:
    """The beam driven by the measured hub angle (potentiometer trace, fitted by
    :class:`sim.trace_fit.FittedTraceDrive`); ``tol`` is the relative tip error ``auto``
    aims at; ``damping_law`` (default: the rig's) the a1 term. The result's
    ``settings["drive"]`` describes the fit. A drive fitted by harmonics alone repeats, and
    the beam is simulated to its periodic steady state only
    (:mod:`pipelines.process.steady_state`, ``settings["steady_state"]``)."""
    good = np.isfinite(rocker_rad)
    drive = FittedTraceDrive(t_s[good], rocker_rad[good])
    beam = BeamProperties.from_config(rig.beam)
    law = rig.damping.law if damping_law is None else damping_law
    from sim.models.registry import simulate

    def run(times: np.ndarray) -> SimResult:
        return simulate(
            model,
            beam,
            drive,
            times,
            a0_per_s=rig.damping.a0_per_s,
            a1_s=rig.damping.a1_s,
            damping_law=law,
            gauge_positions_m=rig.gauges.positions_m,
            n_modes=4,
            tol=tol if model == "auto" else None,  # modal and fe at their own tolerances
        )

    result = None
    if drive.settings["kind"] == "harmonics":
        period_s = 1.0 / float(drive.settings["fundamental_hz"])
        result = simulate_steady(run, t_s, period_s, SETTLE_S, tol)
    if result is None:
        result = run(t_s)
    drive_sd = drive_tip_uncertainty_m(
        beam, drive, t_s[good], rig.damping.a0_per_s, rig.damping.a1_s, law
    )
    settings = {**result.settings, "drive": {**drive.settings, "tip_uncertainty_m": drive_sd}}
    return replace(result, settings=settings)


def _model_side(
    rig: Rig,
    t_s: np.ndarray,
    rocker_angle_rad: np.ndarray,
    strain: np.ndarray,
    model: str,
    sim_tol: float,
    damping_law: str | None = None,
) -> tuple[StrainShape, np.ndarray, Any, SimResult, tuple[float, float, float, float]]:
    """What a run gives without its frames: the strain-based tip, the free decay (if the
    run holds one) and the simulation. Returns them with the wall time of each step and
    the CPU time of the whole."""
    c0 = time.thread_time()
    t0 = time.perf_counter()
    shape = strain_shape_for(rig)
    tip_strain = shape.tip_lateral_m(strain)
    t1 = time.perf_counter()
    decay = find_free_decay(rig, t_s, rocker_angle_rad, strain)
    t2 = time.perf_counter()
    if decay is not None:
        log.info(
            "free decay from %.2f s: log decrement %.4f, zeta %.4f, a0 = a1 = %.3g",
            decay.release_s,
            decay.log_decrement,
            decay.damping_ratio,
            decay.a_simulated,
        )
        sim = simulate_release(rig, t_s, strain, decay)
    else:
        sim = simulate_measured(rig, t_s, rocker_angle_rad, model, sim_tol, damping_law)
    t3 = time.perf_counter()
    return shape, tip_strain, decay, sim, (t1 - t0, t2 - t1, t3 - t2, time.thread_time() - c0)


def _import_ahead() -> None:
    """Import, while the frames are measured, what the serial steps after them import
    on a first run: xarray looks for optional array modules at the results' first
    Dataset (dask.array), and writing the results file imports h5netcdf and h5py, and
    dask's scheduler lookup imports distributed (~0.4 CPU s in all, each run of
    ``beambench process``). A tiny Dataset written to memory takes the same paths. A
    failure is left to the real steps to report."""
    try:
        xr.Dataset({"x": ("x", np.zeros(1))}).to_netcdf(io.BytesIO(), engine="h5netcdf")
    except Exception:  # the results' own write reports what fails
        log.debug("importing ahead failed", exc_info=True)


def _model_error_below_image(
    sim: SimResult,
    frames: list[MeasuredFrame],
    rig: Rig,
    t_s: np.ndarray,
    rocker_angle_rad: np.ndarray,
    model: str,
    sim_tol: float | None,
    decay: Any,
    damping_law: str | None,
) -> tuple[SimResult, ToleranceChoice]:
    """The simulation whose tip error ``auto`` estimates below a fifth of the frames' RMS
    uncertainty (simulated again if the a-priori run was not), with the record of the
    choice; as it is when the tolerance was given or is not ``auto``'s."""
    if decay is not None:
        return sim, fixed_choice(
            "free decay: modal, from the released shape", sim, frames, math.nan
        )
    if model != "auto":
        return sim, fixed_choice(f"--model {model}: its own tolerance", sim, frames, math.nan)
    if sim_tol is not None:
        return sim, fixed_choice("--sim-tol", sim, frames, sim_tol)
    choice, again = check_tolerance(sim, frames, PRIOR_SIM_TOL)
    if again is None:
        return sim, choice
    log.info(
        "the simulation's estimated tip error %.3g mm is above %s: simulating again at tol %.3g",
        choice.estimate_m * 1e3,
        choice.rule,
        again,
    )
    sim = simulate_measured(rig, t_s, rocker_angle_rad, model, again, damping_law)
    return sim, after_resimulation(choice, sim)


def process_run(
    log_path: Path,
    *,
    rig: Rig | None = None,
    calibration_path: Path | None = None,
    model: str = "auto",
    sim_tol: float | None = None,
    workers: int | None = None,
    damping_law: str | None = None,
    max_tip_uncertainty_m: float = MAX_TIP_UNCERTAINTY_M,
    fit_damping: bool = False,
    on_measured: Callable[[list[MeasuredFrame]], None] | None = None,
) -> Processed:
    """Process the run in ``log_path``; ``damping_law`` (``"paper"`` | ``"material"``,
    default: the rig's ``[damping] law``) is the simulation's a1 term; ``sim_tol`` the
    relative tip error ``auto`` aims at (``None``: a fifth of the image's uncertainty,
    :mod:`pipelines.process.model_error`); ``max_tip_uncertainty_m`` the stated tip
    uncertainty beyond which a frame is refused; ``fit_damping`` fits the law's
    coefficients to the run (:mod:`pipelines.process.damping_fit`) unless the run holds a
    free decay (whose identification then wins); ``on_measured`` is given the measured
    frames as they come, in order (:func:`pipelines.process.frames.measure_frames`).

    The frames that were not measured are counted by reason, one warning line each, and
    a warning names the main reason and the option that would help when fewer than half
    were measured (``Processed.failures``; none measured is the caller's error)."""
    # the frame workers start now: each imports numpy, OpenCV and vision (a second or
    # more) while this process reads the log, which then takes no wall time of its own
    # (a path that is no log, or a log cut short, is refused at once, with none started:
    # stopping workers half started waits for the fork server's imports, ~0.8 s)
    started = start_workers(workers) if opens_as_log(log_path) else None
    try:
        return _process_run(
            log_path, rig, calibration_path, model, sim_tol, workers, damping_law,
            max_tip_uncertainty_m, fit_damping, on_measured, started,
        )  # fmt: skip
    finally:
        if started is not None:
            started.close()  # taken by measure_frames, unless the run stopped before


def _process_run(
    log_path: Path,
    rig: Rig | None,
    calibration_path: Path | None,
    model: str,
    sim_tol: float | None,
    workers: int | None,
    damping_law: str | None,
    max_tip_uncertainty_m: float,
    fit_damping: bool,
    on_measured: Callable[[list[MeasuredFrame]], None] | None,
    started: StartedWorkers | None,
) -> Processed:
    prior_tol = PRIOR_SIM_TOL if sim_tol is None else sim_tol
    timings = Timings()
    t0 = time.perf_counter()
    run = load_log(log_path)
    # our JSON form, another recorder's flat entries, or no record: what is understood
    # is used, the rest comes from ``rig`` (--rig) or the shipped default, in one line
    rig, note = rig_from_log_record(run.rig_record, source=f"{log_path} (rig record)", given=rig)
    if note:
        log.warning("%s", note)
    samples = run.samples
    if samples.t_ns.size < 10:
        raise BeambenchError(f"{log_path}: the log holds only {samples.t_ns.size} DAQ samples")
    t_s = (samples.t_ns - samples.t_ns[0]).astype(float) * 1e-9
    t_zero_ns = int(samples.t_ns[0])
    timings.read_s = time.perf_counter() - t0
    if fit_damping:  # before the frames: a run that cannot support the fit stops here
        check_run_supports_fit(rig, str(log_path), t_s, samples.rocker_angle_rad, samples.strain)

    t0 = time.perf_counter()
    calibration = calibrate(run, rig, calibration_path)
    timings.calibrate_s = time.perf_counter() - t0

    # The model side (strain shape, free-decay search, simulation) needs only the DAQ
    # samples: it runs in a thread while the worker processes measure the frames, on the
    # core that would otherwise idle through the simulation afterwards (the solver's time
    # is then shared with the workers; its steps are timed inside the thread).
    with ThreadPoolExecutor(max_workers=1, thread_name_prefix="model") as side:
        model_side = side.submit(
            _model_side,
            rig,
            t_s,
            samples.rocker_angle_rad,
            samples.strain,
            model,
            prior_tol,
            damping_law,
        )
        side.submit(_import_ahead)  # then, in the same thread
        t0 = time.perf_counter()
        stations = tuple(float(x) for x in rig.gauges.positions_m)
        # a fresh kernel cache: the first frames wait ~25 s for numba's compile; say so
        cached = started.kernels_cached if started is not None else kernels_cached()
        label = "measure" if cached else "measure (compiling, first run: ~25 s)"
        with Progress(label, total=run.frame_count) as bar:
            frames = measure_frames(
                iter_frames(log_path),
                calibration,
                stations_m=stations,
                workers=workers,
                progress=bar.update,
                max_tip_uncertainty_m=max_tip_uncertainty_m,
                on_measured=on_measured,
                started=started,
            )
        cols = as_arrays(frames, calibration)
        failures = _report_failures(log_path, frames)
        hub = measured_hub([f.measurement for f in frames], calibration)
        if (note := offset_warning(hub, rig)) is not None:
            log.warning("%s: %s", log_path, note)
        timings.measure_s = time.perf_counter() - t0
        t0 = time.perf_counter()
        shape, tip_strain, decay, sim, side_timings = model_side.result()
        timings.model_wait_s = time.perf_counter() - t0
    timings.strain_s, timings.damping_s, timings.simulate_s, timings.model_cpu_s = side_timings
    t0 = time.perf_counter()
    sim, tol_choice = _model_error_below_image(
        sim, frames, rig, t_s, samples.rocker_angle_rad, model, sim_tol, decay, damping_law
    )
    timings.resimulate_s = time.perf_counter() - t0

    t0 = time.perf_counter()
    frame_t_cam_s = (cols["t_ns"] - t_zero_ns).astype(float) * 1e-9
    if decay is None:
        alignment = estimate_offset(
            frame_t_cam_s, cols["hub_angle_rad"], t_s, samples.rocker_angle_rad
        )
    else:
        # the hub is still: the vibrating tip, seen by the camera and by the strains
        alignment = estimate_offset(frame_t_cam_s, cols["tip_lateral_m"], t_s, tip_strain)
    if alignment.ok:
        frame_t_s = alignment.to_daq_time(frame_t_cam_s)
    else:
        log.warning("camera-to-DAQ alignment failed (%s); using the logged times", alignment.reason)
        frame_t_s = frame_t_cam_s
    timings.align_s = time.perf_counter() - t0

    fit_attrs: dict[str, Any] = {}
    if fit_damping:
        t0 = time.perf_counter()
        law = rig.damping.law if damping_law is None else damping_law
        # the fitted damping simulated at the tolerance chosen for the unfitted run
        refit_tol = tol_choice.tol if math.isfinite(tol_choice.tol) else prior_tol
        fit_attrs, refit = fit_damping_attrs(
            rig, law, t_s, samples, frame_t_s, cols, decay, str(log_path),
            lambda r: simulate_measured(r, t_s, samples.rocker_angle_rad, model, refit_tol, law),
        )  # fmt: skip
        sim = refit or sim
        timings.damping_fit_s = time.perf_counter() - t0

    attrs = {
        "source_log": str(log_path),
        "rig_json": rig.to_json(),
        "software_version": __version__,
        "sim_model": sim.model,
        "sim_settings": json.dumps(sim.settings, default=str),
        "sim_wall_time_s": sim.wall_time_s,
        "sim_damping_law": rig.damping.law if damping_law is None else damping_law,
        "camera_to_daq_offset_s": alignment.offset_s if alignment.ok else math.nan,
        "camera_clock_drift_ppm": alignment.drift_ppm if alignment.ok else math.nan,
        "alignment": json.dumps(alignment.__dict__),
        "calibration": calibration.to_json(),
        **calibration_attrs(calibration, cols),
        "settle_time_s": SETTLE_S,
        "strain_shape_basis": shape.basis,
        "frames_failed": int(np.count_nonzero(~cols["ok"])),
        "frames_total": len(frames),
        "run_info": json.dumps(run.run_info, default=str),
        "t_zero_ns": t_zero_ns,
        **hub_attrs(hub, rig),
        **(decay.as_attrs() if decay is not None else {}),
        **fit_attrs,
        **tol_choice.as_attrs(),
        "sim_drive": json.dumps(sim.settings.get("drive", {}), default=str),
    }
    results = make_results(
        time_s=t_s,
        rocker_angle_rad=samples.rocker_angle_rad,
        strain=samples.strain,
        gauge_m=np.asarray(rig.gauges.positions_m, float),
        frame_time_s=frame_t_s,
        hub_angle_image_rad=cols["hub_angle_rad"],
        tip_lateral_m=cols["tip_lateral_m"],
        tip_longitudinal_m=cols["tip_longitudinal_m"],
        frame_ok=cols["ok"],
        tip_lateral_strain_m=tip_strain,
        sim_tip_lateral_m=sim.tip_lateral_m,
        sim_strain=sim.strain,
        attrs=attrs,
        sim_tip_longitudinal_m=sim.tip_longitudinal_m,
        hub_angle_sim_rad=sim.hub_angle_rad,
        station_m=np.asarray(stations, float),
        lateral_at_stations_image_m=cols["lateral_at_stations_m"],
        hub_angle_image_sd_rad=cols["hub_angle_sd_rad"],
        tip_lateral_sd_m=cols["tip_lateral_sd_m"],
        tip_longitudinal_sd_m=cols["tip_longitudinal_sd_m"],
    )
    results.attrs["frames_failed_by_reason"] = json.dumps({k: n for k, n, _ in failures.kinds})
    return Processed(
        results,
        frames,
        calibration,
        alignment,
        sim,
        shape,
        timings,
        list(run.events),
        failures,
    )


def _report_failures(log_path: Path, frames: list[MeasuredFrame]) -> FailureSummary:
    failures = summarise_failures(
        [f.measurement.ok for f in frames], [f.measurement.reason for f in frames]
    )
    for line in failures.lines():
        log.warning("%s: %s", log_path, line)
    if failures.measured and failures.few_measured():
        log.warning(
            "%s: only %d of %d frames measured; %s",
            log_path,
            failures.measured,
            failures.total,
            failures.advice(),
        )
    return failures


def write_processed(processed: Processed, out_path: Path) -> None:
    t0 = time.perf_counter()
    write_results(processed.results, out_path)
    processed.timings.write_s = time.perf_counter() - t0
