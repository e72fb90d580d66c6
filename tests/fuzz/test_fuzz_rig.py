"""Rig files, mutated: a value NaN, infinite, 1e300, negative, zero, scaled, of the wrong
type, a key missing or unknown, a section missing. ``beambench sim linkage --json`` on each
either exits 2 with one error line or prints the linkage of the rig it accepted."""

from __future__ import annotations

import json
import logging
import math
import tomllib
from pathlib import Path
from typing import Any

from tests.fuzz.contract import CASES, Case, report, rng, run_cases

DEFAULT = tomllib.loads(
    (Path(__file__).resolve().parents[2] / "pipelines" / "data" / "rig.toml").read_text()
)


def _value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k} = {_value(x)}" for k, x in v.items()) + "}"
    return repr(v)


def dump(data: dict[str, Any]) -> str:
    lines = []
    for section, table in data.items():
        if not isinstance(table, dict):
            lines.insert(0, f"{section} = {_value(table)}")
            continue
        lines.append(f"[{section}]")
        lines += [f"{k} = {_value(v)}" for k, v in table.items()]
    return "\n".join(lines) + "\n"


BAD_VALUES: list[Any] = [
    math.nan,
    math.inf,
    -math.inf,
    1e300,
    -1e300,
    1e-300,
    0,
    0.0,
    -1,
    10**30,
    "x",
    "",
    True,
    [],
    [1.0],
    {"a": 1},
]


def mutate(r: Any) -> tuple[dict[str, Any], str]:
    data = {s: dict(t) for s, t in DEFAULT.items()}
    section = r.choice(sorted(data))
    key = r.choice(sorted(data[section]))
    kind = r.randrange(8)
    if kind == 0:
        del data[section][key]
        return data, f"[{section}] {key} deleted"
    if kind == 1:
        data[section]["unknown_key_m"] = 1.0
        return data, f"[{section}] unknown key added"
    if kind == 2 and r.random() < 0.3:
        del data[section]
        return data, f"[{section}] deleted"
    old = data[section][key]
    if kind == 3 and isinstance(old, int | float) and not isinstance(old, bool):
        new = old * 10.0 ** r.randint(-8, 8) * r.choice([1, -1])
    elif kind == 4 and isinstance(old, list) and old:
        items = list(old)
        items[r.randrange(len(items))] = r.choice(BAD_VALUES)
        if r.random() < 0.3:
            items = items[: r.randrange(len(items))]
        new = items
    else:
        new = r.choice(BAD_VALUES)
    data[section][key] = new
    return data, f"[{section}] {key} = {_value(new)}"


def _expected_linkage(text: str) -> str | None:
    """What ``sim linkage --json`` must print for an accepted rig (computed here)."""
    from pipelines.errors import RigError
    from pipelines.rig import parse_rig
    from sim import scenes

    logging.getLogger("pipelines.rig").disabled = True
    try:
        rig = parse_rig(text)
    except RigError:
        return None
    finally:
        logging.getLogger("pipelines.rig").disabled = False
    return json.dumps(scenes.linkage(rig.linkage), sort_keys=True)


def test_fuzz_rig_files(tmp_path: Path) -> None:
    r = rng("rig")
    cases = []
    for i in range(CASES * 4):  # a rig case takes milliseconds
        data, what = mutate(r)
        path = tmp_path / f"rig{i}.toml"
        text = dump(data)
        path.write_text(text)
        expected = _expected_linkage(text)

        def check(stdout: str, expected: str | None = expected) -> str | None:
            if expected is None:
                return "exit 0 for a rig the loader refuses"
            if stdout.strip() != expected:
                return f"printed {stdout.strip()[:200]!r}, expected {expected[:200]!r}"
            return None

        cases.append(
            Case(["sim", "linkage", "--json", "--rig", str(path)], what, [str(path)], check)
        )
    problems, counts = run_cases(cases, tmp_path)
    report("rig", problems, counts)
    assert counts["exit 2"] > 0  # the mutations reach the checks
