"""``auto``: the cheapest beam model whose estimated error for the scene is below ``tol``
(the ``auto`` entry of :mod:`sim.models.registry`).

The estimate is a sum of parts, each relative to the largest tip deflection delta (of a
quick modal run):

- **Kelvin-Voigt lag of the centrifugal tension** (what the linear modal model gets wrong
  first on the paper's scene; it is *not* geometric nonlinearity). Eq. 28 damps with
  a1 K_T, and K_T holds the geometric stiffness of the axial force. The modal model puts the
  instantaneous centrifugal tension N = Omega^2 n(x) there. The finite elements carry the
  axial strain as coordinates, so a1 K_T acts on the axial strain rate too: the axial
  strain obeys eps + a1 eps' = N / EA (the axial modes, zeta ~ 500, are quasi-static) and
  the tension in the damping term is the *elastic* part EA eps, i.e. Omega^2 low-passed
  with time constant a1. On the paper's scene (a1 = 0.1 s, Omega^2 at 9.9 rad/s) it
  lags by 45 degrees at 70 % amplitude. Putting the lagged tension into the modal
  damping takes the modal-FE gap from 4.4e-3 to 1.0e-3, while the third-order modal model
  (geometric nonlinearity) only takes it to 3.6e-3 (measured, 6 modes against 4-6 FE
  elements; with a1 = 0 the gap vanishes with the damping). Estimate:
  ``E_KV = |tip(K_T damping) - tip(K damping)| / delta * mean|Omega^2 - s| / mean Omega^2``,
  the sensitivity of the tip to the geometric damping term (a second modal run with
  ``damping_geometric=False``) times the relative size of the lag, ``s`` being Omega^2
  filtered by ``a1 s' + s = Omega^2`` from rest. Paper scene: 5.6e-3 for a real 4.4e-3.
  With ``damping_law="material"`` there is no tension in the damping and this part is zero.
- **geometric nonlinearity**: ``C_NL (delta / L)^2``, C_NL = 1.5 over the exact cases: the
  static tip load (elastica 0.95 % below PL^3/3EI at delta/L = 0.097: C = 1.0), the spin-ups
  (4 and 10 rad/s, undamped: C = 0.29, 0.25) and the paper's scene once the lag is taken out
  (C = 0.75).
- **modal truncation**: the change of the tip history from n to n + 1 modes.
- **time integration**: the modal solver's rtol is set to tol / 20 (the FE's: below).

If the modal estimate is below tol the modal model runs with n + 1 modes. Otherwise the
exact finite elements (``corot``, Radau IIA with full Newton, :mod:`sim.solvers.radau`) run with the
fewest elements N whose discretisation estimate ``C_FE N^-4`` (Hermite cubics: h^4) is
below 0.7 tol, with ``C_FE = 30 (delta/L)^2 / max(1, zeta_2)``: 30 (delta/L)^2 fits the
undamped spin-ups (measured C = 28 and 30 at delta/L = 0.04 and 0.086), and when the second
bending mode is overdamped (zeta_2 = a0 / (2 w_2) + a1 w_2 / 2 > 1) the higher modes respond
quasi-statically and the error drops (paper scene: measured C = 1.2e-3, estimate 5.6e-3).
The integrator runs at rtol = atol = tol (atol in m and m/s); its global error, measured,
is about 0.35 rtol.

Where the adaptive integrator's rtol would be tight (the gauged runs, 2e-6: there the
fixed steps are the cheaper, see :data:`FIXED_BELOW_RTOL`), the beam damped enough
(a1 > 0, the second bending mode overdamped: the modes
above it respond quasi-statically and the L-stable method damps their start in a step)
and the drive says how smooth it is (:func:`sim.drives.drive_time_scale_s`: the period of
its highest harmonic, a spline's knot spacing; at least 4 steps in it), the FE runs
instead take fixed steps of the 5-stage Radau IIA (order 9, closed-form stage Jacobians),
each mesh at h = 0.025 s and at h / 2. The h / 2 run is returned and the change from h to
h / 2 is its stated time error, measured, not assumed: it is the h run's error (within
2 % on the paper's scene and on a fitted four-bar trace, tested), and the h / 2 run's own
is 30-1000x below it.
While it is above its share of the tolerance the step is halved again (down to 6.25 ms);
a Newton iteration that fails even in parts, or a time error still too large, hands
the runs back to the adaptive integrator. The first step starts in parts (h / 64, doubling):
from rest with the hub accelerating, the fast modes' start-up layer would otherwise sit in
the first step's dense output, the same at h and h / 2 and so unseen by the halving.
On the rig's minute (the measured four-bar trace, steady state after 3.2 s, 5 elements)
the FE runs took 0.42 CPU s adaptive, 0.2 s so; the time error stated 9.4e-7 of the tip
for an actual 2.9e-8, the strains' 2.6e-6 for 1e-7 (adaptive at rtol 2e-6: 7e-7 stated
for both, actual 2.8e-7 and, the strains, 2.2e-6; against rtol-1e-10 runs).
``settings["auto_time_integration"]`` says which ran, the step and the estimate.

Every output is answered for, not only the tip:

- **stations**, relative to the largest tip deflection (``tol`` is the tip's; the stations'
  estimate is stated, it does not choose). The modal truncation check compares every
  station (the tip is one). The FE's nodes converge as h^4 and are superconvergent (the
  tip: C_FE above); between them the Hermite cubics interpolate, with the error
  h^4 / 384 max|w_xxxx| and EI w_xxxx the lateral load per length. Relative to the tip
  deflection the same load makes that is 1 / 48 = 0.021 N^-4 for a uniform load, 0.028 for
  one growing as x (a rigid rotation's inertia) and :data:`C_STATION` = 0.036 for x^2 (the
  modes' inertia grows no faster); measured (every station against 16 elements, rtol
  1e-10, N = 2..9): 0.020-0.025 on the paper's scene and on a fitted four-bar trace, where
  the tip's was 1.3e-3 and 2.5e-3 (the stations 8-20x the tip), and the tip's own on the
  spin-ups (4 and 10 rad/s, undamped: the tip is the worst station). Estimate
  ``(C_FE + C_STATION) N^-4`` plus the time error (measured on every station at fixed
  steps). ``settings["auto_station_error_estimate"]``. Paper's scene, 2.6 s, tol 1e-3,
  1e-4, 1e-5 (2, 3, 6 elements): 2.6e-3, 5.4e-4, 3.5e-5 stated for 1.3e-3, 2.8e-4,
  1.8e-5 (the tip's estimate, stated for them until 2026-11, was 2.5-3.4x short).
- **strains at the gauges**, relative to each gauge's RMS strain, with the tolerance
  ``max(tol, STRAIN_TOL_MIN)`` (a fifth of the gauges' 1 % calibration): the modal
  model's truncation check includes them; the FE's curvature is recovered from the nodes
  (:func:`sim.models.fe.recovered_curvature`: the element's own curvature converges only
  as h^2 and was 4.2 % low at the 603 mm gauge with 3 elements), the integrator runs at
  rtol <= ``STRAIN_RTOL_PER_TOL`` times that tolerance, and the error is estimated from the
  change from n to n + 1 elements (n + 1 is returned; more until the estimate is within
  tolerance; the coarser mesh runs over the first ``STRAIN_CHECK_S`` only). That change
  is the n mesh's error; the n + 1 mesh's, for errors C h^p, is r^p / (1 - r^p) of it,
  r = n / (n + 1) (Richardson, :func:`_richardson`). The recovered curvature does not
  converge smoothly: against 32 elements with 30 recovery modes (rtol 1e-10) the worst
  gauge (603 mm, where the strain is small) was off 1.0e-3, 9.2e-4, 3.0e-4, 1.6e-4,
  5.0e-4, 4.1e-4, 1.1e-4 with 3..9 elements (paper's scene; the fitted trace alike),
  the error depending on where the gauge sits between the nodes and, from 7 elements,
  on the 12-mode fit; a least-squares line through these and 24 elements gives the order
  p = :data:`STRAIN_ORDER` = 1.3 (1.5 on the trace), and the n + 1 mesh's error was
  0.34-1.46x the change (n = 3..8; the factor r^p / (1 - r^p) is 1.4 to 6 at n = 2..8).
  Paper's scene, 2.6 s, with the four gauges at tol 1e-3, 1e-4, 1e-5 (3, 5, 7 elements):
  1.4e-3, 1.8e-3, 1.5e-3 stated for 1.1e-3, 2.5e-4, 5.4e-4 against 24 elements and 24
  modes (the change alone, stated until 2026-11: 9.5e-4 and 3.4e-4, short at 1e-3 and
  1e-5; it took 4 elements at 1e-4, now 5: 3 -> 4 changes the 603 mm gauge 1.9e-3). The
  undamped spin-up at 4 rad/s (the beam given a rectangle's surface, c = 0.039 m): 1.8e-3,
  3.1e-3 (12 elements, the most), 3.1e-3 for 1.4e-3, 2.4e-3, 2.4e-3 (the change alone:
  6-8e-4 stated for 1.2e-3 to 5.5e-3). ``settings["auto_strain_error_estimate"]``,
  ``["auto_strain_tol"]``.

Paper's scene (10 s at 400 Hz): tol 1e-2 -> modal (estimate 7.7e-3, real 4.4e-3); tol 1e-3,
1e-4, 1e-5 -> FE with 2, 3, 6 elements for the tip alone; with the four gauges 3, 5, 7
(the strains' estimate 1.4e-3, 1.8e-3, 1.5e-3; the paper and the material law alike).
The rig's minute (``process``, tol 1e-4): 5 elements, the strains' estimate 1.85e-3 of
the 2e-3 tolerance (2.97x the change from 4).
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from sim.beam import BeamProperties
from sim.checks import check_choice
from sim.config import DAMPING_LAWS
from sim.drives import Drive, drive_time_scale_s
from sim.errors import IntegrationError, SimInputError
from sim.models.fe import simulate_fe
from sim.models.modal import simulate_modal
from sim.result import SimResult

logger = logging.getLogger(__name__)

C_NONLINEAR = 1.5
C_FE_UNDAMPED = 30.0  # C_FE = C_FE_UNDAMPED (delta / L)^2 / max(1, zeta_2)
# Between the nodes the Hermite cubics interpolate: |w - I_h w| <= h^4 / 384 max|w_xxxx|,
# EI w_xxxx the lateral load per length. Relative to the tip deflection that load makes, for
# a load growing as x^2 (tip (3/5 - 1/6) q_L L^4 / 6 EI): 0.036 (uniform load: 1 / 48 = 0.021,
# growing as x: 0.028); the paper's scene and a fitted four-bar trace measured 0.020-0.025
C_STATION = 6.0 / (384.0 * (3.0 / 5.0 - 1.0 / 6.0))
FE_TIME_ERROR_PER_RTOL = 0.35  # damped (a1 > 0): the stiff modes decay
FE_TIME_ERROR_PER_RTOL_UNDAMPED = 5.0  # undamped: phase errors accumulate
FE_RTOL_MAX = 1e-4  # looser, Newton's tolerance (sqrt rtol) costs rejected steps
FE_SHARE = 0.7  # of tol, for the discretisation
BETA_2 = 4.694091132974175  # second clamped-free root: w_2 = BETA_2^2 sqrt(EI / rhoA) / L^2
MAX_MODES = 10
MAX_RECOVERY_ELEMENTS = 12
# The strains need not be closer than a fifth of the gauges' calibration (gauge factor
# +-1 %): their tolerance is tol, but no tighter than this (RMS, relative to each gauge's).
STRAIN_TOL_MIN = 2e-3
# The coarse mesh of the strain check runs over the first this many seconds only (the
# scene's start-up and a few cycles at the bench's 0.92 Hz), compared on that stretch.
STRAIN_CHECK_S = 5.0
# The curvature near the tip needs a tighter integrator than the tip: at the 603 mm gauge
# (paper's scene) rtol 1e-5 leaves 2.5e-3 RMS, 1e-6 leaves 4e-4 (the mesh's share).
STRAIN_RTOL_PER_TOL = 1e-3
# The curvature recovered from the nodes converges at the gauges, measured, as about
# h^STRAIN_ORDER, not smoothly (module docstring): the change from n to n + 1 elements is
# the n mesh's error, the returned n + 1 mesh's is r^p / (1 - r^p) of it, r = n / (n + 1)
STRAIN_ORDER = 1.3
PROBE_RTOL = 1e-3
# Fixed steps (issue #19): where the beam is damped enough and the drive smooth
# (:func:`_fixed_step`), the FE runs take fixed steps of the 5-stage Radau IIA (order 9,
# closed-form stage Jacobians: :func:`sim.models.fe.simulate_fe`), at h and at h / 2:
# the h / 2 run is returned, and the change from h to h / 2 is its time error estimate
# (the h run's error, measured; the h / 2 run's own is 2^-6 to 2^-9 of it at the method's
# stage and classical orders). Halved again while that is above the time's share of the
# tolerance, adaptive below FIXED_MIN_STEP_S. 0.025 s: on the rig's run (bench four-bar
# trace, a0 = a1 = 0.1) Newton takes every step at 0.025 s but one in ten at 0.03 s
# (they are then split: :func:`sim.solvers.radau.radau5`); 0.05 s only on the paper's
# sinusoid.
FIXED_STEP_S = 0.025
FIXED_STAGES = 5
FIXED_MIN_STEP_S = 0.00625
FIXED_STEPS_PER_DRIVE_SCALE = 4
# Fixed steps where the adaptive integrator would run at this rtol or tighter (the gauged
# runs: STRAIN_RTOL_PER_TOL, 2e-6). Measured, auto on the paper's scene (5 s, CPU s,
# adaptive / fixed): without gauges (rtol 1e-4, 8.6e-5, 8.6e-6 at tol 1e-3, 1e-4, 1e-5)
# 0.07 / 0.09, 0.08 / 0.11, 0.13 / 0.21; with the four gauges (rtol 2e-6) 0.21 / 0.14,
# 0.23 / 0.16, 0.33 / 0.34 (7 elements); the rig's minute (5 elements) 0.36 / 0.20
FIXED_BELOW_RTOL = 5e-6
# The first fixed step is taken in parts from this share of it, each twice the last: from
# rest with the hub accelerating (the rig's runs) the fast modes start with a layer that a
# whole first step's dense output carries to the output times inside it, the same at h
# and at h / 2 (5.7e-7 of the tip at 2.5 and 5 ms on the rig's run, unseen by the halving)
FIXED_START = 1.0 / 64.0
# Newton's stopping tolerance at fixed steps (rtol = atol; 3e-5 or looser spoils the next
# step's predictor, see simulate_fe's ``stages``), no looser than a tenth of the time's
# share of the tolerance
FIXED_NEWTON_RTOL = 1e-7


def _rel_change(a: SimResult, b: SimResult) -> float:
    """The largest change of any station's deflection (the tip is one) relative to the
    largest tip deflection."""
    scale = max(float(np.max(np.abs(b.tip_lateral_m))), 1e-300)
    return float(np.max(np.abs(a.station_lateral_m - b.station_lateral_m)) / scale)


def _strain_change(a: SimResult, b: SimResult, n_samples: int | None = None) -> float:
    """The largest RMS change of a gauge's strain history relative to that gauge's RMS
    strain. RMS, not the largest sample: near the tip the strain is small and its zero
    crossings carry the integrator's error (paper's scene, 603 mm gauge: 9.5 % at one
    instant for 0.3 % RMS at rtol 8.6e-5)."""
    if b.strain.shape[1] == 0:
        return 0.0
    n = min(a.strain.shape[0], b.strain.shape[0]) if n_samples is None else n_samples
    sa, sb = a.strain[:n], b.strain[:n]
    scale = np.maximum(np.sqrt(np.mean(sb**2, axis=0)), 1e-300)
    return float(np.max(np.sqrt(np.mean((sa - sb) ** 2, axis=0)) / scale))


def _richardson(n_coarse: int, order: float = STRAIN_ORDER) -> float:
    """The error of the n + 1 mesh per change from the n mesh, for errors C h^order:
    e_(n+1) = change r^p / (1 - r^p), r = n / (n + 1) (Richardson)."""
    r = (n_coarse / (n_coarse + 1.0)) ** order
    return r / (1.0 - r)


def _zeta_2(beam: BeamProperties, a0: float, a1: float) -> float:
    """The second bending mode's damping ratio under Eq. 28's a0 M + a1 K."""
    w2 = BETA_2**2 * math.sqrt(beam.bending_stiffness_n_m2 / beam.mass_per_length_kg_m)
    w2 /= beam.length_m**2
    return a0 / (2.0 * w2) + a1 * w2 / 2.0


def _fe_constant(beam: BeamProperties, delta_m: float, a0: float, a1: float) -> float:
    """C_FE of the discretisation estimate C_FE N^-4 (see the module docstring)."""
    return C_FE_UNDAMPED * (delta_m / beam.length_m) ** 2 / max(1.0, _zeta_2(beam, a0, a1))


def _fixed_step(
    beam: BeamProperties, drive: Drive, a0: float, a1: float, rtol: float = 0.0
) -> float | None:
    """The first fixed step of the FE runs, s, or None where they run adaptive: the
    adaptive integrator's ``rtol`` at most :data:`FIXED_BELOW_RTOL` (looser, it is the
    cheaper), the second bending mode overdamped (the modes above it respond
    quasi-statically and the L-stable method damps their start-up in a step; an undamped
    beam's fast modes would have to be resolved), the drive's shortest time scale known
    and at least :data:`FIXED_STEPS_PER_DRIVE_SCALE` steps of :data:`FIXED_MIN_STEP_S`."""
    if rtol > FIXED_BELOW_RTOL or a1 <= 0.0 or _zeta_2(beam, a0, a1) < 1.0:
        return None
    scale = drive_time_scale_s(drive)
    if scale is None:
        return None
    step = min(FIXED_STEP_S, scale / FIXED_STEPS_PER_DRIVE_SCALE)
    return step if step >= 2.0 * FIXED_MIN_STEP_S else None


def _fe_elements(c_fe: float, budget: float) -> int:
    n = max(2, math.ceil((c_fe / budget) ** 0.25 - 1e-9))
    return min(n, 64)


class _TimeErrorTooLarge(Exception):
    """The fixed steps' measured time error stays above its share of the tolerance."""


@dataclass(frozen=True)
class _FeRun:
    """An FE run of ``auto`` with its time-integration error estimate: ``time_error`` of
    the stations' deflections (relative to the largest tip deflection), and
    ``strain_time_error`` of the gauges' strains (RMS, relative to each gauge's RMS)."""

    result: SimResult
    time_error: float
    strain_time_error: float
    step_s: float | None  # the result's fixed step; None: adaptive
    runner: _FeRunner

    def again(self, n_elements: int, t_s: np.ndarray) -> _FeRun:
        return self.runner.run(n_elements, t_s)

    def describe(self) -> str:
        if self.step_s is None:
            return (
                f"adaptive radau5 at rtol {self.runner.rtol:.2g}, time error "
                f"~{self.time_error:.2g} ({self.runner.time_per_rtol:g} rtol)"
            )
        return (
            f"{FIXED_STAGES}-stage Radau IIA at fixed {self.step_s:g} s steps, time error "
            f"{self.time_error:.2g} (strains {self.strain_time_error:.2g}), the change "
            f"from {2.0 * self.step_s:g} s"
        )

    def settings(self) -> dict[str, Any]:
        if self.step_s is None:
            return {
                "method": "radau5 adaptive",
                "rtol": self.runner.rtol,
                "estimate": f"{self.runner.time_per_rtol:g} rtol",
            }
        return {
            "method": f"radau IIA {FIXED_STAGES} stages, fixed step",
            "step_s": self.step_s,
            "estimate": f"the change from step {2.0 * self.step_s:g} s",
            "time_error": self.time_error,
            "strain_time_error": self.strain_time_error,
        }


class _FeRunner:
    """The FE runs of ``auto``: at fixed steps from ``step_s`` (halved while the measured
    time error is above ``budget``, see :data:`FIXED_STEP_S`) or, with ``step_s`` None
    or once the fixed steps fail, adaptive radau5 at ``rtol`` (time error
    ``time_per_rtol`` rtol, measured)."""

    def __init__(
        self,
        beam: BeamProperties,
        drive: Drive,
        common: dict[str, Any],
        rtol: float,
        time_per_run: float,
        budget: tuple[float, float],
    ) -> None:
        self.beam, self.drive, self.common = beam, drive, common
        self.rtol = rtol
        self.time_per_rtol = time_per_run / rtol
        self.time_per_run = time_per_run
        self.budget = budget
        self.newton_rtol = min(FIXED_NEWTON_RTOL, 0.1 * budget[0])
        self.step_s: float | None = None

    def _simulate(self, n_elements: int, t_s: np.ndarray, step_s: float | None) -> SimResult:
        if step_s is None:
            return simulate_fe(
                self.beam, self.drive, t_s, n_elements=n_elements, rtol=self.rtol,
                atol=self.rtol, method="radau5", curvature="recovered", **self.common,
            )  # fmt: skip
        return simulate_fe(
            self.beam, self.drive, t_s, n_elements=n_elements, rtol=self.newton_rtol,
            atol=self.newton_rtol, method="radau5", curvature="recovered",
            fixed_step_s=step_s, stages=FIXED_STAGES, first_step_s=step_s * FIXED_START,
            **self.common,
        )  # fmt: skip

    def _adaptive(self, n_elements: int, t_s: np.ndarray) -> _FeRun:
        res = self._simulate(n_elements, t_s, None)
        return _FeRun(res, self.time_per_run, self.time_per_run, None, self)

    def single(self, n_elements: int, t_s: np.ndarray) -> _FeRun:
        """One run at the first fixed step (or adaptive), its time error not estimated:
        the coarse mesh of the strain check, whose change to the finer mesh holds it."""
        if self.step_s is not None:
            try:
                res = self._simulate(n_elements, t_s, self.step_s)
                return _FeRun(res, math.nan, math.nan, self.step_s, self)
            except IntegrationError as exc:
                self._give_up(exc)
        return self._adaptive(n_elements, t_s)

    def run(self, n_elements: int, t_s: np.ndarray) -> _FeRun:
        """The run returned, with its time error estimated."""
        if self.step_s is not None:
            try:
                return self._halved(n_elements, t_s, self.step_s)
            except (IntegrationError, _TimeErrorTooLarge) as exc:
                self._give_up(exc)
        return self._adaptive(n_elements, t_s)

    def _give_up(self, exc: Exception) -> None:
        logger.info("auto: fixed steps from %.3g s not taken (%s): adaptive", self.step_s, exc)
        self.step_s = None

    def _halved(self, n_elements: int, t_s: np.ndarray, step_s: float) -> _FeRun:
        coarse = self._simulate(n_elements, t_s, step_s)
        while True:
            fine = self._simulate(n_elements, t_s, 0.5 * step_s)
            e_time = _rel_change(coarse, fine)
            e_strain = _strain_change(coarse, fine)
            if e_time <= self.budget[0] and e_strain <= self.budget[1]:
                self.step_s = step_s  # a finer mesh starts here
                return _FeRun(fine, e_time, e_strain, 0.5 * step_s, self)
            if 0.25 * step_s < FIXED_MIN_STEP_S:
                raise _TimeErrorTooLarge(
                    f"{e_time:.2g} (strains {e_strain:.2g}) from {step_s:g} to {0.5 * step_s:g} s"
                )
            step_s *= 0.5
            coarse = fine


def _tension_lag(drive: Drive, t_s: np.ndarray, a1: float) -> float:
    """mean |Omega^2 - s| / mean Omega^2 with a1 s' + s = Omega^2, s(t0) = 0: how far the
    elastic (Kelvin-Voigt) part of the centrifugal tension lags the applied one."""
    om2 = np.asarray(drive.rate(t_s), dtype=float) ** 2
    mean = float(np.mean(om2))
    if a1 == 0.0 or t_s.size < 2 or mean == 0.0:
        return 0.0
    # exact for Omega^2 linear between the samples
    s = np.zeros_like(om2)
    for k in range(1, t_s.size):
        x = (t_s[k] - t_s[k - 1]) / a1
        e = math.exp(-x)
        b = (1.0 - e) / x if x > 0 else 1.0
        s[k] = e * s[k - 1] + (b - e) * om2[k - 1] + (1.0 - b) * om2[k]
    return float(np.mean(np.abs(om2 - s)) / mean)


def simulate_auto(
    beam: BeamProperties,
    drive: Drive,
    t_eval_s: ArrayLike,
    *,
    tol: float = 1e-4,
    a0_per_s: float = 0.0,
    a1_s: float = 0.0,
    gauge_positions_m: Sequence[float] | ArrayLike = (),
    n_stations: int = 21,
    damping_law: str = "paper",
) -> SimResult:
    """Simulate with the cheapest model whose estimated error is below ``tol``.

    Parameters
    ----------
    beam, drive, t_eval_s, a0_per_s, a1_s, gauge_positions_m, n_stations, damping_law :
        as :func:`sim.models.fe.simulate_fe`.
    tol : requested relative error of the tip deflection history (max |error| / max |tip|),
        in (0, 0.5).

    Returns
    -------
    SimResult
        from the chosen model, with ``settings["auto_choice"]`` (e.g. ``"modal n_modes=5"``
        or ``"fe-corot n_elements=4"``), ``settings["auto_error_estimate"]`` (the estimate,
        relative), ``settings["auto_reason"]`` (one sentence) and
        ``settings["auto_parts"]`` (the parts), ``settings["auto_station_error_estimate"]``
        and ``settings["auto_strain_error_estimate"]``, ``settings["auto_time_integration"]``
        (the FE's integrator, fixed step or adaptive, and how its time error is estimated;
        see the module docstring).
        ``wall_time_s`` includes the trial runs that made the choice.
    """
    t_tol = float(tol)
    if not math.isfinite(t_tol) or not 0.0 < t_tol < 0.5:
        raise SimInputError("tol", f"must be in (0, 0.5), got {tol!r}")
    s_tol = max(t_tol, STRAIN_TOL_MIN)
    common: dict[str, Any] = {
        "a0_per_s": a0_per_s,
        "a1_s": a1_s,
        "gauge_positions_m": gauge_positions_m,
        "n_stations": n_stations,
        "damping_law": check_choice("damping_law", damping_law, DAMPING_LAWS),
    }
    rtol_modal = max(t_tol / 20.0, 1e-12)
    a0, a1 = float(a0_per_s), float(a1_s)
    t0 = time.perf_counter()
    # the deflection only needs a few per cent: one loose 3-mode run (it is the first
    # step of the truncation check too when that runs no tighter)
    rtol_probe = max(PROBE_RTOL, rtol_modal)
    probe = simulate_modal(beam, drive, t_eval_s, n_modes=3, rtol=rtol_probe, **common)
    delta = float(np.max(np.abs(probe.tip_lateral_m)))
    e_nl = C_NONLINEAR * (delta / beam.length_m) ** 2
    e_time = rtol_modal
    e_kv = e_trunc = e_strain_trunc = 0.0
    n = 3
    modal: SimResult | None = None
    if e_nl + e_time < t_tol:
        if rtol_probe == rtol_modal:
            prev = probe
        else:
            prev = simulate_modal(beam, drive, t_eval_s, n_modes=n, rtol=rtol_modal, **common)
        while True:
            modal = simulate_modal(beam, drive, t_eval_s, n_modes=n + 1, rtol=rtol_modal, **common)
            e_trunc = _rel_change(prev, modal)
            e_strain_trunc = _strain_change(prev, modal)
            converged = e_trunc < t_tol / 3.0 and e_strain_trunc < s_tol / 3.0
            if converged or n + 1 >= MAX_MODES:
                break
            prev, n = modal, n + 1
        # the material law has no tension in its damping, so nothing lags (module docstring)
        if a1 > 0.0 and damping_law == "paper" and e_nl + e_trunc + e_time < t_tol:
            kd = simulate_modal(
                beam, drive, t_eval_s, n_modes=n + 1, rtol=rtol_modal,
                **{**common, "damping_law": "material"},
            )  # fmt: skip
            t_arr = np.asarray(t_eval_s, dtype=float)
            e_kv = _rel_change(kd, modal) * _tension_lag(drive, t_arr, a1)
    estimate = e_nl + e_kv + e_trunc + e_time
    # the strains carry the same model errors, relative to each gauge's amplitude
    strain_estimate = e_nl + e_kv + e_strain_trunc + e_time
    parts = {"nonlinear": e_nl, "tension_lag": e_kv, "truncation": e_trunc, "time": e_time}
    time_settings: dict[str, Any] = {"method": "modal, adaptive", "estimate": "rtol"}
    # the modal truncation check compares every station (the tip is one)
    station_estimate = estimate
    if modal is not None and estimate <= t_tol and strain_estimate <= s_tol:
        result = modal
        choice = f"modal n_modes={n + 1}"
        reason = (
            f"tip deflection / length = {delta / beam.length_m:.3g}: geometric nonlinearity "
            f"~{e_nl:.2g}, Kelvin-Voigt tension lag ~{e_kv:.2g}, truncation at {n} modes "
            f"{e_trunc:.2g} (strains {e_strain_trunc:.2g}), below tol {t_tol:.2g}"
        )
    else:
        c_fe = _fe_constant(beam, delta, a0, a1)
        ne = _fe_elements(c_fe, FE_SHARE * t_tol)
        time_per_rtol = FE_TIME_ERROR_PER_RTOL if a1 > 0.0 else FE_TIME_ERROR_PER_RTOL_UNDAMPED
        rtol_fe = max(min((1.0 - FE_SHARE) * t_tol / time_per_rtol, FE_RTOL_MAX), 1e-11)
        if np.size(gauge_positions_m):
            rtol_fe = min(rtol_fe, STRAIN_RTOL_PER_TOL * s_tol)
        t_all = np.asarray(t_eval_s, dtype=float)
        head = t_all <= t_all[0] + STRAIN_CHECK_S
        gauged = bool(np.size(gauge_positions_m))
        budget = ((1.0 - FE_SHARE) * t_tol, (1.0 - FE_SHARE) * s_tol)
        time_per_run = time_per_rtol * rtol_fe
        runner = _FeRunner(beam, drive, common, rtol_fe, time_per_run, budget)
        runner.step_s = _fixed_step(beam, drive, a0, a1, rtol_fe)
        # the first run: the coarse mesh of the strain check (over its head) or the result
        fe_run = runner.single(ne, t_all[head]) if gauged else runner.run(ne, t_all)
        # the strains: curvature recovered from the nodes, its error estimated from the
        # change from n to n + 1 elements (the n mesh's error), Richardson-corrected to
        # the n + 1 mesh's, the one returned
        strain_estimate = 0.0
        while gauged:
            coarse = fe_run.result
            ne += 1
            fe_run = fe_run.again(ne, t_all)
            strain_change = _strain_change(coarse, fe_run.result, int(np.count_nonzero(head)))
            strain_estimate = strain_change * _richardson(ne - 1) + fe_run.strain_time_error
            if strain_estimate <= s_tol or ne >= MAX_RECOVERY_ELEMENTS:
                break
        result = fe_run.result
        e_fe_time = fe_run.time_error
        e_fe = c_fe * ne**-4.0
        parts = {"discretisation": e_fe, "time": e_fe_time}
        modal_estimate = estimate
        estimate = e_fe + e_fe_time
        # the stations between the nodes: the nodes' error plus the cubics' interpolation
        station_estimate = (c_fe + C_STATION) * ne**-4.0 + e_fe_time
        choice = f"fe-corot n_elements={ne}"
        reason = (
            f"modal estimate {modal_estimate:.2g} above tol {t_tol:.2g} (tip deflection / "
            f"length = {delta / beam.length_m:.3g}: geometric nonlinearity ~{e_nl:.2g}, "
            f"Kelvin-Voigt tension lag ~{e_kv:.2g}); exact FE with {ne} elements, "
            f"curvature recovered from the nodes (strains ~{strain_estimate:.2g} RMS: "
            f"{_richardson(ne - 1):.3g} times the change from {ne - 1} elements, "
            f"Richardson for h^{STRAIN_ORDER:g}); {fe_run.describe()}"
        )
        time_settings = fe_run.settings()
    wall = time.perf_counter() - t0
    logger.info("auto: %s (estimate %.3g): %s", choice, estimate, reason)
    if strain_estimate > s_tol:
        # the mesh stopped at its cap: the strains are stated as they are, and said so
        logger.warning(
            "auto: the gauges' strains are estimated off by %.2g of their RMS, above their "
            "tolerance %.2g, with the most elements auto uses (%d)",
            strain_estimate,
            s_tol,
            MAX_RECOVERY_ELEMENTS,
        )
    settings = dict(result.settings)
    settings.update(
        {
            "auto_choice": choice,
            "auto_error_estimate": float(estimate),
            "auto_reason": reason,
            "auto_parts": parts,
            "auto_tol": t_tol,
            # relative to the largest tip deflection (the tip is one of the stations)
            "auto_station_error_estimate": float(station_estimate),
            "auto_strain_error_estimate": float(strain_estimate),
            "auto_strain_tol": s_tol,
            "auto_time_integration": time_settings,
            "solve_wall_time_s": result.wall_time_s,
        }
    )
    return SimResult(
        time_s=result.time_s,
        hub_angle_rad=result.hub_angle_rad,
        tip_lateral_m=result.tip_lateral_m,
        tip_longitudinal_m=result.tip_longitudinal_m,
        stations_m=result.stations_m,
        station_lateral_m=result.station_lateral_m,
        station_longitudinal_m=result.station_longitudinal_m,
        gauge_positions_m=result.gauge_positions_m,
        strain=result.strain,
        model=f"auto:{result.model}",
        wall_time_s=wall,
        settings=settings,
    )
