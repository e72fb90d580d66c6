"""Writing and reading results files (NetCDF4/HDF5 through h5netcdf).

Dict attributes become JSON strings (NetCDF attributes are flat); boolean attributes are
written as the strings ``"true"``/``"false"``, listed in ``bool_attrs``, and read back as
``bool``. Files are written atomically (:mod:`pipelines.atomic`).
"""

from __future__ import annotations

import io
import json
import logging
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from pipelines.atomic import write_bytes_atomic
from pipelines.results.schema import FORMAT_NAME, VARIABLES

log = logging.getLogger(__name__)


def json_default(obj: Any) -> Any:
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    raise TypeError(f"cannot store {type(obj).__name__} in a results attribute")


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
            out[key] = json.dumps(value, sort_keys=True, default=json_default)
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
    write_netcdf_bytes(encoded, out)
    log.info("wrote results %s", out)
    return out


def write_netcdf_bytes(ds: xr.Dataset, path: str | os.PathLike[str]) -> Path:
    """NetCDF4 (h5netcdf) built in memory, then written atomically: HDF5 writing to a full
    disk reports through its own error stack and object destructors (and can crash the
    interpreter at exit); a plain write reports one ``OSError``. Results are megabytes."""
    buf = io.BytesIO()
    ds.to_netcdf(buf, engine="h5netcdf")
    return write_bytes_atomic(path, buf.getvalue())


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
