"""beambench measure: hub angle and tip deflection from photographs."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

from pipelines.commands._args import add_max_tip_uncertainty_argument, max_tip_uncertainty_m
from pipelines.errors import BeambenchError

if TYPE_CHECKING:
    from vision import FrameMeasurement


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("images", metavar="IMAGE", nargs="+")
    p.add_argument("--calibration", metavar="CAL.json", required=True)
    p.add_argument("--json", action="store_true", help="one JSON object per image")
    p.add_argument(
        "--method", choices=("default", "paper"), default="default", help="measurement chain"
    )
    add_max_tip_uncertainty_argument(p)


def _read_images(paths: list[str]) -> list[tuple[str, Any]]:
    from vision import decode

    out = []
    for path in paths:
        try:
            data = Path(path).read_bytes()
        except FileNotFoundError:
            raise BeambenchError(f"{path}: no such file") from None
        except OSError as exc:
            raise BeambenchError(f"{path}: cannot be read ({exc.strerror})") from None
        try:
            out.append((path, decode(data)))
        except ValueError as exc:
            raise BeambenchError(f"{path}: {exc}") from None
    return out


def _text(path: str, m: dict[str, Any]) -> str:
    if not m["ok"]:
        return f"{path}: no measurement ({m['reason']})"

    def mm(v: object) -> str:
        return f"{float(v) * 1e3:+.3f} mm"  # type: ignore[arg-type]

    def sd(key: str, scale: float, unit: str) -> str:
        v = m.get(key)
        return "" if v is None else f" (sd {float(v) * scale:.3f} {unit})"

    hub = math.degrees(float(m["hub_angle_rad"]))
    stations = ", ".join(
        f"{float(s) * 1e3:.0f} mm: {mm(v)}"
        for s, v in zip(m["stations_m"], m["lateral_at_stations_m"], strict=True)
    )
    return (
        f"{path}: hub angle {hub:.4f} deg{sd('hub_angle_sd_rad', math.degrees(1.0), 'deg')}, "
        f"tip lateral {mm(m['tip_lateral_m'])}{sd('tip_lateral_sd_m', 1e3, 'mm')}, "
        f"tip longitudinal {mm(m['tip_longitudinal_m'])}{sd('tip_longitudinal_sd_m', 1e3, 'mm')}"
        f"; lateral at {stations}{_hub_width_text(m)}"
    )


def _hub_width_text(m: dict[str, Any]) -> str:
    w, sd = m.get("hub_width_m"), m.get("hub_width_sd_m")
    if w is None:
        return "; hub width not measured (its long edges are not both straight lines)"
    return f"; hub width {float(w) * 1e3:.2f} mm" + (
        "" if sd is None else f" (sd {float(sd) * 1e3:.3f} mm)"
    )


# Each value and the key of its standard uncertainty, which follows it in the JSON.
_SD_OF = {
    "hub_angle_rad": "hub_angle_sd_rad",
    "tip_lateral_m": "tip_lateral_sd_m",
    "tip_longitudinal_m": "tip_longitudinal_sd_m",
}


def _with_sds(m: dict[str, Any], longitudinal_sd_m: float) -> dict[str, Any]:
    """``m`` with each value's standard uncertainty beside it: ``tip_longitudinal_sd_m``
    added when vision does not state it (None when the frame gave no measurement)."""
    if m.get("tip_longitudinal_sd_m") is None:
        sd = longitudinal_sd_m
        m = {**m, "tip_longitudinal_sd_m": sd if math.isfinite(sd) else None}
    out: dict[str, Any] = {}
    for key, value in m.items():
        if key in _SD_OF.values():
            continue
        out[key] = value
        if key in _SD_OF:
            out[_SD_OF[key]] = m.get(_SD_OF[key])
    return out


def _calibration_included(
    m: dict[str, Any], total: tuple[float, ...], calibration: tuple[float, ...]
) -> tuple[dict[str, Any], float]:
    """``m`` with each standard uncertainty the total (the frame's noise and the
    calibration's error in quadrature) and the calibration's share added as
    ``calibration_*`` keys (zero when the calibration file states no covariance), and
    the longitudinal total for :func:`_with_sds`."""
    if not m["ok"]:
        return m, math.nan
    out = {**m, "hub_angle_sd_rad": total[0], "tip_lateral_sd_m": total[1]}
    names = ("hub_angle_sd_rad", "tip_lateral_sd_m", "tip_longitudinal_sd_m")
    for name, value in zip(names, calibration, strict=True):
        out[f"calibration_{name}"] = value
    return out, total[2]


def _seen(m: dict[str, Any], measured: FrameMeasurement) -> dict[str, Any]:
    """``m`` with what the frame showed beside the measurement: ``beam_width_m``, the
    beam's width measured from its edges; ``blur_px``, the median ramp width of its
    edges (motion blur and smear widen it; a frame beyond the measurer's ``max_blur_px``
    is measured from the centroids of the beam's light); ``hub_width_m`` and its
    ``hub_width_sd_m``, from the hub's two long edges as straight lines (None where they
    are not: a bar lying against one, a short block showing none clear of its ends).
    None where not measured."""

    def num(x: float) -> float | None:
        return float(x) if math.isfinite(x) else None

    return {
        **m,
        "beam_width_m": num(measured.beam_width_m),
        "blur_px": num(measured.blur_px),
        "hub_width_m": num(measured.hub_width_m),
        "hub_width_sd_m": num(measured.hub_width_std_m),
    }


#: Said on a terminal before the first image when vision's kernels are not compiled yet.
COMPILING_NOTE = (
    "measure: compiling vision's kernels first (after an install or an update of "
    "beambench: ~25 s, once; cached for every later run)"
)


def compiling_note(cold: bool, stream: TextIO | None = None) -> None:
    """Say why the first image takes ~25 s when the kernel cache is cold, on a terminal
    only (like :class:`pipelines.progress.Progress`; a pipe or a log gets nothing)."""
    stream = sys.stderr if stream is None else stream
    isatty = getattr(stream, "isatty", None)
    if cold and isatty is not None and isatty():
        print(COMPILING_NOTE, file=stream, flush=True)


def run(args: argparse.Namespace) -> int:
    from pipelines.process.frames import measurer_for
    from vision import load_calibration
    from vision.calibration import check_points_in_image
    from vision.jit import cached as kernels_cached

    # asked first: loading the calibration compiles a few kernels of its own
    cold = not kernels_cached()
    limit_m = max_tip_uncertainty_m(args)
    try:
        cal = load_calibration(args.calibration)
    except ValueError as exc:
        raise BeambenchError(f"{args.calibration}: {exc}") from None
    images = _read_images(args.images)
    for path, image in images:
        try:
            check_points_in_image(cal, image.shape[1], image.shape[0])
        except ValueError as exc:
            raise BeambenchError(f"{args.calibration}: {exc} ({path})") from None
    measurer = measurer_for(cal, None, args.method, limit_m)
    from pipelines.process.frames import stated_sds

    compiling_note(cold)
    for path, image in images:
        measured = measurer.measure(image)
        m = _with_sds(*_calibration_included(measured.to_dict(), *stated_sds(measured, cal)))
        m = _seen(m, measured)
        if args.json:
            print(json.dumps({"image": path, **m}))
        else:
            print(_text(path, m))
    return 0
