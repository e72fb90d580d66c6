"""Linear time-varying ODEs x' = A(t) x + f(t), solved with the 3-stage Radau IIA
collocation method (order 5, L-stable, stiffly accurate), batched.

Because the system is linear, one Radau IIA step is an affine map x_{k+1} = P_k x_k + g_k
whose matrices depend only on the known coefficients at the three stage times. All the
P_k, g_k of a run are formed by one batched linear solve (numpy; for a second-order
system's first-order form, as the modal models', the stages' positions are eliminated
first, which leaves a system of half the size), and the affine recursion runs about
sqrt(k) blocks of steps at once, joined by multiple shooting. Both give the states of
the one-step-at-a-time algorithm to rounding (tests/sim/solvers/test_linear_radau.py
keeps that algorithm as the reference). Steps land on the output times; the step size
is refined (halved) until two successive solutions agree to the requested tolerance, so
the error control is on the global error at the outputs, not just the local error per
step. The coefficients are :mod:`sim.solvers.radau_iia`'s, shared with :mod:`sim.solvers.radau`.
"""

from __future__ import annotations

import logging
import math
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


def _second_order_size(a_mat: FloatArray) -> int:
    """n when every A (K, 3, m, m) is the first-order form [[0, I], [B, D]] of a
    second-order system in x = [q, q'] (m = 2 n; exact zeros and ones), else 0."""
    m = a_mat.shape[-1]
    n = m // 2
    if m % 2 or n == 0:
        return 0
    top = a_mat[..., :n, :]
    form = np.concatenate([np.zeros((n, n)), np.eye(n)], axis=1)
    return n if bool(np.all(top == form)) else 0


def _stages_full(
    hs: FloatArray, a_mat: FloatArray, f_vec: FloatArray, invert: bool
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The (k, 3m, 3m) stage system I - h (a_ij A(t_j)) and the state columns and forcing
    column of its solution: zx (k, 3, m, m), zf (k, 3, m) (stage i = zx_i x + zf_i) and the
    system's inverse (``invert``) or the system."""
    k, _, m, _ = a_mat.shape
    eye = np.eye(m)
    big = np.zeros((k, 3 * m, 3 * m))
    for i in range(3):
        for j in range(3):
            block = -(hs * A[i, j])[:, None, None] * a_mat[:, j]
            if i == j:
                block = block + eye
            big[:, i * m : (i + 1) * m, j * m : (j + 1) * m] = block
    if invert:
        inv = np.asarray(np.linalg.inv(big), dtype=float)
        zx = inv @ np.tile(eye, (3, 1))[None]
        return zx.reshape(k, 3, m, m), _full_forcing(inv, hs, f_vec), inv
    col = (hs[:, None, None] * np.matmul(A, f_vec)).reshape(k, 3 * m)
    # one solve for the state columns and the forcing column together
    full = np.linalg.solve(
        big,
        np.concatenate(
            [np.broadcast_to(np.tile(eye, (3, 1)), (k, 3 * m, m)), col[:, :, None]], axis=2
        ),
    )
    return full[:, :, :m].reshape(k, 3, m, m), full[:, :, m].reshape(k, 3, m), big


def _full_forcing(inv: FloatArray, hs: FloatArray, f_vec: FloatArray) -> FloatArray:
    """zf (k, 3, m) of the full system from its inverse, for the forcing f_vec (k, 3, m)."""
    col = (hs[:, None, None] * np.matmul(A, f_vec)).reshape(hs.size, -1, 1)
    return np.matmul(inv, col).reshape(f_vec.shape)


# S's blocks as one product: row (i, l) of _S_MAP times [h^2 B_1..3, h D_1..3]
_S_MAP = np.zeros((9, 6))
_S_MAP[:, :3] = np.einsum("ij,jl->ilj", A, A).reshape(9, 3)  # a_ij a_jl
for _i in range(3):
    for _l in range(3):
        _S_MAP[3 * _i + _l, 3 + _l] = A[_i, _l]


def _reduced_system(hs: FloatArray, a_mat: FloatArray, n: int) -> FloatArray:
    """For A = [[0, I], [B, D]] (a_mat (k, 3, 2n, 2n)): the stage equations' q parts,
    Yq_i = xq + h sum_l a_il (Yv_l + fq_l), put into their q' parts leave the (k, 3n, 3n)
    system S_il = delta_il I - h a_il D_l - h^2 sum_j a_ij a_jl B_j in the stages' q'
    (an eighth of the full system's factorisation)."""
    k = hs.size
    parts = np.empty((k, 6, n, n))
    np.multiply((hs * hs)[:, None, None, None], a_mat[:, :, n:, :n], out=parts[:, :3])
    np.multiply(hs[:, None, None, None], a_mat[:, :, n:, n:], out=parts[:, 3:])
    blocks = np.matmul(_S_MAP, parts.reshape(k, 6, n * n)).reshape(k, 3, 3, n, n)
    out = np.empty((k, 3, n, 3, n))  # (k, i, a, l, b): block (i, l), row a, column b
    np.negative(blocks.transpose(0, 1, 3, 2, 4), out=out)
    s_mat: FloatArray = out.reshape(k, 3 * n, 3 * n)
    s_mat.reshape(k, -1)[:, :: 3 * n + 1] += 1.0
    return s_mat


def _reduced_forcing(hs: FloatArray, b_mat: FloatArray, f_vec: FloatArray, n: int) -> FloatArray:
    """The reduced system's forcing (k, 3, n): h sum_j a_ij (fv_j + h B_j sum_l a_jl fq_l)."""
    fq, fv = f_vec[:, :, :n], f_vec[:, :, n:]
    if np.any(fq):
        fv = fv + hs[:, None, None] * np.matmul(b_mat, np.matmul(A, fq)[..., None])[..., 0]
    return hs[:, None, None] * np.matmul(A, fv)


def _stages_second_order(
    hs: FloatArray, a_mat: FloatArray, f_vec: FloatArray, n: int, invert: bool, rows: slice
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """As :func:`_stages_full` for A = [[0, I], [B, D]] by the reduced system
    (:func:`_reduced_system`), for the stages ``rows`` only; the last is x_{k+1}."""
    k = hs.size
    m = 2 * n
    b_mat = a_mat[:, :, n:, :n]
    s_mat = _reduced_system(hs, a_mat, n)
    columns = np.zeros((k, 3, n, m + 1))  # the state's columns, then the forcing's
    columns[:, :, :, :n] = (hs[:, None, None] * np.matmul(A, b_mat.reshape(k, 3, n * n))).reshape(
        k, 3, n, n
    )
    columns[:, :, :, n:m] = np.eye(n)
    columns[:, :, :, m] = _reduced_forcing(hs, b_mat, f_vec, n)
    rhs = columns.reshape(k, 3 * n, m + 1)
    inv = np.asarray(np.linalg.inv(s_mat), dtype=float) if invert else s_mat
    w = np.asarray(inv @ rhs if invert else np.linalg.solve(s_mat, rhs), dtype=float)
    w = w.reshape(k, 3, n, m + 1)
    s = len(range(3)[rows])
    zx = np.empty((k, s, m, m))
    zx[:, :, n:] = w[:, rows, :, :m]
    wx = np.ascontiguousarray(w[..., :m]).reshape(k, 3, n * m)
    zx[:, :, :n] = (hs[:, None, None] * np.matmul(A[rows], wx)).reshape(k, s, n, m)
    zx[:, :, :n, :n] += np.eye(n)
    return zx, _lift_forcing(hs, w[..., m], f_vec[:, :, :n], rows), inv


def _lift_forcing(hs: FloatArray, wf: FloatArray, fq: FloatArray, rows: slice) -> FloatArray:
    """zf (k, s, 2n) of the stages ``rows`` from the reduced system's forcing solution
    wf (k, 3, n): [h sum_l a_il (wf_l + fq_l), wf_i]."""
    k, _, n = wf.shape
    a_rows = A[rows]
    zf = np.empty((k, a_rows.shape[0], 2 * n))
    zf[:, :, n:] = wf[:, rows]
    zf[:, :, :n] = hs[:, None, None] * np.matmul(a_rows, wf + fq)
    return zf


def _affine_run(p_mat: FloatArray, g_vec: FloatArray, x: FloatArray, out: FloatArray) -> None:
    """out[s] = x_{s+1} of x_{s+1} = P_s x_s + g_s from x_0 = ``x``, s < k.

    By multiple shooting: the k steps are cut into about sqrt(k) blocks of about sqrt(k)
    steps, all blocks stepped at once (so 3 sqrt(k) batched steps and 2 sqrt(k) small
    products instead of k Python steps). Each block's composed map
    ((P2, g2) o (P1, g1) = (P2 P1, P2 g1 + g2)) carries the blocks' starts; a product of
    steps can round far worse than the steps applied to the state (the P need not be
    normal: the stiff modes' P grow some vectors a hundredfold that the state never
    holds), so the starts are corrected once, Newton-fashion, by the gaps between each
    block's stepped end and the next start (e_{j+1} = P_j.. e_j + gap_j), and the
    blocks stepped again: every state is the step-by-step recursion's from a start that
    is itself that recursion's to rounding."""
    k, m = g_vec.shape
    size = max(1, math.isqrt(k))
    nb = -(-k // size)
    pad = nb * size - k
    if pad:
        p_mat = np.concatenate([p_mat, np.broadcast_to(np.eye(m), (pad, m, m))])
        g_vec = np.concatenate([g_vec, np.zeros((pad, m))])
    p = p_mat.reshape(nb, size, m, m)
    g = g_vec.reshape(nb, size, m, 1)
    composed, shift = p[:, 0].copy(), g[:, 0].copy()
    for r in range(1, size):
        composed = p[:, r] @ composed
        shift = p[:, r] @ shift + g[:, r]
    starts = np.empty((nb, m, 1))
    starts[0, :, 0] = x
    for j in range(nb - 1):
        starts[j + 1] = composed[j] @ starts[j] + shift[j]

    def stepped(y: FloatArray) -> FloatArray:
        states = np.empty((nb, size, m, 1))
        for r in range(size):
            y = p[:, r] @ y + g[:, r]
            states[:, r] = y
        return states

    gaps = stepped(starts)[:-1, -1] - starts[1:]
    error = np.zeros((m, 1))
    for j in range(nb - 1):
        error = composed[j] @ error + gaps[j]
        starts[j + 1] += error
    out[:] = stepped(starts).reshape(nb * size, m)[:k]


def radau_grid(
    coefficients: Coefficients,
    grid: FloatArray,
    x0: FloatArray,
    extra_forcing: FloatArray | None = None,
    stages_out: FloatArray | None = None,
    cache: dict[int, tuple[Any, ...]] | None = None,
) -> FloatArray:
    """One Radau IIA step between consecutive ``grid`` times; returns the states (T, m).

    ``extra_forcing`` (T - 1, 3, m), if given, is added to f at the stage times of every
    step (a forcing known only at those times, e.g. a nonlinear term from a previous
    iterate). ``stages_out`` (T - 1, 3, m), if given, receives the stage values. ``cache``
    (a dict, empty on the first call) keeps the factorised stage systems so that later calls
    on the same grid and coefficients only pay for the new forcing.

    Coefficients of a second-order system's first-order form (A = [[0, I], [B, D]] at every
    stage time) are solved by the smaller system of :func:`_stages_second_order`, others
    by the full one; the stage values are the same to rounding.
    """
    m = x0.size
    h = np.diff(grid)
    starts = grid[:-1]
    n_steps = h.size
    states = np.empty((n_steps + 1, m))
    states[0] = x0
    rows = slice(0, 3) if stages_out is not None or cache is not None else slice(2, 3)
    for c0 in range(0, n_steps, _CHUNK):
        c1 = min(n_steps, c0 + _CHUNK)
        hs = h[c0:c1]
        k = c1 - c0
        if cache is not None and c0 in cache:
            n, inv, zx, f_vec, a_mat = cache[c0]
            forcing = f_vec if extra_forcing is None else f_vec + extra_forcing[c0:c1]
            if n:
                rf = _reduced_forcing(hs, a_mat[:, :, n:, :n], forcing, n)
                wf = np.matmul(inv, rf.reshape(k, 3 * n, 1)).reshape(k, 3, n)
                zf = _lift_forcing(hs, wf, forcing[:, :, :n], rows)
            else:
                zf = _full_forcing(inv, hs, forcing)
        else:
            ts = starts[c0:c1, None] + hs[:, None] * C[None, :]  # (k, 3)
            a_mat, f_vec = coefficients(ts.ravel())
            a_mat = a_mat.reshape(k, 3, m, m)
            f_vec = f_vec.reshape(k, 3, m)
            forcing = f_vec if extra_forcing is None else f_vec + extra_forcing[c0:c1]
            n = _second_order_size(a_mat)
            if n:
                zx, zf, inv = _stages_second_order(hs, a_mat, forcing, n, cache is not None, rows)
            else:
                zx, zf, inv = _stages_full(hs, a_mat, forcing, cache is not None)
            if cache is not None:
                cache[c0] = (n, inv, zx, f_vec, a_mat)
        # the last stage is x_{k+1}
        _affine_run(zx[:, -1], zf[:, -1], states[c0], states[c0 + 1 : c1 + 1])
        if stages_out is not None:
            stages_out[c0:c1] = np.einsum("ksij,kj->ksi", zx, states[c0:c1]) + zf
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
