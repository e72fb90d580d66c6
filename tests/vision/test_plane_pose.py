"""The registration plane's pose fit (vision.plane_pose) against a camera of known K, R, t
(not the renderer's: another focal length, an off-centre principal point, a plate turned
and far from the optical axis), and its covariance against repeated noise."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from vision.homography import apply_homography, homography_from_lines
from vision.plane_pose import fit_lines, normalised, pose_from_homography, pose_homography

K = np.array([[1730.0, 0.0, 1011.0], [0.0, 1730.0, 779.0], [0.0, 0.0, 1.0]])
# the plate 0.3 m across, seen from 1.9 m, tilted 22 deg about an oblique axis, rolled
RVEC = np.array([0.30, -0.22, 0.06])
TVEC = np.array([0.21, 0.12, 1.9])
LEVELS = (-0.15, -0.05, 0.05, 0.15)
# where the beam's tip would be: 0.8 m from the plate, beyond its edge
FAR_M = np.array([[-0.45, -0.68], [0.35, -0.75]])


def _lines_and_points(
    rng: np.random.Generator | None, sigma_px: float, k: np.ndarray = K
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Ideal-pixel points (one per ~1.5 px) along the eight plate edges seen by the camera
    (K, RVEC, TVEC), with Gaussian noise of ``sigma_px``; their line index; the lines."""
    g = np.linalg.inv(pose_homography(np.concatenate([RVEC, TVEC]), k))
    pts, idx, lines = [], [], []
    for axis in (0, 1):
        for level in LEVELS:
            t = np.linspace(-0.14, 0.14, 200)
            local = np.zeros((len(t), 2))
            local[:, axis], local[:, 1 - axis] = level, t
            px = apply_homography(g, local)
            if rng is not None:
                px = px + sigma_px * rng.standard_normal(px.shape)
            pts.append(px)
            idx.append(np.full(len(t), len(lines)))
            line = np.zeros(3)
            line[axis], line[2] = 1.0, -level
            lines.append(line)
    return np.vstack(pts), np.concatenate(idx), np.array(lines)


def _true_plane_from_ideal() -> np.ndarray:
    return pose_homography(np.concatenate([RVEC, TVEC]), K)


def _free(pts: np.ndarray, idx: np.ndarray, lines: np.ndarray) -> np.ndarray:
    start = _true_plane_from_ideal() @ np.diag([1.0 + 1e-3, 1.0, 1.0])
    per_line = [pts[idx == j] for j in range(len(lines))]
    return homography_from_lines(per_line, lines, start).matrix


def test_the_pose_of_a_homography_is_recovered_in_closed_form() -> None:
    h = _true_plane_from_ideal()
    x = pose_from_homography(h, K)
    np.testing.assert_allclose(x[:3], RVEC, atol=1e-12)
    np.testing.assert_allclose(x[3:], TVEC, rtol=1e-12)
    r, _ = cv2.Rodrigues(RVEC)
    g = K @ np.column_stack([r[:, 0], r[:, 1], TVEC])
    np.testing.assert_allclose(h, normalised(np.linalg.inv(g)), rtol=1e-12)


def test_noise_free_edges_give_the_true_pose() -> None:
    pts, idx, lines = _lines_and_points(None, 0.0)
    fit = fit_lines(pts, idx, lines, _free(pts, idx, lines), K)
    assert fit.model == "pose" and not fit.note
    far = apply_homography(np.linalg.inv(_true_plane_from_ideal()), FAR_M)
    np.testing.assert_allclose(apply_homography(fit.matrix, far), FAR_M, atol=1e-9)


def test_the_pose_and_its_covariance_against_repeated_noise() -> None:
    """With the right K, the pose extrapolates to the tip better than the free homography,
    and the stated covariance there is the spread of the repeated fits."""
    sigma = 0.12
    rng = np.random.default_rng(2024)
    far_px = apply_homography(np.linalg.inv(_true_plane_from_ideal()), FAR_M)
    z, err_pose, err_free = [], [], []
    for _ in range(30):
        pts, idx, lines = _lines_and_points(rng, sigma)
        free = _free(pts, idx, lines)
        fit = fit_lines(pts, idx, lines, free, K)
        assert fit.model == "pose", fit.note
        assert fit.sigma_px == pytest.approx(sigma, rel=0.1)
        d = apply_homography(fit.matrix, far_px) - FAR_M
        err_pose.append(d)
        err_free.append(apply_homography(free, far_px) - FAR_M)
        for p, di in zip(far_px, d, strict=True):
            jac = _plane_jacobian(fit.matrix, p)
            cov = jac @ fit.covariance @ jac.T
            z.extend(di / np.sqrt(np.diag(cov)))
    rms_z = float(np.sqrt(np.mean(np.square(z))))
    # 120 normalised errors (30 fits x 2 points x 2 axes): RMS 1 within its sampling spread
    assert 0.75 < rms_z < 1.3
    assert np.max(np.abs(z)) < 3.5
    rms_pose = float(np.sqrt(np.mean(np.square(err_pose))))
    rms_free = float(np.sqrt(np.mean(np.square(err_free))))
    assert rms_pose < 0.6 * rms_free


def _plane_jacobian(h: np.ndarray, px: np.ndarray) -> np.ndarray:
    """(2, 9) derivative of the plane point at pixel px with H's elements (by differences:
    independent of vision.calibration_error's closed form)."""
    out = np.zeros((2, 9))
    for k in range(9):
        dh = np.zeros(9)
        dh[k] = 1e-6 * max(abs(h.ravel()[k]), 1e-9)
        up = apply_homography(h + dh.reshape(3, 3), px[None])[0]
        down = apply_homography(h - dh.reshape(3, 3), px[None])[0]
        out[:, k] = (up - down) / (2 * dh[k])
    return out


@pytest.mark.parametrize(
    "wrong",
    [
        np.array([[1.12, 0, 0], [0, 1.12, 0], [0, 0, 1.0]]),  # focal length 12 % long
        np.array([[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]])
        + np.array([[0, 0, 90.0 / 1730], [0, 0, 0], [0, 0, 0]]),  # principal point 90 px off
    ],
)
def test_a_wrong_camera_matrix_falls_back_to_the_free_homography(wrong: np.ndarray) -> None:
    k_wrong = K @ wrong
    pts, idx, lines = _lines_and_points(np.random.default_rng(5), 0.12)
    free = _free(pts, idx, lines)
    fit = fit_lines(pts, idx, lines, free, k_wrong)
    assert fit.model == "homography"
    assert "stated camera matrix" in fit.note and "free homography is used" in fit.note
    np.testing.assert_allclose(fit.matrix, normalised(free), rtol=1e-12)
    # the right K on the same points is accepted
    assert fit_lines(pts, idx, lines, free, K).model == "pose"


def test_without_intrinsics_the_free_fit_and_its_covariance() -> None:
    pts, idx, lines = _lines_and_points(np.random.default_rng(6), 0.12)
    free = _free(pts, idx, lines)
    fit = fit_lines(pts, idx, lines, free, None)
    assert fit.model == "homography" and not fit.note and math.isnan(fit.focal_length_px)
    assert fit.covariance.shape == (9, 9)
    np.testing.assert_allclose(fit.covariance[8], 0.0, atol=0.0)
    assert np.all(np.linalg.eigvalsh(fit.covariance) > -1e-12 * np.abs(fit.covariance).max())
