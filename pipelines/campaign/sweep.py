"""Simulator sweeps as Dask tasks: the bench driven by the true four-bar output at each
crank frequency (and each a1), the steady-state crank fundamental of the tip and of the
gauges' strains per point, gathered into one Dataset with dims ``(crank_hz, a1)``.

Each point starts from rest and is simulated for ``settle_s`` plus ``periods`` crank
periods; the fits use the part after ``settle_s`` and give amplitudes and phase lags
behind the hub angle, like the campaign catalogue's (:mod:`pipelines.campaign.summary`),
so a sweep overlays the measured runs directly.

A point that fails (a crank frequency the bench model refuses, a solver that gives up)
has NaN values and its error text in the ``error`` variable; the other points carry on.
"""

from __future__ import annotations

import dataclasses
import math
import uuid
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import xarray as xr

from pipelines import __version__
from pipelines.campaign.harmonics import fit_fundamental, phase_lag
from pipelines.errors import BeambenchError
from pipelines.rig import Rig

SETTLE_S = 3.0
PERIODS = 4


def point_duration_s(crank_hz: float, settle_s: float = SETTLE_S, periods: int = PERIODS) -> float:
    """Simulated time of one point: the settling and the fitted crank periods."""
    return settle_s + periods / crank_hz


@dataclass(frozen=True)
class SweepPoint:
    crank_hz: float
    a1_s: float
    a0_per_s: float
    damping_law: str
    model: str
    sim_tol: float
    settle_s: float = SETTLE_S
    periods: int = PERIODS


def parse_range(text: str, option: str = "--crank-hz") -> np.ndarray:
    """``START:STOP:N`` -> N values from START to STOP inclusive (``START`` alone: one)."""
    parts = text.split(":")
    try:
        if len(parts) == 1:
            values = np.array([float(parts[0])])
        elif len(parts) == 3:
            values = np.linspace(float(parts[0]), float(parts[1]), int(parts[2]))
        else:
            raise ValueError("expected START:STOP:N")
    except ValueError as exc:
        raise BeambenchError(f"{option} {text!r}: {exc} (expected START:STOP:N)") from None
    if values.size < 1 or not np.all(np.isfinite(values)) or np.any(values <= 0):
        raise BeambenchError(f"{option} {text!r}: values must be positive and finite, N >= 1")
    return values


def parse_list(text: str, option: str) -> np.ndarray:
    """``0.05,0.1,0.2`` -> the values (non-negative, finite, distinct)."""
    try:
        values = np.array([float(v) for v in text.split(",") if v.strip()])
    except ValueError:
        raise BeambenchError(f"{option} {text!r}: expected numbers separated by commas") from None
    if values.size == 0 or not np.all(np.isfinite(values)) or np.any(values < 0):
        raise BeambenchError(f"{option} {text!r}: values must be non-negative and finite")
    if np.unique(values).size != values.size:
        raise BeambenchError(f"{option} {text!r}: values repeat")
    return values


def simulate_point(rig: Rig, point: SweepPoint) -> dict[str, Any]:
    """One point: the steady crank fundamental of the hub, the tip and the strains, or
    ``{"error": why}`` when the simulator refuses the point or fails on it."""
    from pipelines.blas_threads import limit_blas_threads
    from sim.errors import SimError

    limit_blas_threads()
    try:
        return _simulate(rig, point)
    except (SimError, BeambenchError) as exc:
        return {"error": str(exc)}


def _simulate(rig: Rig, point: SweepPoint) -> dict[str, Any]:
    from sim import scenes

    linkage = dataclasses.replace(rig.linkage, crank_frequency_hz=point.crank_hz)
    duration_s = point_duration_s(point.crank_hz, point.settle_s, point.periods)
    run = scenes.reciprocating(
        linkage,
        rig.beam,
        rig.drive,
        drive="fourbar",
        a0_per_s=point.a0_per_s,
        a1_s=point.a1_s,
        duration_s=duration_s,
        model=point.model,
        gauge_positions_m=tuple(rig.gauges.positions_m),
        rtol=point.sim_tol,
        damping_law=point.damping_law,
    )
    res = run.result
    t = res.time_s
    keep = t >= point.settle_s
    f = point.crank_hz
    hub = fit_fundamental(t[keep], res.hub_angle_rad[keep], f)
    tip = fit_fundamental(t[keep], res.tip_lateral_m[keep], f)
    out: dict[str, Any] = {
        "hub_amplitude_rad": hub.amplitude,
        "tip_lateral_amplitude_m": tip.amplitude,
        "tip_lateral_phase_lag_rad": phase_lag(tip, hub)[0],
        "strain_amplitude": [],
        "strain_phase_lag_rad": [],
        "model": res.model,
        "wall_time_s": res.wall_time_s,
    }
    for g in range(res.strain.shape[1]):
        fit = fit_fundamental(t[keep], res.strain[keep, g], f)
        out["strain_amplitude"].append(fit.amplitude)
        out["strain_phase_lag_rad"].append(phase_lag(fit, hub)[0])
    return out


def run_sweep(
    rig: Rig,
    crank_hz: Sequence[float],
    a1_s: Sequence[float],
    client: Any,
    *,
    damping_law: str,
    model: str,
    sim_tol: float,
    report: Callable[[str], None] = print,
) -> xr.Dataset:
    """Every (crank_hz, a1) point as one task on ``client``; the gathered Dataset (a
    failed point: NaN values and its ``error``)."""
    from pipelines.campaign.cluster import completed, outcome_of

    points = {
        (i, j): SweepPoint(float(f), float(a1), rig.damping.a0_per_s, damping_law, model, sim_tol)
        for i, f in enumerate(crank_hz)
        for j, a1 in enumerate(a1_s)
    }
    shape = (len(crank_hz), len(a1_s))
    n_g = len(rig.gauges.positions_m)
    arrays = {
        "hub_amplitude_rad": np.full(shape, math.nan),
        "tip_lateral_amplitude_m": np.full(shape, math.nan),
        "tip_lateral_phase_lag_rad": np.full(shape, math.nan),
        "strain_amplitude": np.full((*shape, n_g), math.nan),
        "strain_phase_lag_rad": np.full((*shape, n_g), math.nan),
        "wall_time_s": np.full(shape, math.nan),
    }
    errors = np.full(shape, "", dtype=object)
    models: set[str] = set()
    tag = uuid.uuid4().hex
    with client.as_current():
        futures = {
            client.submit(simulate_point, rig, p, key=f"sweep-{i}-{j}-{tag}"): (i, j)
            for (i, j), p in points.items()
        }
        for k, future in enumerate(completed(client, futures), start=1):
            i, j = futures[future]
            p = points[(i, j)]
            where = f"[{k}/{len(points)}] crank {p.crank_hz:.4g} Hz, a1 {p.a1_s:.4g} s"
            r, exc = outcome_of(client, future)
            future.release()
            if exc is not None:
                errors[i, j] = f"{type(exc).__name__}: {exc}"
            elif "error" in r:
                errors[i, j] = str(r["error"])
            if errors[i, j]:
                report(f"{where}: FAILED: {errors[i, j].splitlines()[0]}")
                continue
            for name, arr in arrays.items():
                arr[i, j] = r[name]
            models.add(str(r["model"]))
            report(
                f"{where}: tip {r['tip_lateral_amplitude_m'] * 1e3:.3f} mm, lag "
                f"{math.degrees(r['tip_lateral_phase_lag_rad']):.2f} deg ({r['model']})"
            )
    ds = _dataset(rig, crank_hz, a1_s, arrays, models, damping_law, sim_tol)
    ds["error"] = (
        ("crank_hz", "a1"),
        errors,
        {"long_name": "why the point failed (empty when it did not; its values are NaN)"},
    )
    ds.attrs["points_failed"] = int(np.count_nonzero(errors != ""))
    return ds


def failed_points(ds: xr.Dataset) -> list[str]:
    """One line per failed point of a sweep Dataset: where and why."""
    if "error" not in ds:
        return []
    lines = []
    for i, f in enumerate(ds["crank_hz"].values):
        for j, a1 in enumerate(ds["a1"].values):
            err = str(ds["error"].values[i, j])
            if err:
                lines.append(f"crank {f:.4g} Hz, a1 {a1:.4g} s: {err.splitlines()[0]}")
    return lines


_UNITS = {
    "hub_amplitude_rad": ("rad", "hub angle, amplitude of the crank fundamental"),
    "tip_lateral_amplitude_m": ("m", "tip lateral deflection, amplitude of the crank fundamental"),
    "tip_lateral_phase_lag_rad": (
        "rad",
        "tip lateral deflection: phase lag of the crank fundamental behind the hub angle's",
    ),
    "strain_amplitude": ("1", "surface strain at the gauge, amplitude of the crank fundamental"),
    "strain_phase_lag_rad": (
        "rad",
        "strain at the gauge: phase lag of the crank fundamental behind the hub angle's",
    ),
    "wall_time_s": ("s", "the point's solve time"),
}


def _dataset(
    rig: Rig,
    crank_hz: Sequence[float],
    a1_s: Sequence[float],
    arrays: dict[str, np.ndarray],
    models: set[str],
    damping_law: str,
    sim_tol: float,
) -> xr.Dataset:
    data = {}
    for name, arr in arrays.items():
        dims = ("crank_hz", "a1") if arr.ndim == 2 else ("crank_hz", "a1", "gauge")
        units, long_name = _UNITS[name]
        data[name] = (dims, arr, {"units": units, "long_name": long_name})
    return xr.Dataset(
        data,
        coords={
            "crank_hz": ("crank_hz", np.asarray(crank_hz, float), {"units": "Hz"}),
            "a1": ("a1", np.asarray(a1_s, float), {"units": "s", "long_name": "damping a1"}),
            "gauge": (
                "gauge",
                np.asarray(rig.gauges.positions_m, float),
                {"units": "m", "long_name": "gauge position from the clamp"},
            ),
        },
        attrs={
            "title": "beambench sweep: reciprocating, four-bar drive",
            "scene": "reciprocating",
            "drive": "fourbar",
            "a0_per_s": rig.damping.a0_per_s,
            "damping_law": damping_law,
            "sim_model": ",".join(sorted(models)),
            "sim_tol": sim_tol,
            "settle_s": SETTLE_S,
            "periods": PERIODS,
            "rig_json": rig.to_json(),
            "software_version": __version__,
        },
    )
