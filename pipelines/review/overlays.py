"""Streams a processed run to Rerun: frames with overlays, series, Fig. 11, events.

Computes every overlay first (pixels from the measurement and the simulation), then
hands them to ``pipelines.review.viewer.RunViewer`` — the only module that talks to Rerun.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import CubicSpline

from daq.log import iter_frames
from pipelines.process.run import Processed
from pipelines.review.viewer import FrameOverlay, RunViewer
from vision import FrameMeasurement

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


def frame_overlay(
    m: FrameMeasurement,
    to_px: Callable[[FloatArray], FloatArray],
    sim_shape: tuple[FloatArray, FloatArray, FloatArray] | None,
    beam_length_m: float,
) -> FrameOverlay:
    """Overlay of one frame: what was measured, the rigid beam, the simulated shape."""
    if not m.ok:
        return FrameOverlay(ok=False, reason=m.reason)
    clamp = np.asarray(m.clamp_plane_m, float)
    axis = np.array([np.cos(m.hub_angle_rad), np.sin(m.hub_angle_rad)])
    rigid = to_px(np.stack([clamp, clamp + beam_length_m * axis]))
    sim_px = None
    if sim_shape is not None:
        stations, lat, lon = sim_shape
        sim_px = to_px(beam_points_plane(clamp, m.hub_angle_rad, stations, lat, lon))
    tip_px = to_px(np.asarray(m.tip_plane_m, float)[None, :])[0]
    return FrameOverlay(
        centreline_px=m.centreline_px,
        hub_line_px=m.hub_line_px,
        rigid_line_px=rigid,
        sim_beam_px=sim_px,
        tip_px=tip_px,
        ok=True,
        reason="",
    )


def stream_processed(processed: Processed, log_path: Path, viewer: RunViewer) -> None:
    """Log a processed run: results series, every frame with its overlays, events."""
    ds = processed.results
    viewer.log_results(ds)
    sim = processed.sim
    lat = CubicSpline(sim.time_s, sim.station_lateral_m, axis=0)
    lon = CubicSpline(sim.time_s, sim.station_longitudinal_m, axis=0)
    t0_ns = int(ds.attrs.get("t_zero_ns", 0))
    frame_t = ds["frame_time"].values
    by_seq = {f.sequence: (i, f) for i, f in enumerate(processed.frames)}
    length = processed.calibration.beam_length_m
    for frame in iter_frames(log_path):
        hit = by_seq.get(frame.sequence)
        if hit is None:
            continue
        i, measured = hit
        t = float(frame_t[i])
        shape = None
        if np.isfinite(t) and sim.time_s[0] <= t <= sim.time_s[-1]:
            shape = (sim.stations_m, np.asarray(lat(t)), np.asarray(lon(t)))
        overlay = frame_overlay(measured.measurement, processed.calibration.to_px, shape, length)
        viewer.log_frame(t, frame.data, frame.encoding, overlay)
    viewer.log_events(processed.events, t0_ns=t0_ns)
