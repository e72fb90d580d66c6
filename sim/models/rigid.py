"""The rigid beam: zero deflection and zero strain on the prescribed hub motion.

The baseline every flexible model is compared with.
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sim.beam import BeamProperties
from sim.checks import check_simulation_inputs
from sim.drives import Drive
from sim.result import SimResult

FloatArray = NDArray[np.float64]


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
