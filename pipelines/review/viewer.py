"""Rerun review of a run: camera frames with overlays, time series, Fig. 11, events.

Follows the rerun-io examples: compute first, then log; one ``log_<stream>`` per
source; hierarchical entity paths; ``send_columns`` for the high-rate series; a
blueprint for the layout; a ``.rrd`` file so CI needs no viewer. ``rerun`` is imported
only in ``pipelines/viewer*.py``.

Timelines: ``time`` (duration, seconds on the run clock, i.e. since run start for a
processed run) for everything, and ``frame`` (sequence) for camera frames.

Entity paths::

    /daq/rocker_angle              potentiometer angle (deg)
    /daq/strain/g1 .. gN           measured strain (microstrain)
    /sim/strain/g1 .. gN           simulated strain (microstrain)
    /sim/tip_lateral               simulated lateral tip deflection (mm)
    /tip_lateral/image             lateral tip deflection from the images (mm, points)
    /tip_lateral/strain            ... reconstructed from the strains (mm)
    /residual/strain/g1 .. gN      measured - simulated strain (microstrain)
    /residual/tip_lateral/...      image - sim (points), strain - sim (line), mm
    /camera/image                  encoded JPEG/PNG frames (not decoded here)
    /camera/image/centreline ...   overlays in pixels, drawn on top of the image
    /fig11/measured, /fig11/sim    Fig. 11: tip lateral (mm) against hub angle (deg),
    /fig11/axes, /fig11/ticks      with its axes and numbers, and /fig11/now, the
                                   current frame's point (on the time line)
    /events                        run events as a text log; /events/frames: failed frames
    /summary                       the error summary and the colour key (markdown)

The methods take SI values (rad, m, m/m) and show degrees, millimetres and microstrain.
"""

from __future__ import annotations

import logging
import math
import os
import uuid
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import pyarrow as pa
import rerun as rr
import xarray as xr
from numpy.typing import ArrayLike, NDArray

from pipelines.atomic import discard, temp_path_beside
from pipelines.paths import write_failed
from pipelines.review.display import fig11_axes, run_view
from pipelines.review.layout import (
    COLOUR_AXES,
    COLOUR_CENTRELINE,
    COLOUR_DIFFERENCE,
    COLOUR_HUB,
    COLOUR_MEASURED,
    COLOUR_RESIDUAL,
    COLOUR_RIGID,
    COLOUR_SIM,
    COLOUR_STRAIN,
    COLOUR_TIP,
    DEG_PER_RAD,
    LAYOUTS,
    MICROSTRAIN,
    MM_PER_M,
    build_blueprint,
    gauge_entity,
)
from pipelines.review.rrd import RrdEntity, rrd_entities

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]

_URL_SCHEMES = ("rerun://", "rerun+http://", "rerun+https://")
_MEDIA_TYPES = {"jpeg": "image/jpeg", "jpg": "image/jpeg", "png": "image/png"}

# Event levels: foxglove.Log numbers (1 debug .. 5 fatal) or names.
_LEVELS = {
    0: "INFO",
    1: "DEBUG",
    2: "INFO",
    3: "WARN",
    4: "ERROR",
    5: "CRITICAL",
    "debug": "DEBUG",
    "info": "INFO",
    "warn": "WARN",
    "warning": "WARN",
    "error": "ERROR",
    "fatal": "CRITICAL",
    "critical": "CRITICAL",
    "unknown": "INFO",
}


class EventLike(Protocol):
    """What ``log_events`` needs of an event (``daq.log`` records have these)."""

    @property
    def t_ns(self) -> int: ...
    @property
    def level(self) -> Any: ...
    @property
    def name(self) -> str: ...
    @property
    def message(self) -> str: ...


@dataclass(frozen=True)
class FrameOverlay:
    """What the measurement found in one frame, in pixels, points ``(x, y)`` = (col, row).

    Attributes
    ----------
    centreline_px : (K, 2) detected beam centre line, or None.
    hub_line_px : (2, 2) end points of the hub line, or None.
    rigid_line_px : (2, 2) pivot and tip of the hypothetical rigid beam, or None.
    sim_beam_px : (S, 2) simulated beam shape projected into the image, or None.
    difference_px : (K, 2) the measured centre line's offset from the simulated beam,
        magnified ``difference_gain`` times about the simulated beam, or None.
    tip_px : (2,) detected tip, or None.
    ok : whether the frame gave a measurement.
    reason : why not, when ``ok`` is False.
    """

    centreline_px: ArrayLike | None = None
    hub_line_px: ArrayLike | None = None
    rigid_line_px: ArrayLike | None = None
    sim_beam_px: ArrayLike | None = None
    difference_px: ArrayLike | None = None
    difference_gain: float = 20.0
    tip_px: ArrayLike | None = None
    ok: bool = True
    reason: str = ""


def _points(name: str, value: ArrayLike | None, n: int | None = None) -> FloatArray | None:
    if value is None:
        return None
    a = np.asarray(value, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 2 or (n is not None and a.shape[0] != n):
        want = f"({n}, 2)" if n is not None else "(K, 2)"
        raise ValueError(f"overlays.{name} must have shape {want}, got {a.shape}")
    return a


# What each frame overlay entity draws with (colour, radius, draw order): lines, then points.
_OVERLAY_LINES = ("hub_line", "rigid_line", "sim_beam", "difference", "centreline")
_OVERLAY_STYLE: dict[str, tuple[Any, float, float]] = {
    "hub_line": (COLOUR_HUB, 3.0, 1.0),
    "rigid_line": (COLOUR_RIGID, 1.5, 2.0),
    "sim_beam": (COLOUR_SIM, 1.0, 3.0),
    "difference": (COLOUR_DIFFERENCE, 1.5, 4.0),
    "centreline": (COLOUR_CENTRELINE, 2.0, 5.0),
    "sim_stations": (COLOUR_SIM, 4.0, 3.5),
    "tip": (COLOUR_TIP, 8.0, 6.0),
}


def _overlay_shapes(o: FrameOverlay) -> dict[str, FloatArray | None]:
    """The points each overlay entity shows for ``o`` (None: the entity is cleared), as
    :meth:`RunViewer.log_frame` logs them."""
    sim = _points("sim_beam_px", o.sim_beam_px)
    shapes = {
        "hub_line": _points("hub_line_px", o.hub_line_px, 2),
        "rigid_line": _points("rigid_line_px", o.rigid_line_px, 2),
        "sim_beam": sim,
        "difference": _points("difference_px", o.difference_px),
        "centreline": _points("centreline_px", o.centreline_px),
        "sim_stations": sim,
    }
    out: dict[str, FloatArray | None] = {
        k: (v if v is not None and v.shape[0] >= 2 else None) for k, v in shapes.items()
    }
    if o.tip_px is None:
        out["tip"] = None
    else:
        tip = np.asarray(o.tip_px, dtype=np.float64)
        if tip.shape != (2,):
            raise ValueError(f"overlays.tip_px must have shape (2,), got {tip.shape}")
        out["tip"] = tip[None, :]
    return out


#: the overlay entities, under ``/camera/image``
OVERLAY_ENTITIES = tuple(_OVERLAY_STYLE)
# the fewest points an overlay entity draws (fewer: it is cleared at that frame)
_OVERLAY_MIN_POINTS = {name: 1 if name == "tip" else 2 for name in OVERLAY_ENTITIES}


@dataclass(frozen=True)
class OverlayColumns:
    """Many frames' overlays at once: what :meth:`RunViewer.log_frames` makes of a list
    of :class:`FrameOverlay` (:meth:`from_overlays`), or built as columns directly
    (``pipelines.review.overlays.overlay_columns``), for F frames.

    Attributes
    ----------
    counts : for each overlay entity (``hub_line``, ``rigid_line``, ``sim_beam``,
        ``difference``, ``centreline``, ``sim_stations``, ``tip``), (F,) how many points
        it draws at each frame; 0: it is cleared there.
    points : for each entity, (sum of counts, 2) those points in pixels, frame after frame.
    given : (F,) whether the frame has an overlay at all (one without is logged bare:
        nothing drawn, nothing cleared).
    failed : (F,) whether the frame gave no measurement; reasons : (F,) why not.
    """

    counts: dict[str, NDArray[np.int64]]
    points: dict[str, FloatArray]
    given: NDArray[np.bool_]
    failed: NDArray[np.bool_]
    reasons: list[str]

    def __post_init__(self) -> None:
        n = self.given.shape[0]
        if self.failed.shape != (n,) or len(self.reasons) != n:
            raise ValueError(f"given, failed and reasons must be as long: {n}")
        for name, least in _OVERLAY_MIN_POINTS.items():
            counts, points = self.counts[name], self.points[name]
            if counts.shape != (n,) or points.ndim != 2 or points.shape[1] != 2:
                raise ValueError(
                    f"overlays.{name}: counts ({n},) and points (P, 2), "
                    f"got {counts.shape} and {points.shape}"
                )
            if int(counts.sum()) != points.shape[0] or np.any((counts > 0) & (counts < least)):
                raise ValueError(f"overlays.{name}: counts do not match its points")

    @classmethod
    def from_overlays(cls, overlays: Sequence[FrameOverlay | None]) -> OverlayColumns:
        """The columns of ``overlays`` (None: a frame without one), as
        :meth:`RunViewer.log_frame` would log each."""
        n = len(overlays)
        counts = {name: np.zeros(n, np.int64) for name in OVERLAY_ENTITIES}
        values: dict[str, list[FloatArray]] = {name: [] for name in OVERLAY_ENTITIES}
        for i, o in enumerate(overlays):
            if o is None:
                continue
            for name, pts in _overlay_shapes(o).items():
                if pts is not None:
                    counts[name][i] = pts.shape[0]
                    values[name].append(pts)
        return cls(
            counts=counts,
            points={k: np.concatenate(v) if v else np.zeros((0, 2)) for k, v in values.items()},
            given=np.array([o is not None for o in overlays], bool),
            failed=np.array([o is not None and not o.ok for o in overlays], bool),
            reasons=[o.reason if o is not None else "" for o in overlays],
        )


def _overlay_rows(overlays: Sequence[FrameOverlay | None] | OverlayColumns) -> int:
    return overlays.given.shape[0] if isinstance(overlays, OverlayColumns) else len(overlays)


def _offsets(lengths: Sequence[int] | NDArray[np.int64]) -> pa.Array:
    out = np.zeros(len(lengths) + 1, np.int32)
    out[1:] = np.cumsum(lengths)
    return pa.array(out)


def _blob_array(data: Sequence[bytes | bytearray | memoryview]) -> pa.Array:
    """Rerun's Blob column of ``data``, built in one piece: Rerun's own conversion of a list
    of blobs makes an arrow array per blob and joins them, 15x slower for a few hundred
    JPEGs (the same array: tested through what the recording holds)."""
    inner = pa.array(np.frombuffer(b"".join(data), np.uint8))
    return pa.ListArray.from_arrays(
        _offsets([len(d) for d in data]), inner, type=pa.list_(pa.field("item", pa.uint8(), False))
    )


def _strips_array(points: FloatArray, lengths: NDArray[np.int64]) -> pa.Array:
    """Rerun's LineStrip2D column (one strip per row) of the strips of ``lengths`` points
    one after the other in ``points`` (P, 2), in one piece (Rerun converts them strip by
    strip)."""
    flat = np.ascontiguousarray(points, np.float32).ravel()
    values = pa.FixedSizeListArray.from_arrays(
        pa.array(flat), type=pa.list_(pa.field("item", pa.float32(), False), 2)
    )
    point = pa.field("item", values.type, False)
    return pa.ListArray.from_arrays(_offsets(lengths), values, type=pa.list_(point))


def _series(name: str, value: ArrayLike, n: int | None = None) -> FloatArray:
    a = np.asarray(value, dtype=np.float64)
    if a.ndim != 1 or (n is not None and a.shape[0] != n):
        raise ValueError(f"{name} must have shape ({n if n is not None else 'N'},), got {a.shape}")
    return a


def _time_column(t_s: FloatArray) -> rr.TimeColumn:
    # Rounded to whole ns here: rerun's own float conversion truncates (0.0025 s -> 2499999 ns).
    ns = np.round(t_s * 1e9).astype(np.int64).astype("timedelta64[ns]")
    return rr.TimeColumn("time", duration=ns)


class RunViewer:
    """One Rerun recording of a run; create it with :func:`open_viewer`.

    Use as a context manager or call :meth:`close`. For a ``.rrd`` destination the data
    goes to a temporary file beside it that replaces the destination on a successful
    close; :meth:`abort` (or leaving the ``with`` block on an exception) removes it and
    leaves an existing file untouched.
    """

    def __init__(
        self,
        recording: rr.RecordingStream,
        *,
        rrd_path: Path | None = None,
        tmp_path: Path | None = None,
    ) -> None:
        self.recording = recording
        self.rrd_path = rrd_path
        self._tmp_path = tmp_path
        self._frame_index = 0
        self._closed = False
        self._styled: set[str] = set()

    # -- sinks -----------------------------------------------------------------------

    def __enter__(self) -> RunViewer:
        return self

    def __exit__(self, exc_type: object, exc: object, tb: object) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()

    def _finish(self) -> None:
        # closed even when the flush fails (a full disk): abort() then only discards
        self._closed = True
        try:
            self.recording.flush()
        finally:
            self.recording.disconnect()

    def close(self) -> Path | None:
        """Flush everything; for a ``.rrd`` the file is complete afterwards.

        Returns
        -------
        Path or None
            The ``.rrd`` written, or None for a live viewer.
        """
        if self._closed:
            return self.rrd_path
        try:
            self._finish()
        except RuntimeError as exc:  # Rerun's file writer stopped (e.g. a full disk)
            reason = _sink_failure(exc, self._tmp_path)
            if self._tmp_path is not None:
                discard(self._tmp_path)
            raise write_failed(self.rrd_path or "the Rerun viewer", reason) from None
        if self._tmp_path is not None and self.rrd_path is not None:
            os.replace(self._tmp_path, self.rrd_path)
            log.info("wrote Rerun recording %s", self.rrd_path)
        return self.rrd_path

    def abort(self) -> None:
        """Stop logging; a ``.rrd`` destination is left as it was before."""
        if not self._closed:
            self._finish()
        if self._tmp_path is not None:
            discard(self._tmp_path)

    # -- helpers ---------------------------------------------------------------------

    def _style(self, entity: str, archetype: Any) -> None:
        if entity not in self._styled:
            self.recording.log(entity, archetype, static=True, strict=True)
            self._styled.add(entity)

    def _send_scalars(
        self, entity: str, t_s: FloatArray, values: FloatArray, name: str, colour: Any
    ) -> None:
        self._send(entity, t_s, values, rr.SeriesLines(names=name, colors=[colour]))

    def _send_points_series(
        self, entity: str, t_s: FloatArray, values: FloatArray, name: str, colour: Any
    ) -> None:
        style = rr.SeriesPoints(names=name, colors=[colour], marker_sizes=[3.0])
        self._send(entity, t_s, values, style)

    def _send(self, entity: str, t_s: FloatArray, values: FloatArray, style: Any) -> None:
        """A time series as one column (its style logged once); NaN values are skipped."""
        self._style(entity, style)
        keep = np.isfinite(values)
        if not keep.any():
            return
        self.recording.send_columns(
            entity,
            indexes=[_time_column(t_s[keep])],
            columns=rr.Scalars.columns(scalars=values[keep]),
            strict=True,
        )

    # -- streams ---------------------------------------------------------------------

    def log_samples(self, t_s: ArrayLike, rocker_angle_rad: ArrayLike, strain: ArrayLike) -> None:
        """The DAQ stream: rocker angle and the gauge strains.

        Parameters
        ----------
        t_s : (N,) sample times on the run clock [s].
        rocker_angle_rad : (N,) potentiometer angle [rad].
        strain : (N, G) surface strain [m/m], gauges ordered from the clamp.
        """
        t = _series("t_s", t_s)
        rocker = _series("rocker_angle_rad", rocker_angle_rad, t.size)
        eps = np.asarray(strain, dtype=np.float64)
        if eps.ndim != 2 or eps.shape[0] != t.size:
            raise ValueError(f"strain must have shape ({t.size}, G), got {eps.shape}")
        self._send_scalars(
            "/daq/rocker_angle", t, DEG_PER_RAD * rocker, "rocker angle", COLOUR_MEASURED
        )
        for j in range(eps.shape[1]):
            self._send_scalars(
                gauge_entity("/daq/strain", j),
                t,
                MICROSTRAIN * eps[:, j],
                f"g{j + 1} measured",
                COLOUR_MEASURED,
            )

    def log_sim(self, t_s: ArrayLike, tip_lateral_m: ArrayLike, strain: ArrayLike) -> None:
        """The simulation: lateral tip deflection and strain at the gauges.

        Parameters
        ----------
        t_s : (N,) times [s].
        tip_lateral_m : (N,) simulated lateral tip deflection [m].
        strain : (N, G) simulated surface strain at the gauges [m/m].
        """
        t = _series("t_s", t_s)
        tip = _series("tip_lateral_m", tip_lateral_m, t.size)
        eps = np.asarray(strain, dtype=np.float64)
        if eps.ndim != 2 or eps.shape[0] != t.size:
            raise ValueError(f"strain must have shape ({t.size}, G), got {eps.shape}")
        self._send_scalars("/sim/tip_lateral", t, MM_PER_M * tip, "simulated", COLOUR_SIM)
        for j in range(eps.shape[1]):
            self._send_scalars(
                gauge_entity("/sim/strain", j),
                t,
                MICROSTRAIN * eps[:, j],
                f"g{j + 1} simulated",
                COLOUR_SIM,
            )

    def log_frame(
        self,
        t_s: float,
        data: bytes | None,
        encoding: str,
        overlays: FrameOverlay | None = None,
        *,
        frame_index: int | None = None,
    ) -> None:
        """One camera frame (kept encoded) and what was measured in it.

        Parameters
        ----------
        t_s : frame time on the run clock [s].
        data : the JPEG or PNG bytes as logged; None for a frame that did not decode (the
            image is cleared at its time, as :meth:`log_frames` does).
        encoding : "jpeg" or "png".
        overlays : measurement overlays in pixels, or None (raw replay). A missing
            overlay clears the previous frame's one, so nothing stale is drawn.
        frame_index : value on the ``frame`` timeline (default: one more than the last).
        """
        if data is not None and not isinstance(data, bytes | bytearray | memoryview):
            raise TypeError(f"data must be bytes or None, got {type(data).__name__}")
        media = _MEDIA_TYPES.get(str(encoding).lower())
        if media is None:
            raise ValueError(f"encoding must be jpeg or png, got {encoding!r}")
        if not math.isfinite(t_s):
            raise ValueError(f"t_s must be finite, got {t_s!r}")
        index = self._frame_index if frame_index is None else int(frame_index)
        self._frame_index = index + 1
        rec = self.recording
        rec.set_time("time", duration=np.timedelta64(round(t_s * 1e9), "ns"))
        rec.set_time("frame", sequence=index)
        try:
            image: Any = (
                rr.Clear(recursive=False)
                if data is None
                else rr.EncodedImage(contents=bytes(data), media_type=media)
            )
            rec.log("/camera/image", image, strict=True)
            if overlays is not None:
                self._log_overlays(overlays, t_s)
        finally:
            rec.reset_time()

    @property
    def frame_index(self) -> int:
        """The next frame's value on the ``frame`` timeline."""
        return self._frame_index

    def log_frames(
        self,
        t_s: ArrayLike,
        data: Sequence[bytes | None],
        encodings: Sequence[str],
        overlays: Sequence[FrameOverlay | None] | OverlayColumns | None = None,
        *,
        first_index: int | None = None,
    ) -> None:
        """Many frames at once, as :meth:`log_frame` would log them one by one (the same
        entities, rows and times), sent as columns: one call per entity instead of about
        ten per frame, which was most of a processed run's ``.rrd`` step (issue #19). A
        frame whose ``data`` is None (it did not decode) has no image: the image is
        cleared at its time, so the last frame's is not shown for it."""
        t = _series("t_s", t_s)
        n = t.size
        n_over = n if overlays is None else _overlay_rows(overlays)
        if len(data) != n or len(encodings) != n or n_over != n:
            raise ValueError(
                f"t_s, data, encodings and overlays must be as long: {n}, {len(data)}, "
                f"{len(encodings)}, {n_over}"
            )
        if not np.isfinite(t).all():
            raise ValueError("t_s must be finite")
        media = []
        for d, e in zip(data, encodings, strict=True):
            if d is not None and not isinstance(d, bytes | bytearray | memoryview):
                raise TypeError(f"data must be bytes or None, got {type(d).__name__}")
            m = _MEDIA_TYPES.get(str(e).lower())
            if m is None:
                raise ValueError(f"encoding must be jpeg or png, got {e!r}")
            media.append(m)
        first = self._frame_index if first_index is None else int(first_index)
        self._frame_index = first + n
        if n == 0:
            return
        shown = np.array([d is not None for d in data], dtype=bool)
        rows = np.flatnonzero(shown)
        images = [d for d in data if d is not None]
        self._send_rows(
            "/camera/image",
            t,
            first,
            rows,
            rr.EncodedImage.columns(
                blob=_blob_array(images), media_type=[media[i] for i in rows.tolist()]
            ),
        )
        blank = np.flatnonzero(~shown)
        self._send_rows(
            "/camera/image",
            t,
            first,
            blank,
            rr.Clear.columns(is_recursive=[False] * blank.size),
        )
        if overlays is not None:
            columns = (
                overlays
                if isinstance(overlays, OverlayColumns)
                else OverlayColumns.from_overlays(overlays)
            )
            self._send_overlays(t, first, columns)

    def log_frame_overlays(
        self, t_s: ArrayLike, overlays: OverlayColumns, *, first_index: int
    ) -> None:
        """The overlays of frames logged by :meth:`log_frames` without them (the frames
        from ``first_index`` on, at ``t_s``), as :meth:`log_frames` would have logged them
        with the frames: the same rows, in as many calls as there are entities."""
        t = _series("t_s", t_s)
        if _overlay_rows(overlays) != t.size:
            raise ValueError(
                f"t_s and overlays must be as long: {t.size}, {_overlay_rows(overlays)}"
            )
        if not np.isfinite(t).all():
            raise ValueError("t_s must be finite")
        if t.size:
            self._send_overlays(t, int(first_index), overlays)

    def _send_rows(
        self, entity: str, t: FloatArray, first: int, rows: NDArray[np.intp], columns: Any
    ) -> None:
        """``columns`` at the frames ``rows`` of those at times ``t`` from ``first`` on."""
        if rows.size == 0:
            return
        t_ns = np.round(t[rows] * 1e9).astype(np.int64)
        self.recording.send_columns(
            entity,
            indexes=[
                rr.TimeColumn("time", duration=t_ns.astype("timedelta64[ns]")),
                rr.TimeColumn("frame", sequence=first + rows.astype(np.int64)),
            ],
            columns=columns,
            strict=True,
        )

    def _send_overlays(self, t: FloatArray, first: int, o: OverlayColumns) -> None:
        """The overlays ``o`` of the frames at times ``t`` from ``first`` on: each entity
        drawn where it has points and cleared where it has none, each in one call."""
        for name, (colour, radius, order) in _OVERLAY_STYLE.items():
            counts = o.counts[name]
            drawn = np.flatnonzero(counts > 0)
            k = drawn.size
            if k:
                style = {"colors": [colour] * k, "radii": [radius] * k, "draw_order": [order] * k}
                columns: list[Any]
                if name in _OVERLAY_LINES:
                    strips = _strips_array(o.points[name], counts[drawn])
                    columns = list(rr.LineStrips2D.columns(strips=strips, **style))
                else:
                    columns = [
                        *rr.Points2D.columns(positions=o.points[name]).partition(counts[drawn]),
                        *rr.Points2D.columns(**style),
                    ]
                self._send_rows(f"/camera/image/{name}", t, first, drawn, columns)
            cleared = np.flatnonzero(o.given & (counts == 0))
            self._send_rows(
                f"/camera/image/{name}",
                t,
                first,
                cleared,
                rr.Clear.columns(is_recursive=[False] * cleared.size),
            )
        failed = np.flatnonzero(o.given & o.failed)
        texts = [
            f"frame at {t[i]:.3f} s: {o.reasons[i] or 'no measurement'}" for i in failed.tolist()
        ]
        self._send_rows(
            "/events/frames",
            t,
            first,
            failed,
            rr.TextLog.columns(text=texts, level=["WARN"] * len(texts)),
        )

    def _log_overlays(self, o: FrameOverlay, t_s: float) -> None:
        # No labels on the lines (they piled up at the beam's middle): the summary document
        # carries the colour key. The simulated beam is a thin line with a dot at each
        # station, under the measured centre line; the difference between the two, magnified,
        # is its own line, so what the comparison is about can be seen.
        sim = _points("sim_beam_px", o.sim_beam_px)
        lines = {
            "hub_line": (_points("hub_line_px", o.hub_line_px, 2), COLOUR_HUB, 3.0, 1.0),
            "rigid_line": (_points("rigid_line_px", o.rigid_line_px, 2), COLOUR_RIGID, 1.5, 2.0),
            "sim_beam": (sim, COLOUR_SIM, 1.0, 3.0),
            "difference": (_points("difference_px", o.difference_px), COLOUR_DIFFERENCE, 1.5, 4.0),
            "centreline": (_points("centreline_px", o.centreline_px), COLOUR_CENTRELINE, 2.0, 5.0),
        }
        rec = self.recording
        for name, (pts, colour, radius, order) in lines.items():
            entity = f"/camera/image/{name}"
            if pts is None or pts.shape[0] < 2:
                rec.log(entity, rr.Clear(recursive=False), strict=True)
            else:
                rec.log(
                    entity,
                    rr.LineStrips2D([pts], colors=[colour], radii=[radius], draw_order=order),
                    strict=True,
                )
        entity = "/camera/image/sim_stations"
        if sim is None or sim.shape[0] < 2:
            rec.log(entity, rr.Clear(recursive=False), strict=True)
        else:
            rec.log(
                entity,
                rr.Points2D(sim, colors=[COLOUR_SIM], radii=[4.0], draw_order=3.5),
                strict=True,
            )
        entity = "/camera/image/tip"
        if o.tip_px is None:
            rec.log(entity, rr.Clear(recursive=False), strict=True)
        else:
            tip = np.asarray(o.tip_px, dtype=np.float64)
            if tip.shape != (2,):
                raise ValueError(f"overlays.tip_px must have shape (2,), got {tip.shape}")
            rec.log(
                entity,
                rr.Points2D([tip], colors=[COLOUR_TIP], radii=[8.0], draw_order=6.0),
                strict=True,
            )
        if not o.ok:
            rec.log(
                "/events/frames",
                rr.TextLog(f"frame at {t_s:.3f} s: {o.reason or 'no measurement'}", level="WARN"),
                strict=True,
            )

    def log_tip_deflection(
        self,
        frame_t_s: ArrayLike,
        tip_lateral_image_m: ArrayLike,
        t_s: ArrayLike,
        tip_lateral_strain_m: ArrayLike,
        sim_tip_lateral_m: ArrayLike | None = None,
    ) -> None:
        """Lateral tip deflection from images (points), strains and simulation (lines).

        Parameters
        ----------
        frame_t_s : (F,) frame times [s]; tip_lateral_image_m : (F,) [m], NaN = no value.
        t_s : (N,) sample times [s]; tip_lateral_strain_m : (N,) [m].
        sim_tip_lateral_m : (N,) [m] or None (already logged by :meth:`log_sim`).
        """
        ft = _series("frame_t_s", frame_t_s)
        image = _series("tip_lateral_image_m", tip_lateral_image_m, ft.size)
        t = _series("t_s", t_s)
        strain = _series("tip_lateral_strain_m", tip_lateral_strain_m, t.size)
        self._send_points_series(
            "/tip_lateral/image", ft, MM_PER_M * image, "image", COLOUR_MEASURED
        )
        self._send_scalars(
            "/tip_lateral/strain", t, MM_PER_M * strain, "from strains", COLOUR_STRAIN
        )
        if sim_tip_lateral_m is not None:
            sim = _series("sim_tip_lateral_m", sim_tip_lateral_m, t.size)
            self._send_scalars("/sim/tip_lateral", t, MM_PER_M * sim, "simulated", COLOUR_SIM)

    def log_residuals(
        self,
        t_s: ArrayLike,
        strain_residual: ArrayLike,
        frame_t_s: ArrayLike,
        tip_image_minus_sim_m: ArrayLike,
        tip_strain_minus_sim_m: ArrayLike,
    ) -> None:
        """What the comparison is about: measured minus simulated, under each pair.

        Parameters
        ----------
        t_s : (N,) sample times [s]; strain_residual : (N, G) measured - simulated strain
            [m/m]; tip_strain_minus_sim_m : (N,) strain-based - simulated tip [m].
        frame_t_s : (F,) frame times [s]; tip_image_minus_sim_m : (F,) image - simulated
            tip [m]. NaN = nothing to compare (before the simulation settles, failed frames).
        """
        t = _series("t_s", t_s)
        eps = np.asarray(strain_residual, dtype=np.float64)
        if eps.ndim != 2 or eps.shape[0] != t.size:
            raise ValueError(f"strain_residual must have shape ({t.size}, G), got {eps.shape}")
        ft = _series("frame_t_s", frame_t_s)
        image = _series("tip_image_minus_sim_m", tip_image_minus_sim_m, ft.size)
        strain_tip = _series("tip_strain_minus_sim_m", tip_strain_minus_sim_m, t.size)
        for j in range(eps.shape[1]):
            self._send_scalars(
                gauge_entity("/residual/strain", j),
                t,
                MICROSTRAIN * eps[:, j],
                f"g{j + 1} measured - sim",
                COLOUR_RESIDUAL,
            )
        self._send_points_series(
            "/residual/tip_lateral/image_minus_sim",
            ft,
            MM_PER_M * image,
            "image - sim",
            COLOUR_MEASURED,
        )
        self._send_scalars(
            "/residual/tip_lateral/strain_minus_sim",
            t,
            MM_PER_M * strain_tip,
            "strains - sim",
            COLOUR_STRAIN,
        )

    def log_fig11(
        self,
        hub_angle_rad: ArrayLike,
        tip_lateral_m: ArrayLike,
        sim_hub_angle_rad: ArrayLike,
        sim_tip_lateral_m: ArrayLike,
    ) -> tuple[float, float, float, float] | None:
        """The paper's Fig. 11: lateral tip deflection against hub angle (static).

        Drawn in a 2D view in degrees (x) and millimetres (up = +lateral, so the 2D
        view's y is -mm): measured points over the simulated loop, with axes at the edges
        of the data and numbered ticks (a 2D view has no axes of its own).

        Parameters
        ----------
        hub_angle_rad, tip_lateral_m : (F,) measured points; NaN pairs are skipped.
        sim_hub_angle_rad, sim_tip_lateral_m : (M,) simulated loop, in time order.

        Returns
        -------
        (x_min, x_max, y_min, y_max) of the figure in view units, with room for the tick
        numbers (what :func:`pipelines.review.layout.build_blueprint` takes as
        ``fig11_bounds``), or None when there is nothing to draw.
        """
        a = _series("hub_angle_rad", hub_angle_rad)
        w = _series("tip_lateral_m", tip_lateral_m, a.size)
        sa = _series("sim_hub_angle_rad", sim_hub_angle_rad)
        sw = _series("sim_tip_lateral_m", sim_tip_lateral_m, sa.size)
        rec = self.recording
        keep = np.isfinite(a) & np.isfinite(w)
        measured = np.column_stack([DEG_PER_RAD * a[keep], -MM_PER_M * w[keep]])
        rec.log(
            "/fig11/measured",
            rr.Points2D(measured, colors=[COLOUR_MEASURED], radii=[0.6], draw_order=3.0),
            static=True,
            strict=True,
        )
        keep = np.isfinite(sa) & np.isfinite(sw)
        loop = np.column_stack([DEG_PER_RAD * sa[keep], -MM_PER_M * sw[keep]])
        if loop.shape[0] >= 2:
            rec.log(
                "/fig11/sim",
                rr.LineStrips2D([loop], colors=[COLOUR_SIM], radii=[0.15], draw_order=2.0),
                static=True,
                strict=True,
            )
        extent = np.vstack([measured, loop]) if loop.size else measured
        if not extent.size:
            return None
        axes = fig11_axes(extent.min(axis=0), extent.max(axis=0))
        rec.log(
            "/fig11/axes",
            rr.LineStrips2D(axes.lines, colors=[COLOUR_AXES], radii=[0.05], draw_order=1.0),
            static=True,
            strict=True,
        )
        rec.log(
            "/fig11/ticks",
            rr.Points2D(
                axes.tick_positions,
                labels=axes.tick_labels,
                colors=[COLOUR_AXES],
                radii=[0.1],
                show_labels=True,
            ),
            static=True,
            strict=True,
        )
        return axes.bounds

    def log_fig11_marker(
        self, frame_t_s: ArrayLike, hub_angle_rad: ArrayLike, tip_lateral_m: ArrayLike
    ) -> None:
        """Where the run is on Fig. 11 at each frame time: one point that moves along the
        loop as the time line plays (frames without a value are skipped).

        Parameters
        ----------
        frame_t_s : (F,) frame times [s]; hub_angle_rad, tip_lateral_m : (F,).
        """
        ft = _series("frame_t_s", frame_t_s)
        a = _series("hub_angle_rad", hub_angle_rad, ft.size)
        w = _series("tip_lateral_m", tip_lateral_m, ft.size)
        keep = np.isfinite(ft) & np.isfinite(a) & np.isfinite(w)
        self._style("/fig11/now", rr.Points2D.from_fields(colors=[COLOUR_TIP], radii=[1.2]))
        if not keep.any():
            return
        points = np.column_stack([DEG_PER_RAD * a[keep], -MM_PER_M * w[keep]])
        self.recording.send_columns(
            "/fig11/now",
            indexes=[_time_column(ft[keep])],
            columns=rr.Points2D.columns(positions=points).partition(
                np.ones(points.shape[0], dtype=np.int64)
            ),
            strict=True,
        )

    def log_events(self, events: Iterable[EventLike], *, t0_ns: int = 0) -> None:
        """Run events (start, stop, overruns, drops, clipping, errors) as a text log.

        Parameters
        ----------
        events : objects with ``t_ns`` (int, run clock), ``level`` (foxglove.Log number
            or name), ``name`` and ``message``.
        t0_ns : subtracted from ``t_ns`` (the run start, when times are since start).
        """
        evs: Sequence[EventLike] = list(events)
        if not evs:
            return
        t_ns = np.array([int(e.t_ns) - int(t0_ns) for e in evs], dtype=np.int64)
        levels = [_level(e.level) for e in evs]
        texts = [f"{e.name}: {e.message}" if e.message else str(e.name) for e in evs]
        self.recording.send_columns(
            "/events",
            indexes=[rr.TimeColumn("time", duration=t_ns.astype("timedelta64[ns]"))],
            columns=rr.TextLog.columns(text=texts, level=levels),
            strict=True,
        )

    def log_summary(self, markdown: str) -> None:
        """A markdown document shown beside the event log (static)."""
        if not isinstance(markdown, str):
            raise TypeError(f"markdown must be a str, got {type(markdown).__name__}")
        self.recording.log(
            "/summary",
            rr.TextDocument(markdown, media_type=rr.MediaType.MARKDOWN),
            static=True,
            strict=True,
        )

    def log_results(self, ds: xr.Dataset, *, summary_note: str = "") -> None:
        """Everything a results Dataset holds (see ``pipelines.results.schema``), the residuals
        and Fig. 11 with its marker, and the error summary with the colour key as a markdown
        document (all computed by :func:`pipelines.review.display.run_view`), with
        ``summary_note`` (how the frames are shown) as its last paragraph."""
        view = run_view(ds)
        self.log_samples(view.t_s, view.rocker_angle_rad, view.strain)
        self.log_sim(view.t_s, view.sim_tip_lateral_m, view.sim_strain)
        self.log_tip_deflection(
            view.frame_t_s, view.tip_lateral_image_m, view.t_s, view.tip_lateral_strain_m
        )
        self.log_residuals(
            view.t_s,
            view.strain_residual,
            view.frame_t_s,
            view.tip_image_minus_sim_m,
            view.tip_strain_minus_sim_m,
        )
        bounds = self.log_fig11(*view.fig11)
        self.log_fig11_marker(view.frame_t_s, view.hub_at_frames_rad, view.tip_lateral_image_m)
        if bounds is not None:
            self.recording.send_blueprint(build_blueprint("processed", fig11_bounds=bounds))
        note = f"\n\n{summary_note}" if summary_note else ""
        self.log_summary(view.summary_markdown + note)


def _level(level: Any) -> str:
    if isinstance(level, str):
        key: Any = level.strip().lower()
    else:
        try:
            key = int(level)
        except (TypeError, ValueError):
            key = str(level).lower()
    return _LEVELS.get(key, "INFO")


def open_viewer(
    app_id: str,
    *,
    rrd_path: str | os.PathLike[str] | None = None,
    spawn: bool = False,
    connect_url: str | None = None,
    layout: str = "processed",
) -> RunViewer:
    """Open a recording to exactly one destination, with the beambench blueprint.

    Parameters
    ----------
    app_id : Rerun application id (e.g. "beambench").
    rrd_path : save to this ``.rrd`` file (written beside it under a temporary name and
        renamed on :meth:`RunViewer.close`).
    spawn : start a Rerun viewer and stream to it.
    connect_url : stream to a running viewer, e.g. ``rerun+http://127.0.0.1:9876/proxy``.
    layout : ``"processed"`` (a processed run), ``"raw"`` (a log replayed as recorded) or
        ``"live"`` (a capture as it is recorded).

    Raises
    ------
    ValueError
        Not exactly one destination, or the ``.rrd`` folder does not exist.
    """
    chosen = [rrd_path is not None, bool(spawn), connect_url is not None]
    if sum(chosen) != 1:
        raise ValueError(
            f"give exactly one destination: rrd_path, spawn=True or connect_url (got {sum(chosen)})"
        )
    if connect_url is not None and not str(connect_url).startswith(_URL_SCHEMES):
        # Checked here, before a recording exists: rerun would refuse it too, but only
        # after buffering data that it then complains about dropping.
        raise ValueError(
            f"connect_url must start with one of {', '.join(_URL_SCHEMES)}, got {connect_url!r}"
        )
    if layout not in LAYOUTS:
        raise ValueError(f"layout must be one of {', '.join(LAYOUTS)}, got {layout!r}")
    rec = rr.RecordingStream(app_id, recording_id=uuid.uuid4())
    blueprint = build_blueprint(layout)
    if rrd_path is not None:
        out = Path(rrd_path)
        if out.is_dir():
            raise ValueError(f"rrd_path {out} is a folder, expected a .rrd file path")
        if not out.parent.is_dir():
            raise ValueError(f"rrd_path {out}: folder {out.parent} does not exist")
        tmp = temp_path_beside(out)
        rec.save(tmp, default_blueprint=blueprint)
        return RunViewer(rec, rrd_path=out, tmp_path=tmp)
    if spawn:
        rec.spawn(default_blueprint=blueprint)
    else:
        rec.connect_grpc(connect_url, default_blueprint=blueprint)
    return RunViewer(rec)


__all__ = [
    "OVERLAY_ENTITIES",
    "EventLike",
    "FrameOverlay",
    "OverlayColumns",
    "RrdEntity",
    "RunViewer",
    "build_blueprint",
    "open_viewer",
    "rrd_entities",
]


# Free space under which a file sink that stopped is taken to have met a full disk.
FULL_DISK_BYTES = 1 << 20


def _sink_failure(exc: RuntimeError, tmp_path: Path | None) -> BaseException:
    """Why Rerun's file writer stopped. Its error says only that the writer thread shut
    down (the cause went to Rerun's own log, which is off: pipelines.review sets
    ``RUST_LOG``); a disk with (almost) nothing left says the rest."""
    import errno

    if tmp_path is not None:
        try:
            st = os.statvfs(tmp_path.parent)
        except OSError:
            return exc
        if st.f_bavail * st.f_frsize < FULL_DISK_BYTES:
            return OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(tmp_path))
    return exc
