"""SimResult's row operations: a held start and a subset of times."""

from __future__ import annotations

import numpy as np
import pytest

from sim.beam import BeamProperties
from sim.config import BeamConfig
from sim.drives import FixedDrive
from sim.models.modal import simulate_modal


def test_a_held_start_repeats_the_first_state_and_rows_select() -> None:
    beam = BeamProperties.from_config(BeamConfig())
    t = np.linspace(1.0, 2.0, 11)
    res = simulate_modal(
        beam, FixedDrive(0.3), t, n_modes=2, initial_q=[0.01, 0.0], gauge_positions_m=[0.2]
    )
    held = res.held_before([0.0, 0.5])
    assert held.time_s.tolist() == [0.0, 0.5, *t.tolist()]
    for name in ("tip_lateral_m", "strain", "station_lateral_m"):
        got = getattr(held, name)
        np.testing.assert_array_equal(got[:2], np.repeat(getattr(res, name)[:1], 2, axis=0))
        np.testing.assert_array_equal(got[2:], getattr(res, name))
    back = held.rows(slice(2, None))
    np.testing.assert_array_equal(back.strain, res.strain)
    assert back.model == res.model
    with pytest.raises(ValueError, match="earlier"):
        res.held_before([1.5])
