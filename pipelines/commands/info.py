"""beambench info: what a run log holds (``daq.log.summarize_log``), as a table."""

from __future__ import annotations

import argparse


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("log", metavar="RUN.mcap")


def run(args: argparse.Namespace) -> int:
    from daq.log import summarize_log

    s = summarize_log(args.log)
    print(f"{s.path}: {s.size_bytes / 1e6:.2f} MB, {s.chunks} chunks, {s.library}")
    print(f"run {s.run_id}  start {s.start_utc}  duration {s.duration_s:.3f} s")
    rate = "an unrecorded rate" if s.acquisition_rate_hz is None else f"{s.acquisition_rate_hz} Hz"
    daq, camera = (b if b is not None else "not recorded" for b in s.backends)
    print(f"backends: daq {daq}, camera {camera}; acquired at {rate}")
    print(
        f"{'topic':<16} {'schema':<30} {'count':>8} {'rate Hz':>9} {'seq gaps':>8} "
        f"{'missing':>8} {'time gaps':>9} {'max gap s':>9}"
    )
    for c in s.channels:
        rate_s = f"{c.rate_hz:.3f}" if c.rate_hz else "-"
        gap_s = f"{c.largest_gap_s:.4f}" if c.largest_gap_s is not None else "-"
        print(
            f"{c.topic:<16} {c.schema:<30} {c.count:>8} {rate_s:>9} "
            f"{c.sequence_gaps:>8} {c.missing:>8} {c.time_gaps:>9} {gap_s:>9}"
        )
    if s.problems:
        listed = ", ".join(f"{name} x{n}" for name, n in sorted(s.problems.items()))
        print(f"events: {listed}")
    else:
        print("events: no drops, overruns, clipping or device errors")
    return 0
