"""What failed when a run's frames were measured: the failure reasons counted, the main
one named with the option that would help (``beambench process`` prints them)."""

from __future__ import annotations

import re
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass

# A reason's kind: its text before the first colon, with numbers blanked (a frame's
# reason carries its own numbers: "too noisy: tip lateral uncertainty 0.62 mm ...").
_NUMBER = re.compile(r"[-+]?\d+(?:\.\d+)?")

# What helps against a kind of failure, by words in the reason (first match wins).
HELP: tuple[tuple[tuple[str, ...], str], ...] = (
    (("too noisy",), "--max-tip-uncertainty MM (the tip uncertainty a frame may have)"),
    (("motion blur",), "no option of process: a shorter camera exposure (less smear)"),
    (("hub", "clamp"), "--rig RIG.toml with this bench's [hub] and [beam] hub_offset_m"),
    (
        ("beam width", "beam length", "too short", "no beam", "strip not visible"),
        "--rig RIG.toml with this bench's beam, or --calibration CAL.json",
    ),
    (("decode", "blank frame", "not a uint8"), "none: the frames themselves are unusable"),
)
FALLBACK_HELP = "--calibration CAL.json and --rig RIG.toml describing this bench"


def reason_kind(reason: str) -> str:
    kind = _NUMBER.sub("#", reason).split(":", 1)[0].strip()
    return kind or "no reason given"


def help_for(kind: str) -> str:
    for words, option in HELP:
        if any(w in kind for w in words):
            return option
    return FALLBACK_HELP


@dataclass(frozen=True)
class FailureSummary:
    """Frames measured and failed, the failures by kind (most first) with an example
    reason each."""

    total: int
    measured: int
    kinds: list[tuple[str, int, str]]

    @property
    def failed(self) -> int:
        return self.total - self.measured

    @property
    def main_kind(self) -> str | None:
        return self.kinds[0][0] if self.kinds else None

    def lines(self) -> list[str]:
        """One line per kind of failure: ``N of M frames not measured: kind (e.g. ...)``."""
        return [
            f"{n} of {self.total} frames not measured: {kind}"
            + (f" (e.g. {example})" if example != kind else "")
            for kind, n, example in self.kinds
        ]

    def few_measured(self) -> bool:
        """Fewer than half the frames measured."""
        return self.total > 0 and 2 * self.measured < self.total

    def advice(self) -> str:
        """The main reason and the option that would help."""
        kind = self.main_kind or "no reason given"
        n = self.kinds[0][1] if self.kinds else self.failed
        return f"the main reason is '{kind}' ({n} frames); what may help: {help_for(kind)}"


def summarise_failures(oks: Sequence[bool], reasons: Sequence[str]) -> FailureSummary:
    counts: Counter[str] = Counter()
    example: dict[str, str] = {}
    for ok, reason in zip(oks, reasons, strict=True):
        if ok:
            continue
        kind = reason_kind(reason)
        counts[kind] += 1
        example.setdefault(kind, reason)
    kinds = [(k, n, example[k]) for k, n in sorted(counts.items(), key=lambda kv: (-kv[1], kv[0]))]
    return FailureSummary(len(oks), sum(bool(o) for o in oks), kinds)
