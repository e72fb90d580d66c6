"""Files that appear whole or not at all: write beside the target, then rename.

Every output of beambench (results, simulations, reports, plots, ``.rrd`` recordings, the
demo's log) is written under a fresh temporary name in the target's folder and renamed onto
the target once complete. The rename is atomic on one file system, so a run that fails or is
killed leaves an existing file as it was and no temporary file behind.
"""

from __future__ import annotations

import contextlib
import os
import uuid
from collections.abc import Iterator
from pathlib import Path


def temp_path_beside(path: str | os.PathLike[str]) -> Path:
    """A fresh, unused name in ``path``'s folder for writing ``path``'s content.

    Not ``mkstemp``: its 0600 mode would stick to the renamed file.
    """
    out = Path(path)
    return out.parent / f".{out.name}.{uuid.uuid4().hex}.tmp"


def discard(tmp: str | os.PathLike[str]) -> None:
    """Remove a temporary file if it exists."""
    with contextlib.suppress(FileNotFoundError):
        Path(tmp).unlink()


def write_bytes_atomic(path: str | os.PathLike[str], data: bytes) -> Path:
    """``path`` replaced by ``data``, whole or not at all: a full disk is one ``OSError``
    (ENOSPC) from a plain write, and the target is left as it was."""
    out = Path(path)
    with atomic_path(out) as tmp:
        with open(tmp, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
    return out


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """``with atomic_path(out) as tmp: write(tmp)``: ``out`` is replaced by ``tmp`` when
    the block ends without an exception; otherwise ``tmp`` is removed and ``out`` untouched.
    """
    out = Path(path)
    tmp = temp_path_beside(out)
    try:
        yield tmp
        os.replace(tmp, out)
    finally:
        discard(tmp)
