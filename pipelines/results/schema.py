"""The results file of a processed run: one xarray Dataset, written as NetCDF4/HDF5.

The schema is the contract of ``shared/design.md`` ("Results"):

- coordinates ``time`` (s since run start, the DAQ samples), ``frame_time`` (s, camera
  frames, on the DAQ run clock: the camera-to-DAQ offset is already applied) and
  ``gauge`` (gauge position from the clamp, m);
- the nine variables of :data:`VARIABLES`, each with ``units`` and ``long_name``;
- optional extras (:data:`OPTIONAL_VARIABLES`);
- global attributes: :data:`REQUIRED_ATTRS` given by the caller, plus the error
  summaries of :func:`summarise_errors` and the frame counts, computed here so they
  always agree with the variables.

Dict attributes become JSON strings (NetCDF attributes are flat); boolean attributes are
written as the strings ``"true"``/``"false"``, listed in ``bool_attrs``, and read back as
``bool``.
"""

from __future__ import annotations

import contextlib
import json
import logging
import math
import os
import uuid
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr
from numpy.typing import ArrayLike, NDArray

log = logging.getLogger(__name__)

FORMAT_NAME = "beambench-results"
FORMAT_VERSION = 1

# name -> (dims, units, long_name); the order is the order in the file.
VARIABLES: dict[str, tuple[tuple[str, ...], str, str]] = {
    "rocker_angle": (("time",), "rad", "potentiometer (hub) angle"),
    "strain": (("time", "gauge"), "1", "measured surface strain"),
    "hub_angle_image": (("frame_time",), "rad", "hub angle measured in the image"),
    "tip_lateral": (
        ("frame_time",),
        "m",
        "lateral tip deflection relative to the rigid beam, from images",
    ),
    "tip_longitudinal": (("frame_time",), "m", "longitudinal tip deflection, from images"),
    "frame_ok": (("frame_time",), "bool", "whether the frame gave a measurement"),
    "tip_lateral_strain": (
        ("time",),
        "m",
        "lateral tip deflection reconstructed from the four strains",
    ),
    "sim_tip_lateral": (("time",), "m", "simulated lateral tip deflection"),
    "sim_strain": (("time", "gauge"), "1", "simulated strain at the gauges"),
}

OPTIONAL_VARIABLES: dict[str, tuple[tuple[str, ...], str, str]] = {
    "sim_tip_longitudinal": (("time",), "m", "simulated longitudinal tip deflection"),
    "hub_angle_sim": (("time",), "rad", "hub angle that drove the simulation"),
    "lateral_at_stations_image": (
        ("frame_time", "station"),
        "m",
        "lateral deflection at stations along the beam, from images",
    ),
}

COORDS: dict[str, tuple[str, str]] = {
    "time": ("s", "time since run start (DAQ samples)"),
    "frame_time": ("s", "camera frame time since run start, on the DAQ clock"),
    "gauge": ("m", "gauge position from the clamp"),
    "station": ("m", "station position from the clamp"),
}

# Global attributes the caller must give to make_results, with their meaning.
REQUIRED_ATTRS: dict[str, str] = {
    "source_log": "path of the run log the results came from",
    "rig_json": "the rig configuration as JSON (pipelines.rig.Rig.to_json)",
    "software_version": "beambench version that processed the run",
    "sim_model": "simulation model used (e.g. 'modal', 'fe-corot')",
    "sim_settings": "simulation settings (dict, stored as JSON)",
    "camera_to_daq_offset_s": "offset added to camera timestamps to get DAQ time (s)",
}


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
# Display units of the error table: metres shown as mm, strain as microstrain.
DISPLAY_UNITS = {"m": ("mm", 1e3), "1": ("µε", 1e6)}

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
            out[key] = json.dumps(value, sort_keys=True, default=_json_default)
    return out


def _json_default(obj: Any) -> Any:
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    raise TypeError(f"cannot store {type(obj).__name__} in a results attribute")


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


def _errors_as_attrs(errors: Mapping[str, Any]) -> dict[str, Any]:
    return {
        k: (np.asarray(v, dtype=np.float64) if isinstance(v, list) else v)
        for k, v in errors.items()
    }


def _encode_attrs(attrs: Mapping[str, Any]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    bools: list[str] = []
    for key, value in attrs.items():
        if key == "bool_attrs":
            continue
        if isinstance(value, bool | np.bool_):
            out[key] = "true" if value else "false"
            bools.append(key)
        elif isinstance(value, Mapping):
            out[key] = json.dumps(value, sort_keys=True, default=_json_default)
        elif value is None:
            raise TypeError(f"attribute {key!r} is None; NetCDF cannot store it")
        else:
            out[key] = value
    if bools:
        out["bool_attrs"] = ",".join(bools)
    return out


def write_results(ds: xr.Dataset, path: str | os.PathLike[str]) -> Path:
    """Write a results Dataset to NetCDF4/HDF5 (h5netcdf), atomically.

    The file is written next to ``path`` under a temporary name and renamed when
    complete: a failed write leaves an existing ``path`` untouched and no temporary file.

    Parameters
    ----------
    ds : results Dataset, normally from :func:`make_results`.
    path : output file (``.nc``).

    Returns
    -------
    Path
        ``path``.
    """
    if not isinstance(ds, xr.Dataset):
        raise TypeError(f"ds must be an xarray.Dataset, got {type(ds).__name__}")
    out = Path(path)
    if out.is_dir():
        raise ValueError(f"{out}: is a folder, expected a results file path")
    if not out.parent.is_dir():
        raise FileNotFoundError(f"{out}: folder {out.parent} does not exist")
    encoded = ds.copy(deep=False)
    encoded.attrs = _encode_attrs(ds.attrs)
    # A fresh name beside the target (same file system, so the rename is atomic); not
    # mkstemp, whose 0600 mode would stick to the renamed file.
    tmp = out.parent / f".{out.name}.{uuid.uuid4().hex}.tmp"
    try:
        encoded.to_netcdf(tmp, engine="h5netcdf")
        os.replace(tmp, out)
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
    log.info("wrote results %s", out)
    return out


def read_results(path: str | os.PathLike[str]) -> xr.Dataset:
    """Read a results file written by :func:`write_results` into memory.

    Raises
    ------
    FileNotFoundError
        ``path`` does not exist.
    ValueError
        ``path`` is not a beambench results file (the message names the file).
    """
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"{p}: no such results file")
    try:
        with xr.open_dataset(
            p, engine="h5netcdf", decode_times=False, decode_timedelta=False
        ) as opened:
            ds = opened.load()
    except (OSError, ValueError, TypeError, KeyError) as exc:
        raise ValueError(f"{p}: not a beambench results file ({exc})") from None
    if ds.attrs.get("format") != FORMAT_NAME:
        raise ValueError(f"{p}: not a beambench results file (no format={FORMAT_NAME!r})")
    missing = [name for name in VARIABLES if name not in ds]
    if missing:
        raise ValueError(f"{p}: results file lacks variable(s) {', '.join(missing)}")
    bools = ds.attrs.pop("bool_attrs", "")
    for key in filter(None, str(bools).split(",")):
        ds.attrs[key] = ds.attrs.get(key) == "true"
    for key in ("frames_total", "frames_failed", "n_frames_compared", "format_version"):
        if key in ds.attrs:
            ds.attrs[key] = int(ds.attrs[key])
    return ds


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
