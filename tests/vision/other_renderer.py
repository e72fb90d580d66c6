"""A bench drawn by other hands: a renderer that shares no code with
:mod:`vision.synthetic`, to check the measurement on frames beambench did not make.

Everything here is done differently from beambench's renderer on purpose:
- the camera is OpenCV's (``cv2.projectPoints``: rotation, translation, K, k1), placed
  by its own tilt, azimuth and roll about a target on the plane, not by
  :mod:`vision.synthetic.pose`;
- shapes are polygons filled by Anti-Grain Geometry (matplotlib's Agg backend), whose
  scan-line rasterizer gives each pixel the exact area of it inside the polygon (its
  vertices at 1/256 px), not half-planes with sub-pixel offsets; outlines are sampled
  densely so that lens distortion curves them. (A first version filled the polygons with
  ``cv2.fillPoly`` on a canvas 8 times finer and box-averaged it down: that canvas decides
  each sub-pixel by its centre, which puts a straight edge up to 1/16 px off, in runs
  along it, and on one frame turned the hub's edges 0.009 deg, about 2 of their stated
  sd, with no noise at all; 12, 16, 24 and 32 times finer gave 0.006, 0.000, 0.004 and
  0.003 deg. A camera's pixel integrates its exact area.)
- the beam's shape is a sum of clamped-free mode shapes (the textbook's Eq. 8.4, from
  its own eigenvalues), inextensible, with a square free end; the truth is its tip at
  mid-exposure relative to the rigid beam on the hub axis;
- motion blur is the mean of renders at poses spaced so that the tip moves at most
  ``MAX_STEP_M`` between them; optics blur, lighting gradient, Gaussian noise, and a
  JPEG encoded by OpenCV (no restart markers) follow.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Polygon
from numpy.typing import NDArray

W_PX, H_PX = 2048, 1536
BEAM_LENGTH_M, HUB_OFFSET_M = 0.835, 0.008
REG_CENTER_M, SQUARE_M, PLATE_M = np.array([0.50, 0.05]), 0.100, 0.300
SQUARE_CORNERS_M = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * SQUARE_M / 2 + REG_CENTER_M
MAX_STEP_M = 3e-4  # tip travel between the poses averaged over an exposure
LAMBDAS = (1.8751040687, 4.6940911330)  # cos(l) cosh(l) + 1 = 0, first two roots


def mode_shapes(s_m: NDArray[np.float64]) -> list[NDArray[np.float64]]:
    """Clamped-free mode shapes at stations ``s_m``, each 1 at the tip."""
    out = []
    for lam in LAMBDAS:
        k = lam / BEAM_LENGTH_M
        sig = (math.cosh(lam) + math.cos(lam)) / (math.sinh(lam) + math.sin(lam))
        phi = np.cosh(k * s_m) - np.cos(k * s_m) - sig * (np.sinh(k * s_m) - np.sin(k * s_m))
        out.append(phi / phi[-1])
    return out


@dataclass(frozen=True)
class Camera:
    """A pinhole camera with radial distortion k1 above the beam plane (z = 0)."""

    K: NDArray[np.float64]
    dist: NDArray[np.float64]
    rvec: NDArray[np.float64]
    tvec: NDArray[np.float64]

    @classmethod
    def looking_at(
        cls,
        target_m: tuple[float, float],
        distance_m: float,
        tilt_deg: float,
        azimuth_deg: float,
        roll_deg: float,
        focal_px: float,
        principal_px: tuple[float, float],
        k1: float,
    ) -> Camera:
        az = math.radians(azimuth_deg)
        tilt_axis = np.array([math.cos(az), math.sin(az), 0.0])
        r_tilt, _ = cv2.Rodrigues(tilt_axis * math.radians(tilt_deg))
        r_roll, _ = cv2.Rodrigues(np.array([0.0, 0.0, math.radians(roll_deg)]))
        # Seen from above (+z), the image's x along the plane's x and its y down the
        # plane's y: a proper rotation (no mirror).
        world_to_cam = np.diag([1.0, -1.0, -1.0]) @ r_roll @ r_tilt.T
        centre = np.array([*target_m, 0.0]) + r_tilt @ np.array([0.0, 0.0, distance_m])
        rvec, _ = cv2.Rodrigues(world_to_cam)
        K = np.array([[focal_px, 0, principal_px[0]], [0, focal_px, principal_px[1]], [0, 0, 1.0]])
        return cls(K, np.array([k1, 0.0, 0.0, 0.0, 0.0]), rvec, -world_to_cam @ centre)

    def px(self, xy_m: NDArray[np.float64]) -> NDArray[np.float64]:
        """Plane points (N, 2), m, to image pixels (N, 2) (pixel centres at integers)."""
        p3 = np.column_stack([xy_m, np.zeros(len(xy_m))])
        out, _ = cv2.projectPoints(p3, self.rvec, self.tvec, self.K, self.dist)
        return out.reshape(-1, 2)


def _rect(centre, axis, half_len, half_w, n=80):  # type: ignore[no-untyped-def]
    u = np.asarray(axis, float) / np.linalg.norm(axis)
    v = np.array([-u[1], u[0]])
    c = np.asarray(centre, float)
    corners = [c - half_len * u - half_w * v, c + half_len * u - half_w * v]
    corners += [c + half_len * u + half_w * v, c - half_len * u + half_w * v]
    t = np.linspace(0.0, 1.0, n, endpoint=False)[:, None]
    return np.vstack([corners[i] + (corners[(i + 1) % 4] - corners[i]) * t for i in range(4)])


@dataclass(frozen=True)
class BeamState:
    hub_angle_rad: float
    q_m: tuple[float, float]  # the two modes' tip amplitudes

    def centre_line(self) -> tuple[NDArray[np.float64], NDArray[np.float64], float, float]:
        """(points (N, 2) m, slope angles (N,) rad relative to the hub axis, tip lateral m,
        tip longitudinal m)."""
        s = np.linspace(0.0, BEAM_LENGTH_M, 700)
        m1, m2 = mode_shapes(s)
        w = self.q_m[0] * m1 + self.q_m[1] * m2
        ang = np.arctan(np.gradient(w, s, edge_order=2))
        mid = 0.5 * (ang[1:] + ang[:-1])
        x = np.concatenate([[0.0], np.cumsum(np.cos(mid) * np.diff(s))])
        y = np.concatenate([[0.0], np.cumsum(np.sin(mid) * np.diff(s))])
        e = np.array([math.cos(self.hub_angle_rad), math.sin(self.hub_angle_rad)])
        n = np.array([-e[1], e[0]])
        pts = (HUB_OFFSET_M + x)[:, None] * e + y[:, None] * n
        return pts, ang, float(y[-1]), float(x[-1] - BEAM_LENGTH_M)

    def outline(self, width_m: float) -> NDArray[np.float64]:
        pts, ang, _, _ = self.centre_line()
        e = np.array([math.cos(self.hub_angle_rad), math.sin(self.hub_angle_rad)])
        n = np.array([-e[1], e[0]])
        normal = -np.sin(ang)[:, None] * e + np.cos(ang)[:, None] * n
        left, right = pts + 0.5 * width_m * normal, pts - 0.5 * width_m * normal
        return np.vstack([left, right[::-1]])


@dataclass(frozen=True)
class Bench:
    camera: Camera
    hub_length_m: float = 0.2
    hub_width_m: float = 0.04
    beam_width_m: float = 0.01905
    background_dn: float = 55.0
    plate_dn: float = 200.0
    groove_dn: float = 60.0
    hub_dn: float = 170.0
    beam_dn: float = 205.0
    noise_dn: float = 3.0
    optics_sigma_px: float = 0.8
    gradient: float = 0.15  # the light's fractional change across the image, left to right
    jpeg_quality: int = 88
    #: A bar as bright as the hub against one of its long edges, turning with it: (from,
    #: to) m back from the clamp end, its width m, the side (+1: toward a larger hub
    #: angle); None: no bar.
    hub_bar: tuple[float, float, float, int] | None = None


def draw_polygons(
    shapes: list[tuple[NDArray[np.float64], float]],
    background_dn: float,
    x0: int,
    y0: int,
    w: int,
    h: int,
) -> NDArray[np.float32]:
    """The image [row, col] of pixels ``x0 .. x0 + w - 1`` by ``y0 .. y0 + h - 1`` of
    polygons (image pixel coordinates, pixel centres at integers) filled in order with
    their levels (DN) over ``background_dn``: each pixel takes each polygon's level by the
    exact fraction of its area inside it (Agg's coverage, 8-bit)."""
    fig = Figure(figsize=(w / 100.0, h / 100.0), dpi=100)
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_axes((0.0, 0.0, 1.0, 1.0))
    ax.set_axis_off()
    ax.set_xlim(x0 - 0.5, x0 + w - 0.5)  # pixel i spans i - 1/2 .. i + 1/2
    ax.set_ylim(y0 + h - 0.5, y0 - 0.5)  # rows down
    fig.patch.set_facecolor((background_dn / 255.0,) * 3)
    for poly, level in shapes:
        grey = (float(level) / 255.0,) * 3
        # add_artist, not add_patch: the view is set above, and add_patch's update of the
        # data limits (the extrema of every segment) was most of the drawing's time
        ax.add_artist(
            Polygon(poly, closed=True, facecolor=grey, edgecolor="none", linewidth=0.0, snap=False)
        )
    canvas.draw()
    rgba = np.asarray(canvas.buffer_rgba())
    assert rgba.shape[:2] == (h, w), rgba.shape
    return rgba[:, :, 0].astype(np.float32)


def render(bench: Bench, states: list[BeamState], rng: np.random.Generator) -> NDArray[np.uint8]:
    """The frame of an exposure over ``states`` (equally spaced in time), JPEG-decoded."""
    return expose(bench, light(bench, states), rng)


def expose(bench: Bench, lit: NDArray[np.float32], rng: np.random.Generator) -> NDArray[np.uint8]:
    """The sensor's frame of the light ``lit`` (:func:`light`): noise, 8 bits, JPEG."""
    img = lit + rng.normal(0.0, bench.noise_dn, lit.shape)
    img = np.clip(np.round(img), 0, 255).astype(np.uint8)
    ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, bench.jpeg_quality])
    assert ok
    return cv2.imdecode(buf, cv2.IMREAD_GRAYSCALE)


def light(bench: Bench, states: list[BeamState]) -> NDArray[np.float32]:
    """The light on the sensor (DN, float) over an exposure: the scene averaged over
    ``states``, the lighting gradient and the optics' blur."""
    cam = bench.camera
    statics = [
        (_rect(REG_CENTER_M, [1, 0], PLATE_M / 2, PLATE_M / 2), bench.plate_dn),
        (_rect(REG_CENTER_M, [1, 0], PLATE_M / 2, SQUARE_M / 2), bench.groove_dn),
        (_rect(REG_CENTER_M, [0, 1], PLATE_M / 2, SQUARE_M / 2), bench.groove_dn),
    ]

    def dynamic(st: BeamState):  # type: ignore[no-untyped-def]
        e = np.array([math.cos(st.hub_angle_rad), math.sin(st.hub_angle_rad)])
        half_len, half_w = bench.hub_length_m / 2, bench.hub_width_m / 2
        hub = _rect((HUB_OFFSET_M - half_len) * e, e, half_len, half_w)
        shapes = [(hub, bench.hub_dn), (st.outline(bench.beam_width_m), bench.beam_dn)]
        if bench.hub_bar is not None:
            a0, a1, w, side = bench.hub_bar
            n = np.array([-e[1], e[0]])
            c = (HUB_OFFSET_M - 0.5 * (a0 + a1)) * e + side * (half_w + 0.5 * w) * n
            shapes.insert(1, (_rect(c, e, 0.5 * (a1 - a0), 0.5 * w), bench.hub_dn))
        return shapes

    def draw(shapes, x0, y0, w, h):  # type: ignore[no-untyped-def]
        px = [(cam.px(poly), level) for poly, level in shapes]
        return draw_polygons(px, bench.background_dn, x0, y0, w, h)

    img = draw(statics + dynamic(states[0]), 0, 0, W_PX, H_PX)
    if len(states) > 1:  # the moving parts' box, drawn again for every pose
        ends = (states[0], states[-1])
        pts = np.vstack([cam.px(np.vstack([p for p, _ in dynamic(s)])) for s in ends])
        x0, y0 = np.maximum(np.floor(pts.min(axis=0)).astype(int) - 8, 0)
        x1, y1 = np.minimum(np.ceil(pts.max(axis=0)).astype(int) + 8, [W_PX, H_PX])
        acc = np.zeros((y1 - y0, x1 - x0), np.float32)
        for st in states:
            acc += draw(statics + dynamic(st), x0, y0, x1 - x0, y1 - y0)
        img[y0:y1, x0:x1] = acc / len(states)
    img = img * (1.0 + bench.gradient * np.linspace(-1.0, 1.0, W_PX)[None, :])
    return np.asarray(cv2.GaussianBlur(img, (0, 0), bench.optics_sigma_px), dtype=np.float32)


def random_camera(rng: np.random.Generator) -> Camera:
    """A camera 1.95 m above the plane, tilted 8-16 deg toward any azimuth, rolled up to
    6 deg, f 2000-2400 px, principal point within 30 px of the centre, |k1| <= 0.04."""
    return Camera.looking_at(
        (0.2 + rng.uniform(-0.05, 0.05), -0.33 + rng.uniform(-0.05, 0.05)),
        1.95,
        rng.uniform(8, 16),
        rng.uniform(0, 360),
        rng.uniform(-6, 6),
        rng.uniform(2000, 2400),
        (1024 + rng.uniform(-30, 30), 768 + rng.uniform(-30, 30)),
        0.04 * rng.uniform(-1, 1),
    )


def exposure(rng: np.random.Generator, smear_m: float) -> tuple[list[BeamState], BeamState]:
    """Poses over one exposure (and the mid-exposure one, the truth): the hub within the
    stroke, the first mode up to 35 mm at the tip and a little of the second; with
    ``smear_m`` > 0 the tip travels that far across during the exposure, 30-70 % of it
    from the hub turning (either way), the rest from the first mode (either way)."""
    theta = math.radians(rng.uniform(245, 328))
    q = (rng.uniform(-0.035, 0.035), rng.uniform(-0.002, 0.002))
    mid = BeamState(theta, q)
    if smear_m <= 0:
        return [mid], mid
    share = rng.uniform(0.3, 0.7)
    d_theta = float(rng.choice([-1, 1])) * share * smear_m / (BEAM_LENGTH_M + HUB_OFFSET_M)
    d_q = float(rng.choice([-1, 1])) * (1 - share) * smear_m
    n = max(3, math.ceil(smear_m / MAX_STEP_M) + 1)
    fs = np.linspace(-0.5, 0.5, n)
    states = [BeamState(theta + d_theta * f, (q[0] + d_q * f, q[1])) for f in fs]
    return states, mid
