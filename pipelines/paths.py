"""Outputs never alias inputs: checked once, before any work, for every command.

``beambench process RUN --out RUN`` used to turn the log into a NetCDF file. Every command
that reads files and writes files hands both sets to :func:`refuse_aliases`, which compares
them as the file system does (``os.path.samefile``: device and inode), so a second name for
the same file, a hard link or a symbolic link, is caught as surely as the same path.
"""

from __future__ import annotations

import contextlib
import os
import uuid
from collections.abc import Iterable, Mapping
from pathlib import Path

from pipelines.errors import BeambenchError

PathArg = str | os.PathLike[str] | None


def same_file(a: str | os.PathLike[str], b: str | os.PathLike[str]) -> bool:
    """``a`` and ``b`` name one file: the same path, a hard link or a symbolic link to it.

    Two names of which one does not exist yet are the same file when they resolve to the
    same place (two outputs given as one path).
    """
    try:
        return os.path.samefile(a, b)
    except OSError:
        return os.path.realpath(a) == os.path.realpath(b)


def _given(paths: Mapping[str, PathArg]) -> list[tuple[str, Path]]:
    return [(label, Path(p)) for label, p in paths.items() if p is not None]


def refuse_aliases(outputs: Mapping[str, PathArg], inputs: Mapping[str, PathArg]) -> None:
    """Raise ``BeambenchError`` when an output names an input file or another output.

    ``outputs`` and ``inputs`` map an option label (``"--out"``, ``"the log"``) to a path
    or None (not given). Call it before any work: a refused run has changed nothing.
    """
    outs = _given(outputs)
    for out_label, out in outs:
        for in_label, inp in _given(inputs):
            if inp.exists() and same_file(out, inp):
                raise BeambenchError(
                    f"{out_label} {out}: is the same file as {in_label} {inp} "
                    "(same path, hard link or symbolic link); an output never replaces an input"
                )
    for i, (label_a, a) in enumerate(outs):
        for label_b, b in outs[i + 1 :]:
            if same_file(a, b):
                raise BeambenchError(f"{label_a} {a} and {label_b} {b}: name the same file")


def refuse_inputs_among(
    folder: str | os.PathLike[str],
    names: Iterable[str],
    inputs: Mapping[str, PathArg],
    option: str = "--out",
) -> None:
    """Raise ``BeambenchError`` when an input is one of the files ``names`` that a command
    writes into ``folder`` (the demo's log, results, recording, report and plots)."""
    root = Path(folder)
    for name in names:
        target = root / name
        for in_label, inp in _given(inputs):
            if inp.exists() and same_file(target, inp):
                raise BeambenchError(
                    f"{option} {root}: would replace {target}, which is {in_label} {inp}; "
                    "an output never replaces an input"
                )


def check_writable_output(path: str | os.PathLike[str], option: str) -> Path:
    """Refuse, before any work, an output file whose folder is missing or refuses a new
    file (``/proc``, a read-only mount, no permission): a file is created beside it and
    removed, since ``os.access`` says yes to root wherever a write would still fail."""
    out = Path(path)
    folder = out.absolute().parent
    if not folder.is_dir():
        raise BeambenchError(f"{option} {out}: folder {folder} does not exist")
    if out.is_dir():
        raise BeambenchError(f"{option} {out}: is a folder")
    probe = folder / f".{out.name}.{uuid.uuid4().hex}.probe"
    try:
        with open(probe, "xb") as f:
            f.write(b"\0")
            f.flush()
            os.fsync(f.fileno())
    except OSError as exc:
        raise BeambenchError(
            f"{option} {out}: cannot write in {folder} ({exc.strerror or exc})"
        ) from None
    finally:
        with contextlib.suppress(OSError):
            probe.unlink()
    return out


def write_failed(path: str | os.PathLike[str], exc: BaseException) -> BeambenchError:
    """The error for an output that could not be written after the work (a full disk):
    it names the file and the reason; any earlier file of that name is as it was."""
    reason = getattr(exc, "strerror", None) or str(exc) or type(exc).__name__
    return BeambenchError(f"{path}: cannot write ({reason}); an earlier file there is unchanged")
