"""beambench info: what a run log holds."""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

from pipelines.errors import BeambenchError

HELP = "channels, counts, rates, gaps and duration of a run log"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("log", metavar="RUN.mcap")


def summarize(path: str) -> dict[str, Any]:
    """Per-topic counts, rates, sequence and time gaps, drop events and duration."""
    from daq.log import LogError, read_run, scan_log

    try:
        stats, meta = scan_log(path)
        run = read_run(path, topics=["/events"])
    except LogError as exc:
        raise BeambenchError(str(exc)) from None
    channels = []
    t_min, t_max = None, None
    for topic, st in sorted(stats.items()):
        n = len(st.log_time_ns)
        row: dict[str, Any] = {
            "topic": topic,
            "schema": st.schema_name,
            "encoding": st.message_encoding,
            "count": n,
            "rate_hz": None,
            "sequence_gaps": 0,
            "missing": 0,
            "time_gaps": 0,
            "largest_gap_s": None,
        }
        if n:
            t = np.sort(st.log_time_ns)
            t_min = int(t[0]) if t_min is None else min(t_min, int(t[0]))
            t_max = int(t[-1]) if t_max is None else max(t_max, int(t[-1]))
        if n >= 2:
            order = np.argsort(st.log_time_ns, kind="stable")
            t = st.log_time_ns[order]
            seq = st.sequence[order]
            dt = np.diff(t)
            span = (t[-1] - t[0]) * 1e-9
            row["rate_hz"] = (n - 1) / span if span > 0 else None
            if topic != "/events":
                dseq = np.diff(seq)
                row["sequence_gaps"] = int(np.count_nonzero(dseq > 1))
                row["missing"] = int(np.sum(dseq[dseq > 1] - 1))
                median = float(np.median(dt))
                if median > 0:
                    row["time_gaps"] = int(np.count_nonzero(dt > 1.5 * median))
                row["largest_gap_s"] = float(dt.max()) * 1e-9
        channels.append(row)
    drops: dict[str, int] = {}
    for ev in run.events:
        if ev.level != "info":
            drops[ev.name] = drops.get(ev.name, 0) + 1
    return {
        "path": path,
        "library": meta["library"],
        "size_bytes": meta["size_bytes"],
        "chunks": meta["chunks"],
        "run_id": run.run_info.get("run_id"),
        "start_utc": run.run_info.get("start_utc"),
        "backends": (run.run_info.get("backend_daq"), run.run_info.get("backend_camera")),
        "acquisition_rate_hz": run.run_info.get("acquisition_rate_hz"),
        "duration_s": (t_max - t_min) * 1e-9 if t_min is not None and t_max is not None else 0.0,
        "channels": channels,
        "problems": drops,
    }


def run(args: argparse.Namespace) -> int:
    s = summarize(args.log)
    print(f"{s['path']}: {s['size_bytes'] / 1e6:.2f} MB, {s['chunks']} chunks, {s['library']}")
    print(f"run {s['run_id']}  start {s['start_utc']}  duration {s['duration_s']:.3f} s")
    rate = s["acquisition_rate_hz"]
    print(f"backends: daq {s['backends'][0]}, camera {s['backends'][1]}; acquired at {rate} Hz")
    print(
        f"{'topic':<16} {'schema':<30} {'count':>8} {'rate Hz':>9} {'seq gaps':>8} "
        f"{'missing':>8} {'time gaps':>9} {'max gap s':>9}"
    )
    for c in s["channels"]:
        rate_s = f"{c['rate_hz']:.3f}" if c["rate_hz"] else "-"
        gap_s = f"{c['largest_gap_s']:.4f}" if c["largest_gap_s"] is not None else "-"
        print(
            f"{c['topic']:<16} {c['schema']:<30} {c['count']:>8} {rate_s:>9} "
            f"{c['sequence_gaps']:>8} {c['missing']:>8} {c['time_gaps']:>9} {gap_s:>9}"
        )
    if s["problems"]:
        listed = ", ".join(f"{name} x{n}" for name, n in sorted(s["problems"].items()))
        print(f"events: {listed}")
    else:
        print("events: no drops, overruns, clipping or device errors")
    return 0
