"""``beambench bench vision``: measurement error against speed on seeded rendered frames.

Sets (all 2048 x 1536, truth from the renderer):
- nominal: noise 2 DN, no lens distortion, PNG, camera tilted 10-20 deg;
- hard: tilt 30-45 deg, noise 10 DN, JPEG quality 60, |k1| = 0.1 with known intrinsics,
  lighting gradient and vignetting, bright clutter beside the beam, hub at either stroke
  end, tip deflections up to 80 mm (all at once in every frame);
- hard-low: the same with low contrast (beam 130, hub 120 on a 70 DN background instead
  of 215/190 on 40);
- blur: motion blur of a beam swinging at the rig's peak rate over a 2 ms exposure;
- short-hub: nominal imaging (tilt 8-12 deg, 2 DN) of a bench whose hub is the paper's
  short clamp block, 68 x 51 mm with the clamp 8 mm from the pivot;
- short-hub-generic: the same with the generic shapes of the sets above, which lack a
  free end's zero moment and shear (the variety sets' shapes are a cantilever's: the
  static response to a random smooth load), so the cantilever's shape model is wrong
  there and must be found wrong;
- smear-20, smear-40: nominal imaging under uneven light (10-20 % across the image at a
  random azimuth), the hub turning and the beam vibrating in its first mode during an
  exposure of 20 / 40 mm over the tip's speed (2-3.4 m/s, the hub's share 0.3-1 of it),
  truth at mid-exposure. The two shares have independent signs: where they add (about
  half the frames) the tip moves 20 / 40 mm across the beam, the most of any point; where
  they counter-move (the beam lagging the hub near a stroke end: the synthetic bench's
  simulated beam does so 14 % of the time at 0.92 Hz, 32 % at 2.35 Hz, its mode's share
  up to 3 m/s there) the tip moves less and the root and mid-beam are smeared by the
  hub's turn. The set's smear is thus the most any point of the beam moves, reached at
  the tip when the shares add;
- low-30, low-60: nominal imaging with the beam only 30 DN above the background at 5 DN of
  noise, and 60 DN at 8 DN (the hub 0.85 of that);
- fast: the built-in synthetic bench (:mod:`pipelines.acquire.synthetic`: the simulated
  beam, its camera, exposure and JPEG) driven at 2.35 Hz, frames every 1/15 s from 0.2 s:
  tips swinging up to 155 mm (slope 0.28 at the tip) at up to 3.4 m/s.
Besides the errors, each set's line gives the stated uncertainty's coverage: the fraction
of measured frames whose hub angle and tip lateral errors lie within 3 stated standard
uncertainties (a method that states none shows "-").
A second table times both methods with the JPEG decode included: each frame encoded as
the capture writes it (:func:`vision.codec.encode`, quality 90, restart markers), the paper
chain decoding it whole, the default method through :class:`vision.regions.RegionReader`
(only the segments it measures; the same result as from the whole JPEG, which the table
checks: its last column is the largest difference in the hub angle and the tip over the
set), every frame without a track (the set's poses are independent: each is read as a
run's first frame, not helped by its own previous pass). Its errors are those of the JPEG
frames. Its last row, "nominal colour", is the nominal set as a colour camera's driver
writes it (:mod:`daq.drivers.opencv_camera`: the frame in BGR with a warm cast, OpenCV's
4:2:0 JPEG at the capture's quality and restart interval), measured from its gray (Y)
decode as a real colour bench's frames are.
Both methods are timed with freed memory kept in the process
(:func:`pipelines.bench.malloc.keep_freed_memory`): the paper chain's temporaries otherwise
come back as fresh pages, and its speed depends on what ran before it.
Per-frame errors use the calibration from the true registration corners (the per-frame
chain alone); the last lines give the automatic registration detection's corner error,
what measuring with the detected registration instead of the true one changes, and the
standard uncertainty the detected calibration states for that change (its covariance
carried to each frame) with the share of frames whose change lies within 3 of it.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from daq.drivers.opencv_camera import JPEG_RST_INTERVAL_MCU
from pipelines.bench.malloc import keep_freed_memory
from vision import (
    Calibration,
    FrameMeasurement,
    Measurer,
    calibration_from_registration,
    decode,
    detect_registration_corners,
)
from vision.calibration_error import frame_calibration_sd
from vision.centreline import cantilever_eigenvalues, cantilever_modes_t
from vision.codec import encode
from vision.config import CameraConfig, CameraPoseConfig, RegistrationConfig
from vision.measure import METHODS
from vision.regions import RegionReader
from vision.synthetic.render import render_frame
from vision.synthetic.scene import BeamMotion, BeamPose, Clutter, RenderTruth, SceneSpec

L_M, W_M = 0.835, 0.01905
STROKE_DEG = (243.0, 330.0)
HUB_OFFSET_M = 0.008
SETS = (
    "nominal",
    "hard",
    "hard-low",
    "blur",
    "short-hub",
    "short-hub-generic",
    "smear-20",
    "smear-40",
    "low-30",
    "low-60",
    "fast",
)
SEEDS = dict(zip(SETS, (11, 22, 44, 33, 55, 56, 66, 77, 88, 99, 111), strict=True))
#: The fast set: the built-in synthetic bench's crank rate (Hz) and first frame (s).
FAST_CRANK_HZ = 2.35
FAST_START_S = 0.2
#: The variety sets: (hub length, width) m, tip smear m, (contrast, noise) DN.
VARIETY = {
    "short-hub": ((0.068, 0.051), 0.0, (175.0, 2.0)),
    "short-hub-generic": ((0.068, 0.051), 0.0, (175.0, 2.0)),
    "smear-20": ((0.20, 0.04), 0.020, (175.0, 2.0)),
    "smear-40": ((0.20, 0.04), 0.040, (175.0, 2.0)),
    "low-30": ((0.20, 0.04), 0.0, (30.0, 5.0)),
    "low-60": ((0.20, 0.04), 0.0, (60.0, 8.0)),
}
#: The smear sets' uneven light: the illumination changes by 10-20 % across the image
#: (``SceneSpec.lighting_gradient``) at a random azimuth.
SMEAR_LIGHTING = (0.10, 0.20)
#: The smeared exposure's slices: no point of the beam moves more than this (m) a slice.
SMEAR_STEP_M = 2e-4


@dataclass
class Frame:
    image: np.ndarray
    truth: RenderTruth
    calibration: Calibration
    auto: Calibration | None = None  # from the detected registration object


def _shape(rng: np.random.Generator, hub_rad: float, tip_max_m: float) -> BeamPose:
    """A mix of the first two cantilever-like shapes with tip deflection up to tip_max_m."""
    c1 = rng.uniform(-1, 1) * 1.5 * tip_max_m / L_M
    c2 = rng.uniform(-1, 1) * 0.3 * tip_max_m / L_M

    def slope(s: np.ndarray) -> np.ndarray:
        x = s / L_M
        return c1 * (2 * x - x**2) + c2 * np.sin(2.2 * np.pi * x) * x

    return BeamPose.from_slope(hub_rad, L_M, slope)


def _physical_shape(rng: np.random.Generator, hub_rad: float, tip_max_m: float) -> BeamPose:
    """A reciprocating cantilever's shape at an instant, tip deflection up to
    ``tip_max_m``: the static response (:meth:`BeamPose.from_load`, integrated from the
    free end) to its distributed inertial load, the hub's angular acceleration's (linear
    along the beam from the pivot) and its vibration's (``-rho A w''``: mode ``i``'s
    shape times ``beta_i^4``, modes 1-3 at up to 1, 0.15 and 0.04 of the first's
    deflection). Zero moment and shear at the free end, which :func:`_shape`'s lack."""
    amp = rng.uniform(-1, 1, 3) * np.array([1.0, 0.15, 0.04])
    accel = rng.uniform(-1, 1)
    beta4 = np.array(cantilever_eigenvalues(3)) ** 4

    def load(s: np.ndarray) -> np.ndarray:
        x = s / L_M
        return 8.0 * accel * (HUB_OFFSET_M / L_M + x) + (amp * beta4) @ cantilever_modes_t(x, 3)

    return BeamPose.from_load(hub_rad, L_M, load, rng.uniform(-1, 1) * tip_max_m)


def _spec(
    rng: np.random.Generator, hard: bool, seed: int, hub_deg: float, low: bool = False
) -> SceneSpec:
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
    az = float(rng.choice([0.0, math.pi / 2, math.pi, -math.pi / 2]) + rng.uniform(-0.3, 0.3))
    k1 = float(rng.choice([-0.1, 0.1]))
    cam = CameraConfig(distortion=(k1, 0.0, 0.0, 0.0, 0.0))
    pose = _framing(cam, reg, tilt, az, hub_deg)
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
        clutter=_clutter_near_beam(rng, hub_deg),
    )


def _variety_spec(kind: str, rng: np.random.Generator, seed: int) -> SceneSpec:
    """A nominal view of another bench: the hub's size, contrast and noise of ``kind``."""
    (hub_len, hub_w), _, (contrast, noise) = VARIETY[kind]
    tilt = (8.0, 12.0) if kind.startswith("short-hub") else (10.0, 20.0)
    pose = CameraPoseConfig(tilt_rad=math.radians(rng.uniform(*tilt)))
    background = 40.0
    light: dict[str, float] = {}
    if VARIETY[kind][1] > 0:  # the smear sets' uneven light (the others' draws unchanged)
        light = {
            "lighting_gradient": float(rng.uniform(*SMEAR_LIGHTING)),
            "lighting_azimuth_rad": float(rng.uniform(-math.pi, math.pi)),
        }
    return SceneSpec.from_rig(
        CameraConfig(),
        pose,
        RegistrationConfig(),
        beam_length_m=L_M,
        beam_width_m=W_M,
        hub_offset_m=HUB_OFFSET_M,
        noise_dn=noise,
        seed=seed,
        hub_length_m=hub_len,
        hub_width_m=hub_w,
        background_dn=background,
        beam_dn=background + contrast,
        hub_dn=background + 0.85 * contrast,
        **light,
    )


def _smeared(rng: np.random.Generator, smear_m: float) -> list[BeamPose]:
    """Poses over an exposure of ``smear_m / speed``: the hub turning and the beam
    vibrating in its first mode, each share of the tip's speed (the hub's 0.3-1 of
    ``speed``, 2-3.4 m/s, the mode's the rest) with its own sign. Where the two add
    (about half the frames) the tip moves ``smear_m`` across the beam, the most of any
    point; where they counter-move (the beam lagging the hub near a stroke end) the tip
    moves ``|hub - mode|`` of it and the root and mid-beam are smeared by the hub's turn,
    often more than the tip: ``smear_m`` bounds every point's smear then."""
    hub = math.radians(rng.uniform(265, 305))
    pose = _physical_shape(rng, hub, 0.035)
    speed = rng.uniform(2.0, 3.4)
    share = rng.uniform(0.3, 1.0)  # of the tip speed from the hub's rotation
    hub_sign, mode_sign = (float(v) for v in rng.choice([-1.0, 1.0], size=2))
    radius = HUB_OFFSET_M + pose.stations_m + pose.longitudinal_m
    hub_rate = hub_sign * share * speed / float(radius[-1])
    x = pose.stations_m / L_M
    mode = cantilever_modes_t(x, 1)[0] / 2.0  # the first mode, 1 at the tip
    lat_rate = mode_sign * (1 - share) * speed * mode
    exposure = smear_m / speed
    motion = BeamMotion(pose, hub_rate, lat_rate)
    return motion.exposure_poses(exposure, HUB_OFFSET_M, max_step_m=SMEAR_STEP_M)


def _framing(
    cam: CameraConfig, reg: RegistrationConfig, tilt: float, az: float, hub_deg: float
) -> CameraPoseConfig:
    """The closest oblique view that shows the hub, the beam at this stroke end (with
    80 mm deflection either way) and the registration plate, at 0.85-1.3 mm/px at the tip."""
    th = math.radians(hub_deg)
    e = np.array([math.cos(th), math.sin(th)])
    n = np.array([-e[1], e[0]])
    tip = 0.843 * e
    h = reg.plate_side_m / 2
    keep = [tip + 0.09 * n, tip - 0.09 * n, -0.2 * e + 0.03 * n, -0.2 * e - 0.03 * n]
    keep += [
        np.asarray(reg.center_m) + np.array([sx * h, sy * h]) for sx in (-1, 1) for sy in (-1, 1)
    ]
    pts = np.array(keep)
    target = tuple(float(v) for v in 0.5 * (pts.min(axis=0) + pts.max(axis=0)))
    best = None
    for dist in np.arange(1.0, 3.0, 0.05):
        pose = CameraPoseConfig(
            distance_m=float(dist), target_m=target, tilt_rad=tilt, tilt_azimuth_rad=az
        )
        spec = SceneSpec.from_rig(
            cam, pose, reg, beam_length_m=L_M, beam_width_m=W_M, hub_offset_m=0.008
        )
        try:
            px = spec.to_px(pts)
            tip_px = spec.to_px(np.array([tip, tip + 0.001 * n]))
        except ValueError:
            continue
        inside = np.all(px > 30) and np.all(px[:, 0] < cam.width_px - 30)
        inside = inside and np.all(px[:, 1] < cam.height_px - 30)
        mm_px = 1.0 / float(np.linalg.norm(tip_px[1] - tip_px[0]))
        if inside and 0.85 <= mm_px <= 1.3:
            return pose
        if inside and best is None:
            best = pose
    return best if best is not None else CameraPoseConfig(tilt_rad=tilt, tilt_azimuth_rad=az)


def _clutter_near_beam(rng: np.random.Generator, hub_deg: float) -> tuple[Clutter, ...]:
    """Bright bars beside the beam (clear of its deflection envelope, up to 80 mm at the
    tip) and a few farther away."""
    th = math.radians(hub_deg)
    e = np.array([math.cos(th), math.sin(th)])
    n = np.array([-e[1], e[0]])
    out = []
    for k in range(6):
        s = rng.uniform(0.15, 0.8)
        side = 1.0 if k % 2 else -1.0
        size = (float(rng.uniform(0.03, 0.1)), float(rng.uniform(0.01, 0.03)))
        gap = 0.012 + 0.1 * (s / L_M) ** 1.5 + 0.5 * math.hypot(*size) + rng.uniform(0, 0.05)
        centre = (0.008 + s) * e + side * gap * n
        out.append(
            Clutter(
                (float(centre[0]), float(centre[1])),
                size,
                float(th + rng.uniform(-0.5, 0.5)),
                float(rng.uniform(150, 250)),
            )
        )
    return tuple(out)


def _fast_frames(n: int, seed: int) -> list[Frame]:
    """``n`` frames of the built-in synthetic bench at :data:`FAST_CRANK_HZ`, as its
    camera takes them (frame rate, exposure, JPEG quality), truth averaged over the
    exposure."""
    import dataclasses

    from pipelines.acquire.synthetic import SyntheticBench
    from pipelines.rig import load_rig

    rig = load_rig()
    rig = dataclasses.replace(
        rig, linkage=dataclasses.replace(rig.linkage, crank_frequency_hz=FAST_CRANK_HZ)
    )
    cam = rig.camera
    bench = SyntheticBench(rig, FAST_START_S + n / cam.frame_rate_hz + 0.1, seed=seed)
    frames = []
    for k in range(n):
        t0 = FAST_START_S + k / cam.frame_rate_hz
        m = bench.blur_samples
        times = t0 + cam.exposure_s * (np.arange(m) + 0.5) / m
        poses = [bench.pose(float(t)) for t in times]
        fr = render_frame(bench.scene, poses, rng=np.random.default_rng([seed, k]))
        tr = fr.truth
        image = decode(encode(fr.image, cam.encoding, cam.jpeg_quality))
        cal = Calibration(
            tr.corners_px,
            tr.plane_points_m,
            tr.camera_matrix,
            tr.distortion,
            beam_length_m=rig.beam.length_m,
            beam_width_m=rig.beam.width_m,
        )
        frames.append(Frame(image, tr, cal))
    return frames


def _frames(kind: str, n: int, seed: int) -> tuple[list[Frame], list[float]]:
    if kind == "fast":
        return _fast_frames(n, seed), []
    rng = np.random.default_rng(seed)
    frames, corner_err = [], []
    n_specs = 1 if kind == "nominal" else max(1, n // 3)
    hard = kind.startswith("hard")
    for k in range(n_specs):
        end_deg = float(STROKE_DEG[k % 2])
        if kind in VARIETY:
            spec = _variety_spec(kind, rng, seed + k)
        else:
            spec = _spec(rng, hard, seed + k, end_deg, low=kind == "hard-low")
        for _ in range(n // n_specs):
            if kind in VARIETY:
                smear = VARIETY[kind][1]
                shape = _shape if kind.endswith("-generic") else _physical_shape
                if smear > 0:
                    poses = _smeared(rng, smear)
                else:
                    poses = [shape(rng, math.radians(rng.uniform(*STROKE_DEG)), 0.035)]
            elif hard:
                hub = math.radians(end_deg + rng.uniform(-2, 2))
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
            if hard:
                image = decode(encode(image, "jpeg", 60))
            cal = Calibration(tr.corners_px, tr.plane_points_m, tr.camera_matrix, tr.distortion)
            frames.append(Frame(image, tr, cal))
        try:
            det = detect_registration_corners(
                frames[-1].image, spec.registration, spec.camera_matrix, spec.distortion
            )
            corner_err.append(float(np.max(np.abs(det - frames[-1].truth.corners_px))))
            auto = calibration_from_registration(
                frames[-1].image,
                spec.registration,
                spec.camera_matrix,
                spec.distortion,
                beam_length_m=L_M,
                beam_width_m=W_M,
            )
            for f in frames[-(n // n_specs) :]:
                f.auto = auto
        except ValueError:
            corner_err.append(math.nan)
    return frames, corner_err


def _time_methods(
    frames: list[Frame], methods: tuple[str, ...], repeats: int
) -> tuple[dict[str, float], dict[str, list[FrameMeasurement]]]:
    """Seconds per pass over ``frames`` for each method: the methods take turns, pass by
    pass, and each keeps its fastest pass, so a busy spell on a shared machine slows
    both alike or neither (one pass each measured the ratio anywhere from 1.8x to 3.2x
    with another job on the second core). Also each method's results."""
    measurers = {
        m: {id(f.calibration): Measurer(f.calibration, method=m) for f in frames} for m in methods
    }
    for m in methods:  # warm-up (imports, first-touch allocations)
        measurers[m][id(frames[0].calibration)].measure(frames[0].image)
    best = dict.fromkeys(methods, math.inf)
    results: dict[str, list[FrameMeasurement]] = {}
    for _ in range(repeats):
        for m in methods:
            t0 = time.perf_counter()
            results[m] = [measurers[m][id(f.calibration)].measure(f.image) for f in frames]
            best[m] = min(best[m], time.perf_counter() - t0)
    return best, results


#: The capture's JPEG quality (the rig's and the synthetic camera's default).
CAPTURE_QUALITY = CameraConfig().jpeg_quality


def colour_jpeg(image: np.ndarray, quality: int = CAPTURE_QUALITY) -> bytes:
    """A gray frame as a colour camera's driver writes it: BGR with a warm cast (blue
    0.85, green 0.97, red 1.12 of the gray level: its Y within 0.2 % of it, its chroma
    not flat), OpenCV's JPEG (4:2:0) with the driver's restart interval."""
    import cv2

    g = image.astype(np.float32)
    bgr = np.stack((g * 0.85, g * 0.97, g * 1.12), axis=-1)
    bgr = np.clip(np.round(bgr), 0, 255).astype(np.uint8)
    params = [cv2.IMWRITE_JPEG_QUALITY, int(quality)]
    params += [cv2.IMWRITE_JPEG_RST_INTERVAL, JPEG_RST_INTERVAL_MCU]
    ok, buf = cv2.imencode(".jpg", bgr, params)
    if not ok:
        raise RuntimeError("OpenCV could not encode a colour frame")
    return bytes(buf)


def _time_decoded(
    frames: list[Frame], repeats: int, colour: bool = False
) -> tuple[dict[str, float], dict[str, list[FrameMeasurement]], tuple[float, float], float]:
    """Seconds per pass with the JPEG decode included (the methods taking turns, the
    fastest pass of each), each method's results, the largest difference (hub rad, tip
    lateral m) of the default method's parts from the same JPEGs decoded whole, and the
    fraction of segments decoded (NaN when none was decoded in parts). ``colour``: the
    frames as a colour camera's driver writes them (:func:`colour_jpeg`)."""
    if colour:
        jpegs = [colour_jpeg(f.image) for f in frames]
    else:
        jpegs = [encode(f.image, "jpeg", CAPTURE_QUALITY) for f in frames]
    cals = {id(f.calibration): f.calibration for f in frames}
    readers = {k: RegionReader(Measurer(c)) for k, c in cals.items()}
    papers = {k: Measurer(c, method="paper") for k, c in cals.items()}

    def default() -> list[FrameMeasurement]:
        out = []
        for f, j in zip(frames, jpegs, strict=True):
            reader = readers[id(f.calibration)]
            # independent poses: no track from the previous frame (nor from this frame's
            # own previous pass), as the first frame of a run is read
            reader.lose_track()
            out.append(reader.measure(j))
        return out

    def paper() -> list[FrameMeasurement]:
        return [
            papers[id(f.calibration)].measure(decode(j)) for f, j in zip(frames, jpegs, strict=True)
        ]

    runs = {"default": default, "paper": paper}
    for fn in runs.values():  # warm-up
        fn()
    best = dict.fromkeys(runs, math.inf)
    results: dict[str, list[FrameMeasurement]] = {}
    for _ in range(repeats):
        for name, fn in runs.items():
            t0 = time.perf_counter()
            results[name] = fn()
            best[name] = min(best[name], time.perf_counter() - t0)
    whole = [Measurer(f.calibration).measure(decode(j)) for f, j in zip(frames, jpegs, strict=True)]
    d_hub = d_tip = 0.0
    for a, b in zip(results["default"], whole, strict=True):
        if a.ok != b.ok:
            d_hub = d_tip = math.inf
        elif a.ok:
            d_hub = max(d_hub, abs(a.hub_angle_rad - b.hub_angle_rad))
            d_tip = max(d_tip, abs(a.tip_lateral_m - b.tip_lateral_m))
    fractions = [x for r in readers.values() for x in r.stats.decoded_fraction]
    return best, results, (d_hub, d_tip), float(np.mean(fractions)) if fractions else math.nan


def _errors(
    frames: list[Frame], results: list[FrameMeasurement], seconds: float
) -> dict[str, float]:
    """Error statistics of the measured frames, and the stated uncertainty's coverage:
    the fraction of them whose error is within 3 stated standard uncertainties (NaN
    when the method states none)."""
    errs: dict[str, list[float]] = {"hub": [], "lat": [], "lon": []}
    within: dict[str, list[bool]] = {"hub": [], "lat": []}
    failed = 0
    for f, m in zip(frames, results, strict=True):
        if not m.ok:
            failed += 1
            continue
        tr = f.truth
        d_hub = (m.hub_angle_rad - tr.hub_angle_rad + math.pi) % (2 * math.pi) - math.pi
        d_lat = m.tip_lateral_m - tr.tip_lateral_m
        errs["hub"].append(math.degrees(d_hub))
        errs["lat"].append(d_lat * 1e3)
        errs["lon"].append((m.tip_longitudinal_m - tr.tip_longitudinal_m) * 1e3)
        if math.isfinite(m.hub_angle_std_rad):
            within["hub"].append(abs(d_hub) <= 3 * m.hub_angle_std_rad)
        if math.isfinite(m.tip_lateral_std_m):
            within["lat"].append(abs(d_lat) <= 3 * m.tip_lateral_std_m)
    out = {"fps": len(frames) / seconds, "failed": failed, "n": len(frames)}
    for k, v in errs.items():
        a = np.abs(np.array(v)) if v else np.array([math.nan])
        out[f"{k}_rms"] = float(np.sqrt(np.mean(a**2)))
        out[f"{k}_max"] = float(np.max(a))
    for k, w in within.items():
        out[f"{k}_cover"] = float(np.mean(w)) if w else math.nan
    return out


def _cover(x: float) -> str:
    return "-" if not math.isfinite(x) else f"{x:.2f}"


def _registration_bias(frames: list[Frame]) -> dict[str, list[float]]:
    """Hub angle (deg) and tip lateral (mm) with the detected registration minus with
    the true one, frame by frame (frames whose scene's object was found), and the
    standard uncertainty the detected calibration states for each (its covariance carried
    to the frame, :func:`vision.calibration_error.frame_calibration_sd`)."""
    out: dict[str, list[float]] = {"hub": [], "lat": [], "hub_sd": [], "lat_sd": []}
    for f in frames:
        if f.auto is None:
            continue
        a = Measurer(f.auto).measure(f.image)
        b = Measurer(f.calibration).measure(f.image)
        if a.ok and b.ok:
            d = (a.hub_angle_rad - b.hub_angle_rad + math.pi) % (2 * math.pi) - math.pi
            sd = frame_calibration_sd(f.auto, a)
            out["hub"].append(math.degrees(d))
            out["lat"].append((a.tip_lateral_m - b.tip_lateral_m) * 1e3)
            out["hub_sd"].append(math.degrees(sd.hub_angle_rad))
            out["lat_sd"].append(sd.tip_lateral_m * 1e3)
    return out


def _render_seconds(passes: int) -> float:
    """Seconds to render and JPEG-encode one nominal frame (the synthetic camera's work),
    fastest of ``passes`` after a warm-up; the renderer's speed used to be a wall-clock
    assertion in the tests and is measured here instead."""
    rng = np.random.default_rng(5)
    spec = _spec(rng, False, 5, float(STROKE_DEG[0]), low=False)
    pose = _shape(rng, math.radians(float(np.mean(STROKE_DEG))), 0.05)
    encode(render_frame(spec, [pose]).image, "jpeg", 90)
    best = math.inf
    for _ in range(passes):
        t0 = time.perf_counter()
        encode(render_frame(spec, [pose]).image, "jpeg", 90)
        best = min(best, time.perf_counter() - t0)
    return best


def run(quick: bool, sets: tuple[str, ...] = SETS) -> int:
    """Print the table for ``sets`` (all by default) and the registration and render
    lines."""
    import cv2

    # Both methods on one core (OpenCV would otherwise spread the paper's filters).
    cv2.setNumThreads(1)
    kept = keep_freed_memory()
    n = 6 if quick else 24
    repeats = 1 if quick else 7
    print(
        f"beambench bench vision: seeded rendered 2048x1536 frames ({n} per set); "
        f"frames/s from the fastest of {repeats} pass(es), the methods taking turns; "
        + (
            "freed memory kept in the process for both (pipelines.bench.malloc)"
            if kept
            else "freed memory given back as the C library does (the paper chain's "
            "speed then depends on the allocations before it: pipelines.bench.malloc)"
        )
    )
    print(
        f"{'set':17s} {'method':8s} {'frames/s':>9s} {'flagged':>8s} "
        f"{'hub deg rms/max':>18s} {'tip lat mm rms/max':>20s} {'tip lon mm rms/max':>20s} "
        f"{'3sd cover hub/lat':>18s}"
    )
    corner_all: list[float] = []
    ratios: list[str] = []
    total = dict.fromkeys(METHODS, 0.0)
    bias: dict[str, list[float]] = {"hub": [], "lat": [], "hub_sd": [], "lat_sd": []}
    decoded_sets: list[tuple[str, list[Frame]]] = []
    for kind in sets:
        frames, corner_err = _frames(kind, n, SEEDS[kind])
        decoded_sets.append((kind, frames))
        corner_all += corner_err
        for key, values in _registration_bias(frames).items():
            bias[key] += values
        seconds, results = _time_methods(frames, METHODS, repeats)
        for method in METHODS:
            r = _errors(frames, results[method], seconds[method])
            print(
                f"{kind:17s} {method:8s} {r['fps']:9.1f} {r['failed']:4d}/{r['n']:<3d} "
                f"{r['hub_rms']:8.4f}/{r['hub_max']:<8.4f} "
                f"{r['lat_rms']:9.3f}/{r['lat_max']:<9.3f} "
                f"{r['lon_rms']:9.3f}/{r['lon_max']:<9.3f} "
                f"{_cover(r['hub_cover']):>9s}/{_cover(r['lat_cover']):<8s}"
            )
        ratios.append(f"{kind} {seconds['paper'] / seconds['default']:.2f}x")
        for method in METHODS:
            total[method] += seconds[method]
    ratios.append(f"all {len(sets) * n} frames {total['paper'] / total['default']:.2f}x")
    print("default against the paper chain (speed): " + ", ".join(ratios))
    print(
        f"with the JPEG decode (quality {CAPTURE_QUALITY}, restart markers; the paper chain "
        "decodes whole, the default method the segments it measures):"
    )
    print(
        f"{'set':17s} {'default f/s':>11s} {'paper f/s':>9s} {'ratio':>6s} {'segments':>8s} "
        f"{'hub deg rms':>11s} {'tip lat mm rms':>14s} {'parts-whole hub deg/tip mm':>27s}"
    )
    colour_sets = [("nominal colour", f) for k, f in decoded_sets if k == "nominal"]
    for i, (kind, frames) in enumerate(decoded_sets + colour_sets):
        colour = i >= len(decoded_sets)
        sec, res, (d_hub, d_tip), frac = _time_decoded(frames, repeats, colour)
        r = _errors(frames, res["default"], sec["default"])
        rp = _errors(frames, res["paper"], sec["paper"])
        print(
            f"{kind:17s} {r['fps']:11.1f} {rp['fps']:9.1f} "
            f"{sec['paper'] / sec['default']:5.2f}x {frac:8.0%} "
            f"{r['hub_rms']:11.4f} {r['lat_rms']:14.3f} "
            f"{math.degrees(d_hub):15.2g}/{d_tip * 1e3:<11.2g}"
        )
    ce = np.array(corner_all)
    if np.isfinite(ce).any():  # the fast set's frames are not searched for it
        print(
            f"registration detection: max corner error {np.nanmax(ce):.3f} px over "
            f"{np.isfinite(ce).sum()}/{len(ce)} scenes found"
        )
    render_s = _render_seconds(3 if quick else 7)
    print(
        f"synthetic camera: {render_s * 1e3:.0f} ms to render and JPEG-encode a 2048x1536 "
        f"frame ({1 / render_s:.1f} frames/s on one core)"
    )
    bh, bl = np.abs(np.array(bias["hub"])), np.abs(np.array(bias["lat"]))
    sh, sl = np.array(bias["hub_sd"]), np.array(bias["lat_sd"])
    if bh.size:
        print(
            f"detected against true registration over {bh.size} frames: hub "
            f"{np.sqrt(np.mean(bh**2)):.4f}/{bh.max():.4f} deg rms/max, tip lateral "
            f"{np.sqrt(np.mean(bl**2)):.3f}/{bl.max():.3f} mm rms/max"
        )
        print(
            f"the detected calibration's stated sd over those frames: hub "
            f"{np.sqrt(np.mean(sh**2)):.4f} deg rms, tip lateral {np.sqrt(np.mean(sl**2)):.3f} "
            f"mm rms; the change within 3 stated sd: hub {np.mean(bh <= 3 * sh):.2f}, "
            f"tip lateral {np.mean(bl <= 3 * sl):.2f}"
        )
    return 0
