"""``beambench reproduce``: the paper's comparisons recomputed, as a report.

Every section recomputes one of the paper's results from the rig (the paper's bench by
default) with the simulator and sets the paper's printed value beside beambench's, with
an explanation where they disagree (the paper has errors; geometry and physics decide):

1. the four-bar (§2.1-2.2, Eqs. 8-11) and the hub drive (Eq. 53) against the true output;
2. Table 2, the static tip loads (Eq. 47, §5.1.3, FLXDYN);
3. the clamped-free natural frequencies and the modal damping of Eqs. 37-39;
4. the free-decay damping identification (§5.2.1);
5. Figs. 10 and 11, the reciprocating beam, for the paper's sinusoid and the true four-bar;
6. the spin-up beam with and without geometric stiffening (the hard case);
7. the simulator's speed against its error (``pipelines.bench.sim``, quick table).

Sections are computed first (:func:`compute_sections`; each returns a
:class:`pipelines.reproduce.section.Section` with its numbers, text, tables and plot
callables), then written (:func:`write_report`):
``report.md``, PNG plots, ``numbers.csv`` (every key number, the paper's and beambench's
side by side, with its unit) and one CSV per table. Everything goes into a fresh folder
beside the output folder that is renamed (or whose files are moved) into place only when
complete, so a failing run never clobbers an earlier report.

The sections live in ``linkage`` (1, 5), ``statics`` (2),
``damping`` (3, 4) and ``simulator`` (6, 7); the plots in
``plots``.
"""

from __future__ import annotations

import contextlib
import csv
import logging
import math
import os
import shutil
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

from pipelines import __version__
from pipelines.progress import Progress
from pipelines.reproduce.damping import section_free_decay, section_modes
from pipelines.reproduce.linkage import section_four_bar, section_reciprocating
from pipelines.reproduce.section import (
    Section,
    format_value,
)
from pipelines.reproduce.simulator import section_speed, section_spin_up
from pipelines.reproduce.statics import section_table2
from pipelines.rig import Rig, load_rig

log = logging.getLogger(__name__)

REPORT_NAME = "report.md"
NUMBERS_NAME = "numbers.csv"


SECTIONS: tuple[Callable[[Rig], Section], ...] = (
    section_four_bar,
    section_table2,
    section_modes,
    section_free_decay,
    section_reciprocating,
    section_spin_up,
    section_speed,
)


def compute_sections(
    rig: Rig | None = None, sections: Sequence[Callable[[Rig], Section]] = SECTIONS
) -> list[Section]:
    """Compute every section (the slow part), with a progress bar on a terminal."""
    rig = load_rig() if rig is None else rig
    out = []
    with Progress("reproduce", total=len(sections)) as bar:
        for make in sections:
            start = time.perf_counter()
            sec = make(rig)
            sec.wall_s = time.perf_counter() - start
            log.info("section %s: %.2f s", sec.key, sec.wall_s)
            out.append(sec)
            bar.update(1)
    return out


# -- writing --------------------------------------------------------------------------------
def _numbers_table(sec: Section) -> list[str]:
    lines = ["| quantity | paper | beambench | unit | note |", "|---|---:|---:|---|---|"]
    for n in sec.numbers:
        lines.append(
            f"| {n.quantity} | {format_value(n.paper, n.fmt)} | "
            f"{format_value(n.beambench, n.fmt)} | {n.unit} | {n.note} |"
        )
    return lines


def _write_csv(path: Path, rows: Sequence[dict[str, Any]]) -> None:
    with path.open("w", newline="", encoding="utf-8") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
        writer.writeheader()
        for r in rows:
            writer.writerow(
                {k: ("" if isinstance(v, float) and math.isnan(v) else v) for k, v in r.items()}
            )


def _markdown(sections: Sequence[Section], total_s: float) -> str:
    lines = [
        "# beambench reproduce: the paper's comparisons",
        "",
        f"beambench {__version__}; the whole report took {total_s:.1f} s "
        f"({', '.join(f'{s.key} {s.wall_s:.1f} s' for s in sections)}).",
        "",
        "The paper is Langlois & Hayes' reciprocating flexible-beam benchmark; equation, table "
        "and figure numbers are its own. A dash in the paper column: the paper prints no such "
        "number. Every number is in `numbers.csv` (paper and beambench side by side, with its "
        "unit); each table has its own CSV (column names carry the units).",
        "",
    ]
    for k, sec in enumerate(sections, start=1):
        lines += [f"## {k}. {sec.title}", ""]
        if sec.numbers:
            lines += [*_numbers_table(sec), ""]
        for para in sec.text:
            lines += [para, ""] if para else [""]
        for name in sec.tables:
            lines += [f"Table: [`{name}.csv`]({name}.csv)", ""]
        for name in sec.plots:
            lines += [f"![{sec.title}]({name})", ""]
    return "\n".join(lines)


def write_report(
    sections: Sequence[Section], out_dir: str | os.PathLike[str], *, started_s: float
) -> Path:
    """Write the report into ``out_dir`` (created if missing; its parent must exist).

    ``started_s`` is the ``time.perf_counter()`` at which the run began: the report
    states the time from then to its last plot.

    Everything is written into a temporary folder beside ``out_dir`` first; a new
    ``out_dir`` is that folder renamed, an existing one gets the finished files moved in
    (other files in it are left alone). Returns the path of ``report.md``.
    """
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise ValueError(f"out_dir {out} exists and is not a folder")
    parent = out.absolute().parent
    if not parent.is_dir():
        raise ValueError(f"out_dir {out}: its parent folder {parent} does not exist")
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".tmp", dir=parent))
    try:
        numbers = [{"section": s.key, **asdict(n)} for s in sections for n in s.numbers]
        for row in numbers:
            row.pop("fmt")
        _write_csv(tmp / NUMBERS_NAME, numbers)
        for sec in sections:
            for name, rows in sec.tables.items():
                _write_csv(tmp / f"{name}.csv", rows)
            for name, draw in sec.plots.items():
                draw(tmp / name)
        total_s = time.perf_counter() - started_s
        (tmp / REPORT_NAME).write_text(_markdown(sections, total_s), encoding="utf-8")
        if out.exists():
            for f in tmp.iterdir():
                os.replace(f, out / f.name)
        else:
            os.rename(tmp, out)
    finally:
        with contextlib.suppress(FileNotFoundError):
            shutil.rmtree(tmp)
    log.info("wrote report %s", out / REPORT_NAME)
    return out / REPORT_NAME


def run_reproduce(out_dir: str | os.PathLike[str], rig: Rig | None = None) -> Path:
    """Compute every section and write the report; returns the path of ``report.md``."""
    start = time.perf_counter()
    sections = compute_sections(rig)
    return write_report(sections, out_dir, started_s=start)
