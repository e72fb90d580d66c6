from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from daq.errors import DeviceTimeoutError
from pipelines.cli import COMMANDS, main
from pipelines.errors import BeambenchError
from sim.errors import IntegrationError
from vision.errors import CalibrationError


def test_help_lists_every_subcommand(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as info:
        main(["--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    for name in COMMANDS:
        assert name in out
    assert set(COMMANDS) == {
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
    }


def test_the_list_and_a_mistake_import_no_command() -> None:
    # a command's module (and its libraries: numpy, OpenCV, numba, xarray...) is imported
    # when it runs, or its own help is asked for; ``--help`` and a usage mistake answer
    # without them (they took ~1.3 s when every command was imported first)
    code = (
        "import sys\n"
        "from pipelines.cli import main\n"
        "for argv in (['--help'], ['bogus'], ['-v']):\n"
        "    try:\n"
        "        main(argv)\n"
        "    except SystemExit:\n"
        "        pass\n"
        "heavy = [m for m in ('numpy', 'vision', 'sim', 'daq') if m in sys.modules]\n"
        "commands = [m for m in sys.modules if m.startswith('pipelines.commands.')]\n"
        "print('imported:', heavy, commands)\n"
        "main(['info', '--help'])\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    assert "imported: [] []" in proc.stdout.splitlines(), proc.stdout + proc.stderr
    assert "usage: beambench info" in proc.stdout and proc.returncode == 0


@pytest.mark.parametrize("name", COMMANDS)
def test_each_subcommand_has_help(name: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as info:
        main([name, "--help"])
    assert info.value.code == 0
    assert "usage: beambench " + name in capsys.readouterr().out


def test_bad_rig_is_one_error_line_and_exit_2(tmp_path: Path) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text("[beam]\nlength_m = -1\n")
    proc = subprocess.run(
        [sys.executable, "-m", "pipelines.cli", "sim", "static", "--rig", str(bad)],
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("error: ") and str(bad) in lines[0]
    assert "Traceback" not in proc.stderr


@pytest.mark.parametrize(
    "argv",
    [
        ["sim", "no-such-scene"],
        ["process", "run.mcap", "--out", "r.nc", "--frame-previews", "bogus"],
    ],
    ids=["scene", "frame-previews"],
)
def test_usage_mistake_is_one_error_line(
    argv: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ")
    assert argv[-1] in err[0]


@pytest.mark.parametrize(
    "error",
    [
        BeambenchError("run.mcap: no such file"),
        IntegrationError("radau5", 1.25, "step size underflow"),
        CalibrationError("the plane is mirrored", section="registration"),
        DeviceTimeoutError("strain DAQ", 2.0),
    ],
    ids=["pipelines", "sim", "vision", "daq"],
)
def test_each_package_root_is_one_error_line_and_exit_2(
    error: Exception, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Whatever package a known error comes from, the user sees one line, never a traceback."""
    import pipelines.commands.info as info

    def fail(args: object) -> int:
        raise error

    monkeypatch.setattr(info, "run", fail)
    assert main(["info", "run.mcap"]) == 2
    err = capsys.readouterr().err
    assert err == f"error: {error}\n"
