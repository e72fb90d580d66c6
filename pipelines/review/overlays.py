"""Streams a processed run to Rerun: frames with overlays, series, Fig. 11, events.

Computes the pixels (from the measurement and the simulation), then hands them to
``pipelines.review.viewer.RunViewer`` — the only module that talks to Rerun.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import CubicSpline
from scipy.linalg import solve_banded

from daq.imageinfo import image_encoding
from daq.log import LogError, iter_frames
from pipelines.process.frames import MeasuredFrame
from pipelines.process.run import Processed
from pipelines.review.display import DIFFERENCE_GAIN
from pipelines.review.previews import (
    PREVIEW_MODES,
    RegionPreviews,
    Shown,
    region_note,
    whole_preview,
)
from pipelines.review.viewer import OVERLAY_ENTITIES, FrameOverlay, OverlayColumns, RunViewer
from vision import FrameMeasurement, VisionError
from vision.calibration import Calibration

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]


def beam_points_plane(
    clamp_m: FloatArray,
    hub_angle_rad: float,
    stations_m: FloatArray,
    lateral_m: FloatArray,
    longitudinal_m: FloatArray,
) -> FloatArray:
    """Plane points (S, 2) of a beam shape given in the hub frame from the clamp."""
    axis = np.array([np.cos(hub_angle_rad), np.sin(hub_angle_rad)])
    normal = np.array([-axis[1], axis[0]])  # toward increasing hub angle
    along = (stations_m + longitudinal_m)[:, None] * axis[None, :]
    return np.asarray(clamp_m[None, :] + along + lateral_m[:, None] * normal[None, :], float)


def magnified_difference(
    centreline_m: FloatArray,
    clamp_m: FloatArray,
    hub_angle_rad: float,
    sim_shape: tuple[FloatArray, FloatArray, FloatArray],
    gain: float,
) -> FloatArray:
    """Plane points (K, 2): the simulated beam plus ``gain`` times the measured centre
    line's lateral offset from it, at the centre line's points.

    A 0.2 mm difference is a tenth of a pixel on the bench's framing; twenty times it is
    visible. Points outside the simulated beam's span are dropped.
    """
    stations, lat, lon = sim_shape
    axis = np.array([np.cos(hub_angle_rad), np.sin(hub_angle_rad)])
    normal = np.array([-axis[1], axis[0]])
    rel = np.asarray(centreline_m, float) - clamp_m[None, :]
    along, across = rel @ axis, rel @ normal
    sim_along = stations + lon
    inside = (along >= sim_along[0]) & (along <= sim_along[-1])
    along, across = along[inside], across[inside]
    # a cubic through the stations: a straight line between them would itself differ from
    # the simulated shape by tens of micrometres, magnified like a real difference
    sim_across = not_a_knot_cubic(sim_along, lat, along)
    shown = sim_across + gain * (across - sim_across)
    return np.asarray(clamp_m[None, :] + np.outer(along, axis) + np.outer(shown, normal), float)


def not_a_knot_cubic(x: FloatArray, y: FloatArray, at: FloatArray) -> FloatArray:
    """The not-a-knot cubic spline through (``x``, ``y``) (``x`` increasing) at ``at``:
    scipy's ``CubicSpline(x, y)(at)`` to rounding, without its per-call checks (a
    frame's overlay built one, 0.2 ms, on each of a bench minute's 900 frames, in the
    serial step after them). Its slopes from the same equations (continuity of the
    second derivative inside, of the third at the second and last-but-one points),
    solved densely: the simulation's 21 stations."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    n = x.size
    if n < 4:  # scipy's own cases: a line, a parabola through three points
        return np.asarray(CubicSpline(x, y)(at), float)
    h = np.diff(x)
    d = np.diff(y) / h
    a = np.zeros((n, n))
    b = np.empty(n)
    i = np.arange(1, n - 1)
    a[i, i - 1] = h[1:]
    a[i, i] = 2.0 * (h[:-1] + h[1:])
    a[i, i + 1] = h[:-1]
    b[1:-1] = 3.0 * (h[1:] * d[:-1] + h[:-1] * d[1:])
    a[0, 0], a[0, 1] = h[1], h[0] + h[1]
    b[0] = ((h[0] + 2.0 * (h[0] + h[1])) * h[1] * d[0] + h[0] ** 2 * d[1]) / (h[0] + h[1])
    a[-1, -1], a[-1, -2] = h[-2], h[-1] + h[-2]
    b[-1] = (h[-1] ** 2 * d[-2] + (2.0 * (h[-2] + h[-1]) + h[-1]) * h[-2] * d[-1]) / (h[-2] + h[-1])
    m = np.linalg.solve(a, b)
    q = np.asarray(at, float)
    k = np.clip(np.searchsorted(x, q, side="right") - 1, 0, n - 2)
    t = q - x[k]
    hk = h[k]
    c2 = (3.0 * d[k] - 2.0 * m[k] - m[k + 1]) / hk
    c3 = (m[k] + m[k + 1] - 2.0 * d[k]) / hk**2
    return np.asarray(y[k] + t * (m[k] + t * (c2 + t * c3)), float)


def spline_at(x: FloatArray, y: FloatArray, at: FloatArray) -> FloatArray:
    """scipy's ``CubicSpline(x, y, axis=0)(at)`` bit for bit, for ``x`` (n,) of 4 or more
    finite increasing times and finite ``y`` (n, ...) (otherwise it is scipy's own call):
    its slopes from the same not-a-knot system and solver, but the polynomials made only
    in the intervals of ``at`` (scipy makes all n - 1: a bench minute's simulation, 24 000
    steps of 21 stations, twice, was most of the overlays' time after the frames), each
    evaluated as scipy's ``PPoly`` does (powers by repeated products, summed from the
    constant term)."""
    x, y = np.asarray(x, np.float64), np.asarray(y, np.float64)
    n = x.shape[0]
    dx = np.diff(x) if x.ndim == 1 else np.zeros(0)
    usual = x.ndim == 1 and n >= 4 and y.ndim >= 1 and y.shape[0] == n
    if not (usual and np.isfinite(x).all() and np.isfinite(y).all() and (dx > 0).all()):
        return np.asarray(CubicSpline(x, y, axis=0)(at), float)
    # scipy.interpolate.CubicSpline.__init__, its not-a-knot case, step by step
    dxr = dx.reshape([dx.shape[0]] + [1] * (y.ndim - 1))
    slope = np.diff(y, axis=0) / dxr
    a = np.zeros((3, n))
    b = np.empty((n, *y.shape[1:]), dtype=y.dtype)
    a[1, 1:-1] = 2 * (dx[:-1] + dx[1:])
    a[0, 2:] = dx[:-1]
    a[-1, :-2] = dx[1:]
    b[1:-1] = 3 * (dxr[1:] * slope[:-1] + dxr[:-1] * slope[1:])
    a[1, 0] = dx[1]
    a[0, 1] = x[2] - x[0]
    d = x[2] - x[0]
    b[0] = ((dxr[0] + 2 * d) * dxr[1] * slope[0] + dxr[0] ** 2 * slope[1]) / d
    a[1, -1] = dx[-2]
    a[-1, -2] = x[-1] - x[-3]
    d = x[-1] - x[-3]
    b[-1] = (dxr[-1] ** 2 * slope[-2] + (2 * d + dxr[-1]) * dxr[-2] * slope[-1]) / d
    s = solve_banded(
        (1, 1), a, b.reshape(n, -1), overwrite_ab=True, overwrite_b=True, check_finite=False
    ).reshape(b.shape)
    # CubicHermiteSpline's coefficients and PPoly's evaluation, in the intervals of ``at``
    q = np.ascontiguousarray(np.asarray(at, np.float64).ravel())
    k = np.clip(np.searchsorted(x, q, side="right") - 1, 0, n - 2)
    hk, sk, s0, s1 = dxr[k], slope[k], s[k], s[k + 1]
    t = (s0 + s1 - 2 * sk) / hk
    c0, c1 = t / hk, (sk - s0) / hk - t
    v = (q - x[k]).reshape([q.size] + [1] * (y.ndim - 1))
    v2 = v * v
    out = (0.0 + y[k]) + s0 * v + c1 * v2 + c0 * (v2 * v)
    return np.asarray(out.reshape(np.shape(at) + y.shape[1:]), float)


def frame_overlay(
    m: FrameMeasurement,
    to_px: Callable[[FloatArray], FloatArray],
    sim_shape: tuple[FloatArray, FloatArray, FloatArray] | None,
    beam_length_m: float,
    *,
    scale: float = 1.0,
) -> FrameOverlay:
    """Overlay of one frame: what was measured, the rigid beam, the simulated shape and
    the measured - simulated difference magnified :data:`DIFFERENCE_GAIN` times.

    ``scale`` maps the measurement's pixels onto the displayed image's (a preview at
    1/``reduction`` of the size: pixel centres map as ``(p + 0.5) * scale - 0.5``).
    """
    if not m.ok:
        return FrameOverlay(ok=False, reason=m.reason)

    def shown(px: FloatArray) -> FloatArray:
        return np.asarray((np.asarray(px, float) + 0.5) * scale - 0.5, float)

    clamp = np.asarray(m.clamp_plane_m, float)
    axis = np.array([np.cos(m.hub_angle_rad), np.sin(m.hub_angle_rad)])
    rigid = to_px(np.stack([clamp, clamp + beam_length_m * axis]))
    sim_px = difference_px = None
    if sim_shape is not None:
        stations, lat, lon = sim_shape
        sim_px = shown(to_px(beam_points_plane(clamp, m.hub_angle_rad, stations, lat, lon)))
        diff = magnified_difference(
            m.centreline_plane_m, clamp, m.hub_angle_rad, sim_shape, DIFFERENCE_GAIN
        )
        if diff.shape[0] >= 2:
            difference_px = shown(to_px(diff))
    tip_px = to_px(np.asarray(m.tip_plane_m, float)[None, :])[0]
    return FrameOverlay(
        centreline_px=shown(m.centreline_px),
        hub_line_px=shown(m.hub_line_px),
        rigid_line_px=shown(rigid),
        sim_beam_px=sim_px,
        difference_px=difference_px,
        difference_gain=DIFFERENCE_GAIN,
        tip_px=shown(tip_px),
        ok=True,
        reason="",
    )


@dataclass(frozen=True)
class MeasuredParts:
    """What :func:`frame_overlay` takes from a measured frame alone, made as the frames
    are measured (:meth:`FramePreviews.feed`): the clamp (2,), the hub axis and its normal
    (2,) and the centre line's points along and across them from the clamp (K,), m."""

    clamp: FloatArray
    axis: FloatArray
    normal: FloatArray
    along: FloatArray
    across: FloatArray


def measured_parts(m: FrameMeasurement) -> MeasuredParts | None:
    """:class:`MeasuredParts` of ``m`` by :func:`frame_overlay`'s operations (those of
    :func:`beam_points_plane` and :func:`magnified_difference`); None if not ``ok``."""
    if not m.ok:
        return None
    clamp = np.asarray(m.clamp_plane_m, float)
    axis = np.array([np.cos(m.hub_angle_rad), np.sin(m.hub_angle_rad)])
    normal = np.array([-axis[1], axis[0]])
    rel = np.asarray(m.centreline_plane_m, float) - clamp[None, :]
    return MeasuredParts(clamp, axis, normal, rel @ axis, rel @ normal)


def _parts_or_none(m: FrameMeasurement) -> MeasuredParts | None:
    """:func:`measured_parts` of ``m``, or None where it cannot make them: they are made
    again where they are used, which says what is wrong there, not in the thread that
    receives the measured frames."""
    if not isinstance(m, FrameMeasurement):
        return None
    try:
        return measured_parts(m)
    except ValueError:  # arrays of the wrong shapes
        return None


def overlay_columns(
    measurements: Sequence[FrameMeasurement],
    calibration: Calibration,
    sim_shapes: tuple[FloatArray, FloatArray, FloatArray] | None,
    shape_rows: NDArray[np.intp],
    scale: FloatArray,
    parts: Sequence[MeasuredParts | None] | None = None,
) -> OverlayColumns:
    """:func:`frame_overlay` of every frame at once, as the columns the viewer logs: bit
    for bit :meth:`OverlayColumns.from_overlays` of the overlays made one by one (the same
    operations, element by element, on all the frames' points together; the points mapped
    to pixels in one call, or in frame_overlay's calls where the lens is OpenCV's:
    :attr:`~vision.calibration.Calibration.to_px_pointwise`).

    Parameters
    ----------
    measurements : the F frames' measurements.
    calibration : what maps the beam plane to the image, and the beam's length.
    sim_shapes : the simulated shapes: stations (S,), lateral and longitudinal offsets
        (W, S), m; or None.
    shape_rows : (F,) which row of ``sim_shapes`` each frame shows (-1: none).
    scale : (F,) each frame's pixel scale (see :func:`frame_overlay`).
    parts : each frame's :func:`measured_parts`, where made ahead (None: made here).
    """
    n = len(measurements)
    scale = np.asarray(scale, float).reshape(n)
    shape_rows = np.asarray(shape_rows, np.intp).reshape(n)
    at = np.flatnonzero([m.ok for m in measurements])  # the frames measured
    k = at.size
    measured = [measurements[i] for i in at.tolist()]
    made = [parts[i] for i in at.tolist()] if parts is not None else [None] * k
    ps = [p if p is not None else measured_parts(m) for p, m in zip(made, measured, strict=True)]
    mp = [p for p in ps if p is not None]  # all of them: the frames are measured

    def rows(values: list[Any], shape: tuple[int, ...]) -> FloatArray:
        return np.array(values, float).reshape(k, *shape) if k else np.zeros((0, *shape))

    clamp, axis = rows([p.clamp for p in mp], (2,)), rows([p.axis for p in mp], (2,))
    normal = rows([p.normal for p in mp], (2,))
    hub = rows([m.hub_line_px for m in measured], (2, 2)).reshape(-1, 2)
    tip = rows([m.tip_plane_m for m in measured], (2,))
    rigid = np.stack([clamp, clamp + calibration.beam_length_m * axis], axis=1).reshape(-1, 2)
    centre = [np.asarray(m.centreline_px, float) for m in measured]
    for c in centre:
        if c.ndim != 2 or c.shape[1] != 2:
            raise ValueError(f"overlays.centreline_px must have shape (K, 2), got {c.shape}")
    centre_counts = np.array([c.shape[0] for c in centre], np.int64).reshape(k)
    centre_counts[centre_counts < 2] = 0  # a line needs two points
    kept = [c for c, m in zip(centre, centre_counts, strict=True) if m]

    # the simulated beam and the magnified difference, at the frames with a shape
    with_shape = np.flatnonzero(shape_rows[at] >= 0) if sim_shapes is not None else at[:0]
    beam, diff, diff_counts = np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0, np.int64)
    stations_count = 0
    if sim_shapes is not None and with_shape.size:
        stations, lat, lon = sim_shapes
        beam, diff, diff_counts = _sim_overlays(
            stations,
            np.asarray(lat)[shape_rows[at[with_shape]]],
            np.asarray(lon)[shape_rows[at[with_shape]]],
            clamp[with_shape],
            axis[with_shape],
            normal[with_shape],
            [mp[j] for j in with_shape.tolist()],
        )
        stations_count = stations.shape[0] if stations.shape[0] >= 2 else 0
        beam = beam if stations_count else np.zeros((0, 2))

    # to pixels, then to the displayed image's pixels
    sizes = [np.full(k, 2), np.ones(k, np.int64)]  # a call per frame: its rigid line, its tip
    sizes += [np.full(with_shape.size if stations_count else 0, stations_count), diff_counts]
    px = _to_px(calibration, [rigid, tip, beam, diff], [a[a > 0] for a in sizes])
    rigid_px, tip_px, beam_px, diff_px = np.split(
        px, np.cumsum([rigid.shape[0], tip.shape[0], beam.shape[0]])
    )
    counts = {name: np.zeros(n, np.int64) for name in OVERLAY_ENTITIES}
    points: dict[str, FloatArray] = {}

    def put(name: str, frames: NDArray[np.intp], per_frame: NDArray[np.int64], px: Any) -> None:
        counts[name][frames] = per_frame
        points[name] = _shown(px, np.repeat(scale[frames], per_frame))

    two = np.full(k, 2, np.int64)
    put("hub_line", at, two, hub)
    put("rigid_line", at, two, rigid_px)
    put("tip", at, np.ones(k, np.int64), tip_px)
    put("centreline", at, centre_counts, np.concatenate(kept) if kept else np.zeros((0, 2)))
    sim_frames = at[with_shape]
    for name in ("sim_beam", "sim_stations"):
        put(name, sim_frames, np.full(sim_frames.size, stations_count, np.int64), beam_px)
    put("difference", sim_frames, diff_counts, diff_px)
    return OverlayColumns(
        counts=counts,
        points=points,
        given=np.ones(n, bool),
        failed=np.array([not m.ok for m in measurements], bool).reshape(n),
        reasons=[m.reason if not m.ok else "" for m in measurements],
    )


def _shown(px: FloatArray, scale: FloatArray) -> FloatArray:
    """:func:`frame_overlay`'s pixels ``px`` (P, 2) on the displayed image, each point's
    frame at ``scale`` (P,): one scale for all is the same arithmetic, done faster."""
    px = np.asarray(px, float).reshape(-1, 2)
    s: Any = scale[0] if scale.size and (scale == scale[0]).all() else scale[:, None]
    return np.asarray((px + 0.5) * s - 0.5, float)


def _sim_overlays(
    stations: FloatArray,
    lat: FloatArray,
    lon: FloatArray,
    clamp: FloatArray,
    axis: FloatArray,
    normal: FloatArray,
    parts: list[MeasuredParts],
) -> tuple[FloatArray, FloatArray, NDArray[np.int64]]:
    """The W frames' simulated beams (W * S, 2) (:func:`beam_points_plane`) and magnified
    differences (:func:`magnified_difference`), plane points, with how many points each
    frame's difference has (0: fewer than two, none drawn), at once."""
    w = lat.shape[0]
    x = stations + lon  # (W, S): where the stations are along the hub axis
    beam = (
        clamp[:, None, :] + x[:, :, None] * axis[:, None, :] + lat[:, :, None] * normal[:, None, :]
    )
    sizes = np.array([p.along.size for p in parts], np.int64)
    along = np.concatenate([p.along for p in parts]) if w else np.zeros(0)
    across = np.concatenate([p.across for p in parts]) if w else np.zeros(0)
    # the centre line's points within the simulated beam's span
    inside = (along >= np.repeat(x[:, 0], sizes)) & (along <= np.repeat(x[:, -1], sizes))
    frame = np.repeat(np.arange(w), sizes)
    counts = np.bincount(frame[inside], minlength=w).astype(np.int64)
    counts[counts < 2] = 0  # fewer: frame_overlay draws no difference
    keep = inside & np.repeat(counts > 0, sizes)
    along, across = along[keep], across[keep]
    sim_across = _not_a_knot_cubics(x, lat, along, counts)
    shown = sim_across + DIFFERENCE_GAIN * (across - sim_across)
    diff = (
        np.repeat(clamp, counts, axis=0)
        + along[:, None] * np.repeat(axis, counts, axis=0)
        + shown[:, None] * np.repeat(normal, counts, axis=0)
    )
    return beam.reshape(-1, 2), diff, counts


def _to_px(
    calibration: Calibration, groups: list[FloatArray], calls: list[NDArray[np.int64]]
) -> FloatArray:
    """The plane points of ``groups`` (each (P, 2)) in raw pixels: in one call where that
    is what calls of ``calls`` points each give, else in those calls."""
    points = np.concatenate([np.asarray(g, float).reshape(-1, 2) for g in groups])
    if calibration.to_px_pointwise:
        return np.asarray(calibration.to_px(points), float).reshape(-1, 2)
    bounds = np.cumsum(np.concatenate(calls))[:-1]
    mapped = [calibration.to_px(p) for p in np.split(points, bounds) if p.shape[0]]
    return np.concatenate(mapped).reshape(-1, 2) if mapped else np.zeros((0, 2))


def _not_a_knot_cubics(
    x: FloatArray, y: FloatArray, at: FloatArray, counts: NDArray[np.int64]
) -> FloatArray:
    """:func:`not_a_knot_cubic` of each row of ``x``, ``y`` (W, n) at its ``counts``
    points of ``at``, one row after the other, bit for bit: its element-wise steps on all
    rows at once, its scalars' powers as scalars, the same LAPACK solve of each row."""
    w, n = x.shape
    ends = np.cumsum(counts).tolist()
    starts = [0, *ends[:-1]]
    if n < 4:  # scipy's own cases
        got = [not_a_knot_cubic(x[r], y[r], at[starts[r] : ends[r]]) for r in range(w)]
        return np.concatenate(got) if got else np.zeros(0)
    h = np.diff(x, axis=1)
    d = np.diff(y, axis=1) / h
    a = np.zeros((w, n, n))
    b = np.empty((w, n))
    i = np.arange(1, n - 1)
    a[:, i, i - 1] = h[:, 1:]
    a[:, i, i] = 2.0 * (h[:, :-1] + h[:, 1:])
    a[:, i, i + 1] = h[:, :-1]
    b[:, 1:-1] = 3.0 * (h[:, 1:] * d[:, :-1] + h[:, :-1] * d[:, 1:])
    h0, h1, hl, hm = h[:, 0], h[:, 1], h[:, -1], h[:, -2]
    # numpy's power of a scalar (the C library's pow), as the one-row function takes it
    h0sq = np.array([v**2 for v in h0], float)
    hlsq = np.array([v**2 for v in hl], float)
    a[:, 0, 0], a[:, 0, 1] = h1, h0 + h1
    b[:, 0] = ((h0 + 2.0 * (h0 + h1)) * h1 * d[:, 0] + h0sq * d[:, 1]) / (h0 + h1)
    a[:, -1, -1], a[:, -1, -2] = hm, hl + hm
    b[:, -1] = (hlsq * d[:, -2] + (2.0 * (hm + hl) + hl) * hm * d[:, -1]) / (hm + hl)
    m = np.linalg.solve(a, b[:, :, None])[:, :, 0]
    # each interval's cubic, in the one-row function's operations
    c2 = (3.0 * d - 2.0 * m[:, :-1] - m[:, 1:]) / h
    c3 = (m[:, :-1] + m[:, 1:] - 2.0 * d) / h**2
    q = np.asarray(at, float)
    k = [
        np.searchsorted(x[r], q[s:e], side="right")
        for r, (s, e) in enumerate(zip(starts, ends, strict=True))
    ]
    cell = np.repeat(np.arange(w) * (n - 1), counts) + np.clip(
        (np.concatenate(k) if k else np.zeros(0, np.intp)) - 1, 0, n - 2
    )
    t = q - x[:, :-1].ravel()[cell]
    ck = [v.ravel()[cell] for v in (y[:, :-1], m[:, :-1], c2, c3)]
    return np.asarray(ck[0] + t * (ck[1] + t * (ck[2] + t * ck[3])), float)


def displayed_frame(data: bytes, encoding: str, reduction: int) -> Shown:
    """The frame as the recording shows it: as logged (``reduction`` 1) or a JPEG preview
    at 1/``reduction`` of its size (:func:`whole_preview`: None for a frame that does not
    decode); with the pixel scale."""
    if reduction == 1:
        return data, encoding, 1.0
    return whole_preview(data, reduction)


# Previews made ahead are kept in memory up to this many bytes (a bench minute at 1/2 size
# is about 90 MB); the frames past it are reduced while the recording is written.
PREVIEW_BUDGET_BYTES = 256 * 1024 * 1024
# frames sent to Rerun per call: 16 frames at 1/2 size are a chunk of about Rerun's own
# chunk size (1 MiB); a few hundred per chunk made the recording's close wait several
# times longer, one per call spent more CPU in Python (900 frames under load: 1.5-2.0 s
# CPU at 16 per call, 2.4 s one by one, 3.0 s at 256)
_FRAMES_PER_BATCH = 16
# whole previews are made this many at a time (each frame alone, the decode and encode
# outside the GIL): those left when the frames are measured use both cores, not one
_WHOLE_THREADS = 2
# the measured frames' bytes (given with their measurements) are held for the previews
# up to this many bytes; the frames past it are read from the log again
HELD_BYTES = 64 * 1024 * 1024


class FramePreviews:
    """The log's frames as the recording shows them (:class:`RegionPreviews`), made in a
    thread while the frames are measured, so the ``.rrd`` step after them only logs.

    Start it before ``process_run`` and give ``process_run`` its :meth:`feed` as
    ``on_measured``: most frames show only the measured region as that frame's
    (``mode="region"``), so the thread follows the measurements, made from the bytes the
    run read (given with them; up to :data:`HELD_BYTES` held, a frame given without its
    bytes or past them is read from the log again); ``mode="whole"`` makes
    every frame whole, ahead of them, :data:`_WHOLE_THREADS` at a time (each depends on
    its frame alone), so those left when the frames are measured do not leave a core
    idle. :func:`stream_processed` takes what it made (the decodes and the JPEG encodes
    run outside the GIL). Up to :data:`PREVIEW_BUDGET_BYTES` are kept; a failure (a frame
    that does not decode) is not raised here: that frame and the rest are made again, in
    order, where they always were.
    """

    def __init__(self, log_path: Path, reduction: int, mode: str = "whole") -> None:
        if mode not in PREVIEW_MODES:
            raise ValueError(f"mode must be one of {PREVIEW_MODES}, got {mode!r}")
        self.log_path = Path(log_path)
        self.reduction = int(reduction)
        self.mode = mode
        self.composer = (
            RegionPreviews(self.reduction, whole=mode == "whole")
            if self.reduction in (2, 4)
            else None
        )
        self._made: dict[int, Shown] = {}
        # each frame fed: its measurement and that measurement's overlay parts
        self._parts: dict[int, tuple[FrameMeasurement, MeasuredParts | None]] = {}
        self.wall_s = 0.0  # how long the thread took
        self.cpu_s = 0.0  # and the CPU time it used (its helper threads' too)
        self._helpers_cpu_s: list[float] = []
        self._stop = threading.Event()
        # (t_ns, sequence, measurement, bytes or None) of the frames fed, in that order
        self._measured: deque[tuple[int, int, FrameMeasurement, bytes | None]] = deque()
        self._fed: set[int] = set()
        self._held = 0  # bytes of the frames fed and not yet made
        self._fed_all = False
        self._cond = threading.Condition()
        self._thread = threading.Thread(target=self._run, name="frame-previews", daemon=True)

    def start(self) -> FramePreviews:
        self._thread.start()
        return self

    def feed(self, frames: Iterable[MeasuredFrame]) -> None:
        """Measured frames, in the log's order, in any number at a time
        (``process_run``'s ``on_measured``); a frame given again is ignored. Their
        overlays' :func:`measured_parts` are made here (a few microseconds a frame, in
        the thread that receives them, which waits for the workers between batches)."""
        frames = list(frames)
        for f in frames:
            if f.sequence not in self._parts:
                self._parts[f.sequence] = (f.measurement, _parts_or_none(f.measurement))
        if self.mode == "whole":
            return
        with self._cond:
            for f in frames:
                if f.sequence in self._fed:
                    continue
                self._fed.add(f.sequence)
                data = f.data
                if data is not None and self._held + len(data) > HELD_BYTES:
                    data = None  # read from the log again
                self._held += len(data) if data is not None else 0
                self._measured.append((f.t_ns, f.sequence, f.measurement, data))
            self._cond.notify_all()

    def _next_measured(self) -> tuple[int, int, FrameMeasurement, bytes | None] | None:
        """The next frame fed (t_ns, sequence, measurement, bytes or None), or None when
        no more will be."""
        with self._cond:
            while not self._measured:
                if self._fed_all or self._stop.is_set():
                    return None
                self._cond.wait(timeout=0.5)
            fed = self._measured.popleft()
            self._held -= len(fed[3]) if fed[3] is not None else 0
            return fed

    def _run(self) -> None:
        t0, c0 = time.perf_counter(), time.thread_time()
        try:
            self._make()
        finally:
            self.wall_s = time.perf_counter() - t0
            self.cpu_s = time.thread_time() - c0 + sum(self._helpers_cpu_s)

    def _make(self) -> None:
        if self.composer is None:
            return
        if self.mode == "whole":
            self._make_whole(self.composer)
            return
        size = 0
        logged: Iterator[Any] | None = None  # the log, opened at the first frame fed bare
        try:
            while not (self._stop.is_set() or size > PREVIEW_BUDGET_BYTES):
                fed = self._next_measured()
                if fed is None:
                    return
                t_ns, sequence, m, data = fed
                if data is not None:
                    encoding = image_encoding(data) or ""  # as the log's reader tells it
                else:
                    if logged is None:
                        logged = iter_frames(self.log_path, start_ns=t_ns)
                    frame = next((f for f in logged if f.sequence == sequence), None)
                    if frame is None:
                        return  # not in the log from there on: made in stream_processed
                    data, encoding = frame.data, frame.encoding
                shown = self.composer.show(data, encoding, m)
                self._made[sequence] = shown
                size += len(shown[0] or b"")
        except (VisionError, LogError, OSError, ValueError):
            return  # the frames left are reduced in stream_processed, which reports it

    def _make_whole(self, composer: RegionPreviews) -> None:
        """:meth:`_make` of whole previews: the log read here, the frames made
        :data:`_WHOLE_THREADS` at a time, kept in the log's order (the same as one by
        one: up to the budget, up to the first that fails)."""
        size = 0
        pending: deque[tuple[int, Future[Shown]]] = deque()

        def made(data: bytes) -> Shown:
            c0 = time.thread_time()
            try:
                return whole_preview(data, composer.reduction)
            finally:
                self._helpers_cpu_s.append(time.thread_time() - c0)

        def keep() -> bool:  # the oldest made frame kept; False: no more are
            nonlocal size
            sequence, done = pending.popleft()
            if self._stop.is_set() or size > PREVIEW_BUDGET_BYTES:
                return False
            shown = done.result()
            self._made[sequence] = shown
            composer.whole_frames += 1
            size += len(shown[0] or b"")
            return True

        pool = ThreadPoolExecutor(_WHOLE_THREADS, thread_name_prefix="frame-previews")
        try:
            for frame in iter_frames(self.log_path):
                if self._stop.is_set() or size > PREVIEW_BUDGET_BYTES:
                    return
                try:
                    pending.append((frame.sequence, pool.submit(made, frame.data)))
                except RuntimeError:  # the interpreter is exiting (never stopped): no more
                    return
                if len(pending) > 2 * _WHOLE_THREADS and not keep():
                    return
            while pending:
                if not keep():
                    return
        except (VisionError, LogError, OSError, ValueError):
            return  # the frames left are reduced in stream_processed, which reports it
        finally:
            pool.shutdown(wait=True, cancel_futures=True)

    def _finish(self) -> None:
        with self._cond:
            self._fed_all = True
            self._cond.notify_all()
        if self._thread.is_alive():
            self._thread.join()

    def stop(self) -> None:
        """Stop making previews (the run failed, or they were used); safe to repeat."""
        self._stop.set()
        self._finish()

    def overlay_parts(self, frames: Sequence[MeasuredFrame]) -> list[MeasuredParts | None]:
        """The :func:`measured_parts` of each of ``frames`` made as it was fed (None where
        none was, or it was fed with another measurement: made where they are used)."""
        out: list[MeasuredParts | None] = []
        for f in frames:
            fed = self._parts.get(f.sequence)
            out.append(fed[1] if fed is not None and fed[0] is f.measurement else None)
        return out

    def take(self, frames: Iterable[MeasuredFrame] = ()) -> dict[int, Shown]:
        """Wait for the thread (if started), given the run's measured ``frames`` (those
        not fed already); the previews it made, by frame sequence."""
        self.feed(frames)
        self._finish()
        return self._made


def stream_processed(
    processed: Processed,
    log_path: Path,
    viewer: RunViewer,
    *,
    frame_reduction: int = 2,
    previews: FramePreviews | None = None,
    frame_previews: str = "whole",
) -> None:
    """Log a processed run: results series, every frame with its overlays, events.

    Frames go in at 1/``frame_reduction`` of their size (2 by default: a 20 s run's
    recording loads in seconds; 1 keeps the logged frames as they are), made by
    :class:`~pipelines.review.previews.RegionPreviews` (``frame_previews`` "region": whole
    once a second, the measured region alone between; "whole": every frame whole), taken
    from ``previews`` where it made them that way (:class:`FramePreviews`), and sent to
    Rerun as columns, 16 frames per call. Their overlays follow, all the frames' at once
    (:func:`overlay_columns`, from the parts of them ``previews`` made as the frames were
    measured), one call per overlay entity.
    """
    if frame_previews not in PREVIEW_MODES:
        raise ValueError(f"frame_previews must be one of {PREVIEW_MODES}, got {frame_previews!r}")
    ds = processed.results
    frames = processed.frames
    logged, scales, first = _log_results_and_frames(
        processed, log_path, viewer, frame_reduction, previews, frame_previews
    )
    # then the overlays of all the frames logged, at once (frame_overlay's, bit for bit)
    rows = np.asarray(logged, np.intp)
    shapes, shape_row = _sim_shapes(processed)
    parts = previews.overlay_parts(frames) if previews is not None else None
    overlays = overlay_columns(
        [frames[i].measurement for i in logged],
        processed.calibration,
        shapes,
        shape_row[rows],
        np.asarray(scales, float),
        [parts[i] for i in logged] if parts is not None else None,
    )
    frame_t = ds["frame_time"].values
    viewer.log_frame_overlays(frame_t[rows], overlays, first_index=first)
    viewer.log_events(processed.events, t0_ns=int(ds.attrs.get("t_zero_ns", 0)))


def _sim_shapes(
    processed: Processed,
) -> tuple[tuple[FloatArray, FloatArray, FloatArray] | None, NDArray[np.intp]]:
    """The simulated shapes at the frames' times within the simulation's (stations (S,),
    lateral and longitudinal (W, S) at those W frames), and each frame's row of them (-1:
    none)."""
    sim = processed.sim
    frame_t = processed.results["frame_time"].values
    within = np.isfinite(frame_t) & (sim.time_s[0] <= frame_t) & (frame_t <= sim.time_s[-1])
    shapes = None
    if within.any():
        at = frame_t[within]
        lat = spline_at(sim.time_s, sim.station_lateral_m, at)
        shapes = sim.stations_m, lat, spline_at(sim.time_s, sim.station_longitudinal_m, at)
    return shapes, np.where(within, np.cumsum(within) - 1, -1)


def _log_results_and_frames(
    processed: Processed,
    log_path: Path,
    viewer: RunViewer,
    frame_reduction: int,
    previews: FramePreviews | None,
    frame_previews: str,
) -> tuple[list[int], list[float], int]:
    """:func:`stream_processed`'s results and frames, without their overlays: which of
    ``processed.frames`` were logged, in order, at which pixel scales, from which value
    on the ``frame`` timeline."""
    ds = processed.results
    region = frame_reduction > 1 and frame_previews == "region"
    viewer.log_results(ds, summary_note=region_note(frame_reduction) if region else "")
    frame_t = ds["frame_time"].values
    by_seq = {f.sequence: (i, f) for i, f in enumerate(processed.frames)}
    made: dict[int, Shown] = {}
    composer = None
    if (
        previews is not None
        and previews.reduction == frame_reduction
        and previews.mode == frame_previews
    ):
        made = previews.take(processed.frames)
        composer = previews.composer  # continues where the thread stopped
    elif previews is not None:
        previews.stop()
    if composer is None and frame_reduction > 1:
        composer = RegionPreviews(frame_reduction, whole=frame_previews == "whole")
    first = viewer.frame_index
    logged: list[int] = []  # each frame logged: its place in processed.frames
    scales: list[float] = []  # and its pixel scale
    times: list[float] = []
    images: list[bytes | None] = []
    encodings: list[str] = []
    blank = 0  # frames that did not decode: logged without an image

    def send() -> None:
        if times:
            viewer.log_frames(times, images, encodings)
            for column in (times, images, encodings):
                column.clear()

    for sequence, frame in _measured_in_log_order(log_path, processed.frames, made):
        hit = by_seq.get(sequence)
        if hit is None:
            continue
        i, measured = hit
        shown = made.pop(sequence, None)
        if shown is None:
            assert frame is not None  # read from the log wherever no preview was made
            if composer is None:
                shown = displayed_frame(frame.data, frame.encoding, frame_reduction)
            else:
                shown = composer.show(frame.data, frame.encoding, measured.measurement)
        data, encoding, scale = shown
        blank += data is None
        times.append(float(frame_t[i]))
        images.append(data)
        encodings.append(encoding)
        logged.append(i)
        scales.append(scale)
        if len(times) >= _FRAMES_PER_BATCH:
            send()
    send()
    if blank:
        log.warning(
            "%s: %d frame(s) did not decode; the recording shows them without an image",
            log_path,
            blank,
        )
    return logged, scales, first


def _measured_in_log_order(
    log_path: Path, frames: list[MeasuredFrame], made: dict[int, Shown]
) -> Iterator[tuple[int, Any]]:
    """(sequence, the logged frame or None) of the log's frames in its order, the log
    read only where it is needed: not at all while ``made`` holds a preview of each
    measured frame (they were measured from this log, in its order), from the start
    again at the first without one (the previews thread stops at a frame and makes no
    later one), then every frame not given yet, as the log has them. A log whose frames
    repeat a sequence number is read whole, as before."""
    seqs = [f.sequence for f in frames]
    given: set[int] = set()
    if len(set(seqs)) == len(seqs):
        for seq in seqs:
            if seq not in made:
                break
            given.add(seq)
            yield seq, None
        else:
            return
    for f in iter_frames(log_path):
        if f.sequence not in given:
            yield f.sequence, f
