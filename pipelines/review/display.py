"""What a review shows, computed from a results Dataset before anything is logged: the
series and Fig. 11 (:func:`run_view`), the error table in display units (mm, microstrain)
and the frames drawn as measured points in Fig. 11.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import xarray as xr
from numpy.typing import ArrayLike, NDArray

from pipelines.results.compare import (
    ERROR_METRICS,
    STRAIN_METRICS,
    sim_start_s,
    steady_state_mask,
    summarise_errors,
)
from pipelines.results.schema import VARIABLES

# Display units of the error table: metres shown as mm, strain as microstrain.
DISPLAY_UNITS = {"m": ("mm", 1e3), "1": ("µε", 1e6)}

FloatArray = NDArray[np.float64]

#: the camera overlay shows the measured - simulated beam this many times enlarged
DIFFERENCE_GAIN = 20.0

# What the camera overlays mean, for the summary document (Rerun's 2D views have no legend).
OVERLAY_KEY = (
    "| overlay | colour |\n|---|---|\n"
    "| measured centre line | cyan |\n"
    "| simulated beam (line and station dots) | green |\n"
    "| measured - simulated, x{gain:g} about the simulated beam | pink |\n"
    "| rigid beam on the measured hub angle | purple |\n"
    "| hub axis | red |\n"
    "| measured tip | yellow |"
)


def format_value(value: float, scale: float = 1.0) -> str:
    """``value * scale`` to 4 significant digits, or ``n/a`` when not finite."""
    return "n/a" if not math.isfinite(value) else f"{value * scale:.4g}"


def error_table(errors: Mapping[str, Any]) -> list[str]:
    """The error summary (:func:`summarise_errors`) as markdown table lines, in mm and
    microstrain."""
    lines = ["| comparison | value | unit |", "|---|---:|---|"]
    for m in ERROR_METRICS:
        unit, scale = DISPLAY_UNITS[m.units]
        lines.append(f"| {m.label} | {format_value(float(errors[m.key]), scale)} | {unit} |")
    for m in STRAIN_METRICS:
        unit, scale = DISPLAY_UNITS[m.units]
        for j, v in enumerate(errors[m.key]):
            label = m.label.replace("strain,", f"strain g{j + 1},", 1)
            lines.append(f"| {label} | {format_value(float(v), scale)} | {unit} |")
    lines.append(f"| frames compared | {int(errors['n_frames_compared'])} | |")
    return lines


def compact_error_table(errors: Mapping[str, Any]) -> list[str]:
    """The error summary as markdown table lines, RMS and max side by side (half the rows
    of :func:`error_table`, so it is read without scrolling), in mm and microstrain."""
    lines = ["| comparison | RMS | max | unit |", "|---|---:|---:|---|"]
    for stem, label in (
        ("tip_lateral_image_vs_sim", "tip lateral, image - sim"),
        ("tip_lateral_strain_vs_image", "tip lateral, strain - image"),
        ("tip_lateral_strain_vs_sim", "tip lateral, strain - sim"),
    ):
        rms, mx = (format_value(float(errors[f"{stem}_{k}_m"]), 1e3) for k in ("rms", "max"))
        lines.append(f"| {label} | {rms} | {mx} | mm |")
    for j, (rms_v, max_v) in enumerate(
        zip(errors["strain_vs_sim_rms"], errors["strain_vs_sim_max"], strict=True)
    ):
        rms, mx = format_value(float(rms_v), 1e6), format_value(float(max_v), 1e6)
        lines.append(f"| strain g{j + 1}, measured - sim | {rms} | {mx} | µε |")
    lines.append(f"| frames compared | {int(errors['n_frames_compared'])} | | |")
    return lines


def fig11_frames_mask(ds: xr.Dataset) -> NDArray[np.bool_]:
    """(F,) bool: the frames drawn as measured points over the simulated loop.

    Every frame that gave a measurement inside the DAQ span, after the simulation's
    start-up transient (global attribute ``settle_time_s``, s, when present). Points of
    any steady cycle lie on the steady loop, so they are not limited to the last cycles.
    """
    ft = np.asarray(ds["frame_time"].values, dtype=np.float64)
    t = np.asarray(ds["time"].values, dtype=np.float64)
    settle = float(ds.attrs.get("settle_time_s", 0.0))
    if not math.isfinite(settle):
        settle = 0.0
    ok = np.asarray(ds["frame_ok"].values, dtype=bool)
    return np.asarray(ok & (ft >= t[0] + settle) & (ft <= t[-1]))


@dataclass(frozen=True)
class RunView:
    """The series of a results Dataset as a review shows them (SI units, NaN = no value).

    ``fig11`` holds (measured hub angle [rad], measured tip lateral [m], simulated hub
    angle [rad], simulated tip lateral [m]): Fig. 11's points and loop. The residuals are
    measured minus simulated, NaN before the simulation has settled (what the error summary
    compares); ``hub_at_frames_rad`` is the potentiometer angle at each frame time, the
    abscissa of Fig. 11 and of its marker.
    """

    t_s: FloatArray
    rocker_angle_rad: FloatArray
    strain: FloatArray
    sim_tip_lateral_m: FloatArray
    sim_strain: FloatArray
    frame_t_s: FloatArray
    tip_lateral_image_m: FloatArray
    tip_lateral_strain_m: FloatArray
    fig11: tuple[FloatArray, FloatArray, FloatArray, FloatArray]
    summary_markdown: str
    strain_residual: FloatArray
    tip_image_minus_sim_m: FloatArray
    tip_strain_minus_sim_m: FloatArray
    hub_at_frames_rad: FloatArray


def run_view(ds: xr.Dataset) -> RunView:
    """What a review of ``ds`` shows: its series, Fig. 11 and the error summary.

    Raises
    ------
    ValueError
        ``ds`` is not a results Dataset (a variable of the schema is missing).
    """
    missing = [name for name in VARIABLES if name not in ds]
    if missing:
        raise ValueError(f"ds is not a results Dataset: missing {', '.join(missing)}")
    t = np.asarray(ds["time"].values, dtype=np.float64)
    ft = np.asarray(ds["frame_time"].values, dtype=np.float64)
    rocker = np.asarray(ds["rocker_angle"].values, dtype=np.float64)
    ok = np.asarray(ds["frame_ok"].values, dtype=bool)
    image = np.where(ok, ds["tip_lateral"].values, np.nan)
    sim_tip = np.asarray(ds["sim_tip_lateral"].values, dtype=np.float64)
    # Fig. 11 on the potentiometer's angle for both, so a constant offset between
    # the image frame and the potentiometer zero does not shift the points.
    hub_at_frames = np.interp(ft, t, rocker, left=np.nan, right=np.nan) if ft.size else ft
    steady = steady_state_mask(ds)
    points = fig11_frames_mask(ds)
    sim_hub = ds["hub_angle_sim"].values if "hub_angle_sim" in ds else rocker
    model = ds.attrs.get("sim_model", "?")
    lines = [
        f"### Simulation ({model}) against measurement",
        "",
        *compact_error_table(summarise_errors(ds)),
        "",
        "### Camera overlays",
        "",
        OVERLAY_KEY.format(gain=DIFFERENCE_GAIN),
    ]
    settled = t >= sim_start_s(ds)
    settled_frames = ft >= sim_start_s(ds)
    sim_at_frames = np.interp(ft, t, sim_tip, left=np.nan, right=np.nan) if ft.size else ft
    strain = np.asarray(ds["strain"].values, dtype=np.float64)
    sim_strain = np.asarray(ds["sim_strain"].values, dtype=np.float64)
    tip_strain = np.asarray(ds["tip_lateral_strain"].values, dtype=np.float64)
    return RunView(
        t_s=t,
        rocker_angle_rad=rocker,
        strain=strain,
        sim_tip_lateral_m=sim_tip,
        sim_strain=sim_strain,
        frame_t_s=ft,
        tip_lateral_image_m=image,
        tip_lateral_strain_m=tip_strain,
        fig11=(
            hub_at_frames[points],
            image[points],
            np.asarray(sim_hub, dtype=np.float64)[steady],
            sim_tip[steady],
        ),
        summary_markdown="\n".join(lines),
        strain_residual=np.where(settled[:, None], strain - sim_strain, np.nan),
        tip_image_minus_sim_m=np.where(settled_frames, image - sim_at_frames, np.nan),
        tip_strain_minus_sim_m=np.where(settled, tip_strain - sim_tip, np.nan),
        hub_at_frames_rad=np.asarray(hub_at_frames, dtype=np.float64),
    )


@dataclass(frozen=True)
class Fig11Axes:
    """Axes for Fig. 11 drawn in its 2D view (units: degrees across, -mm down).

    ``lines``: the two axes and the zero-deflection line as line strips; ``tick_positions``
    (T, 2) with ``tick_labels`` (T,): tick marks with their numbers; ``bounds``: (x_min,
    x_max, y_min, y_max) of the whole figure, numbers included.
    """

    lines: list[FloatArray]
    tick_positions: FloatArray
    tick_labels: list[str]
    bounds: tuple[float, float, float, float]


def nice_step(span: float, target_ticks: int = 6) -> float:
    """A tick spacing of 1, 2 or 5 times a power of ten giving about ``target_ticks``
    ticks over ``span``."""
    if not (math.isfinite(span) and span > 0):
        return 1.0
    raw = span / target_ticks
    power = 10.0 ** math.floor(math.log10(raw))
    return next(m * power for m in (1.0, 2.0, 5.0, 10.0) if m * power >= raw)


def fig11_axes(lo: ArrayLike, hi: ArrayLike) -> Fig11Axes:
    """Axes around Fig. 11's data box ``lo``..``hi`` (x: hub angle in degrees; y: -mm).

    The hub-angle axis runs under the data, the deflection axis to its left; ticks carry
    numbers in degrees and in mm (up = +lateral, so a tick at view y shows -y).
    """
    (x0, y0), (x1, y1) = np.asarray(lo, float), np.asarray(hi, float)
    if x1 - x0 <= 0:
        x0, x1 = x0 - 1.0, x1 + 1.0
    if y1 - y0 <= 0:
        y0, y1 = y0 - 1.0, y1 + 1.0
    sx, sy = nice_step(x1 - x0), nice_step(y1 - y0)
    pad_x, pad_y = 0.06 * (x1 - x0), 0.06 * (y1 - y0)
    ax_y = y1 + pad_y  # the hub-angle axis, under the data (view y grows downwards)
    ax_x = x0 - pad_x  # the deflection axis, left of the data
    tick = 0.35 * min(pad_x, pad_y) + 1e-9
    xs = np.arange(math.ceil(x0 / sx) * sx, x1 + 1e-9 * sx, sx)
    ys = np.arange(math.ceil(y0 / sy) * sy, y1 + 1e-9 * sy, sy)
    lines: list[FloatArray] = [
        np.array([[ax_x, ax_y], [x1 + pad_x, ax_y]]),
        np.array([[ax_x, ax_y], [ax_x, y0 - pad_y]]),
    ]
    if y0 < 0 < y1:
        lines.append(np.array([[ax_x, 0.0], [x1 + pad_x, 0.0]]))
    positions = [[x, ax_y + tick] for x in xs] + [[ax_x - tick, y] for y in ys]
    labels = [f"{x:g}°" for x in xs] + [f"{-y + 0.0:g} mm" for y in ys]
    lines += [np.array([[x, ax_y], [x, ax_y + tick]]) for x in xs]
    lines += [np.array([[ax_x - tick, y], [ax_x, y]]) for y in ys]
    label_room_x = 0.18 * (x1 - x0)
    bounds = (ax_x - label_room_x, x1 + 2 * pad_x, y0 - 2 * pad_y, ax_y + 4 * pad_y)
    return Fig11Axes(
        lines=lines,
        tick_positions=np.asarray(positions, dtype=np.float64).reshape(-1, 2),
        tick_labels=labels,
        bounds=bounds,
    )
