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
from numpy.typing import NDArray

from pipelines.results.compare import (
    ERROR_METRICS,
    STRAIN_METRICS,
    steady_state_mask,
    summarise_errors,
)
from pipelines.results.schema import VARIABLES

# Display units of the error table: metres shown as mm, strain as microstrain.
DISPLAY_UNITS = {"m": ("mm", 1e3), "1": ("µε", 1e6)}

FloatArray = NDArray[np.float64]


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
    angle [rad], simulated tip lateral [m]): Fig. 11's points and loop.
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
        f"# Simulation ({model}) against measurement",
        "",
        *error_table(summarise_errors(ds)),
    ]
    return RunView(
        t_s=t,
        rocker_angle_rad=rocker,
        strain=np.asarray(ds["strain"].values, dtype=np.float64),
        sim_tip_lateral_m=sim_tip,
        sim_strain=np.asarray(ds["sim_strain"].values, dtype=np.float64),
        frame_t_s=ft,
        tip_lateral_image_m=image,
        tip_lateral_strain_m=np.asarray(ds["tip_lateral_strain"].values, dtype=np.float64),
        fig11=(
            hub_at_frames[points],
            image[points],
            np.asarray(sim_hub, dtype=np.float64)[steady],
            sim_tip[steady],
        ),
        summary_markdown="\n".join(lines),
    )
