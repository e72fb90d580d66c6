"""The simulation's error below the image measurement's: the tolerance rule, and a short
synthetic run processed end to end whose image - simulation difference is the image's own
error (the bench's truth is known, so the simulation is also checked against it)."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from daq.antialias import AntiAliasDecimator, design_antialias
from daq.config import DaqConfig
from pipelines.demo import capture_synthetic
from pipelines.process.frames import MeasuredFrame
from pipelines.process.model_error import (
    IMAGE_SHARE,
    NO_FRAMES_TOL,
    PRIOR_SIM_TOL,
    check_tolerance,
    drive_tip_uncertainty_m,
    image_tip_sd_rms_m,
)
from pipelines.process.run import process_run
from pipelines.results.compare import sim_start_s, summarise_errors
from pipelines.rig import load_rig
from sim.beam import BeamProperties
from sim.models.registry import simulate
from sim.result import SimResult
from sim.trace_fit import FittedTraceDrive
from vision import FrameMeasurement


def _sim(tip_amplitude_m: float, estimate: float) -> SimResult:
    t = np.linspace(0.0, 2.0, 201)
    tip = tip_amplitude_m * np.sin(2 * math.pi * t)
    z = np.zeros((t.size, 2))
    return SimResult(
        time_s=t,
        hub_angle_rad=np.zeros_like(t),
        tip_lateral_m=tip,
        tip_longitudinal_m=np.zeros_like(t),
        stations_m=np.array([0.0, 1.0]),
        station_lateral_m=z,
        station_longitudinal_m=z,
        gauge_positions_m=np.zeros(0),
        strain=np.zeros((t.size, 0)),
        model="auto:fe-corot",
        wall_time_s=0.0,
        settings={"auto_error_estimate": estimate},
    )


def _frames(sd_m: list[float], failed: int = 0) -> list[MeasuredFrame]:
    out = [
        MeasuredFrame(k, k, FrameMeasurement(ok=True, tip_lateral_m=0.0, tip_lateral_std_m=s))
        for k, s in enumerate(sd_m)
    ]
    out += [MeasuredFrame(99, 99, FrameMeasurement(ok=False, reason="no beam"))] * failed
    return out


def test_the_frames_set_the_tolerance_and_a_loose_simulation_is_done_again() -> None:
    frames = _frames([0.03e-3, 0.04e-3, 0.05e-3], failed=2)
    sd = math.sqrt((0.03**2 + 0.04**2 + 0.05**2) / 3) * 1e-3
    assert image_tip_sd_rms_m(frames) == pytest.approx(sd)
    # 40 mm tip: a fifth of 0.041 mm is 2.0e-4 of it
    good = _sim(0.04, estimate=1e-5)
    choice, again = check_tolerance(good, frames, PRIOR_SIM_TOL)
    assert again is None and not choice.resimulated
    assert choice.tip_tol_m == pytest.approx(IMAGE_SHARE * sd)
    assert choice.estimate_m == pytest.approx(1e-5 * 0.04)
    attrs = choice.as_attrs()
    assert attrs["sim_tol"] == PRIOR_SIM_TOL and attrs["sim_resimulated"] == 0
    loose = _sim(0.04, estimate=1e-3)
    choice, again = check_tolerance(loose, frames, PRIOR_SIM_TOL)
    assert again == pytest.approx(IMAGE_SHARE * sd / 0.04) and choice.resimulated
    # no measured frame: 1e-3 of the tip
    choice, again = check_tolerance(loose, _frames([], failed=3), PRIOR_SIM_TOL)
    assert again is None and choice.tip_tol_m == pytest.approx(NO_FRAMES_TOL * 0.04)
    assert math.isnan(choice.image_sd_rms_m)


@pytest.mark.slow
def test_a_short_run_compares_with_the_simulation_to_the_image_own_error(
    tmp_path: Path,
) -> None:
    # not the bench's defaults: a faster crank, less damping, another seed
    rig = load_rig()
    rig = dataclasses.replace(
        rig,
        linkage=dataclasses.replace(rig.linkage, crank_frequency_hz=1.05),
        damping=dataclasses.replace(rig.damping, a0_per_s=0.08, a1_s=0.08),
        synthetic=dataclasses.replace(rig.synthetic, warmup_s=3.0, seed=4242),
    )
    log_path = tmp_path / "run.mcap"
    devices = capture_synthetic(rig, log_path, 5.0)
    processed = process_run(log_path, workers=2)
    ds = processed.results
    a = ds.attrs
    assert a["sim_model"].startswith("auto:fe")  # below the modal model's ~1 %
    assert json.loads(a["sim_drive"])["kind"] == "harmonics"
    sd = float(a["image_tip_lateral_sd_rms_m"])
    est = float(a["sim_tip_error_estimate_m"])
    assert est <= IMAGE_SHARE * sd  # the rule held, with or without simulating again
    errors = summarise_errors(ds)
    n = int(errors["n_frames_compared"])
    assert n > 40
    drive = float(a["sim_drive_tip_uncertainty_m"])
    cal = float(a["calibration_tip_lateral_sd_m"])
    # image - sim: the image's stated noise, the model's estimate and the fitted drive's
    # uncertainty in quadrature; an RMS over n frames of Gaussian errors is within
    # 3 / sqrt(2 n) of its expectation (three standard deviations); the calibration's
    # error is one draw for the run (the registration detected once), within 3 of its sd
    expected = math.sqrt(sd**2 + est**2 + drive**2)
    bound = math.hypot(expected * (1 + 3 / math.sqrt(2 * n)), 3.0 * cal)
    assert errors["tip_lateral_image_vs_sim_rms_m"] < bound, (expected, cal)
    # the simulation itself, against the bench's truth: within its stated uncertainty (the
    # drive's, a draw of a few harmonics' noise: within twice its RMS, as in
    # tests/sim/test_trace_fit.py), and below the image's error
    t = ds["time"].values
    late = t >= sim_start_s(ds)
    truth = devices.bench.truth.tip_lateral_m(t[late] + a["t_zero_ns"] * 1e-9)
    sim_err = float(np.sqrt(np.mean((ds["sim_tip_lateral"].values[late] - truth) ** 2)))
    assert sim_err < 2.0 * math.sqrt(est**2 + drive**2)
    assert sim_err < sd


class _SpeedingUpCrank:
    """A hub angle that does not repeat: a rocker-like swing whose rate rises 30 % over
    the run (a crank motor coming up to speed), not the bench's 0.92 Hz."""

    def __init__(self, duration_s: float) -> None:
        self.w0, self.k = 2 * math.pi * 0.9, 0.15 / duration_s

    def angle(self, t: np.ndarray) -> np.ndarray:
        t = np.asarray(t, float)
        return 0.7 * np.sin(self.w0 * (t + self.k * t**2))

    def rate(self, t: np.ndarray) -> np.ndarray:
        t = np.asarray(t, float)
        return 0.7 * np.cos(self.w0 * (t + self.k * t**2)) * self.w0 * (1 + 2 * self.k * t)

    def accel(self, t: np.ndarray) -> np.ndarray:
        t = np.asarray(t, float)
        phase, d = self.w0 * (t + self.k * t**2), self.w0 * (1 + 2 * self.k * t)
        return -0.7 * np.sin(phase) * d * d + 0.7 * np.cos(phase) * 2 * self.w0 * self.k


def test_a_spline_fitted_drive_states_the_tip_error_its_noise_causes() -> None:
    """A run that does not repeat is driven by a spline: the potentiometer's noise it
    passes reaches the tip through the beam, and the stated drive uncertainty (the noise's
    PSD through the spline's passband and the linear beam) must match what simulating the
    beam on the fitted and on the true drive gives. The pot's noise (2 kHz, 0.6 mrad, then
    the DAQ's anti-alias filter and decimation to 400 Hz) is not the bench's default."""
    duration, fs = 10.0, 2000.0
    true = _SpeedingUpCrank(duration)
    beam = BeamProperties.from_config(load_rig().beam)
    design = design_antialias(DaqConfig(), fs)
    damping = {"a0_per_s": 0.1, "a1_s": 0.1, "damping_law": "paper"}
    actual_sq, stated = [], []
    for seed in (1, 2, 3, 4):
        n = round((duration + 0.5) * fs)
        t_acq = np.arange(n) / fs
        noisy = true.angle(t_acq) + np.random.default_rng(seed).normal(0.0, 6e-4, n)
        out = AntiAliasDecimator(design, 1).process(
            np.round(t_acq * 1e9).astype(np.int64), noisy[:, None], 0
        )
        t, y = out.t_ns * 1e-9, out.volts[:, 0]
        drive = FittedTraceDrive(t, y)
        assert drive.settings["kind"] == "spline"
        stated.append(drive_tip_uncertainty_m(beam, drive, t, 0.1, 0.1, "paper"))
        t_eval = t[(t > t[0] + 0.01) & (t < t[-1] - 0.01)]
        fitted = simulate("modal", beam, drive, t_eval, **damping)
        exact = simulate("modal", beam, true, t_eval, **damping)
        late = t_eval > t_eval[0] + 3.0  # the start-up transient of both has died out
        err = np.asarray(fitted.tip_lateral_m)[late] - np.asarray(exact.tip_lateral_m)[late]
        actual_sq.append(float(np.mean(err**2)))
    actual = math.sqrt(float(np.mean(actual_sq)))
    expected = float(np.mean(stated))
    # four 7 s stretches of a ~5 Hz wide tip noise: ~280 degrees of freedom, the RMS within
    # ~4 % (1 sd) of its expectation; the PSD from Welch over ~5 segments of 2 s within
    # ~5 %; the passband is the dense-sample, far-from-the-ends limit: 20 % is ~4 sd
    assert actual == pytest.approx(expected, rel=0.2), (actual, stated)
