"""Compiled kernels: :func:`kernel` is numba's ``njit`` with this project's options, for the
per-frame loops whose numpy form spends its time in thousands of small array calls.

- ``cache=True``: compiled once per machine and source version, so a run's frame workers
  and CLI calls load the machine code instead of compiling it (a fresh cache compiles all
  of vision's kernels in ~25 CPU s, a warm one loads them in ~0.5 s).
- ``nogil=True``: a kernel releases the GIL, so frames measured in threads run in parallel.
- ``error_model="numpy"``: division by zero gives inf/NaN as numpy does, not an exception.
- no ``fastmath``: IEEE arithmetic, so a kernel and the numpy form it replaces differ only
  by the order of their sums (and the last place of libm's functions against numpy's).

**The cache's key.** numba keys a cached kernel on its own source file only, so a kernel
that calls a kernel of another module would load stale machine code after that module
changed (a ``git pull`` in an editable install; seen crashing). Here each package's kernels
are cached in a directory named by a digest of all the package's sources
(:func:`cache_dir`): any change to any of them compiles afresh. The directory is
``__pycache__/kernels-<digest>`` beside the sources, or under ``$NUMBA_CACHE_DIR`` or the
user's cache directory when the package's own is not writable; the newest
:data:`KEEP_CACHES` of them are kept.
"""

from __future__ import annotations

import functools
import hashlib
import os
import shutil
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar, cast

import numba

F = TypeVar("F", bound=Callable[..., Any])

#: Cache directories kept per place (other source versions, e.g. git branches switched to
#: and fro); older ones are removed when a new one is made.
KEEP_CACHES = 4
_PREFIX = "kernels-"
# numba's settings (CACHE_DIR from $NUMBA_CACHE_DIR), set on the module at run time
_config: Any = numba.config
#: Every kernel made by :func:`kernel`, in the order made (for :func:`load_cached`).
_KERNELS: list[Any] = []


def kernel(fn: F) -> F:
    """``fn`` compiled by numba (nopython mode) with the options above, cached under
    :func:`cache_dir` of its package."""
    module = sys.modules.get(fn.__module__)
    source = getattr(module, "__file__", None)
    where = cache_dir(Path(source).parent) if source else None
    saved = _config.CACHE_DIR
    try:
        if where is not None:
            # read by numba's cache locator when caching is enabled, i.e. inside njit()
            _config.CACHE_DIR = str(where)
        # nowhere writable (a read-only install and home): compiled in each process, since
        # numba's own cache places would be the same unwritable ones, and it refuses then
        compiled = numba.njit(cache=where is not None, nogil=True, error_model="numpy")(fn)
    finally:
        _config.CACHE_DIR = saved
    _KERNELS.append(compiled)
    return cast(F, compiled)


def load_cached() -> int:
    """Load the machine code of every kernel made so far (the modules imported) that
    Python code may call (:func:`_entry_kernels`) and its cache holds, for each
    signature cached, now rather than at each kernel's first call; the number loaded. A
    process that forks workers loads them once for all of them
    (:mod:`pipelines.process.frames`: ~0.4 s a worker otherwise). Only what the cache
    holds for this machine and source is asked for: a cold cache loads nothing, and its
    kernels compile at their first call, as before; so does any kernel whose cache numba
    cannot be asked (its cache's internals are not public API: they are used here only
    to read which signatures are cached)."""
    loaded = 0
    for dispatcher in _entry_kernels():
        try:
            cache = dispatcher._cache
            magic = dispatcher.targetctx.codegen().magic_tuple()
            keys = list(cache._cache_file._load_index())
        except Exception:  # numba's internals moved: the kernel loads at its first call
            continue
        for key in keys:
            sig = key[0] if isinstance(key, tuple) and len(key) > 1 else None
            if sig is None or key[1] != magic or sig in dispatcher.overloads:
                continue
            # the index is this source's (numba checks its stamp): a load, not a compile
            dispatcher.compile(sig)
            loaded += 1
    return loaded


def _entry_kernels() -> list[Any]:
    """The kernels Python code may call: those no kernel calls, and those a Python
    function or method of the kernels' packages names. A kernel called only by other
    kernels needs no machine code of its own: numba compiles a callee into each caller's
    code (cached with it), so loading the callee's own (a third of vision's cached
    kernels, ~0.2 s) is wasted. A kernel left out that Python calls after all is loaded
    at its first call, as without this."""
    names = {k.py_func.__name__ for k in _KERNELS}
    by_kernels: set[str] = set()
    for k in _KERNELS:
        by_kernels.update(_names_in(k.py_func.__code__) & names)
    packages = {k.py_func.__module__.partition(".")[0] for k in _KERNELS}
    by_python: set[str] = set()
    for name, module in list(sys.modules.items()):
        if name.partition(".")[0] in packages and module is not None:
            for value in list(vars(module).values()):
                for code in _codes_of(value):
                    by_python.update(_names_in(code) & names)
    return [
        k
        for k in _KERNELS
        if k.py_func.__name__ not in by_kernels or k.py_func.__name__ in by_python
    ]


def _names_in(code: Any) -> set[str]:
    """The global and attribute names a code object and the code nested in it use."""
    found = set(code.co_names)
    for const in code.co_consts:
        if hasattr(const, "co_names"):
            found |= _names_in(const)
    return found


def _codes_of(value: Any) -> list[Any]:
    """The code objects of a Python function, or of a class's functions, methods and
    properties (a kernel, numba's dispatcher, has none: its Python function is
    ``py_func``)."""
    if hasattr(value, "py_func"):  # a kernel
        return []
    if isinstance(value, type):
        return [c for member in vars(value).values() for c in _codes_of(member)]
    if isinstance(value, (staticmethod, classmethod)):
        return _codes_of(value.__func__)
    if isinstance(value, property):
        return [c for f in (value.fget, value.fset) if f is not None for c in _codes_of(f)]
    code = getattr(getattr(value, "__wrapped__", value), "__code__", None)
    return [code] if code is not None else []


def cached(package: Path | None = None) -> bool:
    """Whether any kernel of ``package`` (default: vision) is in its cache already: False
    on a machine's first run and after its sources changed, when the first frame measured
    compiles them (~25 CPU s for vision's); a caller starting several worker processes
    measures its first frames itself then, so that they are compiled once, not in each."""
    where = cache_dir(package if package is not None else Path(__file__).parent)
    return where is not None and any(where.rglob("*.nbi"))


def sources_digest(package: Path) -> str:
    """A digest of every ``.py`` file under ``package`` (names and contents) and of
    numba's version: it changes when any source a kernel may call changes."""
    h = hashlib.sha256(numba.__version__.encode())
    for path in sorted(package.rglob("*.py")):
        h.update(str(path.relative_to(package)).encode() + b"\0")
        h.update(path.read_bytes() + b"\0")
    return h.hexdigest()[:16]


@functools.cache
def cache_dir(package: Path) -> Path | None:
    """Where the kernels of ``package`` (a directory of sources) are cached: a directory
    named by :func:`sources_digest`, in the first writable place of ``__pycache__``
    beside the sources, ``$NUMBA_CACHE_DIR``, the user's cache directory; None when none
    is writable (the kernels are then compiled in each process, not cached)."""
    name = _PREFIX + sources_digest(package)
    user = os.environ.get("XDG_CACHE_HOME") or os.path.join(Path.home(), ".cache")
    places = [package / "__pycache__"]
    if _config.CACHE_DIR:
        places.append(Path(_config.CACHE_DIR) / "beambench")
    places.append(Path(user) / "beambench" / "numba")
    for place in places:
        target = place / name
        try:
            fresh = not target.is_dir()
            target.mkdir(parents=True, exist_ok=True)
            if not os.access(target, os.W_OK):
                continue
        except OSError:
            continue
        if fresh:
            _prune(place)
        return target
    return None


def _prune(place: Path) -> None:
    """Remove all but the newest :data:`KEEP_CACHES` kernel caches in ``place``."""
    try:
        caches = [p for p in place.iterdir() if p.name.startswith(_PREFIX) and p.is_dir()]
        caches.sort(key=lambda p: p.stat().st_mtime, reverse=True)
    except OSError:
        return
    for old in caches[KEEP_CACHES:]:
        shutil.rmtree(old, ignore_errors=True)
