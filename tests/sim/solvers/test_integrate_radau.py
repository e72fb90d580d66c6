"""Our Radau IIA (``sim.solvers.radau``): accuracy against known solutions, both Newton variants,
energy on an undamped oscillator, and agreement with scipy on the paper's FE scene."""

from __future__ import annotations

import numpy as np
import pytest

from sim.beam import BeamProperties
from sim.config import BeamConfig
from sim.drives import SinusoidDrive
from sim.models.fe import simulate_fe
from sim.solvers.radau import radau5

LAM = 1e4  # stiffness of the Prothero-Robinson problem


def _pr_rhs(ts: np.ndarray, ys: np.ndarray) -> np.ndarray:
    # y' = -LAM (y - cos t) - sin t, y = cos t; second component y2' = -y1 (y2 = -sin t)
    out = np.empty_like(ys)
    out[:, 0] = -LAM * (ys[:, 0] - np.cos(ts)) - np.sin(ts)
    out[:, 1] = -ys[:, 0]
    return out


def _pr_jac(t: float, y: np.ndarray) -> np.ndarray:
    return np.array([[-LAM, 0.0], [-1.0, 0.0]])


def _pr_jac_stages(ts: np.ndarray, ys: np.ndarray) -> np.ndarray:
    return np.broadcast_to(_pr_jac(0.0, ys[0]), (ts.size, 2, 2)).copy()


@pytest.mark.parametrize("full_newton", [False, True])
def test_stiff_problem_error_follows_the_tolerance(full_newton: bool) -> None:
    t = np.linspace(0.0, 10.0, 101)
    exact = np.stack([np.cos(t), -np.sin(t)], axis=1)
    errs = []
    for rtol in (1e-5, 1e-7, 1e-9):
        y, stats, _ = radau5(
            _pr_rhs, _pr_jac, t, exact[0], rtol=rtol, atol=rtol,
            jac_stages=_pr_jac_stages if full_newton else None,
        )  # fmt: skip
        errs.append(float(np.max(np.abs(y - exact))))
        assert errs[-1] <= 10 * rtol
        assert stats.n_steps > 0
    # a 100x tighter tolerance buys at least 20x: the local error is controlled (order 5,
    # the step scales as rtol^(1/5) and the global error as rtol)
    assert errs[1] <= errs[0] / 20 and errs[2] <= errs[1] / 20


def test_undamped_oscillator_keeps_its_energy() -> None:
    w = 2.0 * np.pi

    def rhs(ts: np.ndarray, ys: np.ndarray) -> np.ndarray:
        return np.stack([ys[:, 1], -w * w * ys[:, 0]], axis=1)

    def jac(t: float, y: np.ndarray) -> np.ndarray:
        return np.array([[0.0, 1.0], [-w * w, 0.0]])

    t = np.linspace(0.0, 20.0, 401)  # 20 periods
    y, _, _ = radau5(rhs, jac, t, np.array([1.0, 0.0]), rtol=1e-9, atol=1e-12)
    energy = 0.5 * y[:, 1] ** 2 + 0.5 * w * w * y[:, 0] ** 2
    # Radau IIA is dissipative at O(h^5) per step: over 20 periods the energy may only
    # drift at the level of the tolerance (outputs come from the dense output, so it is
    # not monotone between steps)
    assert abs(energy[-1] / energy[0] - 1.0) < 1e-6
    assert np.max(np.abs(y[:, 0] - np.cos(w * t))) < 1e-6


def test_fe_radau5_matches_scipy_radau_on_the_paper_scene() -> None:
    beam = BeamProperties.from_config(BeamConfig())
    drive = SinusoidDrive(0.7669, 4.970)
    t = np.linspace(0.0, 0.6, 121)
    kw = {"n_elements": 2, "a0_per_s": 0.1, "a1_s": 0.1}
    ours = simulate_fe(beam, drive, t, rtol=1e-8, atol=1e-10, method="radau5", **kw)
    theirs = simulate_fe(beam, drive, t, rtol=1e-8, atol=1e-10, method="Radau", **kw)
    scale = np.max(np.abs(theirs.tip_lateral_m))
    assert np.max(np.abs(ours.tip_lateral_m - theirs.tip_lateral_m)) < 1e-5 * scale


def test_predicted_stage_jacobians_need_about_one_evaluation_per_step() -> None:
    # the reason radau5 is fast on the damped scene: Jacobians at the predicted stages are
    # nearly exact, so Newton rarely re-evaluates them (measured: 1.0 per attempted step
    # and 2.1 iterations over 5 s of the paper's scene; a Jacobian per iteration, the full
    # Newton, would be 2.1)
    beam = BeamProperties.from_config(BeamConfig())
    drive = SinusoidDrive(0.7669, 4.970)
    t = np.linspace(0.0, 2.0, 401)
    res = simulate_fe(
        beam, drive, t, n_elements=2, a0_per_s=0.1, a1_s=0.1, rtol=1e-4, atol=1e-4,
        method="radau5",
    )  # fmt: skip
    jac_per_step = res.settings["n_jac"] / 3 / res.settings["n_steps"]
    assert jac_per_step < 1.4


def test_blas_runs_on_one_thread_during_the_integration_and_is_restored() -> None:
    """OpenBLAS factors the 3n x 3n Newton matrix with its busy-waiting thread pool from
    about 3n = 144 (six elements) on, which made a six-element run 10-40x slower whenever
    another job held the second core; radau5 therefore holds BLAS to one thread itself
    (whatever the caller set) and gives the caller's setting back afterwards."""
    from threadpoolctl import threadpool_info, threadpool_limits

    seen: list[int] = []

    def rhs(ts: np.ndarray, ys: np.ndarray) -> np.ndarray:
        seen.extend(p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas")
        return _pr_rhs(ts, ys)

    with threadpool_limits(limits=2, user_api="blas"):
        before = [p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"]
        radau5(rhs, _pr_jac, np.linspace(0.0, 0.5, 6), np.array([1.0, 0.0]), rtol=1e-6, atol=1e-9)
        after = [p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"]
    assert seen and set(seen) == {1}
    assert after == before


def test_error_filter_on_the_displacements_equals_the_full_solve() -> None:
    """The Schur complement of ``gamma I - J`` for ``J = [[0, I], [Kd, Kv]]`` gives the
    full system's solution (to rounding), on random, unsymmetric blocks."""
    from sim.solvers.radau import _ErrorFilter

    rng = np.random.default_rng(5)
    m = 7
    kd = rng.normal(size=(m, m)) * 50.0
    kv = rng.normal(size=(m, m)) * 3.0
    jac = np.block([[np.zeros((m, m)), np.eye(m)], [kd, kv]])
    b = rng.normal(size=2 * m)
    gamma = 41.3
    exact = np.linalg.solve(gamma * np.eye(2 * m) - jac, b)
    for second_order in (False, True):
        got = _ErrorFilter(gamma, jac, second_order).solve(b)
        np.testing.assert_allclose(got, exact, rtol=1e-12, atol=1e-12 * np.max(np.abs(exact)))


def _duffing(ts: np.ndarray, ys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two coupled stiff, damped, nonlinear oscillators, y = [x1, x2, v1, v2], and their
    Jacobians; forced at 3 rad/s."""
    x1, x2, v1, v2 = ys.T
    k, c = 4.0e4, 30.0
    a1 = -k * (x1 - x2) - 5.0 * x1**3 - c * (v1 - v2) + np.sin(3.0 * ts)
    a2 = -k * (x2 - x1) - 20.0 * x2 - c * (v2 - v1) - x2 * v2**2
    f = np.stack([v1, v2, a1, a2], axis=1)
    j = np.zeros((ts.size, 4, 4))
    j[:, 0, 2] = j[:, 1, 3] = 1.0
    j[:, 2, 0], j[:, 2, 1], j[:, 2, 2], j[:, 2, 3] = -k - 15.0 * x1**2, k, -c, c
    j[:, 3, 0], j[:, 3, 1], j[:, 3, 2], j[:, 3, 3] = k, -k - 20.0 - v2**2, c, -c - 2 * x2 * v2
    return f, j


def test_second_order_newton_gives_the_full_newtons_solution() -> None:
    """Newton on the rates alone converges to the same collocation solution as on the
    whole state: the two runs agree far inside their tolerance, against a tight run."""
    t = np.linspace(0.0, 3.0, 61)
    y0 = np.array([0.01, -0.02, 0.0, 0.3])

    def rhs(ts: np.ndarray, ys: np.ndarray) -> np.ndarray:
        return _duffing(ts, ys)[0]

    def jac(t_s: float, y: np.ndarray) -> np.ndarray:
        return _duffing(np.array([t_s]), y[None, :])[1][0]

    def run(rtol: float, second_order: bool) -> tuple[np.ndarray, int]:
        y, stats, _ = radau5(
            rhs, jac, t, y0, rtol=rtol, atol=rtol, rhs_jac_stages=_duffing,
            second_order=second_order,
        )  # fmt: skip
        return y, stats.n_newton

    truth = run(1e-11, False)[0]
    for rtol in (1e-5, 1e-7):
        (full, it_full), (reduced, it_reduced) = run(rtol, False), run(rtol, True)
        err_full = np.max(np.abs(full - truth))
        assert np.max(np.abs(reduced - truth)) <= 2.0 * err_full + 1e-12
        assert err_full <= 1e3 * rtol  # sanity: both follow the tolerance
        # the same Newton (exact matrix): as many iterations, not a slower fixed point
        assert abs(it_reduced - it_full) <= 0.05 * it_full
    assert np.max(np.abs(run(1e-11, True)[0] - truth)) < 1e-8
