"""The hub as the frames show it, beside the rig's hints: its length and width (``[hub]``,
hints only: the measurement finds the hub itself) and the pivot-to-clamp offset
(``[beam] hub_offset_m``, which the simulation uses)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from pipelines.rig import Rig
from vision import Calibration, FrameMeasurement

# The measured clamp offset disagrees with the rig's beyond this and beyond 5 of its
# standard uncertainties: the simulation's hub_offset_m is then wrong by more than the
# clamp face's position is uncertain (a face is found to ~0.05 mm on the bench's frames;
# 1 mm moves the simulated tip by 1 mm x the hub's turn, ~1.3 % of its swing).
OFFSET_TOLERANCE_M = 1e-3


def measured_hub(
    measurements: Sequence[FrameMeasurement], calibration: Calibration
) -> dict[str, float]:
    """Medians over the measured frames of the hub's length (back face to clamp face),
    width and pivot-to-clamp offset (m), with the offset's standard uncertainty (robust
    spread over the frames / sqrt(n)); empty when no frame was measured. The width is
    the median over the frames that measured it (a frame whose hub edges are no
    straight lines, e.g. a bar lying against one, does not: NaN), their count
    ``hub_width_measured_frames`` of ``hub_measured_frames`` (the width NaN for none)."""
    ok = [m for m in measurements if m.ok and np.all(np.isfinite(m.hub_line_px))]
    if not ok:
        return {}
    ends = calibration.to_plane(np.vstack([m.hub_line_px for m in ok])).reshape(-1, 2, 2)
    length = np.linalg.norm(ends[:, 1] - ends[:, 0], axis=1)
    width = np.array([m.hub_width_m for m in ok], dtype=np.float64)
    width = width[np.isfinite(width)]
    offset = np.array([float(np.hypot(*m.clamp_plane_m)) for m in ok])
    mad = float(np.median(np.abs(offset - np.median(offset))))
    return {
        "hub_length_measured_m": float(np.nanmedian(length)),
        "hub_width_measured_m": float(np.median(width)) if len(width) else math.nan,
        "hub_width_measured_frames": len(width),
        "hub_measured_frames": len(ok),
        "hub_offset_measured_m": float(np.median(offset)),
        "hub_offset_measured_sd_m": 1.4826 * mad / math.sqrt(len(ok)),
    }


def hub_attrs(measured: dict[str, float], rig: Rig) -> dict[str, Any]:
    """Results attributes: the hints and what was measured."""
    return {
        "hub_length_hint_m": rig.hub.length_m,
        "hub_width_hint_m": rig.hub.width_m,
        **measured,
    }


def hub_line(attrs: dict[str, Any], rig_hub_offset_m: float) -> str | None:
    """One line for people (mm): the hub measured beside the rig's hints, from a results
    file's attributes (:func:`hub_attrs`)."""
    if "hub_length_measured_m" not in attrs:
        return None
    length_mm = float(attrs["hub_length_measured_m"]) * 1e3
    width_mm = float(attrs["hub_width_measured_m"]) * 1e3
    n_w, n = attrs.get("hub_width_measured_frames"), attrs.get("hub_measured_frames")
    if not math.isfinite(width_mm):
        size = f"{length_mm:.1f} mm long (its width on none of {n} frames)"
    elif n_w is not None and n is not None and int(n_w) < int(n):
        size = f"{length_mm:.1f} x {width_mm:.1f} mm (the width on {n_w} of {n} frames)"
    else:
        size = f"{length_mm:.1f} x {width_mm:.1f} mm"
    return (
        f"hub measured {size}, clamp "
        f"{float(attrs['hub_offset_measured_m']) * 1e3:.2f} mm from the pivot (rig: hints "
        f"{float(attrs['hub_length_hint_m']) * 1e3:.0f} x "
        f"{float(attrs['hub_width_hint_m']) * 1e3:.0f} mm, hub_offset_m "
        f"{rig_hub_offset_m * 1e3:.2f} mm)"
    )


def offset_warning(measured: dict[str, float], rig: Rig) -> str | None:
    """A warning when the frames put the clamp elsewhere than the rig's ``hub_offset_m``
    (which the simulation uses)."""
    if not measured:
        return None
    got = measured["hub_offset_measured_m"]
    gap = got - rig.beam.hub_offset_m
    if abs(gap) <= max(OFFSET_TOLERANCE_M, 5.0 * measured["hub_offset_measured_sd_m"]):
        return None
    return (
        f"the frames put the clamp {got * 1e3:.2f} mm from the pivot, the rig's [beam] "
        f"hub_offset_m {rig.beam.hub_offset_m * 1e3:.2f} mm (the simulation uses the rig's; "
        "pass --rig RIG.toml with this bench's)"
    )
