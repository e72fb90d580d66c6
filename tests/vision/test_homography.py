from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from vision.errors import DegeneratePointsError
from vision.homography import apply_homography, collineation_4pt, dlt_homography

SQUARE = np.array([[0.0, 0.0], [0.04, 0.0], [0.04, 0.04], [0.0, 0.04]])


def _random_h(rng: np.random.Generator) -> np.ndarray:
    h = np.eye(3) + rng.normal(scale=[[0.3, 0.3, 50], [0.3, 0.3, 50], [1e-4, 1e-4, 0]])
    h[:2, :2] *= 1000.0
    return h


def test_collineation_maps_the_four_points_exactly() -> None:
    img = np.array([[100.0, 120.0], [410.0, 90.0], [450.0, 400.0], [80.0, 380.0]])
    fit = collineation_4pt(img, SQUARE)
    np.testing.assert_allclose(apply_homography(fit.matrix, img), SQUARE, atol=1e-13)
    assert fit.rms_residual < 1e-12


def test_collineation_recovers_a_known_homography() -> None:
    rng = np.random.default_rng(3)
    h = _random_h(rng)
    dst = apply_homography(h, SQUARE)
    fit = collineation_4pt(SQUARE, dst)
    np.testing.assert_allclose(fit.matrix / fit.matrix[2, 2], h / h[2, 2], rtol=1e-9, atol=1e-9)
    # And every other point of the plane follows.
    other = rng.uniform(-0.5, 0.5, size=(50, 2))
    np.testing.assert_allclose(
        apply_homography(fit.matrix, other), apply_homography(h, other), rtol=1e-8, atol=1e-6
    )


def test_dlt_agrees_with_the_collineation_on_four_points_and_fits_many() -> None:
    rng = np.random.default_rng(4)
    h = _random_h(rng)
    dst = apply_homography(h, SQUARE)
    a = collineation_4pt(SQUARE, dst).matrix
    b = dlt_homography(SQUARE, dst).matrix
    np.testing.assert_allclose(a, b, rtol=1e-7, atol=1e-7)
    many = rng.uniform(-0.2, 0.2, size=(30, 2))
    fit = dlt_homography(many, apply_homography(h, many))
    assert fit.rms_residual < 1e-8
    assert fit.condition < 1e4


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.floats(-0.2, 0.2), min_size=8, max_size=8),
    st.floats(-0.5, 0.5),
    st.floats(0.5, 2.0),
)
def test_inverse_round_trip(jitter: list[float], angle: float, scale: float) -> None:
    quad = SQUARE * 10 + np.reshape(jitter, (4, 2)) * 0.4
    c, s = np.cos(angle), np.sin(angle)
    rot = np.array([[c, -s], [s, c]]) * scale
    dst = (quad @ rot.T) * 100 + 500 + np.reshape(jitter[::-1], (4, 2)) * 30
    try:
        fit = collineation_4pt(quad, dst)
    except DegeneratePointsError:
        return
    pts = quad.mean(axis=0) + np.reshape(jitter, (4, 2))
    back = apply_homography(np.linalg.inv(fit.matrix), apply_homography(fit.matrix, pts))
    np.testing.assert_allclose(back, pts, atol=1e-8)


@pytest.mark.parametrize(
    ("pts", "words"),
    [
        ([[0, 0], [1, 0], [2, 0.0001], [0, 1]], "nearly collinear"),
        ([[0, 0], [1, 0], [1, 0], [0, 1]], "coincide"),
        ([[0, 0], [1, 0], [1, 1]], "at least 4"),
    ],
)
def test_degenerate_input_is_refused_with_a_reason(pts: list, words: str) -> None:
    dst = SQUARE[: len(pts)]
    with pytest.raises(DegeneratePointsError, match=words):
        collineation_4pt(np.array(pts, float), dst)


def test_shape_and_finiteness_are_checked() -> None:
    with pytest.raises(ValueError, match="src must have shape"):
        dlt_homography(np.zeros((4, 3)), SQUARE)
    with pytest.raises(ValueError, match="finite"):
        dlt_homography(np.full((4, 2), np.nan), SQUARE)
    with pytest.raises(ValueError, match="same shape"):
        dlt_homography(np.vstack([SQUARE, [[1, 2]]]), SQUARE)


def test_apply_homography_points_at_and_near_the_horizon() -> None:
    """The line w = 0 maps to infinity: NaN there, and the formula's (huge, finite)
    value just beside it, not the (0, 0) OpenCV's transform puts for |w| <= FLT_EPSILON."""
    h = np.array([[1.1, 0.02, 3.0], [0.01, 0.9, 4.0], [1e-3, 2e-3, -1.0]])
    pts = np.array([[1000.0, 0.0], [1000.0 + 1e-5, 0.0], [0.0, 0.0], [3.0, 7.0]])
    out = apply_homography(h, pts)
    assert np.all(np.isnan(out[0]))
    w = 1e-3 * pts[1, 0] - 1.0
    np.testing.assert_allclose(out[1], [(1.1 * pts[1, 0] + 3.0) / w, (0.01 * pts[1, 0] + 4.0) / w])
    np.testing.assert_allclose(out[2], [-3.0, -4.0])
    ref = (h @ [3.0, 7.0, 1.0])[:2] / (h @ [3.0, 7.0, 1.0])[2]
    np.testing.assert_allclose(out[3], ref, rtol=1e-14)
    # a plane point that truly maps to the image origin stays there
    g = np.eye(3)
    np.testing.assert_array_equal(apply_homography(g, [[0.0, 0.0]]), [[0.0, 0.0]])
    assert apply_homography(g, np.zeros((0, 2))).shape == (0, 2)


def test_map_points_is_the_formula_exactly() -> None:
    """``map_points`` (the kernel the calibration's mappings use) gives the numpy
    formula's values exactly, NaN on the horizon, and OpenCV's transform's within
    rounding elsewhere (OpenCV multiplies by 1 / w: one more rounding)."""
    from vision.homography import _apply_numpy, map_points

    rng = np.random.default_rng(51)
    h = np.array([[1.1, 0.02, 3.0], [0.01, 0.9, 4.0], [1e-3, 2e-3, -1.0]])
    pts = np.vstack([rng.uniform(-500, 500, (300, 2)), [[1000.0, 0.0], [0.0, 0.0]]])
    got = map_points(h, pts)
    np.testing.assert_array_equal(got, _apply_numpy(h, pts))
    assert np.all(np.isnan(got[-2]))
    np.testing.assert_allclose(got[:-2], apply_homography(h, pts[:-2]), rtol=1e-13)
    assert map_points(h, np.zeros((0, 2))).shape == (0, 2)
    one = np.array([[3.0, 7.0]])
    np.testing.assert_array_equal(map_points(h, [3.0, 7.0]), _apply_numpy(h, one))
