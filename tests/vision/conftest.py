"""Rendered scenes shared by the vision tests (building a scene's pixel maps takes ~1 s)."""

from __future__ import annotations

import math

import pytest

from vision.calibration import Calibration
from vision.config import CameraConfig, CameraPoseConfig, RegistrationConfig
from vision.synthetic.scene import BeamPose, SceneSpec

L_M = 0.835
W_M = 0.01905


def make_spec(**kw: object) -> SceneSpec:
    camera = kw.pop("camera", CameraConfig())
    pose = kw.pop("pose", CameraPoseConfig())
    return SceneSpec.from_rig(
        camera,  # type: ignore[arg-type]
        pose,  # type: ignore[arg-type]
        RegistrationConfig(),
        beam_length_m=L_M,
        beam_width_m=W_M,
        hub_offset_m=0.008,
        **kw,  # type: ignore[arg-type]
    )


def bent(hub_angle_rad: float, tip_slope_rad: float) -> BeamPose:
    """A static-tip-load-like shape: slope th(s) = th_L (2 s/L - (s/L)^2)."""
    return BeamPose.from_slope(
        hub_angle_rad, L_M, lambda s: tip_slope_rad * (2 * s / L_M - (s / L_M) ** 2)
    )


def truth_calibration(truth: object) -> Calibration:
    return Calibration(
        truth.corners_px,  # type: ignore[attr-defined]
        truth.plane_points_m,  # type: ignore[attr-defined]
        truth.camera_matrix,  # type: ignore[attr-defined]
        truth.distortion,  # type: ignore[attr-defined]
        beam_length_m=L_M,
        beam_width_m=W_M,
    )


@pytest.fixture(scope="session")
def nominal_spec() -> SceneSpec:
    return make_spec(noise_dn=2.0, seed=1)


@pytest.fixture(scope="session")
def clean_spec() -> SceneSpec:
    return make_spec(noise_dn=0.0, seed=2)


HUB_ANGLES_RAD = tuple(math.radians(a) for a in (245.0, 287.0, 328.0))


@pytest.fixture(scope="session")
def vt() -> object:
    """The helpers above (test modules cannot import conftest in importlib mode)."""
    import types

    return types.SimpleNamespace(
        L_M=L_M,
        W_M=W_M,
        make_spec=make_spec,
        bent=bent,
        truth_calibration=truth_calibration,
        HUB_ANGLES_RAD=HUB_ANGLES_RAD,
    )
