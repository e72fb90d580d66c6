"""Calibration files, mutated: points NaN, infinite, huge, negative, of the wrong type or
shape, dropped, swapped, mirrored, moved out of the image; the camera matrix and the
distortion broken; the beam's numbers; unknown keys; JSON cut short. ``beambench measure``
with each either exits 2 with one error line or measures the frame sensibly."""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path
from typing import Any

from tests.fuzz.contract import CASES, Case, report, rng, run_cases

BAD: list[Any] = [math.nan, math.inf, -1e300, 1e300, -5.0, "x", None, True, [], {}, [1, 2, 3]]


def _json(data: Any) -> str:
    return json.dumps(data, allow_nan=True)  # NaN and Infinity: what other tools write


def mutate(r: Any, good: dict[str, Any]) -> tuple[str, str]:
    data = copy.deepcopy(good)
    reg = data["registration"]
    kind = r.randrange(12)
    if kind == 0:
        key = r.choice(["image_points_px", "plane_points_m"])
        i, j = r.randrange(len(reg[key])), r.randrange(2)
        reg[key][i][j] = value = r.choice(BAD)
        return _json(data), f"{key}[{i}][{j}] = {value!r}"
    if kind == 1:
        key = r.choice(["image_points_px", "plane_points_m"])
        reg[key] = value = r.choice([5, None, "pts", {}, [], [1, 2, 3, 4], [[1, 2, 3]] * 4])
        return _json(data), f"{key} = {value!r}"
    if kind == 2:
        n = r.randrange(len(reg["image_points_px"]))
        reg["image_points_px"] = reg["image_points_px"][:n]
        return _json(data), f"image points cut to {n}"
    if kind == 3:
        i, j = r.sample(range(len(reg["image_points_px"])), 2)
        pts = reg["image_points_px"]
        pts[i], pts[j] = pts[j], pts[i]
        return _json(data), f"image points {i} and {j} swapped"
    if kind == 4:
        reg["plane_points_m"] = [[x, -y] for x, y in reg["plane_points_m"]]
        return _json(data), "plane mirrored"
    if kind == 5:
        dx = r.choice([-1, 1]) * r.uniform(500, 5000)
        reg["image_points_px"] = [[x + dx, y] for x, y in reg["image_points_px"]]
        return _json(data), f"image points moved by {dx:.0f} px"
    if kind == 6:
        i, j = r.randrange(3), r.randrange(3)
        data["camera"]["matrix"][i][j] = value = r.choice([*BAD, 0.0])
        return _json(data), f"camera.matrix[{i}][{j}] = {value!r}"
    if kind == 7:
        data["camera"]["distortion"] = value = r.choice(
            [[0.0] * 3, [math.nan] * 5, [1e300] * 5, "none", 1.0, [0.1, 0, 0, 0, 0]]
        )
        return _json(data), f"camera.distortion = {value!r}"
    if kind == 8:
        key = r.choice(["length_m", "width_m"])
        data["beam"][key] = value = r.choice([*BAD, 0.0, 100.0])
        return _json(data), f"beam.{key} = {value!r}"
    if kind == 9:
        data[r.choice(["extra", "registration2"])] = 1
        return _json(data), "unknown top-level key"
    if kind == 10:
        text = _json(data)
        n = r.randrange(len(text))
        return text[:n], f"JSON cut at {n}"
    scale = 10.0 ** r.randint(-6, 6)
    reg["plane_points_m"] = [[x * scale, y * scale] for x, y in reg["plane_points_m"]]
    return _json(data), f"plane points scaled by {scale:g}"


def _sane(stdout: str) -> str | None:
    """An accepted calibration's measurement: one JSON line; a measurement flagged ok has
    finite numbers on the beam's scale."""
    lines = stdout.strip().splitlines()
    if len(lines) != 1:
        return f"{len(lines)} output lines"
    m = json.loads(lines[0])
    if m["ok"]:
        values = [m["hub_angle_rad"], m["tip_lateral_m"], m["tip_longitudinal_m"]]
        if not all(isinstance(v, float) and math.isfinite(v) for v in values):
            return f"ok with non-finite values {values}"
        if abs(m["tip_lateral_m"]) > 0.835:
            return f"ok with a tip deflection of {m['tip_lateral_m']} m on a 0.835 m beam"
    return None


def test_fuzz_calibration_files(tmp_path: Path, frame_files: dict[str, Path]) -> None:
    r = rng("calibration")
    good = json.loads(frame_files["cal.json"].read_text())
    image = str(frame_files["frame.jpg"])
    cases = []
    for i in range(CASES):
        text, what = mutate(r, good)
        path = tmp_path / f"cal{i}.json"
        path.write_text(text)
        argv = ["measure", image, "--calibration", str(path), "--json"]
        cases.append(Case(argv, what, [str(path), image], _sane))
    problems, counts = run_cases(cases, tmp_path)
    report("calibration", problems, counts)
    assert counts["exit 2"] > 0
