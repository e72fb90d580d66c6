"""Stiff time integration for the beam models: our Radau IIA (order 5, a fresh Jacobian
every step, :mod:`sim.solvers.radau`) or a checked wrapper around scipy's Radau, BDF and LSODA, all
with an analytic Jacobian.

A solver failure raises :class:`sim.errors.IntegrationError`; there is no silently wrong
answer.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.integrate import solve_ivp

from sim.errors import IntegrationError, SimInputError
from sim.solvers.radau import radau5

FloatArray = NDArray[np.float64]

METHODS = ("radau5", "Radau", "BDF", "LSODA")


@dataclass(frozen=True)
class Trajectory:
    """States at the requested times and solver statistics."""

    y: FloatArray  # (T, n_state)
    wall_time_s: float
    n_rhs: int
    n_jac: int
    n_lu: int
    n_steps: int = -1  # accepted steps (-1: not reported by the solver)


def integrate(
    rhs: Callable[[float, FloatArray], FloatArray],
    jac: Callable[[float, FloatArray], FloatArray],
    t_eval_s: FloatArray,
    y0: FloatArray,
    *,
    rtol: float,
    atol: float,
    method: str = "Radau",
    first_step_s: float | None = None,
    rhs_stages: Callable[[FloatArray, FloatArray], FloatArray] | None = None,
    jac_stages: Callable[[FloatArray, FloatArray], FloatArray] | None = None,
    rhs_jac_stages: Callable[[FloatArray, FloatArray], tuple[FloatArray, FloatArray]] | None = None,
    second_order: bool = False,
    fixed_step_s: float | None = None,
    stages: int = 3,
) -> Trajectory:
    """Integrate ``dy/dt = rhs(t, y)`` from ``t_eval_s[0]`` and return ``y`` at ``t_eval_s``.

    Parameters
    ----------
    rhs, jac : right-hand side (n,) and its Jacobian (n, n).
    t_eval_s : (T,) increasing output times; the integration starts at ``t_eval_s[0]``.
    y0 : (n,) state at ``t_eval_s[0]``.
    rtol, atol : local error tolerances.
    method : "radau5" (:func:`sim.solvers.radau.radau5`), "Radau" (scipy's; default, L-stable,
        order 5), "BDF" or "LSODA".
    first_step_s : first trial step, s.
    rhs_stages : ``rhs`` at several points at once, times (k,), states (k, n) -> (k, n);
        used by "radau5" (default: ``rhs`` called point by point).
    jac_stages : ``jac`` at several points, (k,), (k, n) -> (k, n, n): "radau5" then runs
        the full Newton iteration (see :func:`sim.solvers.radau.radau5`).
    rhs_jac_stages : ``(rhs_stages, jac_stages)`` at the same points in one call; used by
        "radau5" in place of the two where both are needed.
    second_order : ``y = [d, v]`` with ``d' = v``: "radau5" then solves Newton for the rates
        alone (:func:`sim.solvers.radau.radau5`); ignored by the other methods.
    fixed_step_s : "radau5" only: every step this long, no error control (see
        :func:`sim.solvers.radau.radau5`).
    stages : "radau5" at a ``fixed_step_s`` only: Radau IIA stages, 3 (order 5), 4 or 5
        (orders 7 and 9; see :func:`sim.solvers.radau.radau5`).

    Raises
    ------
    sim.errors.IntegrationError
        if the solver does not reach the last time or the state stops being finite.
    """
    if method not in METHODS:
        raise SimInputError("method", f"must be one of {', '.join(METHODS)}, got {method!r}")
    t = np.asarray(t_eval_s, dtype=float)
    y_start = np.asarray(y0, dtype=float)
    if t.size == 1:
        return Trajectory(y_start[None, :].copy(), 0.0, 0, 0, 0)
    if fixed_step_s is not None and method != "radau5":
        raise SimInputError("fixed_step_s", f"needs method 'radau5', got {method!r}")
    if stages != 3 and method != "radau5":
        raise SimInputError("stages", f"needs method 'radau5', got {method!r}")
    if method == "radau5":
        return _radau5(
            rhs, jac, t, y_start, rtol, atol, first_step_s, rhs_stages, jac_stages,
            rhs_jac_stages, second_order, fixed_step_s, stages,
        )  # fmt: skip
    kwargs: dict[str, object] = {"rtol": rtol, "atol": atol, "t_eval": t}
    kwargs["jac"] = jac
    if first_step_s is not None:
        kwargs["first_step"] = first_step_s

    def checked_rhs(t_s: float, y_now: FloatArray) -> FloatArray:
        out = rhs(t_s, y_now)
        if not np.isfinite(out).all():
            raise IntegrationError(method, t_s, "the right-hand side is not finite")
        return out

    def checked_jac(t_s: float, y_now: FloatArray) -> FloatArray:
        out = jac(t_s, y_now)
        if not np.isfinite(out).all():
            raise IntegrationError(method, t_s, "the Jacobian is not finite")
        return out

    kwargs["jac"] = checked_jac
    t0 = time.perf_counter()
    sol = solve_ivp(checked_rhs, (float(t[0]), float(t[-1])), y_start, method=method, **kwargs)
    wall = time.perf_counter() - t0
    if sol.status != 0:
        t_fail = float(sol.t[-1]) if sol.t.size else float(t[0])
        raise IntegrationError(method, t_fail, str(sol.message))
    y = np.ascontiguousarray(sol.y.T)
    if y.shape[0] != t.size or not np.all(np.isfinite(y)):
        raise IntegrationError(method, float(t[-1]), "non-finite or missing states")
    return Trajectory(y, wall, int(sol.nfev), int(sol.njev), int(sol.nlu))


def _radau5(
    rhs: Callable[[float, FloatArray], FloatArray],
    jac: Callable[[float, FloatArray], FloatArray],
    t: FloatArray,
    y0: FloatArray,
    rtol: float,
    atol: float,
    first_step_s: float | None,
    rhs_stages: Callable[[FloatArray, FloatArray], FloatArray] | None,
    jac_stages: Callable[[FloatArray, FloatArray], FloatArray] | None,
    rhs_jac_stages: Callable[[FloatArray, FloatArray], tuple[FloatArray, FloatArray]] | None,
    second_order: bool,
    fixed_step_s: float | None,
    stages: int = 3,
) -> Trajectory:
    def pointwise(ts: FloatArray, ys: FloatArray) -> FloatArray:
        return np.stack([rhs(float(tk), yk) for tk, yk in zip(ts, ys, strict=True)])

    y, stats, wall = radau5(
        rhs_stages if rhs_stages is not None else pointwise,
        jac,
        t,
        y0,
        rtol=rtol,
        atol=atol,
        first_step_s=first_step_s,
        jac_stages=jac_stages,
        rhs_jac_stages=rhs_jac_stages,
        second_order=second_order,
        fixed_step_s=fixed_step_s,
        stages=stages,
    )
    return Trajectory(y, wall, stats.n_rhs, stats.n_jac, stats.n_lu, stats.n_steps)
