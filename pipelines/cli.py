"""The ``beambench`` command line: one console script, one module per subcommand.

:data:`COMMANDS` holds each subcommand's one-line help; its module in
``pipelines.commands`` provides ``add_arguments`` and ``run(args) -> int`` and is imported
only when its command runs (as pip's command registry does: ``beambench --help`` or a
usage mistake answers at once instead of importing every command's libraries first).
Known errors (``BeambenchError``, and the root of each package's tree: ``SimError``,
``VisionError``, ``DaqError``) become one ``error: ...`` line on stderr and exit status 2;
a traceback is a bug.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys
from collections.abc import Sequence
from typing import NoReturn

from pipelines import __version__

COMMANDS = {
    "demo": "synthetic bench end to end: capture, process, report",
    "check": (
        "preflight: camera, registration, beam, bridges, potentiometer, exposure (pass/warn/fail)"
    ),
    "capture": "record a run (DAQ + camera) to a synchronized MCAP log",
    "info": "channels, counts, rates, gaps and duration of a run log",
    "recover": (
        "restore every flushed message of a broken log into a new file, read back and "
        "verified (exit 2 when nothing usable survives)"
    ),
    "process": "measure frames, reconstruct, simulate and compare a run; write RESULTS.nc",
    "campaign": (
        "process many runs on a Dask cluster; write a results file per run and DIR/campaign.nc"
    ),
    "sweep": "simulate the reciprocating bench over crank frequencies (and a1) on a Dask cluster",
    "replay": "stream a raw run log to Rerun without processing",
    "view": "open a .rrd recording in Rerun's viewer (native, or served to a browser with --web)",
    "measure": "measure hub angle and tip deflection in still images",
    "sim": (
        "simulate a scene (reciprocating, static, free-decay, spin-up, falling-body, "
        "modes, linkage)"
    ),
    "bench": "print speed against error for the simulator, vision, acquisition or processing",
    "reproduce": "reproduce the paper's comparisons as a report",
}

EXIT_BAD_INPUT = 2


class _Parser(argparse.ArgumentParser):
    """argparse that reports usage mistakes as one ``error:`` line (exit 2)."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_BAD_INPUT, f"error: {self.prog}: {message}\n")


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The parser of every command (``only`` None), or of the command ``only`` with the
    others listed by their help alone (``""``: none but the list)."""
    parser = _Parser(
        prog="beambench",
        description="Data acquisition and processing for the reciprocating flexible-beam bench.",
    )
    parser.add_argument("--version", action="version", version=f"beambench {__version__}")
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress details")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for name, help_line in COMMANDS.items():
        p = sub.add_parser(name, help=help_line, description=help_line)
        if only is None or name == only:
            module = importlib.import_module(f"pipelines.commands.{name.replace('-', '_')}")
            module.add_arguments(p)
            p.set_defaults(_run=module.run)
    return parser


def _command_in(argv: Sequence[str]) -> str:
    """The command ``argv`` names ("" for none: the top-level help, the version, or a
    mistake argparse reports), found as argparse finds it: the first word that is not
    one of the top-level options (none of which takes a value)."""
    for word in argv:
        if word in ("-v", "--verbose"):
            continue
        return word if word in COMMANDS else ""
    return ""


#: The root error of each package's tree (module, class): a known error, reported as one
#: line. Looked up in the modules already imported (an error of a package not imported
#: cannot have been raised), so that a command imports only what it uses.
_KNOWN_ERRORS = (
    ("pipelines.errors", "BeambenchError"),
    ("sim.errors", "SimError"),
    ("vision.errors", "VisionError"),
    ("daq.errors", "DaqError"),
)


def _known(exc: Exception) -> bool:
    for module, name in _KNOWN_ERRORS:
        loaded = sys.modules.get(module)
        if loaded is not None and isinstance(exc, getattr(loaded, name)):
            return True
    return False


def main(argv: Sequence[str] | None = None) -> int:
    words = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser(only=_command_in(words))
    args = parser.parse_args(words)
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
    if args.command is None:
        parser.print_help()
        return EXIT_BAD_INPUT
    from pipelines.blas_threads import limit_blas_threads

    limit_blas_threads()
    try:
        return int(args._run(args) or 0)
    except KeyboardInterrupt:
        print("error: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:
        if not _known(exc):
            raise
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
