"""A simulation on its own as an xarray Dataset (design.md), and its atomic NetCDF writer."""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from pipelines import __version__
from pipelines.results.io import write_netcdf_bytes
from sim.result import SimResult


def _json_default(obj: Any) -> Any:
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    return str(obj)


def to_json(value: Any) -> str:
    return json.dumps(value, sort_keys=True, default=_json_default)


def sim_dataset(
    result: SimResult,
    *,
    scene: str,
    rig_json: str | None = None,
    extras: Mapping[str, Any] | None = None,
) -> xr.Dataset:
    """Dataset with coords ``time`` (s), ``gauge`` (m), ``station`` (m) and variables
    ``hub_angle``, ``tip_lateral``, ``tip_longitudinal``, ``strain``, ``station_lateral``,
    ``station_longitudinal``; global attributes ``model``, ``rtol``, ``atol``,
    ``wall_time_s`` (the solve alone), ``settings`` (JSON), ``scene``, and the scene's extra
    numbers (scalars as attributes, the rest as JSON in ``extras``)."""
    settings = dict(result.settings)
    ds = xr.Dataset(
        coords={
            "time": ("time", result.time_s, {"units": "s", "long_name": "time since start"}),
            "gauge": (
                "gauge",
                result.gauge_positions_m,
                {"units": "m", "long_name": "gauge position from the clamp"},
            ),
            "station": (
                "station",
                result.stations_m,
                {"units": "m", "long_name": "station position from the clamp"},
            ),
        }
    )
    ds["hub_angle"] = ("time", result.hub_angle_rad, {"units": "rad", "long_name": "hub angle"})
    ds["tip_lateral"] = (
        "time",
        result.tip_lateral_m,
        {"units": "m", "long_name": "lateral tip deflection relative to the rigid beam"},
    )
    ds["tip_longitudinal"] = (
        "time",
        result.tip_longitudinal_m,
        {"units": "m", "long_name": "longitudinal tip deflection relative to the rigid beam"},
    )
    ds["strain"] = (
        ("time", "gauge"),
        result.strain,
        {"units": "1", "long_name": "surface strain at the gauges"},
    )
    ds["station_lateral"] = (
        ("time", "station"),
        result.station_lateral_m,
        {"units": "m", "long_name": "lateral deflection at the stations"},
    )
    ds["station_longitudinal"] = (
        ("time", "station"),
        result.station_longitudinal_m,
        {"units": "m", "long_name": "longitudinal deflection at the stations"},
    )
    ds.attrs.update(
        {
            "title": f"beambench simulation: {scene}",
            "scene": scene,
            "model": result.model,
            "rtol": float(settings.get("rtol", float("nan"))),
            "atol": float(settings.get("atol", float("nan"))),
            "wall_time_s": float(result.wall_time_s),
            "settings": to_json(settings),
            "software_version": f"beambench {__version__}",
        }
    )
    if rig_json is not None:
        # `rig_json` as in a processed run's results; `rig` kept for files' existing readers
        ds.attrs["rig_json"] = ds.attrs["rig"] = rig_json
    rest: dict[str, Any] = {}
    for key, value in (extras or {}).items():
        if isinstance(value, bool):
            ds.attrs[key] = "true" if value else "false"
        elif isinstance(value, int | float | str | np.integer | np.floating):
            ds.attrs[key] = value
        else:
            rest[key] = value
    if rest:
        ds.attrs["extras"] = to_json(rest)
    return ds


def modes_dataset(modes: Mapping[str, Any], *, rig_json: str | None = None) -> xr.Dataset:
    """Clamped-free modes: ``eigenvalue``, ``natural_frequency`` (mode) and ``shape``
    (mode, station)."""
    n = len(modes["eigenvalue"])
    ds = xr.Dataset(
        coords={
            "mode": ("mode", np.arange(1, n + 1), {"units": "1", "long_name": "mode number"}),
            "station": (
                "station",
                modes["stations_m"],
                {"units": "m", "long_name": "station position from the clamp"},
            ),
        }
    )
    ds["eigenvalue"] = (
        "mode",
        modes["eigenvalue"],
        {"units": "1", "long_name": "root of cos(l) cosh(l) + 1 = 0"},
    )
    ds["natural_frequency"] = (
        "mode",
        np.asarray(modes["frequency_rad_s"]) / (2.0 * np.pi),
        {"units": "Hz", "long_name": "clamped-free natural frequency"},
    )
    ds["shape"] = (
        ("mode", "station"),
        modes["shapes"],
        {"units": "1", "long_name": "mode shape, mean square 1 over the beam"},
    )
    ds.attrs.update(
        {
            "title": "beambench simulation: modes",
            "scene": "modes",
            "model": "modal",
            "rtol": 0.0,
            "atol": 0.0,
            "wall_time_s": float(modes["wall_time_s"]),
            "settings": to_json({"n_modes": n}),
            "software_version": f"beambench {__version__}",
        }
    )
    if rig_json is not None:
        # `rig_json` as in a processed run's results; `rig` kept for files' existing readers
        ds.attrs["rig_json"] = ds.attrs["rig"] = rig_json
    return ds


def check_output_path(path: str | os.PathLike[str]) -> Path:
    """Refuse an output path that cannot be written, before any work is done."""
    out = Path(path)
    if out.is_dir():
        raise ValueError(f"{out}: is a folder, expected a .nc file path")
    if not out.parent.is_dir():
        raise ValueError(f"{out}: folder {out.parent} does not exist")
    if not os.access(out.parent, os.W_OK):
        raise ValueError(f"{out}: folder {out.parent} is not writable")
    if out.exists() and not os.access(out, os.W_OK):
        raise ValueError(f"{out}: exists and is not writable")
    return out


def write_dataset(ds: xr.Dataset, path: str | os.PathLike[str]) -> Path:
    """Write NetCDF4 (h5netcdf) to a temporary file beside ``path`` and rename it on
    success, so a failed run never clobbers an existing file."""
    out = check_output_path(path)
    return write_netcdf_bytes(ds, out)
