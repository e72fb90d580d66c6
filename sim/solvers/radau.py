"""Adaptive Radau IIA (order 5, L-stable) for the finite-element beams.

The step is scipy's ``Radau`` (Hairer and Wanner's RADAU5: the embedded error estimate
filtered through the real factor, Gustafsson's step control, no growth right after a
rejection, the collocation polynomial as dense output), with changes that matter for the
stiff, *nonlinear* beams with Kelvin-Voigt damping:

- the Newton matrix uses each stage's own Jacobian, evaluated at the **predicted** stages
  (the last step's collocation polynomial extrapolated). The axial stiffness EA (times a1)
  acts along the rotating centre line, so a Jacobian a few steps old, or one taken at the
  step start for all three stages, is wrong by ``a1 EA`` times the change of slope: scipy's
  policy (keep it until Newton fails) took 260 BDF steps per simulated second on the paper's
  scene, and a Jacobian fresh at every step start still failed 62 % of the Newton attempts
  (contraction 0.8). At the predicted stages the Jacobians are within the local error of
  the solution's, so one evaluation per step is enough (1.0 per attempt, 2.1 iterations,
  measured on the paper's scene at rtol = atol = 1e-4); when the iteration contracts slower
  than :data:`JAC_REFRESH_RATE` they are re-evaluated at the current iterate (full Newton);
- the function and its Jacobians come from one call (``rhs_jac_stages``: complex-step
  derivatives carry the function in their real part; the FE beam's paper law at a fixed
  step has them in closed form), all stages in one vectorised evaluation, and the
  right-hand side at the step's end is the last stage's, linearised to the final iterate
  (the stage at c = 1 is the new point; a fixed step skips the linearisation, it only
  checks that F is finite);
- LU factors straight from LAPACK, norms and finiteness checks with the fewest numpy calls:
  the systems are small (48 unknowns for two elements), so call overhead is the cost.

Together 2.3x faster than the full Newton with a fresh Jacobian per iteration that this
module used before (0.063 -> 0.027 s per simulated second, 2 elements, same error).
The method's coefficients are :mod:`sim.solvers.radau_iia`'s, shared with the batched linear
integrator. A failure raises :class:`sim.errors.IntegrationError`, never a silently wrong
answer.
"""

from __future__ import annotations

import bisect
import functools
import math
import time
from collections.abc import Callable
from typing import Any, ClassVar, ParamSpec, TypeVar

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import lapack, lu_factor, lu_solve
from threadpoolctl import ThreadpoolController

from sim.errors import IntegrationError, SimInputError
from sim.solvers.radau_iia import (
    MU_COMPLEX,
    MU_REAL,
    STAGES,
    TI,
    TI_COMPLEX,
    TI_REAL,
    C,
    E,
    T,
    tableau,
)

FloatArray = NDArray[np.float64]

RhsStages = Callable[[FloatArray, FloatArray], FloatArray]  # (k,), (k, n) -> (k, n)
Jacobian = Callable[[float, FloatArray], FloatArray]
JacobianStages = Callable[[FloatArray, FloatArray], FloatArray]  # (k,), (k, n) -> (k, n, n)
# (k,), (k, n) -> (k, n), (k, n, n): f and its Jacobians at the same points, one evaluation
RhsJacStages = Callable[[FloatArray, FloatArray], tuple[FloatArray, FloatArray]]

NEWTON_MAXITER = 7
#: at a fixed step there is no shorter step to fall back to, so Newton persists: full
#: Newton (fresh stage Jacobians at each iterate) through a phase that does not contract,
#: up to this many iterations, before the integration fails
NEWTON_MAXITER_FIXED = 12
#: Newton's stopping tolerance, a fraction of the local error tolerance. scipy's
#: min(0.03, rtol^0.5) made it 1e-3 at rtol 1e-6: 1.7 iterations per step on the paper's
#: scene against 1.3 at 0.03, the same tip to 1e-8 (its error is 3 % of one step's)
NEWTON_KAPPA = 0.03
#: contraction above which the stage Jacobians are re-evaluated at the current iterate
#: (at 0.5 a Newton iteration still gains a bit per iteration; slower costs more iterations
#: than a Jacobian)
JAC_REFRESH_RATE = 0.5
#: a fixed step that Newton does not take (a start from rest with the hub accelerating:
#: the first stages are far from the predicted ones) is halved, down to this share of it
FIXED_SPLIT_MIN = 1.0 / 64.0
MIN_FACTOR = 0.2
MAX_FACTOR = 10.0


class RadauStats:
    """Counters of one integration."""

    def __init__(self) -> None:
        self.n_steps = 0
        self.n_rejected = 0
        self.n_rhs = 0
        self.n_jac = 0
        self.n_lu = 0
        self.n_newton = 0
        self.n_newton_failed = 0


def _norm(x: FloatArray) -> float:
    v = x.ravel()
    return math.sqrt(float(v @ v) / v.size)


def _finite(x: FloatArray) -> bool:
    """All finite (a sum is NaN or infinite when any term is)."""
    return math.isfinite(float(x.sum()))


def _lu(a: FloatArray) -> tuple[FloatArray, NDArray[np.int32]]:
    """LU factors straight from LAPACK (scipy's wrapper costs 2x the 48 x 48 factorisation)."""
    lu, piv, info = lapack.dgetrf(a)
    if info < 0:  # pragma: no cover - argument error
        raise ValueError(f"dgetrf: illegal argument {-info}")
    return lu, piv


def _lu_solve(lu: tuple[FloatArray, NDArray[np.int32]], b: FloatArray) -> FloatArray:
    """Solve with :func:`_lu`'s factors or scipy's ``lu_factor`` (the same LAPACK pair)."""
    x, _ = lapack.dgetrs(lu[0], lu[1], b)
    return np.asarray(x)


_BLAS: list[ThreadpoolController] = []  # made on first use (it inspects the loaded libraries)


def _one_blas_thread() -> Any:
    """A context with every loaded BLAS on one thread. The Newton matrices are small
    (3n = 144 for six elements), and OpenBLAS factors them with its thread pool from
    about that size on; its threads busy-wait for each other, so with any other job on
    the second core a 144 x 144 LU took 27 ms instead of 0.2 ms: the six-element spin-up
    and reciprocating runs went from 0.6 s to 10-23 s whenever the caller (a test, a
    notebook) had not limited the pool as the command line does. Five elements
    (3n = 120) stayed on one thread, hence the jump from five to six."""
    if not _BLAS:
        _BLAS.append(ThreadpoolController())
    return _BLAS[0].limit(limits=1, user_api="blas")


_P = ParamSpec("_P")
_R = TypeVar("_R")


def _on_one_blas_thread(fn: Callable[_P, _R]) -> Callable[_P, _R]:
    @functools.wraps(fn)
    def wrapper(*args: _P.args, **kwargs: _P.kwargs) -> _R:
        with _one_blas_thread():
            return fn(*args, **kwargs)

    return wrapper


@_on_one_blas_thread
def radau5(
    rhs_stages: RhsStages,
    jac: Jacobian,
    t_eval_s: FloatArray,
    y0: FloatArray,
    *,
    rtol: float,
    atol: float,
    first_step_s: float | None = None,
    max_steps: int = 2_000_000,
    jac_stages: JacobianStages | None = None,
    rhs_jac_stages: RhsJacStages | None = None,
    fixed_step_s: float | None = None,
    second_order: bool = False,
    stages: int = 3,
) -> tuple[FloatArray, RadauStats, float]:
    """Integrate ``dy/dt = f(t, y)`` and return ``y`` at ``t_eval_s`` (T, n).

    Parameters
    ----------
    rhs_stages : ``f`` at several points at once: times (k,), states (k, n) -> (k, n).
    jac : ``df/dy`` (n, n) at one point.
    t_eval_s : (T,) strictly increasing output times; the integration starts at the first.
    y0 : (n,) state at ``t_eval_s[0]``.
    rtol, atol : local error tolerances (RMS norm of error / (atol + rtol |y|)).
    first_step_s : first trial step (default: 1/100 of the first output interval or less);
        with a ``fixed_step_s``, the first fixed step is taken in parts from this one, each
        twice the last (a start from rest with the hub accelerating has a layer of the
        fast modes that the dense output of a whole first step would carry to the output
        times inside it, the same for every step size).
    jac_stages : Jacobians at several points, (k,), (k, n) -> (k, n, n). If given, Newton
        works on the 3n collocation system with each stage's own Jacobian, taken at the
        predicted stages and re-evaluated at the iterate when convergence is slow;
        otherwise the simplified Newton with the Jacobian at the start of the step.
    rhs_jac_stages : ``(rhs_stages, jac_stages)`` at the same points in one call (cheaper
        where the Jacobians come with the function, e.g. complex-step); implies the Newton
        of ``jac_stages``.
    fixed_step_s : if given, every step is this long (the last one shortened to end at
        ``t_eval_s[-1]``) and the step-size controller is off: no error estimate, no
        rejection, so ``rtol`` and ``atol`` only scale Newton's stopping test. For
        convergence studies (the order of the method shows at the step ends) and for
        :mod:`sim.models.model_choice`, which measures the error by halving the step. A
        step whose Newton iteration does not converge is tried again from the step start's
        state (the extrapolated stages can be far off after a fast start), then taken in
        halves (the parts up to twice the last, back onto the fixed steps at its end),
        down to :data:`FIXED_SPLIT_MIN` of it; then it raises.
    second_order : the state is ``y = [d, v]`` (two halves) with ``d' = v`` exactly (the
        first half of ``f`` is the second half of ``y``): with the stage Jacobians,
        Newton then solves for the rate increments alone, 3n/2 unknowns, the displacement
        increments following from ``P = h A (v + Q)``, and the error filter for n/2.
        The same iterates as the 3n system, whose displacement rows are linear, at an
        eighth of the factorisation (see :func:`_newton_second_order`).
    stages : Radau IIA stages, 3 (default, order 5), 4 (order 7) or 5 (order 9); more than 3
        only at a ``fixed_step_s`` and with the stage Jacobians (the error estimate is the
        3-stage method's). On a smooth, stiff problem the higher orders take longer steps
        at equal error: the paper's damped scene at 8 elements is 1.0e-6 of the tip from
        the converged answer at 3 stages and 0.0125 s, 8.1e-7 at 5 stages and 0.05 s.

    Returns
    -------
    y : (T, n) states; stats : counters; wall_time_s : the integration alone.

    Raises
    ------
    sim.errors.IntegrationError
        if the step size underflows, Newton keeps failing or the state stops being finite.
    """
    if rhs_jac_stages is None and jac_stages is not None:
        js_only = jac_stages

        def rhs_jac_stages(ts: FloatArray, ys: FloatArray) -> tuple[FloatArray, FloatArray]:
            return rhs_stages(ts, ys), js_only(ts, ys)

    full = rhs_jac_stages is not None
    reduced = full and second_order
    if stages not in STAGES:
        raise SimInputError("stages", f"must be one of {STAGES}, got {stages!r}")
    if stages != 3 and (fixed_step_s is None or not full):
        raise SimInputError(
            "stages", f"above 3 need a fixed_step_s and the stage Jacobians, got {stages!r}"
        )
    tab = _Tableau.of(stages)
    if second_order and np.size(y0) % 2:
        raise SimInputError("second_order", f"needs a state of even size, got {np.size(y0)}")
    fixed = fixed_step_s is not None
    if fixed_step_s is not None:
        if not (math.isfinite(fixed_step_s) and fixed_step_s > 0.0):
            raise SimInputError(
                "fixed_step_s", f"must be a positive finite number, got {fixed_step_s!r}"
            )
        if first_step_s is not None and not (
            math.isfinite(first_step_s) and 0.0 < first_step_s <= fixed_step_s
        ):
            raise SimInputError(
                "first_step_s", f"must be in (0, fixed_step_s], got {first_step_s!r}"
            )
    t_out = np.asarray(t_eval_s, dtype=float)
    t_list = t_out.tolist()  # the same floats, for bisect (cheaper per call)
    y = np.array(y0, dtype=float)
    n = y.size
    out = np.empty((t_out.size, n))
    out[0] = y
    stats = RadauStats()
    start = time.perf_counter()
    if t_out.size == 1:
        return out, stats, 0.0
    t = float(t_out[0])
    t_end = float(t_out[-1])
    eye = np.eye(n)
    eye_3n = np.eye(stages * (n // 2 if reduced else n)) if full else eye
    # Newton stops when its remaining error is below NEWTON_KAPPA of the local error
    # tolerance (Hairer and Wanner's kappa; their RADAU5's FNEWT is 0.03 at rtol >= 1e-3)
    newton_tol = max(10 * np.finfo(float).eps / rtol, NEWTON_KAPPA)
    span = t_end - t
    ramp_s = first_step_s if fixed else None  # the first fixed step's first part
    if fixed_step_s is not None:
        first_step_s = fixed_step_s
    h = first_step_s if first_step_s is not None else min(1e-3, 0.01 * (t_out[1] - t_out[0]))
    h = min(max(h, 1e-12 * span), span)
    h_old: float | None = None
    err_old: float | None = None
    f = rhs_stages(np.array([t]), y[None, :])[0]
    stats.n_rhs += 1
    q_prev: FloatArray | None = None  # dense-output coefficients of the last step
    h_prev = 0.0
    y_prev = y.copy()
    k_out = 1
    # Hairer's FACCON: the last contraction's rate / (1 - rate), which lets Newton stop
    # after one iteration when the predicted stages are already within its tolerance
    faccon = 1.0
    # a fixed step that Newton cannot take is taken in halves (see ``fixed_step_s``):
    # ``t_goal`` is where the fixed step would have ended, ``h_fixed`` its length
    h_fixed = h
    t_goal: float | None = None
    if ramp_s is not None and ramp_s < h_fixed:
        t_goal, h = t + h_fixed, ramp_s  # the first step in parts, each twice the last
    while k_out < t_out.size:
        if stats.n_steps >= max_steps:
            raise IntegrationError("radau5", t, f"more than {max_steps} steps")
        if not full:
            jmat = jac(t, y)
            stats.n_jac += 1
            if not np.all(np.isfinite(jmat)):
                raise IntegrationError("radau5", t, "the Jacobian is not finite")
        rejected = False
        zero_start = False
        while True:
            min_step = 10.0 * (math.nextafter(t, math.inf) - t)
            if h < min_step:
                raise IntegrationError("radau5", t, f"step size {h:.3g} s underflows")
            t_new = t + h
            if t_goal is not None and (t_new >= t_goal or t_goal - t_new < 1e-9 * h):
                t_new = t_goal  # the split step's last part ends where the step would
                h = t_new - t
            if t_new >= t_end or t_end - t_new < 1e-9 * h:
                t_new = t_end
                h = t_new - t
            if not full:
                lu_r = lu_factor(MU_REAL / h * eye - jmat, check_finite=False)
                lu_c = lu_factor(MU_COMPLEX / h * eye - jmat, check_finite=False)
                stats.n_lu += 2
            if q_prev is None or zero_start:
                z = np.zeros((tab.s, n))
            else:
                # extrapolate the last collocation polynomial to the new stages
                z = (q_prev @ tab.extrapolation_powers(h / h_prev)).T + (y_prev - y)
            scale = atol + np.abs(y) * rtol
            if not full:
                converged, n_iter, z, _rate = _newton(
                    rhs_stages, t, y, h, z, scale, newton_tol, lu_r, lu_c, stats
                )
            else:
                assert rhs_jac_stages is not None
                newton = _newton_second_order if reduced else _newton_full
                faccon = max(faccon, _EPS) ** 0.8
                converged, n_iter, z, js, f_stages, faccon = newton(
                    rhs_stages, rhs_jac_stages, t, y, h, z, scale, newton_tol, stats, eye_3n,
                    faccon, tab, fixed,
                )  # fmt: skip
                if converged and not fixed:
                    # the error filter (I - h/mu J)^-1 with stage 1's Jacobian (at t + 0.16 h)
                    lu_r = _ErrorFilter(MU_REAL / h, js[0], reduced)
                    stats.n_lu += 1
            if not converged:
                if fixed:
                    stats.n_newton_failed += 1
                    if not zero_start and q_prev is not None:
                        zero_start = True  # the extrapolated stages, then the step start's
                        continue
                    if h <= h_fixed * FIXED_SPLIT_MIN:
                        problem = f"Newton does not converge at the fixed step {h:.3g} s"
                        raise IntegrationError("radau5", t, problem)
                    if t_goal is None:
                        t_goal = min(t + h_fixed, t_end)
                    h *= 0.5
                    zero_start = False
                    stats.n_rejected += 1
                    continue
                h *= 0.5
                rejected = True
                stats.n_rejected += 1
                stats.n_newton_failed += 1
                continue
            y_new = y + z[-1]
            if fixed:
                err = 0.0  # no error control at a fixed step
                break
            ze = (E @ z) * (1.0 / h)
            error = _filter(lu_r, f + ze)
            scale = atol + np.maximum(np.abs(y), np.abs(y_new)) * rtol
            err = _norm(error / scale)
            safety = 0.9 * (2 * NEWTON_MAXITER + 1) / (2 * NEWTON_MAXITER + n_iter)
            if rejected and err > 1:
                fe = rhs_stages(np.array([t]), (y + error)[None, :])[0]
                stats.n_rhs += 1
                error = _filter(lu_r, fe + ze)
                err = _norm(error / scale)
            if not math.isfinite(err):
                h *= 0.5
                rejected = True
                stats.n_rejected += 1
                continue
            if err > 1:
                factor = _predict_factor(h, h_old, err, err_old)
                h *= max(MIN_FACTOR, safety * factor)
                rejected = True
                stats.n_rejected += 1
                continue
            break
        if fixed:
            factor = 1.0
        else:
            factor = min(MAX_FACTOR, safety * _predict_factor(h, h_old, err, err_old))
        if rejected:
            factor = min(1.0, factor)  # no growth right after a rejection (Hairer's RADAU5)
        q = z.T @ tab.p  # (n, s): y(t + x h) = y + q [x, x^2, .., x^s]
        k_end = bisect.bisect_right(t_list, t_new + 1e-12 * h)  # np.searchsorted's
        if k_end > k_out:  # every output time in the step at once
            x = (t_out[k_out:k_end] - t) / h
            out[k_out:k_end] = y + (q @ (x[None, :] ** tab.powers)).T
            k_out = k_end
        if not full:
            f = rhs_stages(np.array([t_new]), y_new[None, :])[0]
            stats.n_rhs += 1
        else:
            f = f_stages[-1]  # the last stage is (t_new, y_new)
        if not _finite(f):
            raise IntegrationError("radau5", t_new, "the right-hand side is not finite")
        y_prev = y
        q_prev, h_prev = q, h
        h_old, err_old = h, err
        t, y = t_new, y_new
        stats.n_steps += 1
        if t_goal is None:
            h = h * factor
        elif t_new == t_goal:  # a split step done: back on the fixed steps
            t_goal, h = None, h_fixed
        else:  # the rest of the split step, in steps up to twice the last
            h = min(2.0 * h, t_goal - t_new)
    if not np.all(np.isfinite(out)):
        raise IntegrationError("radau5", t_end, "non-finite states")
    return out, stats, time.perf_counter() - start


def _newton(
    rhs_stages: RhsStages,
    t: float,
    y: FloatArray,
    h: float,
    z0: FloatArray,
    scale: FloatArray,
    tol: float,
    lu_r: tuple[FloatArray, NDArray[np.int32]],
    lu_c: tuple[FloatArray, NDArray[np.int32]],
    stats: RadauStats,
) -> tuple[bool, int, FloatArray, float]:
    """Simplified Newton on the collocation system (scipy's ``solve_collocation_system``)."""
    m_real = MU_REAL / h
    m_complex = MU_COMPLEX / h
    w = TI @ z0
    z = z0
    ts = t + h * C
    dw = np.empty_like(w)
    dw_norm_old: float | None = None
    rate = math.inf
    k = 0
    for k in range(NEWTON_MAXITER):
        f = rhs_stages(ts, y[None, :] + z)
        stats.n_rhs += 3
        stats.n_newton += 1
        if not np.all(np.isfinite(f)):
            return False, k + 1, z, rate
        f_real = f.T @ TI_REAL - m_real * w[0]
        f_complex = f.T @ TI_COMPLEX - m_complex * (w[1] + 1j * w[2])
        dw[0] = lu_solve(lu_r, f_real, check_finite=False)
        dwc = lu_solve(lu_c, f_complex, check_finite=False)
        dw[1] = dwc.real
        dw[2] = dwc.imag
        dw_norm = _norm(dw / scale)
        has_rate = dw_norm_old is not None
        if dw_norm_old is not None:
            rate = dw_norm / dw_norm_old
        if has_rate and (rate >= 1 or rate ** (NEWTON_MAXITER - k) / (1 - rate) * dw_norm > tol):
            return False, k + 1, z, rate
        w = w + dw
        z = T @ w
        if dw_norm == 0 or (has_rate and rate / (1 - rate) * dw_norm < tol):
            return True, k + 1, z, rate
        dw_norm_old = dw_norm
    return False, k + 1, z, rate


def _newton_full(
    rhs_stages: RhsStages,
    rhs_jac_stages: RhsJacStages,
    t: float,
    y: FloatArray,
    h: float,
    z0: FloatArray,
    scale: FloatArray,
    tol: float,
    stats: RadauStats,
    eye: FloatArray,
    faccon: float = 1.0,
    tab: _Tableau | None = None,
    persist: bool = False,
) -> tuple[bool, int, FloatArray, FloatArray, FloatArray, float]:
    """Newton on ``Z - h (A x I) F(y + Z) = 0`` (3n unknowns; s n with ``tab``'s s stages)
    with each stage's own Jacobian, evaluated at the predicted stages and kept while the
    iteration contracts fast; re-evaluated at the current iterate (full Newton) when it
    does not.

    The predictor (the last step's collocation polynomial) puts the stages within the
    local error of the solution, so their Jacobians are nearly exact and one evaluation
    per step usually suffices. Returns ``(converged, iterations, Z, stage Jacobians (3, n, n),
    F at the stages)``; ``F`` is linearised from the last evaluation to the final iterate
    (error O(dz^2)), which spares the right-hand side at the step's end. ``persist`` (a
    fixed step): an iteration that does not contract with fresh Jacobians is not given up
    but continued as full Newton, up to :data:`NEWTON_MAXITER_FIXED` iterations."""
    n = y.size
    tab = _Tableau.of(3) if tab is None else tab
    a_mat, ns = tab.a, tab.s
    ts = t + h * tab.c
    z = z0.copy()
    dz_norm_old: float | None = None
    lu: tuple[FloatArray, NDArray[np.int32]] | None = None
    jac_k = 0  # the iteration whose iterate the Jacobians were evaluated at
    js = np.empty((ns, n, n))
    k = 0
    for k in range(NEWTON_MAXITER_FIXED if persist else NEWTON_MAXITER):
        ys = y[None, :] + z
        stats.n_rhs += ns
        stats.n_newton += 1
        if lu is None:
            f, js = rhs_jac_stages(ts, ys)  # (s, n), (s, n, n)
            stats.n_jac += ns
            stats.n_lu += 1
            if not (_finite(f) and _finite(js)):
                return False, k + 1, z, js, f, faccon
            blocks = a_mat[:, :, None, None] * js[None, :, :, :]  # (i, j, row, col)
            mat = eye - h * blocks.transpose(0, 2, 1, 3).reshape(ns * n, ns * n)
            lu = _lu(mat)
            jac_k = k
            dz_norm_old = None
        else:
            f = rhs_stages(ts, ys)
            if not _finite(f):
                return False, k + 1, z, js, f, faccon
        res = z - h * (a_mat @ f)
        dz = _lu_solve(lu, -res.ravel()).reshape(ns, n)
        dz_norm = _norm(dz / scale)
        if not math.isfinite(dz_norm):
            return False, k + 1, z, js, f, faccon
        if dz_norm_old is not None:
            rate = dz_norm / dz_norm_old
            if rate >= JAC_REFRESH_RATE:
                if rate >= 1.0 and jac_k == k - 1 and not persist:
                    return False, k + 1, z, js, f, faccon  # diverging, Jacobians a step old
                if rate < 1.0 or persist:
                    z = z + dz
                lu = None  # slow: Jacobians at the current iterate (full Newton)
                continue
            z = z + dz
            faccon = rate / (1.0 - rate)
        else:
            z = z + dz
        # Hairer's test: the remaining error of a contraction at rate theta is about
        # theta / (1 - theta) |dz|; on the first iteration theta is the last one measured
        if faccon * dz_norm < tol:
            return True, k + 1, z, js, f + (js @ dz[:, :, None])[..., 0], faccon
        dz_norm_old = dz_norm
    return False, k + 1, z, js, f, faccon


class _ErrorFilter:
    """``(gamma I - J)^-1`` (``gamma = mu / h``) for the embedded error estimate; for a
    second-order state (``J = [[0, I], [Kd, Kv]]``) by the Schur complement on the
    displacements: ``(gamma^2 I - gamma Kv - Kd) e_d = b_v + (gamma I - Kv) b_d``,
    ``e_v = gamma e_d - b_d`` (a factorisation of n/2 rows instead of n)."""

    def __init__(self, gamma: float, jac: FloatArray, second_order: bool) -> None:
        self.gamma = gamma
        n = jac.shape[0]
        self.m = n // 2 if second_order else 0
        if second_order:
            m = self.m
            self.shifted_kv = -jac[m:, m:]
            self.shifted_kv.flat[:: m + 1] += gamma
            self.lu = _lu(gamma * self.shifted_kv - jac[m:, :m])
        else:
            self.lu = _lu(gamma * np.eye(n) - jac)

    def solve(self, b: FloatArray) -> FloatArray:
        m = self.m
        if not m:
            return _lu_solve(self.lu, b)
        e_d = _lu_solve(self.lu, b[m:] + self.shifted_kv @ b[:m])
        return np.concatenate([e_d, self.gamma * e_d - b[:m]])


def _filter(lu: _ErrorFilter | tuple[FloatArray, NDArray[np.int32]], b: FloatArray) -> FloatArray:
    """The error filter's solve with either kind of factors."""
    return lu.solve(b) if isinstance(lu, _ErrorFilter) else _lu_solve(lu, b)


_EPS = float(np.finfo(float).eps)


class _Tableau:
    """One Radau IIA method's coefficients as the step uses them: nodes ``c``, ``a``, the
    dense output's ``p`` and powers ``[x, .., x^s]``, and the reduced Newton matrix's
    coefficient maps (``A_ij A_jk`` as [(i, k), j] for the displacement part, ``A_ik`` at
    [(i, k), k] for the rate part)."""

    _made: ClassVar[dict[int, _Tableau]] = {}

    def __init__(self, stages: int) -> None:
        self.s = stages
        self.c, self.a, self.p = tableau(stages)
        self.powers = np.arange(1.0, stages + 1.0)[:, None]
        self.aa_flat = np.einsum("ij,jk->ikj", self.a, self.a).reshape(stages * stages, stages)
        self.a_diag = np.einsum("ik,jk->ikj", self.a, np.eye(stages)).reshape(
            stages * stages, stages
        )
        self._at_step: dict[float, tuple[FloatArray, FloatArray, FloatArray]] = {}
        self._powers: dict[float, FloatArray] = {}

    def at_step(self, h: float) -> tuple[FloatArray, FloatArray, FloatArray]:
        """``(h c, h A, -coef)`` for a step ``h``: the stage offsets, ``h A`` and the
        reduced Newton matrix's coefficient map negated (:func:`_newton_second_order`),
        kept for the last few step sizes (a fixed step uses one or two)."""
        made = self._at_step.get(h)
        if made is None:
            coef = np.concatenate([(h * h) * self.aa_flat, h * self.a_diag], axis=1)
            made = (h * self.c, h * self.a, -coef)
            if len(self._at_step) >= 4:
                self._at_step.clear()
            self._at_step[h] = made
        return made

    def extrapolation_powers(self, ratio: float) -> FloatArray:
        """``x^[1..s]`` at the nodes of the next step, ``x = ratio c + 1`` (``ratio`` the
        new step over the last): where the last step's collocation polynomial is evaluated
        to predict the new stages (cached as :meth:`at_step`)."""
        made = self._powers.get(ratio)
        if made is None:
            made = (ratio * self.c + 1.0) ** self.powers
            if len(self._powers) >= 4:
                self._powers.clear()
            self._powers[ratio] = made
        return made

    @classmethod
    def of(cls, stages: int) -> _Tableau:
        made = cls._made.get(stages)
        if made is None:
            made = cls._made[stages] = cls(stages)
        return made


def _newton_second_order(
    rhs_stages: RhsStages,
    rhs_jac_stages: RhsJacStages,
    t: float,
    y: FloatArray,
    h: float,
    z0: FloatArray,
    scale: FloatArray,
    tol: float,
    stats: RadauStats,
    eye: FloatArray,
    faccon: float = 1.0,
    tab: _Tableau | None = None,
    persist: bool = False,
) -> tuple[bool, int, FloatArray, FloatArray, FloatArray, float]:
    """:func:`_newton_full` for ``y = [d, v]`` with ``d' = v``: the same iteration on the
    rate increments ``Q`` (3 x n/2) alone.

    The stage equations split into ``P = h A (v + Q)`` (the displacement increments, linear)
    and ``Q = h A a(d + P, v + Q)``; with ``P`` eliminated, Newton's matrix is
    ``I - h (A x I) diag(Kv) - h^2 (A x I) diag(Kd) (A x I)`` (``Kd``, ``Kv`` each stage's
    acceleration Jacobian by displacement and rate), 3n/2 rows. ``P`` is kept on its line
    from the start, which is where the full iteration puts it after one step, so both
    converge to the same stages; the stopping test is the full one on ``(P, Q)``."""
    n = y.size
    m = n // 2
    tab = _Tableau.of(3) if tab is None else tab
    ns = tab.s
    hc, ha, neg_coef = tab.at_step(h)
    ts = t + hc
    z = z0.copy()  # C order (the prediction is a transpose; the layout steers BLAS's rounding)
    z[:, :m] = ha @ (y[m:] + z[:, m:])  # P on its line
    dz = np.empty_like(z)
    inv_scale = 1.0 / scale
    dz_norm_old: float | None = None
    lu: tuple[FloatArray, NDArray[np.int32]] | None = None
    jac_k = 0
    js = np.empty((ns, n, n))
    # neg_coef: minus the matrix's coefficients of [Kd of the s stages, Kv of the s stages]
    # per block (i, k): h^2 A_ij A_jk for Kd_j, h A_ik for Kv_k; (s^2, 2 s)
    k = 0
    for k in range(NEWTON_MAXITER_FIXED if persist else NEWTON_MAXITER):
        ys = y + z
        stats.n_rhs += ns
        stats.n_newton += 1
        if lu is None:
            f, js = rhs_jac_stages(ts, ys)
            stats.n_jac += ns
            stats.n_lu += 1
            if not _finite(f):
                return False, k + 1, z, js, f, faccon
            jac_k = k
            # [Kd of each stage; Kv of each stage] (2 s, m m): the stage Jacobians'
            # acceleration rows (a non-finite one makes the factors and so dz non-finite,
            # which fails the iteration below)
            kdv = js[:, m:, :].reshape(ns, m, 2, m).transpose(2, 0, 1, 3).reshape(2 * ns, m * m)
            blocks = (
                (neg_coef @ kdv).reshape(ns, ns, m, m).transpose(0, 2, 1, 3).reshape(ns * m, ns * m)
            )
            blocks += eye  # adding zeros elsewhere changes nothing
            lu = _lu(blocks)
            dz_norm_old = None
        else:
            f = rhs_stages(ts, ys)
            if not _finite(f):
                return False, k + 1, z, js, f, faccon
        dq = _lu_solve(lu, (ha @ f[:, m:] - z[:, m:]).ravel()).reshape(ns, m)
        dz[:, m:] = dq
        dz[:, :m] = ha @ dq
        dz_norm = _norm(dz * inv_scale)
        if not math.isfinite(dz_norm):
            return False, k + 1, z, js, f, faccon
        if dz_norm_old is not None:
            rate = dz_norm / dz_norm_old
            if rate >= JAC_REFRESH_RATE:
                if rate >= 1.0 and jac_k == k - 1 and not persist:
                    return False, k + 1, z, js, f, faccon
                if rate < 1.0 or persist:
                    z = z + dz
                lu = None
                continue
            z = z + dz
            faccon = rate / (1.0 - rate)
        else:
            z = z + dz
        # Hairer's test: the remaining error of a contraction at rate theta is about
        # theta / (1 - theta) |dz|; on the first iteration theta is the last one measured
        if faccon * dz_norm < tol:
            if persist:  # a fixed step needs F at the stages only to check it is finite
                return True, k + 1, z, js, f, faccon
            return True, k + 1, z, js, f + (js @ dz[:, :, None])[..., 0], faccon
        dz_norm_old = dz_norm
    return False, k + 1, z, js, f, faccon


def _predict_factor(h: float, h_old: float | None, err: float, err_old: float | None) -> float:
    """Gustafsson's predictive step-size factor (as scipy's Radau)."""
    if err_old is None or h_old is None or err == 0:
        multiplier = 1.0
    else:
        multiplier = h / h_old * (err_old / err) ** 0.25
    return min(1.0, multiplier) * err**-0.25 if err > 0 else MAX_FACTOR
