"""Linear time-varying ODEs x' = A(t) x + f(t), solved with the 3-stage Radau IIA
collocation method (order 5, L-stable, stiffly accurate), batched.

Because the system is linear, one Radau IIA step is an affine map x_{k+1} = P_k x_k + g_k
whose matrices depend only on the known coefficients at the three stage times. All the
P_k, g_k of a run are formed by one batched linear solve (numpy), and the only sequential
work is the affine recursion. Steps land on the output times; the step size is refined
(halved) until two successive solutions agree to the requested tolerance, so the error
control is on the global error at the outputs, not just the local error per step. The
coefficients are :mod:`sim.solvers.radau_iia`'s, shared with :mod:`sim.solvers.radau`.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sim.errors import SimInputError, SolverError
from sim.solvers.radau_iia import A, C

FloatArray = NDArray[np.float64]

logger = logging.getLogger(__name__)

#: coefficients(t) -> (A, f): A of shape (K, m, m), f of shape (K, m) for K times.
Coefficients = Callable[[FloatArray], tuple[FloatArray, FloatArray]]

_CHUNK = 4096
SOLVER = "linear Radau IIA"  # how errors name this solver


def substeps(t_out: FloatArray, h_max: float) -> NDArray[np.intp]:
    """Number of equal steps in each output interval so that no step exceeds ``h_max``."""
    return np.maximum(1, np.ceil(np.diff(t_out) / h_max - 1e-9)).astype(np.intp)


def step_grid(t_out: FloatArray, n_sub: NDArray[np.intp]) -> tuple[FloatArray, NDArray[np.intp]]:
    """All step boundaries (``n_sub[k]`` equal steps in output interval k) and the index of
    every output time in that grid."""
    dt = np.diff(t_out)
    starts = np.repeat(t_out[:-1], n_sub)
    local = np.arange(starts.size) - np.repeat(np.cumsum(n_sub) - n_sub, n_sub)
    grid = np.concatenate([starts + local * np.repeat(dt / n_sub, n_sub), t_out[-1:]])
    out_index = np.concatenate([[0], np.cumsum(n_sub)])
    grid[out_index] = t_out  # exact output times
    return grid, out_index


def radau_grid(
    coefficients: Coefficients,
    grid: FloatArray,
    x0: FloatArray,
    extra_forcing: FloatArray | None = None,
    stages_out: FloatArray | None = None,
    cache: dict[int, tuple[FloatArray, FloatArray, FloatArray]] | None = None,
) -> FloatArray:
    """One Radau IIA step between consecutive ``grid`` times; returns the states (T, m).

    ``extra_forcing`` (T - 1, 3, m), if given, is added to f at the stage times of every
    step (a forcing known only at those times, e.g. a nonlinear term from a previous
    iterate). ``stages_out`` (T - 1, 3, m), if given, receives the stage values. ``cache``
    (a dict, empty on the first call) keeps the factorised stage systems so that later calls
    on the same grid and coefficients only pay for the new forcing.
    """
    m = x0.size
    h = np.diff(grid)
    starts = grid[:-1]
    n_steps = h.size
    states = np.empty((n_steps + 1, m))
    states[0] = x0
    eye = np.eye(m)
    x = x0.copy()
    for c0 in range(0, n_steps, _CHUNK):
        c1 = min(n_steps, c0 + _CHUNK)
        hs = h[c0:c1]
        k = c1 - c0
        if cache is not None and c0 in cache:
            inv, zx, f_vec = cache[c0]
        else:
            ts = starts[c0:c1, None] + hs[:, None] * C[None, :]  # (k, 3)
            a_mat, f_vec = coefficients(ts.ravel())
            a_mat = a_mat.reshape(k, 3, m, m)
            f_vec = f_vec.reshape(k, 3, m)
            big = np.zeros((k, 3 * m, 3 * m))
            for i in range(3):
                for j in range(3):
                    block = -(hs * A[i, j])[:, None, None] * a_mat[:, j]
                    if i == j:
                        block = block + eye
                    big[:, i * m : (i + 1) * m, j * m : (j + 1) * m] = block
        forcing = f_vec if extra_forcing is None else f_vec + extra_forcing[c0:c1]
        col = (hs[:, None, None] * np.einsum("ij,kjm->kim", A, forcing)).reshape(k, 3 * m)
        if cache is None:
            # one solve for the state columns and the forcing column together
            full = np.linalg.solve(
                big,
                np.concatenate(
                    [np.broadcast_to(np.tile(eye, (3, 1)), (k, 3 * m, m)), col[:, :, None]], axis=2
                ),
            )
            zx, zf = full[:, :, :m], full[:, :, m]
        else:
            if c0 not in cache:
                inv = np.asarray(np.linalg.inv(big), dtype=float)
                zx = inv @ np.tile(eye, (3, 1))[None]  # (k, 3m, m)
                cache[c0] = (inv, zx, f_vec)
            zf = np.matmul(inv, col[:, :, None])[:, :, 0]
        p_mat = np.ascontiguousarray(zx[:, 2 * m :, :])  # last stage = x_{k+1}
        g_vec = np.ascontiguousarray(zf[:, 2 * m :])
        for s in range(k):
            x = p_mat[s] @ x + g_vec[s]
            states[c0 + s + 1] = x
        if stages_out is not None:
            y = np.einsum("kij,kj->ki", zx, states[c0:c1]) + zf
            stages_out[c0:c1] = y.reshape(k, 3, m)
    if not np.all(np.isfinite(states)):
        raise SolverError(SOLVER, "the recursion produced non-finite values")
    return states


def radau_fixed(
    coefficients: Coefficients, t_out: FloatArray, x0: FloatArray, n_sub: NDArray[np.intp]
) -> FloatArray:
    """``n_sub[k]`` equal Radau IIA steps in output interval k; returns the states (T, m)."""
    grid, out_index = step_grid(t_out, n_sub)
    return radau_grid(coefficients, grid, x0)[out_index]


def solve_ltv(
    coefficients: Coefficients,
    t_out: FloatArray,
    x0: FloatArray,
    *,
    error_weights: FloatArray,
    rtol: float,
    atol: float,
    h_initial: float,
    max_refinements: int = 14,
    grid_out: list[Any] | None = None,
) -> tuple[FloatArray, float, float]:
    """Solve to tolerance by step halving.

    Each pass runs on a step grid; its every other boundary is the grid of a solution with
    twice the step (the previous pass, or a half-cost run on the first pass). The error
    measure is e = sum_i error_weights_i |x_i^(2h) - x_i^(h)| at those common times (e.g. the
    tip deflection for modal coordinates); the pass is accepted when
    max e / 15 <= atol + rtol * max |sum_i error_weights_i x_i| (order >= 4 in the step) and
    the finer solution is returned.

    Returns
    -------
    states : (T, m) at ``t_out``; estimated error (units of the weighted sum); largest step (s).
    ``grid_out``, if given, receives the accepted step grid and the output indices in it.
    """
    if t_out.ndim != 1 or t_out.size < 1:
        raise SimInputError("t_eval_s", "must be a non-empty 1-D array")
    if t_out.size == 1:
        return x0[None, :].copy(), 0.0, 0.0
    if np.any(np.diff(t_out) <= 0.0):
        raise SimInputError("t_eval_s", "must be strictly increasing")
    n_sub = substeps(t_out, h_initial)
    grid, out_index = step_grid(t_out, n_sub)
    fine = radau_grid(coefficients, grid, x0)
    common = np.arange(0, grid.size, 2)
    if common[-1] != grid.size - 1:
        common = np.append(common, grid.size - 1)
    coarse = radau_grid(coefficients, grid[common], x0)
    est = scale = float("nan")
    for _ in range(max_refinements):
        est = float(np.max(np.abs((fine[common] - coarse) @ error_weights))) / 15.0
        scale = float(np.max(np.abs(fine @ error_weights)))
        h = float(np.max(np.diff(grid)))
        logger.debug("linear Radau: h = %.3g s, error estimate %.3g, scale %.3g", h, est, scale)
        if est <= atol + rtol * scale:
            if grid_out is not None:
                grid_out.append(grid)
                grid_out.append(out_index)
            return fine[out_index], est, h
        # halve every step: the current solution becomes the coarse one
        coarse = fine
        n_sub = 2 * n_sub
        grid, out_index = step_grid(t_out, n_sub)
        common = np.arange(0, grid.size, 2)
        fine = radau_grid(coefficients, grid, x0)
    raise SolverError(
        SOLVER,
        f"no convergence to rtol={rtol:g}, atol={atol:g} after {max_refinements} step halvings "
        f"(estimated error {est:.3g}, scale {scale:.3g})",
    )
