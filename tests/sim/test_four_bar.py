"""Four-bar kinematics against the loop-closure equation (Eq. 4) and brute force."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sim.config import LinkageConfig
from sim.four_bar import (
    FourBar,
    classify_grashof,
    corrected_eq9_rocker_angle_rad,
    paper_eq9_rocker_angle_rad,
)

PAPER = FourBar(0.340, 0.045, 0.330, 0.065)


def _wrap(a: np.ndarray) -> np.ndarray:
    return np.mod(a + math.pi, 2.0 * math.pi) - math.pi


@st.composite
def crank_rockers(draw: st.DrawFn) -> FourBar:
    crank = draw(st.floats(0.01, 0.1))
    ground = draw(st.floats(crank * 1.5, 1.0))
    rocker = draw(st.floats(crank * 1.2, 1.0))
    # coupler within the Grashof window: s + l < p + q with the crank shortest
    lo = abs(ground - rocker) + crank
    hi = ground + rocker - crank
    frac = draw(st.floats(0.02, 0.98))
    coupler = max(lo + frac * (hi - lo), crank * 1.01)
    branch = draw(st.sampled_from([1, -1]))
    if classify_grashof(ground, crank, coupler, rocker) != "crank-rocker":
        return PAPER
    return FourBar(ground, crank, coupler, rocker, branch)


@settings(max_examples=150, deadline=None)
@given(fb=crank_rockers(), psi=st.floats(-20.0, 20.0))
def test_loop_closure_holds_to_1e12_m(fb: FourBar, psi: float) -> None:
    assert abs(float(fb.loop_closure_residual_m(psi))) <= 1e-12
    dense = np.linspace(0.0, 2.0 * math.pi, 2001)
    assert np.max(np.abs(fb.loop_closure_residual_m(dense))) <= 1e-12


def test_paper_values_at_psi_0_and_pi_and_true_extrema_differ() -> None:
    phi = np.degrees(PAPER.rocker_angle_rad([0.0, math.pi]))
    assert phi == pytest.approx([62.598, 150.474], abs=6e-4)
    ext = PAPER.extrema()
    # brute force over a dense crank grid
    psi = np.linspace(0.0, 2.0 * math.pi, 400_001)
    phi_dense = PAPER.rocker_angle_rad(psi)
    assert ext.rocker_min_rad == pytest.approx(phi_dense.min(), abs=1e-10)
    assert ext.rocker_max_rad == pytest.approx(phi_dense.max(), abs=1e-10)
    assert ext.crank_at_min_rad == pytest.approx(psi[np.argmin(phi_dense)], abs=2e-4)
    assert ext.crank_at_max_rad == pytest.approx(psi[np.argmax(phi_dense)], abs=2e-4)
    # the paper's "extrema" are not extrema: the true range is about 1 deg wider
    assert math.degrees(ext.rocker_min_rad) == pytest.approx(61.928, abs=1e-3)
    assert math.degrees(ext.rocker_max_rad) == pytest.approx(150.845, abs=1e-3)
    assert math.degrees(ext.range_rad) - 87.876 > 1.0
    assert math.degrees(ext.crank_at_min_rad) == pytest.approx(8.797, abs=1e-3)
    # dead centres: crank and coupler collinear there
    for psi_x in (ext.crank_at_min_rad, ext.crank_at_max_rad):
        p = PAPER.crank_tip_m(psi_x)
        q = PAPER.rocker_tip_m(psi_x)
        cross = p[0] * (q[1] - p[1]) - p[1] * (q[0] - p[0])
        assert abs(cross) < 1e-12
        assert abs(float(PAPER.rocker_rate_rad_s(psi_x, 1.0))) < 1e-9


def test_printed_eq8_is_off_by_pi_and_printed_eq9_is_wrong() -> None:
    psi = np.linspace(0.0, 2.0 * math.pi, 37)
    phi = PAPER.rocker_angle_rad(psi)
    eq8 = PAPER.paper_eq8_rocker_angle_rad(psi, sign=1)
    assert np.max(np.abs(_wrap(eq8 + math.pi - phi))) < 1e-12
    assert np.min(np.abs(_wrap(eq8 - phi))) > 3.0  # as printed: pi away everywhere
    assert np.max(np.abs(_wrap(corrected_eq9_rocker_angle_rad(psi) - phi))) < 1e-12
    printed = paper_eq9_rocker_angle_rad(0.0)
    assert math.degrees(float(printed)) == pytest.approx(33.82, abs=0.01)  # not 62.598


def test_rates_match_finite_differences() -> None:
    psi = np.linspace(0.1, 6.2, 50)
    h = 1e-5
    for fb in (PAPER, FourBar(0.34, 0.045, 0.33, 0.065, -1), FourBar(0.5, 0.1, 0.45, 0.3)):
        w2, al2 = 3.7, -1.3
        fd_rate = (fb.rocker_angle_rad(psi + h) - fb.rocker_angle_rad(psi - h)) / (2 * h)
        assert fb.rocker_rate_rad_s(psi, w2) == pytest.approx(w2 * fd_rate, rel=1e-8, abs=1e-9)
        # d/dt phi' = (d phi'/d psi) psi' + (d phi'/d psi') psi''; phi' is linear in psi'.
        d_rate = (fb.rocker_rate_rad_s(psi + h, w2) - fb.rocker_rate_rad_s(psi - h, w2)) / (2 * h)
        expected = d_rate * w2 + fb.rocker_rate_rad_s(psi, 1.0) * al2
        assert fb.rocker_accel_rad_s2(psi, w2, al2) == pytest.approx(expected, rel=1e-7, abs=1e-7)


def test_transmission_angle_range() -> None:
    mu_min, mu_max = PAPER.transmission_angle_range_rad()
    psi = np.linspace(0.0, 2.0 * math.pi, 100_001)
    mu = PAPER.transmission_angle_rad(psi)
    assert mu_min == pytest.approx(mu.min(), abs=1e-9)
    assert mu_max == pytest.approx(mu.max(), abs=1e-9)
    # equals the angle between coupler and rocker directions
    th3 = PAPER.coupler_angle_rad(psi[::1000])
    phi = PAPER.rocker_angle_rad(psi[::1000])
    direct = np.abs(_wrap(th3 - phi))
    assert np.minimum(direct, math.pi - direct) == pytest.approx(
        np.minimum(mu[::1000], math.pi - mu[::1000]), abs=1e-9
    )


@pytest.mark.parametrize(
    ("lengths", "kind"),
    [
        ((0.34, 0.045, 0.33, 0.065), "crank-rocker"),
        ((0.045, 0.34, 0.33, 0.065), "double-crank"),
        ((0.34, 0.33, 0.045, 0.065), "double-rocker"),
        ((0.4, 0.2, 0.25, 0.3), "non-grashof"),
        ((0.3, 0.1, 0.3, 0.1), "change-point"),
    ],
)
def test_grashof_classes_and_refusal(lengths: tuple[float, ...], kind: str) -> None:
    assert classify_grashof(*lengths) == kind
    if kind != "crank-rocker":
        with pytest.raises(ValueError, match="not a crank-rocker"):
            FourBar(*lengths)


def test_unassemblable_position_is_refused() -> None:
    fb = FourBar(0.4, 0.2, 0.25, 0.3, require_crank_rocker=False)  # triple rocker
    with pytest.raises(ValueError, match="cannot assemble"):
        fb.rocker_angle_rad(math.pi)


def test_from_config() -> None:
    fb = FourBar.from_config(LinkageConfig())
    assert fb.rocker_angle_rad(0.0) == pytest.approx(PAPER.rocker_angle_rad(0.0))
