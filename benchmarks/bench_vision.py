"""Vision benchmark: ``python benchmarks/bench_vision.py [--quick] [--sets a,b,...]``
(same as ``beambench bench vision``, which runs every set)."""

from __future__ import annotations

import sys

from pipelines.bench.vision import SETS, run

if __name__ == "__main__":
    argv = sys.argv[1:]
    sets = SETS
    if "--sets" in argv:
        sets = tuple(argv[argv.index("--sets") + 1].split(","))
        unknown = sorted(set(sets) - set(SETS))
        if unknown:
            print(f"error: unknown vision set(s) {', '.join(unknown)}; known: {', '.join(SETS)}")
            sys.exit(2)
    sys.exit(run(quick="--quick" in argv, sets=sets))
