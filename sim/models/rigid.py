"""The rigid beam: zero deflection and zero strain on the prescribed hub motion.

The baseline every flexible model is compared with; also the input checks shared by the
beam models.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sim.beam import BeamProperties
from sim.drives import Drive
from sim.result import SimResult

FloatArray = NDArray[np.float64]


def check_simulation_inputs(
    beam: object,
    drive: object,
    t_eval_s: ArrayLike,
    gauge_positions_m: Sequence[float] | ArrayLike,
    n_stations: int,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Validate the arguments every beam model takes.

    Returns
    -------
    t : (N,) output times (s); gauges : (G,) gauge positions (m); stations : (S,) station
    positions from the clamp, 0 and L included (m).
    """
    if not isinstance(beam, BeamProperties):
        raise TypeError(f"beam must be a sim.beam.BeamProperties, got {type(beam).__name__}")
    if not isinstance(drive, Drive):
        raise TypeError(
            f"drive must implement the sim.drives.Drive protocol (angle, rate, accel), "
            f"got {type(drive).__name__}"
        )
    t = np.asarray(t_eval_s, dtype=float)
    if t.ndim != 1 or t.size < 1:
        raise ValueError(f"t_eval_s must be a non-empty 1-D array, got shape {t.shape}")
    if not np.all(np.isfinite(t)):
        raise ValueError("t_eval_s must be finite")
    if t.size > 1 and np.any(np.diff(t) <= 0.0):
        raise ValueError("t_eval_s must be strictly increasing")
    gauges = np.atleast_1d(np.asarray(gauge_positions_m, dtype=float)).reshape(-1)
    if np.any(~np.isfinite(gauges)) or np.any(gauges < 0.0) or np.any(gauges > beam.length_m):
        raise ValueError(
            f"gauge_positions_m must lie on the beam, within [0, {beam.length_m!r}] m, "
            f"got {gauges.tolist()}"
        )
    if isinstance(n_stations, bool) or not isinstance(n_stations, int | np.integer):
        raise TypeError(f"n_stations must be an integer, got {type(n_stations).__name__}")
    if n_stations < 2:
        raise ValueError(f"n_stations must be at least 2 (clamp and tip), got {n_stations!r}")
    stations = np.linspace(0.0, beam.length_m, int(n_stations))
    return t, gauges, stations


def check_non_negative(name: str, value: float) -> float:
    v = float(value)
    if not math.isfinite(v) or v < 0.0:
        raise ValueError(f"{name} must be a non-negative finite number, got {value!r}")
    return v


def simulate_rigid(
    beam: BeamProperties,
    drive: Drive,
    t_eval_s: ArrayLike,
    *,
    gauge_positions_m: Sequence[float] | ArrayLike = (),
    n_stations: int = 21,
) -> SimResult:
    """The rigid beam on the prescribed hub: zero deflection and strain, exactly.

    Parameters
    ----------
    beam : the beam (only its length is used).
    drive : prescribed hub angle.
    t_eval_s : (N,) output times, s.
    gauge_positions_m : (G,) gauge distances from the clamp, m.
    n_stations : number of equally spaced shape stations (clamp and tip included).
    """
    t, gauges, stations = check_simulation_inputs(
        beam, drive, t_eval_s, gauge_positions_m, n_stations
    )
    start = time.perf_counter()
    angle = np.asarray(drive.angle(t), dtype=float).reshape(t.shape)
    zeros = np.zeros_like(t)
    wall = time.perf_counter() - start
    return SimResult(
        time_s=t,
        hub_angle_rad=angle,
        tip_lateral_m=zeros,
        tip_longitudinal_m=zeros.copy(),
        stations_m=stations,
        station_lateral_m=np.zeros((t.size, stations.size)),
        station_longitudinal_m=np.zeros((t.size, stations.size)),
        gauge_positions_m=gauges,
        strain=np.zeros((t.size, gauges.size)),
        model="rigid",
        wall_time_s=wall,
        settings={},
    )
