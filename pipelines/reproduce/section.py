"""The pieces of ``beambench reproduce``'s report: a compared number, a section, and
how numbers and tables are formatted in markdown."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
NAN = math.nan


@dataclass(frozen=True)
class Number:
    """One compared quantity: the paper's value (NaN when it prints none) and ours."""

    key: str
    quantity: str
    unit: str
    paper: float
    beambench: float
    note: str = ""
    fmt: str = ".3f"


@dataclass
class Section:
    """A computed part of the report."""

    key: str
    title: str
    numbers: list[Number] = field(default_factory=list)
    text: list[str] = field(default_factory=list)
    tables: dict[str, list[dict[str, Any]]] = field(default_factory=dict)
    plots: dict[str, Callable[[Path], None]] = field(default_factory=dict)
    wall_s: float = 0.0

    def add(
        self,
        key: str,
        quantity: str,
        unit: str,
        paper: float,
        ours: float,
        note: str = "",
        fmt: str = ".3f",
    ) -> None:
        self.numbers.append(Number(key, quantity, unit, float(paper), float(ours), note, fmt))

    def value(self, key: str) -> float:
        """beambench's value of the number ``key``."""
        for n in self.numbers:
            if n.key == key:
                return n.beambench
        raise KeyError(f"section {self.key} has no number {key!r}")


def join_values(values: Sequence[float] | FloatArray, decimals: int = 2) -> str:
    return ", ".join(f"{v:.{decimals}f}" for v in values)


def wrap_rad(a: FloatArray) -> FloatArray:
    return np.asarray((a + math.pi) % (2.0 * math.pi) - math.pi, dtype=float)


def format_value(value: Any, fmt: str = ".3f") -> str:
    if isinstance(value, str):
        return value
    v = float(value)
    if not math.isfinite(v):
        return "—" if math.isnan(v) else str(v)
    if v == 0.0:
        return "0"
    if fmt.endswith("f") and (abs(v) >= 1e6 or abs(v) < 1e-3):
        return f"{v:.3e}"
    return f"{v:{fmt}}"


def markdown_table(rows: Sequence[dict[str, Any]]) -> list[str]:
    if not rows:
        return []
    cols = list(rows[0])
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for r in rows:
        lines.append("| " + " | ".join(format_value(r[c]) for c in cols) + " |")
    return lines
