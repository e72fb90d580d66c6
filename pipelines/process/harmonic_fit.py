"""The least squares behind ``process --fit-damping`` (:mod:`damping_fit`), on the crank
harmonics of a run cut into cycles (:mod:`run_harmonics`).

The measured side is every gauge's and the image tip's harmonics per cycle, the ones that
stand :data:`RESOLVED_SE` standard errors clear of zero; the simulated side is the same
operator on a simulation over the same cycles. The weights are the residual's scatter over
the cycles, and the coefficients' standard errors are each cycle's residual projected
through the linearised least squares, scattered over the cycles.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pipelines.errors import DampingFitError
from pipelines.process.run_harmonics import harmonics_per_cycle
from sim.result import SimResult

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]

# Harmonics of the crank looked for: the gauges' 400 Hz stream resolves many; the image
# tip at 15 frames a second has ~16 frames a cycle, so at most 5 harmonics (11 parameters).
MAX_HARMONIC_STRAIN = 8
MAX_HARMONIC_IMAGE = 5
# A harmonic is used when its mean over the cycles stands this many standard errors clear
# of zero.
RESOLVED_SE = 5.0


@dataclass(frozen=True)
class Measured:
    """The measured side, cut into cycles, and the harmonics used."""

    windows: FloatArray
    per_cycle: ComplexArray  # (C, F)
    keep: list[tuple[int, int]]  # (signal, harmonic index) of each used feature
    names: list[str]
    se: FloatArray  # (F,) weights' standard errors


def signal_harmonics(
    t_s: FloatArray,
    strain: FloatArray,
    frame_t_s: FloatArray | None,
    tip_m: FloatArray | None,
    windows: FloatArray,
) -> list[ComplexArray]:
    """Per signal (gauges, then the image tip if any) the (C, K) harmonics."""
    out = [
        harmonics_per_cycle(t_s, strain[:, g], windows, MAX_HARMONIC_STRAIN)
        for g in range(strain.shape[1])
    ]
    if frame_t_s is not None and tip_m is not None:
        out.append(harmonics_per_cycle(frame_t_s, tip_m, windows, MAX_HARMONIC_IMAGE))
    return out


def stack(per_signal: list[ComplexArray], keep: list[tuple[int, int]]) -> ComplexArray:
    return np.column_stack([per_signal[s][:, k] for s, k in keep])


def sim_features(
    sim: SimResult, frame_t_s: FloatArray | None, windows: FloatArray, keep: list[tuple[int, int]]
) -> ComplexArray:
    tip = None
    if frame_t_s is not None:
        tip = np.interp(frame_t_s, sim.time_s, sim.tip_lateral_m)
    per = signal_harmonics(sim.time_s, sim.strain, frame_t_s, tip, windows)
    return stack(per, keep)


def scatter_se(per_cycle: ComplexArray) -> FloatArray:
    """Standard error of each column's mean from its scatter over the cycles (pooled over
    real and imaginary parts)."""
    n = per_cycle.shape[0]
    dev = per_cycle - np.nanmean(per_cycle, axis=0)
    var = np.nansum(np.abs(dev) ** 2, axis=0) / (2.0 * (n - 1))
    return np.sqrt(var / n)


@dataclass
class Problem:
    """The fit's moving parts: measured features, the simulator, the parameter map."""

    meas: Measured
    simulate: Callable[..., SimResult]  # (a0, a1[, end_s]) -> the run simulated
    frame_t_s: FloatArray | None
    law: str
    a0_rule: str  # "tied" (a0 = a1), "fixed" or "free"
    a0_fixed: float
    evaluations: int = 0

    def coefficients(self, x: FloatArray) -> tuple[float, float]:
        a1 = float(math.exp(x[-1]))
        if self.a0_rule == "free":
            return float(math.exp(x[0])), a1
        return (a1 if self.a0_rule == "tied" else self.a0_fixed), a1

    def residual_per_cycle(self, a0: float, a1: float) -> tuple[ComplexArray, SimResult]:
        self.evaluations += 1
        sim = self.simulate(a0, a1)
        s = sim_features(sim, self.frame_t_s, self.meas.windows, self.meas.keep)
        return s - self.meas.per_cycle, sim

    def weighted(self, x: FloatArray) -> FloatArray:
        r, _ = self.residual_per_cycle(*self.coefficients(x))
        z = np.nanmean(r, axis=0) / self.meas.se
        return np.concatenate([z.real, z.imag])


def measure(
    t_s: FloatArray,
    strain: FloatArray,
    frame_t_s: FloatArray | None,
    tip_m: FloatArray | None,
    windows: FloatArray,
) -> Measured:
    per = signal_harmonics(t_s, strain, frame_t_s, tip_m, windows)
    keep: list[tuple[int, int]] = []
    names: list[str] = []
    for s, h in enumerate(per):
        full = np.all(np.isfinite(h), axis=0)
        se = scatter_se(h)
        for k in range(h.shape[1]):
            if full[k] and abs(np.mean(h[:, k])) > RESOLVED_SE * se[k]:
                keep.append((s, k))
                label = f"gauge {s + 1}" if s < strain.shape[1] else "image tip"
                names.append(f"{label} h{k + 1}")
    if not keep:
        raise DampingFitError("no crank harmonic stands clear of the noise in any signal")
    per_cycle = stack(per, keep)
    return Measured(windows, per_cycle, keep, names, np.ones(len(keep)))


def with_weights(meas: Measured, resid_per_cycle: ComplexArray) -> Measured:
    """Weights from the residual's scatter over the cycles (the simulation follows the
    hub's own cycle-to-cycle changes, so this is the noise the residual carries); a floor
    at a fifth of the signal's median keeps one quiet harmonic from ruling the fit."""
    se = scatter_se(resid_per_cycle)
    signals = np.array([s for s, _ in meas.keep])
    for s in np.unique(signals):
        m = signals == s
        se[m] = np.maximum(se[m], 0.2 * float(np.median(se[m])))
    if not np.all(np.isfinite(se) & (se > 0)):
        raise DampingFitError("the harmonics' scatter over the cycles could not be measured")
    return Measured(meas.windows, meas.per_cycle, meas.keep, meas.names, se)


def jacobian(problem: Problem, x: FloatArray, step: float = 0.01) -> FloatArray:
    """(2F, p) central differences of the weighted mean residual in log coefficients."""
    cols = []
    for j in range(x.size):
        dx = np.zeros_like(x)
        dx[j] = step
        cols.append((problem.weighted(x + dx) - problem.weighted(x - dx)) / (2.0 * step))
    return np.column_stack(cols)


def cycle_projection_se(
    jac: FloatArray, resid_per_cycle: ComplexArray, se: FloatArray
) -> FloatArray:
    """Standard errors of the log coefficients: each cycle's weighted residual projected
    through the linearised least squares, scattered over the cycles."""
    z = resid_per_cycle / se
    zc = np.concatenate([z.real, z.imag], axis=1)  # (C, 2F)
    g = np.linalg.pinv(jac)  # (p, 2F)
    per_cycle = zc @ g.T  # (C, p)
    n = per_cycle.shape[0]
    return np.std(per_cycle, axis=0, ddof=1) / math.sqrt(n)
