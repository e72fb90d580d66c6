"""A simulation on its own as a dataset: the rig under the same attribute name as a
processed run's results (``rig_json``), the old ``rig`` kept beside it."""

from __future__ import annotations

import json

import numpy as np

from pipelines.results.sim_dataset import sim_dataset
from pipelines.rig import Rig
from sim.result import SimResult


def test_the_rig_is_recorded_as_rig_json_like_the_results_file() -> None:
    t = np.linspace(0.0, 1.0, 5)
    zeros = np.zeros_like(t)
    result = SimResult(
        time_s=t,
        hub_angle_rad=zeros,
        tip_lateral_m=zeros,
        tip_longitudinal_m=zeros,
        stations_m=np.array([0.4]),
        station_lateral_m=np.zeros((t.size, 1)),
        station_longitudinal_m=np.zeros((t.size, 1)),
        gauge_positions_m=np.array([0.005, 0.204]),
        strain=np.zeros((t.size, 2)),
        model="rigid",
        wall_time_s=0.0,
        settings={"rtol": 1e-6, "atol": 1e-9},
    )
    rig_json = Rig().to_json()
    ds = sim_dataset(result, scene="reciprocating", rig_json=rig_json)
    assert ds.attrs["rig_json"] == ds.attrs["rig"] == rig_json
    assert json.loads(ds.attrs["rig_json"])["beam"]["length_m"] == 0.835
