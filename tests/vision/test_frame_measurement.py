from __future__ import annotations

import json
import math

import numpy as np

from vision.frame_measurement import FrameMeasurement


def test_a_failed_frame_is_nan_and_its_summary_is_json_with_nulls() -> None:
    m = FrameMeasurement(
        ok=False,
        reason="blank frame (no contrast)",
        stations_m=np.array([0.2, 0.4]),
        lateral_at_stations_m=np.full(2, np.nan),
    )
    assert math.isnan(m.hub_angle_rad) and np.all(np.isnan(m.clamp_plane_m))
    d = json.loads(json.dumps(m.to_dict(), allow_nan=False))
    assert d["ok"] is False and d["reason"] == "blank frame (no contrast)"
    assert d["tip_lateral_m"] is None and d["lateral_at_stations_m"] == [None, None]
    assert d["stations_m"] == [0.2, 0.4]


def test_defaults_are_not_shared_between_records() -> None:
    a, b = FrameMeasurement(ok=False), FrameMeasurement(ok=False)
    assert a.clamp_plane_m is not b.clamp_plane_m


def test_the_summary_carries_each_uncertainty_beside_its_value() -> None:
    m = FrameMeasurement(
        ok=True,
        hub_angle_rad=4.5,
        tip_lateral_m=0.01,
        hub_angle_std_rad=2e-4,
        tip_lateral_std_m=3e-5,
    )
    d = json.loads(json.dumps(m.to_dict(), allow_nan=False))
    assert d["hub_angle_sd_rad"] == 2e-4 and d["tip_lateral_sd_m"] == 3e-5
    assert FrameMeasurement(ok=False).to_dict()["tip_lateral_sd_m"] is None
