"""The command-line contract every fuzz case is held to (shared/design.md): exit 0 with a
correct result, or exit 2 with one ``error:`` line; never a traceback, a hang or a changed
input. Cases run in batches in a subprocess (``_runner.py``) under a timeout."""

from __future__ import annotations

import json
import os
import random
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
RUNNER = Path(__file__).with_name("_runner.py")
# cases per category: small in `make test`, a few thousand in all with `make fuzz`
CASES = int(os.environ.get("BEAMBENCH_FUZZ_CASES", "40"))
SEED = int(os.environ.get("BEAMBENCH_FUZZ_SEED", "20261123"))
CASE_TIMEOUT_S = 60


@dataclass
class Case:
    """One command line, what it was made from (for the report) and its input files."""

    argv: list[str]
    what: str
    inputs: list[str]
    check_ok: Callable[[str], str | None] | None = None  # stdout -> problem or None
    extra: dict[str, Any] = field(default_factory=dict)


def rng(category: str) -> random.Random:
    return random.Random(f"{SEED}:{category}")


def run_cases(cases: list[Case], tmp: Path) -> tuple[list[str], dict[str, int]]:
    """Run ``cases``; return the contract's violations (one line each) and the counts."""
    spec = tmp / "cases.json"
    spec.write_text(json.dumps([{"argv": c.argv, "inputs": c.inputs} for c in cases]))
    out = tmp / "results.json"
    total_timeout = CASE_TIMEOUT_S * 2 + 2.0 * len(cases) + 60
    proc = subprocess.run(
        [sys.executable, str(RUNNER), str(spec), str(out), str(CASE_TIMEOUT_S)],
        capture_output=True,
        text=True,
        timeout=total_timeout,
        cwd=tmp,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )
    if proc.returncode != 0 or not out.exists():
        return [f"the runner itself failed (exit {proc.returncode}): {proc.stderr[-2000:]}"], {}
    results = json.loads(out.read_text())
    problems = []
    counts = {"cases": len(cases), "exit 0": 0, "exit 2": 0}
    for case, r in zip(cases, results, strict=True):
        problem = violation(case, r)
        if problem:
            problems.append(f"{case.what}: {problem}")
        elif r["rc"] == 0:
            counts["exit 0"] += 1
        else:
            counts["exit 2"] += 1
    return problems, counts


def violation(case: Case, r: dict[str, Any]) -> str | None:
    if r["timeout"]:
        return f"overran {CASE_TIMEOUT_S} s (a hang)"
    if r["traceback"]:
        return "traceback: " + r["traceback"].strip().splitlines()[-1]
    if "Traceback (most recent call last)" in r["stderr"]:
        return "traceback on stderr: " + r["stderr"].strip().splitlines()[-1]
    if r["changed"]:
        return f"input changed: {r['changed']}"
    errors = [x for x in r["stderr"].splitlines() if x.startswith("error:")]
    if r["rc"] == 2:
        if len(errors) != 1:
            return f"exit 2 with {len(errors)} error: lines: {r['stderr'][-500:]!r}"
        return None
    if r["rc"] == 0:
        if errors:
            return f"exit 0 with an error line: {errors[0]}"
        return case.check_ok(r["stdout"]) if case.check_ok else None
    return f"exit {r['rc']}: {r['stderr'][-500:]!r}"


def report(category: str, problems: list[str], counts: dict[str, int]) -> None:
    """Print the counts (``make fuzz`` shows them with -s) and fail with every violation."""
    print(f"fuzz {category}: {counts}")
    assert not problems, f"{len(problems)} case(s) broke the contract:\n" + "\n".join(problems[:40])
