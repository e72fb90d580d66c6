"""Order of accuracy of both Radau IIA integrators at a fixed step: the log-log slope of the
end-point error against the step is 5 (3-stage Radau IIA, order 2s - 1), fitted as
scikit-fem's convergence tests fit theirs.

The problem has a closed form: a damped oscillator driven harmonically,
x'' + 2 zeta w x' + w^2 x = cos(W t), x(0) = 1, x'(0) = 0 (non-autonomous, so the stage
times matter). Steps from T/20 to T/160: errors 2e-4 .. 5e-9, in the asymptotic range
(measured local slopes 5.08, 5.05, 5.03) and far above round-off. With 4 and 5 stages
(orders 7 and 9) the steps are T/10 .. T/40 and T/5 .. T/20 (errors 6e-5 .. 3e-9 and
1e-4 .. 6e-10; local slopes 7.02, 7.03 and 8.88, 9.00): finer steps reach round-off.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.errors import IntegrationError, SimInputError
from sim.solvers.linear_radau import radau_fixed
from sim.solvers.radau import radau5

W, ZETA, W_DRIVE = 2.0 * math.pi, 0.1, 3.0
A = np.array([[0.0, 1.0], [-W * W, -2.0 * ZETA * W]])
X0 = np.array([1.0, 0.0])
T_END = 2.0
STEPS = np.array([20, 40, 80, 160])


def _exact(t: float) -> np.ndarray:
    """[x, x'] at t: the particular solution Re(X e^(i W t)) plus the free decay
    2 Re(c e^(s t)), s = -zeta w + i w sqrt(1 - zeta^2), c fitted to the initial state."""
    amp = 1.0 / (W * W - W_DRIVE**2 + 2j * ZETA * W * W_DRIVE)
    s = -ZETA * W + 1j * W * math.sqrt(1.0 - ZETA * ZETA)
    # 2 Re c = x(0) - Re X, 2 Re(c s) = x'(0) - Re(i W X); c = a + i b
    a, b = np.linalg.solve(
        [[2.0, 0.0], [2.0 * s.real, -2.0 * s.imag]],
        [X0[0] - amp.real, X0[1] - (1j * W_DRIVE * amp).real],
    )
    c = a + 1j * b
    drive, free = amp * np.exp(1j * W_DRIVE * t), c * np.exp(s * t)
    return np.array(
        [drive.real + 2.0 * free.real, (1j * W_DRIVE * drive).real + 2.0 * (s * free).real]
    )


def _forcing(ts: np.ndarray) -> np.ndarray:
    return np.stack([np.zeros_like(ts), np.cos(W_DRIVE * ts)], axis=1)


def _rhs_stages(ts: np.ndarray, ys: np.ndarray) -> np.ndarray:
    return ys @ A.T + _forcing(ts)


def _jac(t: float, y: np.ndarray) -> np.ndarray:
    return A


def _jac_stages(ts: np.ndarray, ys: np.ndarray) -> np.ndarray:
    return np.broadcast_to(A, (ts.size, 2, 2)).copy()


def _rate(errors: list[float], steps: np.ndarray = STEPS) -> float:
    h = T_END / steps
    return float(np.polyfit(np.log(h), np.log(errors), 1)[0])


def _radau5_end(
    n_steps: int, full_newton: bool, stages: int = 3, second_order: bool = False
) -> np.ndarray:
    # tolerances only set Newton's stop here: tight, so the iteration error is round-off
    y, stats, _ = radau5(
        _rhs_stages, _jac, np.array([0.0, T_END]), X0, rtol=1e-13, atol=1e-13,
        fixed_step_s=T_END / n_steps, jac_stages=_jac_stages if full_newton else None,
        stages=stages, second_order=second_order,
    )  # fmt: skip
    assert stats.n_steps == n_steps and stats.n_rejected == 0
    return y[-1]


def _linear_end(n_steps: int) -> np.ndarray:
    def coefficients(ts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return np.broadcast_to(A, (ts.size, 2, 2)).copy(), _forcing(ts)

    return radau_fixed(coefficients, np.array([0.0, T_END]), X0, np.array([n_steps]))[-1]


@pytest.mark.parametrize("full_newton", [False, True])
def test_radau5_at_a_fixed_step_is_fifth_order(full_newton: bool) -> None:
    exact = _exact(T_END)
    errors = [float(np.max(np.abs(_radau5_end(n, full_newton) - exact))) for n in STEPS]
    assert errors[-1] < 1e-8
    assert _rate(errors) == pytest.approx(5.0, abs=0.15)


@pytest.mark.parametrize(("stages", "steps"), [(4, [10, 20, 40]), (5, [5, 10, 20])])
@pytest.mark.parametrize("second_order", [False, True])
def test_more_stages_at_a_fixed_step_are_of_order_2s_minus_1(
    stages: int, steps: list[int], second_order: bool
) -> None:
    exact = _exact(T_END)
    errors = [
        float(np.max(np.abs(_radau5_end(n, True, stages, second_order) - exact))) for n in steps
    ]
    assert errors[-1] < 1e-8
    assert _rate(errors, np.array(steps)) == pytest.approx(2 * stages - 1, abs=0.15)


def test_three_stages_are_the_default_bit_for_bit() -> None:
    for n in STEPS[:2]:
        np.testing.assert_array_equal(_radau5_end(n, True, 3), _radau5_end(n, True))


def test_linear_batched_radau_is_fifth_order() -> None:
    exact = _exact(T_END)
    errors = [float(np.max(np.abs(_linear_end(n) - exact))) for n in STEPS]
    assert errors[-1] < 1e-8
    assert _rate(errors) == pytest.approx(5.0, abs=0.15)


def test_both_integrators_take_the_same_steps() -> None:
    # one coefficient table, one method: on a linear problem at the same steps the adaptive
    # integrator's Newton and the batched affine recursion give the same states to rounding
    for n in STEPS:
        np.testing.assert_allclose(_radau5_end(n, False), _linear_end(n), rtol=0.0, atol=1e-12)


def test_fixed_step_is_validated_and_a_newton_failure_raises() -> None:
    t = np.array([0.0, 1.0])
    with pytest.raises(SimInputError, match="fixed_step_s"):
        radau5(_rhs_stages, _jac, t, X0, rtol=1e-6, atol=1e-6, fixed_step_s=0.0)
    for first in (0.0, 0.2, math.nan):  # the first step's first part: in (0, fixed step]
        with pytest.raises(SimInputError, match="first_step_s"):
            radau5(
                _rhs_stages, _jac, t, X0, rtol=1e-6, atol=1e-6, fixed_step_s=0.1,
                first_step_s=first,
            )  # fmt: skip
    # more stages: only at a fixed step (the error estimate is the 3-stage method's) and
    # with the stage Jacobians; 3, 4 or 5 of them
    for kwargs in ({}, {"fixed_step_s": 0.1, "jac_stages": None}):
        with pytest.raises(SimInputError, match="stages"):
            radau5(_rhs_stages, _jac, t, X0, rtol=1e-6, atol=1e-6, stages=5, **kwargs)  # type: ignore[arg-type]
    with pytest.raises(SimInputError, match="stages"):
        radau5(
            _rhs_stages, _jac, t, X0, rtol=1e-6, atol=1e-6, fixed_step_s=0.1,
            jac_stages=_jac_stages, stages=6,
        )  # fmt: skip

    def poisoned(ts: np.ndarray, ys: np.ndarray) -> np.ndarray:
        return np.where(ts[:, None] < 0.45, _rhs_stages(ts, ys), np.nan)

    # an adaptive run would halve the step until it underflows; a fixed one splits the
    # step down to 1/64 of it, then says where and at which part it failed (the parts
    # close in on 0.45 s, the last one's stages reach past it)
    with pytest.raises(IntegrationError, match=r"Newton does not converge") as failed:
        radau5(poisoned, _jac, t, X0, rtol=1e-6, atol=1e-6, fixed_step_s=0.1)
    message = str(failed.value)
    assert "fixed step 0.00156 s" in message
    t_fail = float(message.split("t = ")[1].split(" s")[0])
    assert 0.45 - 0.1 / 32 <= t_fail < 0.45


def test_a_fixed_step_starts_in_parts_and_stays_on_its_grid() -> None:
    """``first_step_s`` at a fixed step: the first step in parts from it, each twice the
    last (0.1 / 8: 1/8, 1/8, 1/4, 1/2 of it), then the fixed steps, each on the grid."""
    t = np.linspace(0.0, T_END, 21)
    whole, stats, _ = radau5(
        _rhs_stages, _jac, t, X0, rtol=1e-10, atol=1e-10, fixed_step_s=0.1,
        jac_stages=_jac_stages, stages=5,
    )  # fmt: skip
    parts, stats_parts, _ = radau5(
        _rhs_stages, _jac, t, X0, rtol=1e-10, atol=1e-10, fixed_step_s=0.1,
        jac_stages=_jac_stages, stages=5, first_step_s=0.0125,
    )  # fmt: skip
    assert stats_parts.n_steps == stats.n_steps + 3
    exact = np.array([_exact(float(x)) for x in t])
    # order 9 at the step ends: both far below the 3-stage method's error at this step
    assert np.max(np.abs(whole - exact)) < 1e-8
    assert np.max(np.abs(parts - exact)) < 1e-8
