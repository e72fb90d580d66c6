"""``auto``: the cheapest beam model whose estimated error for the scene is below ``tol``.

The estimate is a sum of three parts, each relative to the largest tip deflection:

- **geometric nonlinearity** (what the linear modal model leaves out, with its centrifugal
  stiffening kept): ``C_NL (delta / L)^2`` with delta the largest tip deflection of a quick
  modal run. C_NL = 5 is calibrated on two exact cases: the static tip load (the elastica is
  0.95 % below PL^3/3EI at delta/L = 0.097, C = 1.0) and the paper's reciprocating scene
  (exact FE vs modal 0.44 % at delta/L = 0.037, C = 3.2; part of it is how Eq. 28 damps the
  centrifugal tension), with margin.
- **modal truncation**: the change of the tip history from n to n + 1 modes.
- **time integration**: the modal solver's rtol is set to tol / 20.

If the modal estimate is below tol the modal model runs with n + 1 modes (its truncation
error is then below the n-mode estimate). Otherwise the exact finite elements (``corot``)
run with the fewest elements whose discretisation error estimate ``C_FE N^-4`` (Hermite
cubics: h^4) is below tol / 2. C_FE = 0.25 is set by the worst scene measured, the
spin-up at 10 rad/s (2 elements: 1.35 % off); on the reciprocating scene it is ~1.5e-3,
so there the estimate is very pessimistic. The integrator tolerance is tol * 1e-4 (BDF's
global error on these stiff runs is 10^2-10^3 times its local rtol, measured).
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
from sim.drives import Drive
from sim.fe import simulate_fe
from sim.modal import simulate_modal
from sim.result import SimResult

logger = logging.getLogger(__name__)

C_NONLINEAR = 5.0
C_FE = 0.25
MAX_MODES = 10


def _rel_change(a: SimResult, b: SimResult) -> float:
    scale = max(float(np.max(np.abs(b.tip_lateral_m))), 1e-300)
    return float(np.max(np.abs(a.tip_lateral_m - b.tip_lateral_m)) / scale)


def _fe_elements(tol: float) -> int:
    n = max(2, math.ceil((C_FE / (0.5 * tol)) ** 0.25))
    return min(n, 64)


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
) -> SimResult:
    """Simulate with the cheapest model whose estimated error is below ``tol``.

    Parameters
    ----------
    beam, drive, t_eval_s, a0_per_s, a1_s, gauge_positions_m, n_stations :
        as :func:`sim.fe.simulate_fe`.
    tol : requested relative error of the tip deflection history (max |error| / max |tip|),
        in (0, 0.5).

    Returns
    -------
    SimResult
        from the chosen model, with ``settings["auto_choice"]`` (e.g. ``"modal n_modes=5"``
        or ``"fe-corot n_elements=4"``), ``settings["auto_error_estimate"]`` (the estimate,
        relative), ``settings["auto_reason"]`` (one sentence) and
        ``settings["auto_parts"]`` (the three parts). ``wall_time_s`` includes the trial
        runs that made the choice.
    """
    t_tol = float(tol)
    if not math.isfinite(t_tol) or not 0.0 < t_tol < 0.5:
        raise ValueError(f"tol must be in (0, 0.5), got {tol!r}")
    common: dict[str, Any] = {
        "a0_per_s": a0_per_s,
        "a1_s": a1_s,
        "gauge_positions_m": gauge_positions_m,
        "n_stations": n_stations,
    }
    rtol_modal = max(t_tol / 20.0, 1e-12)
    t0 = time.perf_counter()
    n = 3
    prev = simulate_modal(beam, drive, t_eval_s, n_modes=n, rtol=rtol_modal, **common)
    while True:
        nxt = simulate_modal(beam, drive, t_eval_s, n_modes=n + 1, rtol=rtol_modal, **common)
        e_trunc = _rel_change(prev, nxt)
        if e_trunc < t_tol / 3.0 or n + 1 >= MAX_MODES:
            break
        prev, n = nxt, n + 1
    delta = float(np.max(np.abs(nxt.tip_lateral_m)))
    e_nl = C_NONLINEAR * (delta / beam.length_m) ** 2
    e_time = rtol_modal
    estimate = e_nl + e_trunc + e_time
    parts = {"nonlinear": e_nl, "truncation": e_trunc, "time": e_time}
    if estimate <= t_tol:
        result = nxt
        choice = f"modal n_modes={n + 1}"
        reason = (
            f"tip deflection / length = {delta / beam.length_m:.3g}: geometric nonlinearity "
            f"~{e_nl:.2g}, truncation at {n} modes {e_trunc:.2g}, below tol {t_tol:.2g}"
        )
    else:
        ne = _fe_elements(t_tol)
        rtol_fe = max(t_tol * 1e-4, 1e-11)
        result = simulate_fe(
            beam, drive, t_eval_s, n_elements=ne, rtol=rtol_fe, atol=rtol_fe * 1e-3, **common
        )
        e_fe = C_FE * ne**-4.0
        parts = {"discretisation": e_fe, "time": rtol_fe * 1e3}
        estimate = e_fe + rtol_fe * 1e3
        choice = f"fe-corot n_elements={ne}"
        reason = (
            f"modal estimate {e_nl + e_trunc + e_time:.2g} above tol {t_tol:.2g} "
            f"(tip deflection / length = {delta / beam.length_m:.3g}: geometric "
            f"nonlinearity ~{e_nl:.2g}); exact FE with {ne} elements"
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
