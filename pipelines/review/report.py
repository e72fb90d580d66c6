"""A short report of a processed run: markdown with the error summary, and PNG plots.

Plots (matplotlib; figures are built with ``matplotlib.figure.Figure`` and rendered by
the Agg canvas, so there is no pyplot, no display and no global state):

- ``strains.png``: measured and simulated strain at each gauge against time;
- ``tip_deflection.png``: lateral tip deflection from images (points), from the
  strains and from the simulation against time;
- ``fig10_tip_path.png``: the paper's Fig. 10 view, the tip's path in the plane of
  motion for the flexible beam and for the rigid beam on the same hub angle;
- ``fig11_tip_vs_hub.png``: the paper's Fig. 11 view, lateral tip deflection against
  hub angle, measured points (every measured frame after the simulation's start-up,
  ``results.fig11_frames_mask``) over the simulated loop of the last three crank cycles.

Both figures put measured and simulated values on the potentiometer's angle (the
measured points at the frame times), so a constant offset between the image's frame and
the potentiometer zero does not shift them.
"""

from __future__ import annotations

import logging
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr
from matplotlib.figure import Figure
from numpy.typing import ArrayLike, NDArray

from pipelines.atomic import atomic_path
from pipelines.results.compare import rig_json_of, steady_state_mask, summarise_errors
from pipelines.results.schema import VARIABLES
from pipelines.review.display import error_table, fig11_frames_mask, format_value

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]

REPORT_NAME = "report.md"
PLOTS = {
    "strains": "strains.png",
    "tip_deflection": "tip_deflection.png",
    "fig10": "fig10_tip_path.png",
    "fig11": "fig11_tip_vs_hub.png",
}


def tip_positions_m(
    beam_angle_rad: ArrayLike,
    lateral_m: ArrayLike,
    longitudinal_m: ArrayLike,
    pivot_to_tip_m: float,
) -> tuple[FloatArray, FloatArray]:
    """Tip positions in the plane of motion, pivot at the origin.

    The rigid beam points along ``beam_angle_rad``; ``lateral`` is perpendicular to it
    toward increasing angle, ``longitudinal`` along it (negative = pulled in).

    Parameters
    ----------
    beam_angle_rad : (N,) direction of the rigid beam from the pivot [rad].
    lateral_m, longitudinal_m : (N,) tip deflection relative to the rigid beam [m].
    pivot_to_tip_m : pivot to free end [m] (hub offset + beam length).

    Returns
    -------
    flexible_xy_m, rigid_xy_m : (N, 2) positions (x, y) [m].
    """
    a = np.asarray(beam_angle_rad, dtype=np.float64)
    lat = np.asarray(lateral_m, dtype=np.float64)
    lon = np.asarray(longitudinal_m, dtype=np.float64)
    if a.ndim != 1 or lat.shape != a.shape or lon.shape != a.shape:
        raise ValueError(
            "beam_angle_rad, lateral_m and longitudinal_m must be 1-D of one length, got "
            f"{a.shape}, {lat.shape}, {lon.shape}"
        )
    if not (math.isfinite(pivot_to_tip_m) and pivot_to_tip_m > 0):
        raise ValueError(f"pivot_to_tip_m must be a positive number, got {pivot_to_tip_m!r}")
    along = np.column_stack([np.cos(a), np.sin(a)])
    across = np.column_stack([-np.sin(a), np.cos(a)])
    rigid = pivot_to_tip_m * along
    flexible = rigid + lon[:, None] * along + lat[:, None] * across
    return flexible, rigid


def _save(fig: Figure, path: Path) -> None:
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110)


def _write_text(path: Path, text: str) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def _plot_strains(ds: xr.Dataset, path: Path) -> None:
    t = ds["time"].values
    gauges = ds["gauge"].values
    n = gauges.size
    fig = Figure(figsize=(9, 2.0 * n + 0.6), layout="constrained")
    axes = fig.subplots(n, 1, sharex=True, squeeze=False)[:, 0]
    for j, ax in enumerate(axes):
        ax.plot(t, 1e6 * ds["strain"].values[:, j], lw=0.8, label="measured")
        ax.plot(t, 1e6 * ds["sim_strain"].values[:, j], lw=0.8, label="simulated")
        ax.set_ylabel("strain (µε)")
        ax.set_title(f"gauge {j + 1} at {1e3 * gauges[j]:.0f} mm from the clamp", fontsize=9)
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("time (s)")
    _save(fig, path)


def _plot_tip(ds: xr.Dataset, path: Path) -> None:
    t = ds["time"].values
    ok = ds["frame_ok"].values.astype(bool)
    fig = Figure(figsize=(9, 3.5), layout="constrained")
    ax = fig.subplots()
    ax.plot(t, 1e3 * ds["sim_tip_lateral"].values, lw=1.0, label="simulated")
    ax.plot(t, 1e3 * ds["tip_lateral_strain"].values, lw=0.8, label="from strains")
    ax.plot(
        ds["frame_time"].values[ok],
        1e3 * ds["tip_lateral"].values[ok],
        "o",
        ms=3,
        label="from images",
    )
    ax.set_xlabel("time (s)")
    ax.set_ylabel("lateral tip deflection (mm)")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper right", fontsize=8)
    _save(fig, path)


def _rig_geometry(ds: xr.Dataset) -> tuple[float, float]:
    """(pivot to tip in m, beam mount angle in rad) from the rig recorded in ``ds``."""
    rig: dict[str, Any] = rig_json_of(ds)
    try:
        beam = rig["beam"]
        pivot_to_tip = float(beam["hub_offset_m"]) + float(beam["length_m"])
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"rig_json lacks the beam length and hub offset ({exc})") from None
    mount = float(rig.get("linkage", {}).get("beam_mount_angle_rad", 0.0))
    return pivot_to_tip, mount


def _frame_hub_angle(ds: xr.Dataset) -> FloatArray:
    """Potentiometer angle at the frame times (NaN outside the DAQ span)."""
    out = np.interp(
        ds["frame_time"].values,
        ds["time"].values,
        ds["rocker_angle"].values,
        left=np.nan,
        right=np.nan,
    )
    return np.asarray(out, dtype=np.float64)


def _plot_fig10(ds: xr.Dataset, path: Path) -> None:
    pivot_to_tip, mount = _rig_geometry(ds)
    steady = steady_state_mask(ds)
    hub = ds["hub_angle_sim"].values if "hub_angle_sim" in ds else ds["rocker_angle"].values
    sim_lon = (
        ds["sim_tip_longitudinal"].values[steady]
        if "sim_tip_longitudinal" in ds
        else np.zeros(int(steady.sum()))
    )
    flex, rigid = tip_positions_m(
        hub[steady] + mount, ds["sim_tip_lateral"].values[steady], sim_lon, pivot_to_tip
    )
    frames = fig11_frames_mask(ds)
    meas, _ = tip_positions_m(
        _frame_hub_angle(ds)[frames] + mount,
        ds["tip_lateral"].values[frames],
        ds["tip_longitudinal"].values[frames],
        pivot_to_tip,
    )
    fig = Figure(figsize=(11, 4.8), layout="constrained")
    full, zoom = fig.subplots(1, 2, width_ratios=[3, 2])
    # The right panel zooms on the end of the stroke at the largest hub angle, where the
    # flexible tip overshoots the rigid one (the paper's point about Fig. 10).
    end = rigid[int(np.argmax(hub[steady]))] if rigid.size else np.zeros(2)
    half_m = 0.06
    for ax in (full, zoom):
        ax.plot(rigid[:, 0], rigid[:, 1], color="0.7", lw=3, label="rigid beam")
        ax.plot(flex[:, 0], flex[:, 1], color="k", lw=1.0, label="flexible beam (simulated)")
        ax.plot(meas[:, 0], meas[:, 1], "o", ms=3, label="flexible beam (images)")
        ax.set_xlabel("x (m, pivot at origin)")
        ax.grid(alpha=0.3)
    full.set_aspect("equal", adjustable="datalim")
    zoom.set_aspect("equal", adjustable="box")
    zoom.set_xlim(end[0] - half_m, end[0] + half_m)
    zoom.set_ylim(end[1] - half_m, end[1] + half_m)
    zoom.set_title("end of stroke, zoomed", fontsize=10)
    full.set_ylabel("y (m)")
    full.set_title("Fig. 10 view: simulated tip path of the last three cycles", fontsize=10)
    full.legend(fontsize=8)
    _save(fig, path)


def _plot_fig11(ds: xr.Dataset, path: Path) -> None:
    steady = steady_state_mask(ds)
    hub = ds["hub_angle_sim"].values if "hub_angle_sim" in ds else ds["rocker_angle"].values
    frames = fig11_frames_mask(ds)
    fig = Figure(figsize=(7, 4.5), layout="constrained")
    ax = fig.subplots()
    ax.plot(
        np.degrees(hub[steady]),
        1e3 * ds["sim_tip_lateral"].values[steady],
        "k-",
        lw=1.0,
        label="simulated",
    )
    ax.plot(
        np.degrees(_frame_hub_angle(ds)[frames]),
        1e3 * ds["tip_lateral"].values[frames],
        "o",
        ms=4,
        label="measured (images)",
    )
    ax.set_xlabel("hub (rocker) angle (deg)")
    ax.set_ylabel("lateral tip deflection (mm)")
    ax.set_title("Fig. 11 view: simulated loop of the last three cycles", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    _save(fig, path)


def _free_decay_lines(a: Mapping[str, object]) -> list[str]:
    """The damping section when the run held a free decay (attributes free_decay_*)."""
    if "free_decay_log_decrement" not in a:
        return []

    def v(key: str) -> float:
        return float(a[key])  # type: ignore[arg-type]

    return [
        "## Damping from the free decay (§5.2.1)",
        "",
        f"The hub was still from {v('free_decay_start_s'):.2f} s; the tip was released at "
        f"{v('free_decay_release_s'):.3f} s. Gauge 2 rang at {v('free_decay_frequency_hz'):.3f} Hz "
        f"with log decrement {v('free_decay_log_decrement'):.4f} "
        f"(damping ratio {v('free_decay_damping_ratio'):.4f}).",
        "",
        "| equal coefficients a0 = a1 | value |",
        "|---|---:|",
        f"| first mode, Eq. 37 closed form | {v('free_decay_a0_per_s_eq37'):.3g} |",
        f"| simulated decay matched (the paper's way) | {v('free_decay_a0_per_s_matched'):.3g} |",
        "",
        "The simulation of this run starts from the measured shape at the release with the "
        "matched coefficients.",
        "",
    ]


def _fitted_damping_lines(a: Mapping[str, object]) -> list[str]:
    """The damping section when the run was processed with --fit-damping."""
    if "fitted_damping_failed" in a:
        return [
            "## Damping fitted to the run",
            "",
            f"Not fitted ({a.get('fitted_damping_law', '?')} law): {a['fitted_damping_failed']}. "
            "The simulation keeps the rig's damping.",
            "",
        ]
    if "fitted_damping_note" in a:
        return ["## Damping fitted to the run", "", f"Not fitted: {a['fitted_damping_note']}.", ""]
    if "fitted_a1_s" not in a:
        return []

    def v(key: str) -> float:
        return float(a[key])  # type: ignore[arg-type]

    a0 = (
        f"| a0 | {v('fitted_a0_per_s'):.4g} 1/s | +-{v('fitted_a0_ci95_per_s'):.2g} 1/s |"
        if "fitted_a0_ci95_per_s" in a
        else f"| a0 | {v('fitted_a0_per_s'):.4g} 1/s | {a.get('fitted_a0_note', 'held')} |"
    )
    return [
        "## Damping fitted to the run",
        "",
        f"The {a['fitted_damping_law']} law's coefficients, fitted to the crank harmonics of "
        f"the four strains and the image tip ({a.get('fitted_harmonics', '')}) over "
        f"{int(v('fitted_cycles'))} cycles from {v('fitted_from_s'):.1f} s; the simulation in "
        "this report uses them.",
        "",
        "| coefficient | fitted | 95 % interval (half-width) |",
        "|---|---:|---|",
        f"| a1 | {v('fitted_a1_s'):.5g} s | +-{v('fitted_a1_ci95_s'):.2g} s |",
        a0,
        "",
        "| residual, simulated - measured | before | after |",
        "|---|---:|---:|",
        f"| harmonics (RMS, standard errors) | {v('fitted_residual_before_se'):.1f} | "
        f"{v('fitted_residual_after_se'):.2f} |",
        f"| strains (RMS, microstrain) | {v('fitted_strain_rms_before') * 1e6:.2f} | "
        f"{v('fitted_strain_rms_after') * 1e6:.2f} |",
        f"| image tip (RMS, mm) | {v('fitted_tip_rms_before_m') * 1e3:.3f} | "
        f"{v('fitted_tip_rms_after_m') * 1e3:.3f} |",
        "",
        f"The interval is the cycles' scatter projected through the fit (widened by the Birge "
        f"ratio {v('fitted_birge_ratio'):.2f}); it does not hold errors shared by every cycle "
        "(gauge factors, the beam's stiffness). The loop's model "
        f"({a.get('fitted_loop_model', '?')}) gave a1 = {v('fitted_a1_loop_s'):.5g} s before "
        f"the exact beam ({a.get('fitted_exact_model', '?')}) took its bias out.",
        "",
    ]


def _model_error_lines(a: Mapping[str, object], errors: Mapping[str, Any]) -> list[str]:
    """The image - simulation comparison beside the simulation's own estimated error and the
    image's stated uncertainty (attributes sim_tip_error_estimate_m, ..., written by
    ``process`` since issue 15; nothing for an older results file)."""
    if "sim_tip_error_estimate_m" not in a:
        return []

    def v(key: str) -> float:
        try:
            return float(a.get(key, math.nan))  # type: ignore[arg-type]
        except (TypeError, ValueError):
            return math.nan

    rms = float(errors["tip_lateral_image_vs_sim_rms_m"])
    est = v("sim_tip_error_estimate_m")
    sd = v("image_tip_lateral_sd_rms_m")
    # the simulation's error taken out in quadrature (its estimate is a bound on the max)
    without = math.sqrt(max(rms**2 - est**2, 0.0)) if math.isfinite(est) else math.nan
    drive = v("sim_drive_tip_uncertainty_m")
    cal = v("calibration_tip_lateral_sd_m")
    parts = [x for x in (sd, est, drive, cal) if math.isfinite(x)]
    expected = math.sqrt(sum(x * x for x in parts)) if parts else math.nan
    return [
        "## Image against simulation, and the simulation's own error",
        "",
        f"Simulation tolerance: {a.get('sim_tol_rule', '?')} (asked of the model: relative "
        f"{format_value(v('sim_tol'))}, i.e. {format_value(v('sim_tip_tol_m'), 1e3)} mm"
        f"{'; simulated again after the frames' if v('sim_resimulated') == 1 else ''}).",
        "",
        "| tip lateral | mm |",
        "|---|---:|",
        f"| image - sim, RMS | {format_value(rms, 1e3)} |",
        f"| simulation's estimated error (its model, max over the run) | "
        f"{format_value(est, 1e3)} |",
        f"| image - sim, RMS, the simulation's error taken out | {format_value(without, 1e3)} |",
        f"| simulation's uncertainty from the measured hub angle (fitted drive), RMS | "
        f"{format_value(drive, 1e3)} |",
        f"| image's stated uncertainty, RMS over the frames | {format_value(sd, 1e3)} |",
        f"| the calibration's stated uncertainty at the tip, RMS over the frames | "
        f"{format_value(cal, 1e3)} |",
        f"| expected image - sim RMS from these four alone | {format_value(expected, 1e3)} |",
        "",
        "The image's stated uncertainty here is its edge fits' noise; the calibration's, "
        "one error common to every frame, is stated apart (the frames' `tip_lateral_sd` "
        "holds both in quadrature; being one draw for the whole run, it does not average "
        "out over the frames). The model's estimate is its numerical error; the "
        "drive's is the potentiometer's noise left in the fitted hub angle (`sim_drive`), "
        "carried through the linear beam.",
        "",
    ]


def write_report(
    ds: xr.Dataset,
    out_dir: str | os.PathLike[str],
    *,
    title: str,
    notes: Sequence[str] = (),
) -> Path:
    """Write ``report.md`` and its PNG plots into ``out_dir`` (created if missing).

    Every file is written under a temporary name and renamed when complete.

    Parameters
    ----------
    ds : a results Dataset (``pipelines.results.schema``), with ``rig_json`` in its attributes.
    out_dir : output folder.
    title : first heading of the report.
    notes : extra lines, listed under "Notes".

    Returns
    -------
    Path
        The markdown file.
    """
    missing = [name for name in VARIABLES if name not in ds]
    if missing:
        raise ValueError(f"ds is not a results Dataset: missing {', '.join(missing)}")
    if isinstance(notes, str):
        raise TypeError("notes must be a sequence of lines, not one str")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    errors = summarise_errors(ds)
    _plot_strains(ds, out / PLOTS["strains"])
    _plot_tip(ds, out / PLOTS["tip_deflection"])
    _plot_fig10(ds, out / PLOTS["fig10"])
    _plot_fig11(ds, out / PLOTS["fig11"])
    a = ds.attrs
    offset = float(a.get("camera_to_daq_offset_s", math.nan))
    t = ds["time"].values
    lines = [
        f"# {title}",
        "",
        f"- source log: `{a.get('source_log', '?')}`",
        f"- software version: {a.get('software_version', '?')}",
        f"- simulation model: {a.get('sim_model', '?')}",
        f"- duration: {t[-1] - t[0]:.2f} s, {t.size} DAQ samples",
        f"- frames: {int(ds.sizes['frame_time'])} "
        f"({int(np.count_nonzero(~ds['frame_ok'].values.astype(bool)))} gave no measurement)",
        f"- camera-to-DAQ time offset: {format_value(offset, 1e3)} ms, camera clock "
        f"{format_value(float(a.get('camera_clock_drift_ppm', math.nan)), 1.0)} ppm",
        "",
        *_free_decay_lines(a),
        *_fitted_damping_lines(a),
        "## Error summary",
        "",
        "Differences are first-named minus second-named; series on the DAQ clock are",
        "interpolated at the frame times for comparisons with images. Comparisons with the",
        f"simulation start at {errors['sim_compared_from_s']:.2f} s, after its start-up transient.",
        "",
        *error_table(errors),
        "",
        *_model_error_lines(a, errors),
        "## Plots",
        "",
        f"![strains measured and simulated]({PLOTS['strains']})",
        "",
        f"![lateral tip deflection against time]({PLOTS['tip_deflection']})",
        "",
        f"![Fig. 10 view: tip path, flexible and rigid]({PLOTS['fig10']})",
        "",
        f"![Fig. 11 view: tip deflection against hub angle]({PLOTS['fig11']})",
        "",
    ]
    if notes:
        lines += ["## Notes", "", *[f"- {n}" for n in notes], ""]
    path = out / REPORT_NAME
    _write_text(path, "\n".join(lines))
    log.info("wrote report %s", path)
    return path
