"""The built-in synthetic bench: the simulator and the scene renderer feeding the daq fakes.

The crank turns at the rig's crank frequency; the four-bar gives the true rocker angle
(non-sinusoidal); the beam model driven by that hub motion gives the strains at the
gauges and the beam shape; the renderer draws the shape as the camera sees it. The beam
is simulated from rest for ``rig.synthetic.warmup_s`` before the capture starts, so the
capture sees the steady state.

``rig.synthetic.scene = "free_decay"`` holds the hub still instead and releases the tip
from a static deflection (the paper's damping runs, §5.2.1).

The camera draws the bench the rig describes: the hub of ``[synthetic]`` ``drawn_hub_length_m``
and ``drawn_hub_width_m`` (the shipped rig's: a 200 x 40 mm bar), or of ``[hub]`` when those are
0, with its clamp ``[beam] hub_offset_m`` from the pivot, the beam of ``[beam]``, the brightness,
contrast and lighting of ``[synthetic]`` (``background_dn``, ``beam_dn``,
``lighting_gradient``), motion-blurred over ``[camera] exposure_s``: a frame is the
average of the beam's simulated poses over its exposure, at most a pixel of tip travel
apart. Frames are stamped ``[synthetic] stamp_latency_s`` after mid-exposure.

The fakes only see callables (daq has no physics): ``strain_fn(t_s)``,
``angle_fn(t_s)`` and ``render_fn(t_start_s, exposure_s)``.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import CubicSpline

from pipelines.rig import Rig
from sim.beam import BeamProperties
from sim.drives import FourBarDrive
from sim.four_bar import FourBar
from sim.result import SimResult
from vision.camera import camera_matrix
from vision.codec import encode
from vision.synthetic.render import render_frame
from vision.synthetic.scene import BeamPose, SceneSpec

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]

# Output rate of the beam simulation that the DAQ fake interpolates: well above the
# beam's response (first mode 3.7 Hz, overdamped) and the 2 kHz acquisition's needs
# for a cubic interpolant.
_SIM_RATE_HZ = 1000.0
# Sub-exposure samples per pixel of tip travel for motion blur.
_BLUR_SAMPLES_PER_PX = 1.0


@dataclass(frozen=True)
class SyntheticTruth:
    """The simulated bench the fakes are fed from (for end-to-end error checks)."""

    result: SimResult
    t0_s: float
    crank_phase_rad: float
    mount_angle_rad: float

    def hub_angle_plane_rad(self, t_s: FloatArray) -> FloatArray:
        """True hub angle in the beam-plane frame at run times ``t_s``."""
        spline = CubicSpline(self.result.time_s, self.result.hub_angle_rad)
        return np.asarray(spline(np.asarray(t_s, float)), float) + self.mount_angle_rad

    def tip_lateral_m(self, t_s: FloatArray) -> FloatArray:
        spline = CubicSpline(self.result.time_s, self.result.tip_lateral_m)
        return np.asarray(spline(np.asarray(t_s, float)), float)


class SyntheticBench:
    """Simulates the bench once; serves the callables the daq fakes are built from."""

    def __init__(self, rig: Rig, duration_s: float, *, seed: int | None = None) -> None:
        if not duration_s > 0:
            raise ValueError(f"duration_s must be positive, got {duration_s!r}")
        self.rig = rig
        self.seed = rig.synthetic.seed if seed is None else seed
        self.four_bar = FourBar.from_config(rig.linkage)
        self.crank_speed_rad_s = 2.0 * math.pi * rig.linkage.crank_frequency_hz
        self.mount_angle_rad = rig.linkage.beam_mount_angle_rad
        self.beam = BeamProperties.from_config(rig.beam)
        rng = np.random.default_rng(self.seed)
        # Start the crank at a random phase: runs do not start at a dead centre.
        self.crank_phase_rad = float(rng.uniform(0.0, 2.0 * math.pi))
        self.warmup_s = rig.synthetic.warmup_s
        self.duration_s = duration_s
        drive = FourBarDrive(
            self.four_bar,
            self.crank_speed_rad_s,
            about="absolute",
            crank_phase_rad=self.crank_phase_rad - self.crank_speed_rad_s * self.warmup_s,
        )
        margin_s = 0.5
        started = time.perf_counter()
        if rig.synthetic.scene == "free_decay":
            # hub still where the crank is at the run's start; no warm-up (nothing settles)
            still = float(drive.angle(np.array([self.warmup_s]))[0])
            self.warmup_s = 0.0
            result = _simulate_free_decay(rig, self.beam, still, duration_s + margin_s)
        else:
            t_end = self.warmup_s + duration_s + margin_s
            n = round(t_end * _SIM_RATE_HZ) + 1
            result = _simulate(rig, self.beam, drive, np.linspace(0.0, t_end, n))
        log.info(
            "synthetic bench: %s simulated %.1f s in %.2f s",
            result.model,
            float(result.time_s[-1] - result.time_s[0]),
            time.perf_counter() - started,
        )
        # Run clock: t_run = t_sim - warmup.
        t_run = result.time_s - self.warmup_s
        self.truth = SyntheticTruth(
            result=_shift(result, -self.warmup_s),
            t0_s=0.0,
            crank_phase_rad=self.crank_phase_rad,
            mount_angle_rad=self.mount_angle_rad,
        )
        self._strain = CubicSpline(t_run, result.strain, axis=0)
        self._hub = CubicSpline(t_run, result.hub_angle_rad)
        self._lat = CubicSpline(t_run, result.station_lateral_m, axis=0)
        self._lon = CubicSpline(t_run, result.station_longitudinal_m, axis=0)
        self._stations = result.stations_m
        cam = rig.camera
        self.scene = SceneSpec.from_rig(
            cam,
            rig.camera_pose,
            rig.registration,
            beam_length_m=rig.beam.length_m,
            beam_width_m=rig.beam.width_m,
            hub_offset_m=rig.beam.hub_offset_m,
            hub_length_m=rig.synthetic.drawn_hub_length_m or rig.hub.length_m,
            hub_width_m=rig.synthetic.drawn_hub_width_m or rig.hub.width_m,
            noise_dn=rig.synthetic.image_noise_dn,
            seed=self.seed,
            background_dn=rig.synthetic.background_dn,
            beam_dn=rig.synthetic.beam_dn,
            hub_dn=rig.synthetic.hub_dn,
            lighting_gradient=rig.synthetic.lighting_gradient,
        )
        # Tip travel per second at the fastest, in pixels, sets the motion-blur sampling.
        hub_rate = np.abs(np.gradient(result.hub_angle_rad, result.time_s))
        vibration = np.abs(np.gradient(result.tip_lateral_m, result.time_s))
        tip_speed_m_s = float(np.max(hub_rate * rig.beam.pivot_to_tip_m + vibration))
        px_per_m = cam.focal_length_px / rig.camera_pose.distance_m
        blur_px = tip_speed_m_s * cam.exposure_s * px_per_m
        self.blur_samples = max(1, math.ceil(blur_px * _BLUR_SAMPLES_PER_PX))

    # -- callables for the fakes ------------------------------------------------------
    def strain_fn(self, t_s: FloatArray) -> FloatArray:
        """Surface strain (N, 4) at run times ``t_s`` [s], as the gauges read it (with the
        bridges' zero offsets of ``rig.synthetic.strain_offset``)."""
        offset = np.asarray(self.rig.synthetic.strain_offset, float)
        return np.asarray(self._strain(np.asarray(t_s, float)), float) + offset

    def angle_fn(self, t_s: FloatArray) -> FloatArray:
        """Rocker angle (N,) [rad] in the frame of Eqs. 1-2 at run times ``t_s``."""
        return np.asarray(self._hub(np.asarray(t_s, float)), float)

    def pose(self, t_s: float) -> BeamPose:
        return BeamPose(
            hub_angle_rad=float(self._hub(t_s)) + self.mount_angle_rad,
            stations_m=self._stations,
            lateral_m=np.asarray(self._lat(t_s), float),
            longitudinal_m=np.asarray(self._lon(t_s), float),
        )

    def render(self, t_start_s: float, exposure_s: float) -> bytes:
        """One encoded frame exposed over [t_start_s, t_start_s + exposure_s]."""
        n = self.blur_samples
        times = t_start_s + exposure_s * (np.arange(n) + 0.5) / n
        # Seeded per frame, not from a shared generator: frames render in worker threads.
        # (A frame stamped late may have been exposed before the run's clock started.)
        t_us = round(t_start_s * 1e6)
        key = [self.seed + 1, t_us] if t_us >= 0 else [self.seed + 1, 0, -t_us]
        rng = np.random.default_rng(key)
        frame = render_frame(self.scene, [self.pose(float(t)) for t in times], rng=rng)
        cam = self.rig.camera
        return encode(frame.image, cam.encoding, cam.jpeg_quality)

    def camera_info(self) -> dict[str, Any]:
        """foxglove.CameraCalibration content for the synthetic camera."""
        cam = self.rig.camera
        k = camera_matrix(cam.focal_length_px, cam.width_px, cam.height_px)
        return {
            "width": cam.width_px,
            "height": cam.height_px,
            "distortion_model": "plumb_bob",
            "D": list(cam.distortion),
            "K": k.ravel().tolist(),
            "R": [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            "P": np.column_stack([k, np.zeros(3)]).ravel().tolist(),
        }


def _simulate(rig: Rig, beam: BeamProperties, drive: FourBarDrive, t: FloatArray) -> SimResult:
    from sim.models.registry import simulate

    model = rig.synthetic.model
    return simulate(
        model,
        beam,
        drive,
        t,
        a0_per_s=rig.damping.a0_per_s,
        a1_s=rig.damping.a1_s,
        damping_law=rig.damping.law,
        gauge_positions_m=rig.gauges.positions_m,
        n_stations=41,
        n_modes=4,
        # The fakes' truth: ten times finer than the comparison processing makes (2 %)
        # and than the bench's own uncertainties; modal and fe at their own tolerances.
        tol=1e-3 if model == "auto" else None,
    )


def _simulate_free_decay(
    rig: Rig, beam: BeamProperties, hub_angle_rad: float, t_end_s: float
) -> SimResult:
    """Hub held at ``hub_angle_rad``; the tip held at ``release_tip_m`` by a point force
    (the static shape), released at ``release_at_s``; damped with the free-decay
    coefficients. Before the release the beam holds the static shape."""
    from sim.drives import FixedDrive
    from sim.models.modal import ModalModel, simulate_modal

    syn = rig.synthetic
    n_modes = 6
    mi = ModalModel.build(beam, n_modes).integrals
    q_unit = np.linalg.solve(mi.stiffness, mi.tip_shape)  # unit tip force
    q0 = q_unit * (syn.release_tip_m / float(mi.tip_shape @ q_unit))
    release = min(syn.release_at_s, t_end_s)
    n = round((t_end_s - release) * _SIM_RATE_HZ) + 1
    t = release + np.linspace(0.0, t_end_s - release, max(n, 2))
    res = simulate_modal(
        beam,
        FixedDrive(hub_angle_rad),
        t,
        n_modes=n_modes,
        a0_per_s=rig.damping.free_decay_a0_per_s,
        a1_s=rig.damping.free_decay_a1_s,
        gauge_positions_m=rig.gauges.positions_m,
        n_stations=41,
        initial_q=q0,
        rtol=1e-8,
        atol=1e-12,
    )
    # the held part: the release state repeated back to 0.5 s before the run starts
    t_held = np.arange(-0.5, release, 1.0 / _SIM_RATE_HZ)
    return replace(
        res.held_before(t_held),
        model=f"{res.model} (free decay)",
        wall_time_s=res.wall_time_s,
        settings={**res.settings, "release_at_s": release, "release_tip_m": syn.release_tip_m},
    )


def _shift(result: SimResult, dt_s: float) -> SimResult:

    return replace(result, time_s=result.time_s + dt_s)


@dataclass(frozen=True)
class SyntheticDevices:
    """The fakes of the synthetic bench and the bench that feeds them (its truth)."""

    daq: Any
    camera: Any
    camera_info: dict[str, Any]
    bench: SyntheticBench


def build_synthetic(
    rig: Rig, duration_s: float, *, realtime: bool = False, seed: int | None = None
) -> SyntheticDevices:
    """The fake DAQ and camera of the built-in synthetic bench, the camera's intrinsics
    as ``foxglove.CameraCalibration`` content, and the simulated bench itself.

    The camera clock runs with the rig's drift and jitter against the DAQ clock and a
    fixed start offset, so processing has a real offset to find.
    """
    from daq.fakes import FakeCamera, FakeStrainDaq

    bench = SyntheticBench(rig, duration_s, seed=seed)
    syn = rig.synthetic
    daq_device = FakeStrainDaq(
        rig.gauges,
        rig.potentiometer,
        rig.daq,
        strain_fn=bench.strain_fn,
        angle_fn=bench.angle_fn,
        strain_noise=syn.strain_noise,
        pot_noise_v=syn.pot_noise_v,
        seed=bench.seed,
        realtime=realtime,
    )
    cam = rig.camera
    camera = FakeCamera(
        render_fn=bench.render,
        width_px=cam.width_px,
        height_px=cam.height_px,
        frame_rate_hz=cam.frame_rate_hz,
        encoding=cam.encoding,
        exposure_s=cam.exposure_s,
        latency_s=cam.latency_s,
        clock_drift_ppm=syn.clock_drift_ppm,
        # A camera that stamps its frames L after mid-exposure is, to everything that
        # reads the log, a camera whose clock runs L ahead: the stamps against the true
        # exposure times are the same (daq's fake stamps at mid-exposure).
        clock_offset_s=CAMERA_CLOCK_OFFSET_S + syn.stamp_latency_s,
        clock_jitter_s=syn.clock_jitter_s,
        seed=bench.seed + 2,
        realtime=realtime,
        # rendering (~55 ms a frame at full size) runs ahead on both cores
        render_workers=2,
    )
    return SyntheticDevices(daq_device, camera, bench.camera_info(), bench)


def make_synthetic_devices(
    rig: Rig, duration_s: float, *, realtime: bool = False, seed: int | None = None
) -> tuple[Any, Any, dict[str, Any]]:
    """``(daq, camera, camera_info)`` for ``beambench capture --backend fake``."""
    d = build_synthetic(rig, duration_s, realtime=realtime, seed=seed)
    return d.daq, d.camera, d.camera_info


# The synthetic camera's clock starts this far from the DAQ's (a few frame periods are
# typical of two devices started by software one after the other).
CAMERA_CLOCK_OFFSET_S = 0.0123
