"""Make the sample run and its expected processed numbers.

    .venv/bin/python sample_data/make_sample.py

Captures 6 s of the built-in synthetic bench (default rig, JPEG quality 75 so the log stays
under 10 MB) into ``sample_data/run-6s.mcap``, processes it with the default settings and
writes the numbers ``tests/pipelines/test_sample_data.py`` checks into
``sample_data/expected.json``, beside what the synthetic truth says they should be.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np

from pipelines.demo import capture_synthetic
from pipelines.process.run import process_run
from pipelines.rig import load_rig

HERE = Path(__file__).resolve().parent
DURATION_S = 6.0


def expected_numbers(ds: object) -> dict[str, float | int | str]:
    """The regression numbers of a processed sample run."""
    import xarray as xr

    assert isinstance(ds, xr.Dataset)
    a = ds.attrs
    ok = ds["frame_ok"].values.astype(bool)
    out: dict[str, float | int | str] = {
        "frames_total": int(a["frames_total"]),
        "frames_failed": int(a["frames_failed"]),
        "daq_samples": int(ds.sizes["time"]),
        "sim_model": str(a["sim_model"]),
        "camera_to_daq_offset_s": float(a["camera_to_daq_offset_s"]),
        "tip_lateral_image_peak_m": float(np.nanmax(np.abs(ds["tip_lateral"].values[ok]))),
        "tip_lateral_strain_peak_m": float(np.max(np.abs(ds["tip_lateral_strain"].values))),
        "rocker_angle_range_rad": float(np.ptp(ds["rocker_angle"].values)),
    }
    for k, v in a.items():
        if k.endswith(("_rms_m", "_max_m")) and isinstance(v, float) and math.isfinite(v):
            out[k] = v
    return out


def main() -> None:
    rig = load_rig()
    rig = dataclasses.replace(rig, camera=dataclasses.replace(rig.camera, jpeg_quality=75))
    log_path = HERE / "run-6s.mcap"
    devices = capture_synthetic(rig, log_path, DURATION_S)
    processed = process_run(log_path)
    numbers = expected_numbers(processed.results)
    # the truth the synthetic bench was made with
    numbers["truth_camera_clock_offset_s"] = 0.0123
    numbers["truth_tip_lateral_peak_m"] = float(
        np.max(np.abs(devices.bench.truth.tip_lateral_m(np.linspace(0, DURATION_S, 3001))))
    )
    (HERE / "expected.json").write_text(json.dumps(numbers, indent=2) + "\n")
    size_mb = log_path.stat().st_size / 1e6
    print(f"{log_path.name}: {size_mb:.1f} MB; expected.json written")


if __name__ == "__main__":
    main()
