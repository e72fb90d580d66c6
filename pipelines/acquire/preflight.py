"""Preflight: is the bench ready to record? (``beambench check``)

A few seconds are captured from the devices exactly as ``capture`` would (the synthetic bench
or the hardware), then each thing a run depends on is judged ``pass``, ``warn`` or ``fail``,
with the number it was judged on and what to do about it:

- the camera's frame rate against the rig's;
- the registration object found in a frame, and the calibration's reprojection error;
- the beam and the hub found and measured in a frame;
- the strain bridges' zero: the mean strain over whole crank cycles (the beam swings about its
  unloaded shape, so its cycle-mean bending strain is zero to within the noise; at rest the
  plain mean), per gauge;
- the potentiometer: its volts inside the supply range, the rocker's stroke against the
  four-bar's;
- the exposure: the smear of the tip at its peak speed during one exposure, in pixels and mm.
"""

from __future__ import annotations

import math
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from daq.log import RunLog, iter_frames, read_run
from pipelines.errors import BeambenchError
from pipelines.process.run import calibrate
from pipelines.rig import Rig
from sim.four_bar import FourBar
from vision import Calibration, Measurer, decode

STATUSES = ("pass", "warn", "fail")

# Limits of the judgements (the reasons are in each check's text).
FRAME_RATE_TOLERANCE = 0.02  # relative
REPROJECTION_WARN_PX = 0.5
REPROJECTION_FAIL_PX = 2.0
ZERO_WARN_MICROSTRAIN = 10.0
ZERO_FAIL_MICROSTRAIN = 30.0
STROKE_TOLERANCE_DEG = 3.0
SMEAR_PASS_PX = 2.0  # the edge model's own blur allowance
SMEAR_FAIL_M = 0.020  # beyond this the tip is not measured well (see the vision issue)


@dataclass(frozen=True)
class Check:
    """One judged item: ``status`` is pass, warn or fail; ``value`` the number it was
    judged on, with its unit; ``advice`` what to do (empty when nothing is to be done)."""

    name: str
    status: str
    value: str
    advice: str = ""


@dataclass(frozen=True)
class Preflight:
    checks: tuple[Check, ...]

    @property
    def failed(self) -> bool:
        return any(c.status == "fail" for c in self.checks)

    def table(self) -> list[str]:
        width = max(len(c.name) for c in self.checks)
        lines = []
        for c in self.checks:
            line = f"{c.status.upper():4s}  {c.name:<{width}s}  {c.value}"
            lines.append(line + (f"\n      {' ' * width}  -> {c.advice}" if c.advice else ""))
        return lines


def _frame_rate(run: RunLog, rig: Rig) -> Check:
    t = np.array([f.t_ns for f in iter_frames(run.path)], dtype=np.float64) * 1e-9
    want = rig.camera.frame_rate_hz
    if t.size < 3:
        return Check("frame rate", "fail", f"{t.size} frames", "no camera frames: check the camera")
    rate = (t.size - 1) / (t[-1] - t[0])
    off = rate / want - 1.0
    value = f"{rate:.2f} frames/s (rig {want:g})"
    if abs(off) <= FRAME_RATE_TOLERANCE:
        return Check("frame rate", "pass", value)
    return Check(
        "frame rate",
        "warn",
        value,
        f"{100 * off:+.1f} % off the rig's rate: set the camera to {want:g} frames/s or "
        "correct [camera] frame_rate_hz",
    )


def _registration(run: RunLog, rig: Rig) -> tuple[Check, Calibration | None]:
    try:
        cal = calibrate(run, rig, None)
    except BeambenchError as exc:
        why = str(exc).split("(", 1)[-1].rsplit(")", 1)[0]
        return (
            Check(
                "registration object",
                "fail",
                "not found",
                f"{why}: bring the whole plate into view, lit evenly, or check [registration]",
            ),
            None,
        )
    image = np.asarray(cal.image_points_px, float)
    err = np.linalg.norm(cal.to_px(np.asarray(cal.plane_points_m, float)) - image, axis=1)
    value = f"found; reprojection error {float(np.max(err)):.3f} px max"
    if err.max() <= REPROJECTION_WARN_PX:
        return Check("registration object", "pass", value), cal
    status = "warn" if err.max() <= REPROJECTION_FAIL_PX else "fail"
    return (
        Check(
            "registration object",
            status,
            value,
            "the plate's corners do not fit one plane mapping: check the lens distortion "
            "([camera] distortion) and that the plate lies in the beam's plane",
        ),
        cal,
    )


def _beam(run: RunLog, cal: Calibration | None) -> Check:
    if cal is None:
        return Check("beam and hub", "fail", "not measured", "needs the registration object")
    measurer = Measurer(cal)
    reasons = []
    for k, frame in enumerate(iter_frames(run.path)):
        if k >= 5:
            break
        m = measurer.measure(decode(frame.data))
        if m.ok:
            return Check(
                "beam and hub",
                "pass",
                f"found: hub {math.degrees(m.hub_angle_rad):.2f} deg, tip lateral "
                f"{1e3 * m.tip_lateral_m:.2f} mm",
            )
        reasons.append(m.reason)
    why = reasons[0] if reasons else "no frames"
    return Check("beam and hub", "fail", "not found", f"{why}: check the framing and the lighting")


def _whole_cycles(t_s: np.ndarray, rig: Rig) -> np.ndarray:
    """The samples of the longest run of whole crank cycles from the start."""
    period = 1.0 / rig.linkage.crank_frequency_hz
    n_cycles = math.floor((t_s[-1] - t_s[0]) / period)
    if n_cycles < 1:
        return np.ones(t_s.shape, dtype=bool)
    return np.asarray(t_s < t_s[0] + n_cycles * period)


def _bridges(run: RunLog, rig: Rig) -> Check:
    s = run.samples
    t = np.asarray(s.t_ns, dtype=np.float64) * 1e-9
    rocker = np.asarray(s.rocker_angle_rad, float)
    still = float(np.ptp(rocker)) < math.radians(0.5)
    window = np.ones(t.shape, dtype=bool) if still else _whole_cycles(t, rig)
    mean = 1e6 * np.mean(np.asarray(s.strain, float)[window], axis=0)
    how = "at rest" if still else f"over {window.sum() / 400:.1f} s of whole crank cycles"
    value = "mean " + ", ".join(f"g{j + 1} {v:+.1f}" for j, v in enumerate(mean))
    value += f" µε ({how})"
    worst = float(np.max(np.abs(mean)))
    if worst <= ZERO_WARN_MICROSTRAIN:
        return Check("strain bridges' zero", "pass", value)
    gauges = ", ".join(f"g{j + 1}" for j, v in enumerate(mean) if abs(v) > ZERO_WARN_MICROSTRAIN)
    return Check(
        "strain bridges' zero",
        "warn" if worst <= ZERO_FAIL_MICROSTRAIN else "fail",
        value,
        f"{gauges} read a strain the beam does not have: balance the bridge (or shunt-"
        "calibrate) with the beam unloaded before recording",
    )


def _potentiometer(run: RunLog, rig: Rig) -> Check:
    s = run.samples
    volts = np.asarray(s.raw_volts, float)[:, 0]  # the potentiometer, then the gauges
    supply = rig.potentiometer.supply_v
    rocker = np.asarray(s.rocker_angle_rad, float)
    stroke = math.degrees(float(np.ptp(rocker)))
    want = math.degrees(FourBar.from_config(rig.linkage).extrema().range_rad)
    value = f"{volts.min():.3f}-{volts.max():.3f} V of {supply:g} V; stroke {stroke:.2f} deg"
    if volts.min() <= 0.01 * supply or volts.max() >= 0.99 * supply:
        return Check(
            "potentiometer",
            "fail",
            value,
            "the wiper reaches the end of its track: turn the potentiometer so the stroke "
            "lies inside its electrical range ([potentiometer] zero_angle_deg)",
        )
    if float(np.ptp(rocker)) < math.radians(0.5):
        return Check("potentiometer", "pass", value + " (at rest)")
    if abs(stroke - want) <= STROKE_TOLERANCE_DEG:
        return Check("potentiometer", "pass", value + f" (four-bar {want:.2f})")
    return Check(
        "potentiometer",
        "warn",
        value + f" (four-bar {want:.2f})",
        "the measured stroke is not the linkage's: check [potentiometer] "
        "electrical_range_deg and supply_v, or the linkage lengths",
    )


def _exposure(rig: Rig, cal: Calibration | None) -> Check:
    four_bar = FourBar.from_config(rig.linkage)
    omega = 2 * math.pi * rig.linkage.crank_frequency_hz
    psi = np.linspace(0.0, 2 * math.pi, 721)
    rate = float(np.max(np.abs(four_bar.rocker_rate_rad_s(psi, omega))))
    radius = rig.beam.hub_offset_m + rig.beam.length_m
    speed = rate * radius  # the rigid beam's; the flexible tip overshoots it a little
    smear_m = speed * rig.camera.exposure_s
    px_per_m = math.nan
    if cal is not None:
        tip = np.array([[0.0, 0.0], [radius, 0.0]])
        px = cal.to_px(tip)
        px_per_m = float(np.linalg.norm(px[1] - px[0])) / radius
    smear_px = smear_m * px_per_m
    value = (
        f"tip smear {1e3 * smear_m:.2f} mm ({smear_px:.1f} px) at {speed:.2f} m/s "
        f"over {1e3 * rig.camera.exposure_s:.2f} ms"
    )
    shortest = SMEAR_PASS_PX / px_per_m / speed if math.isfinite(px_per_m) else math.nan
    if smear_px <= SMEAR_PASS_PX:
        return Check("exposure", "pass", value)
    status = "warn" if smear_m <= SMEAR_FAIL_M else "fail"
    return Check(
        "exposure",
        status,
        value,
        f"the tip moves {1e3 * smear_m:.1f} mm during an exposure: shorten it to "
        f"{1e3 * shortest:.2f} ms or less (more light), or expect blurred-tip uncertainty",
    )


def run_preflight(
    rig: Rig,
    record: Callable[[Path, float], Any],
    duration_s: float = 3.0,
) -> Preflight:
    """Record ``duration_s`` with ``record(path, duration_s)`` (a capture into a new log)
    and judge it."""
    with tempfile.TemporaryDirectory(prefix="beambench-check-") as tmp:
        path = Path(tmp) / "check.mcap"
        record(path, duration_s)
        run = read_run(path)
        reg, cal = _registration(run, rig)
        checks = (
            _frame_rate(run, rig),
            reg,
            _beam(run, cal),
            _bridges(run, rig),
            _potentiometer(run, rig),
            _exposure(rig, cal),
        )
    return Preflight(checks)
