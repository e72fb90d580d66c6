"""A campaign's inputs: which logs, what each run is processed with, and the key that
says whether a run recorded earlier was made from the same inputs.

The key is cheap to compute on the client (a log's size and modification time, not its
contents: a hundred logs of a gigabyte are not read to decide what to skip); the log's
sha256 is computed inside the task and recorded for provenance.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

from pipelines import __version__
from pipelines.errors import BeambenchError

LOG_SUFFIX = ".mcap"


@dataclass(frozen=True)
class Options:
    """The process options every run of a campaign shares (``beambench process``'s)."""

    model: str = "auto"
    sim_tol: float | None = None
    damping_law: str | None = None
    fit_damping: bool = False
    rig_path: str | None = None
    calibration_path: str | None = None
    rig_sha256: str = ""
    calibration_sha256: str = ""
    max_tip_uncertainty_m: float | None = None

    def key(self) -> str:
        """What a result depends on besides the log: the options, the contents of the rig
        and calibration files (not their paths) and the software version."""
        d = asdict(self)
        d.pop("rig_path")
        d.pop("calibration_path")
        if d["max_tip_uncertainty_m"] is None:  # the keys of runs made before the option
            d.pop("max_tip_uncertainty_m")
        d["software_version"] = __version__
        return json.dumps(d, sort_keys=True)


@dataclass(frozen=True)
class RunSpec:
    """One run of the campaign: its log, where its results go, and its input key."""

    name: str
    log_path: str
    results_path: str
    log_size_bytes: int
    log_mtime_ns: int
    options: Options

    def input_key(self) -> str:
        return json.dumps(
            {
                "log_size_bytes": self.log_size_bytes,
                "log_mtime_ns": self.log_mtime_ns,
                "options": self.options.key(),
            },
            sort_keys=True,
        )


def sha256_file(path: str | Path, chunk_bytes: int = 1 << 20) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while chunk := f.read(chunk_bytes):
            h.update(chunk)
    return h.hexdigest()


def find_logs(items: Sequence[str]) -> list[Path]:
    """The logs named, and every ``*.mcap`` directly inside a folder named, in order,
    without repeats. Raises ``BeambenchError`` for a missing path or no log at all."""
    logs: list[Path] = []
    for item in items:
        p = Path(item)
        if p.is_dir():
            found = sorted(q for q in p.iterdir() if q.suffix == LOG_SUFFIX and q.is_file())
            if not found:
                raise BeambenchError(f"{p}: folder holds no {LOG_SUFFIX} logs")
            logs += found
        elif p.is_file():
            logs.append(p)
        else:
            raise BeambenchError(f"{p}: no such file or folder")
    seen: set[Path] = set()
    unique = []
    for p in logs:
        r = p.resolve()
        if r not in seen:
            seen.add(r)
            unique.append(p)
    if not unique:
        raise BeambenchError("no logs given")
    return unique


def plan_runs(logs: Sequence[Path], out_dir: Path, options: Options) -> list[RunSpec]:
    """One :class:`RunSpec` per log; results are ``OUT/<log stem>.nc``, so two logs with
    one stem are refused (their results would overwrite each other)."""
    by_name: dict[str, Path] = {}
    specs = []
    for p in logs:
        name = p.stem
        if name in by_name:
            raise BeambenchError(
                f"{p} and {by_name[name]}: two logs named {name!r}; their results would "
                "share one file (rename one)"
            )
        by_name[name] = p
        st = p.stat()
        specs.append(
            RunSpec(
                name=name,
                log_path=str(p.resolve()),
                results_path=str((out_dir / f"{name}.nc").resolve()),
                log_size_bytes=int(st.st_size),
                log_mtime_ns=int(st.st_mtime_ns),
                options=options,
            )
        )
    return specs
