"""The project's numba options (vision/jit.py): numpy's error model and IEEE sums."""

from __future__ import annotations

import math
import os
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

from vision.jit import KEEP_CACHES, _prune, cache_dir, kernel, sources_digest

REPO = Path(__file__).resolve().parents[2]


@kernel
def _ratio_sum(a, b):  # type: ignore[no-untyped-def]
    s = 0.0
    for i in range(a.size):
        s += a[i] / b[i]
    return s


def test_kernel_divides_as_numpy_does() -> None:
    # error_model="numpy": 1/0 is inf and 0/0 NaN, not ZeroDivisionError
    assert _ratio_sum(np.array([1.0]), np.array([0.0])) == math.inf
    assert math.isnan(_ratio_sum(np.array([0.0]), np.array([0.0])))


def test_kernel_sums_in_order_without_fastmath() -> None:
    # no fastmath: a left-to-right sum, bit for bit what Python's loop gives
    rng = np.random.default_rng(7)
    a, b = rng.normal(size=1001), rng.uniform(0.5, 2.0, size=1001)
    expect = 0.0
    for x, y in zip(a.tolist(), b.tolist(), strict=True):
        expect += x / y
    assert _ratio_sum(a, b) == expect


def test_kernel_runs_in_threads() -> None:
    a, b = np.ones(10_000), np.full(10_000, 4.0)
    out: list[float] = []
    threads = [threading.Thread(target=lambda: out.append(_ratio_sum(a, b))) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert out == [2500.0] * 4


def _run(code: str, root: Path) -> str:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(root), str(REPO)]))
    env.pop("NUMBA_CACHE_DIR", None)
    out = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300
    )
    assert out.returncode == 0, out.stderr
    return out.stdout.strip()


def _package(root: Path, **modules: str) -> Path:
    """A package ``kpkg`` under ``root`` with the modules given (name: source)."""
    pkg = root / "kpkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    for name, source in modules.items():
        (pkg / f"{name}.py").write_text(source)
    return pkg


@pytest.mark.slow
def test_a_changed_callee_compiles_its_callers_again(tmp_path: Path) -> None:
    # numba keys a cached kernel on its own file: the caller's cache would keep the
    # callee's old code. The package's digest in the cache directory's name prevents it.
    callee = "from vision.jit import kernel\n\n@kernel\ndef f(x):\n    return x + {}\n"
    pkg = _package(
        tmp_path,
        callee=callee.format("1.0"),
        caller="from vision.jit import kernel\nfrom kpkg.callee import f\n\n"
        "@kernel\ndef g(x):\n    return f(x) * 2.0\n",
    )
    code = "import kpkg.caller as c; print(c.g(1.0))"
    assert _run(code, tmp_path) == "4.0"
    assert _run(code, tmp_path) == "4.0"  # from the cache
    caches = list((pkg / "__pycache__").glob("kernels-*"))
    assert len(caches) == 1 and any(caches[0].rglob("*.nbi"))
    (pkg / "callee.py").write_text(callee.format("2.0"))
    assert _run(code, tmp_path) == "6.0"
    assert len(list((pkg / "__pycache__").glob("kernels-*"))) == 2


LOAD = """
import kpkg.callee as c
from vision.jit import load_cached
load_cached()  # all kernels made so far: vision's (imported with vision.jit) and f
f = c.f
print(len(f.overloads), sum(f._cache_hits.values()), sum(f._cache_misses.values()), f(1.0),
      sum(f._cache_misses.values()))
"""


def test_load_cached_loads_what_the_cache_holds_and_compiles_nothing(tmp_path: Path) -> None:
    # what a fork server does before it forks the frame workers: every cached kernel
    # loaded at once; a cold cache loads nothing and compiles nothing (the first call does)
    _package(
        tmp_path, callee="from vision.jit import kernel\n\n@kernel\ndef f(x):\n    return x + 1.0\n"
    )
    # cold: none loaded, no overload made, none compiled until the call (one then)
    assert _run(LOAD, tmp_path).split() == ["0", "0", "0", "2.0", "1"]
    # warm (the call above cached it): loaded from the cache, nothing compiled
    assert _run(LOAD, tmp_path).split() == ["1", "1", "0", "2.0", "0"]


ENTRY = """
import kpkg.caller as c
from vision.jit import load_cached
load_cached()
print(*(len(k.overloads) for k in (c.inner, c.both, c.outer)))
print(c.outer(1.0), c.py(1.0), sum(c.outer._cache_misses.values()), len(c.inner.overloads))
"""


def test_load_cached_leaves_out_kernels_only_kernels_call(tmp_path: Path) -> None:
    # a kernel called only by kernels is compiled into its callers' code: its own
    # machine code is never run, and the fork server does not load it; a kernel that
    # Python code calls (too) is loaded
    _package(
        tmp_path,
        caller="from vision.jit import kernel\n\n"
        "@kernel\ndef inner(x):\n    return x + 1.0\n\n"
        "@kernel\ndef both(x):\n    return x * 3.0\n\n"
        "@kernel\ndef outer(x):\n    return inner(x) * 2.0 + both(x)\n\n"
        "def py(x):\n    return both(x)\n",
    )
    warm = "import kpkg.caller as c; print(c.outer(1.0), c.py(1.0))"
    assert _run(warm, tmp_path) == "7.0 3.0"  # compiles and caches all three
    # inner not loaded, both and outer loaded; outer runs from the cache, inner unneeded
    assert _run(ENTRY, tmp_path).splitlines() == ["0 1 1", "7.0 3.0 0 0"]


def test_digest_follows_every_source(tmp_path: Path) -> None:
    (tmp_path / "a.py").write_text("x = 1\n")
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "b.py").write_text("y = 1\n")
    first = sources_digest(tmp_path)
    assert sources_digest(tmp_path) == first
    (tmp_path / "sub" / "b.py").write_text("y = 2\n")
    assert sources_digest(tmp_path) != first
    (tmp_path / "sub" / "b.py").write_text("y = 1\n")
    assert sources_digest(tmp_path) == first
    (tmp_path / "c.txt").write_text("not a source")
    assert sources_digest(tmp_path) == first


def test_old_caches_are_pruned(tmp_path: Path) -> None:
    for i in range(KEEP_CACHES + 3):
        d = tmp_path / f"kernels-{i:016x}"
        d.mkdir()
        os.utime(d, (1_000_000 + i, 1_000_000 + i))
    (tmp_path / "other").mkdir()
    cache_dir.cache_clear()
    src = tmp_path / "src"
    src.mkdir()
    (src / "m.py").write_text("z = 0\n")
    made = cache_dir(src)
    assert made is not None and made.parent == src / "__pycache__"
    _prune(tmp_path)
    left = sorted(p.name for p in tmp_path.iterdir() if p.name.startswith("kernels-"))
    assert left == [f"kernels-{i:016x}" for i in range(3, KEEP_CACHES + 3)]
    assert (tmp_path / "other").is_dir()


def test_nowhere_writable_compiles_without_a_cache(monkeypatch: pytest.MonkeyPatch) -> None:
    # a read-only install and home: numba's cache=True would refuse at import time
    # ("no locator available"); the kernel is compiled for this process instead
    import vision.jit as jit

    monkeypatch.setattr(jit, "cache_dir", lambda package: None)

    def twice(x):  # type: ignore[no-untyped-def]
        return 2.0 * x

    compiled = jit.kernel(twice)
    assert compiled(1.5) == 3.0
    assert type(compiled._cache).__name__ == "NullCache"  # numba's: nothing written
