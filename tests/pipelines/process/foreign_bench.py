"""A "foreign bench": a run log as another recorder writes it, of a bench that differs from
beambench's synthetic one, written with the ``mcap`` library directly (not ``daq``).

What differs on purpose from beambench's defaults and its own recorder:
- the recorder: library ``benchrec 2.3``, its own sample schema text, a 500 Hz stream, a
  ``/diagnostics/temperature`` channel beambench does not know, the rig as flat string
  entries (some beambench does not know, one ambiguous, a camera latency it believes
  wrongly), frames stamped on arrival 37 ms after mid-exposure on the DAQ's clock;
- the bench: the paper's short clamp block (68 x 51 mm, clamp 8 mm from the pivot), a
  brighter background with a lighting gradient and vignetting (beam 95 DN above the
  background instead of 175), 3 DN of noise, a 1.5 ms exposure (tip smear up to ~5.5 mm),
  another camera pose and focal length, the registration plate elsewhere;
- the frames: rendered by ``vision.synthetic`` from the poses over each exposure of the
  beam simulated by the synthetic bench's physics (``SyntheticBench``: four-bar drive,
  beam model), JPEG quality 85.
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
from foxglove_schemas_protobuf.Log_pb2 import Log
from mcap.writer import CompressionType, Writer
from mcap_protobuf.schema import build_file_descriptor_set

from pipelines.acquire.synthetic import SyntheticBench
from pipelines.rig import Rig, load_rig
from vision.camera import camera_matrix
from vision.codec import encode
from vision.config import CameraConfig, CameraPoseConfig, RegistrationConfig
from vision.synthetic.render import render_frame
from vision.synthetic.scene import BeamPose, SceneSpec

RATE_HZ = 500.0
FRAME_RATE_HZ = 15.0
EXPOSURE_S = 1.5e-3
LATENCY_S = 0.037  # frame stamped on arrival: mid-exposure + this
HUB_LENGTH_M, HUB_WIDTH_M, HUB_OFFSET_M = 0.068, 0.051, 0.008
REGISTRATION_CENTER_M = (0.46, 0.08)
JPEG_QUALITY = 85
SMEAR_STEP_M = 5e-4  # the tip moves at most this between the exposure's poses
STRAIN_NOISE = 3e-6
ANGLE_NOISE_RAD = 2e-4
SAMPLE_SCHEMA = json.dumps(
    {
        "title": "beambench.DaqSample",
        "type": "object",
        "description": "benchrec's DAQ sample (rad, m/m, V)",
    }
).encode()

# The rig as benchrec stores it: flat strings. beam_length_m etc. by section prefix,
# crank_frequency_hz bare, registration by section prefix; width_m is ambiguous
# ([beam] or [hub]), operator and lens are not beambench's, the camera latency is what
# the recorder believes (processing must find 37 ms from the data, not from this).
FLAT_RIG = {
    "beam_length_m": "0.835",
    "beam_width_m": "0.01905",
    "beam_thickness_m": "0.003175",
    "hub_offset_m": "0.008",
    "hub_length_m": "0.068",
    "hub.width_m": "0.051",
    "crank_frequency_hz": "0.92",
    "gauges_positions_m": "0.005, 0.204, 0.403, 0.603",
    "registration_center_m": f"[{REGISTRATION_CENTER_M[0]}, {REGISTRATION_CENTER_M[1]}]",
    "registration_square_side_m": "0.1",
    "camera_latency_s": "0.005",
    "width_m": "0.01905",
    "operator": "A. N. Other",
    "lens": "5.4 mm",
}


@dataclass
class ForeignRun:
    """The log and its truth: each frame's true mid-exposure time (DAQ run clock, s), the
    tip deflections and hub angle the renderer drew (means over the exposure, m, rad)."""

    path: Path
    bench: SyntheticBench
    t_mid_s: np.ndarray
    tip_lateral_m: np.ndarray
    tip_longitudinal_m: np.ndarray
    hub_angle_rad: np.ndarray


def foreign_rig() -> Rig:
    """The physics of the foreign bench: the paper's beam and linkage, the registration
    plate where the flat record says, its own seed, a 3 s warm-up."""
    rig = load_rig()
    reg = dataclasses.replace(rig.registration, center_m=REGISTRATION_CENTER_M)
    syn = dataclasses.replace(rig.synthetic, seed=4242, warmup_s=3.0)
    return dataclasses.replace(rig, registration=reg, synthetic=syn)


def _scene(rig: Rig) -> SceneSpec:
    camera = CameraConfig(
        width_px=2048,
        height_px=1536,
        frame_rate_hz=FRAME_RATE_HZ,
        exposure_s=EXPOSURE_S,
        focal_length_px=2200.0,
        jpeg_quality=JPEG_QUALITY,
    )
    pose = CameraPoseConfig(
        distance_m=2.1,
        target_m=(0.16, -0.36),
        tilt_rad=math.radians(10.0),
        tilt_azimuth_rad=math.radians(35.0),
        roll_rad=math.radians(3.0),
    )
    registration = RegistrationConfig(center_m=REGISTRATION_CENTER_M)
    return SceneSpec.from_rig(
        camera,
        pose,
        registration,
        beam_length_m=rig.beam.length_m,
        beam_width_m=rig.beam.width_m,
        hub_offset_m=HUB_OFFSET_M,
        hub_length_m=HUB_LENGTH_M,
        hub_width_m=HUB_WIDTH_M,
        noise_dn=2.5,
        seed=77,
        background_dn=55.0,
        beam_dn=200.0,
        hub_dn=185.0,
        plate_dn=230.0,
        groove_dn=30.0,
        lighting_gradient=0.2,
        lighting_azimuth_rad=math.radians(60.0),
        vignetting=0.12,
        blur_sigma_px=0.7,
    )


def _exposure_poses(bench: SyntheticBench, t_start_s: float, rig: Rig) -> list[BeamPose]:
    """Poses at the midpoints of equal slices of the exposure, enough that the tip moves
    at most SMEAR_STEP_M per slice (the renderer averages their coverage)."""
    a, b = bench.pose(t_start_s), bench.pose(t_start_s + EXPOSURE_S)
    reach = rig.beam.pivot_to_tip_m
    smear = abs(b.hub_angle_rad - a.hub_angle_rad) * reach + abs(b.lateral_m[-1] - a.lateral_m[-1])
    n = max(1, math.ceil(smear / SMEAR_STEP_M))
    return [bench.pose(t_start_s + EXPOSURE_S * (k + 0.5) / n) for k in range(n)]


def _image_message(t_ns: int, data: bytes) -> bytes:
    msg = CompressedImage(frame_id="benchrec/cam0", data=data, format="jpeg")
    msg.timestamp.seconds, msg.timestamp.nanos = divmod(t_ns, 1_000_000_000)
    return msg.SerializeToString()


def _camera_info(spec: SceneSpec) -> bytes:
    cam = spec.camera
    k = camera_matrix(cam.focal_length_px, cam.width_px, cam.height_px).ravel().tolist()
    msg = CameraCalibration(
        frame_id="benchrec/cam0",
        width=cam.width_px,
        height=cam.height_px,
        distortion_model="plumb_bob",
        D=[0.0] * 5,
        K=k,
    )
    return msg.SerializeToString()


def _sample(t_ns: int, angle: float, strain: np.ndarray, rig: Rig) -> bytes:
    pot = rig.potentiometer
    volts_pot = pot.supply_v * (angle - pot.zero_angle_rad) / pot.electrical_range_rad
    bridge = [rig.gauges.excitation_v * rig.gauges.gauge_factor * s / 4.0 for s in strain]
    return json.dumps(
        {
            "timestamp": {"sec": t_ns // 1_000_000_000, "nsec": t_ns % 1_000_000_000},
            "rocker_angle_rad": angle,
            "strain": [float(s) for s in strain],
            "raw_volts": [volts_pot, *bridge],
            "board_temperature_c": 31.5,
        }
    ).encode()


def write_foreign_log(path: Path, duration_s: float) -> ForeignRun:
    """Simulate, render and write the foreign bench's log; return it with its truth."""
    rig = foreign_rig()
    bench = SyntheticBench(rig, duration_s)
    spec = _scene(rig)
    rng = np.random.default_rng(99)
    n_samples = int(duration_s * RATE_HZ)
    t_s = np.arange(n_samples) / RATE_HZ
    angle = bench.angle_fn(t_s) + ANGLE_NOISE_RAD * rng.standard_normal(n_samples)
    strain = bench.strain_fn(t_s) + STRAIN_NOISE * rng.standard_normal((n_samples, 4))
    # the camera starts 23.4 ms after the DAQ; the last frame arrives within the run
    t_start = 0.0234 + np.arange(int((duration_s - 0.1) * FRAME_RATE_HZ)) / FRAME_RATE_HZ
    t_mid = t_start + 0.5 * EXPOSURE_S
    tips, lons, hubs = [], [], []
    with open(path, "wb") as f:
        w = Writer(f, compression=CompressionType.ZSTD, chunk_size=1 << 20)
        w.start(profile="beambench", library="benchrec 2.3 (python mcap)")
        sid = w.register_schema("beambench.DaqSample", "jsonschema", SAMPLE_SCHEMA)
        ch = {"/daq/samples": w.register_channel("/daq/samples", "json", sid)}
        for topic, cls in (
            ("/camera/image", CompressedImage),
            ("/camera/info", CameraCalibration),
            ("/events", Log),
        ):
            fds = build_file_descriptor_set(cls).SerializeToString()
            sid = w.register_schema(cls.DESCRIPTOR.full_name, "protobuf", fds)
            ch[topic] = w.register_channel(topic, "protobuf", sid)
        sid = w.register_schema(
            "benchrec.Temperature", "jsonschema", b'{"type":"object","title":"benchrec.Temp"}'
        )
        ch["/diagnostics/temperature"] = w.register_channel("/diagnostics/temperature", "json", sid)
        w.add_metadata("rig", FLAT_RIG)
        w.add_metadata(
            "run",
            {
                "run_id": "benchrec-0042",
                "start_utc": "2026-10-30T14:02:11.250Z",
                "software": "benchrec 2.3",
                "daq_rate_hz": "500",
            },
        )
        log_time = lambda t: round(t * 1e9)  # noqa: E731
        w.add_message(ch["/camera/info"], 0, _camera_info(spec), 0, 0)
        start = Log(level=Log.INFO, message="recording", name="start")
        w.add_message(ch["/events"], 0, start.SerializeToString(), 0, 0)
        for k in range(0, n_samples, int(RATE_HZ)):
            t = log_time(t_s[k])
            w.add_message(ch["/diagnostics/temperature"], t, b'{"c": 31.5}', t, k)
        frame_at = 0
        for k in range(n_samples):
            t = log_time(t_s[k])
            # frames arrive LATENCY_S after mid-exposure, interleaved in arrival order
            while frame_at < len(t_start) and t_mid[frame_at] + LATENCY_S <= t_s[k]:
                t_frame = log_time(t_mid[frame_at] + LATENCY_S)
                poses = _exposure_poses(bench, float(t_start[frame_at]), rig)
                frame_rng = np.random.default_rng([7, frame_at])
                rendered = render_frame(spec, poses, rng=frame_rng)
                tips.append(rendered.truth.tip_lateral_m)
                lons.append(rendered.truth.tip_longitudinal_m)
                hubs.append(rendered.truth.hub_angle_rad)
                data = encode(rendered.image, "jpeg", JPEG_QUALITY)
                w.add_message(
                    ch["/camera/image"], t_frame, _image_message(t_frame, data), t_frame, frame_at
                )
                frame_at += 1
            w.add_message(ch["/daq/samples"], t, _sample(t, angle[k], strain[k], rig), t, k)
        w.finish()
    n = len(tips)
    return ForeignRun(path, bench, t_mid[:n], np.array(tips), np.array(lons), np.array(hubs))
