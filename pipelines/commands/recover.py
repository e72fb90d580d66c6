"""beambench recover: salvage a log whose writer was killed."""

from __future__ import annotations

import argparse
from pathlib import Path

from pipelines.errors import BeambenchError
from pipelines.paths import refuse_aliases


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("log", metavar="BROKEN.mcap")
    p.add_argument("--out", metavar="FIXED.mcap", required=True)


def run(args: argparse.Namespace) -> int:
    from daq.log import recover_log

    out = Path(args.out)
    refuse_aliases({"--out": out}, {"the log": args.log})
    if out.exists():
        raise BeambenchError(f"{out}: already exists; choose another --out (never overwritten)")
    if not out.parent.is_dir():
        raise BeambenchError(f"{out}: the folder {out.parent} does not exist")
    try:
        s = recover_log(args.log, out)
    except FileExistsError as exc:
        raise BeambenchError(str(exc)) from None
    except OSError as exc:
        raise BeambenchError(f"{out}: cannot write: {exc.strerror or exc}") from None
    state = "complete (had its footer)" if s.complete else "truncated" if s.truncated else "open"
    print(
        f"recovered {s.messages} messages from {args.log} ({state}) into {s.out_path} "
        "(read back and verified)"
    )
    for topic, n in sorted(s.messages_by_topic.items()):
        print(f"  {topic:<16} {n}")
    if s.last_log_time_ns is not None:
        print(f"  last message at {s.last_log_time_ns * 1e-9:.3f} s of run time")
    if s.bad_chunks:
        print(f"  {s.bad_chunks} unfinished chunk(s) dropped (never fully flushed)")
    return 0
