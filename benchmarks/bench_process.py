"""Processing benchmark: the same table as ``beambench bench process [--quick]``."""

from __future__ import annotations

import argparse
import sys

from pipelines.bench.process import run

if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="a 10 s run instead of 60 s")
    sys.exit(run(quick=parser.parse_args().quick))
