"""The batched linear Radau IIA (``sim.solvers.linear_radau``) against the algorithm it
replaced, kept here as the reference: the full (3m, 3m) stage solve of every step and the
affine recursion x_{k+1} = P_k x_k + g_k one step at a time.

The current code solves a second-order system's stages by the reduced (3n, 3n) system
and runs the recursion blocked (about sqrt(k) blocks composed at once). Both are the
same method on the same grid, so the states agree to rounding: 1e-12 of each state
component's largest magnitude, on the modal model's own coefficients and on a stiff,
strongly damped, time-varying system unlike the bench (its forcing also enters the q
equations, and one copy of it has its state reordered out of the second-order form so
the full stage solve runs too). Measured: 5e-15 to 8e-15 (modal, 4000 and 9000 steps),
2e-14 (the stiff system), 5e-14 (its stages, through the cache). The blocked recursion
on 100k steps of the lightly damped modal model (a1 = 1e-4 s, the first mode's P has
spectral radius 0.999993) is 2.4e-14 from the recursion in extended precision, as is the
step-by-step recursion in double.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest

from pipelines.rig import load_rig
from sim.beam import BeamProperties
from sim.drives import FourBarDrive
from sim.four_bar import FourBar
from sim.models.modal import ModalModel
from sim.solvers.linear_radau import (
    _CHUNK,
    _affine_run,
    _second_order_size,
    _stages_full,
    _stages_second_order,
    radau_grid,
)
from sim.solvers.radau_iia import A, C

Coefficients = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]
ROUNDING = 1e-12  # of each state component's largest magnitude over the run


def reference_radau_grid(
    coefficients: Coefficients,
    grid: np.ndarray,
    x0: np.ndarray,
    extra_forcing: np.ndarray | None = None,
    stages_out: np.ndarray | None = None,
    cache: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] | None = None,
) -> np.ndarray:
    """The replaced algorithm (sim/solvers/linear_radau.py before the reduced solve and
    the blocked recursion), verbatim but for names."""
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
            ts = starts[c0:c1, None] + hs[:, None] * C[None, :]
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
                zx = inv @ np.tile(eye, (3, 1))[None]
                cache[c0] = (inv, zx, f_vec)
            zf = np.matmul(inv, col[:, :, None])[:, :, 0]
        p_mat = np.ascontiguousarray(zx[:, 2 * m :, :])
        g_vec = np.ascontiguousarray(zf[:, 2 * m :])
        for s in range(k):
            x = p_mat[s] @ x + g_vec[s]
            states[c0 + s + 1] = x
        if stages_out is not None:
            y = np.einsum("kij,kj->ki", zx, states[c0:c1]) + zf
            stages_out[c0:c1] = y.reshape(k, 3, m)
    return states


def relative_difference(new: np.ndarray, ref: np.ndarray) -> float:
    """Largest difference of each component over the run, over that component's scale."""
    flat_new, flat_ref = new.reshape(-1, new.shape[-1]), ref.reshape(-1, ref.shape[-1])
    scale = np.max(np.abs(flat_ref), axis=0)
    assert np.all(scale > 0)
    return float(np.max(np.max(np.abs(flat_new - flat_ref), axis=0) / scale))


def modal_coefficients(law: str, a1_s: float) -> tuple[Coefficients, int]:
    """The modal model's x' = (A0 + theta'^2 A1) x + theta'' f1 on the rig's four-bar
    (its 4 modes, as the damping fit's loop)."""
    rig = load_rig()
    model = ModalModel.build(
        BeamProperties.from_config(rig.beam), 4, a0_per_s=a1_s, a1_s=a1_s, damping_law=law
    )
    drive = FourBarDrive(
        FourBar.from_config(rig.linkage), 2.0 * math.pi * rig.linkage.crank_frequency_hz
    )
    a0, a1, f1 = model.first_order_parts()

    def coefficients(ts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        rate = np.asarray(drive.rate(ts))
        acc = np.asarray(drive.accel(ts))
        return a0[None] + (rate**2)[:, None, None] * a1[None], acc[:, None] * f1[None]

    return coefficients, 2 * model.n_modes


# The stiff system: q'' + C(t) q' + K(t) q = F(t) with q' = v + fq(t), three coupled
# modes at 3, 80 and 2500 rad/s, the fastest overdamped (zeta ~ 5), every coefficient
# moving in time; at h = 1 ms, h w = 2.5 and h c = 25 for the fastest.
_W = np.array([3.0, 80.0, 2500.0])
_ZETA = np.array([0.02, 0.3, 5.0])
_COUPLE = np.array([[0.0, 0.2, 0.05], [0.2, 0.0, 0.1], [0.05, 0.1, 0.0]])


def stiff_coefficients(ts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = _W.size
    mod = 1.0 + 0.3 * np.sin(2.0 * math.pi * 1.7 * ts)
    stiff = (np.diag(_W**2) + _COUPLE * np.outer(_W, _W))[None] * mod[:, None, None]
    damp = np.diag(2.0 * _ZETA * _W)[None] * (1.0 + 0.5 * np.cos(7.0 * ts))[:, None, None]
    a_mat = np.zeros((ts.size, 2 * n, 2 * n))
    a_mat[:, :n, n:] = np.eye(n)
    a_mat[:, n:, :n] = -stiff
    a_mat[:, n:, n:] = -damp
    f_vec = np.zeros((ts.size, 2 * n))
    f_vec[:, 0] = 0.01 * np.cos(3.0 * ts)
    f_vec[:, n:] = np.stack([np.cos(5.0 * ts), 40.0 * np.sin(11.0 * ts), 1e4 + 0 * ts], axis=1)
    return a_mat, f_vec


def swapped_stiff_coefficients(ts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The stiff system in y = [v, q]: not a second-order form [[0, I], [B, D]] any more,
    so the full stage system is solved."""
    a_mat, f_vec = stiff_coefficients(ts)
    return a_mat[:, _SWAP][:, :, _SWAP], f_vec[:, _SWAP]


_SWAP = np.r_[3:6, 0:3]
_ROTATION = np.linalg.qr(np.random.default_rng(7).normal(size=(6, 6)))[0]


def rotated_stiff_coefficients(ts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The stiff system in y = R x (R orthogonal), whose P mix the stiff modes' fast
    rates into every component: the step-by-step recursion itself rounds to 3e-12 here."""
    a_mat, f_vec = stiff_coefficients(ts)
    return _ROTATION @ a_mat @ _ROTATION.T, f_vec @ _ROTATION.T


X0_STIFF = np.array([1e-3, -2e-4, 3e-6, 0.0, 0.1, -0.5])


@pytest.mark.parametrize(("law", "a1_s"), [("material", 0.05), ("paper", 0.2)])
def test_modal_states_equal_the_replaced_algorithms_to_rounding(law: str, a1_s: float) -> None:
    coefficients, m = modal_coefficients(law, a1_s)
    # the fit's grid: 400 Hz over 10 s (one chunk), and a 2-chunk run at 1 kHz
    for grid in (np.arange(0.0, 10.0, 1.0 / 400.0), np.arange(0.0, 9.0, 1.0 / 1000.0)):
        x0 = np.zeros(m)
        new, ref = radau_grid(coefficients, grid, x0), reference_radau_grid(coefficients, grid, x0)
        assert relative_difference(new, ref) < ROUNDING


@pytest.mark.parametrize("swapped", [False, True])
def test_a_stiff_time_varying_system_equals_the_replaced_algorithm(swapped: bool) -> None:
    coefficients = swapped_stiff_coefficients if swapped else stiff_coefficients
    grid = np.linspace(0.0, 5.0, 5001)  # 5000 steps of 1 ms: two chunks
    x0 = X0_STIFF[_SWAP] if swapped else X0_STIFF
    new, ref = radau_grid(coefficients, grid, x0), reference_radau_grid(coefficients, grid, x0)
    assert relative_difference(new, ref) < ROUNDING
    # and the states move: the comparison is not between two near-zero runs
    assert np.ptp(ref[:, 2 + 3 * swapped]) > 10 * abs(ref[0, 2 + 3 * swapped])


@pytest.mark.parametrize("swapped", [False, True])
def test_stages_and_the_cached_factors_equal_the_replaced_algorithms(swapped: bool) -> None:
    """The nonlinear modal model's use: stage values out, a cache, then a second call with
    a forcing known at the stage times only."""
    coefficients = swapped_stiff_coefficients if swapped else stiff_coefficients
    grid = np.linspace(0.0, 5.0, 5001)
    x0 = X0_STIFF[_SWAP] if swapped else X0_STIFF
    v = slice(0, 3) if swapped else slice(3, 6)
    shape = (grid.size - 1, 3, x0.size)
    stages_new, stages_ref = np.empty(shape), np.empty(shape)
    cache_new: dict[int, tuple[np.ndarray, ...]] = {}
    cache_ref: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
    extra = np.zeros(shape)
    for _ in range(2):
        new = radau_grid(coefficients, grid, x0, extra, stages_new, cache_new)
        ref = reference_radau_grid(coefficients, grid, x0, extra, stages_ref, cache_ref)
        assert relative_difference(new, ref) < ROUNDING
        assert relative_difference(stages_new, stages_ref) < ROUNDING
        # a forcing in the q' equations, as the nonlinear terms enter
        extra[:, :, v] = 50.0 * np.sin(stages_ref[:, :, v] * 3.0)


def _one_step_p_g(coefficients: Coefficients, grid: np.ndarray, m: int) -> tuple[np.ndarray, ...]:
    hs = np.diff(grid)
    k = hs.size
    ts = grid[:-1, None] + hs[:, None] * C[None, :]
    a_mat, f_vec = coefficients(ts.ravel())
    a_mat, f_vec = a_mat.reshape(k, 3, m, m), f_vec.reshape(k, 3, m)
    if _second_order_size(a_mat):
        zx, zf, _ = _stages_second_order(hs, a_mat, f_vec, m // 2, False, slice(2, 3))
    else:
        zx, zf, _ = _stages_full(hs, a_mat, f_vec, False)
    return zx[:, -1], zf[:, -1]


@pytest.mark.slow
@pytest.mark.parametrize("case", ["lightly damped modal, 100k steps", "rotated stiff system"])
def test_the_blocked_recursion_rounds_as_the_step_by_step_one(case: str) -> None:
    """The worst cases for composed steps: 100k steps (25 s at 4 kHz) of the modal model
    with a1 = 1e-4 s, whose P barely shrink anything, and the rotated stiff system, whose
    products of P round far worse than the P applied to the state (composing alone was
    1e-10 off there). Against the step-by-step recursion in extended precision on the same
    P, g, the blocked recursion is as close as the step-by-step recursion in double
    (measured 2.4e-14 and 2.4e-14; 3.3e-12 and 3.0e-12)."""
    if case.startswith("lightly"):
        coefficients, m = modal_coefficients("material", 1e-4)
        grid, x0 = np.arange(100_001) / 4000.0, np.zeros(m)
    else:
        coefficients, m = rotated_stiff_coefficients, 6
        grid, x0 = np.linspace(0.0, 5.0, 5001), _ROTATION @ X0_STIFF
    p_mat, g_vec = _one_step_p_g(coefficients, grid, m)
    if case.startswith("lightly"):
        assert np.max(np.abs(np.linalg.eigvals(p_mat[::997]))) > 0.99999
    k = grid.size - 1
    blocked = np.empty((k + 1, m))
    blocked[0] = x0
    for c0 in range(0, k, _CHUNK):  # as radau_grid runs it: chunk by chunk
        c1 = min(k, c0 + _CHUNK)
        _affine_run(p_mat[c0:c1], g_vec[c0:c1], blocked[c0], blocked[c0 + 1 : c1 + 1])
    double = np.empty((k + 1, m))
    extended = np.empty((k + 1, m), dtype=np.longdouble)
    double[0] = extended[0] = x0
    x, y = x0.copy(), x0.astype(np.longdouble)
    p_ext, g_ext = p_mat.astype(np.longdouble), g_vec.astype(np.longdouble)
    for s in range(k):
        x = p_mat[s] @ x + g_vec[s]
        y = p_ext[s] @ y + g_ext[s]
        double[s + 1], extended[s + 1] = x, y
    exact = extended.astype(float)
    own = relative_difference(double, exact)
    assert relative_difference(blocked, exact) <= 2.0 * own
    if case.startswith("lightly"):
        assert relative_difference(blocked, exact) < ROUNDING


def test_the_blocked_recursion_on_short_and_ragged_runs() -> None:
    """Every run length, blocks or not filling the run exactly, gives the recursion."""
    rng = np.random.default_rng(3)
    for k in (1, 2, 3, 5, 16, 17, 99):
        p = 0.5 * rng.normal(size=(k, 4, 4)) / 2.0
        g = rng.normal(size=(k, 4))
        x = rng.normal(size=4)
        out = np.empty((k, 4))
        _affine_run(p, g, x, out)
        want = np.empty((k, 4))
        for s in range(k):
            x = p[s] @ x + g[s]
            want[s] = x
        np.testing.assert_allclose(out, want, rtol=0.0, atol=1e-13 * np.max(np.abs(want)))
