"""Regression: the shipped sample run processes to the numbers recorded with it.

``sample_data/make_sample.py`` made the run and ``expected.json``; if processing changes
on purpose, rerun it and say why in the commit.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SAMPLE = ROOT / "sample_data"


@pytest.fixture(scope="module")
def expected() -> dict[str, float | int | str]:
    data: dict[str, float | int | str] = json.loads((SAMPLE / "expected.json").read_text())
    return data


def test_the_sample_is_small_enough_to_ship() -> None:
    assert (SAMPLE / "run-6s.mcap").stat().st_size < 10e6


@pytest.mark.slow
def test_the_sample_run_processes_to_its_expected_numbers(
    expected: dict[str, float | int | str],
) -> None:
    import importlib.util

    from pipelines.process.run import process_run

    spec = importlib.util.spec_from_file_location("make_sample", SAMPLE / "make_sample.py")
    assert spec is not None and spec.loader is not None
    make_sample = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(make_sample)

    got = make_sample.expected_numbers(process_run(SAMPLE / "run-6s.mcap", workers=2).results)
    for key in ("frames_total", "frames_failed", "daq_samples", "sim_model"):
        assert got[key] == expected[key], key
    # the offset is fitted to ~20 us (the camera's jitter)
    assert got["camera_to_daq_offset_s"] == pytest.approx(
        expected["camera_to_daq_offset_s"], abs=2e-5
    )
    assert got["rocker_angle_range_rad"] == pytest.approx(
        expected["rocker_angle_range_rad"], abs=1e-4
    )
    # deflections and their comparisons: far below the image's 0.05 mm noise
    for key, value in expected.items():
        if key.endswith("_m") and not key.startswith("truth"):
            assert got[key] == pytest.approx(value, abs=2e-5), key
    # and against the truth the synthetic bench was made with
    assert -got["camera_to_daq_offset_s"] == pytest.approx(
        expected["truth_camera_clock_offset_s"], abs=2e-4
    )
    assert got["tip_lateral_image_peak_m"] == pytest.approx(
        expected["truth_tip_lateral_peak_m"], abs=1e-4
    )
