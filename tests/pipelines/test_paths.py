"""Outputs never alias inputs: the same path, a hard link or a symbolic link is refused
with one error line and exit status 2 before any work, by every command that has both."""

from __future__ import annotations

import hashlib
import os
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from daq.fakes import FakeStrainDaq
from pipelines.acquire.capture import capture_run
from pipelines.cli import main
from pipelines.errors import BeambenchError
from pipelines.paths import refuse_aliases, refuse_inputs_among, same_file
from pipelines.rig import load_rig

RIG = load_rig()
RIG_TEXT = (Path(__file__).parents[2] / "pipelines" / "data" / "rig.toml").read_text()


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _alias(kind: str, target: Path, folder: Path, name: str) -> Path:
    """A second name for ``target``: itself, a hard link or a symbolic link."""
    if kind == "same":
        return target
    alias = folder / name
    if kind == "hardlink":
        os.link(target, alias)
    else:
        alias.symlink_to(target)
    return alias


@pytest.fixture(scope="module")
def small_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One second of a zero-strain log (no camera): enough to be a real input file."""
    out = tmp_path_factory.mktemp("alias") / "run.mcap"
    daq = FakeStrainDaq(
        RIG.gauges,
        RIG.potentiometer,
        RIG.daq,
        strain_fn=lambda t: np.zeros((len(t), 4)),
        angle_fn=lambda t: 0 * t + 1,
    )
    capture_run(RIG, daq, None, out, 1.0, realtime=False)
    return out


KINDS = ("same", "hardlink", "symlink")


def _refused(argv: list[str], inputs: list[Path], capsys: pytest.CaptureFixture[str]) -> str:
    before = [_digest(p) for p in inputs]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: "), err
    assert [_digest(p) for p in inputs] == before
    return err


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("option", ["--out", "--rrd"])
def test_process_refuses_an_output_that_is_the_log(
    kind: str,
    option: str,
    small_log: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    alias = _alias(kind, small_log, tmp_path, "alias.mcap")
    other = {"--out": str(tmp_path / "r.nc"), "--rrd": str(tmp_path / "r.rrd")}
    other[option] = str(alias)
    argv = ["process", str(small_log), "--out", other["--out"], "--rrd", other["--rrd"]]
    err = _refused(argv, [small_log], capsys)
    assert f"{option} {alias}: is the same file as the log {small_log}" in err


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("input_option", ["--rig", "--calibration"])
def test_process_refuses_an_output_that_is_the_rig_or_calibration(
    kind: str,
    input_option: str,
    small_log: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    source = tmp_path / "input.toml"
    source.write_text(RIG_TEXT)
    alias = _alias(kind, source, tmp_path, "results.nc")
    argv = ["process", str(small_log), "--out", str(alias), input_option, str(source)]
    err = _refused(argv, [source, small_log], capsys)
    assert f"is the same file as {input_option} {source}" in err


def test_process_refuses_out_and_rrd_as_one_file(
    small_log: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "both"
    argv = ["process", str(small_log), "--out", str(out), "--rrd", str(out)]
    err = _refused(argv, [small_log], capsys)
    assert "name the same file" in err
    assert not out.exists()


@pytest.mark.parametrize("kind", KINDS)
def test_replay_refuses_a_recording_that_is_the_log(
    kind: str, small_log: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # a recording must end in .rrd (refused before the alias check): a log named so
    log = tmp_path / "log.rrd"
    log.write_bytes(small_log.read_bytes())
    alias = _alias(kind, log, tmp_path, "alias.rrd")
    err = _refused(["replay", str(log), "--rrd", str(alias)], [log], capsys)
    assert "is the same file as the log" in err


def test_replay_default_recording_of_a_log_named_rrd_is_refused(
    small_log: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # the default recording is RUN.rrd beside the log: for a log named x.rrd that is the log
    log = tmp_path / "x.rrd"
    log.write_bytes(small_log.read_bytes())
    err = _refused(["replay", str(log)], [log], capsys)
    assert "is the same file as the log" in err


@pytest.mark.parametrize("kind", KINDS)
def test_recover_refuses_an_output_that_is_the_log(
    kind: str, small_log: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    alias = _alias(kind, small_log, tmp_path, "fixed.mcap")
    err = _refused(["recover", str(small_log), "--out", str(alias)], [small_log], capsys)
    assert "is the same file as the log" in err


def _rig_file(tmp_path: Path) -> Path:
    rig = tmp_path / "rig.toml"
    rig.write_text(RIG_TEXT)
    return rig


@pytest.mark.parametrize("kind", KINDS)
def test_sim_refuses_an_output_that_is_the_rig(
    kind: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rig = _rig_file(tmp_path)
    alias = _alias(kind, rig, tmp_path, "out.nc")
    err = _refused(["sim", "modes", "--rig", str(rig), "--out", str(alias)], [rig], capsys)
    assert f"--out {alias}: is the same file as --rig {rig}" in err


@pytest.mark.parametrize("kind", KINDS)
def test_capture_refuses_an_output_that_is_the_rig(
    kind: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rig = _rig_file(tmp_path)
    alias = _alias(kind, rig, tmp_path, "run.mcap")
    argv = ["capture", "--duration", "1", "--rig", str(rig), "--out", str(alias)]
    err = _refused(argv, [rig], capsys)
    assert "is the same file as --rig" in err


@pytest.mark.parametrize("kind", KINDS)
def test_demo_refuses_a_rig_among_its_outputs(
    kind: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rig = _rig_file(tmp_path)
    out = tmp_path / "demo"
    out.mkdir()
    if kind == "same":
        rig = out / "report.md"
        rig.write_text(RIG_TEXT)
    else:
        _alias(kind, rig, out, "report.md")
    err = _refused(["demo", "--out", str(out), "--rig", str(rig)], [rig], capsys)
    assert "would replace" in err and "report.md" in err


@pytest.mark.parametrize(
    "make",
    [
        lambda a, b: os.link(a, b),
        lambda a, b: Path(b).symlink_to(a),
        lambda a, b: Path(b).symlink_to(Path(a).name),  # relative link
    ],
)
def test_same_file_sees_links(tmp_path: Path, make: Callable[[Path, Path], None]) -> None:
    a = tmp_path / "a"
    a.write_text("x")
    b = tmp_path / "b"
    make(a, b)
    assert same_file(a, b)
    c = tmp_path / "c"
    c.write_text("x")  # same content, another file
    assert not same_file(a, c)


def test_same_file_of_paths_spelled_differently(tmp_path: Path) -> None:
    (tmp_path / "sub").mkdir()
    a = tmp_path / "a"
    assert same_file(a, tmp_path / "sub" / ".." / "a")  # neither exists yet
    assert not same_file(a, tmp_path / "b")


def test_helpers_name_both_options(tmp_path: Path) -> None:
    a = tmp_path / "a"
    a.write_text("x")
    with pytest.raises(BeambenchError, match=r"--out .*a: is the same file as --rig .*a"):
        refuse_aliases({"--out": a, "--rrd": None}, {"--rig": a, "--calibration": None})
    refuse_aliases({"--out": tmp_path / "b"}, {"--rig": a})
    with pytest.raises(BeambenchError, match="would replace"):
        refuse_inputs_among(tmp_path, ["a"], {"--rig": a})
    refuse_inputs_among(tmp_path, ["b"], {"--rig": a})
