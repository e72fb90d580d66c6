"""Damping identified from a reciprocating run (``beambench process --fit-damping``).

The run is simulated driven by its measured hub angle (the potentiometer trace, as
:func:`pipelines.process.run.simulate_measured`) and the damping law's coefficients are
adjusted until the simulation's crank harmonics match the measured ones: every gauge's
and the image tip's fundamental and the higher harmonics the data resolve, each as a
complex number (amplitude and phase), cycle by cycle (:mod:`run_harmonics`).

What a run determines: at the bench's 0.92 Hz the first mode (3.7 Hz) is overdamped by
a1 (zeta_1 = a0 / (2 w1) + a1 w1 / 2 ~ 0.002 + 1.2 with the paper's 0.1 and 0.1), so the
response's phase and the harmonics near the first mode fix a1 to a fraction of a percent,
while a0 moves zeta_1 by a part in a thousand: the run does not determine a0. The fit
says so from its own numbers: a0 is fitted only when its 95 % interval is narrower than
half its value; otherwise it is held equal to a1 when the rig's a0 equals its a1 (the
paper's a0 = a1), else at the rig's value, and the results say which.

The noise the interval comes from is the data's: the residual (simulated minus measured
harmonics) of each crank cycle is projected through the linearised fit onto the
coefficients, and the scatter of those per-cycle estimates over the cycles is the
estimate's standard error (a t quantile with C - 1 degrees of freedom gives the 95 %
interval). A model that cannot follow the data within that noise (chi^2 per degree of
freedom above one) widens the interval by the Birge ratio sqrt(chi^2 / dof) and says so.
The interval does not hold errors common to every cycle that the fit cannot see (a gauge
factor, the beam's stiffness): those are the rig's.

Inside the loop the model is the modal model with the same law (:data:`FIT_MODEL`, a
few tenths of a second per run); it agrees with the exact beam to ~0.02 % with the
material law, but with the paper's law (tangent stiffness: the centrifugal tension is
damped too) it misses by ~0.4 % of the tip, which moved a1 by ~0.8 % on a synthetic run:
more than the interval. So the answer is finished with the exact beam (``auto`` at
:data:`EXACT_TOL`, the finite elements): the two models' harmonics are compared over the
first :data:`EXACT_CYCLES` cycles (the difference is the models', the same in every
cycle), and Gauss-Newton steps with the cheap model's Jacobian take it out. The cheap
loop's value stays in the results (``fitted_a1_loop_s``): the bias it had. The exact
beam at that tolerance has 3-5 elements and is itself good to ~2e-3 in the strains, which
is not below the data's precision: it is run once more with one element more, the finer
mesh's difference is used, and the step the refinement made is the mesh's standard
uncertainty of a1 (``fitted_a1_mesh_sd_s``), added in quadrature to the noise's.
"""

from __future__ import annotations

import logging
import math
import time
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import optimize, stats

from pipelines.errors import DampingFitError
from pipelines.process.harmonic_fit import (
    Problem,
    cycle_projection_se,
    jacobian,
    measure,
    sim_features,
    with_weights,
)
from pipelines.process.run_harmonics import cycle_windows
from pipelines.rig import Rig
from sim.beam import BeamProperties
from sim.drives import TraceDrive
from sim.result import SimResult
from sim.trace_fit import FittedTraceDrive

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]

#: the model simulated inside the fit loop, with :data:`FIT_MODES` modes
FIT_MODEL = "modal"
FIT_MODES = 4
# the modal integrator's rtol in the loop: its error (~0.35 rtol) is far below the
# harmonics' noise (~1e-3 of the fundamental per cycle) and the finite-difference steps
FIT_RTOL = 1e-6
# Whole crank cycles after the start-up transient a fit needs (and the scatter of at least
# this many gives the interval).
MIN_CYCLES = 4
# A hub that reciprocates: its stroke (2nd to 98th percentile) is at least this.
MIN_STROKE_RAD = math.radians(5.0)
# The simulation starts from rest: cycles start after this many time constants of the
# slowest free motion of the first mode (or at least SETTLE_MIN_S).
SETTLE_TIME_CONSTANTS = 8.0
SETTLE_MIN_S = 1.0
# a0 is fitted only when the run pins it to better than this fraction (95 % half-width).
A0_IDENTIFIABLE = 0.5
# A fit whose Birge ratio sqrt(chi^2 / dof) stays above this is flagged (it is widened
# whenever it exceeds one).
CHI2_FLAG = 2.0
# The exact beam the cheap model's answer is finished with (``auto`` at this tolerance:
# the finite elements with the gauges' strains checked), in at most EXACT_STEPS runs.
EXACT_TOL = 1e-3
EXACT_CYCLES = 3
# the loop model's runs kept for a repeated request (8: the 2 x 2 Jacobian of a0's test
# lies between the least squares' end and the next request of that point)
CHEAP_RUNS_KEPT = 8
A_MIN = 1e-4  # search bounds of a0 [1/s] and a1 [s]
A1_MAX_S = 10.0


@dataclass(frozen=True)
class DampingFit:
    """What a reciprocating run says about the damping (``ok`` False: see ``reason``;
    then no number here is to be used)."""

    ok: bool
    reason: str
    law: str
    a0_per_s: float
    a1_s: float
    a1_ci95_s: float
    a0_ci95_per_s: float  # NaN when a0 was held (see a0_note)
    a0_note: str
    residual_before_se: float  # RMS of the harmonic residuals, in standard errors
    residual_after_se: float
    strain_rms_before: float  # sim - measured over the fitted cycles
    strain_rms_after: float
    tip_rms_before_m: float  # image tip, NaN without frames
    tip_rms_after_m: float
    birge_ratio: float
    n_cycles: int
    n_harmonics: int  # complex harmonics fitted, over all signals
    evaluations: int
    wall_time_s: float
    start_s: float
    features: list[str] = field(default_factory=list)
    a1_loop_s: float = math.nan  # the cheap model's a1, before the exact beam's steps
    a1_mesh_sd_s: float = math.nan  # the exact beam's mesh, as a standard uncertainty of a1
    exact_model: str = ""

    def as_attrs(self) -> dict[str, float | str | int]:
        """The results file's global attributes (design.md)."""
        if not self.ok:
            return {"fitted_damping_failed": self.reason, "fitted_damping_law": self.law}
        attrs: dict[str, float | str | int] = {
            "fitted_damping_law": self.law,
            "fitted_a0_per_s": self.a0_per_s,
            "fitted_a1_s": self.a1_s,
            "fitted_a1_ci95_s": self.a1_ci95_s,
            "fitted_residual_before_se": self.residual_before_se,
            "fitted_residual_after_se": self.residual_after_se,
            "fitted_strain_rms_before": self.strain_rms_before,
            "fitted_strain_rms_after": self.strain_rms_after,
            "fitted_tip_rms_before_m": self.tip_rms_before_m,
            "fitted_tip_rms_after_m": self.tip_rms_after_m,
            "fitted_birge_ratio": self.birge_ratio,
            "fitted_cycles": self.n_cycles,
            "fitted_from_s": self.start_s,
            "fitted_harmonics": ", ".join(self.features),
            "fitted_evaluations": self.evaluations,
            "fitted_wall_time_s": self.wall_time_s,
            "fitted_loop_model": f"{FIT_MODEL} n_modes={FIT_MODES}",
            "fitted_a1_loop_s": self.a1_loop_s,
            "fitted_a1_mesh_sd_s": self.a1_mesh_sd_s,
            "fitted_exact_model": self.exact_model,
        }
        if math.isfinite(self.a0_ci95_per_s):
            attrs["fitted_a0_ci95_per_s"] = self.a0_ci95_per_s
        else:
            attrs["fitted_a0_note"] = self.a0_note
        return attrs

    def summary(self) -> str:
        """One line for people (a1 in s, a0 in 1/s)."""
        if not self.ok:
            return f"damping not fitted: {self.reason}"
        a0 = (
            f"a0 = {self.a0_per_s:.4g} +- {self.a0_ci95_per_s:.2g} 1/s"
            if math.isfinite(self.a0_ci95_per_s)
            else f"a0 = {self.a0_per_s:.4g} 1/s ({self.a0_note})"
        )
        return (
            f"{self.law} law: a1 = {self.a1_s:.4g} +- {self.a1_ci95_s:.2g} s (95 %), {a0}; "
            f"harmonic residual {self.residual_before_se:.1f} -> {self.residual_after_se:.2f} "
            f"standard errors over {self.n_cycles} cycles"
        )


def first_mode_rad_s(beam: BeamProperties) -> float:
    """Undamped clamped-free first mode, rad/s (beta_1 L = 1.8751)."""
    return (1.875104069 / beam.length_m) ** 2 * math.sqrt(
        beam.bending_stiffness_n_m2 / beam.mass_per_length_kg_m
    )


def settle_time_s(beam: BeamProperties, a0_per_s: float, a1_s: float) -> float:
    """Time for the start-from-rest transient to die: SETTLE_TIME_CONSTANTS of the first
    mode's slowest free motion (Eq. 37's zeta_1; overdamped: the slow root)."""
    w = first_mode_rad_s(beam)
    zeta = a0_per_s / (2.0 * w) + 0.5 * a1_s * w
    rate = w * (zeta - math.sqrt(zeta * zeta - 1.0)) if zeta > 1.0 else zeta * w
    return max(SETTLE_MIN_S, SETTLE_TIME_CONSTANTS / max(rate, 1e-9))


def check_fit_possible(
    source: str, t_s: FloatArray, rocker_rad: FloatArray, strain: FloatArray, settle_s: float
) -> FloatArray:
    """The crank cycles a fit would use; :class:`DampingFitError` naming ``source`` when
    the run cannot determine the damping."""
    eps = np.asarray(strain, float)
    if eps.ndim != 2 or eps.shape[1] == 0 or not np.isfinite(eps).any(axis=0).all():
        raise DampingFitError(
            f"{source}: --fit-damping needs every gauge's strain; the run has "
            f"{'none' if eps.ndim != 2 or eps.shape[1] == 0 else 'a gauge without samples'}"
        )
    r = np.asarray(rocker_rad, float)
    good = np.isfinite(r)
    if good.sum() < 10:
        raise DampingFitError(f"{source}: --fit-damping needs the hub angle; the run has none")
    lo, hi = np.percentile(r[good], [2.0, 98.0])
    if hi - lo < MIN_STROKE_RAD:
        raise DampingFitError(
            f"{source}: --fit-damping needs a reciprocating hub; it moved "
            f"{math.degrees(hi - lo):.2f} deg (at least {math.degrees(MIN_STROKE_RAD):.0f} "
            "deg), so the run does not determine the damping (a free decay would: release "
            "the tip with the hub held)"
        )
    windows = cycle_windows(t_s, r, float(t_s[0]) + settle_s)
    if len(windows) < MIN_CYCLES:
        raise DampingFitError(
            f"{source}: --fit-damping needs {MIN_CYCLES} whole crank cycles after the "
            f"{settle_s:.1f} s start-up; the run holds {len(windows)} "
            f"({float(t_s[-1] - t_s[0]):.1f} s)"
        )
    return windows


def _rms_differences(
    sim: SimResult,
    t_s: FloatArray,
    strain: FloatArray,
    frame_t_s: FloatArray | None,
    tip_m: FloatArray | None,
    start_s: float,
    end_s: float,
) -> tuple[float, float]:
    n = sim.time_s.size  # the simulation stops at the last cycle's end
    sel = (t_s[:n] >= start_s) & (t_s[:n] < end_s)
    d = sim.strain[sel] - strain[:n][sel]
    strain_rms = float(np.sqrt(np.nanmean(d**2)))
    tip_rms = math.nan
    if frame_t_s is not None and tip_m is not None:
        f = (frame_t_s >= start_s) & (frame_t_s < end_s) & np.isfinite(tip_m)
        if f.any():
            e = np.interp(frame_t_s[f], sim.time_s, sim.tip_lateral_m) - tip_m[f]
            tip_rms = float(np.sqrt(np.mean(e**2)))
    return strain_rms, tip_rms


@dataclass(frozen=True)
class _RunSimulator:
    """The run simulated from its measured hub up to a time: by the fit's loop model
    (:meth:`cheap`) or the exact beam (:meth:`exact`)."""

    rig: Rig
    law: str
    t_s: FloatArray
    drive: TraceDrive | FittedTraceDrive
    # the loop model's latest runs by (a0, a1, end): the fit asks for some twice or three
    # times (its start, the least squares' end point, the Jacobian's centre), and a
    # simulation is a pure function of them
    _cheap_runs: OrderedDict[tuple[float, float, float | None], SimResult] = field(
        default_factory=OrderedDict, compare=False, repr=False
    )

    def _until(self, end_s: float | None) -> FloatArray:
        if end_s is None:
            return self.t_s
        return self.t_s[: int(np.searchsorted(self.t_s, end_s, side="right")) + 1]

    def cheap(self, a0: float, a1: float, end_s: float | None = None) -> SimResult:
        key = (a0, a1, end_s)
        if key in self._cheap_runs:
            self._cheap_runs.move_to_end(key)
            return self._cheap_runs[key]
        sim = self._simulate_cheap(a0, a1, end_s)
        self._cheap_runs[key] = sim
        if len(self._cheap_runs) > CHEAP_RUNS_KEPT:
            self._cheap_runs.popitem(last=False)
        return sim

    def _simulate_cheap(self, a0: float, a1: float, end_s: float | None) -> SimResult:
        from sim.models.registry import simulate

        return simulate(
            FIT_MODEL,
            BeamProperties.from_config(self.rig.beam),
            self.drive,
            self._until(end_s),
            a0_per_s=a0,
            a1_s=a1,
            damping_law=self.law,
            gauge_positions_m=self.rig.gauges.positions_m,
            n_modes=FIT_MODES,
            tol=FIT_RTOL,
        )

    def exact(
        self,
        a0: float,
        a1: float,
        end_s: float,
        n_elements: int | None = None,
        settings: dict[str, Any] | None = None,
    ) -> SimResult:
        """``auto`` at :data:`EXACT_TOL`; with ``n_elements`` and an earlier FE result's
        ``settings``, that FE on ``n_elements`` at the same tolerances."""
        from sim.models.fe import simulate_fe
        from sim.models.registry import simulate

        beam = BeamProperties.from_config(self.rig.beam)
        common: dict[str, Any] = {
            "a0_per_s": a0,
            "a1_s": a1,
            "damping_law": self.law,
            "gauge_positions_m": self.rig.gauges.positions_m,
        }
        t = self._until(end_s)
        if n_elements is None or settings is None:
            return simulate("auto", beam, self.drive, t, tol=EXACT_TOL, **common)
        return simulate_fe(
            beam, self.drive, t, n_elements=n_elements, rtol=float(settings["rtol"]),
            atol=float(settings["atol"]), method="radau5", curvature="recovered", **common,
        )  # fmt: skip


def fit_damping(
    rig: Rig,
    t_s: FloatArray,
    rocker_rad: FloatArray,
    strain: FloatArray,
    *,
    law: str | None = None,
    frame_t_s: FloatArray | None = None,
    tip_lateral_m: FloatArray | None = None,
    source: str = "the run",
    max_evaluations: int = 40,
    exact_beam: bool = True,
) -> DampingFit:
    """Fit the damping law's coefficients to a reciprocating run.

    Parameters
    ----------
    rig : the bench (beam, gauges; its ``[damping]`` is the starting point and says how
        a0 is held when the run does not determine it).
    t_s, rocker_rad, strain : the DAQ samples: (N,) times [s], hub angle [rad], (N, G)
        strains.
    law : ``"paper"`` or ``"material"`` (default: the rig's).
    frame_t_s, tip_lateral_m : the image tip [m] at the frame times on the DAQ clock [s]
        (NaN where a frame gave none), or None.
    source : names the run in messages.
    max_evaluations : simulations the least squares may spend.
    exact_beam : finish with the exact beam (default); False leaves the cheap loop's
        answer, biased by its model (for a test of the interval's noise alone).

    Returns
    -------
    DampingFit
        ``ok`` False with the reason when the least squares did not converge.

    Raises
    ------
    DampingFitError
        when the run cannot determine the damping.
    """
    started = time.perf_counter()
    law = rig.damping.law if law is None else law
    t = np.asarray(t_s, float)
    rocker = np.asarray(rocker_rad, float)
    eps = np.asarray(strain, float)
    ft: FloatArray | None = None
    tip: FloatArray | None = None
    if frame_t_s is not None and tip_lateral_m is not None:
        if np.isfinite(np.asarray(tip_lateral_m, float)).any():
            ft, tip = np.asarray(frame_t_s, float), np.asarray(tip_lateral_m, float)
    a0_start, a1_start = rig.damping.a0_per_s, rig.damping.a1_s
    windows = check_fit_possible(source, t, rocker, eps, fit_settle_s(rig))
    end_s = float(windows[-1, 1])
    n_sim = int(np.searchsorted(t, end_s, side="right")) + 1
    t_sim = t[: min(n_sim, t.size)]
    good = np.isfinite(rocker)

    sims = _RunSimulator(rig, law, t_sim, FittedTraceDrive(t[good], rocker[good]))
    run, run_exact = sims.cheap, sims.exact

    meas = measure(t, eps, ft, tip, windows)
    tied = a0_start == a1_start
    problem = Problem(meas, run, ft, law, "tied" if tied else "fixed", a0_start)
    r0, sim0 = problem.residual_per_cycle(a0_start, a1_start)
    problem.meas = meas = with_weights(meas, r0)
    x0 = np.array([math.log(a1_start)])
    z0 = problem.weighted(x0)
    before = float(np.sqrt(np.mean(z0**2)))
    strain_before, tip_before = _rms_differences(sim0, t, eps, ft, tip, windows[0, 0], end_s)
    fitted = _least_squares(problem, x0, max_evaluations)
    if isinstance(fitted, str):
        return _failed(law, fitted, problem, started, windows)
    x = fitted
    a0_note = "held equal to a1 (the paper's a0 = a1)"
    if not tied:
        a0_note = f"held at the rig's {a0_start:.4g} 1/s"
    free, a0_half = _a0_determined(problem, x)
    if free:
        a0_fit, a1_fit = problem.coefficients(x)
        problem = Problem(meas, run, ft, law, "free", a0_fit, problem.evaluations)
        fitted = _least_squares(problem, np.log([a0_fit, a1_fit]), max_evaluations)
        if isinstance(fitted, str):
            return _failed(law, fitted, problem, started, windows)
        x = fitted
        a0_note = ""
    else:
        a0_note += (
            f": the run does not determine a0 (its 95 % interval would be "
            f"+-{a0_half:.3g} 1/s on {problem.coefficients(x)[0]:.3g})"
        )
    a1_loop = problem.coefficients(x)[1]
    skipped = float(windows[0, 0] - t[0])
    needed = settle_time_s(BeamProperties.from_config(rig.beam), *problem.coefficients(x))
    if needed > skipped:
        why = (
            f"the fitted damping (a1 = {a1_loop:.3g} s) rings for {needed:.1f} s after the "
            f"start from rest, longer than the {skipped:.1f} s skipped for the rig's a1 = "
            f"{a1_start:.3g} s; give the rig a [damping] a1 nearer the run's"
        )
        return _failed(law, why, problem, started, windows)
    jac = jacobian(problem, x)
    # the cheap model's bias, measured against the exact beam, stepped out (Gauss-Newton)
    diff: ComplexArray | float = 0.0
    mesh: ComplexArray | float = 0.0
    exact_model = "none (the loop's model's answer)"
    if exact_beam:
        diff, mesh, exact_model = _exact_difference(problem, run_exact, x)
    for i in range(3):
        r_fit, sim_fit = problem.residual_per_cycle(*problem.coefficients(x))
        r_fit = r_fit + diff
        z = np.nanmean(r_fit, axis=0) / meas.se
        step = -(np.linalg.pinv(jac) @ np.concatenate([z.real, z.imag]))
        if i == 2 or np.all(np.abs(step) <= 0.02 * cycle_projection_se(jac, r_fit, meas.se)):
            break  # r_fit and sim_fit are at x
        x = x + step
    se = cycle_projection_se(jac, r_fit, meas.se)
    z = np.nanmean(r_fit, axis=0) / meas.se
    zz = np.concatenate([z.real, z.imag])
    dof = max(zz.size - x.size, 1)
    birge = math.sqrt(max(float(zz @ zz) / dof, 1.0))
    if birge > CHI2_FLAG:
        log.warning(
            "%s: the fitted simulation misses the measured harmonics by %.1f standard "
            "errors RMS; the damping's interval is widened by that factor",
            source,
            math.sqrt(float(zz @ zz) / zz.size),
        )
    n = meas.per_cycle.shape[0]
    # the exact beam's own discretisation: the step its mesh refinement made, taken as a
    # standard uncertainty and added to the noise's in quadrature
    zm = np.broadcast_to(np.asarray(mesh / meas.se), z.shape)
    mesh_sd = np.abs(np.linalg.pinv(jac) @ np.concatenate([zm.real, zm.imag]))
    noise_half = se * float(stats.t.ppf(0.975, n - 1)) * birge
    half = np.exp(x) * np.hypot(noise_half, 2.0 * mesh_sd)
    strain_after, tip_after = _rms_differences(sim_fit, t, eps, ft, tip, windows[0, 0], end_s)
    a0_fit, a1_fit = problem.coefficients(x)
    return DampingFit(
        ok=True,
        reason="",
        law=law,
        a0_per_s=a0_fit,
        a1_s=a1_fit,
        a1_ci95_s=float(half[-1]),
        a0_ci95_per_s=float(half[0]) if problem.a0_rule == "free" else math.nan,
        a0_note=a0_note,
        residual_before_se=before,
        residual_after_se=float(np.sqrt(np.mean(zz**2))),
        strain_rms_before=strain_before,
        strain_rms_after=strain_after,
        tip_rms_before_m=tip_before,
        tip_rms_after_m=tip_after,
        birge_ratio=birge,
        n_cycles=n,
        n_harmonics=len(meas.keep),
        evaluations=problem.evaluations,
        wall_time_s=time.perf_counter() - started,
        start_s=float(windows[0, 0]),
        features=meas.names,
        a1_loop_s=a1_loop,
        a1_mesh_sd_s=float(np.exp(x[-1]) * mesh_sd[-1]),
        exact_model=exact_model,
    )


def _model_label(sim: SimResult) -> str:
    choice = sim.settings.get("auto_choice")
    return f"{sim.model} ({choice})" if choice else sim.model


def _a0_determined(problem: Problem, x: FloatArray) -> tuple[bool, float]:
    """Whether the run pins a0 (its 95 % half-width below A0_IDENTIFIABLE of its value,
    from the two-coefficient Jacobian at the one-coefficient fit), and that half-width."""
    a0, a1 = problem.coefficients(x)
    if a0 <= 0:
        return False, math.nan
    two = Problem(problem.meas, problem.simulate, problem.frame_t_s, problem.law, "free", a0)
    x2 = np.log([a0, a1])
    r, _ = problem.residual_per_cycle(a0, a1)
    se2 = cycle_projection_se(jacobian(two, x2), r, problem.meas.se)
    problem.evaluations += two.evaluations
    n = problem.meas.per_cycle.shape[0]
    half = a0 * float(se2[0]) * float(stats.t.ppf(0.975, n - 1))
    return bool(math.isfinite(half) and half < A0_IDENTIFIABLE * a0), half


def _exact_difference(
    problem: Problem, exact_run: Callable[..., SimResult], x: FloatArray
) -> tuple[ComplexArray, ComplexArray, str]:
    """(F,) exact beam minus cheap model, the harmonics' mean over the first
    EXACT_CYCLES cycles at ``x`` (both driven by the same measured hub, so the
    difference is the models' and barely changes from cycle to cycle); (F,) how much of
    it the exact beam's own mesh moves (its answer with one element more, whose
    difference is returned, less ``auto``'s mesh); and the exact model's label."""
    meas = problem.meas
    k = min(EXACT_CYCLES, len(meas.windows))
    windows = meas.windows[:k]
    a0, a1 = problem.coefficients(x)
    end = float(windows[-1, 1])
    sims = [problem.simulate(a0, a1, end), exact_run(a0, a1, end)]
    label = _model_label(sims[1])
    ne = sims[1].settings.get("n_elements")
    if isinstance(ne, int):
        sims.append(exact_run(a0, a1, end, n_elements=ne + 1, settings=sims[1].settings))
        label += f", checked with {ne + 1} elements"
    problem.evaluations += len(sims)
    cheap, *exact = (sim_features(sim, problem.frame_t_s, windows, meas.keep) for sim in sims)
    diffs = [np.nanmean(e - cheap, axis=0) for e in exact]
    return diffs[-1], diffs[-1] - diffs[0], label


def _least_squares(problem: Problem, x0: FloatArray, max_evaluations: int) -> FloatArray | str:
    """The fitted log coefficients, or why the least squares did not converge."""
    lo = np.full(x0.size, math.log(A_MIN))
    hi = np.full(x0.size, math.log(A1_MAX_S))
    try:
        res = optimize.least_squares(
            problem.weighted,
            x0,
            bounds=(lo, hi),
            method="trf",
            diff_step=1e-3,
            xtol=1e-5,
            ftol=1e-8,
            max_nfev=max_evaluations,
        )
    except (ValueError, ArithmeticError) as exc:
        return f"the least squares failed ({exc})"
    if res.status <= 0:
        return f"the least squares did not converge in {res.nfev} simulations ({res.message})"
    at_bound = np.isclose(res.x, lo, atol=1e-3) | np.isclose(res.x, hi, atol=1e-3)
    if np.any(at_bound):
        return "the fit ran to the end of the coefficients' range (a1 in [1e-4, 10] s)"
    return np.asarray(res.x, float)


def _failed(
    law: str, reason: str, problem: Problem, started: float, windows: FloatArray
) -> DampingFit:
    nan = math.nan
    return DampingFit(
        ok=False,
        reason=reason,
        law=law,
        a0_per_s=nan,
        a1_s=nan,
        a1_ci95_s=nan,
        a0_ci95_per_s=nan,
        a0_note="",
        residual_before_se=nan,
        residual_after_se=nan,
        strain_rms_before=nan,
        strain_rms_after=nan,
        tip_rms_before_m=nan,
        tip_rms_after_m=nan,
        birge_ratio=nan,
        n_cycles=len(windows),
        n_harmonics=len(problem.meas.keep),
        evaluations=problem.evaluations,
        wall_time_s=time.perf_counter() - started,
        start_s=float(windows[0, 0]),
    )


__all__ = [
    "FIT_MODEL",
    "DampingFit",
    "DampingFitError",
    "check_fit_possible",
    "fit_damping",
]


def fit_settle_s(rig: Rig) -> float:
    """Start-up the fit skips: the rig's damping's settling time, or that of a tenth of
    its a1 if longer (a lighter damping rings longer)."""
    beam = BeamProperties.from_config(rig.beam)
    a0, a1 = rig.damping.a0_per_s, rig.damping.a1_s
    return max(settle_time_s(beam, a0, a1), settle_time_s(beam, a0, 0.1 * a1))


def fit_and_resimulate(
    rig: Rig,
    law: str,
    t_s: FloatArray,
    rocker_rad: FloatArray,
    strain: FloatArray,
    frame_t_s: FloatArray | None,
    tip_lateral_m: FloatArray | None,
    resimulate: Callable[[Rig], SimResult],
    source: str,
) -> tuple[DampingFit, SimResult | None]:
    """The fit, and the run simulated again by ``resimulate`` with the fitted damping
    (None when the fit failed: the caller keeps its unfitted simulation, with a warning)."""
    from dataclasses import replace

    fit = fit_damping(
        rig,
        t_s,
        rocker_rad,
        strain,
        law=law,
        frame_t_s=frame_t_s,
        tip_lateral_m=tip_lateral_m,
        source=source,
    )
    if not fit.ok:
        log.warning("%s: %s; the simulation keeps the rig's damping", source, fit.summary())
        return fit, None
    log.info("%s: fitted damping, %s", source, fit.summary())
    damping = replace(rig.damping, a0_per_s=fit.a0_per_s, a1_s=fit.a1_s, law=law)
    return fit, resimulate(replace(rig, damping=damping))


def check_run_supports_fit(
    rig: Rig, source: str, t_s: FloatArray, rocker_rad: FloatArray, strain: FloatArray
) -> None:
    """:class:`DampingFitError` now, before the frames are measured, when ``--fit-damping``
    cannot work on the run; a run whose hub stands still long enough for a free decay
    passes (its free decay, if there is one, identifies the damping instead)."""
    from pipelines.process.free_decay import still_stretch

    if still_stretch(t_s, rocker_rad) is not None:
        return
    check_fit_possible(source, t_s, rocker_rad, strain, fit_settle_s(rig))


def fit_damping_attrs(
    rig: Rig,
    law: str,
    t_s: FloatArray,
    samples: Any,
    frame_t_s: FloatArray,
    cols: dict[str, Any],
    decay: Any,
    source: str,
    resimulate: Callable[[Rig], SimResult],
) -> tuple[dict[str, Any], SimResult | None]:
    """``process --fit-damping``: the results' ``fitted_*`` attributes and the run
    simulated with the fitted damping (None: keep the unfitted one). A run that holds a
    free decay keeps that identification (and says so)."""
    if decay is not None:
        note = (
            f"the run holds a free decay from {decay.release_s:.2f} s: its identification "
            f"(a0 = a1 = {decay.a_simulated:.3g}) is used, not a fit to the reciprocating motion"
        )
        log.warning("%s: --fit-damping: %s", source, note)
        return {"fitted_damping_note": note}, None
    ok = np.asarray(cols["ok"], bool)
    tip = np.where(ok, np.asarray(cols["tip_lateral_m"], float), np.nan)
    fit, sim = fit_and_resimulate(
        rig,
        law,
        t_s,
        samples.rocker_angle_rad,
        samples.strain,
        frame_t_s if ok.any() else None,
        tip if ok.any() else None,
        resimulate,
        source,
    )
    return fit.as_attrs(), sim
