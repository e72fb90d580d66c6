"""Comparing a processed run's measurements with each other and with the simulation.

The error summaries (:func:`summarise_errors`) are stored as global attributes of the
results file; the masks say which samples and frames a comparison or a figure uses.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import xarray as xr
from numpy.typing import NDArray

from pipelines.results.schema import VARIABLES


@dataclass(frozen=True)
class ErrorMetric:
    """One row of the error summary: attribute name, what is compared, unit."""

    key: str
    label: str
    units: str


# Scalar metrics in metres; strain metrics are per gauge (arrays over ``gauge``).
ERROR_METRICS: tuple[ErrorMetric, ...] = (
    ErrorMetric("tip_lateral_image_vs_sim_rms_m", "tip lateral, image - sim, RMS", "m"),
    ErrorMetric("tip_lateral_image_vs_sim_max_m", "tip lateral, image - sim, max abs", "m"),
    ErrorMetric("tip_lateral_strain_vs_image_rms_m", "tip lateral, strain - image, RMS", "m"),
    ErrorMetric("tip_lateral_strain_vs_image_max_m", "tip lateral, strain - image, max abs", "m"),
    ErrorMetric("tip_lateral_strain_vs_sim_rms_m", "tip lateral, strain - sim, RMS", "m"),
    ErrorMetric("tip_lateral_strain_vs_sim_max_m", "tip lateral, strain - sim, max abs", "m"),
)


STRAIN_METRICS: tuple[ErrorMetric, ...] = (
    ErrorMetric("strain_vs_sim_rms", "strain, measured - sim, RMS", "1"),
    ErrorMetric("strain_vs_sim_max", "strain, measured - sim, max abs", "1"),
)


FloatArray = NDArray[np.float64]


def _rms_max(diff: FloatArray) -> tuple[float, float]:
    d = diff[np.isfinite(diff)]
    if d.size == 0:
        return math.nan, math.nan
    return float(np.sqrt(np.mean(d**2))), float(np.max(np.abs(d)))


def _at_frames(ds: xr.Dataset, name: str) -> FloatArray:
    """A ``time`` series interpolated at the frame times (NaN outside the DAQ span)."""
    t = ds["time"].values
    ft = ds["frame_time"].values
    y = np.asarray(ds[name].values, dtype=np.float64)
    out = np.interp(ft, t, y, left=np.nan, right=np.nan)
    return np.asarray(out, dtype=np.float64)


def sim_start_s(ds: xr.Dataset) -> float:
    """Time from which the simulation is compared: the first sample plus the global
    attribute ``settle_time_s`` (the start-up transient of a simulation started from
    rest; 0 when absent)."""
    settle = ds.attrs.get("settle_time_s", 0.0)
    try:
        settle = float(settle)
    except (TypeError, ValueError):
        settle = 0.0
    if not math.isfinite(settle) or settle < 0:
        settle = 0.0
    return float(ds["time"].values[0]) + settle


def summarise_errors(ds: xr.Dataset) -> dict[str, Any]:
    """Compare simulation, strain-based and image-based results.

    Time series on ``time`` are linearly interpolated at the frame times for the
    comparisons with images; only frames with ``frame_ok`` and finite values inside the
    DAQ time span count. Comparisons with the simulation start at :func:`sim_start_s`
    (after its start-up transient); strain-based against image uses every frame.
    Differences are taken as first-named minus second-named.

    Parameters
    ----------
    ds : a results Dataset (see :func:`make_results`).

    Returns
    -------
    dict
        The keys of :data:`ERROR_METRICS` (float, m; NaN when nothing can be compared),
        ``strain_vs_sim_rms`` and ``strain_vs_sim_max`` (list of float per gauge, m/m),
        ``n_frames_compared`` (int, frames in the image - sim comparison) and
        ``sim_compared_from_s`` (float, s).
    """
    for name in VARIABLES:
        if name not in ds:
            raise ValueError(f"ds is missing variable {name!r}")
    start = sim_start_s(ds)
    t = np.asarray(ds["time"].values, dtype=np.float64)
    late = t >= start
    late_frames = np.asarray(ds["frame_time"].values, dtype=np.float64) >= start
    ok = np.asarray(ds["frame_ok"].values, dtype=bool)
    image = np.where(ok, np.asarray(ds["tip_lateral"].values, dtype=np.float64), np.nan)
    sim_f = _at_frames(ds, "sim_tip_lateral")
    strain_f = _at_frames(ds, "tip_lateral_strain")
    image_vs_sim = np.where(late_frames, image - sim_f, np.nan)
    out: dict[str, Any] = {}
    pairs = {
        "tip_lateral_image_vs_sim": image_vs_sim,
        "tip_lateral_strain_vs_image": strain_f - image,
        "tip_lateral_strain_vs_sim": np.asarray(
            ds["tip_lateral_strain"].values[late] - ds["sim_tip_lateral"].values[late],
            dtype=np.float64,
        ),
    }
    for stem, diff in pairs.items():
        out[f"{stem}_rms_m"], out[f"{stem}_max_m"] = _rms_max(diff)
    d = np.asarray(ds["strain"].values[late] - ds["sim_strain"].values[late], dtype=np.float64)
    per_gauge = [_rms_max(d[:, j]) for j in range(d.shape[1])]
    out["strain_vs_sim_rms"] = [r for r, _ in per_gauge]
    out["strain_vs_sim_max"] = [m for _, m in per_gauge]
    out["n_frames_compared"] = int(np.count_nonzero(np.isfinite(image_vs_sim)))
    out["sim_compared_from_s"] = start
    return out


def rig_json_of(ds: xr.Dataset) -> dict[str, Any]:
    """The rig configuration recorded in a results Dataset, as a dict."""
    value = json.loads(ds.attrs["rig_json"])
    if not isinstance(value, dict):
        raise ValueError("rig_json attribute is not a JSON object")
    return value


def crank_period_s(ds: xr.Dataset) -> float:
    """The crank period recorded in the rig configuration (NaN when not recorded)."""
    try:
        freq = float(rig_json_of(ds)["linkage"]["crank_frequency_hz"])
    except (KeyError, TypeError, ValueError, json.JSONDecodeError):
        return math.nan
    return 1.0 / freq if math.isfinite(freq) and freq > 0 else math.nan


def steady_state_mask(ds: xr.Dataset, cycles: int = 3) -> NDArray[np.bool_]:
    """(N,) bool: the samples of the last ``cycles`` crank cycles (the paper's Fig. 11).

    The whole run when the crank period is unknown or the run is shorter.
    """
    if cycles < 1:
        raise ValueError(f"cycles must be at least 1, got {cycles}")
    t = np.asarray(ds["time"].values, dtype=np.float64)
    period = crank_period_s(ds)
    if not math.isfinite(period) or t[-1] - t[0] <= cycles * period:
        return np.ones(t.shape, dtype=bool)
    return np.asarray(t >= t[-1] - cycles * period)
