"""Building a results Dataset from a processed run's arrays, checked against the schema
(:mod:`pipelines.results.schema`), with its error summaries computed here.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Mapping
from typing import Any

import numpy as np
import xarray as xr
from numpy.typing import ArrayLike, NDArray

from pipelines.results.compare import summarise_errors
from pipelines.results.io import json_default
from pipelines.results.schema import (
    COORDS,
    FORMAT_NAME,
    FORMAT_VERSION,
    OPTIONAL_VARIABLES,
    REQUIRED_ATTRS,
    VARIABLES,
)

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]


def _vector(name: str, value: ArrayLike, n: int | None = None) -> FloatArray:
    a = np.asarray(value, dtype=np.float64)
    if a.ndim != 1:
        raise ValueError(f"{name} must be 1-D, got shape {a.shape}")
    if n is not None and a.shape[0] != n:
        raise ValueError(f"{name} must have shape ({n},), got {a.shape}")
    return a


def _matrix(name: str, value: ArrayLike, shape: tuple[int, int]) -> FloatArray:
    a = np.asarray(value, dtype=np.float64)
    if a.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {a.shape}")
    return a


def _axis(name: str, value: ArrayLike) -> FloatArray:
    a = _vector(name, value)
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be finite")
    if a.size > 1 and not np.all(np.diff(a) > 0):
        raise ValueError(f"{name} must be strictly increasing")
    return a


def _check_attrs(attrs: Mapping[str, Any]) -> dict[str, Any]:
    if not isinstance(attrs, Mapping):
        raise TypeError(f"attrs must be a dict, got {type(attrs).__name__}")
    missing = [k for k in REQUIRED_ATTRS if k not in attrs]
    if missing:
        raise ValueError(f"attrs is missing required key(s): {', '.join(missing)}")
    out = dict(attrs)
    for key in ("source_log", "software_version", "sim_model"):
        if not isinstance(out[key], str):
            raise TypeError(f"attrs[{key!r}] must be a str, got {type(out[key]).__name__}")
    rig = out["rig_json"]
    if not isinstance(rig, str):
        raise TypeError(f"attrs['rig_json'] must be a JSON str, got {type(rig).__name__}")
    try:
        rig_obj = json.loads(rig)
    except json.JSONDecodeError as exc:
        raise ValueError(f"attrs['rig_json'] is not valid JSON: {exc}") from None
    if not isinstance(rig_obj, dict):
        raise ValueError("attrs['rig_json'] must be a JSON object")
    settings = out["sim_settings"]
    if isinstance(settings, str):
        try:
            json.loads(settings)
        except json.JSONDecodeError as exc:
            raise ValueError(f"attrs['sim_settings'] is not valid JSON: {exc}") from None
    elif not isinstance(settings, Mapping):
        raise TypeError(
            f"attrs['sim_settings'] must be a dict or JSON str, got {type(settings).__name__}"
        )
    offset = out["camera_to_daq_offset_s"]
    if isinstance(offset, bool) or not isinstance(offset, int | float | np.floating):
        raise TypeError(
            f"attrs['camera_to_daq_offset_s'] must be a number (NaN if unknown), got {offset!r}"
        )
    out["camera_to_daq_offset_s"] = float(offset)
    # Dicts and lists of dicts are flattened now, so the in-memory Dataset already has
    # the on-disk attribute types.
    for key, value in list(out.items()):
        if not isinstance(key, str) or not key:
            raise TypeError(f"attrs keys must be non-empty str, got {key!r}")
        if value is None:
            raise TypeError(f"attrs[{key!r}] is None; NetCDF cannot store it (leave it out)")
        if isinstance(value, Mapping):
            out[key] = json.dumps(value, sort_keys=True, default=json_default)
    return out


def make_results(
    *,
    time_s: ArrayLike,
    rocker_angle_rad: ArrayLike,
    strain: ArrayLike,
    gauge_m: ArrayLike,
    frame_time_s: ArrayLike,
    hub_angle_image_rad: ArrayLike,
    tip_lateral_m: ArrayLike,
    tip_longitudinal_m: ArrayLike,
    frame_ok: ArrayLike,
    tip_lateral_strain_m: ArrayLike,
    sim_tip_lateral_m: ArrayLike,
    sim_strain: ArrayLike,
    attrs: Mapping[str, Any],
    sim_tip_longitudinal_m: ArrayLike | None = None,
    hub_angle_sim_rad: ArrayLike | None = None,
    station_m: ArrayLike | None = None,
    lateral_at_stations_image_m: ArrayLike | None = None,
    hub_angle_image_sd_rad: ArrayLike | None = None,
    tip_lateral_sd_m: ArrayLike | None = None,
    tip_longitudinal_sd_m: ArrayLike | None = None,
) -> xr.Dataset:
    """Build a results Dataset with the schema of ``shared/design.md``.

    Parameters
    ----------
    time_s : (N,) DAQ sample times since run start [s], strictly increasing.
    rocker_angle_rad : (N,) potentiometer angle [rad].
    strain : (N, G) measured surface strain [m/m], gauges ordered by distance from the clamp.
    gauge_m : (G,) gauge positions from the clamp [m], strictly increasing.
    frame_time_s : (F,) camera frame times [s] on the DAQ clock (offset applied),
        strictly increasing; F may be 0.
    hub_angle_image_rad : (F,) hub angle measured in each image [rad].
    tip_lateral_m, tip_longitudinal_m : (F,) tip deflection from the images [m].
    frame_ok : (F,) bool, whether the frame gave a measurement. Image values of frames
        that are not ok are set to NaN here.
    tip_lateral_strain_m : (N,) tip deflection reconstructed from the strains [m].
    sim_tip_lateral_m : (N,) simulated lateral tip deflection [m].
    sim_strain : (N, G) simulated strain at the gauges [m/m].
    attrs : global attributes; must hold every key of :data:`REQUIRED_ATTRS`. Dict
        values are stored as JSON strings. The error summaries
        (:func:`summarise_errors`) and ``frames_total``/``frames_failed`` are computed
        here and override keys of the same name.
    sim_tip_longitudinal_m, hub_angle_sim_rad : optional (N,) simulated extras.
    station_m : optional (S,) station positions from the clamp [m], with
    lateral_at_stations_image_m : optional (F, S) lateral deflection at the stations [m].
    hub_angle_image_sd_rad, tip_lateral_sd_m, tip_longitudinal_sd_m : optional (F,)
        standard uncertainties of the image measurements [rad, m, m] (NaN where a frame
        is not ok); each becomes ``hub_angle_image_sd``, ``tip_lateral_sd``,
        ``tip_longitudinal_sd``.

    Returns
    -------
    xarray.Dataset

    Raises
    ------
    ValueError, TypeError
        A shape, dtype or attribute problem, naming the parameter.
    """
    t = _axis("time_s", time_s)
    g = _axis("gauge_m", gauge_m)
    ft = _axis("frame_time_s", frame_time_s)
    n, ng, nf = t.size, g.size, ft.size
    if n == 0:
        raise ValueError("time_s must hold at least one sample")
    if ng == 0:
        raise ValueError("gauge_m must hold at least one gauge")
    ok = np.asarray(frame_ok)
    if ok.dtype != np.bool_:
        raise TypeError(f"frame_ok must be a bool array, got dtype {ok.dtype}")
    if ok.shape != (nf,):
        raise ValueError(f"frame_ok must have shape ({nf},), got {ok.shape}")
    data: dict[str, np.ndarray] = {
        "rocker_angle": _vector("rocker_angle_rad", rocker_angle_rad, n),
        "strain": _matrix("strain", strain, (n, ng)),
        "hub_angle_image": _vector("hub_angle_image_rad", hub_angle_image_rad, nf).copy(),
        "tip_lateral": _vector("tip_lateral_m", tip_lateral_m, nf).copy(),
        "tip_longitudinal": _vector("tip_longitudinal_m", tip_longitudinal_m, nf).copy(),
        "frame_ok": ok.copy(),
        "tip_lateral_strain": _vector("tip_lateral_strain_m", tip_lateral_strain_m, n),
        "sim_tip_lateral": _vector("sim_tip_lateral_m", sim_tip_lateral_m, n),
        "sim_strain": _matrix("sim_strain", sim_strain, (n, ng)),
    }
    for name in ("hub_angle_image", "tip_lateral", "tip_longitudinal"):
        data[name][~ok] = np.nan
    if sim_tip_longitudinal_m is not None:
        data["sim_tip_longitudinal"] = _vector("sim_tip_longitudinal_m", sim_tip_longitudinal_m, n)
    if hub_angle_sim_rad is not None:
        data["hub_angle_sim"] = _vector("hub_angle_sim_rad", hub_angle_sim_rad, n)
    for name, arg, values in (
        ("hub_angle_image_sd", "hub_angle_image_sd_rad", hub_angle_image_sd_rad),
        ("tip_lateral_sd", "tip_lateral_sd_m", tip_lateral_sd_m),
        ("tip_longitudinal_sd", "tip_longitudinal_sd_m", tip_longitudinal_sd_m),
    ):
        if values is not None:
            sd = _vector(arg, values, nf).copy()
            if np.any(sd[np.isfinite(sd)] < 0):
                raise ValueError(f"{arg} must not be negative")
            sd[~ok] = np.nan
            data[name] = sd
    coords: dict[str, FloatArray] = {"time": t, "frame_time": ft, "gauge": g}
    if (station_m is None) != (lateral_at_stations_image_m is None):
        raise ValueError("station_m and lateral_at_stations_image_m must be given together")
    if station_m is not None and lateral_at_stations_image_m is not None:
        s = _axis("station_m", station_m)
        coords["station"] = s
        lat = _matrix("lateral_at_stations_image_m", lateral_at_stations_image_m, (nf, s.size))
        lat = lat.copy()
        lat[~ok, :] = np.nan
        data["lateral_at_stations_image"] = lat

    checked = _check_attrs(attrs)
    spec = {**VARIABLES, **OPTIONAL_VARIABLES}
    ds = xr.Dataset(
        {
            name: (spec[name][0], values, {"units": spec[name][1], "long_name": spec[name][2]})
            for name, values in data.items()
        },
        coords={
            name: (name, values, {"units": COORDS[name][0], "long_name": COORDS[name][1]})
            for name, values in coords.items()
        },
    )
    ds.attrs.update(checked)
    ds.attrs["format"] = FORMAT_NAME
    ds.attrs["format_version"] = FORMAT_VERSION
    ds.attrs["frames_total"] = int(nf)
    ds.attrs["frames_failed"] = int(np.count_nonzero(~ok))
    ds.attrs.update(_errors_as_attrs(summarise_errors(ds)))
    if ds.attrs["frames_failed"]:
        log.info("%d of %d frames gave no measurement", ds.attrs["frames_failed"], nf)
    return ds


def _errors_as_attrs(errors: Mapping[str, Any]) -> dict[str, Any]:
    return {
        k: (np.asarray(v, dtype=np.float64) if isinstance(v, list) else v)
        for k, v in errors.items()
    }
