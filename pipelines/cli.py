"""The ``beambench`` command line: one console script, one module per subcommand.

Each module in ``pipelines.commands`` provides ``HELP`` (one line), ``add_arguments``
and ``run(args) -> int``. Known errors (``BeambenchError``, and the root of each
package's tree: ``SimError``, ``VisionError``, ``DaqError``) become one ``error: ...`` line
on stderr and exit status 2; a traceback is a bug.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys
from collections.abc import Sequence
from typing import NoReturn

from daq.errors import DaqError
from pipelines import __version__
from pipelines.blas_threads import limit_blas_threads
from pipelines.errors import BeambenchError
from sim.errors import SimError
from vision.errors import VisionError

COMMANDS = (
    "demo",
    "check",
    "capture",
    "info",
    "recover",
    "process",
    "campaign",
    "sweep",
    "replay",
    "view",
    "measure",
    "sim",
    "bench",
    "reproduce",
)

EXIT_BAD_INPUT = 2


class _Parser(argparse.ArgumentParser):
    """argparse that reports usage mistakes as one ``error:`` line (exit 2)."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_BAD_INPUT, f"error: {self.prog}: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="beambench",
        description="Data acquisition and processing for the reciprocating flexible-beam bench.",
    )
    parser.add_argument("--version", action="version", version=f"beambench {__version__}")
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress details")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for name in COMMANDS:
        module = importlib.import_module(f"pipelines.commands.{name.replace('-', '_')}")
        p = sub.add_parser(name, help=module.HELP, description=module.HELP)
        module.add_arguments(p)
        p.set_defaults(_run=module.run)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
    if args.command is None:
        parser.print_help()
        return EXIT_BAD_INPUT
    limit_blas_threads()
    try:
        return int(args._run(args) or 0)
    except (BeambenchError, SimError, VisionError, DaqError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("error: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
