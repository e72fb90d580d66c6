"""Acquisition benchmark: the same table as ``beambench bench daq [--quick]``."""

from __future__ import annotations

import argparse
import sys

from pipelines.bench.daq import run

if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="a short smoke run (~15 s)")
    sys.exit(run(quick=parser.parse_args().quick))
