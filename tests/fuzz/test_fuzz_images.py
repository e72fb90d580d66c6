"""Image files, mutated: truncated, bytes flipped, the magic number wrong, a header that
claims a huge image, empty, random bytes. ``beambench measure`` on each either exits 2
with one error line or measures: a measurement flagged ok is the frame's true tip."""

from __future__ import annotations

import json
import math
import struct
from pathlib import Path
from typing import Any

from tests.fuzz.contract import CASES, Case, report, rng, run_cases

# a corrupted frame that still measures ok must be right: the image chain resolves the tip
# to ~0.05 mm RMS on clean frames; 0.5 mm is ten times that, a JPEG block's worth of damage
# that the measurement should have flagged
TIP_TOLERANCE_M = 0.5e-3


def mutate(r: Any, data: bytes, kind_name: str) -> tuple[bytes, str]:
    kind = r.randrange(6)
    if kind == 0:
        n = r.randrange(len(data))
        return data[:n], f"{kind_name} truncated to {n} bytes"
    if kind == 1:
        out = bytearray(data)
        flips = [r.randrange(len(out)) for _ in range(r.randint(1, 8))]
        for i in flips:
            out[i] ^= 1 << r.randrange(8)
        return bytes(out), f"{kind_name} bits flipped at {flips}"
    if kind == 2:
        out = bytearray(data)
        out[: r.randint(1, 4)] = b"\x00GIF"[: r.randint(1, 4)]
        return bytes(out), f"{kind_name} magic number broken"
    if kind == 3:
        w, h = r.randint(1, 200000), r.randint(1, 200000)
        out = bytearray(data)
        if data[:4] == b"\x89PNG":
            out[16:24] = struct.pack(">II", w, h)
        else:
            i = 2
            while out[i + 1] not in (0xC0, 0xC1, 0xC2):
                i += 2 + struct.unpack(">H", out[i + 2 : i + 4])[0]
            out[i + 5 : i + 9] = struct.pack(">HH", min(h, 65535), min(w, 65535))
        return bytes(out), f"{kind_name} header claims {w} x {h} px"
    if kind == 4:
        return b"", f"{kind_name} empty"
    return bytes(r.getrandbits(8) for _ in range(r.randint(1, 4096))), "random bytes"


def test_fuzz_image_files(tmp_path: Path, frame_files: dict[str, Path]) -> None:
    r = rng("images")
    truth = json.loads(frame_files["truth.json"].read_text())["tip_lateral_m"]
    cal = str(frame_files["cal.json"])

    def correct(stdout: str) -> str | None:
        m = json.loads(stdout.strip().splitlines()[0])
        if m["ok"] and not abs(m["tip_lateral_m"] - truth) <= TIP_TOLERANCE_M:
            return (
                f"flagged ok but tip {m['tip_lateral_m'] * 1e3:.3f} mm, truth {truth * 1e3:.3f} mm"
            )
        if m["ok"] and not math.isfinite(m["hub_angle_rad"]):
            return "flagged ok with a non-finite hub angle"
        return None

    cases = []
    sources = [(frame_files["frame.jpg"], "jpeg"), (frame_files["frame.png"], "png")]
    for i in range(CASES):
        src, name = sources[i % 2]
        data, what = mutate(r, src.read_bytes(), name)
        path = tmp_path / f"img{i}{src.suffix}"
        path.write_bytes(data)
        argv = ["measure", str(path), "--calibration", cal, "--json"]
        cases.append(Case(argv, what, [str(path), cal], correct))
    problems, counts = run_cases(cases, tmp_path)
    report("images", problems, counts)
    assert counts["exit 2"] > 0
