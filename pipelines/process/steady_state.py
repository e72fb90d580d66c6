"""A run driven periodically is simulated to its periodic steady state, not to its end.

When the measured hub angle is fitted by harmonics of the crank alone
(:class:`sim.trace_fit.FittedTraceDrive`, ``kind == "harmonics"``), the drive repeats
exactly every crank period P, and the damped beam settles onto a response that repeats
with it: the start-up transient decays (on the bench the slowest part, the overdamped first
mode, as exp(-12.5 t)), and what follows is a copy of one cycle. So the beam is simulated
from the run's start to ``settle_s`` plus a few periods, until its last period matches the
one before within the tolerance, and every later output time takes the value at the same
crank phase in that last period. On the demo's 20 s that simulates 4.3 s; on a bench
minute, 4.3 s instead of 60 (the exact FE beam then costs less than the modal model did on
the whole run).

The difference between the last two simulated periods (the transient left) is recorded and
added to the simulation's error estimate.

The later output times fall at every crank phase (the DAQ's 2.5 ms and the period share
no multiple), so simulating each phase meant sampling the solver's output ~23,000 times a
bench minute inside one period: half the simulation's cost. The last period is instead
simulated on a uniform grid :data:`GRID_PER_SAMPLE` times finer than the run's samples, and
the later times take a cubic spline through it. Its error is estimated from the spline
through every other grid point, at the points left out (twice the spacing: for the h^4
interpolation error, about 16 times the spline's own): on a bench minute 5e-8 of the
largest tip deflection at the stations, 4e-6 of each gauge's largest strain (the spline's
own, checked against the exact phases: 2e-8 and 3e-6, the solver's dense output's own
roughness at rtol 2e-6). The estimate is recorded (``interpolation_rel``: deflections,
``interpolation_strain_rel``: strains, each gauge's relative to its largest) and added to
the simulation's error estimate; above :data:`INTERPOLATION_SHARE` of the tolerance the
later phases are simulated one by one, as before.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np
from scipy.interpolate import CubicSpline

from sim.result import SimResult

# Periods simulated after the settling time, first try; doubled while the last two
# differ by more than the tolerance.
FIRST_PERIODS = 2
# Grid points of the last simulated period per sample interval of the run.
GRID_PER_SAMPLE = 2
# The later times are interpolated when the interpolation's estimated error is at most
# this share of the tolerance (added in quadrature: +0.5 % of it); else simulated.
INTERPOLATION_SHARE = 0.1


def cycle_change_rel(res: SimResult, last: np.ndarray, before: np.ndarray) -> float:
    """Largest change of any station's deflection (tip included) between the output rows
    ``last`` and ``before`` (one period earlier), relative to the largest tip deflection."""
    scale = max(float(np.max(np.abs(res.tip_lateral_m))), 1e-300)
    d_tip = np.abs(res.tip_lateral_m[last] - res.tip_lateral_m[before])
    d_st = np.abs(res.station_lateral_m[last] - res.station_lateral_m[before])
    return float(max(np.max(d_tip, initial=0.0), np.max(d_st, initial=0.0)) / scale)


def simulate_steady(
    run: Callable[[np.ndarray], SimResult],
    t_s: np.ndarray,
    period_s: float,
    settle_s: float,
    tol_rel: float,
) -> SimResult | None:
    """The simulation at ``t_s`` by ``run`` (a function of the output times, from rest at
    ``t_s[0]``) over its settling and a few periods, later times interpolated in its last
    period (simulated at each when the interpolation's error is not small enough); None
    when the run is too short for that to save anything.

    ``tol_rel``: the largest change between the last two simulated periods (relative to
    the largest tip deflection) accepted as steady."""
    t = np.asarray(t_s, dtype=float)
    t0, t_end = float(t[0]), float(t[-1])
    if not (math.isfinite(period_s) and period_s > 0):
        return None
    # the grid over the last period: an even number of intervals (the estimate leaves out
    # every other point), each at most 1/GRID_PER_SAMPLE of the run's median sample interval
    step = float(np.median(np.diff(t))) / GRID_PER_SAMPLE if t.size > 1 else math.nan
    n_grid = math.ceil(period_s / step) if math.isfinite(step) and step > 0 else 0
    n_grid += n_grid % 2
    interpolate = 2 <= n_grid <= 4 * t.size
    n_periods = FIRST_PERIODS
    while True:
        horizon = t0 + settle_s + n_periods * period_s
        if horizon + period_s >= t_end:
            return None  # as long as the run itself
        direct = t[t <= horizon]
        later = t[t > horizon]
        start = horizon - period_s  # the last simulated period is [start, horizon]
        copied = start + np.mod(later - start, period_s)
        grid = start + period_s * np.arange(n_grid + 1) / max(n_grid, 1)
        in_last = direct[direct >= start]
        check = in_last - period_s
        want = np.concatenate([direct, check, grid if interpolate else copied])
        times, inverse = np.unique(want, return_inverse=True)
        res = run(times)
        n_d = direct.size
        last_rows = inverse[n_d - in_last.size : n_d]
        before_rows = inverse[n_d : n_d + check.size]
        change = cycle_change_rel(res, last_rows, before_rows)
        if change <= tol_rel:
            break
        n_periods *= 2
    extra: dict[str, float] = {}
    if interpolate:
        grid_rows = inverse[n_d + check.size :]
        errors = _interpolation_errors(res, grid_rows, grid)
        if max(errors.values()) <= INTERPOLATION_SHARE * tol_rel:
            out = _direct_and_interpolated(res, inverse[:n_d], grid_rows, grid, copied, t)
            extra = errors
        else:  # the later phases simulated one by one
            return _simulated_at_each_phase(run, t, direct, copied, check, period_s, change)
    else:
        out = res.rows(inverse[: n_d + copied.size])
    return _at_run_times(out, res, t, times, period_s, change, extra)


def _simulated_at_each_phase(
    run: Callable[[np.ndarray], SimResult],
    t: np.ndarray,
    direct: np.ndarray,
    copied: np.ndarray,
    check: np.ndarray,
    period_s: float,
    change: float,
) -> SimResult:
    """The run simulated at ``direct``, at each later time's phase ``copied`` and at the
    steadiness check's times (the horizon found steady already)."""
    want = np.concatenate([direct, copied, check])
    times, inverse = np.unique(want, return_inverse=True)
    res = run(times)
    out = res.rows(inverse[: direct.size + copied.size])
    return _at_run_times(out, res, t, times, period_s, change, {})


def _at_run_times(
    out: SimResult,
    res: SimResult,
    t: np.ndarray,
    times: np.ndarray,
    period_s: float,
    change: float,
    extra: dict[str, float],
) -> SimResult:
    """``out`` (the rows of ``res``, simulated at ``times``, for the run's times ``t``)
    at those times, with the steady state's settings (``extra``: the interpolation's)."""
    settings = {
        **res.settings,
        "steady_state": {
            "period_s": period_s,
            "simulated_s": float(times[-1] - times[0]),
            "cycle_change_rel": change,
            **extra,
        },
    }
    return replace(out, time_s=t.copy(), hub_angle_rad=out.hub_angle_rad, settings=settings)


# the fields interpolated in the last period, and what each error is relative to
_DEFLECTIONS = (
    "tip_lateral_m",
    "tip_longitudinal_m",
    "station_lateral_m",
    "station_longitudinal_m",
)


def _interpolation_errors(
    res: SimResult, grid_rows: np.ndarray, grid: np.ndarray
) -> dict[str, float]:
    """The largest error of the cubic spline through every other grid point at the
    points left out: the deflections' relative to the largest tip deflection, the hub
    angle's to its largest, each gauge's strain to its largest."""
    scale = max(float(np.max(np.abs(res.tip_lateral_m))), 1e-300)

    def miss(values: np.ndarray) -> np.ndarray:
        v = values[grid_rows]
        return np.abs(CubicSpline(grid[::2], v[::2], axis=0)(grid[1::2]) - v[1::2])

    deflection = max(float(np.max(miss(getattr(res, k)))) for k in _DEFLECTIONS) / scale
    hub = float(np.max(miss(res.hub_angle_rad)))
    hub /= max(float(np.max(np.abs(res.hub_angle_rad))), 1e-300)
    strain = 0.0
    if res.strain.shape[1]:
        gauge_scale = np.maximum(np.max(np.abs(res.strain), axis=0), 1e-300)
        strain = float(np.max(np.max(miss(res.strain), axis=0) / gauge_scale))
    return {
        "interpolation_rel": max(deflection, hub),
        "interpolation_strain_rel": strain,
    }


def _direct_and_interpolated(
    res: SimResult,
    direct_rows: np.ndarray,
    grid_rows: np.ndarray,
    grid: np.ndarray,
    copied: np.ndarray,
    t: np.ndarray,
) -> SimResult:
    """The result at the simulated rows ``direct_rows``, then at the phases ``copied``
    by a cubic spline through the grid's rows (the output times ``t``, in order)."""
    new: dict[str, Any] = {}
    for k in ("hub_angle_rad", "strain", *_DEFLECTIONS):
        v = getattr(res, k)
        later = CubicSpline(grid, v[grid_rows], axis=0)(copied)
        new[k] = np.concatenate([v[direct_rows], later.reshape((copied.size, *v.shape[1:]))])
    return replace(res, time_s=t.copy(), **new)
