"""How accurate the simulation of a run must be: its error below the image measurement's.

The comparison image - simulation can only show the bench's disagreement with the model if
the simulation's own (numerical) error is well below what the image resolves. So by default
``process`` asks ``auto`` for a tip error no larger than :data:`IMAGE_SHARE` (a fifth) of
the image measurement's RMS stated uncertainty on that run (each frame's
``tip_lateral_std_m``, from its edge fits), or :data:`NO_FRAMES_TOL` of the tip amplitude
when the run has no measured frame. A fifth: added in quadrature to the image's own error
it grows the expected RMS difference by at most 2 %.

The simulation runs in a thread while the frames are measured, so the image's uncertainty
is known only afterwards. The simulation first runs at :data:`PRIOR_SIM_TOL`, a
tolerance chosen a priori from the camera; afterwards :func:`check_tolerance` compares
``auto``'s own error estimate with what the frames ask for, and only if the estimate is
larger is the run simulated again (after the frames, so it costs wall time).

Why 1e-4 of the tip a priori: the image resolves a fraction of a pixel (the bench's camera:
0.95 mm per pixel at the beam, per-frame tip uncertainties of ~0.04 mm = 0.04 px on the
synthetic bench); a fifth of it on a ~45 mm tip is ~2e-4, and 1e-4 (5 micrometres, 1/200 px)
covers an image twice as good. It costs little more than a looser one: ``auto`` picks the
exact FE beam for any tolerance below its modal model's ~1 % (geometric nonlinearity and the
Kelvin-Voigt tension lag), and the FE's cost is set mostly by the integrator tolerance its
strains at the gauges need, not by the tip's (:mod:`sim.models.model_choice`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from pipelines.process.frames import MeasuredFrame
from sim.beam import BeamProperties
from sim.modes import modal_integrals
from sim.result import SimResult
from sim.trace_fit import FittedTraceDrive, spline_passband

IMAGE_SHARE = 0.2
# modes of the linear transfer function the drive's uncertainty is carried through
DRIVE_ERROR_MODES = 4
# the spline's passed noise is integrated up to this many over its knot spacing (its
# passband at 1.5 / h: 1e-6), on this many frequencies (the lightly damped first mode's
# resonance is ~0.08 Hz wide: 0.004 Hz apart at h = 0.02 s)
SPLINE_BAND_WIDTHS = 1.5
SPLINE_BAND_POINTS = 20001
NO_FRAMES_TOL = 1e-3
PRIOR_SIM_TOL = 1e-4
# auto's tolerance must lie in (0, 0.5); tighter than this the FE's time integration
# reaches its own floor (sim.models.model_choice: rtol >= 1e-11)
MIN_SIM_TOL = 1e-8
MAX_SIM_TOL = 0.2


def drive_tip_uncertainty_m(
    beam: BeamProperties,
    drive: FittedTraceDrive,
    t_s: np.ndarray,
    a0_per_s: float,
    a1_s: float,
    damping_law: str,
) -> float:
    """The RMS tip error the fitted drive's own uncertainty causes (m); NaN when the fit
    gives no estimate of it.

    Each kept harmonic m of the hub angle carries a coefficient noise of variance V (the
    pot's noise at that frequency over the run: shorter runs, more of it), each dropped
    one its fitted power; a spline (a run that does not repeat) passes the pot's noise
    PSD S through its passband R (:meth:`FittedTraceDrive.spline_uncertainty`,
    :func:`sim.trace_fit.spline_passband`). Both reach the
    tip through the linear beam at each frequency,
    ``H(W) = W^2 phi_tip^T (K_e - W^2 M + i W C)^-1 b`` (assumed modes, Euler load
    ``-theta'' b``; the centrifugal stiffening with the run's mean square hub rate,
    ``K_e = K + <theta'^2> (G - M)``; ``C = a0 M + a1 K`` plus ``a1 <theta'^2> G`` for
    the paper's law): ``sum |H(m w)|^2 P_m`` over the harmonics plus
    ``int |H(2 pi f)|^2 R(f) S df`` for the spline. Near the first mode (3.7 Hz) the
    pot's noise matters most."""
    found = drive.harmonic_uncertainty()
    spline = drive.spline_uncertainty()
    harmonic_ok = found is not None and math.isfinite(found[2])
    spline_ok = spline is not None and all(math.isfinite(x) for x in spline)
    if not (harmonic_ok or spline_ok):
        return math.nan
    mi = modal_integrals(
        beam.length_m,
        beam.hub_offset_m,
        beam.mass_per_length_kg_m,
        beam.bending_stiffness_n_m2,
        DRIVE_ERROR_MODES,
    )
    rate_sq = float(np.mean(drive.rate(t_s) ** 2))
    k_e = mi.stiffness + rate_sq * (mi.centrifugal - mi.mass)
    c = a0_per_s * mi.mass + a1_s * mi.stiffness
    if damping_law == "paper":
        c = c + a1_s * rate_sq * mi.centrifugal

    def gain_sq(w: np.ndarray) -> np.ndarray:
        """|H(w)|^2 at the angular frequencies ``w`` (rad/s)."""
        a = k_e[None] - (w * w)[:, None, None] * mi.mass[None] + 1j * w[:, None, None] * c[None]
        q = np.linalg.solve(a, (w * w)[:, None, None] * mi.euler[None, :, None])[..., 0]
        return np.abs(q @ mi.tip_shape) ** 2

    total = 0.0
    if found is not None and harmonic_ok:
        omega, kept, var, dropped = found
        m = np.arange(1, kept + dropped.size + 1)
        power = np.r_[np.full(kept, var), dropped]
        total += float(np.sum(gain_sq(m * omega) * power))
    if spline is not None and spline_ok:
        spacing_s, psd = spline
        f = np.linspace(0.0, SPLINE_BAND_WIDTHS / spacing_s, SPLINE_BAND_POINTS)
        passed = gain_sq(2.0 * math.pi * f) * spline_passband(f, spacing_s)
        total += float(np.trapezoid(passed, f)) * psd
    return math.sqrt(total)


def image_tip_sd_rms_m(frames: list[MeasuredFrame]) -> float:
    """RMS of the measured frames' stated tip uncertainties (m); NaN without any."""
    sd = np.array(
        [f.measurement.tip_lateral_std_m for f in frames if f.measurement.ok], dtype=float
    )
    sd = sd[np.isfinite(sd)]
    return float(np.sqrt(np.mean(sd**2))) if sd.size else math.nan


def tip_scale_m(sim: SimResult) -> float:
    """The largest simulated tip deflection: what ``auto``'s relative error refers to."""
    tip = np.asarray(sim.tip_lateral_m, dtype=float)
    tip = tip[np.isfinite(tip)]
    return float(np.max(np.abs(tip))) if tip.size else math.nan


@dataclass(frozen=True)
class ToleranceChoice:
    """The simulation's tolerance for a run, where it came from, and what ``auto`` estimated.

    ``rule``: one sentence. ``tol``: the relative tip tolerance asked of ``auto`` in the end
    (NaN: not ``auto``). ``tip_tol_m``: that tolerance in metres. ``image_sd_rms_m``: the
    frames' RMS stated tip uncertainty. ``estimate_rel`` / ``estimate_m``: ``auto``'s
    estimate of the simulation's tip error (max over the run, relative to the largest tip
    deflection / in metres). ``resimulated``: the a-priori run was not good enough.
    ``drive_sd_m``: the RMS tip error the fitted drive's uncertainty causes
    (:func:`drive_tip_uncertainty_m`; not in ``auto``'s estimate)."""

    rule: str
    tol: float
    tip_tol_m: float
    image_sd_rms_m: float
    estimate_rel: float
    estimate_m: float
    resimulated: bool
    prior_tol: float
    drive_sd_m: float = math.nan

    def as_attrs(self) -> dict[str, Any]:
        return {
            "sim_tol_rule": self.rule,
            "sim_tol": self.tol,
            "sim_tip_tol_m": self.tip_tol_m,
            "sim_prior_tol": self.prior_tol,
            "image_tip_lateral_sd_rms_m": self.image_sd_rms_m,
            "sim_tip_error_estimate_rel": self.estimate_rel,
            "sim_tip_error_estimate_m": self.estimate_m,
            "sim_resimulated": int(self.resimulated),
            "sim_drive_tip_uncertainty_m": self.drive_sd_m,
        }


def drive_sd_of(sim: SimResult) -> float:
    """The drive's tip uncertainty recorded by ``simulate_measured`` (NaN if none)."""
    drive = sim.settings.get("drive", {})
    try:
        return float(drive.get("tip_uncertainty_m", math.nan))
    except (AttributeError, TypeError, ValueError):
        return math.nan


def auto_estimate(sim: SimResult) -> float:
    """``auto``'s relative tip error estimate (NaN for another model), plus the change
    between the last two simulated periods and the interpolation's estimated error in
    the last when the run was simulated to its periodic steady state only
    (:mod:`pipelines.process.steady_state`)."""
    value = sim.settings.get("auto_error_estimate", math.nan)
    steady = sim.settings.get("steady_state", {})
    try:
        return (
            float(value)
            + float(steady.get("cycle_change_rel", 0.0))
            + float(steady.get("interpolation_rel", 0.0))
        )
    except (AttributeError, TypeError, ValueError):
        return math.nan


def required_tol(image_sd_rms_m: float, scale_m: float) -> tuple[float, str]:
    """The relative tolerance the frames ask for, and the rule that gave it."""
    if math.isfinite(image_sd_rms_m) and image_sd_rms_m > 0 and scale_m > 0:
        tol = IMAGE_SHARE * image_sd_rms_m / scale_m
        rule = (
            f"a fifth of the image's RMS tip uncertainty ({image_sd_rms_m * 1e3:.4f} mm) "
            f"on a {scale_m * 1e3:.2f} mm tip"
        )
    else:
        tol = NO_FRAMES_TOL
        rule = f"{NO_FRAMES_TOL:g} of the tip amplitude (no frame with a stated uncertainty)"
    return min(max(tol, MIN_SIM_TOL), MAX_SIM_TOL), rule


def check_tolerance(
    sim: SimResult, frames: list[MeasuredFrame], prior_tol: float
) -> tuple[ToleranceChoice, float | None]:
    """After the frames: is the a-priori simulation (``auto`` at ``prior_tol``) accurate
    enough? Returns the choice and the tolerance to simulate again at (None: keep it)."""
    sd = image_tip_sd_rms_m(frames)
    scale = tip_scale_m(sim)
    tol, rule = required_tol(sd, scale)
    est = auto_estimate(sim)
    again = None if est <= tol else tol
    choice = ToleranceChoice(
        rule=rule,
        tol=prior_tol if again is None else tol,
        tip_tol_m=tol * scale,
        image_sd_rms_m=sd,
        estimate_rel=est,
        estimate_m=est * scale,
        resimulated=again is not None,
        prior_tol=prior_tol,
        drive_sd_m=drive_sd_of(sim),
    )
    return choice, again


def after_resimulation(choice: ToleranceChoice, sim: SimResult) -> ToleranceChoice:
    """The choice with the estimate of the simulation run again."""
    est = auto_estimate(sim)
    scale = tip_scale_m(sim)
    return ToleranceChoice(
        rule=choice.rule,
        tol=choice.tol,
        tip_tol_m=choice.tip_tol_m,
        image_sd_rms_m=choice.image_sd_rms_m,
        estimate_rel=est,
        estimate_m=est * scale,
        resimulated=True,
        prior_tol=choice.prior_tol,
        drive_sd_m=drive_sd_of(sim),
    )


def fixed_choice(
    rule: str, sim: SimResult, frames: list[MeasuredFrame], tol: float
) -> ToleranceChoice:
    """The record when the tolerance was not the image's (``--sim-tol``, another model,
    a free decay): what was asked and what the model estimated, if it says."""
    est = auto_estimate(sim)
    scale = tip_scale_m(sim)
    return ToleranceChoice(
        rule=rule,
        tol=tol,
        tip_tol_m=tol * scale,
        image_sd_rms_m=image_tip_sd_rms_m(frames),
        estimate_rel=est,
        estimate_m=est * scale,
        resimulated=False,
        prior_tol=math.nan,
        drive_sd_m=drive_sd_of(sim),
    )
