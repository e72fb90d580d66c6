"""Speed against error of the modal model (a study script, not part of `beambench bench`).

    .venv/bin/python benchmarks/study_modal.py [--quick]

Reciprocating scene (rig beam, paper drive Eq. 53, a0 = a1 = 0.1, 10 s from rest, 400 Hz
output): error = max |tip - reference| over the last three cycles / max |reference| there.
Spin-up (Kane beam, omega_s = 4 and 10 rad/s, 30 s, 100 Hz output): error over the whole
run. The reference is the modal model with 12 modes at rtol 1e-11; the time is the solve
alone (``wall_time_s``), best of three, per simulated second.
"""

from __future__ import annotations

import sys

import numpy as np

from sim.beam import BeamProperties, spin_up_beam
from sim.config import BeamConfig
from sim.drives import Drive, SinusoidDrive, SpinUpDrive
from sim.models.modal import simulate_modal


def _run(
    beam: BeamProperties, drive: Drive, t: np.ndarray, n: int, rtol: float, damping: float
) -> tuple[np.ndarray, float]:
    best = np.inf
    tip = np.empty(0)
    for _ in range(3):
        res = simulate_modal(
            beam, drive, t, n_modes=n, rtol=rtol, atol=1e-14, a0_per_s=damping, a1_s=damping
        )
        best = min(best, res.wall_time_s)
        tip = res.tip_lateral_m
    return tip, best / (t[-1] - t[0])


def _table(
    name: str,
    beam: BeamProperties,
    drive: Drive,
    t: np.ndarray,
    window: np.ndarray,
    damping: float,
    settings: list[tuple[int, float]],
) -> None:
    ref, _ = _run(beam, drive, t, 12, 1e-11, damping)
    scale = np.abs(ref[window]).max()
    print(f"\n{name}: max |tip| {scale * 1e3:.3f} mm")
    print(f"{'n_modes':>8} {'rtol':>8} {'s per sim s':>12} {'rel. error':>11}")
    for n, rtol in settings:
        tip, cost = _run(beam, drive, t, n, rtol, damping)
        err = np.abs(tip[window] - ref[window]).max() / scale
        print(f"{n:>8d} {rtol:>8.0e} {cost:>12.5f} {err:>11.2e}")


def main(quick: bool = False) -> None:
    beam = BeamProperties.from_config(BeamConfig())
    t = np.arange(0.0, 10.0 + 1e-9, 1.0 / 400.0)
    period = 2 * np.pi / 4.970
    settings = [(2, 1e-4), (3, 1e-4), (4, 1e-4), (4, 1e-6), (6, 1e-6), (8, 1e-8)]
    if quick:
        settings = settings[2:4]
    _table(
        "reciprocating (paper drive)",
        beam,
        SinusoidDrive(),
        t,
        t >= t[-1] - 3 * period,
        0.1,
        settings,
    )
    ts = np.arange(0.0, 30.0 + 1e-9, 0.01)
    spin = [(2, 1e-4), (3, 1e-4), (4, 1e-4), (5, 1e-4), (6, 1e-4), (8, 1e-6)]
    if quick:
        spin = spin[2:4]
    for omega in (4.0, 10.0):
        _table(
            f"spin-up omega {omega:g} rad/s",
            spin_up_beam(),
            SpinUpDrive(omega),
            ts,
            np.ones(ts.size, bool),
            0.0,
            spin,
        )


if __name__ == "__main__":
    main(quick="--quick" in sys.argv)
