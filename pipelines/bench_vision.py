"""``beambench bench vision``: measurement error against speed on seeded rendered frames.

Sets (all 2048 x 1536, truth from the renderer):
- nominal: noise 2 DN, no lens distortion, PNG, camera tilted 10-20 deg;
- hard: tilt up to 45 deg, noise 10 DN, JPEG quality 60, |k1| = 0.1 with known intrinsics,
  lighting gradient and vignetting, low contrast, bright clutter near the beam, hub at
  either stroke end, tip deflections up to 80 mm;
- blur: motion blur of a beam swinging at the rig's peak rate over a 2 ms exposure.
Per-frame errors use the calibration from the true registration corners (the per-frame
chain alone); a last line gives the automatic registration detection's corner error.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from vision import Calibration, Measurer, decode, detect_registration_corners
from vision.config import CameraConfig, CameraPoseConfig, RegistrationConfig
from vision.render import BeamPose, Clutter, RenderTruth, SceneSpec, encode, render_frame

L_M, W_M = 0.835, 0.01905
STROKE_DEG = (243.0, 330.0)


@dataclass
class Frame:
    image: np.ndarray
    truth: RenderTruth
    calibration: Calibration


def _shape(rng: np.random.Generator, hub_rad: float, tip_max_m: float) -> BeamPose:
    """A mix of the first two cantilever-like shapes with tip deflection up to tip_max_m."""
    c1 = rng.uniform(-1, 1) * 1.5 * tip_max_m / L_M
    c2 = rng.uniform(-1, 1) * 0.3 * tip_max_m / L_M

    def slope(s: np.ndarray) -> np.ndarray:
        x = s / L_M
        return c1 * (2 * x - x**2) + c2 * np.sin(2.2 * np.pi * x) * x

    return BeamPose.from_slope(hub_rad, L_M, slope)


def _spec(rng: np.random.Generator, hard: bool, seed: int) -> SceneSpec:
    reg = RegistrationConfig()
    if not hard:
        pose = CameraPoseConfig(tilt_rad=math.radians(rng.uniform(10, 20)))
        return SceneSpec.from_rig(
            CameraConfig(),
            pose,
            reg,
            beam_length_m=L_M,
            beam_width_m=W_M,
            hub_offset_m=0.008,
            noise_dn=2.0,
            seed=seed,
        )
    tilt = math.radians(rng.uniform(30, 45))
    az = rng.choice([0.0, math.pi / 2, math.pi, -math.pi / 2]) + rng.uniform(-0.3, 0.3)
    pose = CameraPoseConfig(distance_m=1.75, tilt_rad=tilt, tilt_azimuth_rad=float(az))
    k1 = float(rng.choice([-0.1, 0.1]))
    cam = CameraConfig(distortion=(k1, 0.0, 0.0, 0.0, 0.0))
    clutter = tuple(
        Clutter(
            (float(rng.uniform(-0.5, 0.8)), float(rng.uniform(-0.9, -0.2))),
            (float(rng.uniform(0.03, 0.12)), float(rng.uniform(0.01, 0.05))),
            float(rng.uniform(0, np.pi)),
            float(rng.uniform(120, 250)),
        )
        for _ in range(6)
    )
    low = rng.random() < 0.5
    return SceneSpec.from_rig(
        cam,
        pose,
        reg,
        beam_length_m=L_M,
        beam_width_m=W_M,
        hub_offset_m=0.008,
        noise_dn=10.0,
        seed=seed,
        lighting_gradient=0.4,
        vignetting=0.3,
        background_dn=70.0 if low else 40.0,
        beam_dn=130.0 if low else 215.0,
        hub_dn=120.0 if low else 190.0,
        clutter=clutter,
    )


def _frames(kind: str, n: int, seed: int) -> tuple[list[Frame], list[float]]:
    rng = np.random.default_rng(seed)
    frames, corner_err = [], []
    n_specs = 1 if kind == "nominal" else max(1, n // 3)
    for k in range(n_specs):
        spec = _spec(rng, kind == "hard", seed + k)
        for _ in range(n // n_specs):
            if kind == "hard":
                hub = math.radians(float(rng.choice(STROKE_DEG)) + rng.uniform(-2, 2))
                poses = [_shape(rng, hub, 0.080)]
            elif kind == "blur":
                hub = math.radians(rng.uniform(265, 305))
                base = _shape(rng, hub, 0.035)
                rate = 3.8 * 0.002  # peak hub rate (rad/s) x exposure (s)
                poses = [
                    BeamPose(hub + d, base.stations_m, base.lateral_m, base.longitudinal_m)
                    for d in np.linspace(-rate / 2, rate / 2, 7)
                ]
            else:
                poses = [_shape(rng, math.radians(rng.uniform(*STROKE_DEG)), 0.035)]
            fr = render_frame(spec, poses, rng=rng)
            tr = fr.truth
            image = fr.image
            if kind == "hard":
                image = decode(encode(image, "jpeg", 60))
            cal = Calibration(tr.corners_px, tr.plane_points_m, tr.camera_matrix, tr.distortion)
            frames.append(Frame(image, tr, cal))
        try:
            det = detect_registration_corners(
                frames[-1].image, spec.registration, spec.camera_matrix, spec.distortion
            )
            corner_err.append(float(np.max(np.abs(det - frames[-1].truth.corners_px))))
        except ValueError:
            corner_err.append(math.nan)
    return frames, corner_err


def _evaluate(frames: list[Frame], method: str) -> dict[str, float]:
    measurers = {id(f.calibration): Measurer(f.calibration, method=method) for f in frames}
    errs: dict[str, list[float]] = {"hub": [], "lat": [], "lon": []}
    failed = 0
    measurers[id(frames[0].calibration)].measure(frames[0].image)  # warm-up (imports)
    t0 = time.perf_counter()
    results = [measurers[id(f.calibration)].measure(f.image) for f in frames]
    dt = time.perf_counter() - t0
    for f, m in zip(frames, results, strict=True):
        if not m.ok:
            failed += 1
            continue
        tr = f.truth
        d_hub = (m.hub_angle_rad - tr.hub_angle_rad + math.pi) % (2 * math.pi) - math.pi
        errs["hub"].append(math.degrees(d_hub))
        errs["lat"].append((m.tip_lateral_m - tr.tip_lateral_m) * 1e3)
        errs["lon"].append((m.tip_longitudinal_m - tr.tip_longitudinal_m) * 1e3)
    out = {"fps": len(frames) / dt, "failed": failed, "n": len(frames)}
    for k, v in errs.items():
        a = np.abs(np.array(v)) if v else np.array([math.nan])
        out[f"{k}_rms"] = float(np.sqrt(np.mean(a**2)))
        out[f"{k}_max"] = float(np.max(a))
    return out


def run(quick: bool) -> int:
    n = 6 if quick else 24
    print(f"beambench bench vision: seeded rendered 2048x1536 frames ({n} per set)")
    print(
        f"{'set':8s} {'method':8s} {'frames/s':>9s} {'flagged':>8s} "
        f"{'hub deg rms/max':>18s} {'tip lat mm rms/max':>20s} {'tip lon mm rms/max':>20s}"
    )
    corner_all: list[float] = []
    for kind, seed in (("nominal", 11), ("hard", 22), ("blur", 33)):
        frames, corner_err = _frames(kind, n, seed)
        corner_all += corner_err
        for method in ("default", "paper"):
            r = _evaluate(frames, method)
            print(
                f"{kind:8s} {method:8s} {r['fps']:9.1f} {r['failed']:4d}/{r['n']:<3d} "
                f"{r['hub_rms']:8.4f}/{r['hub_max']:<8.4f} "
                f"{r['lat_rms']:9.3f}/{r['lat_max']:<9.3f} {r['lon_rms']:9.3f}/{r['lon_max']:<9.3f}"
            )
    ce = np.array(corner_all)
    print(
        f"registration detection: max corner error {np.nanmax(ce):.3f} px over "
        f"{np.isfinite(ce).sum()}/{len(ce)} scenes found"
    )
    return 0
