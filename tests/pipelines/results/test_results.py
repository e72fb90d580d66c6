"""Results file: schema, error summaries against known differences, round trip, failures."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import xarray as xr

from pipelines.results.compare import steady_state_mask, summarise_errors
from pipelines.results.dataset import make_results
from pipelines.results.io import read_results, write_results
from pipelines.results.schema import COORDS, REQUIRED_ATTRS, VARIABLES
from pipelines.rig import Rig

FS_HZ = 400.0
N = 800  # 2 s
STEP = 27  # one frame every 27 samples (~14.8 frames/s), on sample times
IMAGE_ERR_M = 1.5e-3  # image - sim alternates +/- this
STRAIN_TIP_ERR_M = 0.7e-3  # strain-based - sim, constant
STRAIN_ERR = np.array([3e-6, -5e-6, 8e-6, -1e-6])  # measured - sim strain per gauge


def _attrs(**over: Any) -> dict[str, Any]:
    attrs: dict[str, Any] = {
        "source_log": "run.mcap",
        "rig_json": Rig().to_json(),
        "software_version": "0.1.0",
        "sim_model": "modal",
        "sim_settings": {"rtol": 1e-6, "modes": 3, "auto": {"chosen": "modal"}},
        "camera_to_daq_offset_s": 0.0123,
        "synthetic": True,
    }
    attrs.update(over)
    return attrs


def _inputs(failed: tuple[int, ...] = (3,)) -> dict[str, Any]:
    t = np.arange(N) / FS_HZ
    omega = 2 * np.pi * 0.92
    rocker = 0.7669 * np.sin(omega * t)
    sim_tip = 0.02 * np.sin(omega * t - 0.4)
    gauges = np.array([0.005, 0.204, 0.403, 0.603])
    shape = (1 - gauges / 0.835) ** 2
    sim_strain = 4e-4 * np.sin(omega * t - 0.4)[:, None] * shape[None, :]
    idx = np.arange(0, N, STEP)
    nf = idx.size
    sign = np.where(np.arange(nf) % 2 == 0, 1.0, -1.0)
    ok = np.ones(nf, dtype=bool)
    ok[list(failed)] = False
    tip_image = sim_tip[idx] + IMAGE_ERR_M * sign
    tip_image[~ok] = 123.0  # junk the pipeline must not use
    return {
        "time_s": t,
        "rocker_angle_rad": rocker,
        "strain": sim_strain + STRAIN_ERR[None, :],
        "gauge_m": gauges,
        "frame_time_s": t[idx],
        "hub_angle_image_rad": rocker[idx] + 0.01,
        "tip_lateral_m": tip_image,
        "tip_longitudinal_m": -0.5 * tip_image**2 / 0.843,
        "frame_ok": ok,
        "tip_lateral_strain_m": sim_tip + STRAIN_TIP_ERR_M,
        "sim_tip_lateral_m": sim_tip,
        "sim_strain": sim_strain,
        "attrs": _attrs(),
    }


def test_schema_has_every_variable_coordinate_and_unit() -> None:
    ds = make_results(**_inputs())
    assert set(VARIABLES) <= set(ds.data_vars)
    for name, (dims, units, _) in VARIABLES.items():
        assert ds[name].dims == dims, name
        assert ds[name].attrs["units"] == units, name
        assert ds[name].attrs["long_name"], name
    for name in ("time", "frame_time", "gauge"):
        assert ds[name].attrs["units"] == COORDS[name][0]
        assert ds[name].attrs["long_name"]
    assert ds["frame_ok"].dtype == bool
    for key in REQUIRED_ATTRS:
        assert key in ds.attrs
    assert json.loads(ds.attrs["sim_settings"])["modes"] == 3
    assert ds.attrs["frames_total"] == ds.sizes["frame_time"]
    assert ds.attrs["frames_failed"] == 1


def test_failed_frames_become_nan_and_are_not_compared() -> None:
    ds = make_results(**_inputs(failed=(3, 5)))
    assert np.isnan(ds["tip_lateral"].values[[3, 5]]).all()
    assert np.isnan(ds["hub_angle_image"].values[[3, 5]]).all()
    assert ds.attrs["frames_failed"] == 2
    errors = summarise_errors(ds)
    assert errors["n_frames_compared"] == ds.sizes["frame_time"] - 2


def test_error_summary_equals_the_known_differences() -> None:
    ds = make_results(**_inputs())
    e = summarise_errors(ds)
    # Image - sim alternates +/-IMAGE_ERR_M at frames that sit on sample times.
    assert e["tip_lateral_image_vs_sim_rms_m"] == pytest.approx(IMAGE_ERR_M, rel=1e-9)
    assert e["tip_lateral_image_vs_sim_max_m"] == pytest.approx(IMAGE_ERR_M, rel=1e-9)
    assert e["tip_lateral_strain_vs_sim_rms_m"] == pytest.approx(STRAIN_TIP_ERR_M, rel=1e-9)
    assert e["tip_lateral_strain_vs_sim_max_m"] == pytest.approx(STRAIN_TIP_ERR_M, rel=1e-9)
    # strain - image = c - (+/-d): magnitudes d - c and d + c, counted per frame.
    ok = ds["frame_ok"].values
    sign = np.where(np.arange(ok.size) % 2 == 0, 1.0, -1.0)[ok]
    diff = STRAIN_TIP_ERR_M - IMAGE_ERR_M * sign
    assert e["tip_lateral_strain_vs_image_rms_m"] == pytest.approx(
        math.sqrt(np.mean(diff**2)), rel=1e-9
    )
    assert e["tip_lateral_strain_vs_image_max_m"] == pytest.approx(
        IMAGE_ERR_M + STRAIN_TIP_ERR_M, rel=1e-9
    )
    np.testing.assert_allclose(e["strain_vs_sim_rms"], np.abs(STRAIN_ERR), rtol=1e-9)
    np.testing.assert_allclose(e["strain_vs_sim_max"], np.abs(STRAIN_ERR), rtol=1e-9)
    # The same numbers are the Dataset's attributes.
    np.testing.assert_allclose(ds.attrs["strain_vs_sim_rms"], np.abs(STRAIN_ERR), rtol=1e-9)
    assert ds.attrs["tip_lateral_image_vs_sim_rms_m"] == e["tip_lateral_image_vs_sim_rms_m"]


def test_frames_between_samples_are_interpolated_and_outside_ones_skipped() -> None:
    kw = _inputs(failed=())
    t = kw["time_s"]
    # Sim linear in time: interpolation is exact, so image == sim exactly gives zero error.
    kw["sim_tip_lateral_m"] = 0.01 * t
    ft = np.array([0.0101, 0.5037, 1.2, t[-1] + 0.05])
    kw.update(
        frame_time_s=ft,
        tip_lateral_m=0.01 * ft + np.array([0.0, 0.0, 0.0, 9.9]),
        tip_longitudinal_m=np.zeros(4),
        hub_angle_image_rad=np.zeros(4),
        frame_ok=np.ones(4, dtype=bool),
    )
    e = summarise_errors(make_results(**kw))
    assert e["n_frames_compared"] == 3
    assert e["tip_lateral_image_vs_sim_max_m"] == pytest.approx(0.0, abs=1e-15)


def test_round_trip_is_equal(tmp_path: Path) -> None:
    ds = make_results(
        **_inputs(),
        sim_tip_longitudinal_m=np.zeros(N),
        hub_angle_sim_rad=np.linspace(-0.7, 0.7, N),
        station_m=np.array([0.2, 0.4, 0.835]),
        lateral_at_stations_image_m=np.ones((len(range(0, N, STEP)), 3)) * 1e-3,
    )
    path = write_results(ds, tmp_path / "r.nc")
    back = read_results(path)
    xr.testing.assert_identical(back.drop_attrs(), ds.drop_attrs())
    for name in list(ds.variables):
        assert back[name].attrs == ds[name].attrs, name
    assert back["frame_ok"].dtype == bool
    assert back.attrs["synthetic"] is True
    for key, value in ds.attrs.items():
        if isinstance(value, np.ndarray):
            np.testing.assert_array_equal(back.attrs[key], value)
        elif isinstance(value, float) and math.isnan(value):
            assert math.isnan(back.attrs[key])
        else:
            assert back.attrs[key] == value, key
    assert back["station"].attrs["units"] == "m"
    assert summarise_errors(back) == summarise_errors(ds)


def test_missing_or_wrong_inputs_name_the_parameter() -> None:
    kw = _inputs()
    kw["attrs"] = {k: v for k, v in kw["attrs"].items() if k != "camera_to_daq_offset_s"}
    with pytest.raises(ValueError, match="camera_to_daq_offset_s"):
        make_results(**kw)
    kw = _inputs()
    kw["strain"] = kw["strain"][:, :3]
    with pytest.raises(ValueError, match="strain"):
        make_results(**kw)
    kw = _inputs()
    kw["frame_ok"] = kw["frame_ok"].astype(int)
    with pytest.raises(TypeError, match="frame_ok"):
        make_results(**kw)
    kw = _inputs()
    kw["time_s"] = kw["time_s"][::-1]
    with pytest.raises(ValueError, match="time_s"):
        make_results(**kw)
    kw = _inputs()
    kw["attrs"] = _attrs(rig_json="{not json")
    with pytest.raises(ValueError, match="rig_json"):
        make_results(**kw)
    kw = _inputs()
    kw["attrs"] = _attrs(calibration=None)
    with pytest.raises(TypeError, match="calibration"):
        make_results(**kw)
    kw = _inputs()
    kw["station_m"] = np.array([0.1])
    with pytest.raises(ValueError, match="together"):
        make_results(**kw)


def test_reading_a_file_that_is_not_results_names_it(tmp_path: Path) -> None:
    junk = tmp_path / "junk.nc"
    junk.write_bytes(b"this is not HDF5 at all")
    with pytest.raises(ValueError, match=r"junk\.nc"):
        read_results(junk)
    other = tmp_path / "other.nc"
    xr.Dataset({"x": ("t", np.arange(3.0))}).to_netcdf(other, engine="h5netcdf")
    with pytest.raises(ValueError, match=r"other\.nc.*not a beambench results file"):
        read_results(other)
    with pytest.raises(FileNotFoundError, match=r"missing\.nc"):
        read_results(tmp_path / "missing.nc")


def test_a_failed_write_does_not_clobber_the_existing_file(tmp_path: Path) -> None:
    path = tmp_path / "r.nc"
    path.write_bytes(b"previous results")
    ds = make_results(**_inputs())
    ds.attrs["unstorable"] = {1, 2, 3}  # a set: NetCDF cannot hold it
    with pytest.raises(TypeError):
        write_results(ds, path)
    assert path.read_bytes() == b"previous results"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.nc"]
    # A variable of object dtype fails inside the NetCDF writer, after the temp file exists.
    ds = make_results(**_inputs())
    ds["bad"] = ("time", np.array([object()] * N, dtype=object))
    with pytest.raises((TypeError, ValueError)):
        write_results(ds, path)
    assert path.read_bytes() == b"previous results"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.nc"]


def test_steady_state_window_is_the_last_three_crank_cycles() -> None:
    kw = _inputs()
    kw["time_s"] = np.arange(N) / 100.0  # 8 s at 100 Hz
    ds = make_results(**kw)
    t = ds["time"].values
    mask = steady_state_mask(ds)
    period = 1 / 0.92  # the rig's crank frequency
    assert t[mask][0] == pytest.approx(t[-1] - 3 * period, abs=0.01)
    assert mask[-1] and mask.sum() == np.count_nonzero(t >= t[-1] - 3 * period)
    assert steady_state_mask(ds, cycles=8).all()  # longer than the run: all of it
    rig = json.loads(ds.attrs["rig_json"])
    del rig["linkage"]
    ds.attrs["rig_json"] = json.dumps(rig)
    assert steady_state_mask(ds).all()  # period unknown: all of it
    with pytest.raises(ValueError, match="cycles"):
        steady_state_mask(ds, cycles=0)


def test_the_simulation_start_up_transient_is_left_out_of_the_comparison() -> None:
    kw = _inputs(failed=())
    t = kw["time_s"]
    # The simulation starts from rest: a big error in its first 0.5 s only.
    transient = np.where(t < 0.5, 0.05, 0.0)
    kw["sim_tip_lateral_m"] = kw["sim_tip_lateral_m"] - transient
    kw["sim_strain"] = kw["sim_strain"] - 1e-3 * transient[:, None]
    kw["attrs"] = _attrs(settle_time_s=0.5)
    ds = make_results(**kw)
    e = summarise_errors(ds)
    assert e["sim_compared_from_s"] == 0.5
    assert e["tip_lateral_image_vs_sim_max_m"] == pytest.approx(IMAGE_ERR_M, rel=1e-9)
    assert e["tip_lateral_strain_vs_sim_max_m"] == pytest.approx(STRAIN_TIP_ERR_M, rel=1e-9)
    np.testing.assert_allclose(e["strain_vs_sim_max"], np.abs(STRAIN_ERR), rtol=1e-9)
    n_late = int(np.count_nonzero(ds["frame_time"].values >= 0.5))
    assert e["n_frames_compared"] == n_late < ds.sizes["frame_time"]
    # Strain-based against images does not involve the simulation: every frame counts.
    ds.attrs["settle_time_s"] = 0.0
    e0 = summarise_errors(ds)
    assert e0["tip_lateral_strain_vs_image_rms_m"] == e["tip_lateral_strain_vs_image_rms_m"]
    assert e0["tip_lateral_image_vs_sim_max_m"] == pytest.approx(0.05 + IMAGE_ERR_M, rel=1e-6)


def test_each_image_measurement_has_its_standard_uncertainty_beside_it(tmp_path: Path) -> None:
    kw = _inputs(failed=(3,))
    nf = len(kw["frame_ok"])
    kw["hub_angle_image_sd_rad"] = np.full(nf, 3e-5)
    kw["tip_lateral_sd_m"] = np.full(nf, 4e-5)
    kw["tip_longitudinal_sd_m"] = np.full(nf, 5e-5)
    ds = make_results(**kw)
    for name, units, value in (
        ("hub_angle_image_sd", "rad", 3e-5),
        ("tip_lateral_sd", "m", 4e-5),
        ("tip_longitudinal_sd", "m", 5e-5),
    ):
        assert ds[name].dims == ("frame_time",) and ds[name].attrs["units"] == units
        assert "standard uncertainty" in ds[name].attrs["long_name"]
        assert np.isnan(ds[name].values[3])  # the failed frame states none
        assert np.all(np.delete(ds[name].values, 3) == value)
    write_results(ds, tmp_path / "r.nc")
    back = read_results(tmp_path / "r.nc")
    assert back["tip_longitudinal_sd"].attrs["units"] == "m"
    np.testing.assert_array_equal(back["tip_lateral_sd"].values, ds["tip_lateral_sd"].values)
    kw["tip_lateral_sd_m"] = np.full(nf, -1e-5)
    with pytest.raises(ValueError, match="tip_lateral_sd_m must not be negative"):
        make_results(**kw)
