"""What the catalogue keeps of a processed run: the crank frequency measured from the
rocker angle, the tip's crank fundamental from the images, the strains and the
simulation (amplitude and phase lag behind the rocker angle, each with its standard
uncertainty) and the comparison metrics the results file carries.

All fits use the steady part: from the simulation's settling time on
(:func:`pipelines.results.compare.sim_start_s`), the same window for all three sources.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import xarray as xr

from pipelines.campaign.harmonics import Fundamental, crank_frequency, fit_fundamental, phase_lag
from pipelines.results.compare import ERROR_METRICS, sim_start_s

SOURCES = ("image", "strain", "sim")
#: the results' ``--fit-damping`` attributes the catalogue keeps
FITTED_DAMPING = ("fitted_a1_s", "fitted_a1_ci95_s", "fitted_a0_per_s", "fitted_a0_ci95_per_s")
_SERIES = {"image": "tip_lateral", "strain": "tip_lateral_strain", "sim": "sim_tip_lateral"}


def summarise_run(ds: xr.Dataset) -> dict[str, float]:
    """The catalogue's numbers for one results dataset (SI units, names carry them)."""
    t0 = sim_start_s(ds)
    t = ds["time"].values
    steady = t >= t0
    rocker = ds["rocker_angle"].values
    crank = crank_frequency(t[steady], rocker[steady])
    f = crank.frequency_hz
    ref = fit_fundamental(t[steady], rocker[steady], f)
    out: dict[str, float] = {
        "crank_frequency_hz": f,
        "crank_frequency_sd_hz": crank.frequency_sd_hz,
        "rocker_amplitude_rad": ref.amplitude,
        "rocker_amplitude_sd_rad": ref.amplitude_sd,
        "steady_from_s": t0,
    }
    for source in SOURCES:
        name = _SERIES[source]
        tt = ds[name].dims[0]
        ts = ds[tt].values
        keep = ts >= t0
        fit = fit_fundamental(ts[keep], ds[name].values[keep], f)
        out.update(_fundamental_columns(f"tip_lateral_{source}", fit, ref))
    for metric in ERROR_METRICS:
        out[metric.key] = _scalar(ds.attrs.get(metric.key))
    for key in FITTED_DAMPING:  # NaN without --fit-damping, or when the fit failed
        out[key] = _scalar(ds.attrs.get(key))
    out["frames_total"] = float(ds.attrs.get("frames_total", math.nan))
    out["frames_failed"] = float(ds.attrs.get("frames_failed", math.nan))
    return out


def _fundamental_columns(prefix: str, fit: Fundamental, ref: Fundamental) -> dict[str, float]:
    lag, lag_sd = phase_lag(fit, ref)
    return {
        f"{prefix}_amplitude_m": fit.amplitude,
        f"{prefix}_amplitude_sd_m": fit.amplitude_sd,
        f"{prefix}_phase_lag_rad": lag,
        f"{prefix}_phase_lag_sd_rad": lag_sd,
    }


def _scalar(value: Any) -> float:
    if value is None:
        return math.nan
    a = np.asarray(value, dtype=float)
    return float(a) if a.ndim == 0 else math.nan
