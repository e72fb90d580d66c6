"""A sweep point the simulator refuses is recorded (NaN values and its error) and the
sweep carries on; the exit status says points failed."""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from sim.config import MAX_CRANK_HZ

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[3]
BIN = Path(sys.executable).parent


def test_a_refused_point_is_recorded_and_the_sweep_carries_on(tmp_path: Path) -> None:
    out = tmp_path / "sweep.nc"
    bad_hz = MAX_CRANK_HZ + 1.0  # beyond what the bench model accepts for a motor
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    cmd = [str(BIN / "beambench"), "sweep", "reciprocating", "--out", str(out)]
    cmd += ["--crank-hz", f"1.7:{bad_hz}:2", "--a1", "0.004,0.008", "--workers", "2"]
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 1, proc.stderr
    assert "(2 x 2 points, 2 failed)" in proc.stdout
    err = proc.stderr.splitlines()
    assert len(err) == 2 and "Traceback" not in proc.stderr
    for line, a1 in zip(err, ("0.004", "0.008"), strict=True):
        assert line.startswith(f"failed: crank {bad_hz:.4g} Hz, a1 {a1} s: ")
        assert "crank_frequency_hz" in line and f"{MAX_CRANK_HZ:g} Hz" in line
    with xr.open_dataset(out, engine="h5netcdf") as opened:
        ds = opened.load()
    assert ds.attrs["points_failed"] == 2
    good, bad = ds.isel(crank_hz=0), ds.isel(crank_hz=1)
    assert float(good["crank_hz"]) == pytest.approx(1.7)
    assert list(good["error"].values) == ["", ""]
    assert all("crank_frequency_hz" in str(e) for e in bad["error"].values)
    for name in ("tip_lateral_amplitude_m", "tip_lateral_phase_lag_rad", "strain_amplitude"):
        assert np.all(np.isfinite(good[name].values)), name
        assert np.all(np.isnan(bad[name].values)), name
    # more damping, less response at the same drive: the good points are real solutions
    amp = good["tip_lateral_amplitude_m"].values
    assert amp[0] > amp[1] > 0 and not math.isclose(amp[0], amp[1])
