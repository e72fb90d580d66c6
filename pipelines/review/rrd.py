"""Reading a ``.rrd`` recording back: which entities it holds, how many rows.

Used by tests and by anyone checking what a review recording contains without a viewer.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rerun.chunk import RrdReader


@dataclass(frozen=True)
class RrdEntity:
    """What one entity of a ``.rrd`` holds: rows over time, static rows, components."""

    rows: int
    static_rows: int
    components: frozenset[str]
    timelines: frozenset[str]


def rrd_entities(path: str | os.PathLike[str]) -> dict[str, RrdEntity]:
    """Summarise the recording in a ``.rrd`` file: entity path -> :class:`RrdEntity`.

    Component names are ``Archetype:field`` (e.g. ``Scalars:scalars``,
    ``EncodedImage:blob``). Raises ValueError naming the file when it is not a
    readable recording.
    """
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"{p}: no such .rrd file")
    acc: dict[str, dict[str, Any]] = {}
    try:
        for chunk in RrdReader(p).stream():
            entry = acc.setdefault(
                chunk.entity_path,
                {"rows": 0, "static": 0, "components": set(), "timelines": set()},
            )
            if chunk.is_static:
                entry["static"] += chunk.num_rows
            else:
                entry["rows"] += chunk.num_rows
            entry["timelines"].update(chunk.timeline_names)
            names = chunk.to_record_batch().schema.names
            entry["components"].update(n for n in names if ":" in n)
    except (OSError, ValueError, RuntimeError) as exc:
        raise ValueError(f"{p}: not a readable Rerun recording ({exc})") from None
    return {
        k: RrdEntity(
            rows=v["rows"],
            static_rows=v["static"],
            components=frozenset(v["components"]),
            timelines=frozenset(v["timelines"]),
        )
        for k, v in acc.items()
    }


@dataclass(frozen=True)
class BlueprintView:
    """One view of a recording's layout: its kind, origin and what it shows."""

    kind: str  # "2D", "TimeSeries", "TextLog", "TextDocument", ...
    origin: str
    queries: tuple[str, ...]  # entity queries, ``$origin`` expanded

    def shows(self, entity: str) -> bool:
        """Whether the view includes ``entity`` (``/a/**`` matches ``/a`` and below)."""
        for q in self.queries:
            if q.endswith("/**"):
                base = q[:-3].rstrip("/")
                if entity == base or entity.startswith(base + "/") or base == "":
                    return True
            elif entity == q:
                return True
        return False


def blueprint_views(path: str | os.PathLike[str], which: int = -1) -> list[BlueprintView]:
    """The views of the ``which``-th layout (blueprint) stored in a ``.rrd`` file (the last,
    i.e. the one a viewer shows, by default)."""
    reader = RrdReader(Path(path))
    stores = reader.blueprints()
    if not stores:
        return []
    views: dict[str, dict[str, Any]] = {}
    for chunk in reader.stream(store=stores[which]):
        if not chunk.entity_path.startswith("/view/"):
            continue
        view = views.setdefault(chunk.entity_path.split("/")[2], {})
        rb = chunk.to_record_batch()
        for name, key in (
            ("ViewBlueprint:class_identifier", "class"),
            ("ViewBlueprint:space_origin", "origin"),
            ("ViewContents:query", "query"),
        ):
            if name in rb.schema.names:
                view[key] = rb.column(name).to_pylist()[-1]
    out = []
    for v in views.values():
        origin = v["origin"][0]
        queries = tuple(q.replace("$origin", origin) for q in v.get("query", []))
        out.append(BlueprintView(kind=v["class"][0], origin=origin, queries=queries))
    return out
