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
- **time integration**: the modal solver's rtol is set to tol / 20.

If the modal estimate is below tol the modal model runs with n + 1 modes. Otherwise the
exact finite elements (``corot``, Radau IIA with full Newton, :mod:`sim.solvers.radau`) run with the
fewest elements N whose discretisation estimate ``C_FE N^-4`` (Hermite cubics: h^4) is
below 0.7 tol, with ``C_FE = 30 (delta/L)^2 / max(1, zeta_2)``: 30 (delta/L)^2 fits the
undamped spin-ups (measured C = 28 and 30 at delta/L = 0.04 and 0.086), and when the second
bending mode is overdamped (zeta_2 = a0 / (2 w_2) + a1 w_2 / 2 > 1) the higher modes respond
quasi-statically and the error drops (paper scene: measured C = 1.2e-3, estimate 5.6e-3).
The integrator runs at rtol = atol = tol (atol in m and m/s); its global error, measured,
is about 0.35 rtol.

Every output is answered for, not only the tip:

- **stations**: the truncation check compares every station's deflection (the tip is one),
  relative to the largest tip deflection; the FE's displacements converge as h^4
  everywhere. ``settings["auto_station_error_estimate"]``.
- **strains at the gauges**, relative to each gauge's RMS strain, with the tolerance
  ``max(tol, STRAIN_TOL_MIN)`` (a fifth of the gauges' 1 % calibration): the modal
  model's truncation check includes them; the FE's curvature is recovered from the nodes
  (:func:`sim.models.fe.recovered_curvature`: the element's own curvature converges only
  as h^2 and was 4.2 % low at the 603 mm gauge with 3 elements), the integrator runs at
  rtol <= ``STRAIN_RTOL_PER_TOL`` times that tolerance, and the error is estimated by the
  change from n to n + 1 elements (n + 1 is returned; more until the change is within
  tolerance; the coarser mesh runs over the first ``STRAIN_CHECK_S`` only).
  ``settings["auto_strain_error_estimate"]``, ``["auto_strain_tol"]``.

Paper's scene: tol 1e-2 -> modal (estimate 7.7e-3, real 4.4e-3); tol 1e-3 and 1e-4 -> FE
with 3 elements for the tip alone; with the gauges 4 (paper law: 3 -> 4 changes the 603 mm
gauge by 1.9e-3 RMS) or 5 (material law, 2.0e-3 from 3 to 4), every gauge's fundamental
amplitude then within 8e-5 of 16 elements.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from sim.beam import BeamProperties
from sim.checks import check_choice
from sim.config import DAMPING_LAWS
from sim.drives import Drive
from sim.errors import SimInputError
from sim.models.fe import simulate_fe
from sim.models.modal import simulate_modal
from sim.result import SimResult

logger = logging.getLogger(__name__)

C_NONLINEAR = 1.5
C_FE_UNDAMPED = 30.0  # C_FE = C_FE_UNDAMPED (delta / L)^2 / max(1, zeta_2)
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
PROBE_RTOL = 1e-3


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


def _fe_constant(beam: BeamProperties, delta_m: float, a0: float, a1: float) -> float:
    """C_FE of the discretisation estimate C_FE N^-4 (see the module docstring)."""
    w2 = BETA_2**2 * math.sqrt(beam.bending_stiffness_n_m2 / beam.mass_per_length_kg_m)
    w2 /= beam.length_m**2
    zeta_2 = a0 / (2.0 * w2) + a1 * w2 / 2.0
    return C_FE_UNDAMPED * (delta_m / beam.length_m) ** 2 / max(1.0, zeta_2)


def _fe_elements(c_fe: float, budget: float) -> int:
    n = max(2, math.ceil((c_fe / budget) ** 0.25 - 1e-9))
    return min(n, 64)


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
        and ``settings["auto_strain_error_estimate"]`` (see the module docstring).
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
        e_fe_time = time_per_rtol * rtol_fe
        # the strains: curvature recovered from the nodes, its error estimated by the
        # change from n to n + 1 elements (the n + 1 run is the one returned)
        t_all = np.asarray(t_eval_s, dtype=float)
        head = t_all <= t_all[0] + STRAIN_CHECK_S
        strain_estimate = 0.0
        gauged = bool(np.size(gauge_positions_m))
        result = simulate_fe(
            beam, drive, t_all[head] if gauged else t_all, n_elements=ne, rtol=rtol_fe,
            atol=rtol_fe, method="radau5", curvature="recovered", **common,
        )  # fmt: skip
        while gauged:
            coarse = result
            ne += 1
            result = simulate_fe(
                beam, drive, t_all, n_elements=ne, rtol=rtol_fe, atol=rtol_fe,
                method="radau5", curvature="recovered", **common,
            )  # fmt: skip
            strain_estimate = _strain_change(coarse, result, int(np.count_nonzero(head)))
            strain_estimate += e_fe_time
            if strain_estimate <= s_tol or ne >= MAX_RECOVERY_ELEMENTS:
                break
        e_fe = c_fe * ne**-4.0
        parts = {"discretisation": e_fe, "time": e_fe_time}
        modal_estimate = estimate
        estimate = e_fe + e_fe_time
        choice = f"fe-corot n_elements={ne}"
        reason = (
            f"modal estimate {modal_estimate:.2g} above tol {t_tol:.2g} (tip deflection / "
            f"length = {delta / beam.length_m:.3g}: geometric nonlinearity ~{e_nl:.2g}, "
            f"Kelvin-Voigt tension lag ~{e_kv:.2g}); exact FE with {ne} elements, "
            f"curvature recovered from the nodes (strains ~{strain_estimate:.2g} RMS, the "
            f"change from {ne - 1} elements)"
        )
    wall = time.perf_counter() - t0
    logger.info("auto: %s (estimate %.3g): %s", choice, estimate, reason)
    settings = dict(result.settings)
    settings.update(
        {
            "auto_choice": choice,
            "auto_error_estimate": float(estimate),
            "auto_reason": reason,
            "auto_parts": parts,
            "auto_tol": t_tol,
            # the stations' deflections are estimated and controlled with the tip's
            # (relative to the largest tip deflection; the tip is one of them)
            "auto_station_error_estimate": float(estimate),
            "auto_strain_error_estimate": float(strain_estimate),
            "auto_strain_tol": s_tol,
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
