"""Vision benchmark: ``python benchmarks/bench_vision.py [--quick]`` (same as
``beambench bench vision``)."""

from __future__ import annotations

import sys

from pipelines.bench.vision import run

if __name__ == "__main__":
    sys.exit(run(quick="--quick" in sys.argv[1:]))
