"""Decode only what the measurement reads: a run's JPEG frames measured from their parts.

:class:`RegionReader` measures encoded frames with a :class:`~vision.measure.Measurer`
(default method) while decoding, of a JPEG with restart markers (gray, or YCbCr colour
as a colour camera's driver writes it: :mod:`vision.jpeg_regions`), only the segments
the measurement reads (what it reads is found in 8 x 8 blocks, a segment being
``interval`` MCUs of one block gray, of up to 2 x 2 blocks colour):

1. the segments under the measurement's own two search circles about the pivot
   (:func:`vision.locate.search_circles`, a few % of a frame), where
   :func:`vision.locate.crossings` finds the beam as the measurement will;
2. the band the rough location follows from those two crossings (+-5 beam widths about
   their chord, outward past the tip and inward over the hub), widened by the reach of
   the edge scans; how far the band runs behind the pivot comes from the previous
   frame's hub (the track), the whole beam length without one, and a previous frame
   that was smeared (the track too) widens the band by the smeared scans' reach. With
   the previous frame's geometry (the next frame of a run measured from its parts),
   the band is instead the region the check asked of that frame (4.), turned about the
   pivot as the chord through the crossings turned and widened by the motion between
   frames, unless the crossings lie off that turned centre line (the beam bent
   otherwise): ~0.07 Mpx less of a 3 Mpx frame of the bench's run;
3. the measurement, on a full-size image whose other pixels are one gray level (the
   median of the circles: a constant holds no strip, so a part not decoded cannot look
   like beam or hub);
4. the check: the region the measurement read, from its result (the band to the hub's
   back end and past the tip, the edge scans about the hub and the beam, the tip's and
   the clamp's face searches), must lie in what was decoded; a miss decodes the rest of
   that region and measures again, once. Outward of the crossings the rough location
   reads cross-profiles a step (2.5 beam widths) apart, at places the crossings fix:
   where the band was predicted from the track, the check takes those profiles' pixels
   (a fifth or so of their band's segments on the bench's camera), not the band.

A frame refused on its parts, a check missed twice, or crossings not found (a frame
without a beam, a beam that jumped out of the previous frame's band) is decoded whole and
measured as before (the track is then lost, and found again on the next frame that
measures); so is every JPEG without restart markers or with damaged ones, every PNG,
and every frame of the paper's method, which rectifies the whole frame. The
measurement on the parts equals the one on the full frame wherever it reads only what
was decoded, which the check makes so.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import cv2
import numpy as np
from numpy.typing import NDArray

from vision.codec import decode
from vision.frame_measurement import FrameMeasurement
from vision.jit import kernel
from vision.jpeg_regions import (
    JpegLayout,
    decode_into,
    fill_segments,
    image_of,
    jpeg_layout,
    segments_of_blocks,
)
from vision.locate import (
    SearchCircles,
    _offset_grid,  # the follow's own profile points: the check marks exactly those
    crossings,
    follow_half_width,
    outward_width,
    search_circles,
    working_width,
)
from vision.measure import Measurer

_BLOCK_PX = 8
_BLOCK_BITS = 3  # 2**3 = _BLOCK_PX
#: Reach of the edge scans beyond a strip's half width (px): the scan's margin, the
#: widest window and the slant of a scan line across the strip (up to sqrt 2), rounded up.
_SCAN_REACH_PX = 40.0
#: The rough location's cross-profiles reach ``follow_half_width`` either side of the
#: chord through the two crossings; its steps outward and inward, in beam widths.
_STEP_OUT_WIDTHS = 2.5
_STEP_IN_WIDTHS = 1.4
#: Extra room behind the previous frame's hub (m): the hub's back end moves with the
#: hub's angle along the chord only through the angle between the hub and the chord.
_TRACK_SLACK_M = 0.05
#: Without a track, the band is first decoded this far behind the pivot (m); a hub that
#: reaches farther is found cut short by the check, which then decodes the rest.
_HUB_BACK_M = 0.3
#: How far (beam widths) the beam's and the hub's centre lines are allowed for off the
#: chord through the crossings in the first decode (farther: the check decodes the rest).
_OFF_CHORD_WIDTHS = 2.0
#: Behind the pivot the hub's axis leaves the chord at up to this angle (rad; the
#: beam's slope at its root against the chord: up to ~10 degrees on the fast set, under
#: 5 on the others): the band there is a fan of three, the chord's and this either side.
_HUB_FAN_RAD = math.radians(12.0)
#: With a track of the last frame's geometry, the band is what the check asked of that
#: frame, turned about the pivot as the chord through the crossings turned, and widened
#: by this much (m): beyond the rotation, a bending beam's centre line, hub and tip
#: moved up to 9 mm between frames of the bench's 60 s run (15 frames/s: none of its
#: 900 frames regrew at 10 mm, 375 did at 5 mm); the rest the check finds and the
#: reader decodes.
_TRACK_MARGIN_M = 0.015
#: The turned track is used only when the crossings lie this close to its centre line
#: (m; up to 4 mm on that run): farther, the beam changed shape (or the frame is not the
#: next of the same view) and the band is predicted from the crossings alone.
_TRACK_GATE_M = 0.01


@dataclass
class RegionStats:
    """What a :class:`RegionReader` did: frames measured from parts / whole, and the
    fraction of the segments decoded for those measured from parts."""

    parts: int = 0
    whole: int = 0
    regrown: int = 0
    #: frames whose band was predicted from the last frame's geometry (the track)
    tracked: int = 0
    decoded_fraction: list[float] = field(default_factory=list)


class _Shape(NamedTuple):
    """The track's geometry: what the check asked of the last frame measured from its
    parts (plane, m), and the direction of that frame's chord through its crossings."""

    angle: float  # rad, of the chord from the inner crossing to the outer
    line: NDArray[np.float64]  # (K, 2) the beam's centre line
    back: NDArray[np.float64]  # the hub's back end and the clamp, on its axis
    clamp: NDArray[np.float64]
    tip: NDArray[np.float64]
    hub_w: float  # the hub's search width
    beam_w: float  # the beam's measured width (NaN: none)
    smeared: bool


class RegionReader:
    """Decode-and-measure of a run's frames in order, decoding JPEGs in parts where it
    can (see the module's notes); the results are the measurer's on the full frames."""

    def __init__(self, measurer: Measurer, *, parts: bool = True) -> None:
        if not isinstance(measurer, Measurer):
            raise TypeError(f"measurer must be a Measurer, got {type(measurer).__name__}")
        self.measurer = measurer
        #: False: every frame decoded whole (the comparison in ``bench process``)
        self.parts = bool(parts)
        cal = measurer.calibration
        self._length = cal.beam_length_m
        self._circles: SearchCircles = search_circles(
            cal.to_px, cal.beam_length_m, cal.beam_width_m, measurer.px_m
        )
        self._ring_segs: dict[tuple[int, ...], NDArray[np.intp]] = {}
        #: The last frame's canvas, the level it was blanked to and its segments decoded.
        self._canvas: NDArray[np.uint8] | None = None
        self._canvas_level = 0
        self._canvas_done = np.zeros(0, dtype=bool)
        #: The track: how far behind the pivot the previous frame's hub reached (m).
        self.hub_back_m: float | None = None
        self.hub_w_m = math.nan
        #: The track: how much farther than the edge scans the previous frame's smeared
        #: edges were read (m; 0 when it was not smeared).
        self.smear_m = 0.0
        #: The track: the last frame's geometry, when it was measured from its parts.
        self._shape: _Shape | None = None
        self.stats = RegionStats()

    # -- entry point ------------------------------------------------------------------
    def measure(self, data: bytes) -> FrameMeasurement:
        """Decode and measure one encoded frame; a frame that does not decode gives
        ``ok=False`` with the decoder's reason, as a full decode does."""
        layout = jpeg_layout(data) if self.parts and self.measurer.method == "default" else None
        if layout is not None:
            got = self._measure_parts(layout)
            if got is not None:
                m, angle = got
                self.stats.parts += 1
                self._keep_track(m, angle)
                return m
        self.stats.whole += 1
        try:
            image = decode(data)
        except ValueError as exc:
            self.lose_track()
            return FrameMeasurement(ok=False, reason=f"cannot decode frame: {exc}")
        m = self.measurer.measure(image)
        self._keep_track(m)
        return m

    # -- the parts --------------------------------------------------------------------
    def _measure_parts(self, layout: JpegLayout) -> tuple[FrameMeasurement, float] | None:
        # the masks below are of 8 x 8 blocks (what the measurement reads is found to
        # the block); a segment is ``seg_cols`` of them across (and an MCU's block rows
        # down: one gray, two of a colour JPEG whose Y is sampled twice vertically)
        shape = layout.blocks_shape
        seg_cols = layout.segment_px[0] // _BLOCK_PX
        seg_rows = layout.segment_px[1] // _BLOCK_PX
        ring_segs = self._ring_segments(layout)
        if ring_segs.size == 0:  # the circles miss the image: the measurement says why
            return None
        # The circles' segments decoded straight into this frame's canvas (the last
        # frame's, used again: see _take_canvas)
        canvas, old_done, old_level = self._take_canvas(layout)
        try:
            decode_into(layout, canvas, ring_segs)
        except ValueError:
            return None
        # The background's level: the circles' median sample (the beam covers a few % of
        # them; every 2nd row and 4th column of their segments one under another, read
        # in place); what is not decoded is that constant.
        level = int(
            _median_of_segments(canvas, layout.per_row, ring_segs, *layout.segment_px[::-1], 2, 4)
        )
        # what the last frame left that may not hold ``level`` (None: nothing)
        stale = old_done if level == old_level else np.ones_like(old_done)
        # What was decoded, by segment (whole segments are decoded, the circles' first:
        # none of them again where the band overlaps them).
        done = np.zeros(layout.per_row * layout.mcu_rows, dtype=bool)
        done[ring_segs] = True
        # the crossings read the circles' pixels alone (the bilinear samples' four), all
        # decoded: what the last frame left elsewhere is blanked after the band's decode
        image = image_of(layout, canvas)
        found = crossings(image, self._circles)
        if found is None:
            return None
        p1, p2, shown = found
        w0 = outward_width(shown, self.measurer.calibration.beam_width_m)
        d0 = p2 - p1
        angle = math.atan2(float(d0[1]), float(d0[0]))
        want = self._tracked(p1, p2, angle, w0, shape)
        tracked = want is not None
        if want is None:
            want = self._predicted(p1, p2, w0, shape)
        else:
            self.stats.tracked += 1
        for attempt in range(2):
            new = _missing_segments(want, done, seg_cols, seg_rows)
            if new.size:
                done[new] = True
                try:
                    decode_into(layout, canvas, new)
                except ValueError:
                    return None
                self.stats.regrown += attempt
            if attempt == 0:
                self._blank_stale(layout, canvas, stale, done, level)
            # the crossings read the circles' blocks only, decoded first: as found
            m = self.measurer.measure(image_of(layout, canvas), crossings_m=found)
            if not m.ok:
                return None
            # (the outward profiles one by one where the band was predicted from the
            # track; else the whole band they lie in, which that prediction covers)
            read = self._read(m, p1, p2, w0, shape, profiles=tracked)
            if _missing_segments(read, done, seg_cols, seg_rows).size == 0:
                self.stats.decoded_fraction.append(float(done.mean()))
                return m, angle
            # Read beyond what was decoded: decode that, and the band's whole reach
            # behind the pivot (a hub cut short by what was not decoded reads farther
            # once it is decoded), and measure again.
            want = read | self._predicted(p1, p2, w0, shape, behind_m=self._length)
        return None

    def _take_canvas(self, layout: JpegLayout) -> tuple[NDArray[np.uint8], NDArray[np.bool_], int]:
        """The canvas for this frame, the segments of it the last frame decoded and the
        level it was blanked to: the last frame's canvas used again (its segments
        decoded this frame, the rest blanked by :meth:`_blank_stale` once this frame's
        own segments are decoded: a new canvas costs ~0.1 ms of a ~1.5 ms decode,
        blanking the last frame's band anew where this one decodes it again is wasted),
        or a new one of no content (every segment to be blanked, at level -1)."""
        n_seg = layout.per_row * layout.mcu_rows
        seg_w, seg_h = layout.segment_px
        shape = (layout.mcu_rows * seg_h, layout.per_row * seg_w)
        canvas, old = self._canvas, self._canvas_done
        self._canvas = None  # until blanked: a frame given up half way leaves it stale
        if canvas is None or old.size != n_seg or canvas.shape != shape:
            return np.empty(shape, dtype=np.uint8), np.ones(n_seg, dtype=bool), -1
        return canvas, old, self._canvas_level

    def _blank_stale(
        self,
        layout: JpegLayout,
        canvas: NDArray[np.uint8],
        stale: NDArray[np.bool_],
        done: NDArray[np.bool_],
        level: int,
    ) -> None:
        """Set what the last frame left and this one did not decode to ``level``; the
        canvas is then this frame's: ``level`` wherever not ``done`` (which a regrow
        adds to in place)."""
        fill_segments(layout, canvas, stale & ~done, level)
        self._canvas, self._canvas_level, self._canvas_done = canvas, level, done

    def lose_track(self) -> None:
        """Forget the previous frame: the next is searched as the first of a run (a frame
        that is not the next of the same view, e.g. a set of independent poses)."""
        self.hub_back_m = None
        self.hub_w_m = math.nan
        self.smear_m = 0.0
        self._shape = None

    def _keep_track(self, m: FrameMeasurement, angle: float | None = None) -> None:
        """Keep what the next frame's band is predicted from; ``angle``: the chord's
        direction, of a frame measured from its parts (None: no shape kept)."""
        if not m.ok:
            self.lose_track()
            return
        smeared = self._smeared(m)
        self.smear_m = self._smear_reach_m() if smeared else 0.0
        ends = self.measurer.calibration.to_plane(m.hub_line_px)
        back, clamp = ends[0], ends[1]
        hub_w = m.hub_search_width_m
        ok = np.all(np.isfinite(back)) and math.isfinite(hub_w)
        self.hub_back_m = float(np.hypot(*back)) if ok else None
        self.hub_w_m = float(hub_w) if ok else math.nan
        self._shape = None
        if angle is not None and ok:  # (the rest checked where used: _tracked)
            self._shape = _Shape(
                angle,
                m.centreline_plane_m,
                back,
                clamp,
                m.tip_plane_m,
                float(hub_w),
                m.beam_width_m,
                smeared,
            )

    # -- regions ----------------------------------------------------------------------
    def _ring_segments(self, layout: JpegLayout) -> NDArray[np.intp]:
        """The segments under the search circles (the bilinear samples' four pixels)."""
        key = (layout.width_px, layout.height_px, layout.interval, *layout.segment_px)
        got = self._ring_segs.get(key)
        if got is None:
            shape = layout.blocks_shape
            blocks = np.zeros(shape, dtype=bool)
            for px in self._circles.px:
                ok = np.all(np.isfinite(px), axis=1)
                for dx in (0, 1):
                    for dy in (0, 1):
                        bx = np.floor(px[ok, 0]).astype(np.intp) + dx
                        by = np.floor(px[ok, 1]).astype(np.intp) + dy
                        inside = (bx >= 0) & (by >= 0) & (bx < layout.width_px)
                        inside &= by < layout.height_px
                        blocks[by[inside] // _BLOCK_PX, bx[inside] // _BLOCK_PX] = True
            got = segments_of_blocks(layout, blocks)
            got.flags.writeable = False
            self._ring_segs[key] = got
        return got

    def _tracked(
        self,
        p1: NDArray[np.float64],
        p2: NDArray[np.float64],
        angle: float,
        w: float,
        shape: tuple[int, int],
    ) -> NDArray[np.bool_] | None:
        """The blocks the measurement should read, from the track: the region the check
        asked of the last frame (:meth:`_read`'s tubes), its geometry turned about the
        pivot by the turn of the chord through the crossings, about this frame's
        crossings, every tube widened by :data:`_TRACK_MARGIN_M`. None without a track,
        or when the crossings lie off the turned centre line by more than
        :data:`_TRACK_GATE_M` (the beam bent otherwise, or jumped)."""
        track = self._shape
        if (
            track is None
            or len(track.line) < 2
            or not np.all(np.isfinite(track.line))
            or not np.all(np.isfinite(track.clamp))
            or not np.all(np.isfinite(track.tip))
        ):
            return None
        turn = angle - track.angle
        c, s = math.cos(turn), math.sin(turn)
        rot = np.array([[c, s], [-s, c]])  # row vectors: p @ rot turns p by ``turn``
        line = track.line @ rot
        if _off_line(np.array([p1, p2]), line) > _TRACK_GATE_M:
            return None
        tubes = self._read_tubes(
            p1,
            p2,
            w,
            track.back @ rot,
            track.clamp @ rot,
            track.tip @ rot,
            line,
            track.hub_w,
            track.beam_w,
            track.smeared,
            _TRACK_MARGIN_M,
        )
        return self._read_mask(p2, w, *tubes, shape, profiles=True)

    def _predicted(
        self,
        p1: NDArray[np.float64],
        p2: NDArray[np.float64],
        w: float,
        shape: tuple[int, int],
        behind_m: float | None = None,
    ) -> NDArray[np.bool_]:
        """The blocks the measurement should read, before it: the bands about the chord,
        widened by the scans' reach; behind the pivot to the previous frame's hub (the
        track), :data:`_HUB_BACK_M` without one, or ``behind_m``. ``w``: the width of
        the strip on the search circles (the beam's width in the image)."""
        d0 = (p2 - p1) / np.linalg.norm(p2 - p1)
        # the bands the check asks for, and two blocks more (the two are rasterised from
        # different points: their edges differ by a block here and there)
        half = follow_half_width(w) + (2 + 2 * _BLOCK_PX) * self.measurer.px_m
        # outward to a straight beam's tip, two steps and the tip's search beyond
        out_len = self._length + 0.05 - float(p2 @ d0) + (2 * _STEP_OUT_WIDTHS + 7) * w
        if behind_m is not None:
            behind, hub_w = behind_m, 3 * w
        elif self.hub_back_m is None:
            behind, hub_w = _HUB_BACK_M, 3 * w
        else:
            behind, hub_w = self.hub_back_m + _TRACK_SLACK_M, self.hub_w_m
        in_len = float(p1 @ d0) + behind + 3 * _STEP_IN_WIDTHS * w
        # the edge scans about the beam and the hub reach this far from their centre
        # lines; the beam's leaves the chord by up to a few widths (its bending). The
        # hub's runs through the pivot and the beam's root, the chord through the beam
        # near its root: inward of the circles the two hardly part (no room off the
        # chord: measured, none of ~750 frames of the bench's sets read past it), behind
        # the pivot the hub's angle to the chord takes it off, which the fan covers.
        reach = self._reach_m(w)
        scans = reach + _OFF_CHORD_WIDTHS * w
        half_out = max(half, 0.75 * w + scans)
        half_in = max(half, 0.75 * hub_w + reach)
        # behind the pivot (the plane's origin) along the hub's possible axes (the fan's
        # sides are those axes: no room off them)
        half_fan = half_in
        if self.smear_m > 0:
            # the previous frame was smeared (the track): so is this one, likely; its
            # scans about the beam reach that much farther, the beam's centre line
            # running from the clamp, somewhere on the inward band, to the tip
            half_out += self.smear_m
            half_in = max(half_in, 0.75 * w + scans + self.smear_m)
            half_fan = max(half_fan, 0.75 * w + reach + self.smear_m)
        fan_len = behind + 3 * _STEP_IN_WIDTHS * w
        c, s = math.cos(_HUB_FAN_RAD), math.sin(_HUB_FAN_RAD)
        fan = [np.array([[c, -s], [s, c]]) @ -d0, np.array([[c, s], [-s, c]]) @ -d0]
        return self._tubes(
            shape,
            [
                (np.array([p2, p2 + out_len * d0]), half_out),
                (np.array([p1, p1 - in_len * d0]), half_in),
                (np.array([np.zeros(2), fan_len * fan[0]]), half_fan),
                (np.array([np.zeros(2), fan_len * fan[1]]), half_fan),
            ],
        )

    def _read(
        self,
        m: FrameMeasurement,
        p1: NDArray[np.float64],
        p2: NDArray[np.float64],
        w: float,
        shape: tuple[int, int],
        profiles: bool = True,
    ) -> NDArray[np.bool_]:
        """The blocks a measurement read, from its result: the rough location's
        cross-profiles (outward past the tip, inward past the hub's back end: two steps
        beyond where each strip ended; outward, each profile's samples, or without
        ``profiles`` the band they lie in), the edge scans about the beam's and the
        hub's centre lines, the clamp's and the back face's searches (a hub width either
        side of each) and the tip's (its end face, up to four beam widths on)."""
        back, clamp = self.measurer.calibration.to_plane(m.hub_line_px)
        tubes = self._read_tubes(
            p1,
            p2,
            w,
            back,
            clamp,
            m.tip_plane_m,
            m.centreline_plane_m,
            m.hub_search_width_m,
            m.beam_width_m,
            self._smeared(m),
            0.0,
        )
        return self._read_mask(p2, w, *tubes, shape, profiles=profiles)

    def _read_mask(
        self,
        p2: NDArray[np.float64],
        w: float,
        tubes: list[tuple[NDArray[np.float64], float]],
        out_len: float,
        d0: NDArray[np.float64],
        shape: tuple[int, int],
        *,
        profiles: bool,
    ) -> NDArray[np.bool_]:
        """The blocks of :meth:`_read_tubes`' tubes and of the outward cross-profiles
        (:func:`vision.locate.locate`'s follow from the outer crossing ``p2`` along the
        chord, a strip ``w`` wide: its steps, each profile's samples) out to ``out_len``
        along the chord: each sample's bilinear pixels and a pixel more either way (the
        same points, computed here in another order, may round to the next pixel).
        Without ``profiles``, the band the profiles lie in instead (a tube, cheaper).
        ``d0``: the chord's direction."""
        px_m = self.measurer.px_m
        if not profiles:
            band = (np.array([p2, p2 + out_len * d0]), follow_half_width(w) + 2 * px_m)
            return self._tubes(shape, [band, *tubes])
        mask = self._tubes(shape, tubes)
        step = max(_STEP_OUT_WIDTHS * w, 4 * px_m)
        if out_len < step:
            return mask
        half = follow_half_width(w)
        ts = np.arange(step, out_len + step / 2, step)
        offs = np.arange(-half, half + 0.375 * px_m, 0.75 * px_m)
        n = np.array([-d0[1], d0[0]])
        pts = _offset_grid(ts, p2, d0, offs * n[0], offs * n[1])
        px = np.ascontiguousarray(self.measurer.calibration.to_px(pts), dtype=np.float64)
        _mark_points(mask.view(np.uint8), px, _BLOCK_BITS)
        return mask

    def _read_tubes(
        self,
        p1: NDArray[np.float64],
        p2: NDArray[np.float64],
        w: float,
        back: NDArray[np.float64],
        clamp: NDArray[np.float64],
        tip: NDArray[np.float64],
        line: NDArray[np.float64],
        hub_w: float,
        beam_w: float,
        smeared: bool,
        grow: float,
    ) -> tuple[list[tuple[NDArray[np.float64], float]], float, NDArray[np.float64]]:
        """:meth:`_read`'s tubes of a measurement's geometry (plane, m: the hub's back end
        and clamp, the tip, the centre line, the hub's search width, the beam's measured
        width, whether it was smeared), each ``grow`` wider and the bands that much
        longer; how far out along the chord from ``p2`` the outward cross-profiles were
        read (:meth:`_read_mask`), and the chord's direction."""
        cal = self.measurer.calibration
        px_m = self.measurer.px_m
        # ``w``: the outward band's width (the strip's on the circles, or the hint); the
        # rest used the width the beam showed, which the fitted one is within 15 % of
        # where it is not the calibration's (vision.locate.working_width).
        hint = cal.beam_width_m
        wb = w
        if math.isfinite(beam_w):
            wb = working_width(beam_w, hint)
            wb = max(w, wb if wb == hint else 1.15 * wb)
        reach = self._reach_m(wb)
        d0 = (p2 - p1) / np.linalg.norm(p2 - p1)
        hub_w = hub_w if math.isfinite(hub_w) else 3 * wb
        half_in = follow_half_width(wb) + 2 * px_m + grow
        out_end = float((tip - p2) @ d0) + 2 * max(_STEP_OUT_WIDTHS * w, 4 * px_m) + 4 * wb
        in_end = float((p1 - back) @ d0) + 2 * max(_STEP_IN_WIDTHS * wb, 4 * px_m)
        out_end, in_end = out_end + grow, in_end + grow
        # outward, the follow's cross-profiles alone (:meth:`_read_mask`): two steps
        # past the strip's end at most (the last that found it, the one that did not)
        tubes = [(np.array([p1, p1 - max(in_end, 0.0) * d0]), half_in)]
        beam_r = 0.75 * wb + reach
        if smeared:
            beam_r += self._smear_reach_m()
        tubes.append((line, beam_r + grow))
        # the tip's searches: single lines along the tangent, up to 4 widths on
        pad = 6 * self.measurer.px_m
        tip_line = np.vstack([tip, tip + 4.5 * wb * _unit(tip - line[-2])])
        tubes.append((tip_line, 0.5 * wb + pad + grow))
        e = _unit(clamp - back)
        hub_line = np.array([back - 0.5 * hub_w * e, clamp + 0.5 * hub_w * e])
        tubes.append((hub_line, 0.75 * hub_w + reach + grow))
        faces = np.array([back - hub_w * e, clamp + hub_w * e])
        tubes.append((faces, 0.5 * hub_w + pad + grow))
        return tubes, max(out_end, 0.0), d0

    def _smeared(self, m: FrameMeasurement) -> bool:
        return math.isfinite(m.blur_px) and m.blur_px > self.measurer.max_blur_px

    def _smear_reach_m(self) -> float:
        # smeared: centroid cuts reach 1.5 smears + half a width + 3 px either side
        return 1.5 * self.measurer.max_smear_px * self.measurer.px_m * 1.5

    def _reach_m(self, w: float) -> float:
        # px beyond the strip, in the plane, with room for perspective (1.5x the pivot's
        # pixel size) and a pixel of bilinear reach
        return (_SCAN_REACH_PX + 2.0) * self.measurer.px_m * 1.5

    def _tubes(
        self, shape: tuple[int, int], tubes: list[tuple[NDArray[np.float64], float]]
    ) -> NDArray[np.bool_]:
        """The blocks within ``half_m`` (plane) of polylines ``(line (K, 2) plane m,
        half_m)``, each line's ends extended by its ``half_m``, and a block more all
        round; everything when a line reaches behind the camera."""
        lines = np.concatenate([np.asarray(line, dtype=np.float64) for line, _ in tubes])
        counts = np.array([len(line) for line, _ in tubes], dtype=np.intp)
        halves = np.array([half for _, half in tubes], dtype=np.float64)
        # every tube's centre line, its ends extended, and its two sides, in one mapping
        pts, first, bounded = _tube_points(lines, counts, halves)
        if not bounded:
            return np.ones(shape, dtype=bool)
        mask = np.zeros(shape, dtype=np.uint8)
        if first.size == 0:
            return mask.view(bool)
        px_all = self.measurer.calibration.to_px(pts)
        blk, thick = _tube_pixels(px_all, first, _BLOCK_PX)
        if thick.size == 0:  # a point off to infinity: behind the camera
            return np.ones(shape, dtype=bool)
        bounds = [*first.tolist(), len(blk)]
        for i, t in enumerate(thick.tolist()):
            # a thick polyline (round ends and joins) in blocks, a block of slack all round
            line = blk[bounds[i] : bounds[i + 1]].reshape(-1, 1, 2)
            cv2.polylines(mask, [line], False, 1, t, shift=4)
        return mask.view(bool)  # 0 and 1


#: Points of one tube's centre line at most this many (a line of no finite length or a
#: width of ~0 would ask for more): beyond, the tubes are taken to cover everything.
_MAX_LINE_POINTS = 1 << 20


@kernel
def _tube_points(
    lines: NDArray[np.float64], counts: NDArray[np.intp], halves: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.intp], bool]:
    """Each tube's line (``counts[i]`` rows of ``lines``, its non-finite points dropped)
    as points ``halves[i] / 2`` apart or closer (straight in the plane is curved in the
    image; a polyline's by its arc length, as ``np.interp``), with unit tangents there
    (central differences, one-sided at the ends), its ends extended by its half width,
    and the points a half width either side:
    ``(centres, sides +, sides -)`` stacked (3 k, 2) and the index of each kept tube's
    first point (tubes of no length dropped); False when one would take more than
    :data:`_MAX_LINE_POINTS` points (not finite, or no width)."""
    n_tubes = counts.size
    # the finite points of each line, in order, and the number of points along it
    clean = np.empty((lines.shape[0], 2))
    kept = np.zeros(n_tubes, dtype=np.intp)
    dense = np.zeros(n_tubes, dtype=np.intp)
    length = np.zeros(n_tubes)
    at = 0
    for i in range(n_tubes):
        m = 0
        for j in range(at, at + counts[i]):
            if math.isfinite(lines[j, 0]) and math.isfinite(lines[j, 1]):
                clean[at + m, 0] = lines[j, 0]  # element-wise: a row assignment
                clean[at + m, 1] = lines[j, 1]  # costs seconds of compile time
                m += 1
        kept[i] = m
        if m >= 2:
            if m == 2:
                total = math.hypot(clean[at + 1, 0] - clean[at, 0], clean[at + 1, 1] - clean[at, 1])
            else:
                total = 0.0
                for j in range(at + 1, at + m):
                    total += math.hypot(
                        clean[j, 0] - clean[j - 1, 0], clean[j, 1] - clean[j - 1, 1]
                    )
            if total > 0:
                steps = total / (0.5 * halves[i])
                if not steps < _MAX_LINE_POINTS:
                    return np.zeros((0, 2)), np.zeros(0, np.intp), False
                length[i] = total
                dense[i] = max(2, int(steps) + 2)
        at += counts[i]
    k = 0
    n_kept = 0
    for i in range(n_tubes):
        k += dense[i]
        n_kept += dense[i] > 0
    out = np.empty((3 * k, 2))
    first = np.empty(n_kept, dtype=np.intp)
    t = np.empty((k, 2))
    at = 0
    o = 0
    i_kept = 0
    for i in range(n_tubes):
        n = dense[i]
        if n == 0:
            at += counts[i]
            continue
        first[i_kept] = o
        i_kept += 1
        if kept[i] == 2:  # straight: evenly spaced, the end exact
            x0, y0 = clean[at, 0], clean[at, 1]
            x1, y1 = clean[at + 1, 0], clean[at + 1, 1]
            for j in range(n):
                u = j / (n - 1)
                out[o + j, 0] = x0 + u * (x1 - x0)
                out[o + j, 1] = y0 + u * (y1 - y0)
                t[o + j, 0] = (x1 - x0) / length[i]
                t[o + j, 1] = (y1 - y0) / length[i]
            out[o + n - 1, 0] = x1
            out[o + n - 1, 1] = y1
        else:  # np.interp at np.linspace(0, length, n) of the arc length
            m = kept[i]
            s = np.empty(m)
            s[0] = 0.0
            for j in range(1, m):
                d = math.hypot(
                    clean[at + j, 0] - clean[at + j - 1, 0], clean[at + j, 1] - clean[at + j - 1, 1]
                )
                s[j] = s[j - 1] + d
            step = s[m - 1] / (n - 1)
            seg = 0
            for j in range(n):
                x = j * step if j < n - 1 else s[m - 1]
                while seg + 1 < m and s[seg + 1] <= x:
                    seg += 1
                for c in range(2):
                    y0 = clean[at + seg, c]
                    if seg == m - 1 or s[seg] == x:
                        v = y0
                    else:
                        y1 = clean[at + seg + 1, c]
                        slope = (y1 - y0) / (s[seg + 1] - s[seg])
                        v = slope * (x - s[seg]) + y0
                        if math.isnan(v):
                            v = slope * (x - s[seg + 1]) + y1
                            if math.isnan(v) and y0 == y1:
                                v = y0
                    out[o + j, c] = v
            # unit tangents: central differences, one-sided at the ends
            for j in range(n):
                lo = j - 1 if j > 0 else 0
                hi = j + 1 if j < n - 1 else n - 1
                for c in range(2):
                    d = out[o + hi, c] - out[o + lo, c]
                    t[o + j, c] = d / 2.0 if 0 < j < n - 1 else d
            for j in range(n):
                norm = max(math.hypot(t[o + j, 0], t[o + j, 1]), 1e-12)
                t[o + j, 0] /= norm
                t[o + j, 1] /= norm
        # the ends extended by the half width, then the sides
        h = halves[i]
        for c in range(2):
            out[o, c] -= h * t[o, c]
            out[o + n - 1, c] += h * t[o + n - 1, c]
        for j in range(o, o + n):
            ox = -(h * t[j, 1])
            oy = h * t[j, 0]
            out[k + j, 0] = out[j, 0] + ox
            out[k + j, 1] = out[j, 1] + oy
            out[2 * k + j, 0] = out[j, 0] - ox
            out[2 * k + j, 1] = out[j, 1] - oy
        o += n
        at += counts[i]
    return out, first, True


@kernel
def _tube_pixels(
    px: NDArray[np.float64], first: NDArray[np.intp], block_px: int
) -> tuple[NDArray[np.int32], NDArray[np.intp]]:
    """From :func:`_tube_points` in pixels: the centre lines in 1/16 blocks (rounded
    half to even, clipped to +-2**27), and each tube's thickness in blocks (twice its
    widest half width, rounded up, and 3); both empty when a point is not finite."""
    k = px.shape[0] // 3
    blk = np.empty((k, 2), dtype=np.int32)
    thick = np.empty(first.size, dtype=np.intp)
    for j in range(3 * k):
        if not (math.isfinite(px[j, 0]) and math.isfinite(px[j, 1])):
            return np.zeros((0, 2), dtype=np.int32), np.zeros(0, dtype=np.intp)
    lim = float(2**27)
    for j in range(k):
        for c in range(2):
            v = px[j, c] / block_px * 16.0
            blk[j, c] = np.int32(np.rint(min(max(v, -lim), lim)))
    for i in range(first.size):
        end = first[i + 1] if i + 1 < first.size else k
        widest = 0.0
        for j in range(first[i], end):
            a = math.hypot(px[k + j, 0] - px[j, 0], px[k + j, 1] - px[j, 1])
            b = math.hypot(px[2 * k + j, 0] - px[j, 0], px[2 * k + j, 1] - px[j, 1])
            side = max(a, b)
            widest = side if j == first[i] else max(widest, side)
        thick[i] = min(2 * math.ceil(widest / block_px) + 3, 32767)
    return blk, thick


@kernel
def _mark_points(mask: NDArray[np.uint8], px: NDArray[np.float64], bits: int) -> None:
    """Set the blocks of ``mask`` (``2**bits`` px a side) holding the pixels a bilinear
    sample at each point ``px`` (x, y) reads, and a pixel more either way: columns
    ``floor(x) - 1 .. floor(x) + 2``, rows likewise (points off the image: none of it)."""
    rows, cols = mask.shape
    side = 1 << bits
    # shifted a block so that the pixels are non-negative where a point can read the
    # image (x > -2): truncation is then the floor, a shift the division
    xmax, ymax = float(cols * side + 1), float(rows * side + 1)
    shift = float(side)
    l0 = l1 = l2 = l3 = -1
    for i in range(px.shape[0]):
        x, y = px[i, 0], px[i, 1]
        if not (x > -2.0 and y > -2.0 and x < xmax and y < ymax):
            continue  # NaN, or off the image
        ix, iy = int(x + shift), int(y + shift)
        c0 = max(((ix - 1) >> bits) - 1, 0)
        c1 = min(((ix + 2) >> bits) - 1, cols - 1)
        r0 = max(((iy - 1) >> bits) - 1, 0)
        r1 = min(((iy + 2) >> bits) - 1, rows - 1)
        if r0 == l0 and r1 == l1 and c0 == l2 and c1 == l3:
            continue  # the last point's blocks (a profile's are fractions of a pixel apart)
        l0, l1, l2, l3 = r0, r1, c0, c1
        for r in range(r0, r1 + 1):
            for c in range(c0, c1 + 1):
                mask[r, c] = 1


@kernel
def _off_line(pts: NDArray[np.float64], line: NDArray[np.float64]) -> float:
    """The largest distance of points ``pts`` (N, 2) from a polyline ``line`` (K, 2),
    K >= 2 (a segment of no length: its end point)."""
    worst = 0.0
    for i in range(pts.shape[0]):
        px, py = pts[i, 0], pts[i, 1]
        near = math.inf
        for k in range(line.shape[0] - 1):
            ax, ay = line[k, 0], line[k, 1]
            dx, dy = line[k + 1, 0] - ax, line[k + 1, 1] - ay
            rx, ry = px - ax, py - ay
            dd = dx * dx + dy * dy
            t = (rx * dx + ry * dy) / dd if dd > 0 else 0.0
            t = min(max(t, 0.0), 1.0)
            gx, gy = rx - t * dx, ry - t * dy
            near = min(near, gx * gx + gy * gy)
        worst = max(worst, math.sqrt(near))
    return worst


def _unit(v: NDArray[np.float64]) -> NDArray[np.float64]:
    n = float(math.hypot(v[0], v[1]))
    return v / n if n > 0 else np.array([1.0, 0.0])


@kernel
def _median_of_segments(
    canvas: NDArray[np.uint8],
    per_row: int,
    segments: NDArray[np.intp],
    seg_h: int,
    seg_w: int,
    step_rows: int,
    step_cols: int,
) -> float:
    """``np.median(strip[::step_rows, ::step_cols])`` of the strip of the given segments
    (``seg_h x seg_w`` px, ``per_row`` to a row of ``canvas``) one under another, each
    read in its place in the canvas (``seg_h`` a multiple of ``step_rows``, ``seg_w`` of
    ``step_cols``: each segment's samples are then its rows ``0, step_rows, ...`` and
    columns ``0, step_cols, ...``), from the samples' histogram (a partition of tens of
    thousands of values costs several times more)."""
    hist = np.zeros(256, dtype=np.int64)
    flat = canvas.ravel()
    width = np.uint64(canvas.shape[1])
    step = np.uint64(step_cols)
    for j in range(segments.size):
        r0 = segments[j] // per_row * seg_h
        c0 = np.uint64(segments[j] % per_row * seg_w)
        for r in range(r0, r0 + seg_h, step_rows):
            row = np.uint64(r) * width + c0
            for c in range(np.uint64(0), np.uint64(seg_w), step):
                hist[flat[row + c]] += 1
    return _hist_median(hist)


@kernel
def _hist_median(hist: NDArray[np.int64]) -> float:
    """The median of the values a histogram of 256 bins counts (128 of none: numpy's
    NaN-free form of an empty median, as the callers have it)."""
    n = 0
    for v in range(256):
        n += hist[v]
    # the values of rank (n - 1) // 2 and n // 2: the first whose count reaches past it
    lo = hi = 256
    cum = 0
    for v in range(256):
        cum += hist[v]
        if lo == 256 and cum > (n - 1) // 2:
            lo = v
        if cum > n // 2:
            hi = v
            break
    return 0.5 * (float(lo) + float(hi))


def _missing_segments(
    blocks: NDArray[np.bool_], done: NDArray[np.bool_], seg_cols: int, seg_rows: int
) -> NDArray[np.intp]:
    """The segments holding a True block of ``blocks`` (a [block row, block col] mask)
    and not ``done`` (a flag a segment, raster order), a segment ``seg_cols`` blocks
    across and ``seg_rows`` down (an MCU's block rows: 1 gray, 2 of a colour JPEG with Y
    sampled twice vertically, whose two rows are OR-ed first, ~10 us a frame)."""
    if seg_rows > 1:
        rows = blocks.reshape(-1, seg_rows, blocks.shape[1])
        folded = rows[:, 0].copy()
        for j in range(1, seg_rows):
            folded |= rows[:, j]
        blocks = folded
    return _missing(blocks, done, seg_cols)


@kernel
def _missing(blocks: NDArray[np.bool_], done: NDArray[np.bool_], interval: int) -> NDArray[np.intp]:
    """The segments holding a True block of ``blocks`` (C order: segment ``s`` is blocks
    ``s * interval`` to ``(s + 1) * interval`` in raster order) and not ``done``
    (``interval``: the blocks of a segment, its MCUs of a gray JPEG; a segment more
    than one block row tall is first folded to one, :func:`_missing_segments`)."""
    out = np.empty(done.size, dtype=np.intp)
    n = 0
    flat = blocks.ravel().view(np.uint8)
    k = interval
    # a segment's blocks are ``interval`` bytes in a row of the mask: one 4-byte word
    # at beambench's own interval (vision.codec.RST_INTERVAL_MCU), else byte by byte
    # with no branch (at 4 blocks, 8 times slower)
    if k == 4:
        words = flat.view(np.uint32)
        for seg in range(done.size):
            if words[seg] != 0 and not done[seg]:
                out[n] = seg
                n += 1
    else:
        ku = np.uint64(k)
        for seg in range(done.size):
            at = np.uint64(seg) * ku
            hit = False
            for c in range(ku):
                hit |= flat[at + c] != 0  # no branch per block: an OR the compiler vectorises
            if hit and not done[seg]:
                out[n] = seg
                n += 1
    return out[:n]
